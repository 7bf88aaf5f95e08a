//! Cameras over Video4Linux2: memory-mapped streaming on a capture thread,
//! driver timestamps mapped to the session clock, Motion-JPEG recorded as it
//! comes (with the standard Huffman tables inserted when the camera omits
//! them) and decoded only for detection; YUYV, GREY and Z16 rows unpadded
//! to the driver's stride; buffers the driver flags as erroneous dropped
//! and counted; a start-up timeout for the first frame apart from the
//! per-frame timeout.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_channel::{Receiver, Sender, TryRecvError, TrySendError};
use nix::time::{ClockId, clock_gettime};
use slidetrack_core::{Camera, CameraIntrinsics, Clock, DeviceError, ErrorKind, Frame, TimeNs};
use v4l::buffer::{Flags as BufferFlags, Metadata, Type};
use v4l::capability::Flags as CapFlags;
use v4l::io::mmap::Stream;
use v4l::io::traits::CaptureStream;
use v4l::video::Capture;
use v4l::video::capture::Parameters;
use v4l::{Device, Format, FourCC};

use crate::io_error_kind::io_error_kind;
use crate::v4l2::config::{V4l2CameraConfig, V4l2PixelFormat};
use crate::v4l2::decode::{CaptureCounters, FrameLayout, frame_content};

/// Frames the capture thread may hold ahead of the trial loop; beyond this
/// the newest are dropped (the gap shows in `sequence`).
const QUEUE: usize = 4;

/// A V4L2 camera.
pub struct V4l2Camera {
    device: String,
    intrinsics: CameraIntrinsics,
    frames: Receiver<Result<Frame, DeviceError>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    failed: Option<DeviceError>,
    counters: Arc<CaptureCounters>,
}

fn device_error(device: &str, what: &str, e: &std::io::Error) -> DeviceError {
    let kind = match e.kind() {
        std::io::ErrorKind::NotFound => ErrorKind::Disconnected,
        _ => io_error_kind(e),
    };
    let hint = match e.kind() {
        std::io::ErrorKind::PermissionDenied => " (add your user to the `video` group)",
        std::io::ErrorKind::NotFound => " (no such device; `slidetrack devices` lists the cameras)",
        _ => "",
    };
    DeviceError::new(kind, device, format!("{what}: {e}{hint}"))
}

impl V4l2Camera {
    /// Opens `cfg.device`, sets the format and frame rate, and starts
    /// streaming on a thread named `v4l2-capture`. Frame times are mapped to
    /// `clock` (the host's monotonic clock, as the driver's timestamps).
    pub fn open(
        cfg: &V4l2CameraConfig,
        intrinsics: CameraIntrinsics,
        clock: Arc<dyn Clock>,
    ) -> Result<V4l2Camera, DeviceError> {
        let name = cfg.device.as_str();
        let dev = Device::with_path(name).map_err(|e| device_error(name, "cannot open", &e))?;
        let caps = dev.query_caps().map_err(|e| device_error(name, "cannot query", &e))?;
        if !caps.capabilities.contains(CapFlags::VIDEO_CAPTURE | CapFlags::STREAMING) {
            let detail = format!("{} ({}) is not a streaming capture device", caps.card, caps.driver);
            return Err(DeviceError::new(ErrorKind::Other, name, detail));
        }
        let fourcc = FourCC::new(&cfg.pixel_format.fourcc());
        let want = Format::new(cfg.width, cfg.height, fourcc);
        let got = dev.set_format(&want).map_err(|e| device_error(name, "cannot set the format", &e))?;
        if got.fourcc != fourcc || (got.width, got.height) != (cfg.width, cfg.height) {
            let detail = format!(
                "asked for {}x{} {}, the camera gives {}x{} {}; `slidetrack devices` lists what it offers",
                cfg.width, cfg.height, fourcc, got.width, got.height, got.fourcc
            );
            return Err(DeviceError::new(ErrorKind::Other, name, detail));
        }
        let fps = cfg.fps.round().max(1.0) as u32;
        match dev.set_params(&Parameters::with_fps(fps)) {
            Ok(p) if p.interval.numerator > 0 => {
                let actual = f64::from(p.interval.denominator) / f64::from(p.interval.numerator);
                if (actual - cfg.fps).abs() > 0.5 {
                    tracing::warn!("{name}: asked for {} fps, the camera runs at {actual:.1} fps", cfg.fps);
                }
            }
            Ok(_) => {}
            Err(e) => tracing::warn!("{name}: cannot set the frame rate: {e}"),
        }
        let (tx, frames) = crossbeam_channel::bounded(QUEUE);
        let stop = Arc::new(AtomicBool::new(false));
        let counters = Arc::new(CaptureCounters::default());
        let capture = CaptureThread {
            device: name.to_string(),
            layout: FrameLayout {
                format: cfg.pixel_format,
                width: cfg.width,
                height: cfg.height,
                bytes_per_line: got.stride,
            },
            buffers: cfg.buffers,
            timeout: Duration::from_millis(cfg.timeout_ms),
            startup_timeout: Duration::from_millis(cfg.startup_timeout_ms),
            jpeg_quality: cfg.jpeg_quality,
            clock,
            stop: Arc::clone(&stop),
            counters: Arc::clone(&counters),
        };
        let thread = std::thread::Builder::new()
            .name("v4l2-capture".into())
            .spawn(move || capture.run(dev, tx))
            .map_err(|e| DeviceError::new(ErrorKind::Other, name, format!("cannot start capture: {e}")))?;
        Ok(V4l2Camera {
            device: name.to_string(),
            intrinsics,
            frames,
            stop,
            thread: Some(thread),
            failed: None,
            counters,
        })
    }

    /// The capture's counts (frames delivered, flagged erroneous, dropped
    /// while the reader was behind), live while the camera streams.
    pub fn counters(&self) -> Arc<CaptureCounters> {
        Arc::clone(&self.counters)
    }
}

impl Camera for V4l2Camera {
    /// # Contract
    /// - Never blocks: returns the oldest captured frame not yet returned.
    ///   MJPG frames carry the bytes as the camera sent them (Huffman
    ///   tables added when missing) and, when they decode, gray pixels for
    ///   detection; YUYV frames carry the luma and a JPEG of the colour
    ///   image; GREY frames their pixels and a JPEG of them; Z16 frames a
    ///   16-bit PNG and no pixels. Frames the driver flags as erroneous are
    ///   dropped (and counted, see [`V4l2Camera::counters`]).
    /// - Frame times are the driver's timestamps on the session clock (the
    ///   arrival time when the driver's clock is not monotonic).
    /// - `Disconnected` once the device is gone, `Timeout` when no first
    ///   frame came within `startup_timeout_ms` or it stopped delivering
    ///   frames for `timeout_ms`; every later call fails too.
    fn poll(&mut self) -> Result<Option<Frame>, DeviceError> {
        if let Some(e) = &self.failed {
            return Err(e.clone());
        }
        let e = match self.frames.try_recv() {
            Ok(Ok(frame)) => return Ok(Some(frame)),
            Err(TryRecvError::Empty) => return Ok(None),
            Ok(Err(e)) => e,
            Err(TryRecvError::Disconnected) => {
                DeviceError::new(ErrorKind::Disconnected, &self.device, "the capture thread stopped")
            }
        };
        self.failed = Some(e.clone());
        Err(e)
    }

    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    fn device(&self) -> &str {
        &self.device
    }
}

impl Drop for V4l2Camera {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take()
            && t.join().is_err()
        {
            tracing::warn!("{}: the capture thread panicked", self.device);
        }
    }
}

/// What the capture thread needs.
struct CaptureThread {
    device: String,
    layout: FrameLayout,
    buffers: u32,
    timeout: Duration,
    startup_timeout: Duration,
    jpeg_quality: u8,
    clock: Arc<dyn Clock>,
    stop: Arc<AtomicBool>,
    counters: Arc<CaptureCounters>,
}

/// The mapping from the driver's buffer timestamps (`CLOCK_MONOTONIC`) to
/// the session clock: an offset captured once, when streaming starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DriverClockMap {
    /// `session time - monotonic time` (ns).
    pub offset_ns: i128,
}

impl DriverClockMap {
    /// Largest age of a mapped exposure (ns); an older one is a clock mix-up.
    pub const MAX_AGE_NS: i128 = 1_000_000_000;

    /// Captures the offset between `clock` and the host's monotonic clock
    /// now; `None` when the monotonic clock cannot be read.
    pub fn capture(clock: &dyn Clock) -> Option<DriverClockMap> {
        let mono = clock_gettime(ClockId::CLOCK_MONOTONIC).ok()?;
        let session = clock.now();
        let mono_ns = i128::from(mono.tv_sec()) * 1_000_000_000 + i128::from(mono.tv_nsec());
        Some(DriverClockMap { offset_ns: i128::from(session.0) - mono_ns })
    }

    /// The session time of an exposure the driver stamped `device_ns`
    /// (monotonic clock, ns) when the frame arrives at session time `now`:
    /// `now` itself when the mapped time lies in the future or more than
    /// [`MAX_AGE_NS`](Self::MAX_AGE_NS) in the past (a driver whose clock is
    /// not the monotonic one).
    pub fn session_time(&self, device_ns: i128, now: TimeNs) -> TimeNs {
        let t = device_ns + self.offset_ns;
        let now_ns = i128::from(now.0);
        if (now_ns - Self::MAX_AGE_NS..=now_ns).contains(&t) {
            u64::try_from(t).map(TimeNs).unwrap_or(now)
        } else {
            now
        }
    }
}

impl CaptureThread {
    fn run(self, dev: Device, tx: Sender<Result<Frame, DeviceError>>) {
        let mut stream = match Stream::with_buffers(&dev, Type::VideoCapture, self.buffers) {
            Ok(s) => s,
            Err(e) => {
                let _ = tx.send(Err(device_error(&self.device, "cannot map the buffers", &e)));
                return;
            }
        };
        stream.set_timeout(self.startup_timeout);
        let clock_map = DriverClockMap::capture(self.clock.as_ref());
        let mut started = false;
        while !self.stop.load(Ordering::SeqCst) {
            let (bytes, meta) = match CaptureStream::next(&mut stream) {
                Ok((bytes, meta)) => (bytes, *meta),
                Err(e) => {
                    let what = match (e.kind() == std::io::ErrorKind::TimedOut, started) {
                        (true, false) => format!(
                            "no first frame within {} ms (startup_timeout_ms)",
                            self.startup_timeout.as_millis()
                        ),
                        (true, true) => format!("no frame for {} ms (timeout_ms)", self.timeout.as_millis()),
                        (false, _) => "capture failed (camera unplugged?)".into(),
                    };
                    let _ = tx.send(Err(device_error(&self.device, &what, &e)));
                    break;
                }
            };
            if !self.counters.accept(meta.flags.bits()) {
                tracing::debug!("{}: frame {} flagged erroneous by the driver", self.device, meta.sequence);
                continue;
            }
            let used = (meta.bytesused as usize).min(bytes.len());
            let frame = self.frame(&bytes[..used], &meta, clock_map);
            if !started {
                started = true;
                stream.set_timeout(self.timeout);
            }
            match tx.try_send(Ok(frame)) {
                Ok(()) => self.counters.delivered_one(),
                Err(TrySendError::Full(_)) => {
                    self.counters.overrun_one();
                    tracing::debug!("{}: reader behind, frame {} dropped", self.device, meta.sequence);
                }
                Err(TrySendError::Disconnected(_)) => break,
            }
        }
        if self.counters.erroneous() + self.counters.overrun() > 0 {
            tracing::warn!("{}: {}", self.device, self.counters);
        } else {
            tracing::info!("{}: {}", self.device, self.counters);
        }
    }

    fn frame(&self, bytes: &[u8], meta: &Metadata, clock_map: Option<DriverClockMap>) -> Frame {
        let now = self.clock.now();
        let monotonic = meta.flags & BufferFlags::TIMESTAMP_MASK == BufferFlags::TIMESTAMP_MONOTONIC;
        let t = match clock_map.filter(|_| monotonic) {
            Some(map) => {
                let device_ns =
                    i128::from(meta.timestamp.sec) * 1_000_000_000 + i128::from(meta.timestamp.usec) * 1000;
                map.session_time(device_ns, now)
            }
            None => now,
        };
        let (pixels, encoded) = frame_content(&self.layout, self.jpeg_quality, bytes);
        if self.layout.format == V4l2PixelFormat::Mjpg && pixels.is_none() {
            tracing::debug!("{}: frame {} does not decode", self.device, meta.sequence);
        }
        Frame { t, sequence: u64::from(meta.sequence), pixels, encoded }
    }
}

#[cfg(test)]
mod tests;
