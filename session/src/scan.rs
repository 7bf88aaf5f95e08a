//! A linear scan of a session file with bounded memory: records are streamed
//! from the file, and a chunk's messages are handed out only once the whole
//! chunk has been read, decompressed and its CRC checked. A file cut short
//! therefore yields exactly its complete chunks.

use std::collections::{BTreeMap, HashMap, HashSet, VecDeque};
use std::fs::File;
use std::io::{self, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use mcap::records::{Record, op};
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use slidetrack_core::TimeNs;

use super::error::SessionError;
use super::reader::{ChannelDesc, RawMessage};
use super::summary::AttachmentSummary;

/// The largest record (a whole chunk, an attachment) a reader accepts (bytes).
pub(crate) const RECORD_LENGTH_LIMIT: usize = 256 << 20;
/// The most bytes read from the file at once.
const READ_BLOCK: usize = 1 << 20;
/// Footer record (1 + 8 + 20 bytes) and end magic (8 bytes).
pub(crate) const FOOTER_AND_MAGIC: u64 = 37;

/// Opens a session file, checking that it is an MCAP file. Returns the file
/// (positioned at 0) and its size.
pub(crate) fn open_session(path: &Path) -> Result<(File, u64), SessionError> {
    let read_err = |source| SessionError::Read { path: path.to_path_buf(), source };
    let mut file = File::open(path).map_err(|e| SessionError::open(path, e))?;
    let meta = file.metadata().map_err(read_err)?;
    if meta.is_dir() {
        return Err(read_err(io::Error::new(io::ErrorKind::IsADirectory, "is a directory")));
    }
    let size = meta.len();
    if size == 0 {
        return Err(SessionError::Empty { path: path.to_path_buf() });
    }
    let mut magic = [0u8; 8];
    let got = read_full(&mut file, &mut magic).map_err(read_err)?;
    if got < magic.len() || magic != mcap::MAGIC {
        return Err(SessionError::NotMcap { path: path.to_path_buf() });
    }
    file.seek(SeekFrom::Start(0)).map_err(read_err)?;
    Ok((file, size))
}

/// Reads until `buf` is full or the input ends; returns the bytes read.
pub(crate) fn read_full(input: &mut impl Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match input.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}

/// The footer's `summary_start`, or `None` when the file does not end with a
/// footer and the end magic (its writer did not finish).
pub(crate) fn footer_summary_start(input: &mut (impl Read + Seek), size: u64) -> io::Result<Option<u64>> {
    if size < 8 + FOOTER_AND_MAGIC {
        return Ok(None);
    }
    let mut tail = [0u8; FOOTER_AND_MAGIC as usize];
    input.seek(SeekFrom::Start(size - FOOTER_AND_MAGIC))?;
    let got = read_full(input, &mut tail)?;
    input.seek(SeekFrom::Start(0))?;
    let (record, magic) = tail.split_at(29);
    let len = u64::from_le_bytes(record[1..9].try_into().unwrap_or_default());
    if got < tail.len() || record[0] != op::FOOTER || len != 20 || magic != mcap::MAGIC {
        return Ok(None);
    }
    Ok(Some(u64::from_le_bytes(record[9..17].try_into().unwrap_or_default())))
}

/// Splits a buffer of raw records into `(opcode, body)`; `Err(())` at the
/// first record that runs past the end of the buffer.
pub(crate) fn raw_records(mut buf: &[u8]) -> impl Iterator<Item = Result<(u8, &[u8]), ()>> {
    std::iter::from_fn(move || {
        if buf.is_empty() {
            return None;
        }
        let parsed = (|| {
            let (&opcode, rest) = buf.split_first()?;
            let (len, rest) = rest.split_first_chunk::<8>()?;
            let len = usize::try_from(u64::from_le_bytes(*len)).ok()?;
            let body = rest.get(..len)?;
            Some((opcode, body, rest.get(len..)?))
        })();
        match parsed {
            Some((opcode, body, rest)) => {
                buf = rest;
                Some(Ok((opcode, body)))
            }
            None => {
                buf = &[];
                Some(Err(()))
            }
        }
    })
}

/// Name, media type and size of an attachment record, parsed by hand (the
/// `mcap` parser can panic on a malformed attachment).
pub(crate) fn parse_attachment(body: &[u8]) -> Option<AttachmentSummary> {
    fn string(buf: &[u8]) -> Option<(String, &[u8])> {
        let (len, rest) = buf.split_first_chunk::<4>()?;
        let len = u32::from_le_bytes(*len) as usize;
        let s = std::str::from_utf8(rest.get(..len)?).ok()?;
        Some((s.to_string(), rest.get(len..)?))
    }
    let rest = body.get(16..)?; // log_time, create_time
    let (name, rest) = string(rest)?;
    let (media_type, rest) = string(rest)?;
    let (len, rest) = rest.split_first_chunk::<8>()?;
    let size_bytes = u64::from_le_bytes(*len);
    // data, then a 4-byte CRC
    (rest.len() as u64 == size_bytes.checked_add(4)?).then_some(AttachmentSummary {
        name,
        media_type,
        size_bytes,
    })
}

/// What a scan yields besides messages.
pub(crate) enum Event {
    Message(RawMessage),
    Metadata { name: String, map: BTreeMap<String, String> },
    Attachment(AttachmentSummary),
}

/// Why a scan stopped before the end of the file.
#[derive(Debug)]
pub(crate) struct ScanError {
    pub(crate) bytes_read: u64,
    pub(crate) detail: String,
    /// The input itself failed (not the data in it).
    pub(crate) io: Option<io::Error>,
}

/// Messages seen in a group of records.
#[derive(Default)]
struct Tally {
    messages: u64,
    last_log_time: Option<TimeNs>,
}

/// A streaming reader of one session file.
pub(crate) struct Scanner<R> {
    pub(crate) path: PathBuf,
    input: R,
    reader: LinearReader,
    bytes_read: u64,
    schemas: HashMap<u16, (String, String)>,
    pub(crate) channels: BTreeMap<u16, Arc<ChannelDesc>>,
    topics: Option<HashSet<String>>,
    keep_data: bool,
    pending: VecDeque<Event>,
    /// Chunks read completely and verified.
    pub(crate) complete_chunks: u64,
    /// Messages handed out or counted, in complete chunks.
    pub(crate) messages: u64,
    /// The latest log time among those messages.
    pub(crate) last_log_time: Option<TimeNs>,
    done: bool,
}

impl<R: Read> Scanner<R> {
    /// A scanner of `input` (the whole file from its start). Only messages on
    /// `topics` (all when `None`) are yielded, without payload unless `keep_data`.
    pub(crate) fn new(path: &Path, input: R, topics: Option<HashSet<String>>, keep_data: bool) -> Self {
        let options = LinearReaderOptions::default()
            .with_emit_chunks(true)
            .with_validate_data_section_crc(true)
            .with_record_length_limit(RECORD_LENGTH_LIMIT);
        Scanner {
            path: path.to_path_buf(),
            input,
            reader: LinearReader::new_with_options(options),
            bytes_read: 0,
            schemas: HashMap::new(),
            channels: BTreeMap::new(),
            topics,
            keep_data,
            pending: VecDeque::new(),
            complete_chunks: 0,
            messages: 0,
            last_log_time: None,
            done: false,
        }
    }

    fn error(&self, detail: impl Into<String>) -> ScanError {
        ScanError { bytes_read: self.bytes_read, detail: detail.into(), io: None }
    }

    /// The next event; `Ok(None)` at the end of a complete file. After an
    /// error the scan is over and later calls return `Ok(None)`.
    pub(crate) fn next_event(&mut self) -> Result<Option<Event>, ScanError> {
        loop {
            if let Some(event) = self.pending.pop_front() {
                return Ok(Some(event));
            }
            if self.done {
                return Ok(None);
            }
            match self.step() {
                Ok(true) => {}
                Ok(false) => self.done = true,
                Err(e) => {
                    self.done = true;
                    return Err(e);
                }
            }
        }
    }

    /// Processes one record of the file; `Ok(false)` at its end.
    fn step(&mut self) -> Result<bool, ScanError> {
        let (opcode, data) = match self.reader.next_event() {
            None => return Ok(false),
            Some(Err(e)) => return Err(self.error(e.to_string())),
            Some(Ok(LinearReadEvent::ReadRequest(need))) => {
                let buf = self.reader.insert(need.clamp(1, READ_BLOCK));
                let n = match read_full(&mut self.input, buf) {
                    Ok(n) => n,
                    Err(e) => {
                        self.reader.notify_read(0);
                        let detail = e.to_string();
                        return Err(ScanError { bytes_read: self.bytes_read, detail, io: Some(e) });
                    }
                };
                self.reader.notify_read(n);
                self.bytes_read += n as u64;
                return Ok(true);
            }
            Some(Ok(LinearReadEvent::Record { opcode: op::CHUNK, data })) => {
                let inner = chunk_reader(data);
                return self.read_chunk(inner).map(|()| true);
            }
            Some(Ok(LinearReadEvent::Record { opcode, data })) => (opcode, data.to_vec()),
        };
        match opcode {
            op::SCHEMA | op::CHANNEL | op::MESSAGE => {
                let mut out = VecDeque::new();
                let mut tally = Tally::default();
                self.record(opcode, &data, &mut out, &mut tally)?;
                self.add(tally);
                self.pending.extend(out);
            }
            op::METADATA => match mcap::parse_record(opcode, &data) {
                Ok(Record::Metadata(m)) => {
                    self.pending.push_back(Event::Metadata { name: m.name, map: m.metadata });
                }
                Ok(_) => {}
                Err(e) => return Err(self.error(format!("bad metadata record: {e}"))),
            },
            op::ATTACHMENT => match parse_attachment(&data) {
                Some(a) => self.pending.push_back(Event::Attachment(a)),
                None => return Err(self.error("bad attachment record")),
            },
            _ => {}
        }
        Ok(true)
    }

    /// Drains a chunk's reader (see [`chunk_reader`]); queues the chunk's
    /// events only when all of it was read.
    fn read_chunk(&mut self, mut inner: LinearReader) -> Result<(), ScanError> {
        let mut out = VecDeque::new();
        let mut tally = Tally::default();
        let mut eof_sent = false;
        while let Some(event) = inner.next_event() {
            match event {
                Ok(LinearReadEvent::ReadRequest(_)) if !eof_sent => {
                    inner.notify_read(0);
                    eof_sent = true;
                }
                Ok(LinearReadEvent::ReadRequest(_)) => return Err(self.error("chunk ends early")),
                Ok(LinearReadEvent::Record { opcode, data }) => {
                    self.record(opcode, data, &mut out, &mut tally)?;
                }
                Err(e) => return Err(self.error(format!("bad chunk: {e}"))),
            }
        }
        self.complete_chunks += 1;
        self.add(tally);
        self.pending.extend(out);
        Ok(())
    }

    fn add(&mut self, tally: Tally) {
        self.messages += tally.messages;
        self.last_log_time = self.last_log_time.max(tally.last_log_time);
    }

    /// Handles a schema, channel or message record.
    fn record(
        &mut self,
        opcode: u8,
        data: &[u8],
        out: &mut VecDeque<Event>,
        tally: &mut Tally,
    ) -> Result<(), ScanError> {
        let record = match opcode {
            op::SCHEMA | op::CHANNEL | op::MESSAGE => mcap::parse_record(opcode, data)
                .map_err(|e| self.error(format!("bad record {opcode:#04x}: {e}")))?,
            _ => return Ok(()),
        };
        match record {
            Record::Schema { header, .. } => {
                self.schemas.insert(header.id, (header.name, header.encoding));
            }
            Record::Channel(c) => {
                let (schema_name, schema_encoding) =
                    self.schemas.get(&c.schema_id).cloned().unwrap_or_default();
                let desc = ChannelDesc {
                    id: c.id,
                    topic: c.topic,
                    schema_name,
                    schema_encoding,
                    message_encoding: c.message_encoding,
                    metadata: c.metadata,
                };
                self.channels.insert(c.id, Arc::new(desc));
            }
            Record::Message { header, data } => {
                let Some(channel) = self.channels.get(&header.channel_id) else {
                    let id = header.channel_id;
                    return Err(self.error(format!("message on undeclared channel id {id}")));
                };
                let log_time = TimeNs(header.log_time);
                tally.messages += 1;
                tally.last_log_time = tally.last_log_time.max(Some(log_time));
                if self.topics.as_ref().is_none_or(|t| t.contains(&channel.topic)) {
                    out.push_back(Event::Message(RawMessage {
                        channel: Arc::clone(channel),
                        log_time,
                        publish_time: TimeNs(header.publish_time),
                        sequence: header.sequence,
                        data: if self.keep_data { data.into_owned() } else { Vec::new() },
                    }));
                }
            }
            _ => {}
        }
        Ok(())
    }
}

/// A reader of one chunk record (`data` is its body) that decompresses the
/// chunk and checks its CRC before yielding any of its records.
pub(crate) fn chunk_reader(data: &[u8]) -> LinearReader {
    let options = LinearReaderOptions::default()
        .with_skip_start_magic(true)
        .with_skip_end_magic(true)
        .with_prevalidate_chunk_crcs(true)
        .with_record_length_limit(RECORD_LENGTH_LIMIT);
    let mut inner = LinearReader::new_with_options(options);
    let buf = inner.insert(9 + data.len());
    buf[0] = op::CHUNK;
    buf[1..9].copy_from_slice(&(data.len() as u64).to_le_bytes());
    buf[9..].copy_from_slice(data);
    inner.notify_read(9 + data.len());
    inner
}

/// The error of a file that ends before its footer, after counting what is readable.
pub(crate) fn truncated_error<R: Read>(path: &Path, input: R) -> SessionError {
    let mut scan = Scanner::new(path, input, Some(HashSet::new()), false);
    while let Ok(Some(_)) = scan.next_event() {}
    SessionError::Truncated {
        path: path.to_path_buf(),
        readable_messages: scan.messages,
        complete_chunks: scan.complete_chunks,
        readable_until: scan.last_log_time,
    }
}

/// Maps a scan error onto a session error.
pub(crate) fn corrupt(path: &Path, e: ScanError) -> SessionError {
    match e.io {
        Some(source) => SessionError::Read { path: path.to_path_buf(), source },
        None => {
            SessionError::Corrupt { path: path.to_path_buf(), bytes_read: e.bytes_read, detail: e.detail }
        }
    }
}
