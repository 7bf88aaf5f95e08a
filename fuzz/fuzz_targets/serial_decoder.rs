//! Arbitrary bytes, pushed in pieces of arbitrary sizes, into the serial
//! decoder and the scan assembler: no panic, bounded buffer, consistent counters.

#![no_main]

use libfuzzer_sys::fuzz_target;
use slidetrack_drivers::serial::scan::ModuleScanAssembler;
use slidetrack_drivers::sensors::{default_sensors, module_taxels};
use slidetrack_drivers::serial::protocol::{DECODER_CAPACITY, SerialDecoder, SerialEvent};

fuzz_target!(|data: &[u8]| {
    let Some((&chunk, bytes)) = data.split_first() else { return };
    let chunk = usize::from(chunk).max(1);
    let mut decoder = SerialDecoder::new();
    let mut assembler = ModuleScanAssembler::new(&module_taxels(&default_sensors(4, 4)));
    let mut frames = 0u64;
    for piece in bytes.chunks(chunk) {
        decoder.feed(piece, |event| {
            if let SerialEvent::Frame(frame) = event {
                frames += 1;
                assembler.push(&frame);
            }
        });
        assert!(decoder.buffered() <= DECODER_CAPACITY);
    }
    // The end of the stream: whatever a cut frame was hiding comes out.
    decoder.finish();
    while let Some(event) = decoder.next_event() {
        if let SerialEvent::Frame(frame) = event {
            frames += 1;
            assembler.push(&frame);
        }
    }
    let c = decoder.counters();
    assert_eq!(c.frames, frames);
    assert!(c.bytes_skipped + decoder.buffered() as u64 <= bytes.len() as u64);
});
