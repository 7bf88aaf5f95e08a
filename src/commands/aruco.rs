//! `slidetrack aruco detect`: markers (and poses) in one image.

use anyhow::{Context, Result, bail};
use serde_json::json;
use slidetrack_calibration::camera_info::read_camera_info;
use slidetrack_calibration::marker_tool::{
    Refinement, ToolDictionary, detect_markers, detector_parameters, read_image,
};
use slidetrack_calibration::{MarkerDetection, MarkerPose, marker_pose};
use slidetrack_core::CameraIntrinsics;

use crate::cli::{ArucoArgs, ArucoCommand, ArucoDetectArgs, RefineArg};

pub fn run(args: &ArucoArgs) -> Result<()> {
    match &args.what {
        ArucoCommand::Detect(a) => detect(a),
    }
}

fn detect(args: &ArucoDetectArgs) -> Result<()> {
    let dictionary = ToolDictionary::load(&args.dict)?;
    let refinement = match args.refine {
        RefineArg::None => Refinement::None,
        RefineArg::Subpix => Refinement::Subpix,
        RefineArg::Contour => Refinement::Contour,
        RefineArg::Apriltag => Refinement::Apriltag,
    };
    let params = detector_parameters(args.params.as_deref(), refinement)?;
    let image = read_image(&args.image)?;
    let (width, height) = (image.width, image.height);
    let intrinsics = match (&args.camera, args.marker_size) {
        (Some(path), Some(size)) => {
            if !(size.is_finite() && size > 0.0) {
                bail!("--marker-size must be a positive length in metres, got {size}");
            }
            Some((camera_for(path, width, height)?, size))
        }
        _ => None,
    };
    let markers = detect_markers(&image, &dictionary, &params)?;
    let poses: Vec<Option<MarkerPose>> = markers
        .iter()
        .map(|m| match &intrinsics {
            Some((c, size)) => marker_pose(m, c, *size).map(Some),
            None => Ok(None),
        })
        .collect::<Result<_, _>>()?;
    if args.json {
        let list: Vec<_> = markers.iter().zip(&poses).map(|(m, p)| marker_json(m, p.as_ref())).collect();
        let out = json!({
            "image": args.image.display().to_string(),
            "width": width,
            "height": height,
            "dictionary": dictionary.name(),
            "markers": list,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    println!("{}: {} marker(s) of {}", args.image.display(), markers.len(), dictionary.name());
    for (m, p) in markers.iter().zip(&poses) {
        let corners: Vec<String> =
            m.corners_px.iter().map(|c| format!("({:.1}, {:.1})", c[0], c[1])).collect();
        let pose = p.as_ref().map_or(String::new(), |p| {
            let t = p.camera_from_marker.translation.vector;
            format!(
                "; at ({:.4}, {:.4}, {:.4}) m in the camera frame, reprojection {:.2} px",
                t.x, t.y, t.z, p.reprojection_error_px
            )
        });
        println!("  id {:>4}: corners {}{pose}", m.id, corners.join(" "));
    }
    Ok(())
}

/// The intrinsics of `path` for an image of `width x height`: a file without
/// an image size (OpenCV's tutorial files) is taken for this size.
fn camera_for(path: &std::path::Path, width: u32, height: u32) -> Result<CameraIntrinsics> {
    let info = read_camera_info(path).with_context(|| "--camera")?;
    let sized = info.has_image_size();
    let mut c = info.intrinsics;
    if !sized {
        (c.width, c.height) = (width, height);
    } else if (c.width, c.height) != (width, height) {
        bail!(
            "{} is a calibration for {}x{} px images but {width}x{height} px were given",
            path.display(),
            c.width,
            c.height
        );
    }
    Ok(c)
}

fn marker_json(m: &MarkerDetection, pose: Option<&MarkerPose>) -> serde_json::Value {
    let mut v = json!({ "id": m.id, "corners_px": m.corners_px, "centre_px": m.centre_px() });
    if let Some(p) = pose {
        let t = p.camera_from_marker.translation.vector;
        let q = p.camera_from_marker.rotation;
        let r = q.scaled_axis();
        v["pose"] = json!({
            "position_in_camera_m": [t.x, t.y, t.z],
            "orientation_in_camera": { "x": q.i, "y": q.j, "z": q.k, "w": q.w },
            "rvec": [r.x, r.y, r.z],
            "reprojection_error_px": p.reprojection_error_px,
        });
    }
    v
}
