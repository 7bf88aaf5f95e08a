use super::*;

fn testdata(name: &str) -> String {
    format!("{}/../../shared/testdata/aruco/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// The sum of the bytes and the sum weighted by position (1-based): two
/// numbers that change with any pixel.
fn checksums(data: &[u8]) -> (u64, u64) {
    let sum = data.iter().map(|&b| u64::from(b)).sum();
    let weighted = data.iter().zip(1u64..).map(|(&b, i)| u64::from(b) * i).sum();
    (sum, weighted)
}

/// OpenCV's photo decodes to OpenCV's pixels: the checksums of
/// `cv2.imread` (opencv-python 4.13, `IMREAD_COLOR` turned to RGB, and
/// `IMREAD_GRAYSCALE`). Catches a decoder of its own (another IDCT or chroma
/// upsampling changes most pixels by a level or two) and BGR order.
#[test]
fn a_photo_decodes_to_the_pixels_opencv_reads() {
    let bytes = std::fs::read(testdata("singlemarkersoriginal.jpg")).unwrap();
    assert_eq!(dimensions(&bytes).unwrap(), (640, 480));
    let rgb = decode(&bytes, PixelFormat::Rgb8).unwrap();
    assert_eq!((rgb.width, rgb.height, rgb.data.len()), (640, 480, 640 * 480 * 3));
    assert_eq!(checksums(&rgb.data), (157_880_920, 79_009_437_647_474));
    let gray = decode(&bytes, PixelFormat::Gray8).unwrap();
    assert_eq!(checksums(&gray.data), (53_157_119, 8_862_664_068_875));
}

#[test]
fn jpeg_round_trips_in_gray_and_colour() {
    let (w, h) = (64u32, 48u32);
    let gray: Vec<u8> = (0..w * h).map(|i| ((i % w) * 4) as u8).collect();
    let image = Image { width: w, height: h, format: PixelFormat::Gray8, data: gray.clone() };
    let jpeg = encode_jpeg(&image, 95).unwrap();
    assert_eq!(jpeg.format, "jpeg");
    assert_eq!(&jpeg.bytes[..2], &[0xFF, 0xD8], "JPEG start-of-image marker");
    let back = decode(&jpeg.bytes, PixelFormat::Gray8).unwrap();
    assert_eq!((back.width, back.height), (64, 48));
    assert!(back.data.iter().zip(&gray).all(|(a, b)| a.abs_diff(*b) <= 3));

    let rgb: Vec<u8> = (0..w * h).flat_map(|i| [((i % w) * 4) as u8, ((i / w) * 5) as u8, 128]).collect();
    let image = Image { width: w, height: h, format: PixelFormat::Rgb8, data: rgb.clone() };
    let back = decode(&encode_jpeg(&image, 95).unwrap().bytes, PixelFormat::Rgb8).unwrap();
    let worst = back.data.iter().zip(&rgb).map(|(a, b)| a.abs_diff(*b)).max().unwrap();
    assert!(worst <= 6, "{worst} levels");
}

#[test]
fn png_round_trips_exactly_and_colour_turns_gray_as_cvtcolor_does() {
    let (w, h) = (5u32, 3u32);
    let rgb: Vec<u8> = (0..w * h * 3).map(|i| (i * 17 % 256) as u8).collect();
    let image = Image { width: w, height: h, format: PixelFormat::Rgb8, data: rgb.clone() };
    let png = encode_png(&image).unwrap();
    assert_eq!(png.format, "png");
    assert_eq!(dimensions(&png.bytes).unwrap(), (5, 3));
    assert_eq!(decode(&png.bytes, PixelFormat::Rgb8).unwrap().data, rgb);
    let gray = decode(&png.bytes, PixelFormat::Gray8).unwrap();
    let expected: Vec<u8> = rgb.chunks(3).map(|p| gray_of_rgb(p[0], p[1], p[2])).collect();
    assert_eq!(gray.data, expected);
    // Gray is replicated into colour.
    let g = Image { width: w, height: h, format: PixelFormat::Gray8, data: expected.clone() };
    let colour = decode(&encode_png(&g).unwrap().bytes, PixelFormat::Rgb8).unwrap();
    assert!(colour.data.chunks(3).zip(&expected).all(|(p, &v)| p == [v, v, v]));

    let depth: Vec<u16> = (0..w * h).map(|i| (i * 4099) as u16).collect();
    assert_eq!(decode_png16(&encode_png16(w, h, &depth).unwrap()).unwrap(), (w, h, depth));
}

/// `cv2.cvtColor(..., COLOR_RGB2GRAY)` of these pixels (opencv-python 4.13).
#[test]
fn gray_is_opencvs_fixed_point_luma() {
    let pixels =
        [[255, 0, 0], [0, 255, 0], [0, 0, 255], [10, 200, 30], [128, 128, 128], [1, 2, 3], [250, 17, 99]];
    let gray: Vec<u8> = pixels.iter().map(|p| gray_of_rgb(p[0], p[1], p[2])).collect();
    assert_eq!(gray, [76, 150, 29, 124, 128, 2, 96]);
}

#[test]
fn bad_bytes_are_errors_never_panics() {
    assert!(matches!(decode(b"GIF89a....", PixelFormat::Rgb8), Err(CodecError::UnknownFormat { .. })));
    assert!(matches!(decode(&[], PixelFormat::Gray8), Err(CodecError::UnknownFormat { .. })));
    let image = Image { width: 16, height: 16, format: PixelFormat::Rgb8, data: vec![90; 16 * 16 * 3] };
    for encoded in [encode_jpeg(&image, 80).unwrap(), encode_png(&image).unwrap()] {
        for cut in [3, 8, 20, encoded.bytes.len() / 2] {
            let bytes = &encoded.bytes[..cut];
            let _ = decode(bytes, PixelFormat::Rgb8);
            let _ = dimensions(bytes);
            let _ = decode_png16(bytes);
        }
    }
    // A colour PNG is not a depth image.
    let png = encode_png(&image).unwrap();
    assert!(matches!(decode_png16(&png.bytes), Err(CodecError::Unsupported(_))));
}

#[test]
fn an_image_with_the_wrong_byte_count_is_refused() {
    let image = Image { width: 10, height: 10, format: PixelFormat::Rgb8, data: vec![0; 100] };
    assert!(matches!(encode_jpeg(&image, 80), Err(MarkerError::BadImage { .. })));
    assert!(matches!(encode_png(&image), Err(MarkerError::BadImage { .. })));
    // No pixels: the encoders' own errors, not a panic.
    let empty = Image { width: 0, height: 0, format: PixelFormat::Gray8, data: vec![] };
    assert!(matches!(encode_jpeg(&empty, 80), Err(MarkerError::Encode { format: "JPEG", .. })));
    assert!(matches!(encode_png(&empty), Err(MarkerError::Encode { format: "PNG", .. })));
}
