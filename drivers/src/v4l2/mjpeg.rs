//! Camera frames as they come off V4L2: Motion-JPEG frames completed with
//! the standard Huffman tables (USB cameras omit them, most decoders need
//! them), JPEG decoding for detection, and conversions of raw formats.

use std::borrow::Cow;

use slidetrack_core::{EncodedImage, Image, PixelFormat};
use zune_jpeg::JpegDecoder;
use zune_jpeg::zune_core::bytestream::ZCursor;
use zune_jpeg::zune_core::colorspace::ColorSpace;
use zune_jpeg::zune_core::options::DecoderOptions;

/// Bits and values of one Huffman table (ITU-T T.81 Annex K.3).
struct StandardTable {
    /// Table class (0 DC, 1 AC) and id, as in the DHT segment.
    class_id: u8,
    bits: [u8; 16],
    values: &'static [u8],
}

const DC_VALUES: [u8; 12] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11];

#[rustfmt::skip]
const AC_LUMA_VALUES: [u8; 162] = [
    0x01, 0x02, 0x03, 0x00, 0x04, 0x11, 0x05, 0x12, 0x21, 0x31, 0x41, 0x06, 0x13, 0x51, 0x61, 0x07,
    0x22, 0x71, 0x14, 0x32, 0x81, 0x91, 0xa1, 0x08, 0x23, 0x42, 0xb1, 0xc1, 0x15, 0x52, 0xd1, 0xf0,
    0x24, 0x33, 0x62, 0x72, 0x82, 0x09, 0x0a, 0x16, 0x17, 0x18, 0x19, 0x1a, 0x25, 0x26, 0x27, 0x28,
    0x29, 0x2a, 0x34, 0x35, 0x36, 0x37, 0x38, 0x39, 0x3a, 0x43, 0x44, 0x45, 0x46, 0x47, 0x48, 0x49,
    0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58, 0x59, 0x5a, 0x63, 0x64, 0x65, 0x66, 0x67, 0x68, 0x69,
    0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a, 0x83, 0x84, 0x85, 0x86, 0x87, 0x88, 0x89,
    0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99, 0x9a, 0xa2, 0xa3, 0xa4, 0xa5, 0xa6, 0xa7,
    0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba, 0xc2, 0xc3, 0xc4, 0xc5,
    0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda, 0xe1, 0xe2,
    0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8, 0xe9, 0xea, 0xf1, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8,
    0xf9, 0xfa,
];

#[rustfmt::skip]
const AC_CHROMA_VALUES: [u8; 162] = [
    0x00, 0x01, 0x02, 0x03, 0x11, 0x04, 0x05, 0x21, 0x31, 0x06, 0x12, 0x41, 0x51, 0x07, 0x61, 0x71,
    0x13, 0x22, 0x32, 0x81, 0x08, 0x14, 0x42, 0x91, 0xa1, 0xb1, 0xc1, 0x09, 0x23, 0x33, 0x52, 0xf0,
    0x15, 0x62, 0x72, 0xd1, 0x0a, 0x16, 0x24, 0x34, 0xe1, 0x25, 0xf1, 0x17, 0x18, 0x19, 0x1a, 0x26,
    0x27, 0x28, 0x29, 0x2a, 0x35, 0x36, 0x37, 0x38, 0x39, 0x3a, 0x43, 0x44, 0x45, 0x46, 0x47, 0x48,
    0x49, 0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58, 0x59, 0x5a, 0x63, 0x64, 0x65, 0x66, 0x67, 0x68,
    0x69, 0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a, 0x82, 0x83, 0x84, 0x85, 0x86, 0x87,
    0x88, 0x89, 0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99, 0x9a, 0xa2, 0xa3, 0xa4, 0xa5,
    0xa6, 0xa7, 0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba, 0xc2, 0xc3,
    0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda,
    0xe2, 0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8, 0xe9, 0xea, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8,
    0xf9, 0xfa,
];

const STANDARD_TABLES: [StandardTable; 4] = [
    StandardTable {
        class_id: 0x00,
        bits: [0, 1, 5, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0],
        values: &DC_VALUES,
    },
    StandardTable {
        class_id: 0x10,
        bits: [0, 2, 1, 3, 3, 2, 4, 3, 5, 5, 4, 4, 0, 0, 1, 0x7d],
        values: &AC_LUMA_VALUES,
    },
    StandardTable {
        class_id: 0x01,
        bits: [0, 3, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0],
        values: &DC_VALUES,
    },
    StandardTable {
        class_id: 0x11,
        bits: [0, 2, 1, 2, 4, 4, 3, 4, 7, 5, 4, 4, 0, 1, 2, 0x77],
        values: &AC_CHROMA_VALUES,
    },
];

/// The DHT segment (marker included) holding the four standard tables.
fn standard_dht_segment() -> Vec<u8> {
    let body: usize = STANDARD_TABLES.iter().map(|t| 1 + 16 + t.values.len()).sum();
    let mut out = Vec::with_capacity(4 + body);
    out.extend_from_slice(&[0xFF, 0xC4]);
    out.extend_from_slice(&((body + 2) as u16).to_be_bytes());
    for t in &STANDARD_TABLES {
        out.push(t.class_id);
        out.extend_from_slice(&t.bits);
        out.extend_from_slice(t.values);
    }
    out
}

/// Offset of the start-of-scan marker when the header has no DHT segment;
/// `None` when it has one or cannot be parsed (then the frame is left alone).
fn sos_without_dht(jpeg: &[u8]) -> Option<usize> {
    if jpeg.get(..2)? != [0xFF, 0xD8] {
        return None;
    }
    let mut pos = 2;
    loop {
        if *jpeg.get(pos)? != 0xFF {
            return None;
        }
        let mut m = pos + 1;
        while *jpeg.get(m)? == 0xFF {
            m += 1; // fill bytes
        }
        let marker = jpeg[m];
        match marker {
            0xC4 => return None,
            0xDA => return Some(pos),
            0x01 | 0xD0..=0xD7 => pos = m + 1,
            _ => {
                let len = usize::from(u16::from_be_bytes([*jpeg.get(m + 1)?, *jpeg.get(m + 2)?]));
                if len < 2 {
                    return None;
                }
                pos = m + 1 + len;
            }
        }
    }
}

/// The frame with the standard Huffman tables inserted before its scan when
/// it has none (as Motion-JPEG from UVC cameras); otherwise unchanged.
pub fn with_huffman_tables(jpeg: &[u8]) -> Cow<'_, [u8]> {
    match sos_without_dht(jpeg) {
        None => Cow::Borrowed(jpeg),
        Some(at) => {
            let dht = standard_dht_segment();
            let mut out = Vec::with_capacity(jpeg.len() + dht.len());
            out.extend_from_slice(&jpeg[..at]);
            out.extend_from_slice(&dht);
            out.extend_from_slice(&jpeg[at..]);
            Cow::Owned(out)
        }
    }
}

/// Decodes a JPEG to 8-bit gray for detection; `None` when it does not
/// decode (the frame is then recorded without detection).
pub fn decode_gray(jpeg: &[u8]) -> Option<Image> {
    let options = DecoderOptions::default().jpeg_set_out_colorspace(ColorSpace::Luma);
    let mut decoder = JpegDecoder::new_with_options(ZCursor::new(jpeg), options);
    let data = decoder.decode().ok()?;
    let (width, height) = decoder.dimensions()?;
    let image = Image { width: width as u32, height: height as u32, format: PixelFormat::Gray8, data };
    (image.data.len() == width * height).then_some(image)
}

/// The luma of a YUYV (YUV 4:2:2) frame as 8-bit gray; `None` when the
/// buffer is shorter than `width * height * 2` bytes.
pub fn yuyv_to_gray(yuyv: &[u8], width: u32, height: u32) -> Option<Image> {
    let n = width as usize * height as usize;
    let data: Vec<u8> = yuyv.get(..2 * n)?.iter().step_by(2).copied().collect();
    Some(Image { width, height, format: PixelFormat::Gray8, data })
}

/// A YUYV frame as RGB (BT.601, limited range); `None` when too short.
pub fn yuyv_to_rgb(yuyv: &[u8], width: u32, height: u32) -> Option<Image> {
    let n = width as usize * height as usize;
    let src = yuyv.get(..2 * n)?;
    let mut data = Vec::with_capacity(3 * n);
    for q in src.chunks_exact(4) {
        let (u, v) = (f32::from(q[1]) - 128.0, f32::from(q[3]) - 128.0);
        for y in [q[0], q[2]] {
            let c = 1.164 * (f32::from(y) - 16.0);
            let px = [c + 1.596 * v, c - 0.392 * u - 0.813 * v, c + 2.017 * u];
            data.extend(px.map(|x| x.round().clamp(0.0, 255.0) as u8));
        }
    }
    Some(Image { width, height, format: PixelFormat::Rgb8, data })
}

/// A 16-bit depth frame (V4L2 `Z16`, little-endian) as a 16-bit gray PNG;
/// `None` when too short or the encoder fails.
pub fn z16_to_png(z16: &[u8], width: u32, height: u32) -> Option<EncodedImage> {
    let n = width as usize * height as usize;
    let src = z16.get(..2 * n)?;
    // PNG samples are big-endian.
    let be: Vec<u8> = src.chunks_exact(2).flat_map(|p| [p[1], p[0]]).collect();
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Sixteen);
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder.write_header().ok()?;
    writer.write_image_data(&be).ok()?;
    writer.finish().ok()?;
    Some(EncodedImage { format: "png".into(), bytes })
}

#[cfg(test)]
pub(crate) mod tests;
