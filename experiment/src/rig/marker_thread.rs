//! Marker detection beside the trial's control loop, on the host's clock.
//!
//! Each camera frame's marker detection (OpenCV's ArUco search and the
//! marker's pose) used to run on the control loop's thread, between two
//! tactile scans. Following the marker from frame to frame costs well under
//! a millisecond, but searching a whole frame (the first one, and every
//! frame while the marker is lost) took 13 to 26 ms on the recorded RGB-D
//! stand-in's 640x480 frames on 2 idle cores, and 36 to 70 ms beside two
//! busy loops, where the protocol aborted the trial on tactile data older
//! than its 50 ms limit (`tests/rgbd_one_camera.rs`, 2 runs in 5).
//!
//! On the host's clock (the real rig, and the simulated one with
//! `--realtime`) the camera is therefore polled, and each frame searched, on
//! a thread of its own ([`detect_off_the_loop`]):
//! the control loop gets from [`DetectedCamera`] only frames whose detection
//! is done, and [`DetectedMarkers`] hands it that detection at once. What the
//! session records is unchanged (every frame with its own detection, in
//! frame order); frames reach the loop later by their detection's time, and
//! a frame still being searched when the trial ends is not recorded. The
//! simulated rig on the simulator's time keeps detecting on its loop, so a
//! seed still gives the same session.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{Context, Result};
use crossbeam_channel::{Receiver, SendTimeoutError, Sender, TryRecvError};
use slidetrack_control::ObserverError;
use slidetrack_core::{Camera, CameraIntrinsics, DeviceError, ErrorKind, Frame};
use slidetrack_session::ArucoDetection;

use super::trial::RigSetup;
use crate::marker::MarkerSource;

/// How long the thread sleeps when the camera has no new frame (cameras
/// deliver one every 11 to 33 ms).
const IDLE_POLL: Duration = Duration::from_millis(1);
/// Detected frames waiting for the control loop (it takes them at every
/// tactile scan); when they are not taken, the thread waits and the
/// camera's own queue decides what is dropped.
const FRAME_QUEUE: usize = 8;
/// How often a thread waiting for room in the queue checks for the stop.
const STOP_CHECK: Duration = Duration::from_millis(20);

/// One frame's detection, sent before the frame itself.
struct Detected {
    sequence: u64,
    detection: Result<ArucoDetection, ObserverError>,
}

/// Moves the marker detection of `setup`'s camera, when it has one, to a
/// thread of its own ([`detect_beside_the_loop`]).
pub(crate) fn detect_off_the_loop(setup: &mut RigSetup) -> Result<()> {
    match (setup.rig.camera.take(), setup.markers.take()) {
        (Some(camera), Some(markers)) => {
            let (camera, markers) = detect_beside_the_loop(camera, markers)
                .context("cannot start the thread of the marker detection")?;
            setup.rig.camera = Some(Box::new(camera));
            setup.markers = Some(Box::new(markers));
        }
        (camera, markers) => (setup.rig.camera, setup.markers) = (camera, markers),
    }
    Ok(())
}

/// Starts polling `camera` and detecting with `markers` on a thread named
/// `marker detection`. The trial must read its frames from the returned
/// camera and their detections from the returned source, one detection per
/// frame in frame order, as the trial's observer does.
pub(crate) fn detect_beside_the_loop(
    camera: Box<dyn Camera>,
    markers: Box<dyn MarkerSource>,
) -> std::io::Result<(DetectedCamera, DetectedMarkers)> {
    let (intrinsics, device) = (camera.intrinsics().clone(), camera.device().to_owned());
    let marker_intrinsics = markers.intrinsics().clone();
    let (frame_tx, frames) = crossbeam_channel::bounded(FRAME_QUEUE);
    // Unbounded: a detection is sent before its frame, and the frames are bounded.
    let (detection_tx, detections) = crossbeam_channel::unbounded();
    let stop = Arc::new(AtomicBool::new(false));
    let thread = {
        let stop = Arc::clone(&stop);
        std::thread::Builder::new()
            .name("marker detection".into())
            .spawn(move || detect_frames(camera, markers, &frame_tx, &detection_tx, &stop))?
    };
    Ok((
        DetectedCamera { frames, intrinsics, device, stop, thread: Some(thread) },
        DetectedMarkers { detections, intrinsics: marker_intrinsics },
    ))
}

/// The thread: each new frame's detection, then the frame, until stopped,
/// the camera fails (its error goes to the loop) or the loop is gone.
fn detect_frames(
    mut camera: Box<dyn Camera>,
    mut markers: Box<dyn MarkerSource>,
    frames: &Sender<Result<Frame, DeviceError>>,
    detections: &Sender<Detected>,
    stop: &AtomicBool,
) {
    while !stop.load(Ordering::Relaxed) {
        match camera.poll() {
            Ok(Some(frame)) => {
                let detection = markers.detect(&frame);
                if detections.send(Detected { sequence: frame.sequence, detection }).is_err()
                    || !send_unless_stopped(frames, Ok(frame), stop)
                {
                    return;
                }
            }
            Ok(None) => std::thread::sleep(IDLE_POLL),
            Err(e) => {
                send_unless_stopped(frames, Err(e), stop);
                return;
            }
        }
    }
}

/// Sends `item`, waiting for room while not stopped; false when it was not sent.
fn send_unless_stopped<T>(tx: &Sender<T>, mut item: T, stop: &AtomicBool) -> bool {
    loop {
        match tx.send_timeout(item, STOP_CHECK) {
            Ok(()) => return true,
            Err(SendTimeoutError::Timeout(back)) if !stop.load(Ordering::Relaxed) => item = back,
            Err(_) => return false,
        }
    }
}

/// The camera's frames whose marker detection is done. Never blocks;
/// dropping it stops the thread and closes the camera.
pub(crate) struct DetectedCamera {
    frames: Receiver<Result<Frame, DeviceError>>,
    intrinsics: CameraIntrinsics,
    device: String,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Camera for DetectedCamera {
    fn poll(&mut self) -> Result<Option<Frame>, DeviceError> {
        match self.frames.try_recv() {
            Ok(frame) => frame.map(Some),
            Err(TryRecvError::Empty) => Ok(None),
            Err(TryRecvError::Disconnected) => {
                Err(DeviceError::new(ErrorKind::Other, &self.device, "the marker detection thread stopped"))
            }
        }
    }

    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    fn device(&self) -> &str {
        &self.device
    }
}

impl Drop for DetectedCamera {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            // A panic of the thread has already ended the trial (the camera disconnected).
            let _ = thread.join();
        }
    }
}

/// The detections of [`DetectedCamera`]'s frames, one per frame in order.
pub(crate) struct DetectedMarkers {
    detections: Receiver<Detected>,
    intrinsics: CameraIntrinsics,
}

impl MarkerSource for DetectedMarkers {
    fn detect(&mut self, frame: &Frame) -> Result<ArucoDetection, ObserverError> {
        // Sent before the frame: it is here once the frame is.
        let detected = self
            .detections
            .try_recv()
            .map_err(|_| format!("marker detection: no detection for camera frame {}", frame.sequence))?;
        if detected.sequence != frame.sequence {
            return Err(format!(
                "marker detection: camera frame {} got the detection of frame {}",
                frame.sequence, detected.sequence
            )
            .into());
        }
        detected.detection
    }

    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }
}

#[cfg(test)]
#[path = "marker_thread_tests.rs"]
mod tests;
