//! Arbitrary bytes as WebSocket messages of `xela_server` (one per line,
//! lossily made UTF-8) into one XELA decoder with an expectation: no panic,
//! counters consistent, and every decoded scan encodes back to itself.

#![no_main]

use libfuzzer_sys::fuzz_target;
use slidetrack_drivers::xela_ws::protocol::{
    Expected, ExpectedSensor, WireStyle, XelaDecoder, XelaEvent, encode_scan, parse_message,
};

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let expected = Expected { sensors: vec![ExpectedSensor { sensor: 1, model: "uSPa44".into(), taxels: 1 }] };
    let mut checked = XelaDecoder::new(Some(expected));
    let mut open = XelaDecoder::new(None);
    let mut messages = 0u64;
    for line in text.split('\n') {
        messages += 1;
        let _ = checked.decode(line);
        if let Ok(decoded) = open.decode(line)
            && let XelaEvent::Data(scan) = decoded.event
        {
            let again = parse_message(&encode_scan(&scan, WireStyle::HexAndInteger));
            assert_eq!(again, Ok(XelaEvent::Data(scan)));
        }
    }
    for c in [checked.counters(), open.counters()] {
        assert_eq!(c.messages, messages);
        assert_eq!(c.welcomes + c.scans + c.malformed + c.mismatches, c.messages);
        assert!(c.lost_messages >= c.gaps - c.repeats - c.backward);
    }
});
