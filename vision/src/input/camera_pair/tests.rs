//! Pairing by time (closest within the tolerance, the newest pair when
//! behind), registration with known extrinsics, counts, end and timeout.

use std::time::Duration;

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use slidetrack_core::{DepthImage, EncodedImage, Image, PixelFormat};

use super::*;

struct Scripted {
    frames: VecDeque<Frame>,
    intrinsics: CameraIntrinsics,
}

impl Camera for Scripted {
    fn poll(&mut self) -> Result<Option<Frame>, DeviceError> {
        Ok(self.frames.pop_front())
    }
    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }
    fn device(&self) -> &str {
        "scripted"
    }
}

fn intrinsics(width: u32, height: u32, f: f64) -> CameraIntrinsics {
    CameraIntrinsics {
        width,
        height,
        fx: f,
        fy: f,
        cx: f64::from(width) / 2.0,
        cy: f64::from(height) / 2.0,
        distortion: [0.0; 5],
    }
}

/// A colour frame at `t_ms` whose blue channel is `tag`.
fn color(t_ms: u64, tag: u8, w: i32, h: i32) -> Frame {
    let data = [30, 20, tag].repeat((w * h) as usize);
    let rgb = Image { width: w as u32, height: h as u32, format: PixelFormat::Rgb8, data };
    let png = slidetrack_calibration::codec::encode_png(&rgb).unwrap();
    Frame { t: TimeNs(t_ms * 1_000_000), sequence: t_ms, pixels: None, encoded: Some(png) }
}

fn depth_png(t_ms: u64, data: &[u16], w: i32) -> Frame {
    let h = data.len() as u32 / w as u32;
    let bytes = slidetrack_calibration::codec::encode_png16(w as u32, h, data).unwrap();
    let png = EncodedImage { format: "png".into(), bytes };
    Frame { t: TimeNs(t_ms * 1_000_000), sequence: t_ms, pixels: None, encoded: Some(png) }
}

fn depth(t_ms: u64, mm: u16, w: i32, h: i32) -> Frame {
    depth_png(t_ms, &vec![mm; (w * h) as usize], w)
}

fn settings(k: CameraIntrinsics, tolerance_ms: u64) -> PairSettings {
    PairSettings {
        color_intrinsics: k,
        depth_scale_m: 0.001,
        tolerance: Duration::from_millis(tolerance_ms),
        timeout: Duration::from_millis(200),
        registration: None,
    }
}

fn pair(colors: Vec<Frame>, depths: Vec<Frame>, settings: PairSettings) -> CameraPair {
    let k = settings.color_intrinsics.clone();
    CameraPair::new(
        Box::new(Scripted { frames: colors.into(), intrinsics: k.clone() }),
        Box::new(Scripted { frames: depths.into(), intrinsics: k }),
        settings,
    )
}

#[test]
fn each_depth_frame_pairs_with_the_closest_colour_frame() {
    let k = intrinsics(8, 6, 10.0);
    // Depth at 34 ms: the colour frame at 36 ms is closer than the one at
    // 30 ms, though both are within the tolerance. Depth at 100 ms has no
    // colour frame within 16 ms (80 and 120 ms): unpaired.
    let colors = vec![
        color(0, 1, 8, 6),
        color(30, 2, 8, 6),
        color(36, 3, 8, 6),
        color(80, 4, 8, 6),
        color(120, 5, 8, 6),
    ];
    let depths = vec![depth(34, 750, 8, 6), depth(100, 800, 8, 6), depth(119, 900, 8, 6)];
    let mut cameras = pair(colors, depths, settings(k, 16));
    // One pair at a time: poll between them by giving the scripted cameras
    // nothing more (they delivered everything on the first poll), so the
    // newest pair is taken and the first is skipped.
    let newest = cameras.next_frame().unwrap().unwrap();
    assert_eq!(newest.frame.t, TimeNs(119_000_000));
    assert_eq!(newest.frame.color.data[2], 5, "the colour frame at 120 ms");
    assert_eq!(newest.frame.depth.depth_m(0, 0), Some(0.9));
    assert_eq!(newest.frame.sequence, 0);
    let counts = cameras.counts();
    assert_eq!(
        counts,
        PairCounts { pairs: 1, unpaired_color: 3, unpaired_depth: 1, skipped_pairs: 1 },
        "{counts:?}"
    );
}

#[test]
fn pairs_come_in_order_when_the_reader_keeps_up() {
    let k = intrinsics(8, 6, 10.0);
    let mut cameras = pair(
        vec![color(0, 1, 8, 6), color(30, 2, 8, 6), color(36, 3, 8, 6)],
        vec![depth(34, 750, 8, 6)],
        settings(k, 16),
    );
    let first = cameras.next_frame().unwrap().unwrap();
    assert_eq!((first.frame.t, first.frame.color.data[2]), (TimeNs(34_000_000), 3));
    assert_eq!(&first.frame.color.data[..3], &[30, 20, 3], "BGR scalar decoded to RGB");
    assert_eq!(cameras.counts().unpaired_color, 2);
}

#[test]
fn depth_is_registered_to_the_colour_camera_with_the_extrinsics() {
    // A 12x10 depth camera 2 cm to the side of a 16x12 colour camera with
    // another focal length: the registered frame has the colour camera's
    // size and is what `register_depth_to_color` makes of the depth frame.
    let depth_k = intrinsics(12, 10, 12.0);
    let color_k = intrinsics(16, 12, 15.0);
    let color_from_depth = Isometry3::from_parts(
        Translation3::new(0.02, 0.0, 0.0),
        UnitQuaternion::from_euler_angles(0.0, 0.02, 0.0),
    );
    let raw: Vec<u16> = (0..120).map(|i| 500 + (i % 12) as u16 * 10).collect();
    let registration = DepthRegistration { depth_intrinsics: depth_k.clone(), color_from_depth };
    let expected = register_depth_to_color(
        &DepthImage { width: 12, height: 10, data: raw.clone(), scale_m: 0.001 },
        &depth_k,
        &color_k,
        &color_from_depth,
    )
    .unwrap();
    let settings = PairSettings { registration: Some(registration), ..settings(color_k.clone(), 16) };
    let mut cameras = pair(vec![color(10, 1, 16, 12)], vec![depth_png(10, &raw, 12)], settings);
    let frame = cameras.next_frame().unwrap().unwrap().frame;
    assert_eq!((frame.depth.width, frame.depth.height), (16, 12));
    assert_eq!(frame.depth, expected);
    assert_eq!(frame.intrinsics, color_k);
    // Without registration the sizes differ: an error, not a wrong frame.
    let mut unregistered =
        pair(vec![color(10, 1, 16, 12)], vec![depth_png(10, &raw, 12)], super::tests::settings(color_k, 16));
    assert!(matches!(unregistered.next_frame(), Err(VisionError::SizeMismatch { .. })));
}

#[test]
fn a_replay_ends_and_a_stalled_camera_times_out() {
    let k = intrinsics(8, 6, 10.0);
    let ended = Arc::new(AtomicBool::new(true));
    let mut replay =
        pair(vec![color(0, 1, 8, 6)], vec![depth(0, 750, 8, 6)], settings(k.clone(), 16)).with_end(ended);
    assert!(replay.next_frame().unwrap().is_some(), "what was delivered before the end");
    assert!(replay.next_frame().unwrap().is_none());
    let mut stalled = pair(vec![color(0, 1, 8, 6)], vec![], settings(k, 16));
    let started = Instant::now();
    let e = stalled.next_frame().unwrap_err();
    assert!(started.elapsed() >= Duration::from_millis(200), "waited for the timeout");
    assert!(e.to_string().contains("no colour and depth frames within 16.0 ms"), "{e}");
}
