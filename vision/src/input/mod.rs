//! RGB-D inputs: recorded sessions ([`SessionRgbd`]), YCB-Video-style
//! directories of PNGs ([`YcbDirectory`]) and live cameras, a colour camera paired with a Z16 depth camera
//! ([`CameraPair`], for example two V4L2 devices, or a recording replayed
//! in real time as two cameras, [`RecordedRgbd`], with its truth
//! [`RecordedTruth`]), and depth registered to the colour camera
//! ([`register_depth_to_color`]).

mod camera_pair;
mod recorded;
mod recorded_truth;
pub mod registration;
mod session;
mod ycb;

pub use camera_pair::{CameraPair, DepthRegistration, Pacer, PairCounts, PairSettings};
pub use recorded::{RecordedCamera, RecordedRgbd, ReplayCounts, ReplayOptions};
pub use recorded_truth::RecordedTruth;
pub use registration::register_depth_to_color;
pub use session::SessionRgbd;
pub use ycb::{YCB_CLASSES, YcbDirectory, YcbMeta, read_meta};

use opencv::core::{Mat, Vector};
use opencv::imgcodecs;
use opencv::prelude::*;
use slidetrack_core::{
    CameraIntrinsics, DepthImage, EncodedImage, Image, ObjectTruth, PixelFormat, RgbdFrame,
};
use slidetrack_estimators::roft::Mask;

use crate::VisionError;
use crate::error::OpenCvContext;

/// One frame of an input, with the truth that comes with it (simulated
/// sessions and annotated datasets).
#[derive(Clone, Debug)]
pub struct RgbdSample {
    /// The frame.
    pub frame: RgbdFrame,
    /// The object's true pose and velocity.
    pub truth: Option<ObjectTruth>,
    /// The object's true mask.
    pub truth_mask: Option<Mask>,
}

/// A source of RGB-D frames.
///
/// # Contract
/// `next` returns frames in acquisition order, `Ok(None)` at the end (live
/// cameras: when no frame is ready yet is not the end — they block until
/// one is). Every frame has the source's intrinsics and size.
pub trait RgbdSource {
    /// The intrinsics of every frame.
    fn intrinsics(&self) -> &CameraIntrinsics;
    /// The next frame.
    fn next_frame(&mut self) -> Result<Option<RgbdSample>, VisionError>;
    /// Number of frames, when known.
    fn len_hint(&self) -> Option<usize> {
        None
    }
}

/// Decodes a compressed colour image (JPEG, PNG) to RGB8.
pub fn decode_color(bytes: &[u8]) -> Result<Image, VisionError> {
    let mat = imgcodecs::imdecode(&Vector::<u8>::from_slice(bytes), imgcodecs::IMREAD_COLOR)
        .cv("imdecode colour")?;
    bgr_mat_to_rgb(&mat, "colour image")
}

/// Encodes an RGB8 colour image as JPEG (`quality` 1-100) for
/// `foxglove.CompressedImage` channels.
pub fn encode_color_jpeg(image: &Image, quality: i32) -> Result<EncodedImage, VisionError> {
    if image.format != PixelFormat::Rgb8
        || image.data.len() != image.width as usize * image.height as usize * 3
        || image.width == 0
    {
        return Err(VisionError::BadImage {
            what: "colour image",
            detail: format!(
                "{}x{} px {:?} with {} bytes is not RGB8",
                image.width,
                image.height,
                image.format,
                image.data.len()
            ),
        });
    }
    let flat = Mat::from_slice(&image.data).cv("colour bytes")?;
    let rgb = flat.reshape(3, image.height as i32).cv("colour reshape")?;
    let mut bgr = Mat::default();
    opencv::imgproc::cvt_color_def(&rgb, &mut bgr, opencv::imgproc::COLOR_RGB2BGR).cv("cvtColor")?;
    let mut out = Vector::<u8>::new();
    let params = Vector::<i32>::from_slice(&[imgcodecs::IMWRITE_JPEG_QUALITY, quality.clamp(1, 100)]);
    imgcodecs::imencode(".jpg", &bgr, &mut out, &params).cv("imencode JPEG")?;
    Ok(EncodedImage { format: "jpeg".into(), bytes: out.to_vec() })
}

/// Decodes a 16-bit PNG depth image; `scale_m` metres per unit.
pub fn decode_depth(bytes: &[u8], scale_m: f64) -> Result<DepthImage, VisionError> {
    let mat = imgcodecs::imdecode(&Vector::<u8>::from_slice(bytes), imgcodecs::IMREAD_ANYDEPTH)
        .cv("imdecode depth")?;
    depth_mat(&mat, scale_m, "depth image")
}

/// An 8-bit BGR OpenCV image as RGB8.
pub(crate) fn bgr_mat_to_rgb(mat: &Mat, what: &'static str) -> Result<Image, VisionError> {
    if mat.empty() || mat.typ() != opencv::core::CV_8UC3 {
        return Err(VisionError::BadImage { what, detail: "not an 8-bit colour image".into() });
    }
    let mut rgb = Mat::default();
    opencv::imgproc::cvt_color_def(mat, &mut rgb, opencv::imgproc::COLOR_BGR2RGB).cv("cvtColor")?;
    let data = rgb.data_bytes().cv("colour bytes")?.to_vec();
    Ok(Image { width: rgb.cols() as u32, height: rgb.rows() as u32, format: PixelFormat::Rgb8, data })
}

/// Encodes a depth image as a 16-bit PNG (its raw units; the scale is not kept).
pub fn encode_depth_png(depth: &DepthImage) -> Result<EncodedImage, VisionError> {
    if depth.data.len() != depth.width as usize * depth.height as usize || depth.width == 0 {
        return Err(VisionError::BadImage {
            what: "depth image",
            detail: format!("{}x{} px with {} values", depth.width, depth.height, depth.data.len()),
        });
    }
    let flat = Mat::from_slice(&depth.data).cv("depth values")?;
    let mat = flat.reshape(1, depth.height as i32).cv("depth reshape")?;
    let mut out = Vector::<u8>::new();
    imgcodecs::imencode(".png", &mat, &mut out, &Vector::new()).cv("imencode PNG")?;
    Ok(EncodedImage { format: "png".into(), bytes: out.to_vec() })
}

/// A 16-bit one-channel OpenCV image as a depth image.
pub(crate) fn depth_mat(mat: &Mat, scale_m: f64, what: &'static str) -> Result<DepthImage, VisionError> {
    if mat.empty() || mat.typ() != opencv::core::CV_16UC1 {
        return Err(VisionError::BadImage { what, detail: "not a 16-bit single-channel image".into() });
    }
    let data = mat.data_typed::<u16>().cv("depth data")?.to_vec();
    Ok(DepthImage { width: mat.cols() as u32, height: mat.rows() as u32, data, scale_m })
}
