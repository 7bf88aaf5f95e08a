//! Images as they travel between cameras, detectors and the recorder.

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Pixel layout of an [`Image`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum PixelFormat {
    /// 8-bit luminance, one byte per pixel.
    Gray8,
    /// 8-bit red, green, blue, three bytes per pixel.
    Rgb8,
}

impl PixelFormat {
    /// Bytes per pixel.
    pub fn channels(self) -> usize {
        match self {
            PixelFormat::Gray8 => 1,
            PixelFormat::Rgb8 => 3,
        }
    }
}

/// A decoded image, rows top to bottom, no padding.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
    /// Pixel layout.
    pub format: PixelFormat,
    /// `width * height * format.channels()` bytes.
    pub data: Vec<u8>,
}

impl Image {
    /// A black image.
    pub fn zeros(width: u32, height: u32, format: PixelFormat) -> Image {
        let n = width as usize * height as usize * format.channels();
        Image { width, height, format, data: vec![0; n] }
    }

    /// Bytes per row.
    pub fn stride(&self) -> usize {
        self.width as usize * self.format.channels()
    }
}

/// An image still in its compressed form, as a camera delivered it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EncodedImage {
    /// Format name as Foxglove's `CompressedImage.format` uses it: `jpeg` or `png`.
    pub format: String,
    /// The compressed bytes.
    pub bytes: Vec<u8>,
}

/// Why an image could not be encoded as JPEG.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum JpegError {
    /// The image size is zero or too large for JPEG (65535 px per side).
    #[error("image size {width}x{height} px is not usable (1..=65535 px per side)")]
    BadImageSize {
        /// Width (px).
        width: u32,
        /// Height (px).
        height: u32,
    },
    /// The encoder refused the image.
    #[error("JPEG encoding failed")]
    Encoder(#[from] jpeg_encoder::EncodingError),
}

/// Encodes an image as baseline JPEG (4:2:0 chroma below quality 90).
pub fn encode_jpeg(image: &Image, quality: u8) -> Result<EncodedImage, JpegError> {
    let too_big = || JpegError::BadImageSize { width: image.width, height: image.height };
    let width = u16::try_from(image.width).map_err(|_| too_big())?;
    let height = u16::try_from(image.height).map_err(|_| too_big())?;
    let colour = match image.format {
        PixelFormat::Gray8 => jpeg_encoder::ColorType::Luma,
        PixelFormat::Rgb8 => jpeg_encoder::ColorType::Rgb,
    };
    let mut bytes = Vec::with_capacity(image.data.len() / 8);
    jpeg_encoder::Encoder::new(&mut bytes, quality.clamp(1, 100)).encode(
        &image.data,
        width,
        height,
        colour,
    )?;
    Ok(EncodedImage { format: "jpeg".to_owned(), bytes })
}
