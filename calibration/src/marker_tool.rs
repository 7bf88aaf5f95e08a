//! Marker detection in still images with OpenCV's own defaults, for the
//! `aruco detect` tool: any predefined dictionary by name or a custom one
//! from an OpenCV dictionary file (`nmarkers`, `markersize`, `marker_<i>`
//! bit strings), OpenCV's detector parameters (optionally from its YAML),
//! and OpenCV's corner refinement methods. (The session pipeline uses the
//! tuned [`crate::MarkerDetector`] instead.)

use std::fmt;
use std::path::{Path, PathBuf};

use opencv::aruco::{self, DetectorParametersTrait};
use opencv::core::{self, FileStorage, FileStorageTraitConst, Mat, MatTraitConst, Point2f, Ptr, Vector};
use opencv::prelude::*;
use slidetrack_core::{Image, PixelFormat};
use thiserror::Error;

use crate::aruco::{Dictionary, MarkerDetection};
use crate::error::MarkerError;

/// Why markers could not be looked for.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum MarkerToolError {
    /// Neither a predefined dictionary name nor a readable dictionary file.
    #[error("{spec:?} is neither an OpenCV dictionary name ({}) nor a dictionary file", names.join(", "))]
    UnknownDictionary {
        /// The name or path as given.
        spec: String,
        /// Every predefined name.
        names: Vec<&'static str>,
    },
    /// A dictionary or parameter file could not be read.
    #[error("{path}: {detail}")]
    BadFile {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        detail: String,
    },
    /// An OpenCV call failed.
    #[error("OpenCV {operation} failed: {source}")]
    OpenCv {
        /// The OpenCV function.
        operation: &'static str,
        /// OpenCV's error.
        #[source]
        source: opencv::Error,
    },
}

trait Cv<T> {
    fn cv(self, operation: &'static str) -> Result<T, MarkerToolError>;
}

impl<T> Cv<T> for opencv::Result<T> {
    fn cv(self, operation: &'static str) -> Result<T, MarkerToolError> {
        self.map_err(|source| MarkerToolError::OpenCv { operation, source })
    }
}

/// OpenCV's corner refinement methods.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Refinement {
    /// The polygon's corners (OpenCV's default, what its tests assert).
    #[default]
    None,
    /// `cornerSubPix` (`CORNER_REFINE_SUBPIX`).
    Subpix,
    /// Lines fitted to the contour (`CORNER_REFINE_CONTOUR`).
    Contour,
    /// AprilTag's quad fit on decimated edges (`CORNER_REFINE_APRILTAG`), as
    /// OpenCV's diamond test uses.
    Apriltag,
}

/// A dictionary for still-image detection, predefined or from a file.
pub struct ToolDictionary {
    name: String,
    inner: Inner,
}

enum Inner {
    Predefined(Dictionary),
    Custom(Ptr<aruco::Dictionary>),
}

impl fmt::Debug for ToolDictionary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ToolDictionary").field("name", &self.name).finish()
    }
}

impl ToolDictionary {
    /// A predefined dictionary by its OpenCV name (`DICT_6X6_250`), or a
    /// dictionary file (OpenCV's `readDictionary` format).
    pub fn load(spec: &str) -> Result<ToolDictionary, MarkerToolError> {
        match Dictionary::from_name(spec) {
            Ok(d) => return Ok(ToolDictionary { name: d.name().to_string(), inner: Inner::Predefined(d) }),
            Err(MarkerError::UnknownDictionary { .. }) => {}
            Err(e) => return Err(MarkerToolError::BadFile { path: spec.into(), detail: e.to_string() }),
        }
        let path = Path::new(spec);
        if !path.is_file() {
            return Err(MarkerToolError::UnknownDictionary {
                spec: spec.to_string(),
                names: Dictionary::names().collect(),
            });
        }
        let bad = |detail: String| MarkerToolError::BadFile { path: path.to_path_buf(), detail };
        let fs = FileStorage::new(path, core::FileStorage_READ, "")
            .map_err(|e| bad(format!("not an OpenCV YAML/XML file: {}", e.message)))?;
        let mut dictionary = aruco::Dictionary::new_def().cv("Dictionary")?;
        let root = fs.root(0).cv("FileStorage::root")?;
        let read = dictionary.read_dictionary(&root).map_err(|e| bad(e.message))?;
        if !read || aruco::DictionaryTraitConst::bytes_list(&dictionary).rows() <= 0 {
            return Err(bad(
                "not a dictionary file (needs nmarkers, markersize and marker_<i> bit strings)".into()
            ));
        }
        Ok(ToolDictionary { name: path.display().to_string(), inner: Inner::Custom(Ptr::new(dictionary)) })
    }

    /// The name, or the file it came from.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The OpenCV dictionary.
    pub(crate) fn opencv(&self) -> &Ptr<aruco::Dictionary> {
        match &self.inner {
            Inner::Predefined(d) => d.opencv(),
            Inner::Custom(p) => p,
        }
    }
}

/// OpenCV's detector parameters: defaults, or read from a file written by
/// OpenCV (`detector_params.yml`), with `refinement` on top.
pub fn detector_parameters(
    file: Option<&Path>,
    refinement: Refinement,
) -> Result<Ptr<aruco::DetectorParameters>, MarkerToolError> {
    let mut params = aruco::DetectorParameters::create().cv("DetectorParameters::create")?;
    if let Some(path) = file {
        let bad = |detail: String| MarkerToolError::BadFile { path: path.to_path_buf(), detail };
        let fs = FileStorage::new(path, core::FileStorage_READ, "")
            .map_err(|e| bad(format!("cannot read: {}", e.message)))?;
        if !fs.is_opened().cv("FileStorage::isOpened")? {
            return Err(bad("cannot open it".into()));
        }
        let root = fs.root(0).cv("FileStorage::root")?;
        if !params.read_detector_parameters(&root).map_err(|e| bad(e.message))? {
            return Err(bad("not a detector parameters file".into()));
        }
    }
    if file.is_none() || refinement != Refinement::None {
        let method = match refinement {
            Refinement::None => aruco::CornerRefineMethod::CORNER_REFINE_NONE,
            Refinement::Subpix => aruco::CornerRefineMethod::CORNER_REFINE_SUBPIX,
            Refinement::Contour => aruco::CornerRefineMethod::CORNER_REFINE_CONTOUR,
            Refinement::Apriltag => aruco::CornerRefineMethod::CORNER_REFINE_APRILTAG,
        };
        params.set_corner_refinement_method(method as i32);
    }
    Ok(params)
}

/// Every marker of `dictionary` in an image, in OpenCV's
/// order, corners in OpenCV's convention (integer = pixel centre).
pub fn detect_markers(
    image: &Photo,
    dictionary: &ToolDictionary,
    params: &Ptr<aruco::DetectorParameters>,
) -> Result<Vec<MarkerDetection>, MarkerToolError> {
    let mut corners = Vector::<Vector<Point2f>>::new();
    let mut ids = Vector::<i32>::new();
    let mut rejected = Vector::<Vector<Point2f>>::new();
    aruco::detect_markers(&image.mat, dictionary.opencv(), &mut corners, &mut ids, params, &mut rejected)
        .cv("detectMarkers")?;
    let mut found = Vec::with_capacity(ids.len());
    for (id, c) in ids.iter().zip(corners.iter()) {
        let mut corners_px = [[0.0; 2]; 4];
        for (k, out) in corners_px.iter_mut().enumerate() {
            let p = c.get(k).cv("corner")?;
            *out = [f64::from(p.x), f64::from(p.y)];
        }
        found.push(MarkerDetection { id: id.max(0) as u32, corners_px });
    }
    Ok(found)
}

/// An image as OpenCV reads it (8-bit BGR).
#[derive(Debug)]
pub struct Photo {
    mat: Mat,
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
}

impl Photo {
    /// The image as OpenCV holds it.
    pub(crate) fn mat(&self) -> &Mat {
        &self.mat
    }
}

/// An RGB8 image as an OpenCV BGR matrix (what `imread` gives).
pub(crate) fn bgr_mat(image: &Image) -> Result<Mat, MarkerToolError> {
    let rgb = Mat::from_slice(&image.data).cv("Mat from image")?;
    let rgb = rgb.reshape(3, image.height as i32).cv("Mat::reshape")?;
    let mut bgr = Mat::default();
    opencv::imgproc::cvt_color_def(&rgb, &mut bgr, opencv::imgproc::COLOR_RGB2BGR).cv("cvtColor")?;
    Ok(bgr)
}

/// Reads a JPEG or PNG file as OpenCV's `imread` does (colour, BGR).
pub fn read_image(path: &Path) -> Result<Photo, MarkerToolError> {
    let bad = || MarkerToolError::BadFile {
        path: path.to_path_buf(),
        detail: "cannot read it as an image (missing, or neither JPEG nor PNG)".into(),
    };
    // A missing file or a directory fails to read.
    let bytes = std::fs::read(path).map_err(|_| bad())?;
    let rgb = crate::codec::decode(&bytes, PixelFormat::Rgb8).map_err(|_| bad())?;
    Ok(Photo { mat: bgr_mat(&rgb)?, width: rgb.width, height: rgb.height })
}
