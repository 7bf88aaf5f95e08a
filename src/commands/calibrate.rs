//! `slidetrack calibrate camera`: intrinsics from pattern views, to ROS or OpenCV YAML.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, Result, bail};
use serde_json::json;
use slidetrack_calibration::calibrate::{
    CalibrateOptions, Calibration, CalibrationError, MIN_VIEWS, Pattern, PatternFinder, PatternView,
    calibrate, read_gray,
};
use slidetrack_calibration::calibrate_live::{FrameVerdict, LiveOptions, capture_views};
use slidetrack_calibration::camera_info::{CalibrationFormat, CameraInfo, write_camera_info};
use slidetrack_core::Camera;
use slidetrack_experiment::rig_config::RigConfig;
use slidetrack_sim::SimBoardCamera;
use slidetrack_sim::camera::Chessboard;

use crate::cli::{CalibrateArgs, CalibrateCameraArgs, CalibrateCommand, CalibrationFormatArg};

pub fn run(args: &CalibrateArgs, quiet: bool) -> Result<()> {
    match &args.what {
        CalibrateCommand::Camera(a) => camera(a, quiet),
    }
}

/// Views gathered from files or a camera.
struct Views {
    views: Vec<PatternView>,
    width: u32,
    height: u32,
    /// Per image file: whether the pattern was found (file mode), or the
    /// views saved with --save-views (live mode).
    images: Vec<(PathBuf, bool)>,
}

fn camera(args: &CalibrateCameraArgs, quiet: bool) -> Result<()> {
    let pattern: Pattern = args.pattern.parse()?;
    let mut finder = PatternFinder::new(pattern.clone())?;
    let gathered = if !args.images.is_empty() {
        from_files(args, &mut finder, quiet)?
    } else {
        live(args, &mut finder, &pattern, quiet)?
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
    let format = match args.format {
        CalibrationFormatArg::Ros => CalibrationFormat::Ros,
        CalibrationFormatArg::Opencv => CalibrationFormat::OpenCv,
    };
    write_camera_info(&args.out, &info, format)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&to_json(&result, &gathered, args))?);
    } else {
        let c = &result.intrinsics;
        println!(
            "{}: RMS reprojection error {:.3} px over {} views; fx {:.2} fy {:.2} cx {:.2} cy {:.2} px; \
             distortion k1 {:.4} k2 {:.4} p1 {:.5} p2 {:.5} k3 {:.4}",
            args.out.display(),
            result.rms_px,
            gathered.views.len(),
            c.fx,
            c.fy,
            c.cx,
            c.cy,
            c.distortion[0],
            c.distortion[1],
            c.distortion[2],
            c.distortion[3],
            c.distortion[4]
        );
    }
    Ok(())
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

fn from_files(args: &CalibrateCameraArgs, finder: &mut PatternFinder, quiet: bool) -> Result<Views> {
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
        if !quiet && !args.json {
            let verdict = if found.is_some() { "pattern found" } else { "no pattern" };
            eprintln!("{}: {verdict}", file.display());
        }
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
    args: &CalibrateCameraArgs,
    finder: &mut PatternFinder,
    pattern: &Pattern,
    quiet: bool,
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
    if !(args.timeout.is_finite() && args.timeout > 0.0) {
        bail!("--timeout must be a positive number of seconds, got {}", args.timeout);
    }
    let options = LiveOptions {
        views: args.views.max(MIN_VIEWS),
        timeout: Duration::from_secs_f64(args.timeout),
        keep_images: args.save_views.is_some(),
        ..LiveOptions::default()
    };
    let show = !quiet && !args.json;
    let capture = capture_views(camera.as_mut(), finder, &options, &mut |p| {
        if show && let FrameVerdict::Kept(v) = p.verdict {
            eprintln!(
                "view {}/{} kept at frame {} (centre {:.2}, {:.2} of the image, size {:.2}, tilt {:+.2} {:+.2})",
                p.kept, p.wanted, p.frames, v.centre[0], v.centre[1], v.scale, v.tilt[0], v.tilt[1]
            );
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
    Err(super::without_devices("calibrate camera --device"))
}

fn to_json(c: &Calibration, views: &Views, args: &CalibrateCameraArgs) -> serde_json::Value {
    let k = &c.intrinsics;
    json!({
        "out": args.out.display().to_string(),
        "format": match args.format { CalibrationFormatArg::Ros => "ros", CalibrationFormatArg::Opencv => "opencv" },
        "pattern": args.pattern,
        "rms_px": c.rms_px,
        "views": views.views.len(),
        "image_width": k.width,
        "image_height": k.height,
        "fx": k.fx,
        "fy": k.fy,
        "cx": k.cx,
        "cy": k.cy,
        "camera_matrix": k.k(),
        "distortion_coefficients": k.distortion,
        "per_view_rms_px": c.per_view_rms_px,
        "images": views.images.iter().map(|(p, found)| json!({"file": p.display().to_string(), "pattern_found": found})).collect::<Vec<_>>(),
    })
}
