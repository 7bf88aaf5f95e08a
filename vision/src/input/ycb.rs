//! [`YcbDirectory`]: a directory of RGB-D frames in YCB-Video's layout,
//! `NNNNNN-color.png`, `NNNNNN-depth.png` (16-bit), `NNNNNN-label.png`
//! (class index per pixel) and `NNNNNN-meta.mat` (MATLAB v5: `poses` 3x4xN,
//! `cls_indexes`, `intrinsic_matrix`, `factor_depth`), read at 30 fps.
//! `label` and `meta` are optional: without them a frame has no truth.

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use slidetrack_calibration::codec;
use slidetrack_core::{CameraIntrinsics, DepthImage, ObjectTruth, PixelFormat, RgbdFrame, TimeNs};

use super::codec::decode_file;
use super::source::{RgbdSample, RgbdSource};
use crate::VisionError;

/// The 21 YCB-Video classes; class index `i` (1-based, as in the label
/// images and `cls_indexes`) is `YCB_CLASSES[i - 1]`.
pub const YCB_CLASSES: [&str; 21] = [
    "002_master_chef_can",
    "003_cracker_box",
    "004_sugar_box",
    "005_tomato_soup_can",
    "006_mustard_bottle",
    "007_tuna_fish_can",
    "008_pudding_box",
    "009_gelatin_box",
    "010_potted_meat_can",
    "011_banana",
    "019_pitcher_base",
    "021_bleach_cleanser",
    "024_bowl",
    "025_mug",
    "035_power_drill",
    "036_wood_block",
    "037_scissors",
    "040_large_marker",
    "051_large_clamp",
    "052_extra_large_clamp",
    "061_foam_brick",
];

/// The annotations of one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct YcbMeta {
    /// Class index of each annotated object (1-based).
    pub cls_indexes: Vec<u32>,
    /// `camera_from_object` of each annotated object.
    pub poses: Vec<Isometry3<f64>>,
    /// `[fx, fy, cx, cy]` (px).
    pub intrinsics: [f64; 4],
    /// Depth units per metre (10000 in YCB-Video).
    pub factor_depth: f64,
}

impl YcbMeta {
    /// The pose of class `class`, if annotated.
    pub fn pose_of(&self, class: u32) -> Option<Isometry3<f64>> {
        self.cls_indexes.iter().position(|c| *c == class).and_then(|i| self.poses.get(i).copied())
    }
}

/// Reads a `-meta.mat` file.
pub fn read_meta(path: &Path) -> Result<YcbMeta, VisionError> {
    let bad = |detail: String| VisionError::BadFile { path: path.to_path_buf(), detail };
    let file =
        std::fs::File::open(path).map_err(|source| VisionError::Io { path: path.to_path_buf(), source })?;
    let mat = matfile::MatFile::parse(file).map_err(|e| bad(format!("not a MATLAB v5 file: {e:?}")))?;
    let doubles = |name: &str| -> Result<(Vec<usize>, Vec<f64>), VisionError> {
        let array = mat.find_by_name(name).ok_or_else(|| bad(format!("no '{name}' array")))?;
        let values = match array.data() {
            matfile::NumericData::Double { real, .. } => real.clone(),
            matfile::NumericData::Single { real, .. } => real.iter().map(|v| f64::from(*v)).collect(),
            matfile::NumericData::UInt8 { real, .. } => real.iter().map(|v| f64::from(*v)).collect(),
            matfile::NumericData::Int32 { real, .. } => real.iter().map(|v| f64::from(*v)).collect(),
            matfile::NumericData::UInt16 { real, .. } => real.iter().map(|v| f64::from(*v)).collect(),
            _ => return Err(bad(format!("'{name}' has an unsupported numeric type"))),
        };
        Ok((array.size().to_vec(), values))
    };
    let (_, cls) = doubles("cls_indexes")?;
    let cls_indexes: Vec<u32> = cls.iter().map(|c| c.round() as u32).collect();
    let (size, poses) = doubles("poses")?;
    let count = if size.len() == 3 { size[2] } else { 1 };
    if size.first() != Some(&3)
        || size.get(1) != Some(&4)
        || poses.len() != 12 * count
        || count != cls_indexes.len()
    {
        return Err(bad(format!("'poses' is {size:?}, expected 3x4x{}", cls_indexes.len())));
    }
    // Column-major: element (r, c, k) at r + 3 c + 12 k.
    let poses = (0..count)
        .map(|k| {
            let at = |r: usize, c: usize| poses[r + 3 * c + 12 * k];
            let rotation = Matrix3::from_fn(at);
            let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&rotation));
            Isometry3::from_parts(Translation3::from(Vector3::new(at(0, 3), at(1, 3), at(2, 3))), rotation)
        })
        .collect();
    let (_, k) = doubles("intrinsic_matrix")?;
    if k.len() != 9 {
        return Err(bad("'intrinsic_matrix' is not 3x3".into()));
    }
    // Column-major K: fx = K(0,0), fy = K(1,1), cx = K(0,2), cy = K(1,2).
    let intrinsics = [k[0], k[4], k[6], k[7]];
    let factor_depth =
        doubles("factor_depth").map(|(_, f)| f.first().copied().unwrap_or(10000.0)).unwrap_or(10000.0);
    if factor_depth.is_nan() || factor_depth <= 0.0 || !intrinsics.iter().all(|v| v.is_finite()) {
        return Err(bad("non-positive factor_depth or non-finite intrinsics".into()));
    }
    Ok(YcbMeta { cls_indexes, poses, intrinsics, factor_depth })
}

/// A YCB-Video-style directory, tracking one object class.
pub struct YcbDirectory {
    dir: PathBuf,
    frames: Vec<String>,
    class: u32,
    intrinsics: CameraIntrinsics,
    factor_depth: f64,
    next: usize,
}

impl YcbDirectory {
    /// Lists the frames of `dir` (by their `-color.png`) and reads the
    /// intrinsics from the first `-meta.mat` (or `fallback` without one).
    /// `class` is the 1-based class index of the object to track.
    pub fn open(
        dir: &Path,
        class: u32,
        fallback: Option<CameraIntrinsics>,
    ) -> Result<YcbDirectory, VisionError> {
        let entries =
            std::fs::read_dir(dir).map_err(|source| VisionError::Io { path: dir.to_path_buf(), source })?;
        let mut frames: Vec<String> = entries
            .filter_map(|e| e.ok()?.file_name().to_str()?.strip_suffix("-color.png").map(str::to_string))
            .collect();
        frames.sort();
        let first = frames.first().ok_or_else(|| VisionError::BadFile {
            path: dir.to_path_buf(),
            detail: "no NNNNNN-color.png frames in this directory".into(),
        })?;
        let meta_path = dir.join(format!("{first}-meta.mat"));
        let (intrinsics, factor_depth) = if meta_path.exists() {
            let meta = read_meta(&meta_path)?;
            let [fx, fy, cx, cy] = meta.intrinsics;
            let (w, h) = image_size(&dir.join(format!("{first}-color.png")))?;
            (
                CameraIntrinsics { width: w, height: h, fx, fy, cx, cy, distortion: [0.0; 5] },
                meta.factor_depth,
            )
        } else {
            let k = fallback.ok_or_else(|| VisionError::BadFile {
                path: meta_path.clone(),
                detail: "no -meta.mat with the intrinsics; give them with --intrinsics".into(),
            })?;
            (k, 10000.0)
        };
        Ok(YcbDirectory { dir: dir.to_path_buf(), frames, class, intrinsics, factor_depth, next: 0 })
    }

    /// The frames' names (`NNNNNN`).
    pub fn frames(&self) -> &[String] {
        &self.frames
    }

    fn read(&self, name: &str, index: usize) -> Result<RgbdSample, VisionError> {
        let path = |suffix: &str| self.dir.join(format!("{name}-{suffix}"));
        let color = decode_file(&path("color.png"), |b| codec::decode(b, PixelFormat::Rgb8))?;
        let (width, height, data) = decode_file(&path("depth.png"), codec::decode_png16)?;
        let depth = DepthImage { width, height, data, scale_m: 1.0 / self.factor_depth };
        VisionError::check_size("depth image", (depth.width, depth.height), (color.width, color.height))?;
        let t = TimeNs((index as f64 / 30.0 * 1e9).round() as u64);
        let truth = if path("meta.mat").exists() {
            read_meta(&path("meta.mat"))?.pose_of(self.class).map(|camera_from_object| ObjectTruth {
                t,
                camera_from_object,
                linear_velocity_mps: Vector3::zeros(),
                angular_velocity_radps: Vector3::zeros(),
            })
        } else {
            None
        };
        let truth_mask = if path("label.png").exists() {
            let label = decode_file(&path("label.png"), |b| codec::decode(b, PixelFormat::Gray8))?;
            let bytes: Vec<u8> = label.data.iter().map(|c| u8::from(u32::from(*c) == self.class)).collect();
            Some(crate::cloud::mask(label.width, label.height, &bytes)?)
        } else {
            None
        };
        let frame =
            RgbdFrame { t, sequence: index as u64, color, depth, intrinsics: self.intrinsics.clone() };
        Ok(RgbdSample { frame, truth, truth_mask })
    }
}

impl RgbdSource for YcbDirectory {
    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    fn next_frame(&mut self) -> Result<Option<RgbdSample>, VisionError> {
        let Some(name) = self.frames.get(self.next).cloned() else {
            return Ok(None);
        };
        let sample = self.read(&name, self.next)?;
        self.next += 1;
        Ok(Some(sample))
    }

    fn len_hint(&self) -> Option<usize> {
        Some(self.frames.len())
    }
}

fn image_size(path: &Path) -> Result<(u32, u32), VisionError> {
    decode_file(path, codec::dimensions)
}
