//! [`ArucoSource`]: the object's pose from an ArUco marker fixed to it, and
//! its mask rendered from the model at that pose.

use std::collections::VecDeque;
use std::path::Path;
use std::sync::mpsc;
use std::time::Instant;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use slidetrack_calibration::{Dictionary, MarkerDetector, MarkerPose, marker_pose_candidates};
use slidetrack_core::{CameraIntrinsics, DepthImage, RgbdFrame, TimeNs};
use slidetrack_estimators::roft::Mask;

use super::rendered_mask::MaskRenderer;
use super::source::{Arrivals, Delayed, FrameTruth, MeasurementSource};
use crate::VisionError;
use crate::cloud::pinhole;
use crate::model::ObjectModel;

/// A rigid transform as written in the configuration files.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseConfig {
    /// Translation (m).
    pub translation_m: [f64; 3],
    /// Rotation as a unit quaternion `[x, y, z, w]`.
    pub rotation_xyzw: [f64; 4],
}

impl PoseConfig {
    /// The transform; `what` names it in the error.
    pub fn isometry(&self, what: &'static str) -> Result<Isometry3<f64>, VisionError> {
        let [x, y, z, w] = self.rotation_xyzw;
        let q = Quaternion::new(w, x, y, z);
        let norm = q.norm();
        if !(norm.is_finite() && (norm - 1.0).abs() < 1e-3)
            || self.translation_m.iter().any(|v| !v.is_finite())
        {
            return Err(VisionError::BadValue {
                what,
                detail: format!(
                    "rotation_xyzw {:?} is not a unit quaternion or translation_m is not finite",
                    self.rotation_xyzw
                ),
            });
        }
        Ok(Isometry3::from_parts(Translation3::from(self.translation_m), UnitQuaternion::from_quaternion(q)))
    }

    /// The configuration of `pose`.
    pub fn of(pose: &Isometry3<f64>) -> PoseConfig {
        let q = pose.rotation.coords;
        PoseConfig { translation_m: pose.translation.vector.into(), rotation_xyzw: [q.x, q.y, q.z, q.w] }
    }
}

/// When a result is handed over.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ArrivalDelay {
    /// At the frame time plus the measured detection (and rendering) time.
    #[default]
    Measured,
    /// At the frame time itself.
    None,
}

/// Settings of [`ArucoSource`] (the `--aruco-config` TOML file).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArucoConfig {
    /// OpenCV dictionary name, for example `DICT_4X4_50`.
    pub dictionary: String,
    /// The id of the marker on the object.
    pub marker_id: u32,
    /// Side of the marker's black square (m), border cells included.
    pub marker_size_m: f64,
    /// The object frame in the marker frame (OpenCV ArUco: origin at the
    /// centre, x right, y up as printed, z out of the marker).
    pub marker_from_object: PoseConfig,
    /// Detect on every n-th colour frame (1: all).
    #[serde(default = "one")]
    pub every_nth_frame: u32,
    /// When results arrive.
    #[serde(default)]
    pub delay: ArrivalDelay,
    /// Render masks from the model at each detected pose.
    #[serde(default = "yes")]
    pub masks: bool,
    /// Leave out of the masks the pixels whose measured depth differs from
    /// the rendered depth by more than this (m); absent: no depth check.
    #[serde(default)]
    pub mask_depth_tolerance_m: Option<f64>,
    /// Detections whose corners reproject worse than this (px, RMS) are dropped.
    #[serde(default = "two")]
    pub max_reprojection_error_px: f64,
    /// Detect on a thread of its own, one frame at a time, as a network
    /// would run beside the tracker: frames that come while it is busy are
    /// not searched (and counted). Off: detection runs in the caller's
    /// loop, on every `every_nth_frame`-th frame (repeatable).
    #[serde(default)]
    pub background: bool,
}

fn one() -> u32 {
    1
}

fn yes() -> bool {
    true
}

fn two() -> f64 {
    2.0
}

impl ArucoConfig {
    /// Reads a TOML configuration.
    pub fn load(path: &Path) -> Result<ArucoConfig, VisionError> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| VisionError::Io { path: path.to_path_buf(), source })?;
        toml::from_str(&text)
            .map_err(|e| VisionError::BadFile { path: path.to_path_buf(), detail: e.message().to_string() })
    }
}

/// A frame's `camera_from_object` and, when masks are rendered, its mask.
type Measured = (Isometry3<f64>, Option<Mask>);

/// What the search of one frame found.
enum Outcome {
    /// The marker, and the object's pose and mask from it.
    Found(Measured),
    /// No marker with the configured id.
    NoMarker,
    /// The marker, with a reprojection error above the limit.
    Rejected,
}

/// What the source did so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ArucoStats {
    /// Frames looked at.
    pub frames_searched: usize,
    /// Poses delivered (or pending).
    pub poses: usize,
    /// Frames searched without the marker.
    pub frames_without_marker: usize,
    /// Detections dropped for their reprojection error.
    pub rejected: usize,
    /// Frames not searched because the background detection was busy.
    pub skipped_busy: usize,
}

/// Poses `camera_from_object = camera_from_marker * marker_from_object` from
/// the marker seen in the colour image, and masks rendered from the model
/// at those poses.
///
/// Detection runs in the caller's thread on each `every_nth_frame`-th frame
/// (detection and mask rendering: about 17 ms a frame at 640x480 on this
/// project's 2-core machine under load), or with `background` on a thread
/// of its own. Each result refers to its frame and arrives, with
/// [`ArrivalDelay::Measured`], its compute time later: it is handed over by
/// the first frame at or after its arrival. Frames without the marker
/// produce nothing ([`ArucoStats`] counts them).
pub struct ArucoSource {
    config: ArucoConfig,
    runner: Runner,
    pending: VecDeque<(Delayed<Isometry3<f64>>, Option<Mask>)>,
    frame_index: u64,
    stats: ArucoStats,
}

/// Where the search runs.
enum Runner {
    Inline(Box<Measurer>),
    Background(Worker),
}

/// The search of one frame: detection, marker pose, object pose, mask.
struct Measurer {
    detector: MarkerDetector,
    marker_id: u32,
    marker_size_m: f64,
    max_reprojection_error_px: f64,
    marker_from_object: Isometry3<f64>,
    intrinsics: CameraIntrinsics,
    masks: Option<MaskRenderer>,
}

/// A search result: the frame's time, what it found, its compute time (ns).
type Searched = (TimeNs, Result<Outcome, VisionError>, u64);

/// A [`Measurer`] on its own thread, one frame at a time.
struct Worker {
    frames: mpsc::Sender<RgbdFrame>,
    results: mpsc::Receiver<Searched>,
    busy: bool,
}

impl Worker {
    fn spawn(mut measurer: Measurer) -> Result<Worker, VisionError> {
        let (frames, frames_rx) = mpsc::channel::<RgbdFrame>();
        let (results_tx, results) = mpsc::channel();
        std::thread::Builder::new()
            .name("aruco".into())
            .spawn(move || {
                for frame in frames_rx {
                    let started = Instant::now();
                    let outcome = measurer.measure(&frame);
                    let compute_ns = started.elapsed().as_nanos() as u64;
                    if results_tx.send((frame.t, outcome, compute_ns)).is_err() {
                        break;
                    }
                }
            })
            .map_err(|e| VisionError::BadValue { what: "ArUco detection thread", detail: e.to_string() })?;
        Ok(Worker { frames, results, busy: false })
    }

    fn gone() -> VisionError {
        VisionError::BadValue { what: "ArUco detection thread", detail: "it ended unexpectedly".into() }
    }

    /// The finished search, if any.
    fn finished(&mut self) -> Result<Option<Searched>, VisionError> {
        match self.results.try_recv() {
            Ok(r) => {
                self.busy = false;
                Ok(Some(r))
            }
            Err(mpsc::TryRecvError::Empty) => Ok(None),
            Err(mpsc::TryRecvError::Disconnected) => Err(Self::gone()),
        }
    }

    fn start(&mut self, frame: &RgbdFrame) -> Result<(), VisionError> {
        self.frames.send(frame.clone()).map_err(|_| Self::gone())?;
        self.busy = true;
        Ok(())
    }
}

impl ArucoSource {
    /// The source for frames of `intrinsics` and the object `model` (whose
    /// mesh the masks are rendered from).
    pub fn new(
        config: ArucoConfig,
        model: &ObjectModel,
        intrinsics: &CameraIntrinsics,
    ) -> Result<ArucoSource, VisionError> {
        let bad = |what, detail: String| Err(VisionError::BadValue { what, detail });
        if !(config.marker_size_m.is_finite() && config.marker_size_m > 0.0) {
            return bad(
                "marker_size_m",
                format!("{} is not a positive size in metres", config.marker_size_m),
            );
        }
        if config.every_nth_frame == 0 {
            return bad("every_nth_frame", "must be at least 1".into());
        }
        if config.mask_depth_tolerance_m.is_some_and(|t| !(t.is_finite() && t > 0.0)) {
            return bad(
                "mask_depth_tolerance_m",
                format!("{:?} is not a positive distance", config.mask_depth_tolerance_m),
            );
        }
        let dictionary = Dictionary::from_name(&config.dictionary)?;
        if config.marker_id >= dictionary.count() {
            return bad(
                "marker_id",
                format!("{} is not in {} (0..{})", config.marker_id, config.dictionary, dictionary.count()),
            );
        }
        let masks = match (&model.mesh, config.masks) {
            (Some(mesh), true) => {
                Some(MaskRenderer::new(mesh.clone(), intrinsics, config.mask_depth_tolerance_m))
            }
            (None, true) => {
                return bad(
                    "masks",
                    format!(
                        "the model {} has no mesh to render masks from (set masks = false)",
                        model.origin
                    ),
                );
            }
            (_, false) => None,
        };
        let measurer = Measurer {
            detector: MarkerDetector::new(dictionary)?,
            marker_id: config.marker_id,
            marker_size_m: config.marker_size_m,
            max_reprojection_error_px: config.max_reprojection_error_px,
            marker_from_object: config.marker_from_object.isometry("marker_from_object")?,
            intrinsics: intrinsics.clone(),
            masks,
        };
        let runner = if config.background {
            Runner::Background(Worker::spawn(measurer)?)
        } else {
            Runner::Inline(Box::new(measurer))
        };
        Ok(ArucoSource {
            config,
            runner,
            pending: VecDeque::new(),
            frame_index: 0,
            stats: ArucoStats::default(),
        })
    }

    /// What the source did so far.
    pub fn stats(&self) -> ArucoStats {
        self.stats
    }

    /// Counts a search of the frame at `frame_t` and queues what it found.
    fn accept(&mut self, (frame_t, outcome, compute_ns): Searched) -> Result<(), VisionError> {
        match outcome? {
            Outcome::Found((pose, mask)) => {
                let delay_ns = match self.config.delay {
                    ArrivalDelay::Measured => compute_ns,
                    ArrivalDelay::None => 0,
                };
                self.stats.poses += 1;
                let arrival_t = TimeNs(frame_t.0 + delay_ns);
                self.pending.push_back((Delayed { frame_t, arrival_t, value: pose }, mask));
            }
            Outcome::NoMarker => self.stats.frames_without_marker += 1,
            Outcome::Rejected => self.stats.rejected += 1,
        }
        Ok(())
    }
}

impl Measurer {
    /// Of the two poses that explain the marker's corners, the one whose
    /// plane agrees better with the measured depth: the plane fitted to the
    /// depth over the marker (a 15x15 grid of its points) against each
    /// pose's marker normal. The corners alone cannot tell a small or nearly
    /// fronto-parallel marker's two tilts apart (their reprojection errors
    /// differ by a fraction of a pixel), and the wrong tilt turns the object
    /// about the marker: 80 degrees and 10 cm at the object's centre, in 10
    /// of 60 frames of a simulated session. Without enough valid depth on
    /// the marker, the one with the smaller reprojection error.
    fn by_depth(&self, [first, second]: [MarkerPose; 2], depth: &DepthImage) -> MarkerPose {
        let Some(normal) = depth_plane_normal(&first, self.marker_size_m, &self.intrinsics, depth) else {
            return first;
        };
        let agreement =
            |pose: &MarkerPose| (pose.camera_from_marker.rotation * Vector3::z()).dot(&normal).abs();
        if agreement(&second) > agreement(&first) { second } else { first }
    }

    /// Detects the marker in `frame`: the object's pose and mask, if seen.
    fn measure(&mut self, frame: &RgbdFrame) -> Result<Outcome, VisionError> {
        let detections = self.detector.detect(&frame.color)?;
        let Some(detection) = detections.iter().find(|d| d.id == self.marker_id) else {
            return Ok(Outcome::NoMarker);
        };
        let candidates = marker_pose_candidates(detection, &self.intrinsics, self.marker_size_m)?;
        let pose = self.by_depth(candidates, &frame.depth);
        if pose.reprojection_error_px > self.max_reprojection_error_px {
            return Ok(Outcome::Rejected);
        }
        let camera_from_object = pose.camera_from_marker * self.marker_from_object;
        let mask = self.masks.as_mut().map(|r| r.render(&camera_from_object, Some(&frame.depth)));
        Ok(Outcome::Found((camera_from_object, mask)))
    }
}

impl MeasurementSource for ArucoSource {
    fn on_frame(&mut self, t: TimeNs, _truth: Option<FrameTruth<'_>>) -> Result<Arrivals, VisionError> {
        Err(VisionError::BadValue {
            what: "measurement source",
            detail: format!(
                "the ArUco source needs the colour image of the frame at {} ns (call on_rgbd_frame)",
                t.0
            ),
        })
    }

    fn on_rgbd_frame(
        &mut self,
        frame: &RgbdFrame,
        _truth: Option<FrameTruth<'_>>,
    ) -> Result<Arrivals, VisionError> {
        let index = self.frame_index;
        self.frame_index += 1;
        let due = index.is_multiple_of(u64::from(self.config.every_nth_frame));
        match &mut self.runner {
            Runner::Inline(measurer) => {
                if due {
                    self.stats.frames_searched += 1;
                    let started = Instant::now();
                    let outcome = measurer.measure(frame);
                    self.accept((frame.t, outcome, started.elapsed().as_nanos() as u64))?;
                }
            }
            Runner::Background(worker) => {
                let finished = worker.finished()?;
                if due && worker.busy {
                    self.stats.skipped_busy += 1;
                } else if due {
                    worker.start(frame)?;
                    self.stats.frames_searched += 1;
                }
                if let Some(result) = finished {
                    self.accept(result)?;
                }
            }
        }
        let mut out = Arrivals::default();
        while self.pending.front().is_some_and(|(p, _)| p.arrival_t <= frame.t) {
            let Some((pose, mask)) = self.pending.pop_front() else { break };
            if let Some(mask) = mask {
                out.masks.push(Delayed { frame_t: pose.frame_t, arrival_t: pose.arrival_t, value: mask });
            }
            out.poses.push(pose);
        }
        Ok(out)
    }

    fn summary(&self) -> Option<String> {
        let s = self.stats;
        let busy = match self.runner {
            Runner::Background(_) => format!(", {} skipped while detection was busy", s.skipped_busy),
            Runner::Inline(_) => String::new(),
        };
        Some(format!(
            "aruco: {} frames searched, {} poses, {} without the marker, {} rejected for reprojection error{busy}",
            s.frames_searched, s.poses, s.frames_without_marker, s.rejected
        ))
    }
}

/// The unit normal of the plane fitted (least squares) to the measured
/// depth at a 15x15 grid of points inside the marker, as `pose` projects
/// them (both candidate poses project the marker's inside to nearly the
/// same pixels); `None` with fewer than 20 valid depth pixels there.
fn depth_plane_normal(
    pose: &MarkerPose,
    marker_size_m: f64,
    intrinsics: &CameraIntrinsics,
    depth: &DepthImage,
) -> Option<Vector3<f64>> {
    let half = 0.4 * marker_size_m;
    let camera = pinhole(intrinsics);
    let points: Vec<Vector3<f64>> = (0..225)
        .filter_map(|k| {
            let (i, j) = (f64::from(k % 15) / 7.0 - 1.0, f64::from(k / 15) / 7.0 - 1.0);
            let on_marker = nalgebra::Point3::new(i * half, j * half, 0.0);
            let in_camera = pose.camera_from_marker * on_marker;
            let (u, v) = intrinsics.project([in_camera.x, in_camera.y, in_camera.z])?;
            let (u, v) = (u.round(), v.round());
            if u < 0.0 || v < 0.0 {
                return None;
            }
            let z = depth.depth_m(u as u32, v as u32)?;
            Some(Vector3::from(camera.back_project(u, v, z)))
        })
        .collect();
    if points.len() < 20 {
        return None;
    }
    let centroid = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
    let scatter =
        points.iter().map(|p| (p - centroid) * (p - centroid).transpose()).sum::<nalgebra::Matrix3<f64>>();
    let eigen = scatter.symmetric_eigen();
    let smallest = eigen.eigenvalues.imin();
    Some(eigen.eigenvectors.column(smallest).into_owned())
}

#[cfg(test)]
#[path = "aruco_tests.rs"]
mod tests;
