//! Reads any bytes as a session every way the session readers offer.
//!
//! This module is shared: the fuzz target `fuzz/fuzz_targets/session_reader.rs`
//! and the session crate's tests (`tests/mod.rs`, for `tests/read_all.rs`) both
//! declare it, so that the bounded in-repo test and the fuzzer exercise the
//! same path. Its parent module names the session crate `session`.

use std::io::Cursor;

use super::session::{
    ChannelDesc, MessageReader, RawMessage, ReadOptions, SessionInfo, export_csv_from_reader,
};

/// What [`read_all`] read with `ReadOptions::recover()`.
pub struct Recovered {
    /// The messages read, on every topic.
    pub messages: Vec<RawMessage>,
    /// The channels declared (as last declared, when declared again).
    pub channels: Vec<ChannelDesc>,
    /// What `SessionInfo::from_reader` made of the bytes, if it succeeded.
    pub info: Option<SessionInfo>,
}

/// Reads `data` as a session, strictly and with `recover`: opens it and reads
/// every message, reads its `SessionInfo`, and exports (at most 16 of) the
/// channels it declares to CSV and reads each of them alone. Must never
/// panic, whatever `data` holds. Returns what was read with `recover`.
pub fn read_all(data: &[u8]) -> Recovered {
    let name = "input.mcap";
    let mut recovered = Recovered { messages: Vec::new(), channels: Vec::new(), info: None };
    for options in [ReadOptions::default(), ReadOptions::recover()] {
        let info = SessionInfo::from_reader(name, Cursor::new(data), options);
        let (mut messages, mut channels) = (Vec::new(), Vec::new());
        if let Ok(mut reader) = MessageReader::from_reader(name, Cursor::new(data), &[], options) {
            messages = reader.by_ref().filter_map(Result::ok).collect();
            channels = reader.channels().cloned().collect::<Vec<_>>();
        }
        for topic in channels.iter().take(16).map(|c| c.topic.as_str()) {
            let _ = export_csv_from_reader(name, Cursor::new(data), topic, options, std::io::sink());
            if let Ok(reader) = MessageReader::from_reader(name, Cursor::new(data), &[topic], options) {
                reader.for_each(drop);
            }
        }
        if options.recover {
            recovered = Recovered { messages, channels, info: info.ok() };
        }
    }
    recovered
}
