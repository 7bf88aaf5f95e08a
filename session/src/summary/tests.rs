//! The summary fast path: taken for finished sessions, left for the scan
//! whenever the summary lacks something, and never handed a record that
//! would make mcap's summary reader panic.

use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::Path;

use mcap::records::{MessageHeader, op};

use super::indexed::from_summary;
use super::*;
use crate::error::Corruption;
use crate::tests::{EveryChannel, TestDir, record_every_channel};
use crate::{RecorderOptions, SessionError};

/// What a scan of `bytes` (complete, with recover off) makes of them.
fn scanned(bytes: &[u8]) -> SessionInfo {
    scan_info(Path::new("mem.mcap"), Cursor::new(bytes), bytes.len() as u64, true, ReadOptions::default())
        .unwrap()
}

/// The fast path's answer for `bytes`.
fn indexed(bytes: &[u8]) -> Result<Option<SessionInfo>, SessionError> {
    let mut input = Cursor::new(bytes);
    let size = bytes.len() as u64;
    let start = crate::scan::footer_summary_start(&mut input, size).unwrap().unwrap();
    from_summary(Path::new("mem.mcap"), &mut input, size, start)
}

/// A file written by the `mcap` writer with `options`: several chunks on two
/// channels, a metadata record and an attachment.
fn written_with(options: mcap::WriteOptions) -> Vec<u8> {
    let options = options.compression(Some(mcap::Compression::Zstd)).chunk_size(Some(256));
    let mut w = options.create(Cursor::new(Vec::new())).unwrap();
    let schema = w.add_schema("s", "jsonschema", b"{}").unwrap();
    let a = w.add_channel(schema, "/a", "json", &BTreeMap::new()).unwrap();
    let b = w.add_channel(schema, "/b", "json", &BTreeMap::from([("k".into(), "v".into())])).unwrap();
    for i in 0..40u64 {
        let channel_id = if i % 3 == 0 { b } else { a };
        let header =
            MessageHeader { channel_id, sequence: i as u32, log_time: i * 1000, publish_time: i * 1000 };
        w.write_to_known_channel(&header, format!("{{\"i\":{i}}}").as_bytes()).unwrap();
    }
    let metadata = BTreeMap::from([("rig".to_string(), "sim".to_string())]);
    w.write_metadata(&mcap::records::Metadata { name: "slidetrack".into(), metadata }).unwrap();
    let data = std::borrow::Cow::Borrowed(&b"fx = 1\n"[..]);
    let attachment = mcap::Attachment {
        log_time: 0,
        create_time: 0,
        name: "c.toml".into(),
        media_type: "text".into(),
        data,
    };
    w.attach(&attachment).unwrap();
    w.finish().unwrap();
    w.into_inner().into_inner()
}

#[test]
fn a_finished_session_is_read_from_its_summary_and_matches_a_scan() {
    let dir = TestDir::new("summary-fast");
    let path = dir.file("s.mcap");
    record_every_channel(&path, &EveryChannel::new(50), RecorderOptions::default());
    let bytes = std::fs::read(&path).unwrap();
    let fast = indexed(&bytes).unwrap().expect("the summary has all it takes");
    assert_eq!(fast, scanned(&bytes));
    assert_eq!(fast.metadata.len(), 2);
    assert_eq!(fast.attachments.len(), 1);

    let complete = written_with(mcap::WriteOptions::new());
    assert_eq!(indexed(&complete).unwrap().unwrap(), scanned(&complete));
}

#[test]
fn a_summary_that_lacks_something_is_left_for_the_scan() {
    type Lacking = fn(mcap::WriteOptions) -> mcap::WriteOptions;
    let lacking: [(&str, Lacking); 6] = [
        ("message indexes", |o| o.emit_message_indexes(false)),
        ("statistics", |o| o.emit_statistics(false)),
        ("channels", |o| o.repeat_channels(false)),
        ("chunk indexes", |o| o.emit_chunk_indexes(false)),
        ("metadata indexes", |o| o.emit_metadata_indexes(false)),
        ("attachment indexes", |o| o.emit_attachment_indexes(false)),
    ];
    for (what, options) in lacking {
        let bytes = written_with(options(mcap::WriteOptions::new()));
        assert!(indexed(&bytes).unwrap().is_none(), "without {what}: the summary must not be used");
        let info = SessionInfo::from_reader("mem.mcap", Cursor::new(&bytes), ReadOptions::default()).unwrap();
        assert_eq!(info, scanned(&bytes), "without {what}");
        assert_eq!((info.message_count, info.channels.len()), (40, 2), "without {what}");
        assert_eq!((info.metadata.len(), info.attachments.len()), (1, 1), "without {what}");
    }
}

/// A malformed attachment record (its lengths claim more than it holds).
fn bad_attachment() -> Vec<u8> {
    let mut body = vec![0u8; 16]; // log and create time
    body.extend(1u32.to_le_bytes());
    body.push(b'x'); // name
    body.extend(0u32.to_le_bytes()); // media type
    body.extend(1000u64.to_le_bytes()); // data length, but no data and no CRC
    let mut record = vec![op::ATTACHMENT];
    record.extend((body.len() as u64).to_le_bytes());
    record.extend(body);
    record
}

#[test]
fn a_summary_holding_an_attachment_is_refused_before_mcap_parses_it() {
    // mcap's record parser, which its summary reader calls on every record,
    // panics on this record.
    let record = bad_attachment();
    let parsed = std::panic::catch_unwind(|| mcap::parse_record(op::ATTACHMENT, &record[9..]).is_ok());
    assert!(parsed.is_err(), "mcap's parser panics on a malformed attachment");

    // The record first in the summary section: the footer still points at it.
    let good = written_with(mcap::WriteOptions::new());
    let mut input = Cursor::new(&good[..]);
    let start = crate::scan::footer_summary_start(&mut input, good.len() as u64).unwrap().unwrap() as usize;
    let bytes: Vec<u8> = [&good[..start], &record[..], &good[start..]].concat();
    let err = indexed(&bytes).unwrap_err();
    assert!(
        matches!(
            err,
            SessionError::Corrupt { source: Corruption::SummaryRecord { opcode: op::ATTACHMENT }, .. }
        ),
        "{err:?}"
    );
    let strict = SessionInfo::from_reader("mem.mcap", Cursor::new(&bytes), ReadOptions::default());
    assert!(matches!(strict, Err(SessionError::Corrupt { .. })), "{strict:?}");
    // With recover, the scan reads the whole data section, and stops at the
    // stray record after it.
    let recovered =
        SessionInfo::from_reader("mem.mcap", Cursor::new(&bytes), ReadOptions::recover()).unwrap();
    let expected = scanned(&good);
    assert_eq!(recovered.channels, expected.channels);
    assert_eq!((recovered.metadata, recovered.attachments), (expected.metadata, expected.attachments));
    assert_eq!(recovered.message_count, 40);
}
