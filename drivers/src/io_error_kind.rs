//! How a device's I/O errors read to the rig: one mapping from
//! `std::io::Error` (and its errno) onto [`ErrorKind`], shared by every
//! backend (serial ports, SocketCAN, SLCAN, V4L2, Modbus links).

use nix::errno::Errno;

use slidetrack_core::ErrorKind;

/// The [`ErrorKind`] of an I/O error from a device: a vanished device
/// (hang-up, `ENODEV`, `EIO`, interface down) is `Disconnected`.
pub(crate) fn io_error_kind(e: &std::io::Error) -> ErrorKind {
    use std::io::ErrorKind as K;
    if let Some(code) = e.raw_os_error() {
        let errno = Errno::from_raw(code);
        match errno {
            Errno::ENODEV | Errno::ENXIO | Errno::EIO | Errno::ENETDOWN | Errno::EPIPE | Errno::EBADF => {
                return ErrorKind::Disconnected;
            }
            Errno::ENOBUFS => return ErrorKind::Overrun,
            Errno::ETIMEDOUT | Errno::EAGAIN => return ErrorKind::Timeout,
            _ => {}
        }
    }
    match e.kind() {
        K::TimedOut | K::WouldBlock => ErrorKind::Timeout,
        K::BrokenPipe
        | K::NotFound
        | K::UnexpectedEof
        | K::ConnectionReset
        | K::ConnectionAborted
        | K::NotConnected => ErrorKind::Disconnected,
        // serialport reports a failed read(2) on a vanished USB device as
        // an untyped error carrying the errno's text.
        _ if e.to_string().contains("I/O error") || e.to_string().contains("No such device") => {
            ErrorKind::Disconnected
        }
        _ => ErrorKind::Other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vanished_devices_are_disconnected() {
        let kind = |e: std::io::Error| io_error_kind(&e);
        assert_eq!(kind(std::io::Error::from_raw_os_error(Errno::ENODEV as i32)), ErrorKind::Disconnected);
        assert_eq!(kind(std::io::Error::from_raw_os_error(Errno::ENETDOWN as i32)), ErrorKind::Disconnected);
        assert_eq!(kind(std::io::ErrorKind::BrokenPipe.into()), ErrorKind::Disconnected);
        assert_eq!(kind(std::io::Error::other("I/O error")), ErrorKind::Disconnected);
        assert_eq!(kind(std::io::ErrorKind::TimedOut.into()), ErrorKind::Timeout);
        assert_eq!(kind(std::io::Error::from_raw_os_error(Errno::ENOBUFS as i32)), ErrorKind::Overrun);
        assert_eq!(kind(std::io::ErrorKind::InvalidInput.into()), ErrorKind::Other);
    }
}
