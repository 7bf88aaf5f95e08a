//! The SLCAN codec on the examples its public descriptions give, on damaged
//! streams, and on arbitrary bytes and frames (proptest).

use proptest::prelude::*;

use super::*;

fn decode(bytes: &[u8]) -> Vec<SlcanEvent> {
    let mut d = SlcanDecoder::new();
    let mut events = Vec::new();
    d.feed(bytes, |e| events.push(e));
    events
}

fn data_frame(id: u32, extended: bool, data: &[u8], timestamp_ms: Option<u16>) -> SlcanEvent {
    SlcanEvent::Frame { frame: CanFrame::new(id, extended, data).unwrap(), remote: false, timestamp_ms }
}

fn line(frame: &CanFrame, remote: bool, timestamp_ms: Option<u16>) -> String {
    let mut out = Vec::new();
    encode_frame_line(frame, remote, timestamp_ms, &mut out);
    String::from_utf8(out).unwrap()
}

/// The examples of the Linux kernel's slcan driver
/// (torvalds/linux, drivers/net/can/slcan/slcan-core.c, "SLCAN ENCAPSULATION
/// FORMAT" and `SLC_MTU`), of the EasySYNC USB2-F-7x01 user guide (ES_000005,
/// sections 4.1.10 and 4.1.11) and of the esd CAN-USB-Micro manual (`t`).
#[test]
fn documented_frame_lines_decode_and_encode_back() {
    let cases = [
        ("t1230", data_frame(0x123, false, &[], None)),
        ("t4563112233", data_frame(0x456, false, &[0x11, 0x22, 0x33], None)),
        ("T12ABCDEF2AA55", data_frame(0x12AB_CDEF, true, &[0xAA, 0x55], None)),
        (
            "T1111222281122334455667788EA5F",
            data_frame(0x1111_2222, true, &[0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77, 0x88], Some(0xEA5F)),
        ),
        (
            "t34580123456789ABCDEF",
            data_frame(0x345, false, &[0x01, 0x23, 0x45, 0x67, 0x89, 0xAB, 0xCD, 0xEF], None),
        ),
        ("t4560", data_frame(0x456, false, &[], None)),
        (
            "T1234567880123456789ABCDEF",
            data_frame(0x1234_5678, true, &[1, 0x23, 0x45, 0x67, 0x89, 0xAB, 0xCD, 0xEF], None),
        ),
        ("t123499887766", data_frame(0x123, false, &[0x99, 0x88, 0x77, 0x66], None)),
    ];
    for (text, expected) in cases {
        assert_eq!(decode(format!("{text}\r").as_bytes()), vec![expected.clone()], "{text}");
        let SlcanEvent::Frame { frame, remote, timestamp_ms } = expected else { unreachable!() };
        assert_eq!(line(&frame, remote, timestamp_ms), format!("{text}\r"));
    }
    // "r1230: can_id 0x123, len 0, no data, remote transmission request" (kernel);
    // `riiiL[ssss]` (CanHacker protocol description).
    let remote = |len: usize, ts| SlcanEvent::Frame {
        frame: CanFrame::new(0x123, false, &[0; 8][..len]).unwrap(),
        remote: true,
        timestamp_ms: ts,
    };
    assert_eq!(
        decode(b"r1230\rr12381234\rR000001232\r"),
        vec![
            remote(0, None),
            remote(8, Some(0x1234)),
            SlcanEvent::Frame {
                frame: CanFrame::new(0x123, true, &[0, 0]).unwrap(),
                remote: true,
                timestamp_ms: None
            },
        ]
    );
    assert_eq!(line(&CanFrame::new(0x123, false, &[0; 8]).unwrap(), true, Some(0x1234)), "r12381234\r");
    // Lower-case hex is accepted (the kernel parses with hex_to_bin).
    assert_eq!(decode(b"t4563aabbcc\r"), vec![data_frame(0x456, false, &[0xAA, 0xBB, 0xCC], None)]);
}

#[test]
fn commands_encode_as_the_lawicel_set() {
    let text = |c: SlcanCommand| String::from_utf8(c.encode()).unwrap();
    assert_eq!(text(SlcanCommand::Close), "C\r");
    assert_eq!(text(SlcanCommand::Open), "O\r");
    assert_eq!(text(SlcanCommand::Bitrate(8)), "S8\r");
    assert_eq!(text(SlcanCommand::Timestamps(true)), "Z1\r");
    assert_eq!(text(SlcanCommand::Timestamps(false)), "Z0\r");
    assert_eq!(text(SlcanCommand::StatusFlags), "F\r");
    assert_eq!(text(SlcanCommand::Version), "V\r");
    assert_eq!(text(SlcanCommand::SerialNumber), "N\r");
    let start = CanFrame::standard(0x201, &[7, 0]).unwrap();
    assert_eq!(text(SlcanCommand::Transmit(start)), "t20120700\r");
    assert_eq!(SlcanCommand::Transmit(start).text(), "t20120700");
    assert_eq!(SlcanCommand::Bitrate(8).text(), "S8");
}

#[test]
fn bit_rates_map_to_their_codes() {
    assert_eq!(bitrate_code(1_000_000), Ok(8));
    assert_eq!(bitrate_code(800_000), Ok(7));
    assert_eq!(bitrate_code(500_000), Ok(6));
    assert_eq!(bitrate_code(10_000), Ok(0));
    for bad in [0, 750_000, 83_333, 2_000_000] {
        let e = bitrate_code(bad).unwrap_err();
        assert_eq!(e.bitrate, bad);
        assert!(e.to_string().contains("1000000"), "{e}");
    }
    let commands = SlcanConfig::default().setup_commands().unwrap();
    let texts: Vec<(String, bool)> = commands.iter().map(|(c, tolerated)| (c.text(), *tolerated)).collect();
    let expected = [("C", true), ("S8", false), ("Z1", false), ("O", false)];
    assert_eq!(texts, expected.map(|(t, b)| (t.to_string(), b)));
    let no_ts = SlcanConfig { timestamps: false, ..SlcanConfig::default() }.setup_commands().unwrap();
    assert_eq!((no_ts[2].0.text(), no_ts[2].1), ("Z0".to_string(), true));
    assert!(SlcanConfig { bitrate: 1, ..SlcanConfig::default() }.setup_commands().is_err());
}

/// Replies as Lawicel-style adapters give them: CR (OK), BEL (error), `z` / `Z`
/// after `t` / `T` (EasySYNC guide 4.1.10-11), `V`/`N`/`F` with values
/// (can-utils slcanpty.c answers `V1013`, `N4242`, `F00`).
#[test]
fn replies_interleave_with_frames() {
    let events = decode(b"\r\x07z\rZ\rV1013\rN4242\rF00\rt1230\r\rt4560EA5F\r");
    assert_eq!(
        events,
        vec![
            SlcanEvent::Ok,
            SlcanEvent::Error,
            SlcanEvent::TransmitAck { extended: false },
            SlcanEvent::TransmitAck { extended: true },
            SlcanEvent::Reply { line: "V1013".into() },
            SlcanEvent::Reply { line: "N4242".into() },
            SlcanEvent::Reply { line: "F00".into() },
            data_frame(0x123, false, &[], None),
            SlcanEvent::Ok,
            data_frame(0x456, false, &[], Some(59_999)),
        ]
    );
}

#[test]
fn malformed_lines_say_why_and_the_next_line_decodes() {
    use MalformedReason as M;
    let cases = [
        ("x1230", M::UnknownType),
        ("t12", M::WrongSize),
        ("t123", M::WrongSize),
        ("tG230", M::BadId),
        ("t8000", M::IdOutOfRange),
        ("T200000000", M::IdOutOfRange),
        ("t1239", M::BadLength),
        ("t123A", M::BadLength),
        ("t1232AA", M::WrongSize),
        ("t1231AA12", M::WrongSize),
        ("t1231ZZ", M::BadHex),
        ("t1230EA5G", M::BadHex),
        ("d1230", M::CanFd),
        ("zz", M::UnknownType),
    ];
    for (text, reason) in cases {
        let mut d = SlcanDecoder::new();
        let mut events = Vec::new();
        d.feed(format!("{text}\rt1230\r").as_bytes(), |e| events.push(e));
        assert_eq!(
            events,
            vec![
                SlcanEvent::Malformed { line: text.to_string(), reason },
                data_frame(0x123, false, &[], None),
            ]
        );
        let c = d.counters();
        assert_eq!((c.malformed, c.frames, c.bytes_skipped), (1, 1, text.len() as u64), "{text}");
    }
}

#[test]
fn a_bell_cuts_a_line_and_line_feeds_are_ignored() {
    let events = decode(b"t12\x07t1230\r\nt4560\r\n\n");
    assert_eq!(
        events,
        vec![
            SlcanEvent::Malformed { line: "t12".into(), reason: MalformedReason::CutByBell },
            SlcanEvent::Error,
            data_frame(0x123, false, &[], None),
            data_frame(0x456, false, &[], None),
        ]
    );
    let shown = decode(b"\x01\xFFt\r");
    assert_eq!(
        shown,
        vec![SlcanEvent::Malformed { line: "\\x01\\xfft".into(), reason: MalformedReason::UnknownType }]
    );
}

#[test]
fn an_overlong_line_is_dropped_without_growing_the_buffer() {
    let mut d = SlcanDecoder::new();
    let mut events = Vec::new();
    for _ in 0..100 {
        d.feed(&[b'A'; 100], |e| events.push(e));
        assert!(d.buffered() <= MAX_LINE);
    }
    d.feed(b"\x07t1230\r", |e| events.push(e));
    assert_eq!(events.len(), 3, "{events:?}");
    assert!(
        matches!(&events[0], SlcanEvent::Malformed { reason: MalformedReason::Overlong, line } if line.len() < 50)
    );
    assert_eq!(events[1..], [SlcanEvent::Error, data_frame(0x123, false, &[], None)]);
    let c = d.counters();
    assert_eq!((c.overlong, c.malformed, c.bytes_skipped, c.errors, c.frames), (1, 1, 10_000, 1, 1));
    // A version string longer than a frame line is still a reply.
    let long = format!("V{}", "x".repeat(100));
    assert_eq!(decode(format!("{long}\r").as_bytes()), vec![SlcanEvent::Reply { line: long }]);
}

#[test]
fn a_stream_decodes_whole_whatever_the_chunking() {
    let mut bytes = Vec::new();
    let mut expected = Vec::new();
    for k in 0..200u32 {
        let frame = CanFrame::new(0x710 + k % 16, k % 7 == 0, &k.to_be_bytes()[..(k % 5) as usize]).unwrap();
        let ts = (k % 3 != 0).then_some((k * 997 % 60_000) as u16);
        encode_frame_line(&frame, false, ts, &mut bytes);
        expected.push(SlcanEvent::Frame { frame, remote: false, timestamp_ms: ts });
        if k % 10 == 0 {
            bytes.extend_from_slice(b"z\r");
            expected.push(SlcanEvent::TransmitAck { extended: false });
        }
    }
    for chunk in [1, 2, 3, 7, 29, 30, 31, 4096] {
        let mut d = SlcanDecoder::new();
        let mut events = Vec::new();
        for piece in bytes.chunks(chunk) {
            d.feed(piece, |e| events.push(e));
        }
        assert_eq!(events, expected, "chunk {chunk}");
        assert_eq!(d.buffered(), 0);
        assert_eq!(d.counters().malformed, 0);
    }
}

#[test]
fn the_clock_unwraps_minutes() {
    let mut c = SlcanClock::new();
    let got: Vec<Option<u64>> =
        [59_990, 59_999, 5, 10, 30_000, 29_999].iter().map(|&t| c.unwrap(t)).collect();
    let expected = [59_990, 59_999, 60_005, 60_010, 90_000, 149_999];
    assert_eq!(got, expected.map(Some));
    assert_eq!(c.unwrap(60_000), None);
    assert_eq!(c.unwrap(0xFFFF), None);
    assert_eq!(c.rejected(), 2);
    assert_eq!(c.unwrap(0), Some(180_000), "the rejected values left the state as it was");
}

#[test]
fn the_host_clock_resolves_silences_of_minutes() {
    let mut c = SlcanClock::new();
    assert_eq!(c.unwrap_at(100, 5_000), Some(100));
    // 2 min 0.1 s later on the host, with 40 ms of USB latency either way.
    assert_eq!(c.unwrap_at(200, 125_140), Some(120_200));
    assert_eq!(c.unwrap_at(300, 125_200), Some(120_300));
    // A wrap within a second.
    assert_eq!(c.unwrap_at(100, 185_000), Some(180_100));
    // Without host times a silence is invisible.
    let mut c = SlcanClock::new();
    assert_eq!([c.unwrap(100), c.unwrap(200)], [Some(100), Some(200)]);
}

fn arb_frame() -> impl Strategy<Value = (CanFrame, bool, Option<u16>)> {
    (
        any::<bool>(),
        any::<u32>(),
        proptest::collection::vec(any::<u8>(), 0..=8),
        any::<bool>(),
        any::<Option<u16>>(),
    )
        .prop_map(|(extended, id, data, remote, ts)| {
            let id = if extended { id & 0x1FFF_FFFF } else { id & 0x7FF };
            let data = if remote { vec![0; data.len()] } else { data };
            (CanFrame::new(id, extended, &data).unwrap(), remote, ts.map(|t| t % TIMESTAMP_PERIOD_MS))
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(
        std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(256)
    ))]

    /// Arbitrary bytes in arbitrary pieces: no panic, bounded memory,
    /// counters consistent with the events.
    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..4096),
                                   chunk in 1usize..300) {
        let mut d = SlcanDecoder::new();
        let (mut frames, mut malformed) = (0u64, 0u64);
        for piece in bytes.chunks(chunk) {
            d.feed(piece, |e| match e {
                SlcanEvent::Frame { .. } => frames += 1,
                SlcanEvent::Malformed { .. } => malformed += 1,
                _ => {}
            });
            prop_assert!(d.buffered() <= MAX_LINE);
        }
        let c = d.counters();
        prop_assert_eq!((c.frames, c.malformed), (frames, malformed));
        prop_assert!(c.bytes_skipped + d.buffered() as u64 <= bytes.len() as u64);
    }

    /// Frames and replies encoded and decoded come back equal, whatever the chunking.
    #[test]
    fn encoded_frames_decode_back(frames in proptest::collection::vec(arb_frame(), 0..60),
                                  chunk in 1usize..100) {
        let mut bytes = Vec::new();
        let mut expected = Vec::new();
        for (i, (frame, remote, ts)) in frames.iter().enumerate() {
            encode_frame_line(frame, *remote, *ts, &mut bytes);
            expected.push(SlcanEvent::Frame { frame: *frame, remote: *remote, timestamp_ms: *ts });
            if i % 4 == 1 {
                bytes.extend_from_slice(&[CR, BEL]);
                expected.extend([SlcanEvent::Ok, SlcanEvent::Error]);
            }
        }
        let mut d = SlcanDecoder::new();
        let mut events = Vec::new();
        for piece in bytes.chunks(chunk) {
            d.feed(piece, |e| events.push(e));
        }
        prop_assert_eq!(events, expected);
        prop_assert_eq!(d.buffered(), 0);
    }

    /// Frames among garbage lines, cut lines and overlong junk: every intact
    /// frame comes out, in order, and nothing else is taken for a frame.
    #[test]
    fn damaged_streams_lose_only_the_damaged_lines(
        items in proptest::collection::vec((0u8..4, arb_frame(), proptest::collection::vec(any::<u8>(), 0..200)), 0..40),
        chunk in 1usize..100,
    ) {
        let mut bytes = Vec::new();
        let mut intact = Vec::new();
        let junk = |g: &[u8]| g.iter().map(|&b| if b == CR || b == BEL { b'#' } else { b }).collect::<Vec<u8>>();
        for (kind, (frame, remote, ts), garbage) in &items {
            let mut line = Vec::new();
            encode_frame_line(frame, *remote, *ts, &mut line);
            match kind {
                0 => intact.push((*frame, *remote, *ts)),
                1 => { // a garbage line before the frame
                    bytes.push(b'#');
                    bytes.extend(junk(garbage));
                    bytes.push(CR);
                    intact.push((*frame, *remote, *ts));
                }
                2 => { // cut short, then a BEL
                    line.truncate(garbage.len() % (line.len() - 1));
                    line.push(BEL);
                }
                _ => { // preceded by junk that makes the line overlong
                    let mut long = vec![b'#'; MAX_LINE];
                    long.extend(junk(garbage));
                    long.append(&mut line);
                    line = long;
                }
            }
            bytes.extend_from_slice(&line);
        }
        let mut d = SlcanDecoder::new();
        let mut frames = Vec::new();
        for piece in bytes.chunks(chunk) {
            d.feed(piece, |e| if let SlcanEvent::Frame { frame, remote, timestamp_ms } = e {
                frames.push((frame, remote, timestamp_ms));
            });
            prop_assert!(d.buffered() <= MAX_LINE);
        }
        prop_assert_eq!(frames, intact);
    }
}
