//! One or two messages of every channel that [`EveryChannel`] leaves out
//! (decoder counters, calibrated forces, device times, ground truth, estimates, RGB-D and vision tracking),
//! so that a test can record a message of every channel of [`channel_specs`].

use std::collections::BTreeMap;

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use slidetrack_core::DepthImage;

use super::*;
use crate::odometry::{MaskUkfOdometry, Odometry, RoftOdometry};
use crate::vision_pose::{
    MaskUkfPose, MaskUkfTransform, MaskUkfVelocity, RoftPose, RoftTransform, RoftVelocity,
};

fn pose(k: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(0.125 * k, -0.25, 0.5),
        UnitQuaternion::from_euler_angles(0.1 * k, 0.2, -0.3),
    )
}

fn sliding(k: f64) -> SlidingEstimate {
    SlidingEstimate { position: 0.001 * k, velocity: -0.01, covariance: [[1e-8, 1e-9], [1e-9, 1e-6]] }
}

fn velocity(k: f64) -> VelocityEstimate {
    VelocityEstimate {
        frame_id: "camera".into(),
        linear_velocity_mps: [0.01 * k, 0.0, -0.02],
        angular_velocity_radps: [0.0, 0.1, 0.2 * k],
    }
}

fn odometry(child: &str, k: f64) -> Odometry {
    let covariance: Vec<f64> = (0..36).map(|i| if i % 7 == 0 { 1e-6 * k.max(1.0) } else { 0.0 }).collect();
    Odometry {
        frame_id: "camera".into(),
        child_frame_id: child.into(),
        position_m: [0.1 * k, -0.2, 0.6],
        orientation: Quaternion { x: 0.0, y: 0.6, z: 0.0, w: 0.8 },
        pose_covariance: covariance.clone(),
        linear_velocity_in_child_mps: [0.01, 0.0, -0.02 * k],
        angular_velocity_in_child_radps: [0.0, 0.1 * k, 0.2],
        twist_covariance: covariance,
    }
}

/// Logs `message` on its channel at `t`.
fn log_one<T: ChannelMessage>(rec: &Recorder, t: TimeNs, message: T) {
    let channel = rec.register::<T>(BTreeMap::new()).unwrap();
    rec.log_json(&channel, t, t, 0, &message).unwrap();
}

/// Logs the in-hand channels (planar and pose truth, planar estimate, slip
/// estimate) at `t`, message `i` of two (`k` = `i` as a number).
fn log_in_hand(rec: &Recorder, t: TimeNs, i: u64, k: f64) {
    let planar = PlanarState {
        translation_m: [0.001 * k, -0.002],
        rotation_rad: 0.03 * k,
        velocity_m_per_s: [0.01, 0.0],
        angular_velocity_rad_per_s: -0.1,
    };
    log_one(rec, t, GroundTruthPlanar(planar));
    log_one(
        rec,
        t,
        GroundTruthPose {
            position_in_hand_m: [0.01, -0.02, 0.2 + 0.001 * k],
            orientation_in_hand: Quaternion { x: 0.0, y: 0.0, z: 0.0, w: 1.0 },
            velocity_in_hand_m_per_s: [0.0, 0.001, 0.0],
            angular_velocity_in_hand_rad_per_s: [0.1, 0.0, 0.0],
            std: [1e-4; 12],
        },
    );
    log_one(rec, t, PlanarEstimate { state: planar, covariance: vec![1e-6; 36] });
    let state = if i == 0 { GraspStateName::Holding } else { GraspStateName::Dropped };
    log_one(
        rec,
        t,
        SlipEstimate { state, load: 5000.0 - 4900.0 * k, load_ratio: 1.0 - 0.98 * k, slip_score: 0.5 },
    );
}

/// Logs two messages on `rec` on every channel not in [`EveryChannel`].
pub(super) fn log_other_channels(rec: &Recorder) {
    for i in 0..2 {
        let k = i as f64;
        let t = t_ms(2 * i);
        let counters =
            TactileDecoder { frames: 100 + i, crc_errors: i, gaps: 2, ..TactileDecoder::default() };
        log_one(rec, t, counters);
        let force = |f: f64| Xyz { x: 0.125 * f, y: -0.25, z: 1.5 + k };
        let sensors = vec![SensorValues { name: "left".into(), taxels: vec![force(1.0), force(2.0)] }];
        log_one(rec, t, TactileReference { sequence: 7 + i, sensors: sensors.clone() });
        log_one(rec, t, TactileCalibrated { sequence: 7 + i, sensors });
        log_one(rec, t, TactileDeviceTime { sequence: 7 + i, device_time_s: 1_768_296_808.5 + 0.01 * k });
        let truth = GroundTruthSliding {
            position: 0.001 * k,
            velocity: 0.02,
            covariance: [[1e-8, 0.0], [0.0, 1e-6]],
        };
        log_one(rec, t, truth);
        log_one(rec, t, GroundTruthMeasurement { position: 0.002, rejected: i == 1, mahalanobis2: 0.5 });
        log_one(
            rec,
            t,
            HandState { finger_travel: vec![0.001 * k, 0.002, 0.0], opening: Some(0.05), gripper: None },
        );
        let gripper = GripperState {
            activated: true,
            object: 2,
            fault: 0,
            requested: 140 + i as u16,
            position: 138,
            current_ma: 250,
        };
        log_one(
            rec,
            t,
            HandState { finger_travel: vec![0.01, 0.01], opening: Some(0.04), gripper: Some(gripper) },
        );
        log_one(rec, t, GripperCommand { position: 140 + i as u16, speed: 128, force: 64, clamped: i == 1 });
        log_one(rec, t, TactileDerivative { values: vec![1.5, -2.25, 0.0, k] });
        log_one(rec, t, DekfEstimate(sliding(k)));
        log_in_hand(rec, t, i, k);
        log_one(rec, t, ArucoEstimate(sliding(k + 1.0)));

        let jpeg = EncodedImage { format: "jpeg".into(), bytes: vec![0xFF, 0xD8, i as u8, 0xFF, 0xD9] };
        log_one(rec, t, RgbdColor(CompressedImage::new(t, "camera", &jpeg)));
        let depth = DepthImage { width: 2, height: 2, data: vec![0, 1000, 2000, 65535], scale_m: 0.001 };
        log_one(rec, t, RgbdDepth::new(t, "camera", &depth).unwrap());
        log_one(rec, t, RgbdCalibration(CameraCalibration::new(t, "camera", &intrinsics())));
        let mask = RawImage::mask(t, "camera", 2, 2, &[0, 1, 1, 0]);
        log_one(rec, t, RgbdMask(mask.clone()));
        log_one(rec, t, VisionMask(mask));
        let object = ObjectTruth {
            position_m: [0.1, -0.2, 0.6],
            orientation: Quaternion { x: 0.0, y: 0.0, z: 0.0, w: 1.0 },
            linear_velocity_mps: [0.0, 0.01 * k, 0.0],
            angular_velocity_radps: [0.0, 0.0, 0.5],
        };
        log_one(rec, t, object);
        log_one(rec, t, VisionPose(PoseInFrame::new(t, "camera", &pose(k))));
        log_one(rec, t, MaskUkfPose(PoseInFrame::new(t, "camera", &pose(k + 1.0))));
        log_one(rec, t, RoftPose(PoseInFrame::new(t, "camera", &pose(k + 2.0))));
        let transform = |child, k| FrameTransform::new(t, "camera", child, &pose(k));
        log_one(rec, t, MaskUkfTransform(transform("object/maskukf", k)));
        log_one(rec, t, RoftTransform(transform("object/roft", k + 1.0)));
        log_one(rec, t, MaskUkfVelocity(velocity(k)));
        log_one(rec, t, RoftVelocity(velocity(k + 1.0)));
        log_one(rec, t, MaskUkfOdometry(odometry("object/maskukf", k)));
        log_one(rec, t, RoftOdometry(odometry("object/roft", k + 1.0)));
    }
}
