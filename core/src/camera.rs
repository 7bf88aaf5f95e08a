//! Cameras: frames with timestamps, and the intrinsics that go with them.

use serde::{Deserialize, Serialize};

use crate::{DeviceError, EncodedImage, Image, TimeNs};

/// Pinhole intrinsics with plumb-bob (Brown-Conrady) distortion, as in ROS
/// `camera_info` and OpenCV: `k1, k2, p1, p2, k3`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraIntrinsics {
    /// Image width (px).
    pub width: u32,
    /// Image height (px).
    pub height: u32,
    /// Focal length along x (px).
    pub fx: f64,
    /// Focal length along y (px).
    pub fy: f64,
    /// Principal point x (px).
    pub cx: f64,
    /// Principal point y (px).
    pub cy: f64,
    /// `[k1, k2, p1, p2, k3]`, dimensionless.
    pub distortion: [f64; 5],
}

impl CameraIntrinsics {
    /// Camera matrix `K`, row-major.
    pub fn k(&self) -> [f64; 9] {
        [self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0]
    }

    /// Applies the distortion model to normalised coordinates `(x, y) = (X/Z, Y/Z)`.
    pub fn distort_normalized(&self, x: f64, y: f64) -> (f64, f64) {
        let [k1, k2, p1, p2, k3] = self.distortion;
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
        (xd, yd)
    }

    /// Projects a point in the camera frame (m, z forward) to pixels, with
    /// distortion. `None` behind the camera.
    pub fn project(&self, point_in_camera: [f64; 3]) -> Option<(f64, f64)> {
        let [x, y, z] = point_in_camera;
        if z <= 1e-9 {
            return None;
        }
        let (xd, yd) = self.distort_normalized(x / z, y / z);
        Some((self.fx * xd + self.cx, self.fy * yd + self.cy))
    }

    /// Inverts the distortion: pixel -> normalised undistorted coordinates, by
    /// fixed-point iteration (converges for the moderate distortion of real
    /// lenses; 20 iterations reach well under 1e-9 for |k1| < 0.5).
    pub fn undistort_pixel(&self, u: f64, v: f64) -> (f64, f64) {
        let xd = (u - self.cx) / self.fx;
        let yd = (v - self.cy) / self.fy;
        let [k1, k2, p1, p2, k3] = self.distortion;
        let (mut x, mut y) = (xd, yd);
        for _ in 0..20 {
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
            let dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
            let dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
            x = (xd - dx) / radial;
            y = (yd - dy) / radial;
        }
        (x, y)
    }
}

/// One camera frame.
///
/// A frame carries the decoded pixels, the compressed bytes, or both: a USB
/// camera streaming MJPG delivers bytes (decoded only when a detector needs
/// pixels); the simulator renders pixels and also encodes them as the camera
/// would.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Exposure time on the session clock.
    pub t: TimeNs,
    /// The camera's frame counter.
    pub sequence: u64,
    /// Decoded pixels, when available.
    pub pixels: Option<Image>,
    /// Compressed bytes as delivered, when available.
    pub encoded: Option<EncodedImage>,
}

/// A camera.
///
/// # Contract
/// - `poll` never blocks: it returns the oldest frame exposed at or before
///   the current session time that has not been returned yet, or `None`.
///   On simulated time the frame is rendered on demand.
/// - Frames come in exposure order. A backend that had to drop frames says
///   so through the gap in `sequence`.
/// - Errors: [`crate::ErrorKind::Disconnected`] when the device is gone.
pub trait Camera: Send {
    /// The next frame, if one is ready.
    fn poll(&mut self) -> Result<Option<Frame>, DeviceError>;
    /// The camera's intrinsics (from its calibration file, or the simulator's truth).
    fn intrinsics(&self) -> &CameraIntrinsics;
    /// Name of the device, for messages.
    fn device(&self) -> &str;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> CameraIntrinsics {
        CameraIntrinsics {
            width: 640,
            height: 480,
            fx: 600.0,
            fy: 601.0,
            cx: 321.0,
            cy: 239.0,
            distortion: [-0.12, 0.05, 0.001, -0.0005, 0.0],
        }
    }

    #[test]
    fn undistort_inverts_distort() {
        let c = cam();
        for &(x, y) in &[(0.0, 0.0), (0.3, -0.2), (-0.45, 0.35), (0.1, 0.4)] {
            let (u, v) = c.project([x, y, 1.0]).unwrap();
            let (xu, yu) = c.undistort_pixel(u, v);
            assert!((xu - x).abs() < 1e-9 && (yu - y).abs() < 1e-9, "{x},{y} -> {xu},{yu}");
        }
    }

    #[test]
    fn points_behind_the_camera_do_not_project() {
        assert!(cam().project([0.0, 0.0, -1.0]).is_none());
    }
}
