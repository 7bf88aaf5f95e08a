//! The trackers on simulated fast sequences (Fast-YCB-like speeds: up to
//! 60 cm/s and 270 deg/s), rendered at 320x240 to keep the tests quick (the
//! benchmark and `vision eval` use 640x480).

use slidetrack_estimators::metrics::{position_error_m, rotation_error_deg};
use slidetrack_experiment::vision_sim::{evaluate_variant, maskukf_on_sequence};
use slidetrack_sim::rgbd::{FastSequence, FastSequenceConfig, RgbdSceneConfig, SimObjectKind};
use slidetrack_vision::TrackerSettings;
use slidetrack_vision::eval::Variant;
use slidetrack_vision::sources::SlowNetworkConfig;

fn qvga(mut config: FastSequenceConfig) -> FastSequenceConfig {
    config.scene.intrinsics = RgbdSceneConfig::qvga_intrinsics();
    config
}

fn sequences() -> Vec<FastSequenceConfig> {
    [(SimObjectKind::CrackerBox, 11), (SimObjectKind::SoupCan, 12), (SimObjectKind::SugarBox, 13)]
        .into_iter()
        .map(|(kind, seed)| qvga(FastSequenceConfig::new(kind, 4.0, seed)))
        .collect()
}

#[test]
fn roft_beats_the_delayed_network_by_15_add_auc_points() {
    let network = SlowNetworkConfig::default();
    let settings = TrackerSettings::default();
    let roft = evaluate_variant(Variant::Roft, &sequences(), &network, &settings).unwrap();
    let alone = evaluate_variant(Variant::Network, &sequences(), &network, &settings).unwrap();
    println!("ROFT {:?}\nnetwork {:?}", roft.metrics, alone.metrics);
    assert_eq!(roft.metrics.frames, alone.metrics.frames);
    assert!(
        roft.metrics.add_auc_percent >= alone.metrics.add_auc_percent + 15.0,
        "ROFT {:.2} vs network {:.2}",
        roft.metrics.add_auc_percent,
        alone.metrics.add_auc_percent
    );
    assert!(roft.metrics.rotation_rmse_deg < alone.metrics.rotation_rmse_deg);
}

#[test]
fn maskukf_started_5_cm_and_10_degrees_off_converges() {
    // A box moving at YCB-Video-like speeds (MaskUKF's motion model and
    // Table 4.1 are tuned for them).
    let mut config = qvga(FastSequenceConfig::new(SimObjectKind::CrackerBox, 3.0, 21));
    config.motion.max_speed_mps = 0.15;
    config.motion.max_angular_speed_dps = 45.0;
    let first = FastSequence::new(config.clone()).unwrap().truth(0).camera_from_object;
    let (r, p, y) = first.rotation.euler_angles();
    let d = 10f64.to_radians();
    let start = nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::from(first.translation.vector + nalgebra::Vector3::new(0.05, 0.05, 0.05)),
        nalgebra::UnitQuaternion::from_euler_angles(r + d, p + d, y + d),
    );
    let (frames, _) = maskukf_on_sequence(&config, start, &TrackerSettings::default()).unwrap();
    let errors: Vec<(f64, f64)> = frames
        .iter()
        .map(|f| {
            let e = f.estimate.unwrap().camera_from_object;
            (
                position_error_m(&e, &f.truth.camera_from_object) * 100.0,
                rotation_error_deg(&e, &f.truth.camera_from_object),
            )
        })
        .collect();
    assert!(errors[0].0 > 5.0 && errors[0].1 > 5.0, "starts off: {:?}", errors[0]);
    for (k, (cm, deg)) in errors.iter().enumerate().skip(60) {
        assert!(*cm < 1.0 && *deg < 5.0, "frame {k}: {cm:.2} cm, {deg:.2} deg");
    }
}
