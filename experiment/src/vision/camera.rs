//! The `[rgbd]` camera of a rig TOML opened for a live run: two V4L2 nodes
//! or a recording standing in for them, paired and registered by one
//! [`CameraPair`].

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion};
use slidetrack_core::{Clock, parse_toml};
use slidetrack_drivers::rgbd_config::{DepthToColor, RecordedRgbdConfig, ReplayPace, RgbdCameraConfig};
use slidetrack_vision::input::{CameraPair, DepthRegistration, PairSettings, RecordedRgbd, ReplayOptions};

/// A reporter of a camera's frame counts, for the end of a run.
type CountReport = Box<dyn Fn() -> String>;

/// The RGB-D camera of a live run.
pub struct LiveCamera {
    /// Colour and depth, paired and registered.
    pub pair: CameraPair,
    /// The recorded session replayed, if the camera is one, and its offset
    /// (session time minus recording time, ns).
    pub replay: Option<(PathBuf, i128)>,
    /// What each stream counted (frames delivered, dropped).
    reports: Vec<CountReport>,
}

impl LiveCamera {
    /// One line per stream: what it delivered and dropped.
    pub fn counts(&self) -> Vec<String> {
        self.reports.iter().map(|r| r()).collect()
    }

    /// A camera of `pair` alone, with no counts of its own (tests).
    #[cfg(test)]
    pub(crate) fn from_pair(pair: CameraPair) -> LiveCamera {
        LiveCamera { pair, replay: None, reports: Vec::new() }
    }

    /// The pair, to hand to another thread, and the streams' counts.
    pub fn split(self) -> (CameraPair, StreamCounts) {
        (self.pair, StreamCounts(self.reports))
    }
}

/// What each stream of a [`LiveCamera`] counted, live.
pub struct StreamCounts(Vec<CountReport>);

impl StreamCounts {
    /// One line per stream: what it delivered and dropped.
    pub fn lines(&self) -> Vec<String> {
        self.0.iter().map(|r| r()).collect()
    }
}

/// A path of the rig TOML, relative to its directory.
fn resolve(rig_dir: &Path, path: &Path) -> PathBuf {
    if path.is_absolute() { path.to_path_buf() } else { rig_dir.join(path) }
}

/// The depth-to-colour isometry of a `depth_to_color` table (or its file).
pub fn color_from_depth(d: &DepthToColor, rig_dir: &Path) -> Result<Isometry3<f64>> {
    let (values, field) = match &d.file {
        Some(file) => {
            let path = resolve(rig_dir, file);
            let text = std::fs::read_to_string(&path)
                .with_context(|| format!("rgbd.depth_to_color.file: cannot read {}", path.display()))?;
            let inner: DepthToColor = parse_toml(&text, &path.display().to_string())?;
            (inner, path.display().to_string())
        }
        None => (d.clone(), "rgbd.depth_to_color".to_string()),
    };
    let e = values.inline(&field)?;
    let r = Matrix3::from_row_slice(&e.rotation_row_major);
    let [x, y, z] = e.translation_m;
    Ok(Isometry3::from_parts(Translation3::new(x, y, z), UnitQuaternion::from_matrix(&r)))
}

/// Half a frame period at `fps`, or the configured tolerance (ms).
fn tolerance(configured_ms: Option<f64>, fps: f64) -> Duration {
    Duration::from_secs_f64(configured_ms.map_or(0.5 / fps, |ms| ms * 1e-3))
}

/// Opens the camera of `cfg` (paths relative to `rig_dir`) on `clock`.
pub fn open(cfg: &RgbdCameraConfig, rig_dir: &Path, clock: Arc<dyn Clock>) -> Result<LiveCamera> {
    match cfg {
        RgbdCameraConfig::Recording(r) => open_recording(r, rig_dir, clock),
        RgbdCameraConfig::V4l2(v) => open_v4l2(v, rig_dir, clock),
    }
}

fn open_recording(r: &RecordedRgbdConfig, rig_dir: &Path, clock: Arc<dyn Clock>) -> Result<LiveCamera> {
    let options = ReplayOptions {
        color_delay_ns: (r.color_delay_ms * 1e6).round() as i64,
        color_intrinsics: r.color_intrinsics.clone(),
        depth_intrinsics: r.depth_intrinsics.clone(),
        directory_fps: r.fps,
        every_frame: r.pace == ReplayPace::EveryFrame,
    };
    let (replay, session, depth_scale_m) = match (&r.session, &r.directory) {
        (Some(session), _) => {
            let path = resolve(rig_dir, session);
            let replay = RecordedRgbd::open_session(&path, clock, &options)
                .with_context(|| format!("rgbd.session: cannot replay {}", path.display()))?;
            // Sessions store depth in millimetres (`16UC1`).
            (replay, Some(path), 0.001)
        }
        (None, Some(dir)) => {
            let path = resolve(rig_dir, dir);
            let replay = RecordedRgbd::open_directory(&path, clock, &options)
                .with_context(|| format!("rgbd.directory: cannot replay {}", path.display()))?;
            (replay, None, r.depth_scale_m)
        }
        (None, None) => anyhow::bail!("rgbd: a recording needs `session` or `directory`"),
    };
    let color_intrinsics = slidetrack_core::Camera::intrinsics(&replay.color).clone();
    let registration = registration(r.depth_to_color.as_ref(), &replay.depth, rig_dir)?;
    let settings = PairSettings {
        color_intrinsics,
        depth_scale_m,
        tolerance: tolerance(r.pairing_tolerance_ms, r.fps),
        timeout: Duration::from_millis(r.pair_timeout_ms),
        registration,
    };
    let (color_counts, depth_counts) = (replay.color.counts(), replay.depth.counts());
    let report = |what: &'static str, c: Arc<slidetrack_vision::input::ReplayCounts>| -> CountReport {
        Box::new(move || {
            format!(
                "{what}: {} frames delivered, {} lost while the tracker was behind",
                c.delivered(),
                c.lost()
            )
        })
    };
    let offset = replay.offset_ns;
    let pacer = replay.pacer();
    let mut pair =
        CameraPair::new(Box::new(replay.color), Box::new(replay.depth), settings).with_end(replay.ended);
    if let Some(pacer) = pacer {
        pair = pair.with_pacer(pacer);
    }
    Ok(LiveCamera {
        pair,
        replay: session.map(|s| (s, offset)),
        reports: vec![report("colour (replayed)", color_counts), report("depth (replayed)", depth_counts)],
    })
}

/// The registration of a depth camera, `None` without extrinsics.
fn registration(
    d: Option<&DepthToColor>,
    depth: &dyn slidetrack_core::Camera,
    rig_dir: &Path,
) -> Result<Option<DepthRegistration>> {
    d.map(|d| {
        Ok(DepthRegistration {
            depth_intrinsics: depth.intrinsics().clone(),
            color_from_depth: color_from_depth(d, rig_dir)?,
        })
    })
    .transpose()
}

#[cfg(all(feature = "devices", target_os = "linux"))]
fn open_v4l2(
    v: &slidetrack_drivers::rgbd_config::V4l2RgbdConfig,
    rig_dir: &Path,
    clock: Arc<dyn Clock>,
) -> Result<LiveCamera> {
    use crate::v4l2_intrinsics::v4l2_intrinsics;
    use slidetrack_drivers::V4l2Camera;
    let node = |n: &slidetrack_drivers::config::V4l2CameraConfig,
                field: &str|
     -> Result<(V4l2Camera, slidetrack_core::CameraIntrinsics)> {
        let mut n = n.clone();
        n.calibration = n.calibration.map(|c| resolve(rig_dir, &c));
        let k = v4l2_intrinsics(&n).with_context(|| format!("{field}: {}", n.device))?;
        let camera =
            V4l2Camera::open(&n, k.clone(), Arc::clone(&clock)).with_context(|| field.to_string())?;
        Ok((camera, k))
    };
    let (color, color_intrinsics) = node(&v.color, "rgbd.color")?;
    let (depth, _) = node(&v.depth, "rgbd.depth")?;
    let registration = registration(v.depth_to_color.as_ref(), &depth, rig_dir)?;
    let settings = PairSettings {
        color_intrinsics,
        depth_scale_m: v.depth_scale_m,
        tolerance: tolerance(v.pairing_tolerance_ms, v.color.fps),
        timeout: Duration::from_millis(v.pair_timeout_ms),
        registration,
    };
    let report = |what: String, c: Arc<slidetrack_drivers::v4l2::CaptureCounters>| -> CountReport {
        Box::new(move || format!("{what}: {c}"))
    };
    let reports = vec![
        report(format!("colour {}", v.color.device), color.counters()),
        report(format!("depth {}", v.depth.device), depth.counters()),
    ];
    let pair = CameraPair::new(Box::new(color), Box::new(depth), settings);
    Ok(LiveCamera { pair, replay: None, reports })
}

#[cfg(not(all(feature = "devices", target_os = "linux")))]
fn open_v4l2(
    _: &slidetrack_drivers::rgbd_config::V4l2RgbdConfig,
    _: &Path,
    _: Arc<dyn Clock>,
) -> Result<LiveCamera> {
    anyhow::bail!(
        "a V4L2 RGB-D camera (`[rgbd] kind = \"v4l2\"`) needs the real devices' backends, and this slidetrack \
         was built without them (the `devices` feature, Linux only)"
    )
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;

    #[test]
    fn extrinsics_from_a_file_and_inline_agree() {
        let dir = tempfile::tempdir().unwrap();
        let text = "rotation_column_major = [0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0]\ntranslation_m = [0.015, 0.0, 0.001]\n";
        std::fs::write(dir.path().join("e.toml"), text).unwrap();
        let from_file = color_from_depth(
            &DepthToColor { file: Some("e.toml".into()), ..DepthToColor::default() },
            dir.path(),
        )
        .unwrap();
        // A 90 degree turn about z (x -> y), then the translation.
        let p = from_file * nalgebra::Point3::new(1.0, 0.0, 0.0);
        assert!((p.coords - Vector3::new(0.015, 1.0, 0.001)).norm() < 1e-12, "{p}");
        let missing = DepthToColor { file: Some("none.toml".into()), ..DepthToColor::default() };
        let e = color_from_depth(&missing, dir.path()).unwrap_err();
        assert!(format!("{e:#}").contains("rgbd.depth_to_color.file"), "{e:#}");
    }
}
