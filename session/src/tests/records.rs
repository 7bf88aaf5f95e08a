//! The record stream shared by the message reader, the scan and the rewrite:
//! a cut file yields exactly its complete chunks, memory holds one chunk at a
//! time, payloads are kept only where asked, and reading from memory gives
//! what reading the file gives.

use std::cell::Cell;
use std::collections::{BTreeMap, HashSet};
use std::io::{Cursor, Read};
use std::rc::Rc;

use crate::records::{Payloads, Record, RecordStream, StreamError};

use super::*;

/// Where each chunk record of `bytes` ends (bytes from the start of the file).
fn chunk_ends(bytes: &[u8]) -> Vec<usize> {
    let mut ends = Vec::new();
    let mut at = 8;
    while let Some(header) = bytes.get(at..at + 9) {
        let next = at + 9 + u64::from_le_bytes(header[1..9].try_into().unwrap()) as usize;
        if header[0] == mcap::records::op::CHUNK {
            ends.push(next);
        }
        if header[0] == mcap::records::op::DATA_END {
            break;
        }
        at = next;
    }
    ends
}

/// Streams `bytes` to their end or first error: the messages handed out, the
/// complete chunks, and whether it ended in an error.
fn stream(bytes: &[u8], payloads: Payloads) -> (Vec<(u16, Vec<u8>)>, u64, bool) {
    let mut records = RecordStream::new(bytes, payloads);
    let mut messages = Vec::new();
    let failed = loop {
        match records.next_record() {
            Ok(Some(Record::Message { header, data })) => messages.push((header.channel_id, data)),
            Ok(Some(_)) => {}
            Ok(None) => break false,
            Err(_) => break true,
        }
    };
    (messages, records.complete_chunks(), failed)
}

#[test]
fn a_cut_file_yields_exactly_the_records_of_its_complete_chunks() {
    let dir = TestDir::new("stream-cut");
    let path = dir.file("s.mcap");
    let options = RecorderOptions { chunk_size_bytes: 1 << 10, ..RecorderOptions::default() };
    record_every_channel(&path, &EveryChannel::new(60), options);
    let bytes = std::fs::read(&path).unwrap();
    let ends = chunk_ends(&bytes);
    assert!(ends.len() > 10, "{} chunks", ends.len());

    let (all, chunks, failed) = stream(&bytes, Payloads::All);
    assert_eq!((chunks as usize, failed), (ends.len(), false));
    let mut before = 0;
    for (k, &end) in ends.iter().enumerate() {
        // Cut right after chunk k: chunks 0..=k complete.
        let (whole, complete, failed) = stream(&bytes[..end], Payloads::All);
        assert_eq!((complete as usize, failed), (k + 1, true), "cut after chunk {k}");
        assert_eq!(whole, all[..whole.len()], "cut after chunk {k}: a prefix of the messages");
        assert!(whole.len() >= before);
        // Cut one byte, or half a chunk, short: chunk k gives nothing at all.
        for cut in [end - 1, (end + ends.get(k.wrapping_sub(1)).copied().unwrap_or(8)) / 2] {
            let (part, complete, _) = stream(&bytes[..cut], Payloads::All);
            assert_eq!((complete as usize, part.len()), (k, before), "cut at {cut}, in chunk {k}");
        }
        before = whole.len();
    }
}

/// A reader that counts the bytes read from it.
struct Counting<R> {
    inner: R,
    read: Rc<Cell<u64>>,
}

impl<R: Read> Read for Counting<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.read.set(self.read.get() + n as u64);
        Ok(n)
    }
}

#[test]
fn memory_holds_one_chunk_at_a_time() {
    let dir = TestDir::new("stream-memory");
    let path = dir.file("s.mcap");
    let options = RecorderOptions { chunk_size_bytes: 64 << 10, ..RecorderOptions::default() };
    let rec = Recorder::create_with_options(&path, BTreeMap::new(), options).unwrap();
    let blobs = rec.register_channel("/blob", "", "", &[], "bytes", BTreeMap::new()).unwrap();
    // Incompressible 20 kB payloads, 6 MB in all.
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    for i in 0..300u64 {
        let blob: Vec<u8> = (0..20_000)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 32) as u8
            })
            .collect();
        rec.log(&blobs, t_ms(i), t_ms(i), i as u32, blob).unwrap();
    }
    rec.finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert!(bytes.len() > 5 << 20);

    // Where the chunk holding each log time ends.
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let chunk_end = |log_time: u64| {
        let c = summary
            .chunk_indexes
            .iter()
            .find(|c| (c.message_start_time..=c.message_end_time).contains(&log_time));
        c.map(|c| c.chunk_start_offset + c.chunk_length).unwrap()
    };

    let read = Rc::new(Cell::new(0));
    let input = Counting { inner: &bytes[..], read: Rc::clone(&read) };
    let mut records = RecordStream::new(input, Payloads::All);
    let (mut messages, mut most_ahead) = (0u64, 0u64);
    while let Some(record) = records.next_record().unwrap() {
        if let Record::Message { header, data } = record {
            // The blobs, and the recorder's stats at the end.
            messages += u64::from(data.len() == 20_000);
            // Handed out once its chunk was read, and before reading more
            // than one block (1 MiB) beyond it.
            let end = chunk_end(header.log_time);
            assert!(read.get() >= end, "message {} handed out before its chunk ended", header.sequence);
            most_ahead = most_ahead.max(read.get() - end);
        }
    }
    assert_eq!(messages, 300);
    assert!(most_ahead <= 1 << 20, "read {most_ahead} bytes beyond a chunk before handing out its messages");
}

#[test]
fn payloads_are_kept_only_where_asked() {
    let dir = TestDir::new("stream-payloads");
    let path = dir.file("s.mcap");
    record_every_channel(&path, &EveryChannel::new(20), RecorderOptions::default());
    let bytes = std::fs::read(&path).unwrap();
    let info = SessionInfo::read(&path, ReadOptions::default()).unwrap();
    let raw_id = |bytes: &[u8]| {
        let reader =
            MessageReader::from_reader("s", Cursor::new(bytes), &[], ReadOptions::default()).unwrap();
        let mut reader = reader;
        reader.by_ref().for_each(drop);
        reader.channels().find(|c| c.topic == TactileRaw::TOPIC).unwrap().id
    };
    let raw = raw_id(&bytes);

    let (all, _, _) = stream(&bytes, Payloads::All);
    assert_eq!(all.len() as u64, info.message_count);
    assert!(all.iter().all(|(_, data)| !data.is_empty()));
    let (none, _, _) = stream(&bytes, Payloads::None);
    assert_eq!(none.len(), all.len());
    assert!(none.iter().all(|(_, data)| data.is_empty()));
    let (some, _, _) = stream(&bytes, Payloads::Topics(HashSet::from([TactileRaw::TOPIC.to_string()])));
    for ((id, data), (_, full)) in some.iter().zip(&all) {
        assert_eq!(data.is_empty(), *id != raw, "channel {id}");
        if *id == raw {
            assert_eq!(data, full);
        }
    }
}

#[test]
fn a_message_on_an_undeclared_channel_is_corrupt() {
    let mut bytes = mcap::MAGIC.to_vec();
    let record = |opcode: u8, body: &[u8]| {
        let mut r = vec![opcode];
        r.extend((body.len() as u64).to_le_bytes());
        r.extend(body);
        r
    };
    bytes.extend(record(mcap::records::op::HEADER, &[0; 8]));
    let mut message = 7u16.to_le_bytes().to_vec(); // channel id
    message.extend([0; 4 + 8 + 8]); // sequence, log and publish time
    message.extend(b"{}");
    bytes.extend(record(mcap::records::op::MESSAGE, &message));
    let mut records = RecordStream::new(&bytes[..], Payloads::All);
    assert!(matches!(records.next_record(), Ok(Some(Record::Header(_)))));
    match records.next_record() {
        Err(StreamError::Corrupt {
            reason: crate::Corruption::UndeclaredChannel { channel_id: 7 },
            bytes_read,
        }) => {
            assert_eq!(bytes_read, bytes.len() as u64);
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(records.next_record(), Ok(None)), "the stream is over after an error");
}

#[test]
fn reading_from_memory_gives_what_reading_the_file_gives() {
    let dir = TestDir::new("from-reader");
    let path = dir.file("s.mcap");
    record_every_channel(&path, &EveryChannel::new(30), RecorderOptions::default());
    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.file("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    for (file, options) in [(&path, ReadOptions::default()), (&cut, ReadOptions::recover())] {
        let data = std::fs::read(file).unwrap();
        let from_file: Vec<RawMessage> =
            MessageReader::open(file, &[], options).unwrap().map(Result::unwrap).collect();
        let from_memory: Vec<RawMessage> = MessageReader::from_reader(file, Cursor::new(&data), &[], options)
            .unwrap()
            .map(Result::unwrap)
            .collect();
        assert_eq!(from_memory, from_file);
        let info = SessionInfo::from_reader(file, Cursor::new(&data), options).unwrap();
        assert_eq!(info, SessionInfo::read(file, options).unwrap());
        let (mut a, mut b) = (Vec::new(), Vec::new());
        let csv = export_csv(file, TactileRaw::TOPIC, options, &mut a).unwrap();
        let csv_memory =
            export_csv_from_reader(file, Cursor::new(&data), TactileRaw::TOPIC, options, &mut b).unwrap();
        assert_eq!((csv_memory, b), (csv, a));
    }
    let err = MessageReader::from_reader("cut.mcap", Cursor::new(&bytes[..100]), &[], ReadOptions::default());
    assert!(matches!(err, Err(SessionError::Truncated { .. })));
    let err =
        SessionInfo::from_reader("empty.mcap", Cursor::new(Vec::new()), ReadOptions::recover()).unwrap_err();
    assert!(matches!(err, SessionError::Empty { .. }), "{err}");
}

#[test]
fn a_chunk_with_a_bad_record_gives_none_of_its_records() {
    // Uncompressed chunks without CRCs, so that a record in one can be
    // spoiled without the chunk's CRC check catching it.
    let options = mcap::WriteOptions::new().compression(None).calculate_chunk_crcs(false).chunk_size(None);
    let mut w = options.create(Cursor::new(Vec::new())).unwrap();
    let channel = w.add_channel(0, "/a", "json", &BTreeMap::new()).unwrap();
    for (i, payload) in [&b"first"[..], b"second", b"third"].into_iter().enumerate() {
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: i as u32,
            log_time: 0,
            publish_time: 0,
        };
        w.write_to_known_channel(&header, payload).unwrap();
    }
    w.finish().unwrap();
    let mut bytes = w.into_inner().into_inner();
    // mcap 0.26 writes a wrong data-section CRC when it computes no chunk
    // CRCs (its own reader refuses such a file): 0 says "no CRC".
    let data_end = chunk_ends(&bytes).last().copied().unwrap();
    let data_end =
        data_end + bytes[data_end..].windows(9).position(|w| w == [0x0F, 4, 0, 0, 0, 0, 0, 0, 0]).unwrap();
    bytes[data_end + 9..data_end + 13].fill(0);
    let good = stream(&bytes, Payloads::All);
    assert_eq!((good.0.len(), good.1, good.2), (3, 1, false));

    // The third message on a channel never declared.
    let at = bytes.windows(5).position(|w| w == b"third").unwrap() - 22;
    bytes[at..at + 2].copy_from_slice(&99u16.to_le_bytes());
    let mut records = RecordStream::new(&bytes[..], Payloads::All);
    let mut handed_out = Vec::new();
    let err = loop {
        match records.next_record() {
            Ok(Some(record)) => handed_out.push(record),
            Ok(None) => panic!("no error"),
            Err(e) => break e,
        }
    };
    assert!(
        matches!(
            err,
            StreamError::Corrupt { reason: crate::Corruption::UndeclaredChannel { channel_id: 99 }, .. }
        ),
        "{err:?}"
    );
    assert!(
        !handed_out.iter().any(|r| matches!(r, Record::Message { .. } | Record::Channel(_))),
        "records of the bad chunk were handed out: {handed_out:?}"
    );
}
