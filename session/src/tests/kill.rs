//! A recording process killed mid-trial (SIGKILL) leaves a file whose
//! complete chunks read back exactly.
//!
//! The parent test re-executes this test binary, running only
//! [`child_records_until_killed`], which records until it is killed.

use std::collections::BTreeMap;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use super::*;

/// Set (to the session path) in the child process.
const CHILD_ENV: &str = "SLIDETRACK_SESSION_KILL_CHILD";
/// The child's test, by its full path in this test binary.
const CHILD_TEST: &str = "tests::kill::child_records_until_killed";

/// The image bytes logged with tactile scan `i`: incompressible, like JPEG,
/// so that a chunk's data reaches the file before the chunk is closed.
fn frame(i: u64) -> Vec<u8> {
    let mut state = i.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..20_000)
        .map(|_| {
            // xorshift64
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 32) as u8
        })
        .collect()
}

/// The child: does nothing unless [`CHILD_ENV`] is set, then records tactile
/// scans at about 10 kHz and a 20 kB frame every 10 scans, with the default
/// recorder options, until it is killed.
#[test]
fn child_records_until_killed() {
    let Some(path) = std::env::var_os(CHILD_ENV) else {
        return;
    };
    let rec = Recorder::create(&path, session_metadata().to_map()).unwrap();
    let ch = rec.register::<TactileRaw>(BTreeMap::new()).unwrap();
    let images = rec.register_channel("/camera/blob", "", "", &[], "bytes", BTreeMap::new()).unwrap();
    for i in 0u64.. {
        rec.log_json(&ch, t_ms(i), t_ms(i), i as u32, &raw(i)).unwrap();
        if i % 10 == 0 {
            rec.log_lossy(&images, t_ms(i), t_ms(i), i as u32, frame(i)).unwrap();
            std::thread::sleep(Duration::from_millis(1));
        }
    }
}

/// Whether the file ends inside a chunk its writer never finished: the
/// chunk's length is still the placeholder written when it was opened, and
/// some of its compressed data is on disk.
fn ends_in_a_half_written_chunk(path: &Path) -> bool {
    let Ok(bytes) = std::fs::read(path) else {
        return false;
    };
    let mut at = 8;
    while let Some(header) = bytes.get(at..at + 9) {
        let len = u64::from_le_bytes(header[1..9].try_into().unwrap());
        if header[0] == mcap::records::op::CHUNK && len == u64::MAX {
            return bytes.len() > at + 9 + 64;
        }
        match usize::try_from(len).ok().and_then(|l| (at + 9).checked_add(l)) {
            Some(next) => at = next,
            None => return false,
        }
    }
    false
}

#[test]
fn a_killed_writer_leaves_its_complete_chunks_readable() {
    if std::env::var_os(CHILD_ENV).is_some() {
        return;
    }
    let dir = TestDir::new("kill");
    let path = dir.file("killed.mcap");
    let mut child = Command::new(std::env::current_exe().unwrap())
        .args([CHILD_TEST, "--exact", "--nocapture", "--test-threads=1"])
        .env(CHILD_ENV, &path)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();

    // Wait for at least two closed chunks and part of the next one on disk.
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        std::thread::sleep(Duration::from_millis(50));
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the recording child exited by itself: {status}");
        }
        let chunks = SessionInfo::read(&path, ReadOptions::recover()).map_or(0, |i| i.chunk_count);
        if chunks >= 2 && ends_in_a_half_written_chunk(&path) {
            break;
        }
        assert!(Instant::now() < deadline, "the child closed no two chunks in 60 s");
    }
    child.kill().unwrap(); // SIGKILL: no destructor, no finish
    child.wait().unwrap();

    assert!(ends_in_a_half_written_chunk(&path), "killed while a chunk was half written");

    let err = SessionInfo::read(&path, ReadOptions::default()).unwrap_err();
    let SessionError::Truncated { readable_messages, complete_chunks, readable_until, .. } = err else {
        panic!("expected Truncated, got {err}");
    };
    assert!(complete_chunks >= 2, "{complete_chunks} chunks");
    eprintln!("killed: {readable_messages} messages in {complete_chunks} complete chunks readable");
    let err = MessageReader::open(&path, &[], ReadOptions::default()).err().unwrap();
    assert!(matches!(err, SessionError::Truncated { .. }), "{err}");

    let got = read_channel::<TactileRaw>(&path, ReadOptions::recover()).unwrap();
    for (i, (t, m)) in got.iter().enumerate() {
        assert_eq!((*t, m.clone()), (t_ms(i as u64), raw(i as u64)), "message {i}");
    }
    let frames: Vec<RawMessage> = MessageReader::open(&path, &["/camera/blob"], ReadOptions::recover())
        .unwrap()
        .map(Result::unwrap)
        .collect();
    assert!(!frames.is_empty());
    for f in &frames {
        let i = u64::from(f.sequence);
        assert_eq!((f.log_time, &f.data), (t_ms(i), &frame(i)), "frame {i}");
    }
    let last_scan = got.last().unwrap().0;
    assert_eq!(readable_until, Some(last_scan.max(frames.last().unwrap().log_time)));
    assert_eq!(readable_messages, (got.len() + frames.len()) as u64);

    let info = SessionInfo::read(&path, ReadOptions::recover()).unwrap();
    assert!(info.truncated);
    assert_eq!(info.chunk_count, complete_chunks);
    assert_eq!(info.message_count, readable_messages);
    assert_eq!(info.channel(TactileRaw::TOPIC).unwrap().message_count, got.len() as u64);
    assert_eq!(info.session_metadata(), Some(session_metadata()));
    assert_eq!(info.outcome(), None, "a killed writer writes no outcome");
}
