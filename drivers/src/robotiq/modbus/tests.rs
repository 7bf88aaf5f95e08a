//! The codec on the frames the public sources document, and on corrupted
//! and arbitrary bytes (proptest, fixed seed).
//!
//! Fixtures: `howardjchen/robotiq_850`, README.md, "Modbus RTU command"
//! (the Robotiq 2F-85 manual's examples, sec. 4.8): activation request and
//! its echo, status reads while activating and once active, close and open
//! requests, status reads while closing and opening. The set-`rACT` request
//! (`... 06 01 00 ... 72 E1`) is the manual's second activation step; its
//! CRC is checked here against the codec rather than copied.

use proptest::prelude::*;

use super::*;
use crate::robotiq::registers::{RobotiqRequest, RobotiqStatus, STATUS_ADDRESS};

fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace().map(|b| u8::from_str_radix(b, 16).expect("hex byte")).collect()
}

fn status_read(count: u16) -> Request {
    Request::ReadHolding { address: STATUS_ADDRESS, count }
}

fn write(request: RobotiqRequest) -> Request {
    Request::WriteMultiple { address: 0x03E8, values: request.to_registers().to_vec() }
}

#[test]
fn requests_encode_to_the_documented_bytes() {
    assert_eq!(write(RobotiqRequest::reset()).encode(9), hex("09 10 03 E8 00 03 06 00 00 00 00 00 00 73 30"));
    assert_eq!(
        write(RobotiqRequest::activate()).encode(9),
        hex("09 10 03 E8 00 03 06 01 00 00 00 00 00 72 E1")
    );
    assert_eq!(status_read(1).encode(9), hex("09 03 07 D0 00 01 85 CF"));
    assert_eq!(status_read(3).encode(9), hex("09 03 07 D0 00 03 04 0E"));
    let full = |position| RobotiqRequest {
        go_to: true,
        position,
        speed: 255,
        force: 255,
        ..RobotiqRequest::activate()
    };
    assert_eq!(write(full(255)).encode(9), hex("09 10 03 E8 00 03 06 09 00 00 FF FF FF 42 29"));
    assert_eq!(write(full(0)).encode(9), hex("09 10 03 E8 00 03 06 09 00 00 00 FF FF 72 19"));
    // Requests decode back (the emulator's side).
    let bytes = hex("09 10 03 E8 00 03 06 09 00 00 FF FF FF 42 29");
    assert_eq!(Request::decode(&bytes).unwrap(), (9, write(full(255))));
    assert_eq!(request_len(&bytes[..7]), Ok(Some(15)));
}

#[test]
fn documented_responses_decode_to_the_documented_status() {
    let echo = Response::decode(&hex("09 10 03 E8 00 03 01 30"), 9, &write(RobotiqRequest::reset())).unwrap();
    assert_eq!(echo, Response::WroteMultiple { address: 0x03E8, count: 3 });
    let one = |s: &str| match Response::decode(&hex(s), 9, &status_read(1)).unwrap() {
        Response::Registers(r) => RobotiqStatus::from_registers([r[0], 0, 0]),
        other => panic!("not registers: {other:?}"),
    };
    assert!(!one("09 03 02 11 00 55 D5").is_active(), "activation not completed");
    assert!(one("09 03 02 31 00 4C 15").is_active(), "activation completed");
    let three = |s: &str| match Response::decode(&hex(s), 9, &status_read(3)).unwrap() {
        Response::Registers(r) => RobotiqStatus::from_registers([r[0], r[1], r[2]]).gripper_status(),
        other => panic!("not registers: {other:?}"),
    };
    use slidetrack_core::GripperObject::*;
    let closing = three("09 03 06 39 00 00 FF 0E 0A F7 8B");
    assert_eq!(
        (closing.object, closing.requested_steps, closing.position_steps, closing.current_ma),
        (Moving, 255, 14, 100)
    );
    let closed = three("09 03 06 B9 00 00 FF BD 00 1D 7C");
    assert_eq!((closed.object, closed.position_steps, closed.fault), (ContactClosing, 189, 0));
    let opening = three("09 03 06 39 00 00 00 BB 10 30 E0");
    assert_eq!(
        (opening.object, opening.requested_steps, opening.position_steps, opening.current_ma),
        (Moving, 0, 187, 160)
    );
    let open = three("09 03 06 F9 00 00 00 0D 00 56 4C");
    assert_eq!((open.object, open.position_steps, open.activated), (AtRequest, 13, true));
}

#[test]
fn fc23_and_exceptions_round_trip() {
    let request = Request::ReadWriteMultiple {
        read_address: STATUS_ADDRESS,
        read_count: 3,
        write_address: 0x03E8,
        values: vec![0x0900, 0x00FF, 0xFFFF],
    };
    let bytes = request.encode(9);
    assert_eq!(bytes.len(), 19);
    assert_eq!(&bytes[..11], &hex("09 17 07 D0 00 03 03 E8 00 03 06")[..]);
    assert_eq!(Request::decode(&bytes).unwrap(), (9, request.clone()));
    assert_eq!(request_len(&bytes[..11]), Ok(Some(19)));
    let response = Response::Registers(vec![0x3900, 0x00FF, 0x0E0A]).encode(9, 0x17);
    assert_eq!(response_len(&response[..2], &request), Some(response.len()));
    assert!(matches!(Response::decode(&response, 9, &request), Ok(Response::Registers(_))));
    let refused =
        Response::Exception { function: 0x17, code: exception::ILLEGAL_DATA_ADDRESS }.encode(9, 0x17);
    assert_eq!(refused[1], 0x97);
    assert_eq!(response_len(&refused[..2], &request), Some(5));
    assert_eq!(Response::decode(&refused, 9, &request), Ok(Response::Exception { function: 0x17, code: 2 }));
    let single = Request::WriteSingle { address: 0x03E9, value: 0x0080 };
    let echo = Response::WroteSingle { address: 0x03E9, value: 0x0080 }.encode(9, 6);
    assert_eq!(echo, single.encode(9), "FC6 echoes the request");
    assert_eq!(request_len(&[9, 0x2B]), Err(0x2B));
}

#[test]
fn corrupted_responses_are_errors_with_the_fault_named() {
    let request = status_read(3);
    let good = hex("09 03 06 39 00 00 FF 0E 0A F7 8B");
    let mut bad_crc = good.clone();
    bad_crc[5] ^= 0x10;
    assert!(matches!(Response::decode(&bad_crc, 9, &request), Err(FrameError::BadCrc { .. })));
    assert_eq!(
        Response::decode(&good[..4], 9, &request),
        Err(FrameError::BadCrc { expected: crc16(&good[..2]), got: 0x3906 })
    );
    assert_eq!(Response::decode(&good[..3], 9, &request), Err(FrameError::Short { len: 3 }));
    let other = Response::Registers(vec![0x3900, 0x00FF, 0x0E0A]).encode(8, 3);
    assert_eq!(Response::decode(&other, 9, &request), Err(FrameError::WrongDevice { expected: 9, got: 8 }));
    let two = Response::Registers(vec![0x3900, 0x00FF]).encode(9, 3);
    assert!(matches!(Response::decode(&two, 9, &request), Err(FrameError::BadLength { .. })));
    let write_echo = Response::WroteMultiple { address: 0x03E8, count: 3 }.encode(9, 0x10);
    assert_eq!(
        Response::decode(&write_echo, 9, &request),
        Err(FrameError::WrongFunction { expected: 3, got: 0x10 })
    );
}

/// A response frame the client accepted must be one the server could
/// have sent: right id, right function, CRC valid, length as requested.
fn accepted_frames_are_well_formed(bytes: &[u8], request: &Request) -> Result<(), TestCaseError> {
    if let Ok(response) = Response::decode(bytes, 9, request) {
        prop_assert_eq!(bytes[0], 9);
        prop_assert_eq!(
            crc16(&bytes[..bytes.len() - 2]).to_le_bytes(),
            [bytes[bytes.len() - 2], bytes[bytes.len() - 1]]
        );
        let function = match &response {
            Response::Exception { .. } => request.function() | function::EXCEPTION_BIT,
            _ => request.function(),
        };
        prop_assert_eq!(response.encode(9, request.function()), bytes.to_vec());
        prop_assert_eq!(bytes[1], function);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(512),
        rng_seed: proptest::test_runner::RngSeed::Fixed(7),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Arbitrary bytes: no panic on either side, and nothing malformed is
    /// ever accepted as a response.
    #[test]
    fn arbitrary_bytes_never_panic_nor_pass(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
        let _ = Request::decode(&bytes);
        let _ = request_len(&bytes);
        let requests = [
            status_read(3),
            write(RobotiqRequest::reset()),
            Request::WriteSingle { address: 0x03E8, value: 0x0100 },
            Request::ReadWriteMultiple { read_address: STATUS_ADDRESS, read_count: 3, write_address: 0x03E8, values: vec![0; 3] },
        ];
        for request in &requests {
            let _ = response_len(&bytes, request);
            accepted_frames_are_well_formed(&bytes, request)?;
        }
    }

    /// A status response damaged by a bit flip, a cut, another id, or extra
    /// bytes is rejected: the driver never sees its registers.
    #[test]
    fn damaged_status_responses_are_rejected(kind in 0u8..4, at in 0usize..64, byte in 1u8..=255) {
        let request = status_read(3);
        let good = Response::Registers(vec![0x3900, u16::from(byte), 0x0E0A]).encode(9, 3);
        let mut bad = good.clone();
        match kind {
            0 => bad[at % good.len()] ^= byte,
            1 => bad.truncate(at % good.len()),
            2 => bad[0] = if byte == 9 { 10 } else { byte },
            _ => bad.extend(std::iter::repeat_n(byte, at % 8 + 1)),
        }
        prop_assert!(Response::decode(&bad, 9, &request).is_err(), "accepted {:02x?}", bad);
        prop_assert!(Response::decode(&good, 9, &request).is_ok());
    }
}
