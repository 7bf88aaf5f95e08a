//! The recorder's live tap: what it forwards, and that the file never depends on it.

use std::collections::BTreeMap;
use std::time::Duration;

use super::*;

/// Records `n` tactile scans to `path`, with `live` as the tap.
fn record_scans(path: &Path, n: u64, live: Option<LiveTap>) -> RecorderStats {
    let options = RecorderOptions { live, ..RecorderOptions::default() };
    let rec = Recorder::create_with_options(path, BTreeMap::new(), options).unwrap();
    let ch = rec.register::<TactileRaw>(BTreeMap::new()).unwrap();
    for i in 0..n {
        rec.log_json(&ch, t_ms(i), t_ms(i), i as u32, &raw(i)).unwrap();
    }
    rec.finish().unwrap()
}

/// Every record the tap holds.
fn drain(rx: &LiveReceiver) -> Vec<LiveRecord> {
    let mut out = Vec::new();
    while let Ok(Some(r)) = rx.recv_timeout(Duration::from_millis(50)) {
        out.push(r);
    }
    out
}

fn file_messages(path: &Path) -> Vec<(String, TimeNs, Vec<u8>)> {
    MessageReader::open(path, &[], ReadOptions::default())
        .unwrap()
        .map(|m| m.unwrap())
        .map(|m| (m.channel.topic.clone(), m.log_time, m.data))
        .collect()
}

#[test]
fn a_wanted_tap_forwards_every_written_channel_and_message_as_written() {
    let dir = TestDir::new("live-all");
    let path = dir.file("s.mcap");
    let (tap, rx) = LiveTap::new(1 << 20, 1 << 30);
    tap.set_wanted(true);
    record_scans(&path, 500, Some(tap.clone()));
    let records = drain(&rx);
    assert!(matches!(records.first(), Some(LiveRecord::SessionStarted { session: 1, .. })));
    assert!(matches!(records.last(), Some(LiveRecord::SessionFinished { session: 1 })));
    let mut topics = BTreeMap::new();
    let mut live = Vec::new();
    for r in &records {
        match r {
            LiveRecord::Channel { id, channel, .. } => {
                topics.insert(*id, channel.topic.clone());
            }
            LiveRecord::Message { channel, log_time, payload, .. } => {
                live.push((topics[channel].clone(), *log_time, payload.clone()));
            }
            _ => {}
        }
    }
    assert_eq!(live, file_messages(&path), "the stats message included");
    assert_eq!(tap.stats(), LiveTapStats { forwarded: 501, dropped: 0 });
}

#[test]
fn an_unwanted_or_full_tap_drops_messages_and_the_file_is_the_same() {
    let dir = TestDir::new("live-drop");
    let (without, unwanted, full) = (dir.file("a.mcap"), dir.file("b.mcap"), dir.file("c.mcap"));
    record_scans(&without, 2000, None);

    let (tap, rx) = LiveTap::new(16, 1 << 30);
    record_scans(&unwanted, 2000, Some(tap.clone()));
    let records = drain(&rx);
    assert!(records.iter().all(|r| !matches!(r, LiveRecord::Message { .. })), "nobody wanted them");
    // Subscribed later: the latest message of each channel comes first.
    let late = dir.file("d.mcap");
    let options = RecorderOptions { live: Some(tap.clone()), ..RecorderOptions::default() };
    let rec = Recorder::create_with_options(&late, BTreeMap::new(), options).unwrap();
    let ch = rec.register::<TactileRaw>(BTreeMap::new()).unwrap();
    let once = rec.register::<TactileTare>(BTreeMap::new()).unwrap();
    rec.log_json(&once, t_ms(0), t_ms(0), 0, &TactileTare::default()).unwrap();
    rec.log_json(&ch, t_ms(1), t_ms(1), 1, &raw(1)).unwrap();
    std::thread::sleep(Duration::from_millis(100));
    tap.set_wanted(true);
    rec.log_json(&ch, t_ms(2), t_ms(2), 2, &raw(2)).unwrap();
    rec.finish().unwrap();
    let times: Vec<_> = drain(&rx)
        .into_iter()
        .filter_map(|r| match r {
            LiveRecord::Message { log_time, .. } => Some(log_time),
            _ => None,
        })
        .collect();
    assert_eq!(
        times,
        [t_ms(0), t_ms(1), t_ms(2), t_ms(2)],
        "the tare, the latest scan, the new one, the stats"
    );
    tap.set_wanted(false);
    assert!(records.iter().any(|r| matches!(r, LiveRecord::Channel { .. })), "channels always go");

    // A viewer that never reads: the queue fills, the rest is dropped.
    let (tap, _never_read) = LiveTap::new(16, 1 << 30);
    tap.set_wanted(true);
    record_scans(&full, 2000, Some(tap.clone()));
    assert_eq!(tap.stats(), LiveTapStats { forwarded: 16, dropped: 2001 - 16 });

    let reference = file_messages(&without);
    assert_eq!(file_messages(&unwanted), reference);
    assert_eq!(file_messages(&full), reference);
}

/// A tap joined to another ([`LiveTap::and`], `--live` with `--ros2`):
/// each gets every record, numbered in its own sessions, and keeps its own
/// wish: one that nobody wants gets no message, and the other loses none.
#[test]
fn a_joined_tap_hands_everything_to_each_tap_that_wants_it() {
    let dir = TestDir::new("live-and");
    let path = dir.file("s.mcap");
    let (a, rx_a) = LiveTap::new(1 << 20, 1 << 30);
    let (b, rx_b) = LiveTap::new(1 << 20, 1 << 30);
    let (c, rx_c) = LiveTap::new(1 << 20, 1 << 30);
    a.set_wanted(true);
    b.set_wanted(true);
    record_scans(&path, 300, Some(a.and(&b.and(&c))));
    let (got_a, got_b, got_c) = (drain(&rx_a), drain(&rx_b), drain(&rx_c));
    assert_eq!(got_a, got_b, "the same records, session 1 on each");
    assert!(matches!(got_b.first(), Some(LiveRecord::SessionStarted { session: 1, .. })));
    let messages = |r: &[LiveRecord]| r.iter().filter(|r| matches!(r, LiveRecord::Message { .. })).count();
    assert_eq!(messages(&got_a), 301, "every scan and the statistics");
    assert_eq!(messages(&got_c), 0, "nobody subscribed to c");
    assert!(matches!(got_c.last(), Some(LiveRecord::SessionFinished { session: 1 })));
    assert_eq!((a.stats().forwarded, b.stats().forwarded, c.stats().forwarded), (301, 301, 0));
}
