//! A camera's intrinsics from views of a calibration pattern (`calibrate
//! camera`): image files, a V4L2 camera or the simulated board camera,
//! written as ROS or OpenCV YAML.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, Result, bail};
use slidetrack_calibration::calibrate::{
    CalibrateOptions, CalibrationError, MIN_VIEWS, Pattern, PatternFinder, PatternView, calibrate, read_gray,
};
use slidetrack_calibration::calibrate_live::{FrameVerdict, LiveOptions, capture_views};
use slidetrack_calibration::camera_info::{CameraInfo, write_camera_info};
use slidetrack_core::Camera;
use slidetrack_sim::SimBoardCamera;
use slidetrack_sim::camera::Chessboard;

use crate::rig_config::RigConfig;

pub use slidetrack_calibration::calibrate::Calibration;
pub use slidetrack_calibration::camera_info::CalibrationFormat;

/// What to calibrate from and where to write it.
#[derive(Clone, Debug)]
pub struct CameraCalibrationOptions {
    /// Image files or glob patterns; a live camera when empty.
    pub images: Vec<String>,
    /// The V4L2 device of a live camera (`/dev/video0` by default).
    pub device: Option<PathBuf>,
    /// The simulated rig's camera looking at a chessboard instead.
    pub sim: bool,
    /// The simulated rig's configuration (TOML).
    pub config: Option<PathBuf>,
    /// The pattern: `chessboard:COLSxROWS:SQUARE_M`, ...
    pub pattern: String,
    /// Views to keep from a live camera.
    pub views: usize,
    /// Image width of a live camera (px).
    pub width: u32,
    /// Image height of a live camera (px).
    pub height: u32,
    /// Longest a live capture may take (s).
    pub timeout_s: f64,
    /// Where to save the views kept from a live camera.
    pub save_views: Option<PathBuf>,
    /// The calibration file to write.
    pub out: PathBuf,
    /// Its format.
    pub format: CalibrationFormat,
    /// The camera's name in it.
    pub camera_name: String,
    /// Keep fx / fy fixed.
    pub fix_aspect_ratio: bool,
    /// No tangential distortion.
    pub zero_tangent: bool,
    /// No k3.
    pub fix_k3: bool,
}

/// A calibration and the views it came from.
pub struct CameraCalibration {
    /// The intrinsics and their errors.
    pub calibration: Calibration,
    /// The views.
    pub views: Views,
}

/// Views gathered from files or a camera.
pub struct Views {
    /// The views with the pattern found.
    pub views: Vec<PatternView>,
    /// Image width (px).
    pub width: u32,
    /// Image height (px).
    pub height: u32,
    /// Per image file: whether the pattern was found (file mode), or the
    /// views saved with --save-views (live mode).
    pub images: Vec<(PathBuf, bool)>,
}

/// Gathers the views of `args` (image files, or a live camera until enough
/// are kept), calibrates, and writes the calibration to `args.out`;
/// `note` hears of each file's verdict and each view kept.
pub fn calibrate_camera(
    args: &CameraCalibrationOptions,
    note: &mut dyn FnMut(String),
) -> Result<CameraCalibration> {
    let pattern: Pattern = args.pattern.parse()?;
    let mut finder = PatternFinder::new(pattern.clone())?;
    let gathered = if !args.images.is_empty() {
        from_files(args, &mut finder, note)?
    } else {
        live(args, &mut finder, &pattern, note)?
    };
    let options = CalibrateOptions {
        fix_aspect_ratio: args.fix_aspect_ratio,
        zero_tangent: args.zero_tangent,
        fix_k3: args.fix_k3,
    };
    let result = calibrate(&gathered.views, gathered.width, gathered.height, options)?;
    let info = CameraInfo {
        camera_name: args.camera_name.clone(),
        intrinsics: result.intrinsics.clone(),
        avg_reprojection_error_px: Some(result.rms_px),
    };
    write_camera_info(&args.out, &info, args.format)?;
    Ok(CameraCalibration { calibration: result, views: gathered })
}

/// Expands the `--images` arguments (files or glob patterns) in order.
fn image_files(patterns: &[String]) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for p in patterns {
        if p.contains(['*', '?', '[']) {
            let mut matched: Vec<PathBuf> = glob::glob(p)
                .with_context(|| format!("bad glob pattern {p:?}"))?
                .filter_map(Result::ok)
                .filter(|f| f.is_file())
                .collect();
            if matched.is_empty() {
                bail!("no file matches {p:?}");
            }
            matched.sort();
            files.extend(matched);
        } else {
            files.push(PathBuf::from(p));
        }
    }
    Ok(files)
}

fn from_files(
    args: &CameraCalibrationOptions,
    finder: &mut PatternFinder,
    note: &mut dyn FnMut(String),
) -> Result<Views> {
    let files = image_files(&args.images)?;
    let mut out = Views { views: Vec::new(), width: 0, height: 0, images: Vec::new() };
    for (k, file) in files.iter().enumerate() {
        let gray = read_gray(file)?;
        let (w, h) = (gray.width, gray.height);
        if k == 0 {
            (out.width, out.height) = (w, h);
        } else if (w, h) != (out.width, out.height) {
            return Err(CalibrationError::MixedSizes {
                path: file.clone(),
                width: w,
                height: h,
                expected_width: out.width,
                expected_height: out.height,
            }
            .into());
        }
        let found = finder.find(gray.mat())?;
        let verdict = if found.is_some() { "pattern found" } else { "no pattern" };
        note(format!("{}: {verdict}", file.display()));
        out.images.push((file.clone(), found.is_some()));
        out.views.extend(found);
    }
    if out.views.len() < MIN_VIEWS {
        let without: Vec<String> =
            out.images.iter().filter(|(_, f)| !f).take(10).map(|(p, _)| p.display().to_string()).collect();
        return Err(CalibrationError::TooFewViews {
            pattern: finder.pattern().to_string(),
            found: out.views.len(),
            total: files.len(),
            needed: MIN_VIEWS,
            without_pattern: without,
        }
        .into());
    }
    Ok(out)
}

fn live(
    args: &CameraCalibrationOptions,
    finder: &mut PatternFinder,
    pattern: &Pattern,
    note: &mut dyn FnMut(String),
) -> Result<Views> {
    let mut camera: Box<dyn Camera> = if args.sim {
        let Pattern::Chessboard { inner_corners, square_m } = pattern else {
            bail!(
                "the simulated camera renders chessboards only; use --pattern chessboard:COLSxROWS:SQUARE_M"
            );
        };
        let rig = RigConfig::load(args.config.as_deref())?;
        let board =
            Chessboard { inner_corners: *inner_corners, square_size_m: *square_m, ..Chessboard::default() };
        Box::new(SimBoardCamera::new(rig.camera, board, 1)?)
    } else {
        let device = args.device.as_deref().unwrap_or(Path::new("/dev/video0"));
        open_v4l2(device, args.width, args.height)?
    };
    if !(args.timeout_s.is_finite() && args.timeout_s > 0.0) {
        bail!("--timeout must be a positive number of seconds, got {}", args.timeout_s);
    }
    let options = LiveOptions {
        views: args.views.max(MIN_VIEWS),
        timeout: Duration::from_secs_f64(args.timeout_s),
        keep_images: args.save_views.is_some(),
        ..LiveOptions::default()
    };
    let capture = capture_views(camera.as_mut(), finder, &options, &mut |p| {
        if let FrameVerdict::Kept(v) = p.verdict {
            note(format!(
                "view {}/{} kept at frame {} (centre {:.2}, {:.2} of the image, size {:.2}, tilt {:+.2} {:+.2})",
                p.kept, p.wanted, p.frames, v.centre[0], v.centre[1], v.scale, v.tilt[0], v.tilt[1]
            ));
        }
    })
    .with_context(|| format!("live capture from {}", camera.device()))?;
    if capture.views.len() < options.views {
        bail!(
            "only {} of {} views captured from {} in {} frames ({} showed the pattern {}); move the pattern over \
             the whole image at several distances and tilts",
            capture.views.len(),
            options.views,
            camera.device(),
            capture.frames,
            capture.frames_with_pattern,
            pattern
        );
    }
    let images = match &args.save_views {
        Some(dir) => save_views(dir, &capture.images)?,
        None => Vec::new(),
    };
    Ok(Views { views: capture.views, width: capture.width, height: capture.height, images })
}

/// Writes the kept frames as `dir/view-NN.png`; returns the files written.
fn save_views(dir: &Path, pngs: &[Vec<u8>]) -> Result<Vec<(PathBuf, bool)>> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    pngs.iter()
        .enumerate()
        .map(|(k, png)| {
            let file = dir.join(format!("view-{k:02}.png"));
            std::fs::write(&file, png).with_context(|| format!("cannot write {}", file.display()))?;
            Ok((file, true))
        })
        .collect()
}

/// The V4L2 camera at `device`, streaming `width x height` MJPG at 30 fps.
/// Its intrinsics are what is being calibrated: a placeholder is passed.
#[cfg(all(feature = "devices", target_os = "linux"))]
fn open_v4l2(device: &Path, width: u32, height: u32) -> Result<Box<dyn Camera>> {
    use std::sync::Arc;

    use slidetrack_core::{CameraIntrinsics, Clock, WallClock};
    use slidetrack_drivers::V4l2Camera;
    use slidetrack_drivers::config::V4l2CameraConfig;

    let config = V4l2CameraConfig {
        device: device.display().to_string(),
        width,
        height,
        ..V4l2CameraConfig::default()
    };
    let placeholder = CameraIntrinsics {
        width,
        height,
        fx: f64::from(width),
        fy: f64::from(width),
        cx: f64::from(width) / 2.0,
        cy: f64::from(height) / 2.0,
        distortion: [0.0; 5],
    };
    let clock: Arc<dyn Clock> = Arc::new(WallClock::start());
    let camera = V4l2Camera::open(&config, placeholder, clock)?;
    Ok(Box::new(camera))
}

#[cfg(not(all(feature = "devices", target_os = "linux")))]
fn open_v4l2(_device: &Path, _width: u32, _height: u32) -> Result<Box<dyn Camera>> {
    bail!(
        "calibrate camera --device needs the real devices' backends, and this slidetrack was built without \
         them (the `devices` feature, Linux only)"
    )
}
