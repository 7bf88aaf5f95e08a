//! The simulated camera looking at a chessboard that someone moves in front
//! of it: the source of live camera calibration without hardware.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use slidetrack_core::{Camera, CameraIntrinsics, DeviceError, Frame, Image, MarkerPattern, TimeNs};

use crate::camera::{Chessboard, ObjectAppearance, SimCameraConfig, SimCameraError, SimCameraRenderer};

/// The simulated camera of the rig looking at a chessboard that someone
/// moves in front of it: every poll renders the next frame (30 Hz simulated
/// time), the board sweeping the image at 0.3 to 0.6 m with tilts up to
/// about 30 degrees. Deterministic for a seed.
pub struct SimBoardCamera {
    renderer: SimCameraRenderer,
    board: Chessboard,
    intrinsics: CameraIntrinsics,
    sequence: u64,
    period_ns: u64,
}

impl SimBoardCamera {
    /// A camera rendering `board` with the simulated camera `config`.
    pub fn new(
        config: SimCameraConfig,
        board: Chessboard,
        seed: u64,
    ) -> Result<SimBoardCamera, SimCameraError> {
        // The board camera shows no object: a blank marker stands in for one.
        let marker = MarkerPattern { dictionary: "none".into(), id: 0, cells: 1, bits: vec![0] };
        let period_ns = config.frame_period_ns();
        let renderer = SimCameraRenderer::new(config, ObjectAppearance::default(), marker, seed)?;
        let intrinsics = renderer.intrinsics().clone();
        Ok(SimBoardCamera { renderer, board, intrinsics, sequence: 0, period_ns })
    }

    /// The board's pose in the camera frame at frame `k`.
    pub fn camera_from_board(&self, k: u64) -> Isometry3<f64> {
        let c = &self.intrinsics;
        let phase = |period: f64, offset: f64| (std::f64::consts::TAU * k as f64 / period + offset).sin();
        let z = 0.45 + 0.15 * phase(29.0, 0.3);
        // Where the board centre appears, in pixels, then back to metres at depth z.
        let u = c.cx + 0.22 * f64::from(c.width) * phase(37.0, 0.0);
        let v = c.cy + 0.22 * f64::from(c.height) * phase(23.0, 1.0);
        let centre = Vector3::new((u - c.cx) / c.fx * z, (v - c.cy) / c.fy * z, z);
        let tilt = UnitQuaternion::from_euler_angles(
            0.5 * phase(17.0, 0.5),
            0.5 * phase(13.0, 2.0),
            0.25 * phase(41.0, 0.0),
        );
        let [nx, ny] = self.board.inner_corners;
        let s = self.board.square_size_m;
        let board_centre = Vector3::new(f64::from(nx - 1) * s / 2.0, f64::from(ny - 1) * s / 2.0, 0.0);
        Isometry3::from_parts(Translation3::from(centre), tilt) * Translation3::from(-board_centre)
    }

    /// Renders the board at `camera_from_board` (board frame as in OpenCV:
    /// origin at the first inner corner, z into the board).
    pub fn render(&self, camera_from_board: &Isometry3<f64>) -> Image {
        self.renderer.render_board(&self.board, camera_from_board)
    }
}

impl Camera for SimBoardCamera {
    fn poll(&mut self) -> Result<Option<Frame>, DeviceError> {
        let k = self.sequence;
        let pixels = self.render(&self.camera_from_board(k));
        self.sequence += 1;
        Ok(Some(Frame { t: TimeNs(k * self.period_ns), sequence: k, pixels: Some(pixels), encoded: None }))
    }

    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    fn device(&self) -> &str {
        "sim board camera"
    }
}
