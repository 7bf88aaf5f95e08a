//! `CompressedImage::to_json` against serde_json.

use super::*;

/// Catches a splice one byte off (a quote lost or doubled), base64 padding
/// cut or left as zeros, and a frame id or format whose escaping moves the
/// data: the bytes must be serde_json's, which sessions have always held.
#[test]
fn image_json_is_serde_jsons_to_the_byte() {
    let frame_ids = ["camera", "", "a\"b\\c\nd", "format\":\"x", "ümlaut ✓"];
    let formats = ["jpeg", "png", "", "\"data\":\"", "q\u{1}"];
    for (k, frame_id) in frame_ids.iter().enumerate() {
        for format in formats {
            for len in [0, 1, 2, 3, 4, 5, 57, 1000] {
                let data: Vec<u8> = (0..len).map(|i| (i * 131 + k * 7 + format.len()) as u8).collect();
                let t = TimeNs(1_234_567_890_123 * (len as u64 + 1));
                let image = EncodedImage { format: format.into(), bytes: data };
                let msg = CompressedImage::new(t, frame_id, &image);
                let expected = serde_json::to_vec(&msg).unwrap();
                assert_eq!(
                    msg.to_json().unwrap(),
                    expected,
                    "{frame_id:?} {format:?} {len}: {}",
                    String::from_utf8_lossy(&expected)
                );
            }
        }
    }
}
