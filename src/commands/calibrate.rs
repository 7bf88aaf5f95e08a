//! `slidetrack calibrate camera`: intrinsics from pattern views, to ROS or OpenCV YAML
//! (`calibrate tactile` is in `calibrate_tactile`).

use anyhow::Result;
use serde_json::json;
use slidetrack_experiment::camera_calibration::{
    CalibrationFormat, CameraCalibration, CameraCalibrationOptions, calibrate_camera,
};

use slidetrack_experiment::hand_calibration::{HandCalibrationOptions, calibrate_hand_sim};
use slidetrack_experiment::hand_calibration_session::calibrate_hand_session;

use crate::cli::{
    CalibrateArgs, CalibrateCameraArgs, CalibrateCommand, CalibrateHandArgs, CalibrationFormatArg,
};

pub fn run(args: &CalibrateArgs, quiet: bool) -> Result<()> {
    match &args.what {
        CalibrateCommand::Camera(a) => camera(a, quiet),
        CalibrateCommand::Tactile(a) => super::calibrate_tactile::run(a, quiet),
        CalibrateCommand::Hand(a) => hand(a),
    }
}

fn hand(args: &CalibrateHandArgs) -> Result<()> {
    let options = HandCalibrationOptions {
        config: args.config.clone(),
        frames: args.frames,
        seed: args.seed,
        out: args.out.clone(),
    };
    let run = match &args.session {
        Some(session) => {
            calibrate_hand_session(session, args.config.as_deref(), args.frames, args.out.as_deref())?
        }
        None => calibrate_hand_sim(&options)?,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&run)?);
        return Ok(());
    }
    let c = &run.calibration;
    println!("{}", run.placement_toml);
    println!(
        "frames: {} ({} looked at, target seen in {}); intrinsics: {}",
        run.frames_from, run.frames_read, run.frames_with_target, run.intrinsics_from
    );
    println!(
        "frames used {} (rejected: {} reprojection, {} outliers); standard error {:.3} mm, {:.4} deg; per-frame spread {:.3} mm, {:.4} deg",
        c.frames_used,
        c.frames_rejected_reprojection,
        c.frames_rejected_outlier,
        c.translation_std_error_mm,
        c.rotation_std_error_deg,
        c.translation_spread_mm,
        c.rotation_spread_deg
    );
    if let Some((mm, deg)) = run.sim_error_mm_deg {
        println!("error against the simulated camera's placement: {mm:.3} mm, {deg:.4} deg");
    }
    Ok(())
}

fn camera(args: &CalibrateCameraArgs, quiet: bool) -> Result<()> {
    let options = CameraCalibrationOptions {
        images: args.images.clone(),
        device: args.device.clone(),
        sim: args.sim,
        config: args.config.clone(),
        pattern: args.pattern.clone(),
        views: args.views,
        width: args.width,
        height: args.height,
        timeout_s: args.timeout,
        save_views: args.save_views.clone(),
        out: args.out.clone(),
        format: match args.format {
            CalibrationFormatArg::Ros => CalibrationFormat::Ros,
            CalibrationFormatArg::Opencv => CalibrationFormat::OpenCv,
        },
        camera_name: args.camera_name.clone(),
        fix_aspect_ratio: args.fix_aspect_ratio,
        zero_tangent: args.zero_tangent,
        fix_k3: args.fix_k3,
    };
    let show = !quiet && !args.json;
    let calibrated = calibrate_camera(&options, &mut |line| {
        if show {
            eprintln!("{line}");
        }
    })?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&to_json(&calibrated, args))?);
    } else {
        print_text(&calibrated, args);
    }
    Ok(())
}

fn print_text(calibrated: &CameraCalibration, args: &CalibrateCameraArgs) {
    let result = &calibrated.calibration;
    let c = &result.intrinsics;
    println!(
        "{}: RMS reprojection error {:.3} px over {} views; fx {:.2} fy {:.2} cx {:.2} cy {:.2} px; \
         distortion k1 {:.4} k2 {:.4} p1 {:.5} p2 {:.5} k3 {:.4}",
        args.out.display(),
        result.rms_px,
        calibrated.views.views.len(),
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

fn to_json(calibrated: &CameraCalibration, args: &CalibrateCameraArgs) -> serde_json::Value {
    let (c, views) = (&calibrated.calibration, &calibrated.views);
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
