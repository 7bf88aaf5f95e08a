//! Modbus RTU without I/O: the frames of function codes 3, 4, 6, 16 and 23
//! and exception responses, for a client (encode requests, decode
//! responses) and a server (decode requests, encode responses).
//!
//! An RTU frame (ADU) is `device id, function code, data, CRC`; the CRC is
//! CRC-16/MODBUS of everything before it, sent low byte first (Modbus over
//! Serial Line V1.02, sec. 2.5.1.2; Modbus Application Protocol V1.1b3,
//! sec. 6). Frames on the wire are separated by at least 3.5 character
//! times of silence; a reader here finds the end of a frame from its
//! length instead ([`request_len`], [`response_len`]), which works the same
//! through USB adapters that stretch the gaps.

use crc::{CRC_16_MODBUS, Crc};
use thiserror::Error;

const CRC: Crc<u16> = Crc::<u16>::new(&CRC_16_MODBUS);

/// Bytes of the CRC at the end of a frame.
pub const CRC_LEN: usize = 2;
/// The longest RTU frame (Modbus over Serial Line, sec. 2.5.1).
pub const MAX_FRAME: usize = 256;
/// The most registers one read may ask for (Modbus Application Protocol, 6.3).
pub const MAX_READ: u16 = 125;
/// The most registers one write may carry (FC16: 123; FC23: 121).
pub const MAX_WRITE: u16 = 121;

/// Function codes this codec knows.
pub mod function {
    /// Read Holding Registers.
    pub const READ_HOLDING: u8 = 0x03;
    /// Read Input Registers.
    pub const READ_INPUT: u8 = 0x04;
    /// Write Single Register.
    pub const WRITE_SINGLE: u8 = 0x06;
    /// Write Multiple Registers.
    pub const WRITE_MULTIPLE: u8 = 0x10;
    /// Read/Write Multiple Registers (the write happens first).
    pub const READ_WRITE_MULTIPLE: u8 = 0x17;
    /// Set in the function code of an exception response.
    pub const EXCEPTION_BIT: u8 = 0x80;
}

/// Exception codes (Modbus Application Protocol, sec. 7).
pub mod exception {
    /// The function code is not supported.
    pub const ILLEGAL_FUNCTION: u8 = 0x01;
    /// The register range is not there.
    pub const ILLEGAL_DATA_ADDRESS: u8 = 0x02;
    /// A count or value is not allowed.
    pub const ILLEGAL_DATA_VALUE: u8 = 0x03;
}

/// CRC-16/MODBUS of `bytes`.
pub fn crc16(bytes: &[u8]) -> u16 {
    CRC.checksum(bytes)
}

/// A request from the client.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Request {
    /// FC3: `count` holding registers from `address`.
    ReadHolding {
        /// First register.
        address: u16,
        /// Registers to read.
        count: u16,
    },
    /// FC4: `count` input registers from `address`.
    ReadInput {
        /// First register.
        address: u16,
        /// Registers to read.
        count: u16,
    },
    /// FC6: one register.
    WriteSingle {
        /// The register.
        address: u16,
        /// Its new value.
        value: u16,
    },
    /// FC16: consecutive registers from `address`.
    WriteMultiple {
        /// First register.
        address: u16,
        /// The values, one per register.
        values: Vec<u16>,
    },
    /// FC23: writes `values` from `write_address`, then reads `read_count`
    /// registers from `read_address`, in one transaction.
    ReadWriteMultiple {
        /// First register read.
        read_address: u16,
        /// Registers read.
        read_count: u16,
        /// First register written.
        write_address: u16,
        /// The values written.
        values: Vec<u16>,
    },
}

impl Request {
    /// The function code.
    pub fn function(&self) -> u8 {
        match self {
            Request::ReadHolding { .. } => function::READ_HOLDING,
            Request::ReadInput { .. } => function::READ_INPUT,
            Request::WriteSingle { .. } => function::WRITE_SINGLE,
            Request::WriteMultiple { .. } => function::WRITE_MULTIPLE,
            Request::ReadWriteMultiple { .. } => function::READ_WRITE_MULTIPLE,
        }
    }

    /// The frame for device `device_id`, CRC included.
    pub fn encode(&self, device_id: u8) -> Vec<u8> {
        let mut f = vec![device_id, self.function()];
        let words =
            |f: &mut Vec<u8>, ws: &[u16]| ws.iter().for_each(|w| f.extend_from_slice(&w.to_be_bytes()));
        match self {
            Request::ReadHolding { address, count } | Request::ReadInput { address, count } => {
                words(&mut f, &[*address, *count]);
            }
            Request::WriteSingle { address, value } => words(&mut f, &[*address, *value]),
            Request::WriteMultiple { address, values } => {
                words(&mut f, &[*address, values.len() as u16]);
                f.push((2 * values.len()) as u8);
                words(&mut f, values);
            }
            Request::ReadWriteMultiple { read_address, read_count, write_address, values } => {
                words(&mut f, &[*read_address, *read_count, *write_address, values.len() as u16]);
                f.push((2 * values.len()) as u8);
                words(&mut f, values);
            }
        }
        with_crc(f)
    }

    /// Decodes a whole request frame (server side): `(device id, request)`.
    pub fn decode(frame: &[u8]) -> Result<(u8, Request), FrameError> {
        let body = check_crc(frame)?;
        let (id, fc, data) = (body[0], body[1], &body[2..]);
        let word = |i: usize| u16::from_be_bytes([data[2 * i], data[2 * i + 1]]);
        let need = |n: usize| {
            if data.len() == n {
                Ok(())
            } else {
                Err(FrameError::BadLength { function: fc, len: frame.len() })
            }
        };
        let values_at = |offset: usize| -> Result<Vec<u16>, FrameError> {
            let count = usize::from(word(offset / 2));
            let bytes = usize::from(data[offset + 2]);
            need(offset + 3 + bytes)?;
            if bytes != 2 * count || count == 0 {
                return Err(FrameError::BadLength { function: fc, len: frame.len() });
            }
            Ok((0..count)
                .map(|i| u16::from_be_bytes([data[offset + 3 + 2 * i], data[offset + 4 + 2 * i]]))
                .collect())
        };
        let request = match fc {
            function::READ_HOLDING | function::READ_INPUT | function::WRITE_SINGLE => {
                need(4)?;
                let (a, b) = (word(0), word(1));
                match fc {
                    function::READ_HOLDING => Request::ReadHolding { address: a, count: b },
                    function::READ_INPUT => Request::ReadInput { address: a, count: b },
                    _ => Request::WriteSingle { address: a, value: b },
                }
            }
            function::WRITE_MULTIPLE if data.len() >= 5 => {
                Request::WriteMultiple { address: word(0), values: values_at(2)? }
            }
            function::READ_WRITE_MULTIPLE if data.len() >= 9 => Request::ReadWriteMultiple {
                read_address: word(0),
                read_count: word(1),
                write_address: word(2),
                values: values_at(6)?,
            },
            function::WRITE_MULTIPLE | function::READ_WRITE_MULTIPLE => {
                return Err(FrameError::BadLength { function: fc, len: frame.len() });
            }
            other => return Err(FrameError::UnknownFunction { device_id: id, function: other }),
        };
        Ok((id, request))
    }
}

/// A response from the server.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Response {
    /// The registers read (FC3, FC4, FC23).
    Registers(Vec<u16>),
    /// The echo of an FC6 write.
    WroteSingle {
        /// The register.
        address: u16,
        /// Its new value.
        value: u16,
    },
    /// The echo of an FC16 write.
    WroteMultiple {
        /// First register.
        address: u16,
        /// Registers written.
        count: u16,
    },
    /// The server refused the request.
    Exception {
        /// The function code of the request.
        function: u8,
        /// The exception code (see [`exception`]).
        code: u8,
    },
}

impl Response {
    /// The frame answering a request of `function` from device `device_id`.
    pub fn encode(&self, device_id: u8, function: u8) -> Vec<u8> {
        let mut f = vec![device_id, function];
        match self {
            Response::Registers(values) => {
                f.push((2 * values.len()) as u8);
                values.iter().for_each(|v| f.extend_from_slice(&v.to_be_bytes()));
            }
            Response::WroteSingle { address, value } => {
                f.extend_from_slice(&address.to_be_bytes());
                f.extend_from_slice(&value.to_be_bytes());
            }
            Response::WroteMultiple { address, count } => {
                f.extend_from_slice(&address.to_be_bytes());
                f.extend_from_slice(&count.to_be_bytes());
            }
            Response::Exception { function, code } => {
                f[1] = function | function::EXCEPTION_BIT;
                f.push(*code);
            }
        }
        with_crc(f)
    }

    /// Decodes the whole response `frame` to `request` sent to `device_id`
    /// (client side): any frame that is not a well-formed answer to that
    /// request is an error, never a response.
    pub fn decode(frame: &[u8], device_id: u8, request: &Request) -> Result<Response, FrameError> {
        let body = check_crc(frame)?;
        let (id, fc, data) = (body[0], body[1], &body[2..]);
        if id != device_id {
            return Err(FrameError::WrongDevice { expected: device_id, got: id });
        }
        let expected = request.function();
        let bad_length = Err(FrameError::BadLength { function: fc, len: frame.len() });
        if fc == expected | function::EXCEPTION_BIT {
            return match data {
                [code] => Ok(Response::Exception { function: expected, code: *code }),
                _ => bad_length,
            };
        }
        if fc != expected {
            return Err(FrameError::WrongFunction { expected, got: fc });
        }
        let word = |i: usize| u16::from_be_bytes([data[2 * i], data[2 * i + 1]]);
        match request {
            Request::ReadHolding { count, .. }
            | Request::ReadInput { count, .. }
            | Request::ReadWriteMultiple { read_count: count, .. } => {
                let n = usize::from(*count);
                if data.len() != 1 + 2 * n || usize::from(data[0]) != 2 * n {
                    return bad_length;
                }
                Ok(Response::Registers(
                    (0..n).map(|i| u16::from_be_bytes([data[1 + 2 * i], data[2 + 2 * i]])).collect(),
                ))
            }
            Request::WriteSingle { address, value } => {
                if data.len() != 4 {
                    return bad_length;
                }
                let echo = Response::WroteSingle { address: word(0), value: word(1) };
                let sent = Response::WroteSingle { address: *address, value: *value };
                if echo == sent { Ok(echo) } else { Err(FrameError::BadEcho { function: fc }) }
            }
            Request::WriteMultiple { address, values } => {
                if data.len() != 4 {
                    return bad_length;
                }
                let echo = Response::WroteMultiple { address: word(0), count: word(1) };
                let sent = Response::WroteMultiple { address: *address, count: values.len() as u16 };
                if echo == sent { Ok(echo) } else { Err(FrameError::BadEcho { function: fc }) }
            }
        }
    }
}

/// The length of the request frame that `prefix` starts, once enough of it
/// is there to tell (server side); `Err` for a function code this codec
/// does not know (its end is the next silence).
pub fn request_len(prefix: &[u8]) -> Result<Option<usize>, u8> {
    let Some(&fc) = prefix.get(1) else { return Ok(None) };
    Ok(match fc {
        function::READ_HOLDING | function::READ_INPUT | function::WRITE_SINGLE => Some(8),
        function::WRITE_MULTIPLE => prefix.get(6).map(|&n| 9 + usize::from(n)),
        function::READ_WRITE_MULTIPLE => prefix.get(10).map(|&n| 13 + usize::from(n)),
        other => return Err(other),
    })
}

/// The length of the response to `request` that `prefix` starts (client
/// side): 5 for an exception, otherwise what the request implies. `None`
/// until the function code is there.
pub fn response_len(prefix: &[u8], request: &Request) -> Option<usize> {
    let &fc = prefix.get(1)?;
    if fc & function::EXCEPTION_BIT != 0 {
        return Some(5);
    }
    Some(match request {
        Request::ReadHolding { count, .. }
        | Request::ReadInput { count, .. }
        | Request::ReadWriteMultiple { read_count: count, .. } => 5 + 2 * usize::from(*count),
        Request::WriteSingle { .. } | Request::WriteMultiple { .. } => 8,
    })
}

/// A frame that is not a valid answer (or request).
#[derive(Clone, Copy, Debug, Error, PartialEq, Eq)]
pub enum FrameError {
    /// Fewer bytes than the smallest frame.
    #[error("short frame of {len} bytes")]
    Short {
        /// Bytes received.
        len: usize,
    },
    /// The CRC does not match the bytes.
    #[error("bad CRC: computed {expected:#06x}, frame has {got:#06x}")]
    BadCrc {
        /// CRC of the bytes received.
        expected: u16,
        /// CRC in the frame.
        got: u16,
    },
    /// A frame from (or for) another device.
    #[error("frame of device {got}, expected device {expected}")]
    WrongDevice {
        /// The device asked.
        expected: u8,
        /// The device in the frame.
        got: u8,
    },
    /// A response of another function than the request's.
    #[error("response with function code {got:#04x} to a request with {expected:#04x}")]
    WrongFunction {
        /// The request's function code.
        expected: u8,
        /// The response's.
        got: u8,
    },
    /// A length or byte count that does not fit the function.
    #[error("function {function:#04x}: a frame of {len} bytes does not fit its byte counts")]
    BadLength {
        /// The function code.
        function: u8,
        /// Bytes in the frame.
        len: usize,
    },
    /// A write's echo that does not repeat the request.
    #[error("function {function:#04x}: the echo differs from the request")]
    BadEcho {
        /// The function code.
        function: u8,
    },
    /// A function code this codec does not know.
    #[error("device {device_id}: unknown function code {function:#04x}")]
    UnknownFunction {
        /// The device the frame is for.
        device_id: u8,
        /// The function code.
        function: u8,
    },
}

fn with_crc(mut frame: Vec<u8>) -> Vec<u8> {
    let crc = crc16(&frame);
    frame.extend_from_slice(&crc.to_le_bytes());
    frame
}

/// The frame without its CRC, when the CRC matches; at least id and
/// function code.
fn check_crc(frame: &[u8]) -> Result<&[u8], FrameError> {
    if frame.len() < 2 + CRC_LEN {
        return Err(FrameError::Short { len: frame.len() });
    }
    let (body, crc) = frame.split_at(frame.len() - CRC_LEN);
    let (expected, got) = (crc16(body), u16::from_le_bytes([crc[0], crc[1]]));
    if expected == got { Ok(body) } else { Err(FrameError::BadCrc { expected, got }) }
}

#[cfg(test)]
mod tests;
