//! Rewriting keeps every other record, replaces the new channels, is
//! deterministic, and never harms a file it cannot read.

use std::collections::BTreeMap;
use std::path::Path;

use slidetrack_core::TimeNs;

use super::super::tests::{EveryChannel, TestDir, record_every_channel};
use super::super::*;

/// Every message of a file: topic, times, sequence and payload, in file order.
fn messages(path: &Path) -> Vec<(String, TimeNs, TimeNs, u32, Vec<u8>)> {
    MessageReader::open(path, &[], ReadOptions::default())
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            (m.topic().to_string(), m.log_time, m.publish_time, m.sequence, m.data)
        })
        .collect()
}

fn ground_truth(n: u64, offset: f64) -> Vec<NewChannel> {
    let mut sliding = NewChannel::of::<GroundTruthSliding>(BTreeMap::from([("k".into(), "v".into())]));
    let mut measured = NewChannel::of::<GroundTruthMeasurement>(BTreeMap::new());
    for i in 0..n {
        let t = TimeNs(i * 1_000_000 + 500_000);
        let p = offset + i as f64 * 1e-3;
        sliding.push_json(t, &GroundTruthSliding { position: p, ..Default::default() }).unwrap();
        if i % 3 == 0 {
            let m = GroundTruthMeasurement { position: p, rejected: i == 9, mahalanobis2: 1.0 };
            measured.push_json(t, &m).unwrap();
        }
    }
    vec![sliding, measured]
}

fn is_ground_truth(topic: &str) -> bool {
    topic.starts_with(super::super::ground_truth::GROUND_TRUTH_PREFIX)
}

#[test]
fn a_rewrite_keeps_every_record_adds_the_channels_and_is_idempotent() {
    let dir = TestDir::new("rewrite");
    let path = dir.file("s.mcap");
    let e = EveryChannel::new(40);
    record_every_channel(&path, &e, RecorderOptions::default());
    let before_info = SessionInfo::read(&path, ReadOptions::default()).unwrap();
    let before = messages(&path);

    let report =
        rewrite_session(&path, ReadOptions::default(), &is_ground_truth, ground_truth(30, 0.0)).unwrap();
    assert_eq!(report.messages_copied, before.len() as u64);
    assert_eq!((report.messages_added, report.messages_dropped, report.truncated), (40, 0, false));
    let after = messages(&path);
    let kept: Vec<_> = after.iter().filter(|m| !is_ground_truth(&m.0)).cloned().collect();
    assert_eq!(kept, before, "every other message byte-identical, in the same order");
    let sliding: Vec<(TimeNs, GroundTruthSliding)> = read_channel(&path, ReadOptions::default()).unwrap();
    assert_eq!(sliding.len(), 30);
    assert_eq!(sliding[2].1.position, 2e-3);
    // Merged by log time: a new message comes right before the first kept
    // message with a later log time.
    for (k, m) in after.iter().enumerate().filter(|(_, m)| is_ground_truth(&m.0)) {
        let next_kept = after[k + 1..].iter().find(|n| !is_ground_truth(&n.0));
        assert!(next_kept.is_none_or(|n| n.1 > m.1), "{:?} at {}", m.0, m.1);
    }
    let gt_times: Vec<TimeNs> = after.iter().filter(|m| is_ground_truth(&m.0)).map(|m| m.1).collect();
    assert!(gt_times.windows(2).all(|w| w[0] <= w[1]));

    let info = SessionInfo::read(&path, ReadOptions::default()).unwrap();
    assert_eq!(info.metadata, before_info.metadata);
    assert_eq!(info.attachments, before_info.attachments);
    assert_eq!(info.message_count, before_info.message_count + 40);
    for c in &before_info.channels {
        let same = info.channels.iter().find(|d| d.topic == c.topic).unwrap();
        assert_eq!(same, c, "channel {} unchanged (id, schema, metadata, counts)", c.topic);
    }
    let gt = info.channels.iter().find(|c| c.topic == "/ground_truth/sliding").unwrap();
    assert_eq!(gt.metadata.get("k").map(String::as_str), Some("v"));

    // Again with the same channels: the same bytes. With other values: replaced.
    let first = std::fs::read(&path).unwrap();
    rewrite_session(&path, ReadOptions::default(), &is_ground_truth, ground_truth(30, 0.0)).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), first, "labelling twice gives the same bytes");
    let report =
        rewrite_session(&path, ReadOptions::default(), &is_ground_truth, ground_truth(20, 1.0)).unwrap();
    assert_eq!((report.messages_dropped, report.messages_added), (40, 27));
    let sliding: Vec<(TimeNs, GroundTruthSliding)> = read_channel(&path, ReadOptions::default()).unwrap();
    assert_eq!((sliding.len(), sliding[0].1.position), (20, 1.0));
    let kept: Vec<_> = messages(&path).into_iter().filter(|m| !is_ground_truth(&m.0)).collect();
    assert_eq!(kept, before);
    // Dropping without adding removes the channels and their schemas.
    rewrite_session(&path, ReadOptions::default(), &is_ground_truth, Vec::new()).unwrap();
    let info = SessionInfo::read(&path, ReadOptions::default()).unwrap();
    assert!(info.channels.iter().all(|c| !is_ground_truth(&c.topic)));
    assert_eq!(messages(&path), before);
}

#[test]
fn files_that_cannot_be_read_are_left_untouched() {
    let dir = TestDir::new("rewrite-bad");
    let path = dir.file("s.mcap");
    record_every_channel(&path, &EveryChannel::new(30), RecorderOptions::default());
    let good = std::fs::read(&path).unwrap();
    let listing = || {
        let mut names: Vec<_> =
            std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
        names.sort();
        names
    };

    // Cut short: refused without recover.
    let cut = dir.file("cut.mcap");
    std::fs::write(&cut, &good[..good.len() * 2 / 3]).unwrap();
    let err =
        rewrite_session(&cut, ReadOptions::default(), &is_ground_truth, ground_truth(5, 0.0)).unwrap_err();
    assert!(matches!(err, SessionError::Truncated { .. }), "{err}");
    assert_eq!(std::fs::read(&cut).unwrap(), &good[..good.len() * 2 / 3]);

    // A flipped byte in the data section (before the summary, which is
    // rebuilt anyway): a CRC check fails before anything is written.
    let corrupt = dir.file("corrupt.mcap");
    let mut bytes = good.clone();
    let footer = &good[good.len() - 37..];
    let summary_start = u64::from_le_bytes(footer[9..17].try_into().unwrap()) as usize;
    bytes[summary_start / 2] ^= 0x55;
    std::fs::write(&corrupt, &bytes).unwrap();
    let files = listing();
    assert!(
        rewrite_session(&corrupt, ReadOptions::default(), &is_ground_truth, ground_truth(5, 0.0)).is_err()
    );
    assert_eq!(std::fs::read(&corrupt).unwrap(), bytes);
    assert_eq!(listing(), files, "no temporary file left behind");

    // Recover: the complete chunks become a complete file.
    let readable = MessageReader::open(&cut, &[], ReadOptions::recover()).unwrap().count() as u64;
    let report =
        rewrite_session(&cut, ReadOptions::recover(), &is_ground_truth, ground_truth(5, 0.0)).unwrap();
    assert!(report.truncated);
    assert_eq!(report.messages_copied, readable);
    let info = SessionInfo::read(&cut, ReadOptions::default()).unwrap();
    assert!(!info.truncated);

    let missing = dir.file("none.mcap");
    let err = rewrite_session(&missing, ReadOptions::default(), &is_ground_truth, Vec::new()).unwrap_err();
    assert!(matches!(err, SessionError::NotFound { .. }), "{err}");
}
