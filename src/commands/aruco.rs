//! `slidetrack aruco detect`: markers (and poses) in one image.

use anyhow::Result;
use serde_json::json;
use slidetrack_experiment::image_markers::{
    ImageBoard, ImageMarkerOptions, MarkerDetection, MarkerPose, Refinement, detect_in_image,
};

use crate::cli::{ArucoArgs, ArucoCommand, ArucoDetectArgs, RefineArg};

pub fn run(args: &ArucoArgs) -> Result<()> {
    match &args.what {
        ArucoCommand::Detect(a) => detect(a),
    }
}

fn detect(args: &ArucoDetectArgs) -> Result<()> {
    let found = detect_in_image(&ImageMarkerOptions {
        image: &args.image,
        dictionary: &args.dict,
        parameters: args.params.as_deref(),
        refinement: match args.refine {
            RefineArg::None => Refinement::None,
            RefineArg::Subpix => Refinement::Subpix,
            RefineArg::Contour => Refinement::Contour,
            RefineArg::Apriltag => Refinement::Apriltag,
        },
        camera: args.camera.as_deref(),
        marker_size_m: args.marker_size,
        board: args.board.as_deref(),
    })?;
    if args.json {
        let list: Vec<_> = found.markers.iter().map(|(m, p)| marker_json(m, p.as_ref())).collect();
        let out = json!({
            "image": args.image.display().to_string(),
            "width": found.width,
            "height": found.height,
            "dictionary": found.dictionary,
            "markers": list,
            "board": found.board.as_ref().map(board_json),
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    println!("{}: {} marker(s) of {}", args.image.display(), found.markers.len(), found.dictionary);
    for (m, p) in &found.markers {
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
    if let Some(b) = &found.board {
        println!("{}", board_text(b));
    }
    Ok(())
}

fn board_text(b: &ImageBoard) -> String {
    let seen =
        format!("board: {} marker(s), {} point(s)", b.observation.markers, b.observation.image_px.len());
    match &b.pose {
        None => format!("{seen}; too few for a pose"),
        Some(p) => {
            let t = p.camera_from_board.translation.vector;
            format!(
                "{seen}; origin at ({:.4}, {:.4}, {:.4}) m in the camera frame, reprojection {:.2} px",
                t.x, t.y, t.z, p.reprojection_error_px
            )
        }
    }
}

fn board_json(b: &ImageBoard) -> serde_json::Value {
    let pose = b.pose.as_ref().map(|p| {
        let (t, q) = (p.camera_from_board.translation.vector, p.camera_from_board.rotation);
        let c = p.camera_from_centre(&b.layout);
        let (ct, cq) = (c.translation.vector, c.rotation);
        let r = q.scaled_axis();
        json!({
            "board_in_camera": { "position_m": [t.x, t.y, t.z], "rvec": [r.x, r.y, r.z],
                "orientation": { "x": q.i, "y": q.j, "z": q.k, "w": q.w } },
            "centre_in_camera": { "position_m": [ct.x, ct.y, ct.z],
                "orientation": { "x": cq.i, "y": cq.j, "z": cq.k, "w": cq.w } },
            "reprojection_error_px": p.reprojection_error_px,
            "points": p.points,
        })
    });
    json!({
        "layout": b.layout,
        "markers": b.observation.markers,
        "ids": b.observation.ids,
        "image_px": b.observation.image_px,
        "pose": pose,
    })
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
