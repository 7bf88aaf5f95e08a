//! SLCAN, the "Lawicel" ASCII protocol of serial-line CAN adapters (VScom
//! USB-CAN Plus, CANable with slcan firmware, CANUSB), without I/O: command
//! encoding, a streaming decoder of what the adapter sends, and the
//! unwrapping of its millisecond timestamps. See `docs/protocols.md`,
//! section "SLCAN", for the sources of every fact used here.
//!
//! Every message is ASCII and ends with a carriage return (`\r`, 0x0D); a
//! command the adapter refuses is answered with a lone BEL (0x07) instead:
//!
//! ```text
//! host -> adapter            adapter -> host
//! C\r     close channel      \r (OK) or BEL
//! S8\r    1 Mbit/s (S0..S8)  \r or BEL
//! Z1\r    timestamps on      \r or BEL (not every firmware has Z)
//! O\r     open channel       \r or BEL
//! t2012 0700\r (no space)    z\r (Lawicel) or \r (CANable, slcanpty), BEL
//!                            t7108001234...[ssss]\r  received frames
//! ```
//!
//! A frame is `t iii l dd..` (11-bit id, 3 hex digits), `T iiiiiiii l dd..`
//! (29-bit id, 8 hex digits), `r iii l` / `R iiiiiiii l` for remote
//! frames; `l` is the length 0-8 and each data byte two hex digits. With
//! timestamps on (`Z1`) the adapter appends 4 hex digits: milliseconds,
//! 0 to 59999 (0xEA5F), wrapping every minute ([`SlcanClock`] unwraps them).

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::can::protocol::CanFrame;

/// CAN bit rates of the `S0`..`S8` commands, in bit/s (index = code).
pub const BITRATES: [u32; 9] =
    [10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000];

/// A CAN bit rate without an `Sn` code.
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
#[error(
    "CAN bit rate {bitrate} bit/s has no SLCAN `Sn` code; supported: 10000, 20000, 50000, 100000, \
     125000, 250000, 500000, 800000 (S7; CANable firmware reads S7 as 750 kbit/s), 1000000 bit/s"
)]
pub struct UnsupportedBitrate {
    /// The bit rate asked for (bit/s).
    pub bitrate: u32,
}

/// The `Sn` code of a CAN bit rate given in bit/s (`1_000_000` -> 8).
pub fn bitrate_code(bitrate: u32) -> Result<u8, UnsupportedBitrate> {
    BITRATES.iter().position(|&b| b == bitrate).map(|i| i as u8).ok_or(UnsupportedBitrate { bitrate })
}

/// A command from the host to the adapter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SlcanCommand {
    /// `O`: open the channel (join the bus).
    Open,
    /// `C`: close the channel (reset mode).
    Close,
    /// `Sn`: the bit rate of code `n` (0-8, see [`BITRATES`]); adapters
    /// accept it only while the channel is closed.
    Bitrate(u8),
    /// `Z1` / `Z0`: append timestamps to received frames, or not.
    Timestamps(bool),
    /// `F`: read the status flags (reply `Fxx`, hex).
    StatusFlags,
    /// `V`: read the hardware and software version (reply `Vhhss`).
    Version,
    /// `N`: read the serial number (reply `Nxxxx`).
    SerialNumber,
    /// `t` / `T`: transmit a data frame.
    Transmit(CanFrame),
}

impl SlcanCommand {
    /// Appends the command and its `\r` to `out`.
    pub fn encode_into(&self, out: &mut Vec<u8>) {
        match self {
            SlcanCommand::Open => out.push(b'O'),
            SlcanCommand::Close => out.push(b'C'),
            SlcanCommand::Bitrate(code) => {
                out.push(b'S');
                out.extend_from_slice(code.to_string().as_bytes());
            }
            SlcanCommand::Timestamps(on) => out.extend_from_slice(if *on { b"Z1" } else { b"Z0" }),
            SlcanCommand::StatusFlags => out.push(b'F'),
            SlcanCommand::Version => out.push(b'V'),
            SlcanCommand::SerialNumber => out.push(b'N'),
            SlcanCommand::Transmit(frame) => {
                encode_frame_line(frame, false, None, out);
                return;
            }
        }
        out.push(CR);
    }

    /// The command's bytes, `\r` included.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(32);
        self.encode_into(&mut out);
        out
    }

    /// The command as text without its `\r` (`S8`), for messages.
    pub fn text(&self) -> String {
        let bytes = self.encode();
        String::from_utf8_lossy(&bytes[..bytes.len() - 1]).into_owned()
    }
}

const HEX: &[u8; 16] = b"0123456789ABCDEF";

/// Appends a frame line and its `\r` to `out`: `t`/`T` for a data frame,
/// `r`/`R` for a remote frame (whose length is `frame.data().len()` and
/// whose data is not sent), and `timestamp_ms` as 4 hex digits when given
/// (adapters add it to the frames they receive; the host never sends one).
pub fn encode_frame_line(frame: &CanFrame, remote: bool, timestamp_ms: Option<u16>, out: &mut Vec<u8>) {
    let kind = match (remote, frame.extended) {
        (false, false) => b't',
        (false, true) => b'T',
        (true, false) => b'r',
        (true, true) => b'R',
    };
    out.push(kind);
    let digits = if frame.extended { 8 } else { 3 };
    for k in (0..digits).rev() {
        out.push(HEX[((frame.id >> (4 * k)) & 0xF) as usize]);
    }
    out.push(b'0' + frame.data().len() as u8);
    if !remote {
        for b in frame.data() {
            out.extend_from_slice(&[HEX[usize::from(b >> 4)], HEX[usize::from(b & 0xF)]]);
        }
    }
    if let Some(t) = timestamp_ms {
        for k in (0..4).rev() {
            out.push(HEX[usize::from((t >> (4 * k)) & 0xF)]);
        }
    }
    out.push(CR);
}

mod decoder;
mod events;
mod timestamps;
mod wire;

pub use decoder::{SlcanDecoder, parse_frame_line};
pub use events::{MalformedReason, SlcanCounters, SlcanEvent};
pub use timestamps::SlcanClock;
pub use wire::{BEL, CR, MAX_LINE, TIMESTAMP_PERIOD_MS};

/// How `SlcanBus` (module `slcan_bus`, with the `devices` feature) sets up
/// an adapter (a `[hw]` TOML table can hold it).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SlcanConfig {
    /// Serial speed in baud (USB CDC adapters such as CANable ignore it).
    /// Default 3 000 000, as XELA's setup runs `slcand -S 3000000`.
    pub baud: u32,
    /// CAN bit rate in bit/s, one of [`BITRATES`]. Default 1 000 000 (`S8`),
    /// the rate of XELA uSkin boards.
    pub bitrate: u32,
    /// Ask for the adapter's timestamps (`Z1`); with `false`, `Z0` is sent
    /// and a refusal tolerated. Default true. CANable's slcan firmware has
    /// no `Z` command: set false for it.
    pub timestamps: bool,
    /// Send the set-up commands (`C`, `Sn`, `Z1`/`Z0`, `O`) at open and `C`
    /// on drop. False for an adapter that something else opened.
    pub setup: bool,
    /// RTS/CTS hardware flow control on the serial port (`slcand -t hw`, as
    /// XELA's setup uses with the VScom adapter). Default true.
    pub hardware_flow_control: bool,
    /// Longest wait for the reply to a set-up command, milliseconds. Default 500.
    pub reply_timeout_ms: u64,
}

impl Default for SlcanConfig {
    fn default() -> Self {
        SlcanConfig {
            baud: 3_000_000,
            bitrate: 1_000_000,
            timestamps: true,
            setup: true,
            hardware_flow_control: true,
            reply_timeout_ms: 500,
        }
    }
}

impl SlcanConfig {
    /// The set-up commands in the order they are sent, each with whether
    /// a BEL reply is tolerated: `C` (refused by some adapters when the
    /// channel is already closed), `Sn`, `Z1` or `Z0` (`Z0` may be refused
    /// by firmwares without timestamps), `O`.
    pub fn setup_commands(&self) -> Result<[(SlcanCommand, bool); 4], UnsupportedBitrate> {
        Ok([
            (SlcanCommand::Close, true),
            (SlcanCommand::Bitrate(bitrate_code(self.bitrate)?), false),
            (SlcanCommand::Timestamps(self.timestamps), !self.timestamps),
            (SlcanCommand::Open, false),
        ])
    }
}

#[cfg(test)]
mod tests;
