use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use slidetrack_control::ObserverError;
use slidetrack_core::{Camera, CameraIntrinsics, DeviceError, ErrorKind, Frame, TimeNs};
use slidetrack_session::ArucoDetection;

use super::detect_beside_the_loop;
use crate::marker::MarkerSource;

fn intrinsics() -> CameraIntrinsics {
    CameraIntrinsics { width: 64, height: 48, fx: 60.0, fy: 60.0, cx: 32.0, cy: 24.0, distortion: [0.0; 5] }
}

fn frame(sequence: u64) -> Frame {
    Frame { t: TimeNs(sequence * 33_000_000), sequence, pixels: None, encoded: None }
}

/// Returns its queue of frames and errors one per poll, then nothing; sets
/// `closed` when dropped.
struct ScriptedCamera {
    script: VecDeque<Result<Frame, DeviceError>>,
    intrinsics: CameraIntrinsics,
    closed: Arc<AtomicBool>,
}

impl Camera for ScriptedCamera {
    fn poll(&mut self) -> Result<Option<Frame>, DeviceError> {
        self.script.pop_front().transpose()
    }
    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }
    fn device(&self) -> &str {
        "scripted camera"
    }
}

impl Drop for ScriptedCamera {
    fn drop(&mut self) {
        self.closed.store(true, Ordering::Relaxed);
    }
}

/// Takes `delay` per frame (a whole-frame search); the marker id is the
/// frame's sequence, and frame `fail_at` fails.
struct SlowMarkers {
    delay: Duration,
    fail_at: Option<u64>,
    intrinsics: CameraIntrinsics,
}

impl MarkerSource for SlowMarkers {
    fn detect(&mut self, frame: &Frame) -> Result<ArucoDetection, ObserverError> {
        std::thread::sleep(self.delay);
        if Some(frame.sequence) == self.fail_at {
            return Err(format!("cannot search frame {}", frame.sequence).into());
        }
        Ok(ArucoDetection { marker_id: Some(frame.sequence as u32), ..ArucoDetection::missed() })
    }
    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }
}

fn start(
    script: Vec<Result<Frame, DeviceError>>,
    delay: Duration,
    fail_at: Option<u64>,
) -> (super::DetectedCamera, super::DetectedMarkers, Arc<AtomicBool>) {
    let closed = Arc::new(AtomicBool::new(false));
    let camera =
        ScriptedCamera { script: script.into(), intrinsics: intrinsics(), closed: Arc::clone(&closed) };
    let markers = SlowMarkers { delay, fail_at, intrinsics: intrinsics() };
    let (camera, markers) = detect_beside_the_loop(Box::new(camera), Box::new(markers)).unwrap();
    (camera, markers, closed)
}

/// What the loop got: each frame's sequence and detection, the camera's
/// error, and the longest time one poll and its detection took.
type Polled = (Vec<(u64, Result<ArucoDetection, ObserverError>)>, Option<DeviceError>, Duration);

/// Polls `camera` for up to 10 s until `n` frames or an error came.
fn poll_for(camera: &mut super::DetectedCamera, markers: &mut super::DetectedMarkers, n: usize) -> Polled {
    let (mut got, mut longest) = (Vec::new(), Duration::ZERO);
    let deadline = Instant::now() + Duration::from_secs(10);
    while got.len() < n && Instant::now() < deadline {
        let t0 = Instant::now();
        let polled = camera.poll();
        let detection = match &polled {
            Ok(Some(f)) => Some((f.sequence, markers.detect(f))),
            _ => None,
        };
        longest = longest.max(t0.elapsed());
        match (polled, detection) {
            (Err(e), _) => return (got, Some(e), longest),
            (_, Some(d)) => got.push(d),
            _ => std::thread::sleep(Duration::from_millis(2)),
        }
    }
    (got, None, longest)
}

#[test]
fn the_loop_gets_each_frame_with_its_detection_without_waiting_for_it() {
    // Catches a detection on the caller's thread: a poll would take 100 ms.
    let delay = Duration::from_millis(100);
    let (mut camera, mut markers, _) = start((0..4).map(|s| Ok(frame(s))).collect(), delay, None);
    let (got, error, longest) = poll_for(&mut camera, &mut markers, 4);
    assert!(error.is_none(), "{error:?}");
    let ids: Vec<_> = got.into_iter().map(|(s, d)| (s, d.unwrap().marker_id)).collect();
    assert_eq!(ids, [(0, Some(0)), (1, Some(1)), (2, Some(2)), (3, Some(3))]);
    assert!(longest < Duration::from_millis(30), "one poll and its detection took {longest:?}");
    assert_eq!(camera.device(), "scripted camera");
    assert_eq!(camera.intrinsics(), &intrinsics());
}

#[test]
fn a_failed_detection_is_its_frames_error_and_the_next_frames_go_on() {
    let script = (0..3).map(|s| Ok(frame(s))).collect();
    let (mut camera, mut markers, _) = start(script, Duration::ZERO, Some(1));
    let (got, error, _) = poll_for(&mut camera, &mut markers, 3);
    assert!(error.is_none(), "{error:?}");
    let results: Vec<_> = got.into_iter().map(|(s, d)| (s, d.map_err(|e| e.to_string()).is_ok())).collect();
    assert_eq!(results, [(0, true), (1, false), (2, true)]);
}

#[test]
fn a_camera_error_reaches_the_loop_after_the_frames_before_it() {
    let unplugged = DeviceError::new(ErrorKind::Disconnected, "scripted camera", "unplugged");
    let (mut camera, mut markers, closed) =
        start(vec![Ok(frame(0)), Err(unplugged.clone())], Duration::from_millis(5), None);
    let (got, error, _) = poll_for(&mut camera, &mut markers, 2);
    assert_eq!(got.len(), 1);
    assert_eq!(error, Some(unplugged));
    // The thread ended with the error; the camera is closed, and polling again says why.
    let deadline = Instant::now() + Duration::from_secs(10);
    while !closed.load(Ordering::Relaxed) && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(2));
    }
    assert!(closed.load(Ordering::Relaxed), "the camera was not closed");
    let again = camera.poll().unwrap_err();
    assert!(again.detail.contains("marker detection thread stopped"), "{again}");
}

#[test]
fn dropping_the_camera_stops_the_thread_and_closes_the_camera() {
    // Frames the loop never takes: the thread waits for room in the queue.
    let script = (0..20).map(|s| Ok(frame(s))).collect();
    let (camera, markers, closed) = start(script, Duration::ZERO, None);
    std::thread::sleep(Duration::from_millis(50));
    assert!(!closed.load(Ordering::Relaxed));
    drop(camera);
    assert!(closed.load(Ordering::Relaxed), "the camera outlived its reader");
    drop(markers);
}

#[test]
fn a_detection_never_goes_to_another_frame() {
    let (mut camera, mut markers, _) = start(vec![Ok(frame(7))], Duration::ZERO, None);
    let deadline = Instant::now() + Duration::from_secs(10);
    while camera.poll().unwrap().is_none() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(2));
    }
    // Frame 7 came; asked for frame 8, then for a frame never detected.
    let e = markers.detect(&frame(8)).unwrap_err().to_string();
    assert!(e.contains("camera frame 8 got the detection of frame 7"), "{e}");
    let e = markers.detect(&frame(9)).unwrap_err().to_string();
    assert!(e.contains("no detection for camera frame 9"), "{e}");
}
