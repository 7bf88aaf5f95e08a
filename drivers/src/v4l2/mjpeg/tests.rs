//! The standard tables match a JPEG encoder's, and frames without tables
//! decode once they are inserted.

use super::*;

/// The JPEG segments before the scan: `(marker, payload)`.
fn segments(jpeg: &[u8]) -> Vec<(u8, Vec<u8>)> {
    let mut out = Vec::new();
    let mut pos = 2;
    while jpeg[pos + 1] != 0xDA {
        let len = usize::from(u16::from_be_bytes([jpeg[pos + 2], jpeg[pos + 3]]));
        out.push((jpeg[pos + 1], jpeg[pos + 4..pos + 2 + len].to_vec()));
        pos += 2 + len;
    }
    out
}

/// Every Huffman table of the DHT segments: `(class and id, bits, values)`.
fn huffman_tables(jpeg: &[u8]) -> Vec<(u8, Vec<u8>, Vec<u8>)> {
    let mut tables = Vec::new();
    for (_, mut p) in segments(jpeg).into_iter().filter(|(m, _)| *m == 0xC4) {
        while !p.is_empty() {
            let bits = p[1..17].to_vec();
            let n: usize = bits.iter().map(|&b| usize::from(b)).sum();
            tables.push((p[0], bits, p[17..17 + n].to_vec()));
            p.drain(..17 + n);
        }
    }
    tables.sort();
    tables
}

fn test_image(format: PixelFormat) -> Image {
    let (w, h) = (48u32, 32u32);
    let data = (0..w * h * format.channels() as u32).map(|i| ((i * 7) % 251) as u8).collect();
    Image { width: w, height: h, format, data }
}

fn encode(image: &Image) -> Vec<u8> {
    let mut bytes = Vec::new();
    let color = match image.format {
        PixelFormat::Gray8 => jpeg_encoder::ColorType::Luma,
        PixelFormat::Rgb8 => jpeg_encoder::ColorType::Rgb,
    };
    jpeg_encoder::Encoder::new(&mut bytes, 90)
        .encode(&image.data, image.width as u16, image.height as u16, color)
        .unwrap();
    bytes
}

/// The frame without its DHT segments, as a UVC camera sends it.
pub(crate) fn strip_dht(jpeg: &[u8]) -> Vec<u8> {
    let mut out = jpeg[..2].to_vec();
    let mut pos = 2;
    while jpeg[pos + 1] != 0xDA {
        let len = usize::from(u16::from_be_bytes([jpeg[pos + 2], jpeg[pos + 3]]));
        if jpeg[pos + 1] != 0xC4 {
            out.extend_from_slice(&jpeg[pos..pos + 2 + len]);
        }
        pos += 2 + len;
    }
    out.extend_from_slice(&jpeg[pos..]);
    out
}

#[test]
fn the_standard_tables_are_those_a_baseline_encoder_writes() {
    let jpeg = encode(&test_image(PixelFormat::Rgb8));
    let ours = huffman_tables(&with_huffman_tables(&strip_dht(&jpeg)));
    assert_eq!(ours.len(), 4);
    assert_eq!(ours, huffman_tables(&jpeg));
}

#[test]
fn a_frame_without_tables_decodes_once_they_are_inserted() {
    for format in [PixelFormat::Gray8, PixelFormat::Rgb8] {
        let jpeg = encode(&test_image(format));
        let bare = strip_dht(&jpeg);
        assert!(huffman_tables(&bare).is_empty());
        let fixed = with_huffman_tables(&bare);
        assert!(matches!(fixed, Cow::Owned(_)));
        let expected = decode_gray(&jpeg).unwrap();
        assert_eq!(decode_gray(&fixed).unwrap(), expected);
        assert_eq!((expected.width, expected.height), (48, 32));
        // A frame that has its tables is left alone.
        assert!(matches!(with_huffman_tables(&jpeg), Cow::Borrowed(_)));
    }
}

#[test]
fn garbage_is_left_alone_and_does_not_decode() {
    for bytes in
        [&b""[..], b"\xFF\xD8", b"\xFF\xD8\xFF\xE0\x00", b"not a jpeg at all", b"\xFF\xD8\xFF\xE0\x00\x01"]
    {
        assert!(matches!(with_huffman_tables(bytes), Cow::Borrowed(_)));
        assert!(decode_gray(bytes).is_none());
    }
}

#[test]
fn raw_formats_convert() {
    // Two pixels: Y0 U Y1 V, mid-gray and white, no colour.
    let yuyv = [126u8, 128, 235, 128, 16, 128, 126, 128];
    let gray = yuyv_to_gray(&yuyv, 2, 2).unwrap();
    assert_eq!(gray.data, [126, 235, 16, 126]);
    let rgb = yuyv_to_rgb(&yuyv, 2, 2).unwrap();
    assert_eq!(&rgb.data[3..6], &[255, 255, 255]);
    assert_eq!(&rgb.data[6..9], &[0, 0, 0]);
    assert!(yuyv_to_gray(&yuyv, 4, 4).is_none(), "too short");

    let depth: Vec<u16> = vec![0, 1, 1000, 65535];
    let z16: Vec<u8> = depth.iter().flat_map(|d| d.to_le_bytes()).collect();
    let png_image = z16_to_png(&z16, 2, 2).unwrap();
    assert_eq!(png_image.format, "png");
    let decoder = png::Decoder::new(std::io::Cursor::new(png_image.bytes));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.bit_depth, info.width), (png::BitDepth::Sixteen, 2));
    let back: Vec<u16> = buf[..8].chunks_exact(2).map(|p| u16::from_be_bytes([p[0], p[1]])).collect();
    assert_eq!(back, depth);
}
