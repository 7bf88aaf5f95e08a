//! [`CameraPair`]: a live RGB-D camera as two [`Camera`]s, colour (MJPG or
//! YUYV, delivered as JPEG) and depth (`Z16`, delivered as a 16-bit PNG), as
//! the V4L2 backend of `slidetrack-drivers` exposes a RealSense-like device.
//! Frames are paired by time: each depth frame with the colour frame closest
//! to it within half a frame period.

use std::collections::VecDeque;
use std::time::Duration;

use slidetrack_core::{Camera, CameraIntrinsics, DeviceError, ErrorKind, Frame, RgbdFrame, TimeNs};

use super::{RgbdSample, RgbdSource, decode_color, decode_depth};
use crate::VisionError;

/// Colour and depth cameras of one RGB-D device (registered images).
pub struct CameraPair {
    color: Box<dyn Camera>,
    depth: Box<dyn Camera>,
    intrinsics: CameraIntrinsics,
    /// Metres per depth unit (0.001 for RealSense `Z16`).
    depth_scale_m: f64,
    /// Largest time between paired frames.
    tolerance_ns: u64,
    colors: VecDeque<Frame>,
    depths: VecDeque<Frame>,
    sequence: u64,
}

impl CameraPair {
    /// Pairs `color` and `depth` frames no further apart than half of
    /// `frame_period`; `intrinsics` are the (registered) colour intrinsics.
    pub fn new(
        color: Box<dyn Camera>,
        depth: Box<dyn Camera>,
        intrinsics: CameraIntrinsics,
        depth_scale_m: f64,
        frame_period: Duration,
    ) -> CameraPair {
        CameraPair {
            color,
            depth,
            intrinsics,
            depth_scale_m,
            tolerance_ns: (frame_period.as_nanos() / 2) as u64,
            colors: VecDeque::new(),
            depths: VecDeque::new(),
            sequence: 0,
        }
    }

    /// Pulls what the cameras have and returns the next pair, if complete.
    fn try_pair(&mut self) -> Result<Option<(Frame, Frame)>, VisionError> {
        while let Some(f) = self.color.poll()? {
            self.colors.push_back(f);
        }
        while let Some(f) = self.depth.poll()? {
            self.depths.push_back(f);
        }
        while let Some(d) = self.depths.front() {
            let t = d.t.0;
            // Colour frames too old for this depth frame can never pair.
            while self.colors.front().is_some_and(|c| c.t.0 + self.tolerance_ns < t) {
                self.colors.pop_front();
            }
            match self.colors.front() {
                Some(c) if c.t.0 <= t + self.tolerance_ns => {
                    let (Some(c), Some(d)) = (self.colors.pop_front(), self.depths.pop_front()) else {
                        return Ok(None);
                    };
                    return Ok(Some((c, d)));
                }
                // The colour frame is newer than this depth frame allows:
                // drop the depth frame.
                Some(_) => {
                    self.depths.pop_front();
                }
                None => return Ok(None),
            }
        }
        Ok(None)
    }
}

impl RgbdSource for CameraPair {
    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    /// Blocks (polling every millisecond) until a pair is complete; ends
    /// with the cameras' error when one fails, or a timeout error when no
    /// pair completes within 5 s.
    fn next_frame(&mut self) -> Result<Option<RgbdSample>, VisionError> {
        let started = std::time::Instant::now();
        loop {
            if started.elapsed() > Duration::from_secs(5) {
                let detail = "no colour and depth frames within half a frame period of each other for 5 s";
                return Err(DeviceError::new(ErrorKind::Timeout, self.depth.device(), detail).into());
            }
            if let Some((c, d)) = self.try_pair()? {
                let bad = |what: &'static str| VisionError::BadImage {
                    what,
                    detail: "the camera delivered no encoded image".into(),
                };
                let color = decode_color(&c.encoded.ok_or(bad("colour frame"))?.bytes)?;
                let depth = decode_depth(&d.encoded.ok_or(bad("depth frame"))?.bytes, self.depth_scale_m)?;
                if (color.width, color.height) != (depth.width, depth.height) {
                    return Err(VisionError::SizeMismatch {
                        what: "depth frame",
                        width: depth.width,
                        height: depth.height,
                        expected_width: color.width,
                        expected_height: color.height,
                    });
                }
                let frame = RgbdFrame {
                    t: TimeNs(d.t.0),
                    sequence: self.sequence,
                    color,
                    depth,
                    intrinsics: self.intrinsics.clone(),
                };
                self.sequence += 1;
                return Ok(Some(RgbdSample { frame, truth: None, truth_mask: None }));
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use opencv::core::{Mat, Scalar, Vector};
    use opencv::imgcodecs;
    use opencv::prelude::*;
    use slidetrack_core::EncodedImage;

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

    fn encoded(ext: &str, mat: &Mat) -> EncodedImage {
        let mut bytes = Vector::<u8>::new();
        imgcodecs::imencode(ext, mat, &mut bytes, &Vector::new()).unwrap();
        EncodedImage { format: ext.trim_start_matches('.').into(), bytes: bytes.to_vec() }
    }

    #[test]
    fn frames_pair_by_time_and_decode() {
        let k = CameraIntrinsics {
            width: 8,
            height: 6,
            fx: 10.0,
            fy: 10.0,
            cx: 4.0,
            cy: 3.0,
            distortion: [0.0; 5],
        };
        let rgb =
            Mat::new_rows_cols_with_default(6, 8, opencv::core::CV_8UC3, Scalar::new(10.0, 20.0, 30.0, 0.0))
                .unwrap();
        let depth =
            Mat::new_rows_cols_with_default(6, 8, opencv::core::CV_16UC1, Scalar::all(750.0)).unwrap();
        let frame =
            |t: u64, e: EncodedImage| Frame { t: TimeNs(t), sequence: t, pixels: None, encoded: Some(e) };
        let colors = [0u64, 33_000_000, 66_000_000].map(|t| frame(t, encoded(".png", &rgb))).into();
        let depths = [34_000_000u64, 70_000_000].map(|t| frame(t, encoded(".png", &depth))).into();
        let mut pair = CameraPair::new(
            Box::new(Scripted { frames: colors, intrinsics: k.clone() }),
            Box::new(Scripted { frames: depths, intrinsics: k.clone() }),
            k,
            0.001,
            Duration::from_millis(33),
        );
        let first = pair.next_frame().unwrap().unwrap();
        assert_eq!(first.frame.t, TimeNs(34_000_000));
        assert_eq!(first.frame.depth.depth_m(0, 0), Some(0.75));
        assert_eq!(&first.frame.color.data[..3], &[30, 20, 10], "BGR scalar decoded to RGB");
        let second = pair.next_frame().unwrap().unwrap();
        assert_eq!(second.frame.sequence, 1);
    }
}
