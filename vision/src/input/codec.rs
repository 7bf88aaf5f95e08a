//! Colour and depth images to and from their compressed forms (JPEG, PNG)
//! and OpenCV matrices.

use opencv::core::{Mat, Vector};
use opencv::imgcodecs;
use opencv::prelude::*;
use slidetrack_core::{DepthImage, EncodedImage, Image, PixelFormat};

use crate::VisionError;
use crate::error::OpenCvContext;

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
