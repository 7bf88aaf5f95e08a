//! JPEG encoding through OpenCV (libjpeg-turbo), several times faster than a
//! pure-Rust encoder: the simulated camera uses it to deliver frames as a
//! USB camera would.

use opencv::core::{Mat, Vec3b, Vector};
use opencv::prelude::*;
use opencv::{imgcodecs, imgproc};
use slidetrack_core::{EncodedImage, Image, PixelFormat};

use crate::error::{MarkerError, OpenCvContext};

/// Encodes `image` as JPEG at `quality` (1-100).
pub fn encode_jpeg(image: &Image, quality: u8) -> Result<EncodedImage, MarkerError> {
    let rows = i32::try_from(image.height).map_err(|_| bad(image))?;
    let cols = i32::try_from(image.width).map_err(|_| bad(image))?;
    if image.data.len() != image.width as usize * image.height as usize * image.format.channels() {
        return Err(bad(image));
    }
    let params =
        Vector::<i32>::from_slice(&[imgcodecs::IMWRITE_JPEG_QUALITY, i32::from(quality.clamp(1, 100))]);
    let mut bytes = Vector::<u8>::new();
    match image.format {
        PixelFormat::Gray8 => {
            let mat = Mat::new_rows_cols_with_data::<u8>(rows, cols, &image.data).cv("Mat from image")?;
            imgcodecs::imencode(".jpg", &mat, &mut bytes, &params).cv("imencode")?;
        }
        PixelFormat::Rgb8 => {
            let rgb = Mat::new_rows_cols_with_bytes::<Vec3b>(rows, cols, &image.data).cv("Mat from image")?;
            let mut bgr = Mat::default();
            imgproc::cvt_color_def(&rgb, &mut bgr, imgproc::COLOR_RGB2BGR).cv("cvtColor")?;
            imgcodecs::imencode(".jpg", &bgr, &mut bytes, &params).cv("imencode")?;
        }
    }
    Ok(EncodedImage { format: "jpeg".into(), bytes: bytes.to_vec() })
}

fn bad(image: &Image) -> MarkerError {
    let channels = image.format.channels();
    MarkerError::BadImage {
        width: image.width,
        height: image.height,
        channels,
        expected: image.width as usize * image.height as usize * channels,
        len: image.data.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jpeg_round_trips_through_opencv() {
        let (w, h) = (64u32, 48u32);
        let data: Vec<u8> = (0..w * h).map(|i| ((i % w) * 4) as u8).collect();
        let image = Image { width: w, height: h, format: PixelFormat::Gray8, data };
        let jpeg = encode_jpeg(&image, 95).unwrap();
        assert_eq!(&jpeg.bytes[..2], &[0xFF, 0xD8], "JPEG start-of-image marker");
        let decoded =
            imgcodecs::imdecode(&Vector::<u8>::from_slice(&jpeg.bytes), imgcodecs::IMREAD_GRAYSCALE).unwrap();
        assert_eq!((decoded.cols(), decoded.rows()), (64, 48));
        let v = *decoded.at_2d::<u8>(10, 20).unwrap();
        assert!((i32::from(v) - 80).abs() <= 3, "{v}");
    }

    #[test]
    fn an_image_with_the_wrong_byte_count_is_refused() {
        let image = Image { width: 10, height: 10, format: PixelFormat::Rgb8, data: vec![0; 100] };
        assert!(matches!(encode_jpeg(&image, 80), Err(MarkerError::BadImage { .. })));
    }
}
