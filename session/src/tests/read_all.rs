//! Corrupted real sessions, read from memory every way the fuzz target
//! `fuzz/fuzz_targets/session_reader.rs` reads its input (both call the same
//! `read_all`): no panic, and what is recovered is what was written.

use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::other_channels::log_other_channels;
use super::*;

use super::read_all_body::read_all;

/// A message as compared: topic, log time, sequence and payload.
type Key = (String, TimeNs, u32, Vec<u8>);

fn key(m: &RawMessage) -> Key {
    (m.topic().to_string(), m.log_time, m.sequence, m.data.clone())
}

/// A finished session on every channel, in many small chunks.
fn session_bytes(dir: &TestDir) -> Vec<u8> {
    let path = dir.file("fuzzed.mcap");
    let options = RecorderOptions { chunk_size_bytes: 2 << 10, ..RecorderOptions::default() };
    record_every_channel_and(&path, &EveryChannel::new(20), options, log_other_channels);
    std::fs::read(&path).unwrap()
}

/// `bytes` corrupted in one of several ways, chosen by `rng`.
fn corrupt(bytes: &[u8], rng: &mut ChaCha8Rng) -> Vec<u8> {
    let mut b = bytes.to_vec();
    match rng.random_range(0..6) {
        // A few bytes changed.
        0 => {
            for _ in 0..rng.random_range(1..8) {
                let at = rng.random_range(0..b.len());
                b[at] ^= rng.random_range(1..=255u8);
            }
        }
        // Cut short.
        1 => b.truncate(rng.random_range(0..b.len())),
        // Cut short and continued with garbage.
        2 => {
            b.truncate(rng.random_range(0..b.len()));
            let mut tail = vec![0u8; rng.random_range(1..512)];
            rng.fill_bytes(&mut tail);
            b.extend(tail);
        }
        // A range zeroed.
        3 => {
            let start = rng.random_range(0..b.len());
            let end = (start + rng.random_range(1..256)).min(b.len());
            b[start..end].fill(0);
        }
        // A huge record length after the header.
        4 => {
            let at = rng.random_range(8..b.len().min(64));
            let opcode = rng.random_range(1..=0x0Fu8);
            b.splice(at..at, [opcode, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x7F]);
        }
        // Garbage behind the magic.
        _ => {
            let mut g = vec![0u8; rng.random_range(0..2048)];
            rng.fill_bytes(&mut g);
            b = mcap::MAGIC.iter().copied().chain(g).collect();
        }
    }
    b
}

#[test]
fn corrupted_sessions_read_from_memory_never_panic_and_recover_only_what_was_written() {
    let dir = TestDir::new("read-all");
    let bytes = session_bytes(&dir);
    let intact = read_all(&bytes);
    let written: Vec<Key> = intact.messages.iter().map(key).collect();
    assert_eq!(written.len() as u64, EveryChannel::new(20).message_count() + 2 * 31 + 1);
    let info = intact.info.unwrap();
    assert_eq!((info.message_count, info.truncated), (written.len() as u64, false));
    assert_eq!(intact.channels.len(), channel_specs().len());

    let started = std::time::Instant::now();
    let mut rng = ChaCha8Rng::seed_from_u64(0x5e55_1011);
    for round in 0..150 {
        let b = corrupt(&bytes, &mut rng);
        let got = read_all(&b);
        // Recovered messages come from complete, CRC-checked chunks: the
        // ones written, in order, with gaps at most.
        let mut rest = written.iter();
        for m in &got.messages {
            let k = key(m);
            assert!(rest.any(|w| *w == k), "round {round}: {:?} at {} altered or out of order", k.0, k.1);
        }
        if let Some(info) = got.info.filter(|i| i.truncated) {
            assert_eq!(info.message_count, got.messages.len() as u64, "round {round}");
        }
        let declared = |m: &RawMessage| got.channels.iter().any(|c| c.id == m.channel.id);
        assert!(got.messages.iter().all(declared), "round {round}: a message on an undeclared channel");
    }
    eprintln!("150 corrupted sessions read every way in {:?}", started.elapsed());
}
