//! ArUco markers (and their poses, or a board's pose) detected in one image
//! (`aruco detect`), with OpenCV's dictionaries, detector parameters and
//! corner refinements.

use std::path::Path;

use anyhow::{Context, Result, bail};
use slidetrack_calibration::camera_info::read_camera_info;
use slidetrack_calibration::marker_tool::{
    Photo, ToolDictionary, detect_markers, detector_parameters, read_image,
};
use slidetrack_calibration::{Board, board_pose, marker_pose};
use slidetrack_core::{BoardLayout, CameraIntrinsics};

pub use slidetrack_calibration::marker_tool::Refinement;
pub use slidetrack_calibration::{BoardObservation, BoardPose, MarkerDetection, MarkerPose};

/// What to detect in which image.
#[derive(Clone, Copy, Debug)]
pub struct ImageMarkerOptions<'a> {
    /// The image file.
    pub image: &'a Path,
    /// An OpenCV dictionary name (`DICT_6X6_250`, ...) or dictionary file.
    pub dictionary: &'a str,
    /// OpenCV detector parameters file.
    pub parameters: Option<&'a Path>,
    /// Corner refinement.
    pub refinement: Refinement,
    /// The camera's calibration (ROS or OpenCV YAML), for the poses.
    pub camera: Option<&'a Path>,
    /// Side of a marker's black square (m), for the poses.
    pub marker_size_m: Option<f64>,
    /// A board's layout file (TOML, the keys of a rig's `[marker.board]`),
    /// for the board's pose (with `camera`).
    pub board: Option<&'a Path>,
}

/// A board found in an image.
pub struct ImageBoard {
    /// Its layout.
    pub layout: BoardLayout,
    /// The points matched to it.
    pub observation: BoardObservation,
    /// Its pose, when at least four points were seen.
    pub pose: Option<BoardPose>,
}

/// The markers of an image.
pub struct ImageMarkers {
    /// Image width (px).
    pub width: u32,
    /// Image height (px).
    pub height: u32,
    /// The dictionary's name.
    pub dictionary: String,
    /// Each marker with its pose, when the camera and the marker size are given.
    pub markers: Vec<(MarkerDetection, Option<MarkerPose>)>,
    /// The board, when the camera and a board are given.
    pub board: Option<ImageBoard>,
}

/// Detects the markers of `options.image`, and their poses when the
/// camera and the marker size are given.
pub fn detect_in_image(options: &ImageMarkerOptions<'_>) -> Result<ImageMarkers> {
    let dictionary = ToolDictionary::load(options.dictionary)?;
    let params = detector_parameters(options.parameters, options.refinement)?;
    let image = read_image(options.image)?;
    let (width, height) = (image.width, image.height);
    if options.board.is_some() && options.camera.is_none() {
        bail!("--board needs --camera");
    }
    let intrinsics = match (options.camera, options.marker_size_m) {
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
    let board = match (options.board, options.camera) {
        (Some(board), Some(camera)) => {
            Some(board_in_image(board, &dictionary, &markers, &image, &camera_for(camera, width, height)?)?)
        }
        _ => None,
    };
    let markers = markers.into_iter().zip(poses).collect();
    Ok(ImageMarkers { width, height, dictionary: dictionary.name().to_string(), markers, board })
}

/// The board of layout file `path` among the markers `found` in `image`.
fn board_in_image(
    path: &Path,
    dictionary: &ToolDictionary,
    found: &[MarkerDetection],
    image: &Photo,
    camera: &CameraIntrinsics,
) -> Result<ImageBoard> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read --board {}", path.display()))?;
    let layout: BoardLayout = slidetrack_core::parse_toml(&text, &path.display().to_string())?;
    layout.validate().with_context(|| format!("--board {}", path.display()))?;
    let board = Board::with_dictionary(layout.clone(), dictionary)?;
    let observation = board.observe_photo(found, image, camera)?;
    let pose = board_pose(&observation, camera).ok();
    Ok(ImageBoard { layout, observation, pose })
}

/// The intrinsics of `path` for an image of `width x height`: a file without
/// an image size (OpenCV's tutorial files) is taken for this size.
fn camera_for(path: &Path, width: u32, height: u32) -> Result<CameraIntrinsics> {
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
