//! What V4L2 buffers become (MJPG recorded as it comes, YUYV, GREY, Z16,
//! padded rows, buffers flagged erroneous), driver
//! timestamps on the session clock, and a real camera when the machine has
//! one (`SLIDETRACK_V4L2=/dev/videoN`, or the first capture node offering
//! MJPG or YUYV); without one the device test says so and skips.

use std::path::Path;
use std::time::{Duration, Instant};

use slidetrack_core::{PixelFormat, WallClock};

use super::*;
use crate::devices::list_cameras;
use crate::v4l2::mjpeg;
use crate::v4l2::mjpeg::tests::strip_dht;

fn test_jpeg(width: u16, height: u16) -> Vec<u8> {
    let data: Vec<u8> =
        (0..u32::from(width) * u32::from(height) * 3).map(|i| ((i * 13) % 251) as u8).collect();
    let mut bytes = Vec::new();
    jpeg_encoder::Encoder::new(&mut bytes, 85)
        .encode(&data, width, height, jpeg_encoder::ColorType::Rgb)
        .unwrap();
    bytes
}

#[test]
fn mjpg_frames_are_recorded_byte_for_byte() {
    let jpeg = test_jpeg(64, 48);
    let (pixels, encoded) = frame_content(&FrameLayout::packed(V4l2PixelFormat::Mjpg, 64, 48), 90, &jpeg);
    let encoded = encoded.unwrap();
    assert_eq!(encoded.format, "jpeg");
    assert_eq!(encoded.bytes, jpeg, "no re-encoding");
    let pixels = pixels.unwrap();
    assert_eq!((pixels.width, pixels.height, pixels.format), (64, 48, PixelFormat::Gray8));
}

#[test]
fn mjpg_frames_without_huffman_tables_get_only_the_tables_added() {
    let jpeg = test_jpeg(64, 48);
    let bare = strip_dht(&jpeg);
    let (pixels, encoded) = frame_content(&FrameLayout::packed(V4l2PixelFormat::Mjpg, 64, 48), 90, &bare);
    let recorded = encoded.unwrap().bytes;
    assert_eq!(recorded, mjpeg::with_huffman_tables(&bare).into_owned());
    // Everything the camera sent is there, in order, around the inserted tables.
    let sos = bare.windows(2).position(|w| w == [0xFF, 0xDA]).unwrap();
    assert!(recorded.starts_with(&bare[..sos]) && recorded.ends_with(&bare[sos..]));
    assert!(recorded.len() > bare.len());
    assert_eq!(pixels, mjpeg::decode_gray(&jpeg), "decodes as the frame with its tables");
}

#[test]
fn a_corrupt_mjpg_frame_is_still_recorded_but_not_detected_on() {
    let junk = b"\xFF\xD8 not really a jpeg".to_vec();
    let (pixels, encoded) = frame_content(&FrameLayout::packed(V4l2PixelFormat::Mjpg, 64, 48), 90, &junk);
    assert!(pixels.is_none());
    assert_eq!(encoded.unwrap().bytes, junk);
}

#[test]
fn yuyv_frames_give_their_luma_and_a_jpeg() {
    let (w, h) = (16u32, 8u32);
    let yuyv: Vec<u8> = (0..w * h).flat_map(|i| [(i % 220) as u8 + 16, 128]).collect();
    let (pixels, encoded) = frame_content(&FrameLayout::packed(V4l2PixelFormat::Yuyv, w, h), 90, &yuyv);
    let pixels = pixels.unwrap();
    assert_eq!(pixels.data, yuyv.iter().step_by(2).copied().collect::<Vec<_>>());
    let encoded = encoded.unwrap();
    assert_eq!(encoded.format, "jpeg");
    let decoded = mjpeg::decode_gray(&encoded.bytes).unwrap();
    assert_eq!((decoded.width, decoded.height), (w, h));
    // A short buffer (a truncated transfer) gives nothing rather than garbage.
    assert_eq!(
        frame_content(&FrameLayout::packed(V4l2PixelFormat::Yuyv, w, h), 90, &yuyv[..100]),
        (None, None)
    );
}

#[test]
fn z16_frames_are_recorded_as_png_without_pixels() {
    let z16: Vec<u8> = (0..4u16 * 4).flat_map(|d| (d * 1000).to_le_bytes()).collect();
    let (pixels, encoded) = frame_content(&FrameLayout::packed(V4l2PixelFormat::Z16, 4, 4), 90, &z16);
    assert!(pixels.is_none());
    assert_eq!(encoded.unwrap().format, "png");
    assert_eq!(frame_content(&FrameLayout::packed(V4l2PixelFormat::Z16, 4, 4), 90, &z16[..10]), (None, None));
}

/// Rows of `row` bytes each followed by `pad` bytes of junk (0xEE), as a
/// driver whose `bytesperline` exceeds the row lays them out.
fn padded(packed: &[u8], row: usize, pad: usize) -> Vec<u8> {
    packed.chunks(row).flat_map(|r| r.iter().copied().chain(std::iter::repeat_n(0xEE, pad))).collect()
}

#[test]
fn padded_rows_decode_as_the_packed_frame() {
    let (w, h) = (6u32, 4u32);
    let z16: Vec<u8> = (0..w * h).flat_map(|i| (i as u16 * 257 + 3).to_le_bytes()).collect();
    let yuyv: Vec<u8> = (0..w * h).flat_map(|i| [(i % 200) as u8 + 16, (i * 7 % 255) as u8]).collect();
    let grey: Vec<u8> = (0..w * h).map(|i| (i * 11 % 256) as u8).collect();
    for (format, packed, bpp) in [
        (V4l2PixelFormat::Z16, &z16, 2usize),
        (V4l2PixelFormat::Yuyv, &yuyv, 2),
        (V4l2PixelFormat::Grey, &grey, 1),
    ] {
        let row = w as usize * bpp;
        let pad = 10;
        let stride = FrameLayout { format, width: w, height: h, bytes_per_line: (row + pad) as u32 };
        let from_padded = frame_content(&stride, 90, &padded(packed, row, pad));
        let from_packed = frame_content(&FrameLayout::packed(format, w, h), 90, packed);
        assert!(from_padded.1.is_some(), "{format:?}");
        assert_eq!(from_padded, from_packed, "{format:?}: the padding is not image data");
        // The last row need not carry its padding.
        let mut short = padded(packed, row, pad);
        short.truncate(short.len() - pad);
        assert_eq!(frame_content(&stride, 90, &short), from_packed, "{format:?}");
        // One byte fewer is a truncated frame.
        short.pop();
        assert_eq!(frame_content(&stride, 90, &short), (None, None), "{format:?}");
    }
    // The depth units survive the padding: the PNG holds the packed values.
    let stride =
        FrameLayout { format: V4l2PixelFormat::Z16, width: w, height: h, bytes_per_line: 2 * w + 10 };
    let buffer = padded(&z16, 2 * w as usize, 10);
    let rows = stride.packed_rows(&buffer).unwrap();
    assert_eq!(&rows[..], &z16[..]);
    // A stride shorter than a row is a driver we do not understand.
    let bad = FrameLayout { bytes_per_line: 2 * w - 1, ..stride };
    assert_eq!(frame_content(&bad, 90, &z16), (None, None));
}

#[test]
fn grey_frames_give_their_pixels_and_a_jpeg() {
    let (w, h) = (16u32, 8u32);
    let grey: Vec<u8> = (0..w * h).map(|i| (i * 2) as u8).collect();
    let (pixels, encoded) = frame_content(&FrameLayout::packed(V4l2PixelFormat::Grey, w, h), 90, &grey);
    let pixels = pixels.unwrap();
    assert_eq!((pixels.format, &pixels.data), (PixelFormat::Gray8, &grey));
    let decoded = mjpeg::decode_gray(&encoded.unwrap().bytes).unwrap();
    assert_eq!((decoded.width, decoded.height), (w, h));
}

#[test]
fn buffers_flagged_erroneous_are_dropped_and_counted() {
    let counters = CaptureCounters::default();
    // V4L2_BUF_FLAG_MAPPED | QUEUED | TIMESTAMP_MONOTONIC: a good buffer.
    assert!(counters.accept(0x0000_2003));
    assert!(!counters.accept(0x0000_2003 | crate::v4l2::decode::BUF_FLAG_ERROR));
    assert!(!counters.accept(BufferFlags::ERROR.bits()), "the v4l crate's flag is the kernel's");
    assert!(counters.accept(BufferFlags::DONE.bits()));
    counters.delivered_one();
    counters.overrun_one();
    assert_eq!((counters.delivered(), counters.erroneous(), counters.overrun()), (1, 2, 1));
    assert!(counters.to_string().contains("2 flagged erroneous"), "{counters}");
}

#[test]
fn driver_timestamps_map_to_the_session_clock() {
    // Session time 5 s when the monotonic clock read 1000 s.
    let map = DriverClockMap { offset_ns: 5_000_000_000 - 1_000_000_000_000 };
    let now = TimeNs(5_040_000_000);
    let exposed = 1_000_030_000_000; // monotonic 1000.030 s
    assert_eq!(map.session_time(exposed, now), TimeNs(5_030_000_000));
    // Not in the future, not more than a second old: otherwise the arrival time.
    assert_eq!(map.session_time(exposed + 20_000_000, now), now);
    assert_eq!(map.session_time(exposed - 2_000_000_000, now), now);
    // Before the session started: the arrival time, never a negative time.
    let early = DriverClockMap { offset_ns: -1_000_000_000_000 };
    assert_eq!(early.session_time(999_900_000_000, TimeNs(50_000_000)), TimeNs(50_000_000));
    // The offset is captured against the host's monotonic clock.
    let clock = WallClock::start();
    let map = DriverClockMap::capture(&clock).unwrap();
    let mono = clock_gettime(ClockId::CLOCK_MONOTONIC).unwrap();
    let mono_ns = i128::from(mono.tv_sec()) * 1_000_000_000 + i128::from(mono.tv_nsec());
    let t = map.session_time(mono_ns, clock.now());
    assert!(clock.now().0 - t.0 < 100_000_000, "{t:?} vs {:?}", clock.now());
}

/// The formats of the capture device named in `SLIDETRACK_V4L2` that the
/// backend streams: `(path, format, width, height)`.
fn camera_under_test() -> (String, V4l2PixelFormat, u32, u32) {
    let wanted =
        std::env::var("SLIDETRACK_V4L2").expect("SLIDETRACK_V4L2 names the camera, e.g. /dev/video0");
    let camera = list_cameras(Path::new("/dev"))
        .into_iter()
        .find(|c| c.path == wanted)
        .unwrap_or_else(|| panic!("{wanted} is not a V4L2 capture node"));
    camera
        .formats
        .iter()
        .find_map(|f| {
            let format = match f.fourcc.as_str() {
                "MJPG" => V4l2PixelFormat::Mjpg,
                "YUYV" => V4l2PixelFormat::Yuyv,
                _ => return None,
            };
            let size = f.sizes.first()?;
            Some((camera.path.clone(), format, size.width, size.height))
        })
        .unwrap_or_else(|| panic!("{wanted} offers neither MJPG nor YUYV"))
}

/// Runs on the camera named in `SLIDETRACK_V4L2`.
#[test]
#[cfg_attr(not(slidetrack_v4l2), ignore = "needs a V4L2 camera named in SLIDETRACK_V4L2")]
fn a_real_camera_streams_frames_on_the_session_clock() {
    let (path, format, width, height) = camera_under_test();
    let cfg = V4l2CameraConfig {
        device: path.clone(),
        width,
        height,
        pixel_format: format,
        fps: 30.0,
        ..V4l2CameraConfig::default()
    };
    let intrinsics = CameraIntrinsics {
        width,
        height,
        fx: 500.0,
        fy: 500.0,
        cx: f64::from(width) / 2.0,
        cy: f64::from(height) / 2.0,
        distortion: [0.0; 5],
    };
    let clock = Arc::new(WallClock::start());
    let mut camera = V4l2Camera::open(&cfg, intrinsics, clock.clone()).unwrap();
    let start = Instant::now();
    let mut frames = Vec::new();
    while frames.len() < 5 && start.elapsed() < Duration::from_secs(5) {
        match camera.poll().unwrap() {
            Some(f) => frames.push(f),
            None => std::thread::sleep(Duration::from_millis(5)),
        }
    }
    assert!(frames.len() >= 5, "{path}: {} frames in 5 s", frames.len());
    for pair in frames.windows(2) {
        assert!(pair[0].t <= pair[1].t && pair[0].sequence < pair[1].sequence);
    }
    for f in &frames {
        assert!(f.t <= clock.now());
        assert!(f.encoded.as_ref().is_some_and(|e| !e.bytes.is_empty()), "{path}: nothing to record");
    }
    eprintln!("{path}: {} frames of {width}x{height} {format:?}", frames.len());
}

/// A node of the RGB-D camera named in `var`, streaming `format` at its first
/// offered size; `None` (with a message) when `var` is unset.
fn rgbd_node(var: &str, formats: &[V4l2PixelFormat]) -> Option<V4l2CameraConfig> {
    let Some(path) = std::env::var(var).ok().filter(|v| !v.is_empty()) else {
        eprintln!("skipped: {var} does not name a device node (e.g. {var}=/dev/video0)");
        return None;
    };
    let camera = list_cameras(Path::new("/dev"))
        .into_iter()
        .find(|c| c.path == path)
        .unwrap_or_else(|| panic!("{var}={path} is not a V4L2 capture node"));
    let (format, size) = formats
        .iter()
        .find_map(|want| {
            let code = String::from_utf8_lossy(&want.fourcc()).trim().to_string();
            let f = camera.formats.iter().find(|f| f.fourcc.trim() == code)?;
            let size = f.sizes.first()?;
            Some((*want, (size.width, size.height)))
        })
        .unwrap_or_else(|| panic!("{path} offers none of {formats:?}"));
    Some(V4l2CameraConfig {
        device: path,
        width: size.0,
        height: size.1,
        pixel_format: format,
        ..V4l2CameraConfig::default()
    })
}

/// Colour and depth of a real RGB-D camera (a RealSense over uvcvideo):
/// `SLIDETRACK_RGBD_COLOR=/dev/video4 SLIDETRACK_RGBD_DEPTH=/dev/video0
/// cargo test -p slidetrack-drivers -- --ignored rgbd`.
#[test]
#[cfg_attr(not(slidetrack_rgbd), ignore = "needs SLIDETRACK_RGBD_COLOR and SLIDETRACK_RGBD_DEPTH")]
fn a_real_rgbd_camera_streams_colour_and_z16_depth() {
    let formats = [V4l2PixelFormat::Yuyv, V4l2PixelFormat::Mjpg, V4l2PixelFormat::Grey];
    let (Some(color), Some(depth)) = (
        rgbd_node("SLIDETRACK_RGBD_COLOR", &formats),
        rgbd_node("SLIDETRACK_RGBD_DEPTH", &[V4l2PixelFormat::Z16]),
    ) else {
        return;
    };
    let clock = Arc::new(WallClock::start());
    let k = |c: &V4l2CameraConfig| CameraIntrinsics {
        width: c.width,
        height: c.height,
        fx: 500.0,
        fy: 500.0,
        cx: f64::from(c.width) / 2.0,
        cy: f64::from(c.height) / 2.0,
        distortion: [0.0; 5],
    };
    let mut cameras = [
        V4l2Camera::open(&color, k(&color), clock.clone()).unwrap(),
        V4l2Camera::open(&depth, k(&depth), clock.clone()).unwrap(),
    ];
    let start = Instant::now();
    let mut frames = [Vec::new(), Vec::new()];
    while frames.iter().any(|f| f.len() < 10) && start.elapsed() < Duration::from_secs(10) {
        for (camera, got) in cameras.iter_mut().zip(&mut frames) {
            if let Some(f) = camera.poll().unwrap() {
                got.push(f);
            }
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    for ((camera, got), cfg) in cameras.iter().zip(&frames).zip([&color, &depth]) {
        assert!(got.len() >= 10, "{}: {} frames in 10 s ({})", cfg.device, got.len(), camera.counters());
        let encoded = got[0].encoded.as_ref().unwrap();
        let want = if cfg.pixel_format == V4l2PixelFormat::Z16 { "png" } else { "jpeg" };
        assert_eq!(encoded.format, want, "{}", cfg.device);
        eprintln!(
            "{}: {:?} {}x{}: {}",
            cfg.device,
            cfg.pixel_format,
            cfg.width,
            cfg.height,
            camera.counters()
        );
    }
    // Depth frames are 16-bit PNGs of the node's size.
    let png = &frames[1][0].encoded.as_ref().unwrap().bytes;
    let info = png::Decoder::new(std::io::Cursor::new(png)).read_info().unwrap().info().clone();
    assert_eq!(
        (info.width, info.height, info.bit_depth),
        (depth.width, depth.height, png::BitDepth::Sixteen)
    );
}
