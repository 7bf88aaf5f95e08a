//! Throughput of the serial tactile decoder (frames + scan assembly) against
//! the target: 100x the byte rate of three 16-taxel uSkin modules at 1 kHz.
//!
//! `taskset -c 0 cargo bench -p slidetrack-drivers --bench serial_decoder`:
//! the decoder runs on one thread; `taskset` pins the process to one core
//! (the report line names the CPUs it was allowed). It prints the median
//! byte rate and its ratio to the target, then criterion's statistics.

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, Throughput, criterion_group};
use slidetrack_drivers::serial::protocol::{ModuleFrame, SerialDecoder, SerialEvent, frame_len};
use slidetrack_drivers::serial::scan::ModuleScanAssembler;

const MODULES: u8 = 3;
const TAXELS: usize = 16;
const SCAN_RATE_HZ: f64 = 1000.0;
/// One second of the three modules' stream at 1 kHz.
const SCANS: u16 = 1000;

/// Bytes per second the decoder must sustain: 100x three modules at 1 kHz.
fn target_bytes_per_s() -> f64 {
    100.0 * f64::from(MODULES) * SCAN_RATE_HZ * frame_len(TAXELS) as f64
}

/// One second of stream; every `garbage_every`-th frame is preceded by junk.
fn stream(garbage_every: usize) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut n = 0;
    for s in 0..SCANS {
        for m in 0..MODULES {
            n += 1;
            if garbage_every > 0 && n % garbage_every == 0 {
                bytes.extend_from_slice(&[0x00, 0xA5, 0x13, 0x37, 0xA5, 0x5A, 0xFF]);
            }
            let taxels: Vec<[u16; 3]> =
                (0..TAXELS).map(|t| [30_000 + s, 20_000 + t as u16, 40_000 - s]).collect();
            ModuleFrame::new(m, s, &taxels).expect("16 taxels fit").encode_into(&mut bytes);
        }
    }
    bytes
}

/// Decodes `bytes` in 4 KiB reads, as the serial backend does; returns the scans assembled.
fn decode(bytes: &[u8]) -> u64 {
    let mut decoder = SerialDecoder::new();
    let mut assembler = ModuleScanAssembler::new(&[(0, 16), (1, 16), (2, 16)]);
    let mut scans = 0u64;
    for chunk in bytes.chunks(4096) {
        decoder.feed(chunk, |event| {
            if let SerialEvent::Frame(frame) = event
                && assembler.push(&frame).is_some()
            {
                scans += 1;
            }
        });
    }
    scans
}

fn bench(c: &mut Criterion) {
    for (name, garbage_every) in [("clean", 0), ("garbage every 100 frames", 100)] {
        let bytes = stream(garbage_every);
        let mut group = c.benchmark_group("serial decoder");
        group.throughput(Throughput::Bytes(bytes.len() as u64));
        group.bench_function(name, |b| b.iter(|| decode(black_box(&bytes))));
        group.finish();
    }
}

/// The CPUs this process may run on (`Cpus_allowed_list` of
/// `/proc/self/status`), to show that the figure is a one-core figure.
fn allowed_cpus() -> String {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines().find_map(|l| l.strip_prefix("Cpus_allowed_list:").map(|v| v.trim().to_string()))
        })
        .unwrap_or_else(|| "unknown".into())
}

/// A direct measurement with the comparison to the target, printed once:
/// the median (and the slowest decile) of `SAMPLES` timings of one second
/// of stream, decoded on the calling thread (one core).
fn report() {
    const SAMPLES: usize = 101;
    let bytes = stream(0);
    assert_eq!(decode(&bytes), u64::from(SCANS), "every scan decodes");
    for _ in 0..10 {
        black_box(decode(black_box(&bytes))); // warm-up
    }
    let mut rates: Vec<f64> = (0..SAMPLES)
        .map(|_| {
            let start = Instant::now();
            black_box(decode(black_box(&bytes)));
            bytes.len() as f64 / start.elapsed().as_secs_f64()
        })
        .collect();
    rates.sort_by(f64::total_cmp);
    let median = rates[SAMPLES / 2];
    let p10 = rates[SAMPLES / 10];
    let target = target_bytes_per_s();
    println!(
        "serial decoder (one thread, CPUs allowed: {}): median {:.1} MB/s over {SAMPLES} runs \
         (slowest decile {:.1} MB/s); target 100 x 3 modules x 1 kHz x {} B = {:.1} MB/s; \
         median ratio {:.1} ({})",
        allowed_cpus(),
        median / 1e6,
        p10 / 1e6,
        frame_len(TAXELS),
        target / 1e6,
        median / target,
        if median >= target { "meets the target" } else { "BELOW the target" }
    );
}

criterion_group!(benches, bench);

fn main() {
    report();
    benches();
    Criterion::default().configure_from_args().final_summary();
}
