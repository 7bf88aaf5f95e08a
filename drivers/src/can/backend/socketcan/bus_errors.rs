//! SocketCAN error frames turned into one-line problems, without I/O. The
//! class bits and data bytes are those of `linux/can/error.h`.

/// `CAN_ERR_TX_TIMEOUT`: the driver timed out sending.
pub const ERR_TX_TIMEOUT: u32 = 0x0001;
/// `CAN_ERR_CRTL`: controller problems, in data byte 1.
pub const ERR_CRTL: u32 = 0x0004;
/// `CAN_ERR_PROT`: protocol violations, in data bytes 2 and 3.
pub const ERR_PROT: u32 = 0x0008;
/// `CAN_ERR_ACK`: no ACK on transmission.
pub const ERR_ACK: u32 = 0x0020;
/// `CAN_ERR_BUSOFF`: the controller went bus-off.
pub const ERR_BUSOFF: u32 = 0x0040;
/// `CAN_ERR_BUSERROR`: bus error.
pub const ERR_BUSERROR: u32 = 0x0080;
/// `CAN_ERR_RESTARTED`: the controller restarted.
pub const ERR_RESTARTED: u32 = 0x0100;
/// `CAN_ERR_CRTL_RX_PASSIVE` (data byte 1).
pub const CRTL_RX_PASSIVE: u8 = 0x10;
/// `CAN_ERR_CRTL_TX_PASSIVE` (data byte 1).
pub const CRTL_TX_PASSIVE: u8 = 0x20;

/// The error classes the tactile socket asks the kernel for
/// (`CAN_RAW_ERR_FILTER`).
pub const ERROR_MASK: u32 =
    ERR_TX_TIMEOUT | ERR_CRTL | ERR_PROT | ERR_ACK | ERR_BUSOFF | ERR_BUSERROR | ERR_RESTARTED;

/// A bus problem an error frame reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BusProblem {
    /// The controller left the bus after too many errors; it receives
    /// nothing until restarted (`ip link set can0 type can restart-ms 100`).
    BusOff,
    /// The controller's error counters passed 127: it still receives, but
    /// the bus is failing.
    ErrorPassive,
    /// A frame we sent got no ACK: no other node on the bus, or a
    /// different bit rate.
    NoAck,
    /// Protocol violations or other bus errors (bit, stuff, form, CRC errors).
    BusError,
    /// The driver could not send in time.
    TransmitTimeout,
    /// The controller restarted after bus-off.
    Restarted,
}

impl BusProblem {
    /// Whether the bus is unusable until someone intervenes.
    pub fn is_fatal(self) -> bool {
        self == BusProblem::BusOff
    }
}

impl std::fmt::Display for BusProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            BusProblem::BusOff => {
                "bus-off: the CAN controller left the bus after too many errors (check wiring, termination \
                 and bit rate; `ip -details link show` shows the state)"
            }
            BusProblem::ErrorPassive => {
                "error-passive: the CAN controller sees many errors (wiring, termination?)"
            }
            BusProblem::NoAck => "no ACK: is another node on the bus at the same bitrate?",
            BusProblem::BusError => "CAN bus errors (bit, stuff, form or CRC errors): wiring or bit rate?",
            BusProblem::TransmitTimeout => "the CAN driver timed out sending a frame",
            BusProblem::Restarted => "the CAN controller restarted after bus-off",
        })
    }
}

/// The most serious problem an error frame with `class_bits` (the id
/// without `CAN_ERR_FLAG`) and `data` reports; `None` for classes not
/// asked for (arbitration lost, transceiver, counters) or warnings.
pub fn classify(class_bits: u32, data: &[u8]) -> Option<BusProblem> {
    let byte = |i: usize| data.get(i).copied().unwrap_or(0);
    if class_bits & ERR_BUSOFF != 0 {
        return Some(BusProblem::BusOff);
    }
    if class_bits & ERR_ACK != 0 {
        return Some(BusProblem::NoAck);
    }
    if class_bits & ERR_CRTL != 0 && byte(1) & (CRTL_RX_PASSIVE | CRTL_TX_PASSIVE) != 0 {
        return Some(BusProblem::ErrorPassive);
    }
    if class_bits & (ERR_PROT | ERR_BUSERROR) != 0 {
        return Some(BusProblem::BusError);
    }
    if class_bits & ERR_TX_TIMEOUT != 0 {
        return Some(BusProblem::TransmitTimeout);
    }
    if class_bits & ERR_RESTARTED != 0 {
        return Some(BusProblem::Restarted);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_frames_become_the_named_problems() {
        assert_eq!(classify(ERR_BUSOFF | ERR_CRTL, &[0, CRTL_TX_PASSIVE]), Some(BusProblem::BusOff));
        assert_eq!(classify(ERR_ACK | ERR_PROT, &[0; 8]), Some(BusProblem::NoAck));
        assert_eq!(
            classify(ERR_CRTL, &[0, CRTL_RX_PASSIVE, 0, 0, 0, 0, 0, 0]),
            Some(BusProblem::ErrorPassive)
        );
        assert_eq!(classify(ERR_CRTL, &[0, 0x04]), None, "a warning only");
        assert_eq!(classify(ERR_PROT, &[]), Some(BusProblem::BusError));
        assert_eq!(classify(0x0002, &[0; 8]), None, "lost arbitration is not asked for");
        assert!(BusProblem::NoAck.to_string().starts_with("no ACK: is another node on the bus"));
        assert!(BusProblem::BusOff.to_string().starts_with("bus-off"));
        assert!(BusProblem::ErrorPassive.to_string().starts_with("error-passive"));
        assert!(BusProblem::BusOff.is_fatal() && !BusProblem::NoAck.is_fatal());
    }
}
