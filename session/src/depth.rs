//! `/rgbd/depth`: depth frames stored losslessly and compactly.
//!
//! A depth frame is a 16-bit greyscale PNG (millimetres, 0 = no depth) in a
//! `foxglove.CompressedImage` with `format` `png`: lossless, 8x smaller per
//! message than the `16UC1` `foxglove.RawImage` that sessions written
//! before held on the same topic (base64 of the raw pixels) on real depth,
//! only 2.8x on the simulator's noisy depth (`docs/session-format.md`). Readers accept
//! both forms ([`RgbdDepth`] deserialises either); writers write the PNG.
//! `docs/session-format.md` says why this form.

use serde::{Deserialize, Serialize};
use serde_json::Value;
use slidetrack_core::{DepthImage, EncodedImage, TimeNs};
use thiserror::Error;

use super::channel::ChannelMessage;
use super::schema::Foxglove;
use super::vision::CompressedImage;
use super::vision_pose::RawImage;

/// A depth image that cannot be stored or read back.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum DepthCodecError {
    /// A depth image whose size does not match its values.
    #[error("depth image {width}x{height} px has {values} values")]
    Size {
        /// Width (px).
        width: u32,
        /// Height (px).
        height: u32,
        /// Number of values.
        values: usize,
    },
    /// The PNG encoder refused the image.
    #[error("cannot encode the depth image as PNG: {0}")]
    Encode(String),
    /// The bytes are not a 16-bit greyscale PNG.
    #[error("a /rgbd/depth message is not a 16-bit greyscale PNG: {0}")]
    Decode(String),
    /// An old-form message that is not `16UC1` of its stated size.
    #[error(
        "a /rgbd/depth RawImage is not 16UC1 of its stated size ({encoding}, {width}x{height} px, {bytes} bytes)"
    )]
    Raw {
        /// Its `encoding`.
        encoding: String,
        /// Its `width` (px).
        width: u32,
        /// Its `height` (px).
        height: u32,
        /// Its number of data bytes.
        bytes: usize,
    },
}

/// `/rgbd/depth`: one depth frame, registered to the colour camera.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum RgbdDepth {
    /// A 16-bit greyscale PNG of millimetres (`format` `png`): what is written.
    Png(CompressedImage),
    /// `16UC1` millimetres, little-endian (`foxglove.RawImage`): sessions
    /// written before the PNG form; read, never written.
    Raw(RawImage),
}

impl RgbdDepth {
    /// The frame `depth` (converted to millimetres) acquired at `t`, as a
    /// 16-bit PNG.
    pub fn new(t: TimeNs, frame_id: &str, depth: &DepthImage) -> Result<RgbdDepth, DepthCodecError> {
        let png = encode_depth_mm_png(&depth.to_millimetres())?;
        Ok(RgbdDepth::Png(CompressedImage::new(t, frame_id, &png)))
    }

    /// The depth back (millimetres, `scale_m` 0.001), from either form.
    pub fn to_depth(&self) -> Result<DepthImage, DepthCodecError> {
        match self {
            RgbdDepth::Png(c) if c.format == "png" => decode_depth_mm_png(&c.data),
            RgbdDepth::Png(c) => Err(DepthCodecError::Decode(format!("format is {:?}, not png", c.format))),
            RgbdDepth::Raw(r) => r.to_depth().ok_or_else(|| DepthCodecError::Raw {
                encoding: r.encoding.clone(),
                width: r.width,
                height: r.height,
                bytes: r.data.len(),
            }),
        }
    }

    /// The frame as a 16-bit PNG of millimetres: the stored bytes of the
    /// PNG form, the old form encoded.
    pub fn to_png(&self) -> Result<EncodedImage, DepthCodecError> {
        match self {
            RgbdDepth::Png(c) if c.format == "png" => {
                Ok(EncodedImage { format: "png".into(), bytes: c.data.clone() })
            }
            _ => encode_depth_mm_png(&self.to_depth()?),
        }
    }
}

impl ChannelMessage for RgbdDepth {
    const TOPIC: &'static str = "/rgbd/depth";
    const SCHEMA_NAME: &'static str = "foxglove.CompressedImage";
    fn json_schema() -> Value {
        Foxglove::CompressedImage.schema()
    }
}

/// Encodes depth values as they are (the scale is not kept) as a 16-bit
/// greyscale PNG: rows filtered with PNG's `Up` filter (each row minus the
/// one above, which a smooth depth map makes mostly small), then deflated.
pub fn encode_depth_mm_png(depth: &DepthImage) -> Result<EncodedImage, DepthCodecError> {
    let (width, height) = (depth.width, depth.height);
    if width == 0 || height == 0 || depth.data.len() != width as usize * height as usize {
        return Err(DepthCodecError::Size { width, height, values: depth.data.len() });
    }
    let big_endian: Vec<u8> = depth.data.iter().flat_map(|d| d.to_be_bytes()).collect();
    let mut bytes = Vec::with_capacity(big_endian.len() / 4);
    let encode = |bytes: &mut Vec<u8>| -> Result<(), png::EncodingError> {
        let mut encoder = png::Encoder::new(bytes, width, height);
        encoder.set_color(png::ColorType::Grayscale);
        encoder.set_depth(png::BitDepth::Sixteen);
        encoder.set_compression(png::Compression::Default);
        encoder.set_filter(png::FilterType::Up);
        encoder.set_adaptive_filter(png::AdaptiveFilterType::NonAdaptive);
        let mut writer = encoder.write_header()?;
        writer.write_image_data(&big_endian)?;
        writer.finish()
    };
    encode(&mut bytes).map_err(|e| DepthCodecError::Encode(e.to_string()))?;
    Ok(EncodedImage { format: "png".into(), bytes })
}

/// Decodes a 16-bit greyscale PNG to its values (millimetres, `scale_m`
/// 0.001); anything else is refused, never converted.
pub fn decode_depth_mm_png(bytes: &[u8]) -> Result<DepthImage, DepthCodecError> {
    let bad = |e: &dyn std::fmt::Display| DepthCodecError::Decode(e.to_string());
    let mut decoder = png::Decoder::new(bytes);
    decoder.set_transformations(png::Transformations::IDENTITY);
    let mut reader = decoder.read_info().map_err(|e| bad(&e))?;
    let (color, depth) = reader.output_color_type();
    if color != png::ColorType::Grayscale || depth != png::BitDepth::Sixteen {
        return Err(bad(&format!("{color:?} {depth:?}")));
    }
    let mut buffer = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buffer).map_err(|e| bad(&e))?;
    let data =
        buffer[..info.buffer_size()].chunks_exact(2).map(|b| u16::from_be_bytes([b[0], b[1]])).collect();
    Ok(DepthImage { width: info.width, height: info.height, data, scale_m: 0.001 })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(width: u32, height: u32) -> DepthImage {
        let data = (0..width * height)
            .map(|i| if i % 7 == 0 { 0 } else { (400 + i % width + 3 * (i / width)) as u16 })
            .collect();
        DepthImage { width, height, data, scale_m: 0.001 }
    }

    #[test]
    fn every_value_survives_the_png_and_json() {
        let mut depth = ramp(64, 48);
        depth.data[5] = 65535;
        depth.data[6] = 1;
        let message = RgbdDepth::new(TimeNs(5), "camera", &depth).unwrap();
        let json = serde_json::to_string(&message).unwrap();
        let back: RgbdDepth = serde_json::from_str(&json).unwrap();
        assert!(matches!(back, RgbdDepth::Png(_)), "{json:.100}");
        assert_eq!(back.to_depth().unwrap(), depth);
    }

    #[test]
    fn the_old_raw_form_is_still_read() {
        let depth = DepthImage { width: 3, height: 2, data: vec![0, 1, 2, 30000, 65535, 7], scale_m: 0.001 };
        let json = serde_json::to_string(&RawImage::depth(TimeNs(5), "camera", &depth)).unwrap();
        let back: RgbdDepth = serde_json::from_str(&json).unwrap();
        assert!(matches!(back, RgbdDepth::Raw(_)));
        assert_eq!(back.to_depth().unwrap(), depth);
        assert_eq!(decode_depth_mm_png(&back.to_png().unwrap().bytes).unwrap(), depth);
    }

    #[test]
    fn the_png_form_is_at_most_a_quarter_of_the_raw_form() {
        let depth = ramp(640, 480);
        let new = serde_json::to_vec(&RgbdDepth::new(TimeNs(5), "camera", &depth).unwrap()).unwrap();
        let old = serde_json::to_vec(&RawImage::depth(TimeNs(5), "camera", &depth)).unwrap();
        assert!(4 * new.len() <= old.len(), "{} bytes, old form {}", new.len(), old.len());
    }

    /// A corrupted, truncated or 8-bit PNG is an error naming the problem, never a panic.
    #[test]
    fn bad_bytes_are_refused() {
        let png = encode_depth_mm_png(&ramp(16, 8)).unwrap().bytes;
        assert!(decode_depth_mm_png(&png[..png.len() / 2]).is_err());
        let mut flipped = png.clone();
        let k = flipped.len() - 20;
        flipped[k] ^= 0x55;
        assert!(decode_depth_mm_png(&flipped).is_err());
        assert!(decode_depth_mm_png(b"not a png").is_err());
        let mut eight = Vec::new();
        let mut e = png::Encoder::new(&mut eight, 2, 2);
        e.set_color(png::ColorType::Grayscale);
        e.set_depth(png::BitDepth::Eight);
        e.write_header().unwrap().write_image_data(&[0, 1, 2, 3]).unwrap();
        let err = decode_depth_mm_png(&eight).unwrap_err();
        assert!(err.to_string().contains("16-bit"), "{err}");
        let jpeg = RgbdDepth::Png(CompressedImage { format: "jpeg".into(), ..CompressedImage::default() });
        assert!(jpeg.to_depth().is_err());
        let bad = DepthImage { width: 3, height: 3, data: vec![0; 4], scale_m: 0.001 };
        assert!(matches!(encode_depth_mm_png(&bad), Err(DepthCodecError::Size { .. })));
    }
}
