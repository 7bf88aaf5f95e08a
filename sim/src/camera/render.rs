//! [`SimCameraRenderer`]: the per-frame rendering path.

use nalgebra::Isometry3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use slidetrack_core::{CameraIntrinsics, Frame, Image, MarkerPattern, TimeNs, encode_jpeg};

use super::blocks::{BlockScratch, PlanarPattern, Scene, Target, draw_plane};
use super::board::{BoardPattern, Chessboard};
use super::board_face::{BoardFacePattern, BoardPrint};
use super::config::SimCameraConfig;
use super::error::SimCameraError;
use super::face::FacePattern;
use super::object::ObjectAppearance;
use super::raster::{
    FIXED_ONE, PixelRect, PlaneInCamera, UndistortionMap, blur, gaussian_kernel, outline_bbox, quantise_one,
    to_fixed,
};
use super::texture::{BackgroundPlane, Texture, splitmix64};

/// Renders the simulated camera's frames: the object's marker face in front of
/// a static textured background, with distortion, blur, noise and JPEG.
///
/// Deterministic: the same configuration, seed and calls give the same bytes.
/// The noise of frame `sequence` depends only on `(seed, sequence)`, not on
/// the frames rendered before it.
pub struct SimCameraRenderer {
    config: SimCameraConfig,
    appearance: ObjectAppearance,
    marker: MarkerPattern,
    /// A board printed instead of the marker.
    board: Option<BoardPrint>,
    seed: u64,
    hand_from_camera: Isometry3<f64>,
    channels: usize,
    map: UndistortionMap,
    /// Half size of the square (normalised coordinates) that the object
    /// outline is clipped to: a little wider than the image.
    frustum_half_size: f64,
    /// The unblurred background, `channels` floats per pixel (0..255).
    background: Vec<f32>,
    /// The blurred background in fixed point (16 units per gray level).
    background_fixed: Vec<i16>,
    /// Gaussian noise in fixed point; each frame reads a window at a
    /// pseudo-random offset.
    noise_fixed: Vec<i16>,
    kernel: Vec<f32>,
    scratch: BlockScratch,
}

/// Smallest block of the block renderer (px).
const MIN_BLOCK_PX: usize = 4;

impl SimCameraRenderer {
    /// Builds the renderer: validates the inputs, inverts the distortion on
    /// the pixel grid, renders and blurs the background and draws the noise
    /// table from `seed`. Takes about 0.15 s at 640x480 (release build).
    pub fn new(
        config: SimCameraConfig,
        appearance: ObjectAppearance,
        marker: MarkerPattern,
        seed: u64,
    ) -> Result<SimCameraRenderer, SimCameraError> {
        config.validate()?;
        appearance.validate()?;
        marker.validate()?;
        let hand_from_camera = config.hand_from_camera()?;
        let intrinsics = &config.intrinsics;
        let (width, height) = (intrinsics.width as usize, intrinsics.height as usize);
        let channels = config.pixel_format.channels();
        let map = UndistortionMap::new(intrinsics);
        let plane = BackgroundPlane::new(&config.background).ok_or(SimCameraError::BadBackgroundNormal {
            normal_in_hand: config.background.normal_in_hand,
        })?;
        let texture = Texture::new(&config.background);
        let full = PixelRect::full(width, height);
        let background = plane.render(&texture, &map, &hand_from_camera, full, channels);
        let kernel = gaussian_kernel(config.blur_sigma_px);
        let mut blurred = background.clone();
        match channels {
            1 => blur::<1>(&mut blurred, width, height, &kernel, &mut Vec::new()),
            _ => blur::<3>(&mut blurred, width, height, &kernel, &mut Vec::new()),
        }
        let background_fixed = blurred.iter().map(|&v| to_fixed(v)).collect();
        let noise_fixed = noise_table(seed, width * height * channels, config.noise_std_gray);
        Ok(SimCameraRenderer {
            frustum_half_size: 1.25 * map.half_extent(),
            config,
            appearance,
            marker,
            board: None,
            seed,
            hand_from_camera,
            channels,
            map,
            background,
            background_fixed,
            noise_fixed,
            kernel,
            scratch: BlockScratch::with_threads(several_cores()),
        })
    }

    /// As [`SimCameraRenderer::new`], with a board printed on the face
    /// instead of one marker, centred at `appearance.marker_centre_on_face_m`
    /// (its centre frame, [`slidetrack_core::BoardLayout::board_from_centre`],
    /// is then the "marker" frame of [`SimCameraRenderer::camera_from_marker`]).
    pub fn with_board(
        config: SimCameraConfig,
        appearance: ObjectAppearance,
        board: BoardPrint,
        seed: u64,
    ) -> Result<SimCameraRenderer, SimCameraError> {
        board.layout.validate()?;
        let expected = board.layout.markers().len();
        let first =
            board.markers.first().cloned().ok_or(SimCameraError::BoardMarkers { expected, given: 0 })?;
        if board.markers.len() != expected || board.markers.iter().any(|m| m.cells != first.cells) {
            return Err(SimCameraError::BoardMarkers { expected, given: board.markers.len() });
        }
        for m in &board.markers {
            m.validate()?;
        }
        let mut renderer = SimCameraRenderer::new(config, appearance, first, seed)?;
        renderer.board = Some(board);
        Ok(renderer)
    }

    /// The board printed instead of the marker, if any.
    pub fn board(&self) -> Option<&BoardPrint> {
        self.board.as_ref()
    }

    /// With `exhaustive`, renders every pixel of the plane's surroundings one
    /// by one over the whole image (several times slower): the reference the
    /// block renderer is checked against.
    pub fn set_exhaustive(&mut self, exhaustive: bool) {
        self.scratch.exhaustive = exhaustive;
    }

    /// With `two_threads` (the default where this process may run on two
    /// cores or more), the lower half of the object's neighbourhood is drawn
    /// on a second thread. The frames are the same either way.
    pub fn set_two_threads(&mut self, two_threads: bool) {
        self.scratch.two_threads = two_threads;
    }

    /// The camera pose in the hand frame.
    pub fn hand_from_camera(&self) -> &Isometry3<f64> {
        &self.hand_from_camera
    }

    /// The intrinsics the frames are rendered with (the simulator's truth).
    pub fn intrinsics(&self) -> &CameraIntrinsics {
        &self.config.intrinsics
    }

    /// The configuration the renderer was built from.
    pub fn config(&self) -> &SimCameraConfig {
        &self.config
    }

    /// How the object looks.
    pub fn appearance(&self) -> &ObjectAppearance {
        &self.appearance
    }

    /// The marker printed on the object.
    pub fn marker(&self) -> &MarkerPattern {
        &self.marker
    }

    /// The true pose of the marker in the camera frame for an object pose.
    pub fn camera_from_marker(&self, hand_from_object: &Isometry3<f64>) -> Isometry3<f64> {
        self.hand_from_camera.inverse() * hand_from_object * self.appearance.object_from_marker()
    }

    /// Renders one frame and encodes it as JPEG; `t` is stamped on the frame.
    /// The pixels are always there; `encoded` is `None` only if the JPEG
    /// encoder fails (it cannot for a validated configuration), which is logged.
    pub fn render(&mut self, hand_from_object: &Isometry3<f64>, t: TimeNs, sequence: u64) -> Frame {
        let pixels = self.render_image(hand_from_object, sequence);
        let encoded = match encode_jpeg(&pixels, self.config.jpeg_quality) {
            Ok(encoded) => Some(encoded),
            Err(e) => {
                tracing::warn!(sequence, "sim camera: {e}");
                None
            }
        };
        Frame { t, sequence, pixels: Some(pixels), encoded }
    }

    /// Renders the pixels of frame `sequence` with the object at `hand_from_object`.
    pub fn render_image(&mut self, hand_from_object: &Isometry3<f64>, sequence: u64) -> Image {
        let camera_from_face =
            self.hand_from_camera.inverse() * hand_from_object * self.appearance.object_from_face();
        let plane = PlaneInCamera::new(&camera_from_face, false);
        let [w, h] = self.appearance.face_size_m.map(|s| s / 2.0);
        let outline = [(-w, -h), (w, -h), (w, h), (-w, h)];
        let noise_key = splitmix64(self.seed ^ splitmix64(sequence));
        let mut scratch = std::mem::take(&mut self.scratch);
        let image = if let Some(board) = &self.board {
            let pattern = BoardFacePattern::new(&self.appearance, board, &plane);
            let visible =
                plane.faces_camera().then_some(Drawn { plane: &plane, pattern: &pattern, outline: &outline });
            self.compose(visible, noise_key, &mut scratch)
        } else {
            let pattern = FacePattern::new(&self.appearance, &self.marker, &plane);
            let visible =
                plane.faces_camera().then_some(Drawn { plane: &plane, pattern: &pattern, outline: &outline });
            self.compose(visible, noise_key, &mut scratch)
        };
        self.scratch = scratch;
        image
    }

    /// Renders a calibration chessboard at `camera_from_board` (board frame as
    /// in OpenCV: origin at the first inner corner, x along a row of corners,
    /// y along a column, z into the board) in front of the background, through
    /// the same projection, distortion, blur and noise as the frames. The
    /// object is not drawn. The noise depends on the seed and the pose.
    pub fn render_board(&self, board: &Chessboard, camera_from_board: &Isometry3<f64>) -> Image {
        let plane = PlaneInCamera::new(camera_from_board, true);
        let pattern = BoardPattern::new(board);
        let outline = pattern.outline();
        let pose_bits =
            camera_from_board.to_homogeneous().iter().fold(0u64, |h, v| splitmix64(h ^ v.to_bits()));
        let noise_key = splitmix64(self.seed ^ pose_bits);
        let drawn = Drawn { plane: &plane, pattern: &pattern, outline: &outline };
        let mut scratch = BlockScratch::with_threads(self.scratch.two_threads);
        self.compose(Some(drawn), noise_key, &mut scratch)
    }

    /// Background plus (optionally) one plane, blurred, noisy, quantised.
    fn compose<P: PlanarPattern + Sync>(
        &self,
        drawn: Option<Drawn<'_, P>>,
        noise_key: u64,
        scratch: &mut BlockScratch,
    ) -> Image {
        let c = &self.config.intrinsics;
        let (width, height) = (c.width as usize, c.height as usize);
        let channels = self.channels;
        let n = width * height * channels;
        let offset = (noise_key % (self.noise_fixed.len() - n + 1) as u64) as usize;
        let noise = &self.noise_fixed[offset..offset + n];
        // Written once, not zeroed first (every byte is the background's).
        let mut data = quantised(&self.background_fixed, noise);
        let Some(Drawn { plane, pattern, outline }) = drawn else {
            return self.image(data);
        };
        let Some(inner) = outline_bbox(c, plane, outline, self.frustum_half_size) else {
            return self.image(data);
        };
        // Blocks must be at least a blur radius wide; the rectangle holds the
        // outline plus one block and one blur radius on every side.
        let radius = self.kernel.len() / 2;
        let block_size = radius.max(MIN_BLOCK_PX);
        let rect = if scratch.exhaustive {
            PixelRect::full(width, height)
        } else {
            inner.grown(block_size + radius + 1, width, height)
        };
        let scene = Scene { map: &self.map, background: &self.background, kernel: &self.kernel };
        let mut target = Target { data: &mut data, noise, image_width: width, row0: 0 };
        if channels == 1 {
            draw_plane::<P, 1>(&scene, plane, pattern, rect, block_size, &mut target, scratch);
        } else {
            draw_plane::<P, 3>(&scene, plane, pattern, rect, block_size, &mut target, scratch);
        }
        self.image(data)
    }

    fn image(&self, data: Vec<u8>) -> Image {
        let c = &self.config.intrinsics;
        Image { width: c.width, height: c.height, format: self.config.pixel_format, data }
    }
}

/// The noisy background of a whole frame, quantised as by
/// [`quantise`](super::raster::quantise), in a vector filled once (no
/// zeroing first). A frame with the object out of view takes about 17 us
/// at 640x480 gray this way, 21 us zeroed first and 33 us with half of it
/// handed to a pool thread (`time_the_renderer`, release build).
fn quantised(scene_fixed: &[i16], noise_fixed: &[i16]) -> Vec<u8> {
    scene_fixed.iter().zip(noise_fixed).map(|(&s, &n)| quantise_one(s, n)).collect()
}

/// Whether this process may run on two cores or more.
fn several_cores() -> bool {
    std::thread::available_parallelism().is_ok_and(|n| n.get() >= 2)
}

/// A plane to draw over the background: where, what, and its outline in
/// plane coordinates (m).
struct Drawn<'a, P> {
    plane: &'a PlaneInCamera,
    pattern: &'a P,
    outline: &'a [(f64, f64)],
}

/// `2n + 4099` Gaussian samples of standard deviation `std_gray`, in fixed point.
fn noise_table(seed: u64, n: usize, std_gray: f64) -> Vec<i16> {
    let len = 2 * n + 4099;
    if std_gray <= 0.0 {
        return vec![0; len];
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let limit = f32::from(i16::MAX / 4);
    (0..len)
        .map(|_| {
            let z: f32 = rng.sample(StandardNormal);
            (z * std_gray as f32 * FIXED_ONE).round().clamp(-limit, limit) as i16
        })
        .collect()
}
