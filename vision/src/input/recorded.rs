//! [`RecordedRgbd`]: a recording standing in for a live RGB-D camera. The
//! colour and depth frames of a session (`/rgbd/color`, `/rgbd/depth`) or of
//! a directory (`NNNNNN-color.png`, `NNNNNN-depth.png`) are replayed as two
//! [`Camera`]s on a clock: a frame recorded at `t` is delivered once the
//! clock reads `t + offset` and carries that time, so the live path
//! ([`super::CameraPair`]: pairing, registration) runs on them as on a
//! device.
//!
//! - By default the clock is the run's wall clock. A reader that falls
//!   behind loses the oldest frames, as a camera with a queue of four
//!   buffers does.
//! - With [`ReplayOptions::every_frame`] the clock is the replay's own, and moves to
//!   the next recorded frame only when the reader waits for one
//!   ([`RecordedRgbd::pacer`]). Every frame is delivered with the same time
//!   however slow the reader is.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use slidetrack_core::{
    Camera, CameraIntrinsics, Clock, DeviceError, EncodedImage, ErrorKind, Frame, SimClock, TimeNs,
};
use slidetrack_session::{
    ChannelMessage, MessageReader, ReadOptions, RgbdCalibration, RgbdColor, RgbdDepth, read_channel,
};

use crate::VisionError;

/// Frames a replayed camera holds for a slow reader; older ones are lost.
const QUEUE: usize = 4;

/// Recorded frames in order: recording time and the encoded image.
type FrameStream = Box<dyn Iterator<Item = Result<(TimeNs, EncodedImage), VisionError>> + Send>;

/// Options of a replay.
#[derive(Clone, Debug)]
pub struct ReplayOptions {
    /// Colour frames stamped this much later than recorded (ns, may be
    /// negative): unsynchronised nodes.
    pub color_delay_ns: i64,
    /// Colour intrinsics; default a session's `/rgbd/calibration`.
    pub color_intrinsics: Option<CameraIntrinsics>,
    /// Depth intrinsics; default the colour intrinsics.
    pub depth_intrinsics: Option<CameraIntrinsics>,
    /// Frame rate of a directory's frames (Hz).
    pub directory_fps: f64,
    /// Every frame on the replay's own clock (see the module's doc), instead
    /// of on the wall clock.
    pub every_frame: bool,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions {
            color_delay_ns: 0,
            color_intrinsics: None,
            depth_intrinsics: None,
            directory_fps: 30.0,
            every_frame: false,
        }
    }
}

/// Counts of a replayed camera.
#[derive(Debug, Default)]
pub struct ReplayCounts {
    delivered: AtomicU64,
    lost: AtomicU64,
}

impl ReplayCounts {
    /// Frames handed to the reader.
    pub fn delivered(&self) -> u64 {
        self.delivered.load(Ordering::Relaxed)
    }

    /// Frames lost because the reader was behind.
    pub fn lost(&self) -> u64 {
        self.lost.load(Ordering::Relaxed)
    }
}

/// A recording as a colour and a depth camera.
pub struct RecordedRgbd {
    /// The colour camera.
    pub color: RecordedCamera,
    /// The depth camera.
    pub depth: RecordedCamera,
    /// Set once either stream has delivered its last frame.
    pub ended: Arc<AtomicBool>,
    /// Session time minus recording time of every depth frame (ns).
    pub offset_ns: i128,
    /// The replay's own clock, with [`ReplayOptions::every_frame`].
    own_clock: Option<SimClock>,
}

impl RecordedRgbd {
    /// Replays the session at `path`, starting now on `clock`.
    pub fn open_session(
        path: &Path,
        clock: Arc<dyn Clock>,
        options: &ReplayOptions,
    ) -> Result<RecordedRgbd, VisionError> {
        let bad = |detail: &str| VisionError::BadSession { path: path.to_path_buf(), detail: detail.into() };
        let read = ReadOptions::default();
        let color_intrinsics = match &options.color_intrinsics {
            Some(k) => k.clone(),
            None => read_channel::<RgbdCalibration>(path, read)
                .ok()
                .and_then(|c| c.first().and_then(|(_, c)| c.0.intrinsics()))
                .ok_or_else(|| bad("no /rgbd/calibration: give rgbd.color_intrinsics"))?,
        };
        let colors = session_stream(path, RgbdColor::TOPIC, |data| {
            let m: RgbdColor = serde_json::from_slice(data).map_err(|e| e.to_string())?;
            Ok(EncodedImage { format: m.0.format, bytes: m.0.data })
        })?;
        let depths = session_stream(path, RgbdDepth::TOPIC, |data| {
            let m: RgbdDepth = serde_json::from_slice(data).map_err(|e| e.to_string())?;
            // The stored PNG as it is (a session of the old raw form: encoded).
            m.to_png().map_err(|e| e.to_string())
        })?;
        let name = path.display().to_string();
        Self::start(&name, colors, depths, color_intrinsics, clock, options)
    }

    /// Replays the `NNNNNN-color.png` and `NNNNNN-depth.png` files of `dir`
    /// at `options.directory_fps`, starting now on `clock`.
    pub fn open_directory(
        dir: &Path,
        clock: Arc<dyn Clock>,
        options: &ReplayOptions,
    ) -> Result<RecordedRgbd, VisionError> {
        let bad = |detail: String| VisionError::BadFile { path: dir.to_path_buf(), detail };
        let color_intrinsics = options
            .color_intrinsics
            .clone()
            .ok_or_else(|| bad("a directory needs colour intrinsics".into()))?;
        let entries =
            std::fs::read_dir(dir).map_err(|source| VisionError::Io { path: dir.to_path_buf(), source })?;
        let mut stems: Vec<String> = entries
            .filter_map(|e| e.ok()?.file_name().to_str()?.strip_suffix("-color.png").map(str::to_string))
            .collect();
        stems.sort();
        if stems.is_empty() {
            return Err(bad("no NNNNNN-color.png files".into()));
        }
        let period_ns = 1e9 / options.directory_fps;
        let files = |suffix: &'static str, format: &'static str| -> FrameStream {
            let listed: Vec<(TimeNs, PathBuf)> = stems
                .iter()
                .enumerate()
                .map(|(k, stem)| {
                    (TimeNs((k as f64 * period_ns).round() as u64), dir.join(format!("{stem}-{suffix}")))
                })
                .collect();
            Box::new(listed.into_iter().map(move |(t, path)| {
                let bytes = std::fs::read(&path).map_err(|source| VisionError::Io { path, source })?;
                Ok((t, EncodedImage { format: format.into(), bytes }))
            }))
        };
        let name = dir.display().to_string();
        Self::start(
            &name,
            files("color.png", "png"),
            files("depth.png", "png"),
            color_intrinsics,
            clock,
            options,
        )
    }

    fn start(
        name: &str,
        mut colors: FrameStream,
        mut depths: FrameStream,
        color_intrinsics: CameraIntrinsics,
        clock: Arc<dyn Clock>,
        options: &ReplayOptions,
    ) -> Result<RecordedRgbd, VisionError> {
        let first_color = colors.next().transpose()?;
        let first_depth = depths.next().transpose()?;
        let first_t = first_depth
            .as_ref()
            .map(|(t, _)| *t)
            .ok_or_else(|| VisionError::BadFile { path: name.into(), detail: "no depth frames".into() })?;
        let offset_ns = i128::from(clock.now().0) - i128::from(first_t.0);
        let own_clock = options.every_frame.then(|| {
            // Starts where the run's clock is, so times read the same.
            let own = SimClock::new();
            own.sleep_until(clock.now());
            own
        });
        let clock: Arc<dyn Clock> = match &own_clock {
            Some(own) => Arc::new(own.clone()),
            None => clock,
        };
        let ended = Arc::new(AtomicBool::new(false));
        let depth_intrinsics = options.depth_intrinsics.clone().unwrap_or_else(|| color_intrinsics.clone());
        let camera = |device: String, first, rest, intrinsics, delay_ns: i64| RecordedCamera {
            device,
            intrinsics,
            first,
            rest,
            ready: VecDeque::new(),
            clock: Arc::clone(&clock),
            offset_ns: offset_ns + i128::from(delay_ns),
            sequence: 0,
            ended: Arc::clone(&ended),
            counts: Arc::default(),
            next_t: Arc::new(AtomicU64::new(u64::MAX)),
        };
        Ok(RecordedRgbd {
            color: camera(
                format!("{name} (colour)"),
                first_color,
                colors,
                color_intrinsics,
                options.color_delay_ns,
            ),
            depth: camera(format!("{name} (depth)"), first_depth, depths, depth_intrinsics, 0),
            ended,
            offset_ns,
            own_clock,
        })
    }

    /// With [`ReplayOptions::every_frame`], what moves the replay's clock on
    /// when the reader waits ([`super::CameraPair::with_pacer`]): to the
    /// earliest frame either camera has not delivered. It returns false when
    /// both have delivered everything. `None` on the wall clock.
    pub fn pacer(&self) -> Option<super::camera_pair::Pacer> {
        let clock = self.own_clock.clone()?;
        let (color, depth) = (Arc::clone(&self.color.next_t), Arc::clone(&self.depth.next_t));
        Some(Box::new(move || {
            let next = color.load(Ordering::SeqCst).min(depth.load(Ordering::SeqCst));
            if next == u64::MAX || next <= clock.now().0 {
                return next != u64::MAX;
            }
            clock.sleep_until(TimeNs(next));
            true
        }))
    }
}

/// The frames of one session channel, decoded by `decode`.
fn session_stream(
    path: &Path,
    topic: &'static str,
    decode: fn(&[u8]) -> Result<EncodedImage, String>,
) -> Result<FrameStream, VisionError> {
    let reader = MessageReader::open(path, &[topic], ReadOptions::default())?;
    let path = path.to_path_buf();
    Ok(Box::new(reader.map(move |m| {
        let m = m?;
        let image = decode(&m.data).map_err(|detail| VisionError::BadSession {
            path: path.clone(),
            detail: format!("{topic}: {detail}"),
        })?;
        Ok((m.log_time, image))
    })))
}

/// One stream of a recording as a camera.
pub struct RecordedCamera {
    device: String,
    intrinsics: CameraIntrinsics,
    /// The next recorded frame not yet due.
    first: Option<(TimeNs, EncodedImage)>,
    rest: FrameStream,
    /// Due frames not yet polled, oldest first.
    ready: VecDeque<Frame>,
    clock: Arc<dyn Clock>,
    offset_ns: i128,
    sequence: u64,
    ended: Arc<AtomicBool>,
    counts: Arc<ReplayCounts>,
    /// Session time of the next frame not yet due (`u64::MAX`: none left),
    /// for [`RecordedRgbd::pacer`].
    next_t: Arc<AtomicU64>,
}

impl RecordedCamera {
    /// Frames delivered and lost, live while the replay runs.
    pub fn counts(&self) -> Arc<ReplayCounts> {
        Arc::clone(&self.counts)
    }

    fn session_time(&self, recorded: TimeNs) -> TimeNs {
        TimeNs(u64::try_from(i128::from(recorded.0) + self.offset_ns).unwrap_or(0))
    }
}

impl Camera for RecordedCamera {
    /// # Contract
    /// - Never blocks on the clock: returns the oldest frame due by now (its
    ///   recorded time plus the replay's offset), `None` when none is.
    /// - A reader that falls behind loses the oldest due frames beyond four.
    /// - A recording that cannot be read fails with `Other`, naming it.
    fn poll(&mut self) -> Result<Option<Frame>, DeviceError> {
        let now = self.clock.now();
        loop {
            if self.first.is_none() {
                match self.rest.next() {
                    Some(Ok(f)) => self.first = Some(f),
                    Some(Err(e)) => {
                        return Err(DeviceError::new(ErrorKind::Other, &self.device, e.to_string()));
                    }
                    None => {
                        self.ended.store(true, Ordering::SeqCst);
                        self.next_t.store(u64::MAX, Ordering::SeqCst);
                        break;
                    }
                }
            }
            let Some((recorded, _)) = &self.first else { break };
            let t = self.session_time(*recorded);
            if t > now {
                self.next_t.store(t.0, Ordering::SeqCst);
                break;
            }
            let Some((_, image)) = self.first.take() else { break };
            self.ready.push_back(Frame { t, sequence: self.sequence, pixels: None, encoded: Some(image) });
            self.sequence += 1;
            if self.ready.len() > QUEUE {
                self.ready.pop_front();
                self.counts.lost.fetch_add(1, Ordering::Relaxed);
            }
        }
        let frame = self.ready.pop_front();
        if frame.is_some() {
            self.counts.delivered.fetch_add(1, Ordering::Relaxed);
        }
        Ok(frame)
    }

    fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    fn device(&self) -> &str {
        &self.device
    }
}
