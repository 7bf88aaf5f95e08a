//! Images as they travel between cameras, detectors and the recorder.

use serde::{Deserialize, Serialize};

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
