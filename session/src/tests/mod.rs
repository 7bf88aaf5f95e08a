//! Tests of the session module, and the fixtures they share.

mod bad_input;
mod errors;
mod image_json;
mod kill;
mod live_tap;
mod other_channels;
mod pending;
mod python;
mod queue;
mod read_all;
mod read_all_body;
mod records;
mod roundtrip;
mod schema_validation;
mod schemas;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};

use slidetrack_core::{CameraIntrinsics, EncodedImage, Finger, PerFinger, Phase, TimeNs};

use super::*;
// The crate under the name `read_all_body` expects of its parent, as the
// fuzz target names it.
use crate as session;

/// A fresh directory under the system temp dir, removed on drop.
pub(super) struct TestDir(PathBuf);

impl TestDir {
    pub(super) fn new(name: &str) -> TestDir {
        static COUNTER: AtomicU32 = AtomicU32::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("slidetrack-session-{name}-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TestDir(dir)
    }

    pub(super) fn file(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    pub(super) fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TestDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The `slidetrack` metadata of the test sessions.
pub(super) fn session_metadata() -> SessionMetadata {
    SessionMetadata {
        software_version: "0.1.0-test".into(),
        rig: "sim".into(),
        rig_config: "[tactile]\nrate_hz = 1000.0\n".into(),
        object: "box".into(),
        object_config: "mass_kg = 0.2\n".into(),
        trial: "t001".into(),
        seed: 42,
        started_at: "2026-11-21T06:03:07Z".into(),
    }
}

/// The `i`-th tactile scan of the test sessions: values that are exact in JSON.
pub(super) fn raw(i: u64) -> TactileRaw {
    let base = (i * 7 % 60_000) as u16;
    TactileRaw {
        sequence: i,
        sensors: Finger::ALL
            .iter()
            .map(|f| {
                let k = f.index() as u16;
                let taxels = vec![Xyz { x: base + k, y: base / 2 + k, z: u16::MAX - base - k }];
                SensorValues { name: f.name().to_string(), taxels }
            })
            .collect(),
    }
}

pub(super) fn t_ms(i: u64) -> TimeNs {
    TimeNs(i * 1_000_000)
}

pub(super) fn intrinsics() -> CameraIntrinsics {
    CameraIntrinsics {
        width: 640,
        height: 480,
        fx: 600.5,
        fy: 601.25,
        cx: 320.0,
        cy: 240.75,
        distortion: [0.125, -0.25, 0.001953125, -0.0009765625, 0.0625],
    }
}

/// One message of every channel type, as written by [`record_every_channel`].
#[derive(Clone, Debug, PartialEq)]
pub(super) struct EveryChannel {
    pub raw: Vec<(TimeNs, TactileRaw)>,
    pub tare: Vec<(TimeNs, TactileTare)>,
    pub zeroed: Vec<(TimeNs, TactileZeroed)>,
    pub grasp: Vec<(TimeNs, GraspControl)>,
    pub hand: Vec<(TimeNs, HandCommand)>,
    pub image: Vec<(TimeNs, CompressedImage)>,
    pub calibration: Vec<(TimeNs, CameraCalibration)>,
    pub aruco: Vec<(TimeNs, ArucoDetection)>,
    pub truth: Vec<(TimeNs, SimTruth)>,
    pub events: Vec<(TimeNs, ProtocolEvent)>,
}

/// `raw` minus the (single-taxel) baseline of each sensor.
fn minus(raw: &[SensorValues<u16>], baseline: &[SensorValues<f64>]) -> SensorTaxels<f64> {
    raw.iter()
        .zip(baseline)
        .map(|(raw, base)| {
            let b = base.taxels[0];
            let taxels = raw
                .taxels
                .iter()
                .map(|c| Xyz { x: f64::from(c.x) - b.x, y: f64::from(c.y) - b.y, z: f64::from(c.z) - b.z })
                .collect();
            SensorValues { name: raw.name.clone(), taxels }
        })
        .collect()
}

impl EveryChannel {
    /// `n` steps of a plausible trial on every channel.
    pub(super) fn new(n: u64) -> EveryChannel {
        let mut e = EveryChannel {
            raw: vec![],
            tare: vec![],
            zeroed: vec![],
            grasp: vec![],
            hand: vec![],
            image: vec![],
            calibration: vec![(TimeNs::ZERO, CameraCalibration::from(&intrinsics()))],
            aruco: vec![],
            truth: vec![],
            events: vec![(
                TimeNs::ZERO,
                ProtocolEvent { phase: Phase::Zero, message: "zeroing, \"hands off\"".into(), abort: false },
            )],
        };
        let baseline: SensorTaxels<f64> = Finger::ALL
            .iter()
            .map(|f| SensorValues {
                name: f.name().to_string(),
                taxels: vec![Xyz { x: 100.5, y: 200.25, z: 300.0 + f.index() as f64 }],
            })
            .collect();
        e.tare.push((t_ms(0), TactileTare { samples: 50, baseline: baseline.clone() }));
        for i in 0..n {
            let t = t_ms(i);
            let r = raw(i);
            let zeroed = minus(&r.sensors, &baseline);
            e.raw.push((t, r));
            e.zeroed.push((t, TactileZeroed { sensors: zeroed }));
            let fingers = PerFinger::from_fn(|f| FingerSetpoint {
                desired: 500.0 + i as f64,
                achieved: 499.5 + i as f64 - f.index() as f64,
            });
            let phase = if i < n / 2 { Phase::Settle } else { Phase::Cycles };
            e.grasp.push((t, GraspControl { phase, reference: 1500.25, fingers }));
            let volts = PerFinger::from_fn(|f| 1.5 + 0.25 * f.index() as f64);
            e.hand.push((t, HandCommand { volts, saturated: i % 5 == 0 }));
            let force = PerFinger::from_fn(|f: Finger| 2.0 + f.index() as f64);
            e.truth.push((
                t,
                SimTruth {
                    position: -(i as f64) / 1024.0,
                    velocity: -0.01,
                    sliding: i >= n / 2,
                    supported: i == 0,
                    normal_force: force,
                    friction_force: force.map(|v| v * 0.5),
                },
            ));
            if i % 10 == 0 {
                let jpeg =
                    EncodedImage { format: "jpeg".into(), bytes: vec![0xFF, 0xD8, i as u8, 0xFF, 0xD9] };
                e.image.push((t, CompressedImage::new(t, "camera", &jpeg)));
                let detection = if i % 20 == 0 {
                    ArucoDetection::missed()
                } else {
                    ArucoDetection {
                        detected: true,
                        marker_id: Some(7),
                        corners_px: Some([[10.5, 20.0], [30.0, 20.25], [30.0, 40.0], [10.0, 40.5]]),
                        position_in_camera_m: Some([0.0625, -0.125, 0.5]),
                        orientation_in_camera: Some(Quaternion { x: 0.0, y: 0.0, z: 0.0, w: 1.0 }),
                        position_on_axis_m: Some(-(i as f64) / 1024.0),
                        reprojection_error_px: Some(0.375),
                    }
                };
                e.aruco.push((t, detection));
            }
        }
        e.events.push((
            t_ms(n),
            ProtocolEvent { phase: Phase::Done, message: "trial complete".into(), abort: false },
        ));
        e
    }

    /// Messages on all channels, not counting `/recorder/stats`.
    pub(super) fn message_count(&self) -> u64 {
        (self.raw.len()
            + self.tare.len()
            + self.zeroed.len()
            + self.grasp.len()
            + self.hand.len()
            + self.image.len()
            + self.calibration.len()
            + self.aruco.len()
            + self.truth.len()
            + self.events.len()) as u64
    }
}

pub(super) fn log_all<T: ChannelMessage>(
    rec: &Recorder,
    meta: BTreeMap<String, String>,
    msgs: &[(TimeNs, T)],
) {
    let ch = rec.register::<T>(meta).unwrap();
    for (i, (t, m)) in msgs.iter().enumerate() {
        rec.log_json(&ch, *t, *t, i as u32, m).unwrap();
    }
}

/// Records `e` to `path` (channel by channel), with an attachment and the outcome.
pub(super) fn record_every_channel(path: &Path, e: &EveryChannel, options: RecorderOptions) -> RecorderStats {
    record_every_channel_and(path, e, options, |_| {})
}

/// [`record_every_channel`], and whatever `more` records before the recording finishes.
pub(super) fn record_every_channel_and(
    path: &Path,
    e: &EveryChannel,
    options: RecorderOptions,
    more: impl FnOnce(&Recorder),
) -> RecorderStats {
    let rec = Recorder::create_with_options(path, session_metadata().to_map(), options).unwrap();
    rec.attach("camera.toml", "application/toml", b"fx = 600.5\n".to_vec()).unwrap();
    let layout = TaxelLayout::new(&slidetrack_core::TactileInfo::one_module_per_finger("sim", 1000.0, "sim"));
    log_all(&rec, layout.channel_metadata(), &e.raw);
    log_all(&rec, BTreeMap::new(), &e.tare);
    log_all(&rec, BTreeMap::new(), &e.zeroed);
    log_all(&rec, BTreeMap::new(), &e.grasp);
    log_all(&rec, BTreeMap::new(), &e.hand);
    log_all(&rec, BTreeMap::new(), &e.calibration);
    log_all(&rec, BTreeMap::new(), &e.aruco);
    log_all(&rec, BTreeMap::new(), &e.truth);
    log_all(&rec, BTreeMap::new(), &e.events);
    let images = rec.register::<CompressedImage>(BTreeMap::new()).unwrap();
    for (i, (t, m)) in e.image.iter().enumerate() {
        assert!(rec.log_json_lossy(&images, *t, *t, i as u32, m).unwrap());
    }
    more(&rec);
    rec.finish_with_outcome(true, None).unwrap()
}
