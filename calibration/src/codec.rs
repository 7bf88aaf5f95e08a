//! JPEG and PNG images to and from their bytes, without OpenCV's
//! `imgcodecs`.
//!
//! JPEG goes through the system's libjpeg-turbo (its TurboJPEG API), the
//! library Debian's OpenCV decodes and encodes JPEG with, so a decoded
//! photo has the pixels `imread` gave it; PNG through the `png` crate.
//! Linking `imgcodecs` loaded GDAL and about 120 more shared libraries on
//! every process start: 108 ms of CPU each time, against 7 ms for the
//! OpenCV modules the workspace still links (issue 29, `perf stat` of an
//! empty program linked with and without it).
//!
//! Gray from colour is OpenCV's: `cvtColor`'s BT.601 weights in 14-bit
//! fixed point for PNG, the JPEG's own luma for JPEG (what `imread`'s
//! `IMREAD_GRAYSCALE` asks libjpeg for).

use slidetrack_core::{EncodedImage, Image, PixelFormat};

pub use crate::error::CodecError;
use crate::error::MarkerError;

/// The compressed formats read here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageKind {
    /// JPEG (`FF D8 FF`).
    Jpeg,
    /// PNG (its 8-byte signature).
    Png,
}

impl ImageKind {
    /// The format of `bytes`, from their first bytes.
    pub fn of(bytes: &[u8]) -> Result<ImageKind, CodecError> {
        if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
            Ok(ImageKind::Jpeg)
        } else if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
            Ok(ImageKind::Png)
        } else {
            Err(CodecError::UnknownFormat { start: bytes[..bytes.len().min(8)].to_vec() })
        }
    }
}

/// Decodes JPEG or PNG bytes to 8-bit `format`, as OpenCV's `imdecode`
/// with `IMREAD_COLOR` (`Rgb8`; RGB, not its BGR) or `IMREAD_GRAYSCALE`
/// (`Gray8`) does: alpha is dropped, 16-bit samples keep their high byte,
/// gray is replicated into colour.
pub fn decode(bytes: &[u8], format: PixelFormat) -> Result<Image, CodecError> {
    match ImageKind::of(bytes)? {
        ImageKind::Jpeg => {
            let pixel = match format {
                PixelFormat::Gray8 => turbojpeg::PixelFormat::GRAY,
                PixelFormat::Rgb8 => turbojpeg::PixelFormat::RGB,
            };
            let image = turbojpeg::decompress(bytes, pixel)?;
            let row = image.width * format.channels();
            // Rows are packed unless libjpeg-turbo padded them.
            let data = if image.pitch == row {
                image.pixels
            } else {
                image.pixels.chunks(image.pitch).flat_map(|r| &r[..row]).copied().collect()
            };
            Ok(Image { width: image.width as u32, height: image.height as u32, format, data })
        }
        ImageKind::Png => decode_png8(bytes, format),
    }
}

/// The width and height (px) of JPEG or PNG bytes, from their header.
pub fn dimensions(bytes: &[u8]) -> Result<(u32, u32), CodecError> {
    match ImageKind::of(bytes)? {
        ImageKind::Jpeg => {
            let header = turbojpeg::read_header(bytes)?;
            Ok((header.width as u32, header.height as u32))
        }
        ImageKind::Png => {
            let reader = png::Decoder::new(bytes).read_info()?;
            let info = reader.info();
            Ok((info.width, info.height))
        }
    }
}

fn decode_png8(bytes: &[u8], format: PixelFormat) -> Result<Image, CodecError> {
    let mut decoder = png::Decoder::new(bytes);
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder.read_info()?;
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf)?;
    buf.truncate(info.buffer_size());
    let (width, height) = (info.width, info.height);
    let source = info.color_type.samples();
    let data = match (format, info.color_type) {
        (PixelFormat::Gray8, png::ColorType::Grayscale) | (PixelFormat::Rgb8, png::ColorType::Rgb) => buf,
        (PixelFormat::Gray8, png::ColorType::GrayscaleAlpha) => buf.chunks_exact(2).map(|p| p[0]).collect(),
        (PixelFormat::Gray8, _) => buf.chunks_exact(source).map(|p| gray_of_rgb(p[0], p[1], p[2])).collect(),
        (PixelFormat::Rgb8, png::ColorType::Grayscale | png::ColorType::GrayscaleAlpha) => {
            buf.chunks_exact(source).flat_map(|p| [p[0]; 3]).collect()
        }
        (PixelFormat::Rgb8, _) => buf.chunks_exact(source).flat_map(|p| [p[0], p[1], p[2]]).collect(),
    };
    Ok(Image { width, height, format, data })
}

/// OpenCV's `cvtColor(RGB2GRAY)` on 8 bits: `0.299 R + 0.587 G + 0.114 B`
/// with its 14-bit fixed-point weights, rounded.
fn gray_of_rgb(r: u8, g: u8, b: u8) -> u8 {
    const R: u32 = 4899;
    const G: u32 = 9617;
    const B: u32 = 1868;
    ((R * u32::from(r) + G * u32::from(g) + B * u32::from(b) + (1 << 13)) >> 14) as u8
}

/// Decodes a 16-bit single-channel PNG (a depth image): width, height (px)
/// and its values row by row.
pub fn decode_png16(bytes: &[u8]) -> Result<(u32, u32, Vec<u16>), CodecError> {
    if ImageKind::of(bytes)? != ImageKind::Png {
        return Err(CodecError::Unsupported("a depth image must be a 16-bit PNG, not a JPEG".into()));
    }
    let mut reader = png::Decoder::new(bytes).read_info()?;
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf)?;
    if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Sixteen {
        return Err(CodecError::Unsupported(format!(
            "not a 16-bit single-channel image ({:?}, {:?}-bit)",
            info.color_type, info.bit_depth
        )));
    }
    let values =
        buf[..info.buffer_size()].chunks_exact(2).map(|b| u16::from_be_bytes([b[0], b[1]])).collect();
    Ok((info.width, info.height, values))
}

/// Encodes `image` as JPEG at `quality` (1-100): 4:2:0 chroma for colour,
/// as OpenCV's `imencode` does by default.
pub fn encode_jpeg(image: &Image, quality: u8) -> Result<EncodedImage, MarkerError> {
    MarkerError::check_bytes(image)?;
    let (pixel, subsamp) = match image.format {
        PixelFormat::Gray8 => (turbojpeg::PixelFormat::GRAY, turbojpeg::Subsamp::Gray),
        PixelFormat::Rgb8 => (turbojpeg::PixelFormat::RGB, turbojpeg::Subsamp::Sub2x2),
    };
    let width = image.width as usize;
    let view = turbojpeg::Image {
        pixels: &image.data[..],
        width,
        pitch: width * image.format.channels(),
        height: image.height as usize,
        format: pixel,
    };
    let bytes = turbojpeg::compress(view, i32::from(quality.clamp(1, 100)), subsamp)
        .map_err(|e| MarkerError::Encode { format: "JPEG", detail: e.to_string() })?;
    Ok(EncodedImage { format: "jpeg".into(), bytes: bytes.to_vec() })
}

/// Encodes an 8-bit image (gray or RGB) as PNG, with OpenCV's default
/// settings for speed (the `Sub` filter, the fastest compression).
pub fn encode_png(image: &Image) -> Result<EncodedImage, MarkerError> {
    MarkerError::check_bytes(image)?;
    let color = match image.format {
        PixelFormat::Gray8 => png::ColorType::Grayscale,
        PixelFormat::Rgb8 => png::ColorType::Rgb,
    };
    let bytes = write_png(image.width, image.height, color, png::BitDepth::Eight, &image.data)
        .map_err(|e| MarkerError::Encode { format: "PNG", detail: e.to_string() })?;
    Ok(EncodedImage { format: "png".into(), bytes })
}

/// Encodes 16-bit values (`width x height`, row by row) as a one-channel
/// PNG.
pub fn encode_png16(width: u32, height: u32, values: &[u16]) -> Result<Vec<u8>, CodecError> {
    if values.len() != width as usize * height as usize || width == 0 || height == 0 {
        return Err(CodecError::Unsupported(format!("{width}x{height} px with {} values", values.len())));
    }
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_be_bytes()).collect();
    write_png(width, height, png::ColorType::Grayscale, png::BitDepth::Sixteen, &bytes)
}

fn write_png(
    width: u32,
    height: u32,
    color: png::ColorType,
    depth: png::BitDepth,
    data: &[u8],
) -> Result<Vec<u8>, CodecError> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, width, height);
    encoder.set_color(color);
    encoder.set_depth(depth);
    encoder.set_compression(png::Compression::Fast);
    encoder.set_filter(png::FilterType::Sub);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(data)?;
    writer.finish()?;
    Ok(out)
}

#[cfg(test)]
#[path = "codec_tests.rs"]
mod tests;
