//! The controlled-sliding protocol as a state machine without I/O: it takes
//! tactile scans and marker positions and says what to command and record.
//!
//! Phases: zero the tactile baseline (hand open), close until every finger
//! touches, ramp the grasp to its maximum, settle, run the sliding cycles for
//! the requested duration, release. Any safety limit aborts with a release.

use serde::{Deserialize, Serialize};
use slidetrack_core::{
    AXES, ActuatorCommand, ActuatorSpec, DeviceError, Finger, FingerMap, Phase, TactileSample, TimeNs,
};

use crate::gripper::{GripperControlConfig, GripperGrasp};
use crate::pi::{PiConfig, PiController};
use crate::reference::{GraspProfile, partition, partition_two_opposed};
use crate::safety::{AbortReason, SafetyConfig};
use crate::spike_gate::{ZSpikeGate, ZSpikeGateConfig};

/// Settings of the protocol that do not depend on the object (the
/// `[protocol]` table of a rig TOML; every field has a default).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProtocolSettings {
    /// Controller rate (Hz); the thesis ran at 100 Hz.
    pub control_rate_hz: f64,
    /// Duration of the baseline average with the hand open (s).
    pub zero_duration_s: f64,
    /// Voltage that closes a finger until contact (V).
    pub close_volts: f64,
    /// Baseline-subtracted z above which a finger touches (counts).
    pub contact_threshold_counts: f64,
    /// Longest time to reach contact (s).
    pub close_timeout_s: f64,
    /// Duration of the ramp from contact to the maximum grasp (s).
    pub ramp_duration_s: f64,
    /// Hold at the maximum before the cycles (s).
    pub settle_duration_s: f64,
    /// Duration of the release at the end (s).
    pub release_duration_s: f64,
    /// PI gains and limits, the same for every finger (voltage-driven hands).
    pub pi: PiConfig,
    /// The grasp on a position-controlled gripper.
    pub gripper: GripperControlConfig,
    /// Safety limits.
    pub safety: SafetyConfig,
    /// The gate of the z readings the grasp is regulated on, against
    /// isolated tactile spikes (during the ramp, the settling and the cycles).
    pub z_spike_gate: ZSpikeGateConfig,
}

impl Default for ProtocolSettings {
    fn default() -> Self {
        ProtocolSettings {
            control_rate_hz: 100.0,
            zero_duration_s: 0.5,
            close_volts: 2.0,
            contact_threshold_counts: 60.0,
            close_timeout_s: 5.0,
            ramp_duration_s: 1.5,
            settle_duration_s: 2.0,
            release_duration_s: 0.5,
            pi: PiConfig::default(),
            gripper: GripperControlConfig::default(),
            safety: SafetyConfig::default(),
            z_spike_gate: ZSpikeGateConfig::default(),
        }
    }
}

/// Everything the protocol needs for one trial.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProtocolConfig {
    /// Settings of the rig.
    pub settings: ProtocolSettings,
    /// The grasp-strength reference of the cycles (per object).
    pub profile: GraspProfile,
    /// Abort when the marker shows the object further than this from its start (m; per object).
    pub travel_limit_m: f64,
    /// Duration of the sliding cycles (s).
    pub cycles_duration_s: f64,
}

/// A value per channel of every taxel (counts), `[taxel][x, y, z]`, taxels
/// in the order of the tactile source's layout: a baseline, or a scan minus it.
pub type Baseline = Vec<[f64; 3]>;

/// A new tactile baseline.
#[derive(Clone, Debug, PartialEq)]
pub struct Tare {
    /// Mean of the open-hand scans per channel (counts).
    pub baseline: Baseline,
    /// Number of scans averaged.
    pub scans: u32,
}

/// What the controller did at one control tick.
#[derive(Clone, Debug, PartialEq)]
pub struct ControlRecord {
    /// The phase.
    pub phase: Phase,
    /// Generalised grasp strength `tau_g,des` (counts).
    pub reference_counts: f64,
    /// Desired baseline-subtracted z per finger (counts), per (6.11).
    pub desired_counts: [f64; 3],
    /// Achieved baseline-subtracted z per finger (counts).
    pub achieved_counts: [f64; 3],
}

/// What the hand should do after a scan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HandAction {
    /// Nothing new.
    Hold,
    /// Send this command (voltages or a gripper request).
    Command(ActuatorCommand),
    /// Open the hand safely.
    Release,
}

/// A phase change or an abort, for the session's event channel.
#[derive(Clone, Debug, PartialEq)]
pub struct ProtocolEvent {
    /// The phase entered.
    pub phase: Phase,
    /// What happened.
    pub message: String,
    /// The reason, when this is an abort.
    pub abort: Option<AbortReason>,
}

/// Everything one scan produced.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ScanOutput {
    /// A new baseline, when zeroing just finished.
    pub tare: Option<Tare>,
    /// Baseline-subtracted channels (counts), once a baseline exists.
    pub zeroed: Option<Baseline>,
    /// The control tick, if one happened.
    pub control: Option<ControlRecord>,
    /// What the hand should do.
    pub action: Option<HandAction>,
    /// Phase changes and aborts.
    pub events: Vec<ProtocolEvent>,
}

/// What the controller drives.
enum Actuation {
    /// One PI voltage controller per finger (thumb, index, middle).
    Fingers([PiController; 3]),
    /// A parallel gripper: its pads are the thumb and index readings.
    Gripper(Box<GripperGrasp>),
}

impl Actuation {
    /// The fingers whose readings the controller uses.
    fn fingers(&self) -> &'static [usize] {
        match self {
            Actuation::Fingers(_) => &[0, 1, 2],
            Actuation::Gripper(_) => &[0, 1],
        }
    }

    /// What the hand does while the baseline is taken: nothing, open.
    fn idle(&self) -> ActuatorCommand {
        match self {
            Actuation::Fingers(_) => ActuatorCommand::FingerVolts([0.0; 3]),
            Actuation::Gripper(g) => g.approach(),
        }
    }
}

/// The protocol's state.
pub struct Protocol {
    cfg: ProtocolConfig,
    phase: Phase,
    phase_start: TimeNs,
    started: bool,
    fingers: FingerMap,
    /// The taxels a finger reads (the ones the saturation check watches),
    /// each once, with the first finger that reads it.
    watched: Vec<(usize, Finger)>,
    baseline_sum: Baseline,
    baseline_n: u32,
    baseline: Option<Baseline>,
    actuation: Actuation,
    touching: [bool; 3],
    above_threshold: [u32; 3],
    ramp_from_counts: f64,
    last_tick: Option<TimeNs>,
    /// Consecutive saturated scans per watched taxel and axis.
    saturated_scans: Vec<[u32; 3]>,
    abort: Option<AbortReason>,
    z_gate: ZSpikeGate,
}

impl Protocol {
    /// A protocol for a voltage-driven hand about to zero the baseline,
    /// reading each finger's tactile values through `fingers`.
    pub fn new(cfg: ProtocolConfig, fingers: FingerMap) -> Protocol {
        let max_volts = cfg.settings.pi.max_volts;
        Protocol::for_actuator(cfg, fingers, &ActuatorSpec::FingerVolts { max_volts })
    }

    /// A protocol for the hand `actuator` describes: one PI voltage law per
    /// finger, or, on a gripper, one PI law on the position request whose
    /// pads are the thumb and index readings.
    pub fn for_actuator(cfg: ProtocolConfig, fingers: FingerMap, actuator: &ActuatorSpec) -> Protocol {
        let actuation = match actuator {
            ActuatorSpec::FingerVolts { .. } => {
                Actuation::Fingers([0, 1, 2].map(|_| PiController::new(cfg.settings.pi.clone())))
            }
            ActuatorSpec::Gripper(spec) => {
                Actuation::Gripper(Box::new(GripperGrasp::new(cfg.settings.gripper.clone(), spec.clone())))
            }
        };
        let mut watched: Vec<(usize, Finger)> = Vec::new();
        for f in Finger::ALL {
            for taxel in fingers.taxels(f) {
                if !watched.iter().any(|(t, _)| *t == taxel) {
                    watched.push((taxel, f));
                }
            }
        }
        Protocol {
            z_gate: ZSpikeGate::new(cfg.settings.z_spike_gate.clone()),
            cfg,
            phase: Phase::Zero,
            phase_start: TimeNs::ZERO,
            started: false,
            saturated_scans: vec![[0; 3]; watched.len()],
            fingers,
            watched,
            baseline_sum: Vec::new(),
            baseline_n: 0,
            baseline: None,
            actuation,
            touching: [false; 3],
            above_threshold: [0; 3],
            ramp_from_counts: 0.0,
            last_tick: None,
            abort: None,
        }
    }

    /// The current phase.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// The settings.
    pub fn config(&self) -> &ProtocolConfig {
        &self.cfg
    }

    /// Why the trial was aborted, if it was.
    pub fn abort_reason(&self) -> Option<&AbortReason> {
        self.abort.as_ref()
    }

    /// True once the trial is over (done or aborted).
    pub fn finished(&self) -> bool {
        matches!(self.phase, Phase::Done | Phase::Aborted)
    }

    /// Seconds since the current phase began.
    fn in_phase_s(&self, t: TimeNs) -> f64 {
        t.secs_since(self.phase_start)
    }

    fn enter(&mut self, phase: Phase, t: TimeNs, message: String, out: &mut ScanOutput) {
        self.phase = phase;
        self.phase_start = t;
        out.events.push(ProtocolEvent { phase, message, abort: None });
    }

    /// Aborts the trial (idempotent); the caller releases the hand.
    pub fn abort(&mut self, reason: AbortReason) -> Option<ProtocolEvent> {
        if self.finished() {
            return None;
        }
        let message = format!("aborted in phase {}: {reason}", self.phase.name());
        self.phase = Phase::Aborted;
        self.abort = Some(reason.clone());
        Some(ProtocolEvent { phase: Phase::Aborted, message, abort: Some(reason) })
    }

    /// A device failed: abort.
    pub fn device_error(&mut self, error: DeviceError) -> Option<ProtocolEvent> {
        self.abort(AbortReason::Device(error))
    }

    /// A marker position along the sliding axis (m), or `None` when the
    /// marker was not seen. Aborts beyond the travel limit, except during the
    /// final release.
    pub fn on_marker(&mut self, position_on_axis_m: Option<f64>) -> Option<ProtocolEvent> {
        let travel_m = position_on_axis_m?;
        // Once the hand opens the object is let go on purpose.
        if self.phase == Phase::Release {
            return None;
        }
        let limit_m = self.cfg.travel_limit_m;
        if travel_m.abs() > limit_m {
            return self.abort(AbortReason::TravelLimit { travel_m, limit_m });
        }
        None
    }

    /// Checks the age of the newest scan at session time `now`.
    pub fn check_data_age(&mut self, now: TimeNs, newest_scan: TimeNs) -> Option<ProtocolEvent> {
        let age_s = now.secs_since(newest_scan);
        let limit_s = self.cfg.settings.safety.max_data_age_s;
        if age_s > limit_s {
            return self.abort(AbortReason::StaleData { age_s, limit_s });
        }
        None
    }

    fn check_saturation(&mut self, sample: &TactileSample) -> Option<AbortReason> {
        let margin = self.cfg.settings.safety.saturation_margin_counts;
        for ((taxel, finger), n) in self.watched.iter().zip(&mut self.saturated_scans) {
            let Some(v) = sample.raw.get(*taxel) else { continue };
            for (a, axis) in AXES.into_iter().enumerate() {
                n[a] = if v[a] <= margin || v[a] >= u16::MAX - margin { n[a] + 1 } else { 0 };
                if n[a] >= self.cfg.settings.safety.saturation_scans {
                    return Some(AbortReason::Saturated { finger: *finger, axis, counts: v[a], scans: n[a] });
                }
            }
        }
        None
    }

    /// A scan that does not hold the taxels the baseline was taken over.
    fn check_size(&self, sample: &TactileSample) -> Option<AbortReason> {
        let expected = self.baseline.as_ref().map_or(self.baseline_sum.len(), Vec::len);
        let needed = self.watched.iter().map(|(t, _)| t + 1).max().unwrap_or(0);
        let got = sample.raw.len();
        if got < needed || (expected > 0 && got != expected) {
            let expected = expected.max(needed);
            return Some(AbortReason::Device(DeviceError::new(
                slidetrack_core::ErrorKind::Corrupt,
                "tactile",
                format!("a scan of {got} taxels where the layout has {expected}"),
            )));
        }
        None
    }

    /// Readings of the grasp controller held by its spike gate so far.
    pub fn z_readings_held(&self) -> u64 {
        self.z_gate.held_total()
    }

    /// Processes one tactile scan.
    pub fn on_tactile(&mut self, sample: &TactileSample) -> ScanOutput {
        let mut out = ScanOutput::default();
        if self.finished() {
            return out;
        }
        let t = sample.t;
        if !self.started {
            self.started = true;
            self.phase_start = t;
            out.events.push(ProtocolEvent {
                phase: Phase::Zero,
                message: "zeroing the tactile baseline with the hand open".into(),
                abort: None,
            });
            out.action = Some(HandAction::Command(self.actuation.idle()));
        }
        if let Some(reason) = self.check_size(sample).or_else(|| self.check_saturation(sample)) {
            out.events.extend(self.abort(reason));
            out.action = Some(HandAction::Release);
            return out;
        }
        if self.phase == Phase::Zero {
            self.accumulate_baseline(sample, t, &mut out);
            return out;
        }
        let Some(baseline) = &self.baseline else { return out };
        let zeroed: Baseline =
            sample.raw.iter().zip(baseline).map(|(v, b)| [0, 1, 2].map(|a| f64::from(v[a]) - b[a])).collect();
        let readings = self.fingers.read(&zeroed);
        out.zeroed = Some(zeroed);
        let due = match self.last_tick {
            None => true,
            Some(last) => t.secs_since(last) >= 0.999 / self.cfg.settings.control_rate_hz,
        };
        if due {
            let dt_s =
                self.last_tick.map_or(1.0 / self.cfg.settings.control_rate_hz, |last| t.secs_since(last));
            self.last_tick = Some(t);
            let z = readings.into_array().map(|r| r[2]);
            self.control_tick(t, z, dt_s, &mut out);
        }
        out
    }

    fn accumulate_baseline(&mut self, sample: &TactileSample, t: TimeNs, out: &mut ScanOutput) {
        self.baseline_sum.resize(sample.raw.len(), [0.0; 3]);
        for (sum, v) in self.baseline_sum.iter_mut().zip(&sample.raw) {
            for a in 0..3 {
                sum[a] += f64::from(v[a]);
            }
        }
        self.baseline_n += 1;
        if self.in_phase_s(t) >= self.cfg.settings.zero_duration_s {
            let n = f64::from(self.baseline_n);
            let baseline: Baseline = self.baseline_sum.iter().map(|s| s.map(|v| v / n)).collect();
            self.baseline = Some(baseline.clone());
            out.tare = Some(Tare { baseline, scans: self.baseline_n });
            let msg = format!("baseline from {} scans; closing until contact", self.baseline_n);
            self.enter(Phase::Close, t, msg, out);
        }
    }

    fn control_tick(&mut self, t: TimeNs, z: [f64; 3], dt_s: f64, out: &mut ScanOutput) {
        // The grasp is regulated on gated readings; contact is found on raw ones.
        let z = if matches!(self.phase, Phase::Ramp | Phase::Settle | Phase::Cycles) {
            self.z_gate.filter(z)
        } else {
            self.z_gate.reset();
            z
        };
        let threshold = self.cfg.settings.contact_threshold_counts;
        let (reference, desired, command) = match self.phase {
            Phase::Close => match self.close_tick(t, z, dt_s, out) {
                Some(command) => (threshold, [threshold; 3], command),
                None => return,
            },
            Phase::Ramp | Phase::Settle | Phase::Cycles => {
                let reference = self.grasp_reference(t, out);
                if self.phase == Phase::Release {
                    out.action = Some(HandAction::Release);
                    return;
                }
                let used = self.actuation.fingers();
                if matches!(self.phase, Phase::Settle | Phase::Cycles)
                    && used.iter().all(|&f| z[f] < 0.5 * threshold)
                {
                    out.events.extend(self.abort(AbortReason::ContactLost));
                    out.action = Some(HandAction::Release);
                    return;
                }
                let (desired, command) = match &mut self.actuation {
                    Actuation::Fingers(pi) => {
                        let desired = partition(reference);
                        let volts = [0, 1, 2].map(|f| pi[f].step(desired[f] - z[f], dt_s).value);
                        (desired, ActuatorCommand::FingerVolts(volts))
                    }
                    Actuation::Gripper(g) => {
                        let desired = partition_two_opposed(reference);
                        let achieved = 0.5 * (z[0] + z[1]);
                        (desired, g.grasp(reference - achieved, dt_s))
                    }
                };
                (reference, desired, command)
            }
            Phase::Release => {
                if self.in_phase_s(t) >= self.cfg.settings.release_duration_s {
                    self.enter(Phase::Done, t, "trial complete".into(), out);
                }
                return;
            }
            Phase::Zero | Phase::Done | Phase::Aborted => return,
        };
        out.control = Some(ControlRecord {
            phase: self.phase,
            reference_counts: reference,
            desired_counts: desired,
            achieved_counts: z,
        });
        out.action = Some(HandAction::Command(command));
    }

    /// One tick of closing until every finger the controller uses touches:
    /// the command, or `None` when the trial aborted (no contact in time).
    fn close_tick(
        &mut self,
        t: TimeNs,
        z: [f64; 3],
        dt_s: f64,
        out: &mut ScanOutput,
    ) -> Option<ActuatorCommand> {
        let c = &self.cfg.settings;
        let threshold = c.contact_threshold_counts;
        let used = self.actuation.fingers();
        for &f in used {
            // Two ticks in a row, so that a single spike is not a touch.
            self.above_threshold[f] = if z[f] >= threshold { self.above_threshold[f] + 1 } else { 0 };
            if !self.touching[f] && self.above_threshold[f] >= 2 {
                self.touching[f] = true;
                if let Actuation::Fingers(pi) = &mut self.actuation {
                    pi[f].reset_to(c.close_volts * 0.5);
                }
            }
        }
        let all_touch = used.iter().all(|&f| self.touching[f]);
        let command = match &mut self.actuation {
            Actuation::Fingers(pi) => ActuatorCommand::FingerVolts([0, 1, 2].map(|f| {
                if self.touching[f] { pi[f].step(threshold - z[f], dt_s).value } else { c.close_volts }
            })),
            Actuation::Gripper(g) => g.close(all_touch, dt_s),
        };
        if all_touch {
            self.ramp_from_counts = 2.0 * threshold;
            self.enter(Phase::Ramp, t, "every finger touches; raising the grasp".into(), out);
        } else if self.in_phase_s(t) > c.close_timeout_s {
            let timeout_s = c.close_timeout_s;
            let fingers = used.iter().filter(|&&f| !self.touching[f]).map(|&f| Finger::ALL[f]).collect();
            out.events.extend(self.abort(AbortReason::NoContact { fingers, timeout_s }));
            out.action = Some(HandAction::Release);
            return None;
        }
        Some(command)
    }

    /// The grasp-strength reference now, moving through ramp, settle and
    /// cycles as their durations pass.
    fn grasp_reference(&mut self, t: TimeNs, out: &mut ScanOutput) -> f64 {
        let max = self.cfg.profile.max_counts;
        if self.phase == Phase::Ramp {
            let s = (self.in_phase_s(t) / self.cfg.settings.ramp_duration_s).clamp(0.0, 1.0);
            let smooth = s * s * (3.0 - 2.0 * s);
            if s < 1.0 {
                return self.ramp_from_counts + (max - self.ramp_from_counts) * smooth;
            }
            self.enter(Phase::Settle, t, "maximum grasp reached; settling".into(), out);
        }
        if self.phase == Phase::Settle {
            if self.in_phase_s(t) < self.cfg.settings.settle_duration_s {
                return max;
            }
            let msg = format!("sliding cycles for {} s", self.cfg.cycles_duration_s);
            self.enter(Phase::Cycles, t, msg, out);
        }
        let in_cycles = self.in_phase_s(t);
        if in_cycles >= self.cfg.cycles_duration_s {
            self.enter(Phase::Release, t, "cycles complete; releasing".into(), out);
            return max;
        }
        self.cfg.profile.at(in_cycles)
    }
}
