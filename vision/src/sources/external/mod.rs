//! [`ExternalSource`]: masks and poses from another process (a lab's own
//! segmentation or pose network, in any language) over a local TCP socket.
//!
//! slidetrack is the server: it announces each frame's time (and, if asked,
//! the frame's images) to the connected client, which answers with results
//! keyed by that time. The protocol, newline-delimited JSON with a versioned
//! handshake, is specified in `docs/protocols.md` ("External vision source").

pub mod protocol;
mod server;
#[cfg(test)]
mod tests;

use std::collections::VecDeque;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::time::{Duration, Instant};

use base64::Engine;
use slidetrack_core::{CameraIntrinsics, RgbdFrame, TimeNs};

pub use protocol::{ClientMessage, ExternalError, MaskMessage, ServerMessage};
use server::{Event, Writer};

use super::source::{Arrivals, Delayed, FrameTruth, MeasurementSource};
use crate::VisionError;

/// Settings of [`ExternalSource`].
#[derive(Clone, Debug, PartialEq)]
pub struct ExternalConfig {
    /// Address to listen on, for example `127.0.0.1:7450` (port 0: any).
    pub listen: String,
    /// With a client connected, wait up to this long at each frame for its
    /// result for that frame (recorded inputs: lockstep with the client);
    /// `None`: never wait (live cameras).
    pub wait_for_result: Option<Duration>,
    /// Before the first frame, wait up to this long for a client to connect
    /// (recorded inputs whose first frames should not go unanswered).
    pub wait_for_client: Option<Duration>,
    /// Results for frames older than this (ns) at the frame they arrive by are dropped.
    pub max_age_ns: u64,
    /// Send each frame's colour (JPEG) and depth (16-bit PNG) with its time.
    pub send_images: bool,
}

impl Default for ExternalConfig {
    fn default() -> ExternalConfig {
        ExternalConfig {
            listen: "127.0.0.1:7450".into(),
            wait_for_result: None,
            wait_for_client: None,
            max_age_ns: 1_000_000_000,
            send_images: false,
        }
    }
}

/// What the source saw so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExternalStats {
    /// Clients that completed the handshake.
    pub connections: usize,
    /// Clients that left.
    pub disconnections: usize,
    /// Poses delivered to the tracker.
    pub poses: usize,
    /// Masks delivered to the tracker.
    pub masks: usize,
    /// Messages refused (bad JSON, bad pose or mask, truncated, handshake).
    pub refused: usize,
    /// Results for frames never announced.
    pub unknown_frames: usize,
    /// Results dropped as too late.
    pub late: usize,
}

/// How many announced frame times are remembered for checking results.
const REMEMBERED_FRAMES: usize = 4096;

/// The server end of the protocol, polled by the tracker once per frame.
///
/// Results arrive by the first frame processed after they were received
/// (their `arrival_t` is that frame's time); results for unknown frames or
/// older than `max_age_ns` are refused with an `error` message to the
/// client and counted. A client may disconnect and reconnect at any time;
/// the tracker is never stopped by what a client sends.
pub struct ExternalSource {
    config: ExternalConfig,
    intrinsics: CameraIntrinsics,
    local_addr: SocketAddr,
    writer: Writer,
    events: Receiver<Event>,
    stop: Arc<AtomicBool>,
    announced: VecDeque<u64>,
    connected: bool,
    stats: ExternalStats,
    last_error: Option<String>,
}

impl ExternalSource {
    /// Listens on `config.listen` for frames of `intrinsics`.
    pub fn listen(
        config: ExternalConfig,
        intrinsics: &CameraIntrinsics,
    ) -> Result<ExternalSource, VisionError> {
        let (sender, events) = channel();
        let writer = Writer::default();
        let stop = Arc::new(AtomicBool::new(false));
        let hello = ServerMessage::Hello {
            protocol: protocol::PROTOCOL,
            version: protocol::VERSION,
            width: intrinsics.width,
            height: intrinsics.height,
            intrinsics: [intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy],
        };
        let local_addr = server::listen(&config.listen, hello, writer.clone(), sender, stop.clone())?;
        Ok(ExternalSource {
            config,
            intrinsics: intrinsics.clone(),
            local_addr,
            writer,
            events,
            stop,
            announced: VecDeque::new(),
            connected: false,
            stats: ExternalStats::default(),
            last_error: None,
        })
    }

    /// The address listened on (with the port chosen when it was 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// What the source saw so far.
    pub fn stats(&self) -> ExternalStats {
        self.stats
    }

    /// The latest refused message, in words.
    pub fn last_error(&self) -> Option<&str> {
        self.last_error.as_deref()
    }

    /// Waits up to `wait` for a client's handshake.
    fn wait_for_client(&mut self, wait: Duration, t: TimeNs, out: &mut Arrivals) {
        let deadline = Instant::now() + wait;
        while !self.connected {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.events.recv_timeout(left) {
                Ok(event) => {
                    self.handle(event, t, out);
                }
                Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => return,
            }
        }
    }

    /// Tells the client about `frame`.
    fn announce(&mut self, frame: &RgbdFrame) {
        self.announced.push_back(frame.t.0);
        if self.announced.len() > REMEMBERED_FRAMES {
            self.announced.pop_front();
        }
        if !self.writer.is_connected() {
            return;
        }
        let (color_jpeg, depth_png) =
            if self.config.send_images { encode_images(frame) } else { (None, None) };
        self.writer.send(&ServerMessage::Frame {
            frame_t_ns: frame.t.0,
            sequence: frame.sequence,
            color_jpeg,
            depth_png,
        });
    }

    /// Handles one event; returns the frame time of a result it delivered.
    fn handle(&mut self, event: Event, t: TimeNs, out: &mut Arrivals) -> Option<u64> {
        match event {
            Event::Connected => {
                self.connected = true;
                self.stats.connections += 1;
                None
            }
            Event::Disconnected => {
                self.connected = false;
                self.stats.disconnections += 1;
                None
            }
            Event::Error(e) => {
                self.refuse(e);
                None
            }
            Event::Result(message) => match self.accept(message, t, out) {
                Ok(frame_t) => Some(frame_t),
                Err(e) => {
                    self.writer.send(&ServerMessage::Error { kind: e.kind(), detail: e.to_string() });
                    self.refuse(e);
                    None
                }
            },
        }
    }

    fn refuse(&mut self, error: ExternalError) {
        match error {
            ExternalError::UnknownFrame { .. } => self.stats.unknown_frames += 1,
            ExternalError::Late { .. } => self.stats.late += 1,
            _ => self.stats.refused += 1,
        }
        tracing::warn!("external source: {error}");
        self.last_error = Some(error.to_string());
    }

    /// Checks a result and adds it to `out`.
    fn accept(
        &mut self,
        message: ClientMessage,
        t: TimeNs,
        out: &mut Arrivals,
    ) -> Result<u64, ExternalError> {
        let ClientMessage::Result { frame_t_ns, pose, mask } = message else {
            return Err(ExternalError::BadMessage { line: 0, detail: "unexpected hello".into() });
        };
        if !self.announced.contains(&frame_t_ns) {
            return Err(ExternalError::UnknownFrame { frame_t_ns });
        }
        let age_ns = t.0.saturating_sub(frame_t_ns);
        if age_ns > self.config.max_age_ns {
            return Err(ExternalError::Late { frame_t_ns, age_ns, max_age_ns: self.config.max_age_ns });
        }
        let pose = pose.map(|p| protocol::decode_pose(&p, frame_t_ns)).transpose()?;
        let (w, h) = (self.intrinsics.width, self.intrinsics.height);
        let mask = mask.map(|m| protocol::decode_mask(&m, frame_t_ns, w, h)).transpose()?;
        let (frame_t, arrival_t) = (TimeNs(frame_t_ns), t);
        if let Some(value) = pose {
            self.stats.poses += 1;
            out.poses.push(Delayed { frame_t, arrival_t, value });
        }
        if let Some(value) = mask {
            self.stats.masks += 1;
            out.masks.push(Delayed { frame_t, arrival_t, value });
        }
        Ok(frame_t_ns)
    }
}

/// The frame's colour as JPEG and depth as a 16-bit PNG (mm), base64.
fn encode_images(frame: &RgbdFrame) -> (Option<String>, Option<String>) {
    let b64 = |bytes: &[u8]| base64::engine::general_purpose::STANDARD.encode(bytes);
    let color = crate::input::encode_color_jpeg(&frame.color, 90).ok().map(|j| b64(&j.bytes));
    let d = &frame.depth;
    let mut png_bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut png_bytes, d.width, d.height);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Sixteen);
    let to_mm = d.scale_m * 1000.0;
    let samples: Vec<u8> = d
        .data
        .iter()
        .flat_map(|v| ((f64::from(*v) * to_mm).round().min(65535.0) as u16).to_be_bytes())
        .collect();
    let written = encoder.write_header().and_then(|mut w| w.write_image_data(&samples));
    (color, written.ok().map(|()| b64(&png_bytes)))
}

impl MeasurementSource for ExternalSource {
    fn on_frame(&mut self, t: TimeNs, _truth: Option<FrameTruth<'_>>) -> Result<Arrivals, VisionError> {
        Err(VisionError::BadValue {
            what: "measurement source",
            detail: format!("the external source announces frames: call on_rgbd_frame (frame at {} ns)", t.0),
        })
    }

    fn on_rgbd_frame(
        &mut self,
        frame: &RgbdFrame,
        _truth: Option<FrameTruth<'_>>,
    ) -> Result<Arrivals, VisionError> {
        let mut out = Arrivals::default();
        if self.announced.is_empty()
            && let Some(wait) = self.config.wait_for_client
        {
            self.wait_for_client(wait, frame.t, &mut out);
        }
        self.announce(frame);
        let mut answered = false;
        while let Ok(event) = self.events.try_recv() {
            answered |= self.handle(event, frame.t, &mut out) == Some(frame.t.0);
        }
        let Some(wait) = self.config.wait_for_result else { return Ok(out) };
        let deadline = Instant::now() + wait;
        // Lockstep: wait for this frame's result while a client is there.
        while self.connected && !answered {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.events.recv_timeout(left) {
                Ok(event) => {
                    let refused = matches!(event, Event::Error(_));
                    answered = self.handle(event, frame.t, &mut out) == Some(frame.t.0) || refused;
                }
                Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => break,
            }
        }
        Ok(out)
    }

    fn summary(&self) -> Option<String> {
        let s = self.stats;
        Some(format!(
            "external: {} connections, {} poses, {} masks, {} refused, {} for unknown frames, {} late",
            s.connections, s.poses, s.masks, s.refused, s.unknown_frames, s.late
        ))
    }
}

impl Drop for ExternalSource {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        self.writer.close();
    }
}
