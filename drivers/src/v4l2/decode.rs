//! What a captured V4L2 buffer becomes, as pure functions of its bytes (so
//! that tests run on byte streams without a device): rows unpadded to the
//! driver's stride, the pixels for detection and the bytes to record, and
//! the count of frames the driver flagged as erroneous.

use std::borrow::Cow;
use std::sync::atomic::{AtomicU64, Ordering};

use slidetrack_core::{EncodedImage, Image, PixelFormat};

use crate::v4l2::config::V4l2PixelFormat;
use crate::v4l2::mjpeg;

/// How the driver lays a frame out in its buffer (`struct v4l2_pix_format`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameLayout {
    /// Pixel format.
    pub format: V4l2PixelFormat,
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
    /// Bytes from one row's start to the next (`bytesperline`); it may
    /// exceed `width` times the bytes per pixel (padded rows). 0 (what
    /// drivers report for compressed formats) means packed rows.
    pub bytes_per_line: u32,
}

impl FrameLayout {
    /// A layout with packed rows.
    pub fn packed(format: V4l2PixelFormat, width: u32, height: u32) -> FrameLayout {
        FrameLayout { format, width, height, bytes_per_line: 0 }
    }

    /// The frame's pixel bytes with the row padding removed; `None` for MJPG
    /// (not row-based), or when the buffer is too short for `height` rows
    /// or `bytes_per_line` is shorter than a row.
    pub fn packed_rows<'a>(&self, bytes: &'a [u8]) -> Option<Cow<'a, [u8]>> {
        let row = self.width as usize * self.format.bytes_per_pixel()? as usize;
        let stride = if self.bytes_per_line == 0 { row } else { self.bytes_per_line as usize };
        let height = self.height as usize;
        if stride < row || height == 0 {
            return None;
        }
        // The last row need not carry its padding.
        let needed = stride * (height - 1) + row;
        let bytes = bytes.get(..needed)?;
        if stride == row {
            return Some(Cow::Borrowed(bytes));
        }
        let mut packed = Vec::with_capacity(row * height);
        for r in 0..height {
            packed.extend_from_slice(&bytes[r * stride..r * stride + row]);
        }
        Some(Cow::Owned(packed))
    }
}

/// What a captured buffer laid out as `layout` becomes: gray pixels for
/// detection and the bytes to record.
///
/// - MJPG: the bytes as the camera sent them (only the standard Huffman
///   tables inserted when the frame has none; never re-encoded), and their
///   luma when they decode (`None` for a corrupt frame, still recorded).
/// - YUYV: the luma, and the colour image JPEG-encoded at `jpeg_quality`.
/// - GREY: the pixels, and the gray image JPEG-encoded at `jpeg_quality`.
/// - Z16: no pixels, the depth as 16-bit PNG (the raw units; the metres per
///   unit are the camera's depth scale).
///
/// A buffer too short for its layout gives `None` for what it cannot fill.
pub fn frame_content(
    layout: &FrameLayout,
    jpeg_quality: u8,
    bytes: &[u8],
) -> (Option<Image>, Option<EncodedImage>) {
    let (width, height) = (layout.width, layout.height);
    if layout.format == V4l2PixelFormat::Mjpg {
        let jpeg = mjpeg::with_huffman_tables(bytes).into_owned();
        let pixels = mjpeg::decode_gray(&jpeg);
        return (pixels, Some(EncodedImage { format: "jpeg".into(), bytes: jpeg }));
    }
    let Some(rows) = layout.packed_rows(bytes) else {
        return (None, None);
    };
    match layout.format {
        V4l2PixelFormat::Yuyv => {
            let encoded = mjpeg::yuyv_to_rgb(&rows, width, height)
                .and_then(|rgb| slidetrack_core::encode_jpeg(&rgb, jpeg_quality).ok());
            (mjpeg::yuyv_to_gray(&rows, width, height), encoded)
        }
        V4l2PixelFormat::Grey => {
            let gray = Image { width, height, format: PixelFormat::Gray8, data: rows.into_owned() };
            let encoded = slidetrack_core::encode_jpeg(&gray, jpeg_quality).ok();
            (Some(gray), encoded)
        }
        V4l2PixelFormat::Z16 => (None, mjpeg::z16_to_png(&rows, width, height)),
        V4l2PixelFormat::Mjpg => (None, None),
    }
}

/// `V4L2_BUF_FLAG_ERROR` (`videodev2.h`): the driver delivered the buffer
/// but its data may be corrupt (a transfer error).
pub const BUF_FLAG_ERROR: u32 = 0x0000_0040;

/// Counts of a capture: frames delivered, frames the driver flagged as
/// erroneous (dropped), and frames dropped because the reader fell behind.
/// Shared between the capture thread and whoever reports them.
#[derive(Debug, Default)]
pub struct CaptureCounters {
    delivered: AtomicU64,
    erroneous: AtomicU64,
    overrun: AtomicU64,
}

impl CaptureCounters {
    /// Whether a buffer with the driver's `flags` is kept; a buffer flagged
    /// [`BUF_FLAG_ERROR`] is not, and is counted.
    pub fn accept(&self, flags: u32) -> bool {
        if flags & BUF_FLAG_ERROR != 0 {
            self.erroneous.fetch_add(1, Ordering::Relaxed);
            false
        } else {
            true
        }
    }

    /// Counts a frame handed to the reader.
    pub fn delivered_one(&self) {
        self.delivered.fetch_add(1, Ordering::Relaxed);
    }

    /// Counts a frame dropped because the reader's queue was full.
    pub fn overrun_one(&self) {
        self.overrun.fetch_add(1, Ordering::Relaxed);
    }

    /// Frames handed to the reader.
    pub fn delivered(&self) -> u64 {
        self.delivered.load(Ordering::Relaxed)
    }

    /// Frames the driver flagged as erroneous, dropped.
    pub fn erroneous(&self) -> u64 {
        self.erroneous.load(Ordering::Relaxed)
    }

    /// Frames dropped because the reader fell behind.
    pub fn overrun(&self) -> u64 {
        self.overrun.load(Ordering::Relaxed)
    }
}

impl std::fmt::Display for CaptureCounters {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} frames delivered, {} flagged erroneous by the driver and dropped, {} dropped while the reader was behind",
            self.delivered(),
            self.erroneous(),
            self.overrun()
        )
    }
}
