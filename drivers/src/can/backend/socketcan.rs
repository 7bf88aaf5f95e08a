//! CAN buses: a small [`CanBus`] seam (SocketCAN here, an SLCAN adapter in
//! [`crate::slcan::backend`], memory in tests). The tactile boards on it are
//! [`crate::can::backend`], the hand [`crate::can_hand::backend`].
//!
//! SocketCAN sockets ask the kernel for error frames (bus-off,
//! error-passive, missing ACK, protocol errors: [`bus_errors::ERROR_MASK`])
//! and for receive timestamps (`SO_TIMESTAMPNS`, the kernel's
//! `CLOCK_REALTIME` when the frame arrived). A timestamp is mapped onto the
//! session clock by its age: `t = clock.now() - (SystemTime::now() -
//! timestamp)`, read right after the frame, so that the time a frame waited
//! in the socket's queue is not counted; the wall clock's steps between the
//! two readings are microseconds apart and cancel out.

use std::io;
use std::time::{Duration, Instant, SystemTime};

use slidetrack_core::{DeviceError, ErrorKind};
use socketcan::{CanDataFrame, EmbeddedFrame, ExtendedId, Id, Socket, SocketOptions, StandardId};

use crate::can::protocol::CanFrame;
use crate::io_error_kind::io_error_kind;

pub mod bus_errors;

use bus_errors::BusProblem;

/// What a bus delivered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BusEvent {
    /// A data frame.
    Frame {
        /// The frame.
        frame: CanFrame,
        /// How long ago the kernel (or the host's reader) received it, when
        /// known; `None`: just now.
        age: Option<Duration>,
    },
    /// An error frame's problem.
    Problem(BusProblem),
}

/// Moves CAN frames; the backends hold one.
///
/// # Contract
/// - `send` queues one frame or fails (`io::ErrorKind` of the socket).
/// - `recv` returns the next frame, `Ok(None)` after `timeout` without one.
///   Remote and error frames are skipped.
/// - Both may be called from several threads at once.
pub trait CanBus: Send + Sync {
    /// Sends one frame.
    fn send(&self, frame: &CanFrame) -> io::Result<()>;
    /// The next data frame, or `None` after `timeout`.
    fn recv(&self, timeout: Duration) -> io::Result<Option<CanFrame>>;
    /// The interface name, for messages.
    fn name(&self) -> &str;
    /// The next data frame with its age, or a bus problem; `None` after
    /// `timeout`. By default: [`recv`](Self::recv), no age, no problems.
    fn recv_event(&self, timeout: Duration) -> io::Result<Option<BusEvent>> {
        Ok(self.recv(timeout)?.map(|frame| BusEvent::Frame { frame, age: None }))
    }
}

/// A raw SocketCAN socket bound to one interface.
pub struct SocketCanBus {
    socket: socketcan::CanSocket,
    name: String,
    /// `SO_TIMESTAMPNS` is on.
    timestamps: bool,
}

impl SocketCanBus {
    /// Opens `interface` (`can0`, `vcan0`).
    pub fn open(interface: &str) -> Result<SocketCanBus, DeviceError> {
        let socket = socketcan::CanSocket::open(interface).map_err(|e| {
            let kind = match io_error_kind(&e) {
                ErrorKind::Other => ErrorKind::Disconnected,
                k => k,
            };
            DeviceError::new(
                kind,
                interface,
                format!("cannot open CAN interface: {e} (is it up? `ip link show {interface}`)"),
            )
        })?;
        Ok(SocketCanBus { socket, name: interface.to_string(), timestamps: false })
    }

    /// Opens `interface` for a tactile source: error frames of
    /// [`bus_errors::ERROR_MASK`] and kernel receive timestamps on.
    pub fn open_for_tactile(interface: &str) -> Result<SocketCanBus, DeviceError> {
        let mut bus = SocketCanBus::open(interface)?;
        bus.socket.set_error_filter(bus_errors::ERROR_MASK).map_err(|e| {
            DeviceError::new(io_error_kind(&e), interface, format!("cannot set the CAN error filter: {e}"))
        })?;
        match bus.socket.set_recv_timestamp(true) {
            Ok(()) => bus.timestamps = true,
            Err(e) => tracing::debug!("{interface}: no kernel receive timestamps ({e}); stamping on read"),
        }
        Ok(bus)
    }

    /// One frame (data or error) with its kernel timestamp when on.
    fn read_any(&self, timeout: Duration) -> io::Result<(socketcan::CanFrame, Option<SystemTime>)> {
        if self.timestamps {
            self.socket.set_read_timeout(timeout)?;
            let (frame, at) = self.socket.read_frame_with_timestamp()?;
            Ok((frame, Some(at)))
        } else {
            Ok((self.socket.read_frame_timeout(timeout)?, None))
        }
    }
}

fn to_socketcan(frame: &CanFrame) -> io::Result<CanDataFrame> {
    let id: Option<Id> = if frame.extended {
        ExtendedId::new(frame.id).map(Id::Extended)
    } else {
        u16::try_from(frame.id).ok().and_then(StandardId::new).map(Id::Standard)
    };
    id.and_then(|id| CanDataFrame::new(id, frame.data())).ok_or_else(|| {
        io::Error::new(io::ErrorKind::InvalidInput, format!("frame 0x{:X} does not fit CAN", frame.id))
    })
}

impl CanBus for SocketCanBus {
    fn send(&self, frame: &CanFrame) -> io::Result<()> {
        self.socket.write_frame(&to_socketcan(frame)?)
    }

    fn recv(&self, timeout: Duration) -> io::Result<Option<CanFrame>> {
        let deadline = Instant::now() + timeout;
        loop {
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return Ok(None);
            }
            match self.socket.read_frame_timeout(remaining) {
                Ok(socketcan::CanFrame::Data(d)) => {
                    let id = socketcan::Frame::raw_id(&d);
                    if let Some(f) = CanFrame::new(id, d.is_extended(), d.data()) {
                        return Ok(Some(f));
                    }
                }
                Ok(_) => {} // remote and error frames
                Err(e) if matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock) => {
                    return Ok(None);
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
    }

    fn name(&self) -> &str {
        &self.name
    }

    fn recv_event(&self, timeout: Duration) -> io::Result<Option<BusEvent>> {
        let deadline = Instant::now() + timeout;
        loop {
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return Ok(None);
            }
            match self.read_any(remaining) {
                Ok((socketcan::CanFrame::Data(d), at)) => {
                    let age = at.map(|at| SystemTime::now().duration_since(at).unwrap_or_default());
                    let id = socketcan::Frame::raw_id(&d);
                    if let Some(frame) = CanFrame::new(id, d.is_extended(), d.data()) {
                        return Ok(Some(BusEvent::Frame { frame, age }));
                    }
                }
                Ok((socketcan::CanFrame::Error(e), _)) => {
                    if let Some(p) = bus_errors::classify(e.error_bits(), e.data()) {
                        return Ok(Some(BusEvent::Problem(p)));
                    }
                }
                Ok(_) => {} // remote frames
                Err(e) if matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock) => {
                    return Ok(None);
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
    }
}

#[cfg(test)]
mod tests;
