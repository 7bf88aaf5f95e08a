//! The recorder's queue, chunk policy and cost.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{Seek, SeekFrom, Write};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::*;

/// A session file on a disk that stalls: every write waits while the test
/// holds `gate`, so the writer thread stops taking records off the queue.
struct GatedFile {
    file: File,
    gate: Arc<Mutex<()>>,
}

impl GatedFile {
    fn create(path: &std::path::Path, gate: &Arc<Mutex<()>>) -> GatedFile {
        GatedFile { file: File::create(path).unwrap(), gate: Arc::clone(gate) }
    }
}

impl Write for GatedFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let _open = self.gate.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        self.file.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

impl Seek for GatedFile {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.file.seek(pos)
    }
}

impl SessionSink for GatedFile {
    fn sync(&mut self) -> std::io::Result<()> {
        self.file.sync_all()
    }
}

#[test]
fn lossy_logging_drops_and_counts_when_the_queue_is_full_and_lossless_never_drops() {
    let dir = TestDir::new("lossy");
    let path = dir.file("s.mcap");
    let options = RecorderOptions { queue_capacity: 8, ..RecorderOptions::default() };
    let gate = Arc::new(Mutex::new(()));
    let stalled = gate.lock().unwrap();
    let rec = Recorder::with_sink(&path, GatedFile::create(&path, &gate), BTreeMap::new(), options).unwrap();

    let images = rec.register::<CompressedImage>(BTreeMap::new()).unwrap();
    let hand = rec.register::<HandCommand>(BTreeMap::new()).unwrap();
    let frame = CompressedImage::new(
        TimeNs::ZERO,
        "camera",
        &slidetrack_core::EncodedImage { format: "jpeg".into(), bytes: vec![0xAB; 1000] },
    );
    let mut accepted = 0u64;
    for i in 0..100u32 {
        let t = t_ms(u64::from(i));
        if rec.log_json_lossy(&images, t, t, i, &frame).unwrap() {
            accepted += 1;
        }
    }
    let dropped = 100 - accepted;
    assert!((1..=8).contains(&accepted), "the queue holds at most 8 records: {accepted}");
    assert_eq!(rec.images_dropped(), dropped);

    // Lossless logging blocks while the writer is stalled, and loses nothing.
    let progress = Arc::new(AtomicUsize::new(0));
    let producer = {
        let (logger, progress, hand) = (rec.logger(), Arc::clone(&progress), hand.clone());
        std::thread::Builder::new()
            .name("test-producer".into())
            .spawn(move || {
                for i in 0..50u32 {
                    let t = t_ms(u64::from(i));
                    logger.log_json(&hand, t, t, i, &HandCommand::default()).unwrap();
                    progress.fetch_add(1, Ordering::SeqCst);
                }
            })
            .unwrap()
    };
    std::thread::sleep(Duration::from_millis(200));
    // The stalled writer may have taken one more record off the queue.
    assert!(progress.load(Ordering::SeqCst) <= 1, "log blocks on a full queue");
    drop(stalled);
    producer.join().unwrap();

    let stats = rec.finish().unwrap();
    assert_eq!(stats, RecorderStats { messages_written: accepted + 50, images_dropped: dropped });
    let o = ReadOptions::default();
    assert_eq!(read_channel::<HandCommand>(&path, o).unwrap().len(), 50);
    assert_eq!(read_channel::<CompressedImage>(&path, o).unwrap().len() as u64, accepted);
    let info = SessionInfo::read(&path, o).unwrap();
    assert_eq!(read_channel::<RecorderStats>(&path, o).unwrap()[0].1, stats);
    assert_eq!(info.outcome(), None, "finish() writes no outcome record");
}

#[test]
fn lossy_logging_drops_beyond_the_byte_budget() {
    let dir = TestDir::new("lossy-bytes");
    let options = RecorderOptions { lossy_queue_bytes: 2500, ..RecorderOptions::default() };
    let path = dir.file("s.mcap");
    let gate = Arc::new(Mutex::new(()));
    let stalled = gate.lock().unwrap();
    let rec = Recorder::with_sink(&path, GatedFile::create(&path, &gate), BTreeMap::new(), options).unwrap();
    let ch = rec.register_channel("/blob", "", "", &[], "application/octet-stream", BTreeMap::new()).unwrap();
    let results: Vec<bool> =
        (0..5).map(|i| rec.log_lossy(&ch, TimeNs(i), TimeNs(i), 0, vec![0; 1000]).unwrap()).collect();
    assert_eq!(results, [true, true, false, false, false]);
    drop(stalled);
    assert_eq!(rec.finish().unwrap().images_dropped, 3);
}

#[test]
fn logging_100k_small_messages_is_cheap() {
    let dir = TestDir::new("perf");
    let path = dir.file("s.mcap");
    let start = Instant::now();
    let rec = Recorder::create(&path, session_metadata().to_map()).unwrap();
    let ch = rec.register::<TactileRaw>(BTreeMap::new()).unwrap();
    for i in 0..100_000u64 {
        rec.log_json(&ch, t_ms(i), t_ms(i), i as u32, &raw(i)).unwrap();
    }
    let queued = start.elapsed();
    let stats = rec.finish().unwrap();
    let total = start.elapsed();
    let size = std::fs::metadata(&path).unwrap().len();
    eprintln!(
        "100k TactileRaw messages: queued in {:.3} s, written and closed in {:.3} s, {} bytes",
        queued.as_secs_f64(),
        total.as_secs_f64(),
        size
    );
    assert_eq!(stats.messages_written, 100_000);
    let start = Instant::now();
    let info = SessionInfo::read(&path, ReadOptions::default()).unwrap();
    let summary_read = start.elapsed();
    let start = Instant::now();
    let scans = read_channel::<TactileRaw>(&path, ReadOptions::default()).unwrap();
    eprintln!(
        "read back: summary in {:.4} s, all 100k decoded in {:.3} s",
        summary_read.as_secs_f64(),
        start.elapsed().as_secs_f64()
    );
    assert_eq!((info.message_count, scans.len()), (100_001, 100_000));
    // The budget is for release builds; unoptimised builds get a loose bound.
    let limit_s = if cfg!(debug_assertions) { 10.0 } else { 0.2 };
    assert!(total.as_secs_f64() < limit_s, "took {total:?}, budget {limit_s} s");
}

#[test]
fn dropping_the_recorder_without_finish_still_finishes_the_file() {
    let dir = TestDir::new("drop");
    let path = dir.file("s.mcap");
    {
        let rec = Recorder::create(&path, session_metadata().to_map()).unwrap();
        let ch = rec.register::<HandCommand>(BTreeMap::new()).unwrap();
        for i in 0..10 {
            rec.log_json(&ch, t_ms(i), t_ms(i), i as u32, &HandCommand::default()).unwrap();
        }
    }
    let info = SessionInfo::read(&path, ReadOptions::default()).unwrap();
    assert!(!info.truncated);
    assert_eq!(info.channel(HandCommand::TOPIC).unwrap().message_count, 10);
    let outcome = info.outcome().unwrap();
    assert!(!outcome.completed);
    assert!(outcome.abort_reason.unwrap().contains("without finish"));
}

#[test]
fn logging_after_finish_fails_with_closed() {
    let dir = TestDir::new("closed");
    let rec = Recorder::create(dir.file("s.mcap"), BTreeMap::new()).unwrap();
    let logger = rec.logger();
    let ch = rec.register::<HandCommand>(BTreeMap::new()).unwrap();
    rec.finish().unwrap();
    let err = logger.log_json(&ch, TimeNs(0), TimeNs(0), 0, &HandCommand::default()).unwrap_err();
    assert!(matches!(err, SessionError::Closed { .. }), "{err}");
    assert!(err.to_string().contains("s.mcap"), "{err}");
}

/// Copies the file being written, as a crash at this instant would leave it.
fn snapshot(path: &Path, dir: &TestDir) -> PathBuf {
    let copy = dir.file("snapshot.mcap");
    std::fs::copy(path, &copy).unwrap();
    copy
}

#[test]
fn chunks_are_closed_within_the_flush_interval_and_at_the_size_limit() {
    let dir = TestDir::new("flush");
    let path = dir.file("s.mcap");
    let options =
        RecorderOptions { flush_interval: Duration::from_millis(100), ..RecorderOptions::default() };
    let rec = Recorder::create_with_options(&path, BTreeMap::new(), options).unwrap();
    let ch = rec.register::<TactileRaw>(BTreeMap::new()).unwrap();
    for i in 0..10 {
        rec.log_json(&ch, t_ms(i), t_ms(i), i as u32, &raw(i)).unwrap();
    }
    std::thread::sleep(Duration::from_millis(500));
    let copy = snapshot(&path, &dir);
    assert!(matches!(SessionInfo::read(&copy, ReadOptions::default()), Err(SessionError::Truncated { .. })));
    let got = read_channel::<TactileRaw>(&copy, ReadOptions::recover()).unwrap();
    assert_eq!(got.len(), 10, "messages older than the flush interval are on disk");
    rec.finish().unwrap();

    let options = RecorderOptions {
        flush_interval: Duration::from_secs(3600),
        chunk_size_bytes: 2048,
        ..RecorderOptions::default()
    };
    let path = dir.file("by-size.mcap");
    let rec = Recorder::create_with_options(&path, BTreeMap::new(), options).unwrap();
    let ch = rec.register::<TactileRaw>(BTreeMap::new()).unwrap();
    for i in 0..1000 {
        rec.log_json(&ch, t_ms(i), t_ms(i), i as u32, &raw(i)).unwrap();
    }
    std::thread::sleep(Duration::from_millis(300));
    let info = SessionInfo::read(snapshot(&path, &dir), ReadOptions::recover()).unwrap();
    assert!(info.truncated);
    assert!(info.chunk_count >= 10, "closed by size: {} chunks", info.chunk_count);
    rec.finish().unwrap();
}
