//! Camera calibration files: ROS `camera_info` YAML (what `camera_calibration`
//! and `camera_info_manager` read and write) and OpenCV FileStorage YAML
//! (what OpenCV's `calibration` sample writes, `%YAML:1.0` with
//! `!!opencv-matrix`). Both are read back; the format is recognised from the
//! content.

use std::path::{Path, PathBuf};

use opencv::core::{
    self, FileNodeTraitConst, FileStorage, FileStorageTrait, FileStorageTraitConst, Mat, MatTraitConst,
};
use opencv::prelude::*;
use serde_norway::Value;
use slidetrack_core::CameraIntrinsics;
use thiserror::Error;

/// The fields of a ROS `camera_info` file, all required.
pub const ROS_FIELDS: [&str; 8] = [
    "image_width",
    "image_height",
    "camera_name",
    "camera_matrix",
    "distortion_model",
    "distortion_coefficients",
    "rectification_matrix",
    "projection_matrix",
];

/// A file format for camera intrinsics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CalibrationFormat {
    /// ROS `camera_info` YAML.
    #[default]
    Ros,
    /// OpenCV FileStorage YAML.
    OpenCv,
}

/// A camera's calibration as the files hold it.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraInfo {
    /// Camera name (ROS `camera_name`; `camera` when the file has none).
    pub camera_name: String,
    /// Intrinsics with plumb-bob distortion. `width` and `height` are 0 when
    /// an OpenCV file does not give the image size (OpenCV's own tutorial files).
    pub intrinsics: CameraIntrinsics,
    /// RMS reprojection error of the calibration (px), when known.
    pub avg_reprojection_error_px: Option<f64>,
}

impl CameraInfo {
    /// Whether the file gave the image size.
    pub fn has_image_size(&self) -> bool {
        self.intrinsics.width > 0 && self.intrinsics.height > 0
    }
}

/// Why a calibration file could not be read or written.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum CameraInfoError {
    /// The file could not be read.
    #[error("cannot read calibration file {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The file could not be written.
    #[error("cannot write calibration file {path}: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The file is not valid YAML.
    #[error("{path} is not valid YAML: {detail}")]
    Syntax {
        /// The file.
        path: PathBuf,
        /// The parser's message.
        detail: String,
    },
    /// A required field is missing.
    #[error("{path} has no field `{field}` (a {format} calibration file needs {needed})")]
    MissingField {
        /// The file.
        path: PathBuf,
        /// The missing field.
        field: String,
        /// `ROS camera_info` or `OpenCV`.
        format: &'static str,
        /// Every required field, comma-separated.
        needed: String,
    },
    /// A field has the wrong type, size or value.
    #[error("{path}: field `{field}` should be {expected}, found {found}")]
    BadField {
        /// The file.
        path: PathBuf,
        /// The field.
        field: String,
        /// What it should be.
        expected: String,
        /// What it is.
        found: String,
    },
    /// The distortion model is not plumb bob (`k1, k2, p1, p2, k3`).
    #[error(
        "{path}: distortion model {model:?} with {coefficients} coefficients is not supported (plumb_bob only)"
    )]
    UnsupportedDistortion {
        /// The file.
        path: PathBuf,
        /// The model name.
        model: String,
        /// Number of coefficients.
        coefficients: usize,
    },
    /// OpenCV's FileStorage failed.
    #[error("{path}: OpenCV FileStorage {operation} failed: {source}")]
    OpenCv {
        /// The file.
        path: PathBuf,
        /// What was being done.
        operation: &'static str,
        /// OpenCV's error.
        #[source]
        source: opencv::Error,
    },
}

/// Reads a calibration file of either format.
pub fn read_camera_info(path: impl AsRef<Path>) -> Result<CameraInfo, CameraInfoError> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path)
        .map_err(|source| CameraInfoError::Read { path: path.to_path_buf(), source })?;
    parse_camera_info(&text, path)
}

/// Parses the text of a calibration file; `path` names it in errors.
pub fn parse_camera_info(text: &str, path: &Path) -> Result<CameraInfo, CameraInfoError> {
    if text.trim_start().starts_with("%YAML:") || text.contains("!!opencv-matrix") {
        parse_opencv(text, path)
    } else {
        parse_ros(text, path)
    }
}

/// Writes `info` to `path` in `format` (through a temporary file, renamed).
pub fn write_camera_info(
    path: impl AsRef<Path>,
    info: &CameraInfo,
    format: CalibrationFormat,
) -> Result<(), CameraInfoError> {
    let path = path.as_ref();
    let text = match format {
        CalibrationFormat::Ros => to_ros_yaml(info),
        CalibrationFormat::OpenCv => to_opencv_yaml(info, path)?,
    };
    let write_err = |source| CameraInfoError::Write { path: path.to_path_buf(), source };
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let mut temp = tempfile::NamedTempFile::new_in(dir).map_err(write_err)?;
    std::io::Write::write_all(&mut temp, text.as_bytes()).map_err(write_err)?;
    temp.persist(path).map_err(|e| write_err(e.error))?;
    Ok(())
}

/// The ROS `camera_info` YAML of `info` (monocular: `R = I`, `P = [K | 0]`).
pub fn to_ros_yaml(info: &CameraInfo) -> String {
    let c = &info.intrinsics;
    let list = |v: &[f64]| v.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(", ");
    let matrix = |name: &str, rows: usize, cols: usize, v: &[f64]| {
        format!("{name}:\n  rows: {rows}\n  cols: {cols}\n  data: [{}]\n", list(v))
    };
    let identity = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let p = [c.fx, 0.0, c.cx, 0.0, 0.0, c.fy, c.cy, 0.0, 0.0, 0.0, 1.0, 0.0];
    let mut out = format!(
        "image_width: {}\nimage_height: {}\ncamera_name: {}\n",
        c.width,
        c.height,
        yaml_string(&info.camera_name)
    );
    out += &matrix("camera_matrix", 3, 3, &c.k());
    out += "distortion_model: plumb_bob\n";
    out += &matrix("distortion_coefficients", 1, 5, &c.distortion);
    out += &matrix("rectification_matrix", 3, 3, &identity);
    out += &matrix("projection_matrix", 3, 4, &p);
    out
}

/// A YAML scalar for a name: plain when safe, else double-quoted.
fn yaml_string(s: &str) -> String {
    let plain = !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || "_-./".contains(c));
    if plain { s.to_string() } else { format!("{s:?}") }
}

fn parse_ros(text: &str, path: &Path) -> Result<CameraInfo, CameraInfoError> {
    let file = path.to_path_buf();
    let doc: Value = serde_norway::from_str(text)
        .map_err(|e| CameraInfoError::Syntax { path: file.clone(), detail: e.to_string() })?;
    if !doc.is_mapping() {
        return Err(bad(path, "(document)", "a mapping of the camera_info fields", &describe(&doc)));
    }
    let field = |name: &str| {
        doc.get(name).ok_or_else(|| CameraInfoError::MissingField {
            path: file.clone(),
            field: name.to_string(),
            format: "ROS camera_info",
            needed: ROS_FIELDS.join(", "),
        })
    };
    let size = |name: &str| -> Result<u32, CameraInfoError> {
        let v = field(name)?;
        v.as_u64()
            .and_then(|n| u32::try_from(n).ok())
            .filter(|n| *n > 0)
            .ok_or_else(|| bad(path, name, "a positive integer (px)", &describe(v)))
    };
    let (width, height) = (size("image_width")?, size("image_height")?);
    let camera_name = match field("camera_name")? {
        Value::String(s) => s.clone(),
        Value::Null => String::new(),
        other => return Err(bad(path, "camera_name", "a string", &describe(other))),
    };
    let k = ros_matrix(path, field("camera_matrix")?, "camera_matrix", 3, 3)?;
    let model = match field("distortion_model")? {
        Value::String(s) => s.clone(),
        other => return Err(bad(path, "distortion_model", "a string such as plumb_bob", &describe(other))),
    };
    let d_node = field("distortion_coefficients")?;
    let d = ros_data(path, d_node, "distortion_coefficients")?;
    ros_matrix(path, field("rectification_matrix")?, "rectification_matrix", 3, 3)?;
    ros_matrix(path, field("projection_matrix")?, "projection_matrix", 3, 4)?;
    let distortion = plumb_bob(path, &model, &d)?;
    let intrinsics = intrinsics_from_k(path, "camera_matrix", &k, width, height, distortion)?;
    Ok(CameraInfo { camera_name, intrinsics, avg_reprojection_error_px: None })
}

/// `rows x cols` numbers from a `{rows, cols, data}` mapping, row-major.
fn ros_matrix(
    path: &Path,
    node: &Value,
    name: &str,
    rows: usize,
    cols: usize,
) -> Result<Vec<f64>, CameraInfoError> {
    let data = ros_data(path, node, name)?;
    let dim = |key: &str| node.get(key).and_then(Value::as_u64);
    if let (Some(r), Some(c)) = (dim("rows"), dim("cols"))
        && (r as usize, c as usize) != (rows, cols)
    {
        return Err(bad(path, name, &format!("a {rows}x{cols} matrix"), &format!("{r}x{c}")));
    }
    if data.len() != rows * cols {
        return Err(bad(
            path,
            &format!("{name}.data"),
            &format!("{} numbers", rows * cols),
            &format!("{}", data.len()),
        ));
    }
    Ok(data)
}

/// The `data` list of a ROS matrix (or a plain list).
fn ros_data(path: &Path, node: &Value, name: &str) -> Result<Vec<f64>, CameraInfoError> {
    let list = match node {
        Value::Sequence(s) => s,
        Value::Mapping(_) => match node.get("data") {
            Some(Value::Sequence(s)) => s,
            Some(other) => {
                return Err(bad(path, &format!("{name}.data"), "a list of numbers", &describe(other)));
            }
            None => {
                return Err(CameraInfoError::MissingField {
                    path: path.to_path_buf(),
                    field: format!("{name}.data"),
                    format: "ROS camera_info",
                    needed: "rows, cols, data".into(),
                });
            }
        },
        other => return Err(bad(path, name, "a mapping with rows, cols and data", &describe(other))),
    };
    list.iter()
        .map(|v| v.as_f64().filter(|x| x.is_finite()))
        .collect::<Option<Vec<f64>>>()
        .ok_or_else(|| bad(path, &format!("{name}.data"), "finite numbers", "something else"))
}

fn describe(v: &Value) -> String {
    let text = serde_norway::to_string(v).unwrap_or_default();
    let text = text.trim();
    if text.len() > 60 { format!("{}...", &text[..60]) } else { text.to_string() }
}

fn bad(path: &Path, field: &str, expected: &str, found: &str) -> CameraInfoError {
    CameraInfoError::BadField {
        path: path.to_path_buf(),
        field: field.to_string(),
        expected: expected.to_string(),
        found: found.to_string(),
    }
}

/// `[k1, k2, p1, p2, k3]` from a plumb-bob list (4 or 5 coefficients; a
/// longer rational list is accepted when its extra terms are zero).
fn plumb_bob(path: &Path, model: &str, d: &[f64]) -> Result<[f64; 5], CameraInfoError> {
    let known = matches!(model, "plumb_bob" | "rational_polynomial" | "opencv");
    let extra_zero = d.iter().skip(5).all(|x| *x == 0.0);
    if !known || d.len() < 4 || !extra_zero {
        return Err(CameraInfoError::UnsupportedDistortion {
            path: path.to_path_buf(),
            model: model.to_string(),
            coefficients: d.len(),
        });
    }
    let mut out = [0.0; 5];
    for (o, v) in out.iter_mut().zip(d) {
        *o = *v;
    }
    Ok(out)
}

fn intrinsics_from_k(
    path: &Path,
    name: &str,
    k: &[f64],
    width: u32,
    height: u32,
    distortion: [f64; 5],
) -> Result<CameraIntrinsics, CameraInfoError> {
    let (fx, fy, cx, cy) = (k[0], k[4], k[2], k[5]);
    let pinhole = k[1] == 0.0 && k[3] == 0.0 && k[6] == 0.0 && k[7] == 0.0 && k[8] == 1.0;
    if !(pinhole && fx > 0.0 && fy > 0.0) {
        let found = format!("{k:?}");
        return Err(bad(path, name, "[fx, 0, cx, 0, fy, cy, 0, 0, 1] with fx, fy > 0", &found));
    }
    Ok(CameraIntrinsics { width, height, fx, fy, cx, cy, distortion })
}

/// The OpenCV FileStorage YAML of `info`, written by OpenCV itself.
pub fn to_opencv_yaml(info: &CameraInfo, path: &Path) -> Result<String, CameraInfoError> {
    let cv =
        |operation| move |source| CameraInfoError::OpenCv { path: path.to_path_buf(), operation, source };
    let c = &info.intrinsics;
    let k = c.k();
    let camera_matrix = Mat::from_slice_2d(&[&k[0..3], &k[3..6], &k[6..9]]).map_err(cv("Mat"))?;
    let distortion = Mat::from_slice(&c.distortion).map_err(cv("Mat"))?;
    let distortion = distortion.reshape(1, 5).map_err(cv("Mat::reshape"))?;
    let flags = core::FileStorage_WRITE | core::FileStorage_MEMORY | core::FileStorage_FORMAT_YAML;
    let mut fs = FileStorage::new("calibration.yml", flags, "").map_err(cv("open"))?;
    let w = c.width.min(i32::MAX as u32) as i32;
    let h = c.height.min(i32::MAX as u32) as i32;
    core::write_str(&mut fs, "camera_name", &info.camera_name).map_err(cv("write"))?;
    core::write_i32(&mut fs, "image_width", w).map_err(cv("write"))?;
    core::write_i32(&mut fs, "image_height", h).map_err(cv("write"))?;
    core::write_mat(&mut fs, "camera_matrix", &camera_matrix).map_err(cv("write"))?;
    core::write_mat(&mut fs, "distortion_coefficients", &distortion).map_err(cv("write"))?;
    core::write_f64(&mut fs, "avg_reprojection_error", info.avg_reprojection_error_px.unwrap_or(0.0))
        .map_err(cv("write"))?;
    fs.release_and_get_string().map_err(cv("release"))
}

/// The fields read from OpenCV files; the size is optional.
const OPENCV_FIELDS: [&str; 2] = ["camera_matrix", "distortion_coefficients"];

fn parse_opencv(text: &str, path: &Path) -> Result<CameraInfo, CameraInfoError> {
    let file = path.to_path_buf();
    let cv = |operation| {
        let file = file.clone();
        move |source: opencv::Error| {
            if operation == "open" {
                CameraInfoError::Syntax { path: file.clone(), detail: source.message }
            } else {
                CameraInfoError::OpenCv { path: file.clone(), operation, source }
            }
        }
    };
    let flags = core::FileStorage_READ | core::FileStorage_MEMORY | core::FileStorage_FORMAT_YAML;
    let fs = FileStorage::new(text, flags, "").map_err(cv("open"))?;
    if !fs.is_opened().map_err(cv("open"))? {
        return Err(CameraInfoError::Syntax { path: file.clone(), detail: "OpenCV cannot parse it".into() });
    }
    let node = |name: &str| -> Result<Option<core::FileNode>, CameraInfoError> {
        let n = fs.get(name).map_err(cv("get"))?;
        Ok((!n.is_none().map_err(cv("get"))?).then_some(n))
    };
    let required = |name: &str| -> Result<core::FileNode, CameraInfoError> {
        node(name)?.ok_or_else(|| CameraInfoError::MissingField {
            path: file.clone(),
            field: name.to_string(),
            format: "OpenCV",
            needed: OPENCV_FIELDS.join(", "),
        })
    };
    let matrix = |name: &str| -> Result<Vec<f64>, CameraInfoError> {
        let m = required(name)?.mat().map_err(|_| bad(path, name, "an !!opencv-matrix", "something else"))?;
        mat_values(&m).ok_or_else(|| bad(path, name, "a matrix of numbers", "an empty or non-numeric matrix"))
    };
    let k = matrix("camera_matrix")?;
    if k.len() != 9 {
        return Err(bad(path, "camera_matrix", "a 3x3 matrix", &format!("{} values", k.len())));
    }
    let d = matrix("distortion_coefficients")?;
    let size = |name: &str| -> Result<u32, CameraInfoError> {
        match node(name)? {
            None => Ok(0),
            Some(n) => {
                let v = n.to_i32().map_err(cv("read"))?;
                u32::try_from(v)
                    .ok()
                    .filter(|v| *v > 0)
                    .ok_or_else(|| bad(path, name, "a positive integer", &v.to_string()))
            }
        }
    };
    let (width, height) = (size("image_width")?, size("image_height")?);
    let distortion = plumb_bob(path, "opencv", &d)?;
    let intrinsics = intrinsics_from_k(path, "camera_matrix", &k, width, height, distortion)?;
    let camera_name = match node("camera_name")? {
        Some(n) => n.string().map_err(cv("read"))?,
        None => "camera".to_string(),
    };
    let rms = match node("avg_reprojection_error")? {
        Some(n) => Some(n.real().map_err(cv("read"))?).filter(|v| v.is_finite() && *v > 0.0),
        None => None,
    };
    Ok(CameraInfo { camera_name, intrinsics, avg_reprojection_error_px: rms })
}

/// Every value of a matrix as `f64`, row-major.
fn mat_values(m: &Mat) -> Option<Vec<f64>> {
    if m.empty() {
        return None;
    }
    let mut as_f64 = Mat::default();
    m.convert_to(&mut as_f64, core::CV_64F, 1.0, 0.0).ok()?;
    let as_f64 = as_f64.try_clone().ok()?;
    let values = as_f64.data_typed::<f64>().ok()?.to_vec();
    values.iter().all(|v| v.is_finite()).then_some(values)
}

#[cfg(test)]
mod tests;
