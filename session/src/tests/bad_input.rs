//! Missing, empty, garbage, truncated and corrupted files; unwritable places.

use std::collections::BTreeMap;

use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::*;

/// A small finished session with several chunks; returns its bytes and the
/// tactile messages in it.
fn small_session(dir: &TestDir) -> (Vec<u8>, Vec<(TimeNs, TactileRaw)>) {
    let path = dir.file("small.mcap");
    let options = RecorderOptions { chunk_size_bytes: 600, ..RecorderOptions::default() };
    let rec = Recorder::create_with_options(&path, session_metadata().to_map(), options).unwrap();
    rec.attach("camera.toml", "application/toml", b"fx = 1.0\n".to_vec()).unwrap();
    let ch = rec.register::<TactileRaw>(BTreeMap::new()).unwrap();
    let events = rec.register::<ProtocolEvent>(BTreeMap::new()).unwrap();
    let mut expected = Vec::new();
    for i in 0..24 {
        rec.log_json(&ch, t_ms(i), t_ms(i), i as u32, &raw(i)).unwrap();
        expected.push((t_ms(i), raw(i)));
    }
    rec.log_json(&events, t_ms(24), t_ms(24), 0, &ProtocolEvent::default()).unwrap();
    rec.finish_with_outcome(true, None).unwrap();
    (std::fs::read(&path).unwrap(), expected)
}

/// What the readers made of a file.
struct Readings {
    strict_info: Result<SessionInfo, SessionError>,
    recovered_info: Result<SessionInfo, SessionError>,
    recovered_raw: Result<Vec<(TimeNs, TactileRaw)>, SessionError>,
    recovered_count: Option<usize>,
}

/// Runs the readers on `path` in both modes (all of them when `all`). A
/// panic anywhere fails the test.
fn read_every_way(path: &Path, all: bool) -> Readings {
    let strict = ReadOptions::default();
    let recover = ReadOptions::recover();
    if all {
        let _ = read_channel::<TactileRaw>(path, strict);
        let _ = export_csv(path, TactileRaw::TOPIC, recover, std::io::sink());
        let _ = export_csv(path, TactileRaw::TOPIC, strict, std::io::sink());
        if let Ok(reader) = MessageReader::open(path, &[], strict) {
            reader.for_each(drop);
        }
    }
    let recovered_count = MessageReader::open(path, &[], recover).ok().map(|r| r.count());
    Readings {
        strict_info: SessionInfo::read(path, strict),
        recovered_info: SessionInfo::read(path, recover),
        recovered_raw: read_channel::<TactileRaw>(path, recover),
        recovered_count,
    }
}

/// Recovered messages must be the first messages written, unaltered.
fn assert_prefix(got: &[(TimeNs, TactileRaw)], expected: &[(TimeNs, TactileRaw)], what: &str) {
    assert!(got.len() <= expected.len(), "{what}: more messages than written");
    assert_eq!(got, &expected[..got.len()], "{what}: recovered messages differ");
}

#[test]
fn missing_empty_and_non_mcap_files_give_typed_errors_naming_the_path() {
    let dir = TestDir::new("bad-files");
    let o = ReadOptions::recover();
    let missing = dir.file("missing.mcap");
    let err = SessionInfo::read(&missing, o).unwrap_err();
    assert!(matches!(err, SessionError::NotFound { .. }), "{err}");
    assert!(err.to_string().contains("missing.mcap"), "{err}");
    assert!(matches!(MessageReader::open(&missing, &[], o), Err(SessionError::NotFound { .. })));

    let empty = dir.file("empty.mcap");
    std::fs::write(&empty, b"").unwrap();
    let err = SessionInfo::read(&empty, o).unwrap_err();
    assert!(matches!(err, SessionError::Empty { .. }), "{err}");
    assert!(err.to_string().contains("empty.mcap") && err.to_string().contains("empty"), "{err}");
    let err = read_channel::<TactileRaw>(&empty, o).unwrap_err();
    assert!(matches!(err, SessionError::Empty { .. }), "{err}");

    let text = dir.file("notes.txt");
    std::fs::write(&text, b"this is not a recording, just some text\n").unwrap();
    let err = SessionInfo::read(&text, o).unwrap_err();
    assert!(matches!(err, SessionError::NotMcap { .. }), "{err}");
    assert!(err.to_string().contains("notes.txt") && err.to_string().contains("not an MCAP"), "{err}");
    let err = export_csv(&text, "/tactile/raw", o, std::io::sink()).unwrap_err();
    assert!(matches!(err, SessionError::NotMcap { .. }), "{err}");

    let err = SessionInfo::read(dir.path(), o).unwrap_err();
    assert!(matches!(err, SessionError::Read { .. }), "a directory: {err}");
}

#[test]
fn create_fails_clearly_for_missing_or_unwritable_directories() {
    let dir = TestDir::new("create");
    let missing = dir.file("no-such-dir").join("s.mcap");
    let err = Recorder::create(&missing, BTreeMap::new()).err().unwrap();
    assert!(matches!(err, SessionError::Create { .. }), "{err}");
    assert!(err.to_string().contains("no-such-dir/s.mcap"), "{err}");

    let file = dir.file("a-file");
    std::fs::write(&file, b"x").unwrap();
    let err = Recorder::create(file.join("s.mcap"), BTreeMap::new()).err().unwrap();
    assert!(matches!(err, SessionError::Create { .. }), "{err}");

    // An earlier session is never overwritten by accident.
    let err = Recorder::create(&file, BTreeMap::new()).err().unwrap();
    assert!(
        matches!(err, SessionError::Create { ref source, .. } if source.kind() == std::io::ErrorKind::AlreadyExists),
        "{err}"
    );
    assert_eq!(std::fs::read(&file).unwrap(), b"x");
    let options = RecorderOptions { overwrite: true, ..RecorderOptions::default() };
    Recorder::create_with_options(&file, BTreeMap::new(), options).unwrap().finish().unwrap();
    assert!(SessionInfo::read(&file, ReadOptions::default()).is_ok());

    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let ro = dir.file("read-only");
        std::fs::create_dir(&ro).unwrap();
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
        let probe = ro.join("probe");
        if std::fs::write(&probe, b"").is_ok() {
            eprintln!("running with permission to write anywhere (root): read-only case skipped");
        } else {
            let err = Recorder::create(ro.join("s.mcap"), BTreeMap::new()).err().unwrap();
            assert!(matches!(err, SessionError::Create { .. }), "{err}");
            assert!(err.to_string().contains("read-only/s.mcap"), "{err}");
        }
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
}

#[test]
fn write_errors_surface_from_log_and_finish() {
    let full = Path::new("/dev/full");
    if !full.exists() {
        eprintln!("no /dev/full: skipped");
        return;
    }
    let check = |e: &SessionError| {
        assert!(matches!(e, SessionError::Write { kind: Some(std::io::ErrorKind::StorageFull), .. }), "{e}");
        assert!(e.to_string().contains("/dev/full"), "{e}");
    };
    let options = RecorderOptions { overwrite: true, ..RecorderOptions::default() };
    let rec = Recorder::create_with_options(full, session_metadata().to_map(), options).unwrap();
    let mut first_error = None;
    match rec.register::<TactileRaw>(BTreeMap::new()) {
        Err(e) => first_error = Some(e),
        Ok(ch) => {
            for i in 0..1_000_000u64 {
                if let Err(e) = rec.log_json(&ch, t_ms(i), t_ms(i), i as u32, &raw(i)) {
                    first_error = Some(e);
                    break;
                }
                if i % 1000 == 0 {
                    std::thread::sleep(std::time::Duration::from_millis(1));
                }
            }
        }
    }
    check(&first_error.expect("a write error surfaces from a later call"));
    check(&rec.finish().unwrap_err());
}

#[test]
fn every_truncation_of_a_file_reads_a_prefix_or_fails_cleanly() {
    let dir = TestDir::new("truncate");
    let (bytes, expected) = small_session(&dir);
    let path = dir.file("cut.mcap");
    let mut last_count = 0;
    for cut in 0..bytes.len() {
        std::fs::write(&path, &bytes[..cut]).unwrap();
        let r = read_every_way(&path, cut % 5 == 0);
        match cut {
            0 => assert!(matches!(r.strict_info, Err(SessionError::Empty { .. }))),
            1..8 => assert!(matches!(r.strict_info, Err(SessionError::NotMcap { .. }))),
            _ => {
                let Err(SessionError::Truncated { readable_messages, .. }) = r.strict_info else {
                    panic!("cut at {cut}: expected Truncated, got {:?}", r.strict_info);
                };
                let info = r.recovered_info.unwrap();
                assert!(info.truncated, "cut at {cut}");
                assert_eq!(info.message_count, readable_messages, "cut at {cut}");
                let count = r.recovered_count.unwrap();
                assert_eq!(count as u64, readable_messages, "cut at {cut}");
                assert!(count >= last_count, "cut at {cut}: a longer file never reads less");
                last_count = count;
                match r.recovered_raw {
                    Ok(got) => assert_prefix(&got, &expected, &format!("cut at {cut}")),
                    Err(SessionError::NoSuchTopic { .. }) => assert_eq!(count, 0, "cut at {cut}"),
                    Err(e) => panic!("cut at {cut}: {e}"),
                }
            }
        }
    }
    // Without only its end magic, the file still has every chunk.
    std::fs::write(&path, &bytes[..bytes.len() - 1]).unwrap();
    assert_eq!(read_channel::<TactileRaw>(&path, ReadOptions::recover()).unwrap(), expected);
    let err = SessionInfo::read(&path, ReadOptions::default()).unwrap_err();
    let message = err.to_string();
    assert!(message.contains("truncated") && message.contains("26 messages"), "{message}");
    assert!(message.contains("--recover") && !message.contains('\n'), "{message}");
}

#[test]
fn flipped_bytes_never_panic_and_never_alter_recovered_messages() {
    let dir = TestDir::new("flip");
    let (bytes, expected) = small_session(&dir);
    let path = dir.file("flipped.mcap");
    for i in 0..bytes.len() {
        let mut b = bytes.clone();
        b[i] ^= 0x5A;
        std::fs::write(&path, &b).unwrap();
        let r = read_every_way(&path, i % 5 == 0);
        if let Ok(got) = r.recovered_raw {
            // A flipped opcode can turn a whole chunk into an unknown record,
            // which MCAP readers skip: a gap, never an altered message.
            let mut rest = expected.iter();
            for m in &got {
                assert!(rest.any(|e| e == m), "byte {i} flipped: {m:?} altered or out of order");
            }
        }
    }
}

#[test]
fn random_bytes_never_panic() {
    let dir = TestDir::new("random");
    let (bytes, _) = small_session(&dir);
    let path = dir.file("random.mcap");
    let mut rng = ChaCha8Rng::seed_from_u64(0x5e55_10f1);
    for round in 0..400 {
        let mut b = match round % 4 {
            // Garbage, with and without the MCAP magic in front.
            0 | 1 => {
                let mut g = vec![0u8; rng.random_range(0..4096)];
                rng.fill_bytes(&mut g);
                if round % 4 == 1 {
                    g.splice(0..0, mcap::MAGIC.iter().copied());
                }
                g
            }
            // The real file with a few random bytes overwritten.
            2 => {
                let mut b = bytes.clone();
                for _ in 0..rng.random_range(1..8) {
                    let at = rng.random_range(0..b.len());
                    b[at] = rng.random();
                }
                b
            }
            // Cut somewhere and continued with garbage.
            _ => {
                let mut b = bytes[..rng.random_range(0..bytes.len())].to_vec();
                let mut tail = vec![0u8; rng.random_range(0..512)];
                rng.fill_bytes(&mut tail);
                b.extend(tail);
                b
            }
        };
        if round % 16 == 3 {
            // A huge length field right after the magic and header.
            let at = b.len().min(24);
            b.splice(at..at, [op_chunk(), 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x7F]);
        }
        std::fs::write(&path, &b).unwrap();
        read_every_way(&path, true);
    }
}

fn op_chunk() -> u8 {
    mcap::records::op::CHUNK
}
