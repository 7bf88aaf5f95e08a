//! Colour and depth images to and from their compressed forms (JPEG, PNG),
//! through `slidetrack_calibration::codec` (libjpeg-turbo and the `png`
//! crate, not OpenCV's imgcodecs).

use std::path::Path;

use slidetrack_calibration::codec::{self, CodecError};
use slidetrack_core::{DepthImage, EncodedImage, Image, PixelFormat};

use crate::VisionError;

/// Decodes a compressed colour image (JPEG, PNG) to RGB8.
pub fn decode_color(bytes: &[u8]) -> Result<Image, VisionError> {
    codec::decode(bytes, PixelFormat::Rgb8).map_err(|e| bad("colour image", &e))
}

/// Encodes an RGB8 colour image as JPEG (`quality` 1-100) for
/// `foxglove.CompressedImage` channels.
pub fn encode_color_jpeg(image: &Image, quality: i32) -> Result<EncodedImage, VisionError> {
    // The codec checks the byte count; it also takes gray, which this does not.
    if image.format != PixelFormat::Rgb8 {
        return Err(VisionError::BadImage {
            what: "colour image",
            detail: format!("{}x{} px {:?} is not RGB8", image.width, image.height, image.format),
        });
    }
    codec::encode_jpeg(image, quality.clamp(1, 100) as u8)
        .map_err(|e| VisionError::BadImage { what: "colour image", detail: e.to_string() })
}

/// Decodes a 16-bit PNG depth image; `scale_m` metres per unit.
pub fn decode_depth(bytes: &[u8], scale_m: f64) -> Result<DepthImage, VisionError> {
    let (width, height, data) = codec::decode_png16(bytes).map_err(|e| bad("depth image", &e))?;
    Ok(DepthImage { width, height, data, scale_m })
}

/// A codec error as a bad image.
pub(crate) fn bad(what: &'static str, e: &CodecError) -> VisionError {
    VisionError::BadImage { what, detail: e.to_string() }
}

/// Reads the image file `path` and decodes it with `decode`; a missing
/// file is an I/O error, bytes that do not decode name the file.
pub(crate) fn decode_file<T>(
    path: &Path,
    decode: impl FnOnce(&[u8]) -> Result<T, CodecError>,
) -> Result<T, VisionError> {
    let bytes = std::fs::read(path).map_err(|source| VisionError::Io { path: path.into(), source })?;
    decode(&bytes).map_err(|e| VisionError::BadFile { path: path.into(), detail: e.to_string() })
}

/// Encodes a depth image as a 16-bit PNG (its raw units; the scale is not kept).
pub fn encode_depth_png(depth: &DepthImage) -> Result<EncodedImage, VisionError> {
    let bytes =
        codec::encode_png16(depth.width, depth.height, &depth.data).map_err(|e| bad("depth image", &e))?;
    Ok(EncodedImage { format: "png".into(), bytes })
}
