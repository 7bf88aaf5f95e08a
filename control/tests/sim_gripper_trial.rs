//! Controlled-sliding trials on the simulated parallel gripper of the rig
//! TOML example `docs/examples/gripper-rig.toml` (`[sim] hand = "gripper"`),
//! end to end through the protocol's gripper mode and the runner (no
//! camera, no recording).

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use serde::Deserialize;
use slidetrack_control::{
    Baseline, ControlRecord, GraspProfile, ObserverError, Protocol, ProtocolConfig, ProtocolEvent,
    ProtocolSettings, Rig, Tare, TrialObserver, TrialOutcome, run_trial,
};
use slidetrack_core::{
    ActuatorCommand, Frame, HandActuator, Phase, SimClock, SimTruth, TactileSample, TactileSource, TimeNs,
};
use slidetrack_sim::{HandKind, ObjectConfig, SimDevices, SimRigConfig, sliding_episodes};

/// The `[sim]` and `[protocol]` tables of a rig TOML (the other tables are
/// the experiment crate's).
#[derive(Deserialize)]
struct RigTables {
    #[serde(default)]
    sim: SimRigConfig,
    #[serde(default)]
    protocol: ProtocolSettings,
}

/// The rig TOML example of the gripper.
fn example_rig() -> RigTables {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/examples/gripper-rig.toml");
    let text = std::fs::read_to_string(path).expect("the gripper rig example");
    slidetrack_core::parse_toml(&text, path).expect("the gripper rig example parses")
}

#[test]
fn the_example_sets_the_defaults_of_a_gripper() {
    let rig = example_rig();
    assert_eq!(rig.sim, SimRigConfig { hand: HandKind::Gripper, ..SimRigConfig::default() });
    assert_eq!(rig.protocol, ProtocolSettings::default());
}

#[derive(Default)]
struct Collected {
    truth: Vec<SimTruth>,
    requests: Vec<ActuatorCommand>,
    release: Option<TimeNs>,
}

impl TrialObserver for Collected {
    fn on_tactile(&mut self, _: &TactileSample) -> Result<(), ObserverError> {
        Ok(())
    }
    fn on_truth(&mut self, t: &SimTruth) -> Result<(), ObserverError> {
        self.truth.push(*t);
        Ok(())
    }
    fn on_tare(&mut self, _: TimeNs, _: &Tare) -> Result<(), ObserverError> {
        Ok(())
    }
    fn on_zeroed(&mut self, _: TimeNs, _: &Baseline) -> Result<(), ObserverError> {
        Ok(())
    }
    fn on_control(&mut self, _: TimeNs, _: &ControlRecord) -> Result<(), ObserverError> {
        Ok(())
    }
    fn on_command(&mut self, _: TimeNs, c: &ActuatorCommand, _: bool) -> Result<(), ObserverError> {
        self.requests.push(*c);
        Ok(())
    }
    fn on_frame(&mut self, _: Frame) -> Result<Option<f64>, ObserverError> {
        Ok(None)
    }
    fn on_event(&mut self, t: TimeNs, e: &ProtocolEvent) -> Result<(), ObserverError> {
        if e.phase == Phase::Release && self.release.is_none() {
            self.release = Some(t);
        }
        Ok(())
    }
}

/// A trial of `object` on the gripper rig of the example.
fn run(object: &str, seed: u64, trial: u32, duration_s: f64) -> (TrialOutcome, Collected) {
    let obj = ObjectConfig::load(object).expect("a built-in object");
    let RigTables { sim: mut cfg, protocol: settings } = example_rig();
    // Tuning aid: the pads' indentation at 1 N (mm).
    if let Some(mm) = std::env::var("PAD_MM").ok().and_then(|v| v.parse::<f64>().ok()) {
        cfg.gripper.pad_contact_stiffness_n_per_m15 = 1.0 / (mm * 1e-3f64).powf(1.5);
    }
    let clock = Arc::new(SimClock::new());
    let sim = SimDevices::new(&cfg, &obj, seed, trial, clock.clone());
    let fingers = sim.tactile.info().finger_map().expect("the gripper layout resolves");
    let spec = sim.hand.spec();
    let mut rig = Rig {
        tactile: Box::new(sim.tactile),
        hand: Box::new(sim.hand),
        camera: None,
        clock,
        truth: Some(Box::new(sim.truth)),
        hand_monitor: None,
    };
    let e = &obj.experiment;
    let profile = GraspProfile {
        max_counts: e.grasp_max_counts,
        min_counts: e.grasp_min_counts,
        period_s: e.period_s,
        sharpness: e.sharpness,
    };
    let config =
        ProtocolConfig { settings, profile, travel_limit_m: e.travel_limit_m, cycles_duration_s: duration_s };
    let mut protocol = Protocol::for_actuator(config, fingers, &spec);
    let mut seen = Collected::default();
    let outcome = run_trial(&mut rig, &mut protocol, &mut seen, &AtomicBool::new(false));
    (outcome, seen)
}

/// Sliding episodes, travel (m) and whether the trial completed with the
/// object still held at the release.
fn summary(object: &str, seed: u64, trial: u32) -> (usize, f64, bool) {
    let (outcome, seen) = run(object, seed, trial, 60.0);
    let release = seen.release.unwrap_or(TimeNs(u64::MAX));
    let track: Vec<_> = seen
        .truth
        .iter()
        .filter(|t| t.t < release)
        .map(|t| (t.t.as_secs_f64(), t.position_m, t.velocity_mps))
        .collect();
    let eps = sliding_episodes(&track, 1e-3, 0.5, 5e-4);
    if std::env::var("SLIDETRACK_DEBUG").is_ok() {
        for t in seen.truth.iter().step_by(100) {
            eprintln!(
                "{:.1} p {:.4} sup {} n {:.3?}",
                t.t.as_secs_f64(),
                t.position_m,
                t.supported,
                t.normal_n
            );
        }
    }
    let last = seen.truth.iter().rfind(|t| t.t < release).expect("truth before the release");
    let held = outcome.completed && !last.dropped && !last.supported;
    eprintln!(
        "gripper {object} seed {seed} trial {trial}: completed {} abort {:?}, {} episodes, travel {:.2} cm, \
         travel per episode {:?}",
        outcome.completed,
        outcome.abort.as_ref().map(|a| a.to_string()),
        eps.len(),
        last.position_m * 100.0,
        eps.iter().map(|e| (e.travel_m * 1000.0).round() / 10.0).collect::<Vec<_>>()
    );
    (eps.len(), last.position_m, held)
}

#[test]
fn a_minute_on_the_gripper_slides_in_stick_slip_episodes_and_keeps_the_object() {
    for object in ["box", "bottle", "mustard"] {
        for (seed, trial) in [(1, 0), (2, 3)] {
            let (episodes, travel, held) = summary(object, seed, trial);
            assert!(held, "gripper {object} seed {seed} trial {trial}: the object was not held to the end");
            assert!(episodes >= 4, "gripper {object} seed {seed} trial {trial}: {episodes} sliding episodes");
            assert!(
                (0.005..=0.10).contains(&travel),
                "gripper {object} seed {seed} trial {trial}: travel {travel} m"
            );
        }
    }
}

#[test]
fn the_gripper_is_commanded_in_whole_position_steps_only() {
    let (outcome, seen) = run("box", 5, 0, 10.0);
    assert!(outcome.completed, "{outcome:?}");
    assert!(!seen.requests.is_empty());
    assert!(seen.requests.iter().all(|c| matches!(c, ActuatorCommand::Gripper(_))), "gripper requests only");
}

/// Sweeps trials of one object on the gripper (tuning aid).
#[test]
#[ignore = "a tuning aid: [PAD_MM=1.3] [SLIDETRACK_DEBUG=1] SLIDETRACK_OBJECT=box cargo test --test sim_gripper_trial -- --ignored sweep --nocapture"]
fn sweep_gripper_trials() {
    let object = std::env::var("SLIDETRACK_OBJECT").unwrap_or_else(|_| "box".into());
    for seed in 1..4 {
        for trial in 0..4 {
            summary(&object, seed, trial);
        }
    }
}
