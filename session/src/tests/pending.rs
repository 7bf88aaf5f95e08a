//! Messages whose payload another thread computes (`Logger::log_pending`).

use std::collections::BTreeMap;
use std::time::Duration;

use super::*;

/// The image of frame `i`: a few kB that differ from frame to frame.
fn image(i: u32) -> CompressedImage {
    let bytes = (0..3000u32).map(|k| (k * 31 + i * 7) as u8).collect();
    CompressedImage::new(t_ms(u64::from(i)), "camera", &EncodedImage { format: "jpeg".into(), bytes })
}

/// Frame 13's encoder fails: its image is not recorded.
const FAILED: u32 = 13;

/// Records 40 scans with an image every fourth scan (all but [`FAILED`]);
/// with `deferred`, each image is filled by another thread, in reverse
/// order, after the scans that follow it were logged.
fn record(path: &std::path::Path, deferred: bool) {
    // Small chunks (about 40 of the 200 kB), no flush by wall time: the file
    // depends on the messages only.
    let options = RecorderOptions {
        chunk_size_bytes: 4 << 10,
        flush_interval: Duration::from_secs(3600),
        ..RecorderOptions::default()
    };
    let rec = Recorder::create_with_options(path, session_metadata().to_map(), options).unwrap();
    let scans = rec.register::<TactileRaw>(BTreeMap::new()).unwrap();
    let images = rec.register::<CompressedImage>(BTreeMap::new()).unwrap();
    let logger = rec.logger();
    let mut pending = Vec::new();
    for i in 0..40u32 {
        let t = t_ms(u64::from(i));
        rec.log_json(&scans, t, t, i, &raw(u64::from(i))).unwrap();
        if i % 4 != 1 {
            continue;
        }
        if deferred {
            pending.push((i, logger.log_json_pending(&images, t, t, i).unwrap()));
        } else if i != FAILED {
            rec.log_json(&images, t, t, i, &image(i)).unwrap();
        }
    }
    let filler = std::thread::Builder::new().name("filler".into()).spawn(move || {
        std::thread::sleep(Duration::from_millis(20));
        for (i, out) in pending.into_iter().rev() {
            if i != FAILED {
                out.fill_json(&image(i));
            }
        }
    });
    let stats = rec.finish().unwrap();
    filler.unwrap().join().unwrap();
    assert_eq!(stats.messages_written, 40 + 9, "40 scans, 9 images written");
}

#[test]
fn a_pending_message_is_written_in_its_turn_as_if_logged_directly() {
    // Catches a writer that writes pending payloads when they arrive (out of
    // order), skips them, or waits forever on one dropped unfilled.
    let dir = TestDir::new("pending");
    let (direct, deferred) = (dir.file("direct.mcap"), dir.file("deferred.mcap"));
    record(&direct, false);
    record(&deferred, true);
    let (a, b) = (std::fs::read(&direct).unwrap(), std::fs::read(&deferred).unwrap());
    assert!(a == b, "the deferred session differs from the direct one");
}
