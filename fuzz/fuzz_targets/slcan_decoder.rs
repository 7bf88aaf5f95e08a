//! Arbitrary bytes, pushed in pieces of arbitrary sizes, into the SLCAN
//! decoder: no panic, bounded buffer, counters consistent with the events,
//! and every frame it decodes encodes to a line that decodes to it again.

#![no_main]

use libfuzzer_sys::fuzz_target;
use slidetrack_drivers::slcan::protocol::{MAX_LINE, SlcanDecoder, SlcanEvent, encode_frame_line};

fuzz_target!(|data: &[u8]| {
    let Some((&chunk, bytes)) = data.split_first() else { return };
    let chunk = usize::from(chunk).max(1);
    let mut decoder = SlcanDecoder::new();
    let mut frames = Vec::new();
    let mut malformed = 0u64;
    for piece in bytes.chunks(chunk) {
        decoder.feed(piece, |event| match event {
            SlcanEvent::Frame { frame, remote, timestamp_ms } => frames.push((frame, remote, timestamp_ms)),
            SlcanEvent::Malformed { .. } => malformed += 1,
            _ => {}
        });
        assert!(decoder.buffered() <= MAX_LINE);
    }
    let c = decoder.counters();
    assert_eq!((c.frames, c.malformed), (frames.len() as u64, malformed));
    assert!(c.bytes_skipped + decoder.buffered() as u64 <= bytes.len() as u64);
    for (frame, remote, timestamp_ms) in frames {
        let mut line = Vec::new();
        encode_frame_line(&frame, remote, timestamp_ms, &mut line);
        let mut again = Vec::new();
        SlcanDecoder::new().feed(&line, |e| again.push(e));
        assert_eq!(again, [SlcanEvent::Frame { frame, remote, timestamp_ms }]);
    }
});
