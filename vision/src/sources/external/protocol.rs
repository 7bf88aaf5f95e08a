//! The messages of the external source protocol (`docs/protocols.md`,
//! "External vision source, version 1"), without I/O: one JSON object per
//! line, decoded into [`ClientMessage`] or a typed [`ExternalError`].

use base64::Engine;
use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};
use slidetrack_estimators::roft::Mask;

pub use crate::error::ExternalError;
use crate::sources::aruco::PoseConfig;

/// The protocol's name in the handshake.
pub const PROTOCOL: &str = "slidetrack-vision-source";
/// The protocol version this build speaks.
pub const VERSION: u32 = 1;
/// The longest line accepted (bytes, newline excluded).
pub const MAX_LINE_BYTES: usize = 32 << 20;

/// A mask as sent by the client.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "encoding", rename_all = "snake_case", deny_unknown_fields)]
pub enum MaskMessage {
    /// Run lengths over the pixels in row-major order, alternating outside
    /// and inside, starting with outside (a leading 0 when the first pixel
    /// is inside); they add up to `width * height`.
    Rle {
        /// Width (px).
        width: u32,
        /// Height (px).
        height: u32,
        /// The runs.
        counts: Vec<u64>,
    },
    /// A PNG image (any bit depth or colour type), base64; inside where its
    /// first channel is not zero.
    Png {
        /// Base64 (standard alphabet, padded) of the PNG file.
        data: String,
    },
}

/// The messages a client sends.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ClientMessage {
    /// The first message.
    Hello {
        /// Must be [`PROTOCOL`].
        protocol: String,
        /// Must be [`VERSION`].
        version: u32,
        /// The client's name, for logs.
        #[serde(default)]
        name: Option<String>,
    },
    /// A pose, a mask or both computed on one frame.
    Result {
        /// The frame's time (ns, as announced by the server).
        frame_t_ns: u64,
        /// `camera_from_object`: translation (m) and quaternion `[x, y, z, w]`, camera frame.
        #[serde(default)]
        pose: Option<PoseConfig>,
        /// The object's mask.
        #[serde(default)]
        mask: Option<MaskMessage>,
    },
}

/// The server's messages.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ServerMessage {
    /// Sent on connection.
    Hello {
        /// [`PROTOCOL`].
        protocol: &'static str,
        /// [`VERSION`].
        version: u32,
        /// Image width (px).
        width: u32,
        /// Image height (px).
        height: u32,
        /// Pinhole intrinsics `[fx, fy, cx, cy]` (px) of the registered colour camera.
        intrinsics: [f64; 4],
    },
    /// A frame the tracker is processing.
    Frame {
        /// Its time (ns): the key of the client's results.
        frame_t_ns: u64,
        /// Its sequence number.
        sequence: u64,
        /// The colour image as JPEG, base64, when the server sends images.
        #[serde(skip_serializing_if = "Option::is_none")]
        color_jpeg: Option<String>,
        /// The registered depth as a 16-bit grey PNG (millimetres), base64, when the server sends images.
        #[serde(skip_serializing_if = "Option::is_none")]
        depth_png: Option<String>,
    },
    /// A message was refused.
    Error {
        /// [`ExternalError::kind`].
        kind: &'static str,
        /// The error, in words.
        detail: String,
    },
}

/// Decodes line `line` (1-based) of a connection.
pub fn decode_line(bytes: &[u8], line: u64) -> Result<ClientMessage, ExternalError> {
    serde_json::from_slice(bytes).map_err(|e| ExternalError::BadMessage { line, detail: e.to_string() })
}

/// Checks a client's hello.
pub fn check_hello(message: &ClientMessage) -> Result<(), ExternalError> {
    match message {
        ClientMessage::Hello { protocol, version, .. } if protocol == PROTOCOL && *version == VERSION => {
            Ok(())
        }
        ClientMessage::Hello { protocol, version, .. } => Err(ExternalError::BadHandshake {
            detail: format!(
                "protocol {protocol:?} version {version}; this server speaks {PROTOCOL:?} version {VERSION}"
            ),
        }),
        ClientMessage::Result { .. } => {
            Err(ExternalError::BadHandshake { detail: "the first message must be a hello".into() })
        }
    }
}

/// The pose of a result.
pub fn decode_pose(pose: &PoseConfig, frame_t_ns: u64) -> Result<Isometry3<f64>, ExternalError> {
    pose.isometry("pose").map_err(|e| ExternalError::BadPose { frame_t_ns, detail: e.to_string() })
}

/// The mask of a result, which must be `width` x `height`.
pub fn decode_mask(
    mask: &MaskMessage,
    frame_t_ns: u64,
    width: u32,
    height: u32,
) -> Result<Mask, ExternalError> {
    let bad = |detail: String| ExternalError::BadMask { frame_t_ns, detail };
    let (w, h, inside) = match mask {
        MaskMessage::Rle { width, height, counts } => {
            let total = u64::from(*width) * u64::from(*height);
            if counts.iter().try_fold(0u64, |s, c| s.checked_add(*c)) != Some(total) {
                return Err(bad(format!("RLE counts do not add up to {width}x{height} = {total} pixels")));
            }
            let mut inside = Vec::with_capacity(total as usize);
            for (k, run) in counts.iter().enumerate() {
                inside.extend(std::iter::repeat_n(u8::from(k % 2 == 1), *run as usize));
            }
            (*width, *height, inside)
        }
        MaskMessage::Png { data } => {
            let bytes = base64::engine::general_purpose::STANDARD
                .decode(data)
                .map_err(|e| bad(format!("PNG base64: {e}")))?;
            decode_png(&bytes).map_err(|e| bad(format!("PNG: {e}")))?
        }
    };
    if (w, h) != (width, height) {
        return Err(bad(format!("is {w}x{h} px, the frames are {width}x{height} px")));
    }
    Mask::from_bytes(w, h, &inside).ok_or_else(|| bad("has the wrong number of pixels".into()))
}

/// A PNG's first channel as 0/1 per pixel.
fn decode_png(bytes: &[u8]) -> Result<(u32, u32, Vec<u8>), png::DecodingError> {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder.read_info()?;
    let mut buffer = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buffer)?;
    let samples = info.color_type.samples();
    let pixels = info.width as usize * info.height as usize;
    let inside = buffer[..info.buffer_size()]
        .chunks_exact(samples)
        .take(pixels)
        .map(|p| u8::from(p[0] != 0))
        .collect();
    Ok((info.width, info.height, inside))
}
