//! A kinematic parallel gripper: the fingers move at the requested speed
//! towards the requested position, quantised to position steps, and stop
//! on an object of a given width. Enough to stand in for a Robotiq behind
//! the emulator (`slidetrack emulate robotiq`, the driver's tests); the
//! two-finger grasp physics live in the simulator.
//!
//! Model assumptions (not the device's published behaviour): the opening
//! is linear in the position steps; the motor current is 100 mA while
//! moving, proportional to the force request while holding an object
//! (up to 600 mA at force 255), and 0 at rest.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use slidetrack_core::{
    ActuatorCommand, ActuatorSpec, Clock, DeviceError, GripperObject, GripperRequest, GripperSpec,
    GripperStatus, HandActuator, HandMonitor, HandStatus, TimeNs,
};

/// Motor current while the fingers move (mA).
const MOVING_CURRENT_MA: u32 = 100;
/// Motor current holding an object at force 255 (mA).
const MAX_HOLDING_CURRENT_MA: f64 = 600.0;

/// A kinematic gripper of `spec`, fully open, stopping on an object
/// `object_width_m` wide when there is one, on `clock`'s time: its actuator
/// and a monitor of the same fingers.
pub fn kinematic_gripper(
    spec: GripperSpec,
    object_width_m: Option<f64>,
    clock: Arc<dyn Clock>,
) -> (KinematicActuator, KinematicMonitor) {
    let now = clock.now();
    let state = Arc::new(Mutex::new(State {
        spec,
        object_width_m,
        closure_m: 0.0,
        request: GripperRequest::default(),
        moving: false,
        object: GripperObject::AtRequest,
        t: now,
    }));
    let actuator = KinematicActuator { state: Arc::clone(&state), clock: Arc::clone(&clock) };
    (actuator, KinematicMonitor { state, clock })
}

struct State {
    spec: GripperSpec,
    object_width_m: Option<f64>,
    /// Travel of the fingers from fully open (m): opening is `stroke - closure`.
    closure_m: f64,
    request: GripperRequest,
    moving: bool,
    object: GripperObject,
    /// When the state was last advanced.
    t: TimeNs,
}

impl State {
    /// Moves the fingers on to `now`.
    fn advance(&mut self, now: TimeNs) {
        let dt_s = now.secs_since(self.t).max(0.0);
        self.t = now;
        if !self.moving {
            return;
        }
        let spec = &self.spec;
        let target_m = f64::from(self.request.position_steps.min(spec.max_steps)) * spec.step_m();
        // The fingers meet the object when closing past its width.
        let contact_m = self.object_width_m.map(|w| spec.stroke_m - w);
        let step_m = spec.speed_mps(self.request.speed) * dt_s;
        if target_m > self.closure_m {
            let next = (self.closure_m + step_m).min(target_m);
            match contact_m.filter(|&c| next >= c && self.closure_m <= c) {
                Some(c) => self.stop(c, GripperObject::ContactClosing),
                None if next >= target_m => self.stop(target_m, GripperObject::AtRequest),
                None => self.closure_m = next,
            }
        } else {
            let next = (self.closure_m - step_m).max(target_m);
            if next <= target_m {
                self.stop(target_m, GripperObject::AtRequest);
            } else {
                self.closure_m = next;
            }
        }
    }

    fn stop(&mut self, closure_m: f64, object: GripperObject) {
        self.closure_m = closure_m;
        self.moving = false;
        self.object = object;
    }

    fn start(&mut self, request: GripperRequest) {
        self.request =
            GripperRequest { position_steps: request.position_steps.min(self.spec.max_steps), ..request };
        let target_m = f64::from(self.request.position_steps) * self.spec.step_m();
        let holding_further = self.object == GripperObject::ContactClosing && target_m >= self.closure_m;
        if !holding_further {
            self.moving = true;
            self.object = GripperObject::Moving;
        }
    }

    fn status(&self) -> HandStatus {
        let spec = &self.spec;
        let position_steps = (self.closure_m / spec.step_m()).round() as u16;
        let current_ma = match self.object {
            GripperObject::Moving => MOVING_CURRENT_MA,
            GripperObject::ContactClosing => {
                (MAX_HOLDING_CURRENT_MA * f64::from(self.request.force) / 255.0).round() as u32
            }
            _ => 0,
        };
        HandStatus {
            t: self.t,
            finger_travel_m: Vec::new(),
            opening_m: Some(spec.stroke_m - self.closure_m),
            gripper: Some(GripperStatus {
                activated: true,
                object: self.object,
                fault: 0,
                requested_steps: self.request.position_steps,
                position_steps: position_steps.min(spec.max_steps),
                current_ma,
            }),
        }
    }
}

fn lock(state: &Mutex<State>) -> MutexGuard<'_, State> {
    state.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The kinematic gripper's actuator.
pub struct KinematicActuator {
    state: Arc<Mutex<State>>,
    clock: Arc<dyn Clock>,
}

impl HandActuator for KinematicActuator {
    fn spec(&self) -> ActuatorSpec {
        ActuatorSpec::Gripper(lock(&self.state).spec.clone())
    }

    /// Starts moving towards the request; never waits.
    fn command(&mut self, command: &ActuatorCommand) -> Result<(), DeviceError> {
        let ActuatorCommand::Gripper(request) = command else {
            return Err(command.wrong_kind(self.device(), "gripper requests"));
        };
        let mut s = lock(&self.state);
        s.advance(self.clock.now());
        s.start(*request);
        Ok(())
    }

    /// Opens fully at the fastest speed.
    fn release(&mut self) -> Result<(), DeviceError> {
        let mut s = lock(&self.state);
        s.advance(self.clock.now());
        let force = s.request.force;
        s.start(GripperRequest { position_steps: 0, speed: 255, force });
        Ok(())
    }

    fn device(&self) -> &str {
        "kinematic gripper"
    }
}

/// The kinematic gripper's monitor: a new status at every call.
pub struct KinematicMonitor {
    state: Arc<Mutex<State>>,
    clock: Arc<dyn Clock>,
}

impl HandMonitor for KinematicMonitor {
    fn status(&mut self) -> Result<Option<HandStatus>, DeviceError> {
        let mut s = lock(&self.state);
        s.advance(self.clock.now());
        Ok(Some(s.status()))
    }

    fn device(&self) -> &str {
        "kinematic gripper"
    }
}

#[cfg(test)]
mod tests {
    use slidetrack_core::SimClock;

    use super::*;

    fn at(clock: &SimClock, t_s: f64, monitor: &mut KinematicMonitor) -> GripperStatus {
        clock.sleep_until(TimeNs::from_secs_f64(t_s));
        monitor.status().unwrap().unwrap().gripper.unwrap()
    }

    #[test]
    fn closes_at_the_requested_speed_and_stops_on_the_object() {
        let clock = Arc::new(SimClock::new());
        let spec = GripperSpec::robotiq_2f85();
        let (mut hand, mut monitor) = kinematic_gripper(spec.clone(), Some(0.040), clock.clone());
        let close = GripperRequest { position_steps: 255, speed: 255, force: 255 };
        hand.command(&ActuatorCommand::Gripper(close)).unwrap();
        // 150 mm/s: 15 mm after 0.1 s, still moving.
        let s = at(&clock, 0.1, &mut monitor);
        assert_eq!(s.object, GripperObject::Moving);
        assert_eq!(s.position_steps, (0.015 / spec.step_m()).round() as u16);
        // The object (40 mm wide) stops the fingers 45 mm in.
        let s = at(&clock, 1.0, &mut monitor);
        assert_eq!((s.object, s.requested_steps), (GripperObject::ContactClosing, 255));
        assert_eq!(s.position_steps, (0.045 / spec.step_m()).round() as u16);
        assert_eq!(s.current_ma, 600);
        hand.release().unwrap();
        let s = at(&clock, 2.0, &mut monitor);
        assert_eq!((s.object, s.position_steps), (GripperObject::AtRequest, 0));
    }

    #[test]
    fn without_an_object_it_reaches_the_request() {
        let clock = Arc::new(SimClock::new());
        let (mut hand, mut monitor) = kinematic_gripper(GripperSpec::robotiq_2f85(), None, clock.clone());
        let request = GripperRequest { position_steps: 100, speed: 0, force: 0 };
        hand.command(&ActuatorCommand::Gripper(request)).unwrap();
        let s = at(&clock, 5.0, &mut monitor);
        assert_eq!((s.object, s.position_steps, s.current_ma), (GripperObject::AtRequest, 100, 0));
        assert!(hand.command(&ActuatorCommand::FingerVolts([0.0; 3])).is_err());
    }
}
