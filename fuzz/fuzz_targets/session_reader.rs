//! Arbitrary bytes read as a session every way the session readers offer
//! (every message, `SessionInfo`, CSV export of every channel; strictly and
//! with recover), from memory: no panic, whatever the bytes.
//!
//! The reading itself is `read_all`, a module shared with the session crate's
//! bounded in-repo test of corrupted real sessions
//! (`session/src/tests/read_all.rs`).

#![no_main]

use libfuzzer_sys::fuzz_target;
use slidetrack_session as session;

#[path = "../../session/src/tests/read_all_body.rs"]
mod read_all_body;

fuzz_target!(|data: &[u8]| {
    let recovered = read_all_body::read_all(data);
    // Every recovered message is on a declared channel.
    assert!(recovered.messages.iter().all(|m| recovered.channels.iter().any(|c| c.id == m.channel.id)));
    // A scan that stopped early counts exactly the messages the reader
    // recovered: both read the same complete chunks.
    if let Some(info) = recovered.info.filter(|i| i.truncated) {
        assert_eq!(info.message_count, recovered.messages.len() as u64);
    }
});
