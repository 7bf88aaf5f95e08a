//! Errors keep their facts in fields and their cause as the source: each
//! message names what failed and where without repeating the cause, and the
//! chain joined by ": " reads as one line.

use std::collections::BTreeMap;
use std::error::Error;
use std::io::Cursor;

use crate::error::{Corruption, WriteFailure, error_chain};

use super::*;

/// Checks the shape of `e`: the path in its message, one line, a message that
/// does not repeat its cause. Returns the chain as one line.
fn one_line(e: &SessionError, path: &str) -> String {
    let line = error_chain(e);
    assert!(!line.contains('\n'), "{line}");
    assert!(e.to_string().contains(path), "{e} names {path}");
    let mut cause = e.source();
    let mut message = e.to_string();
    while let Some(c) = cause {
        assert!(!message.contains(&c.to_string()), "{message:?} repeats its cause {c:?}");
        message = c.to_string();
        cause = c.source();
    }
    line
}

#[test]
fn reading_errors_name_the_file_and_chain_their_cause() {
    let dir = TestDir::new("errors-read");
    let o = ReadOptions::default();
    let missing = dir.file("x.mcap");
    let e = SessionInfo::read(&missing, o).unwrap_err();
    assert_eq!(one_line(&e, "x.mcap"), format!("session file {} does not exist", missing.display()));

    let e = SessionInfo::read(dir.path(), o).unwrap_err();
    let line = one_line(&e, &dir.path().display().to_string());
    assert_eq!(line, format!("cannot read session file {}: is a directory", dir.path().display()));
    assert!(e.source().unwrap().downcast_ref::<std::io::Error>().is_some());

    // A flipped byte in the compressed data of a chunk.
    let path = dir.file("s.mcap");
    record_every_channel(&path, &EveryChannel::new(40), RecorderOptions::default());
    let mut bytes = std::fs::read(&path).unwrap();
    let first_chunk = bytes.windows(4).position(|w| w == b"zstd").unwrap();
    bytes[first_chunk + 40] ^= 0x55;
    let e = MessageReader::from_reader("flipped.mcap", Cursor::new(&bytes), &[], o)
        .unwrap()
        .find_map(Result::err)
        .unwrap();
    let SessionError::Corrupt { bytes_read, source: Corruption::Chunk(mcap_error), .. } = &e else {
        panic!("{e:?}");
    };
    assert!(*bytes_read > first_chunk as u64 && *bytes_read <= bytes.len() as u64);
    let line = one_line(&e, "flipped.mcap");
    let expected =
        format!("flipped.mcap is corrupt (after reading {bytes_read} bytes): a chunk does not decode: ");
    assert!(line.starts_with(&expected) && line.ends_with(&mcap_error.to_string()), "{line}");

    let e = read_json::<ProtocolEvent>(&path, TactileRaw::TOPIC, o).unwrap_err();
    let SessionError::Decode { topic, log_time, .. } = &e else { panic!("{e:?}") };
    assert_eq!((topic.as_str(), *log_time), (TactileRaw::TOPIC, TimeNs::ZERO));
    let line = one_line(&e, "s.mcap");
    assert!(
        line.contains("message on /tactile/raw at ") && line.contains("does not decode: missing field"),
        "{line}"
    );

    let e = export_csv(&path, CompressedImage::TOPIC, o, std::io::sink()).unwrap_err();
    assert!(matches!(e, SessionError::NotTabular { .. }), "{e}");
    one_line(&e, "s.mcap");
    let e = export_csv(&path, TactileRaw::TOPIC, o, Failing).unwrap_err();
    assert_eq!(
        one_line(&e, "s.mcap"),
        format!("writing the export of {} failed: the pipe broke", path.display())
    );

    let cut = dir.file("cut.mcap");
    std::fs::write(&cut, &std::fs::read(&path).unwrap()[..2000]).unwrap();
    let e = SessionInfo::read(&cut, o).unwrap_err();
    let line = one_line(&e, "cut.mcap");
    assert!(line.contains("is truncated") && line.ends_with("read them with --recover"), "{line}");
}

/// A destination that refuses every write.
struct Failing;

impl std::io::Write for Failing {
    fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
        Err(std::io::Error::new(std::io::ErrorKind::BrokenPipe, "the pipe broke"))
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn writing_errors_name_the_file_and_chain_their_cause() {
    let dir = TestDir::new("errors-write");
    let missing = dir.file("no-such-dir").join("s.mcap");
    let e = Recorder::create(&missing, BTreeMap::new()).err().unwrap();
    let line = one_line(&e, "no-such-dir/s.mcap");
    assert!(line.starts_with(&format!("cannot create session file {}: ", missing.display())), "{line}");
    assert!(line.contains("No such file or directory"), "{line}");

    let full = std::path::Path::new("/dev/full");
    if full.exists() {
        let options = RecorderOptions { overwrite: true, ..RecorderOptions::default() };
        let rec = Recorder::create_with_options(full, session_metadata().to_map(), options).unwrap();
        let e = rec.finish().unwrap_err();
        let SessionError::Write { kind, source, .. } = &e else { panic!("{e:?}") };
        assert_eq!(*kind, Some(std::io::ErrorKind::StorageFull));
        assert!(matches!(source, WriteFailure::Io(io) if io.kind() == std::io::ErrorKind::StorageFull));
        let line = one_line(&e, "/dev/full");
        assert!(line.starts_with("writing session file /dev/full failed: No space left on device"), "{line}");
    }

    let path = dir.file("s.mcap");
    let rec = Recorder::create(&path, BTreeMap::new()).unwrap();
    rec.register::<HandCommand>(BTreeMap::new()).unwrap();
    let e = rec.register::<HandCommand>(BTreeMap::from([("k".into(), "v".into())])).unwrap_err();
    one_line(&e, "s.mcap");
    rec.finish().unwrap();
}
