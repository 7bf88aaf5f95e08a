//! Live calibration from a camera: grab frames, find the pattern, keep views
//! that add something (another part of the image, another distance, another
//! tilt) until enough are kept. No preview window: progress goes to a callback.
//!
//! Any [`Camera`] works, the simulated rig's `SimBoardCamera` (a rendered
//! chessboard moving in front of it) included, so the whole procedure runs
//! without hardware.

use std::time::{Duration, Instant};

use opencv::core::{Mat, MatTraitConst, MatTraitConstManual};
use slidetrack_core::{Camera, DeviceError, Frame, Image, PixelFormat};

use crate::calibrate::{CalibrationError, Cv, PatternFinder, PatternView, gray_mat};
use crate::error::MarkerError;

/// Where a view sits: centre and size in the image, and how the pattern is
/// tilted (log ratios of opposite sides), all dimensionless.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewPlacement {
    /// Centre of the pattern's points, as a fraction of the width and the height.
    pub centre: [f64; 2],
    /// Square root of the area of the points' bounding box over the image area.
    pub scale: f64,
    /// `ln(left / right)` and `ln(top / bottom)` of the pattern's outer sides.
    pub tilt: [f64; 2],
}

impl ViewPlacement {
    /// The placement of `view` in a `width x height` image.
    pub fn of(view: &PatternView, width: u32, height: u32) -> Option<ViewPlacement> {
        let pts = &view.image_points;
        let obj = &view.object_points;
        if pts.len() < 4 {
            return None;
        }
        let (w, h) = (f64::from(width.max(1)), f64::from(height.max(1)));
        let n = pts.len() as f64;
        let centre = [
            pts.iter().map(|p| f64::from(p[0])).sum::<f64>() / n / w,
            pts.iter().map(|p| f64::from(p[1])).sum::<f64>() / n / h,
        ];
        let (lo, hi) = pts.iter().fold(([f64::MAX; 2], [f64::MIN; 2]), |(lo, hi), p| {
            let (x, y) = (f64::from(p[0]), f64::from(p[1]));
            ([lo[0].min(x), lo[1].min(y)], [hi[0].max(x), hi[1].max(y)])
        });
        let scale = (((hi[0] - lo[0]) * (hi[1] - lo[1])).max(0.0) / (w * h)).sqrt();
        // The four extreme points of the pattern, by their pattern coordinates.
        let pick = |score: &dyn Fn(&[f32; 3]) -> f32| {
            let k = (0..obj.len()).max_by(|&a, &b| score(&obj[a]).total_cmp(&score(&obj[b])))?;
            Some([f64::from(pts[k][0]), f64::from(pts[k][1])])
        };
        let tl = pick(&|o| -o[0] - o[1])?;
        let tr = pick(&|o| o[0] - o[1])?;
        let br = pick(&|o| o[0] + o[1])?;
        let bl = pick(&|o| -o[0] + o[1])?;
        let len = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]).max(1e-6);
        let tilt = [(len(tl, bl) / len(tr, br)).ln(), (len(tl, tr) / len(bl, br)).ln()];
        Some(ViewPlacement { centre, scale, tilt })
    }

    /// Distance between two placements: centre counts fully, size and tilt
    /// at half weight.
    pub fn distance(&self, other: &ViewPlacement) -> f64 {
        let d = [
            self.centre[0] - other.centre[0],
            self.centre[1] - other.centre[1],
            0.5 * (self.scale - other.scale),
            0.5 * (self.tilt[0] - other.tilt[0]),
            0.5 * (self.tilt[1] - other.tilt[1]),
        ];
        d.iter().map(|v| v * v).sum::<f64>().sqrt()
    }
}

/// How the live capture runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LiveOptions {
    /// Views to keep.
    pub views: usize,
    /// Smallest [`ViewPlacement::distance`] of a new view to every kept one.
    pub min_spread: f64,
    /// Give up after this many frames.
    pub max_frames: u64,
    /// Give up after this much wall time.
    pub timeout: Duration,
    /// Keep every kept view's frame as lossless PNG bytes in
    /// [`LiveCapture::images`] (to save them and calibrate again from files).
    pub keep_images: bool,
}

impl Default for LiveOptions {
    fn default() -> Self {
        LiveOptions {
            views: 20,
            min_spread: 0.12,
            max_frames: 20_000,
            timeout: Duration::from_secs(300),
            keep_images: false,
        }
    }
}

/// What happened to one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FrameVerdict {
    /// The pattern is not (fully) in it.
    NoPattern,
    /// Too close to a view already kept.
    TooSimilar,
    /// Kept.
    Kept(ViewPlacement),
}

/// Progress of a live capture, after every frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LiveProgress {
    /// Frames looked at.
    pub frames: u64,
    /// Views kept.
    pub kept: usize,
    /// Views wanted.
    pub wanted: usize,
    /// What happened to this frame.
    pub verdict: FrameVerdict,
}

/// The views a live capture kept.
#[derive(Clone, Debug, PartialEq)]
pub struct LiveCapture {
    /// Kept views, in capture order.
    pub views: Vec<PatternView>,
    /// Where each kept view sits.
    pub placements: Vec<ViewPlacement>,
    /// Image width (px).
    pub width: u32,
    /// Image height (px).
    pub height: u32,
    /// Frames looked at.
    pub frames: u64,
    /// Frames in which the pattern was found.
    pub frames_with_pattern: u64,
    /// With [`LiveOptions::keep_images`]: each kept view's frame, 8-bit gray
    /// PNG, in the order of `views`; empty otherwise.
    pub images: Vec<Vec<u8>>,
}

/// Captures well-spread views of the pattern from `camera`. Stops when
/// `options.views` views are kept, or (returning what it has) after
/// `max_frames` frames or `timeout`; fails when the camera fails.
pub fn capture_views(
    camera: &mut dyn Camera,
    finder: &mut PatternFinder,
    options: &LiveOptions,
    progress: &mut dyn FnMut(&LiveProgress),
) -> Result<LiveCapture, LiveError> {
    let started = Instant::now();
    let intrinsics = camera.intrinsics().clone();
    let mut capture = LiveCapture {
        views: Vec::new(),
        placements: Vec::new(),
        width: intrinsics.width,
        height: intrinsics.height,
        frames: 0,
        frames_with_pattern: 0,
        images: Vec::new(),
    };
    while capture.views.len() < options.views && capture.frames < options.max_frames {
        if started.elapsed() > options.timeout {
            break;
        }
        let Some(frame) = camera.poll().map_err(LiveError::Camera)? else {
            std::thread::sleep(Duration::from_millis(2));
            continue;
        };
        capture.frames += 1;
        let gray = frame_gray(&frame)?;
        let (w, h) = (gray.cols().max(0) as u32, gray.rows().max(0) as u32);
        (capture.width, capture.height) = (w, h);
        let verdict = match finder.find(&gray)? {
            None => FrameVerdict::NoPattern,
            Some(view) => {
                capture.frames_with_pattern += 1;
                match ViewPlacement::of(&view, w, h) {
                    Some(p) if capture.placements.iter().all(|q| p.distance(q) >= options.min_spread) => {
                        if options.keep_images {
                            capture.images.push(encode_png(&gray)?);
                        }
                        capture.views.push(view);
                        capture.placements.push(p);
                        FrameVerdict::Kept(p)
                    }
                    _ => FrameVerdict::TooSimilar,
                }
            }
        };
        let kept = capture.views.len();
        progress(&LiveProgress { frames: capture.frames, kept, wanted: options.views, verdict });
    }
    Ok(capture)
}

/// A frame as 8-bit gray: its pixels, or its JPEG/PNG bytes decoded.
fn frame_gray(frame: &Frame) -> Result<Mat, LiveError> {
    if let Some(image) = &frame.pixels {
        return Ok(gray_mat(image)?);
    }
    let Some(encoded) = &frame.encoded else {
        return Err(LiveError::EmptyFrame { sequence: frame.sequence });
    };
    let gray = crate::codec::decode(&encoded.bytes, PixelFormat::Gray8)
        .map_err(|e| CalibrationError::Marker(MarkerError::Decode(e)))?;
    Ok(gray_mat(&gray)?)
}

/// `gray` as PNG bytes (lossless, so a saved view gives the same corners).
fn encode_png(gray: &Mat) -> Result<Vec<u8>, LiveError> {
    let data = gray.data_bytes().cv("Mat::data_bytes")?.to_vec();
    let image =
        Image { width: gray.cols() as u32, height: gray.rows() as u32, format: PixelFormat::Gray8, data };
    Ok(crate::codec::encode_png(&image).map_err(CalibrationError::Marker)?.bytes)
}

/// Why a live capture stopped.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LiveError {
    /// The camera failed.
    #[error("camera: {0}")]
    Camera(DeviceError),
    /// A frame had neither pixels nor decodable bytes.
    #[error("frame {sequence} has no decodable image")]
    EmptyFrame {
        /// The frame's sequence number.
        sequence: u64,
    },
    /// Finding the pattern failed.
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
}
