//! The one streaming reader of a session file's records, shared by the
//! message reader, the linear-scan summary and the rewrite.
//!
//! It drives mcap's sans-IO [`LinearReader`] over any [`Read`], one block at
//! a time. A chunk is read whole, decompressed, CRC-checked and all its
//! records parsed (and every message's channel checked) before the first of
//! them is handed out, so memory holds one chunk at a time and a file cut
//! short (or corrupted) yields exactly its complete, valid chunks.

use std::collections::{HashMap, HashSet, VecDeque};
use std::io::{self, Read};
use std::path::Path;

use mcap::records::{self, MessageHeader, Record as McapRecord, op};
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};

use super::error::{Corruption, SessionError};

/// The largest record (a whole chunk, an attachment) a reader accepts (bytes).
pub(crate) const RECORD_LENGTH_LIMIT: usize = 256 << 20;
/// The most bytes read from the input at once.
const READ_BLOCK: usize = 1 << 20;

/// One record of the file, owned. Chunks are opened: their schemas, channels
/// and messages come as if they stood in the data section.
#[derive(Debug)]
pub(crate) enum Record {
    /// The header record's body, parsed only by those who need it (see
    /// [`parse_header`]), so that readers of messages never fail on it.
    Header(Vec<u8>),
    /// A schema.
    Schema {
        /// Schema id.
        id: u16,
        /// Schema name.
        name: String,
        /// Schema encoding.
        encoding: String,
        /// The schema itself.
        data: Vec<u8>,
    },
    /// A channel.
    Channel(records::Channel),
    /// A message; `data` is empty unless the stream keeps its channel's payloads.
    Message {
        /// Channel, sequence and times.
        header: MessageHeader,
        /// The payload.
        data: Vec<u8>,
    },
    /// An attachment.
    Attachment(mcap::Attachment<'static>),
    /// A metadata record.
    Metadata(records::Metadata),
    /// The end of the data section; the summary section follows.
    DataEnd,
}

/// Whose message payloads a stream keeps (the others come with empty data).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Payloads {
    /// Every message's.
    All,
    /// No message's (for counting).
    None,
    /// Those of the channels on these topics.
    Topics(HashSet<String>),
}

impl Payloads {
    fn keeps(&self, topic: &str) -> bool {
        match self {
            Payloads::All => true,
            Payloads::None => false,
            Payloads::Topics(topics) => topics.contains(topic),
        }
    }
}

/// Why a stream stopped before the end of its input.
#[derive(Debug)]
pub(crate) enum StreamError {
    /// Reading the input failed.
    Io(io::Error),
    /// The data is malformed.
    Corrupt {
        /// Bytes read from the input when the problem showed.
        bytes_read: u64,
        /// What is wrong.
        reason: Corruption,
    },
}

impl StreamError {
    /// The session error for the file at `path`.
    pub(crate) fn into_session_error(self, path: &Path) -> SessionError {
        match self {
            StreamError::Io(source) => SessionError::Read { path: path.to_path_buf(), source },
            StreamError::Corrupt { bytes_read, reason } => {
                SessionError::Corrupt { path: path.to_path_buf(), bytes_read, source: reason }
            }
        }
    }
}

/// A streaming reader of the records of one MCAP file, from its start.
pub(crate) struct RecordStream<R> {
    input: R,
    reader: LinearReader,
    payloads: Payloads,
    /// Declared channels: whether their payloads are kept.
    channels: HashMap<u16, bool>,
    bytes_read: u64,
    pending: VecDeque<Record>,
    complete_chunks: u64,
    done: bool,
}

impl<R: Read> RecordStream<R> {
    /// A stream of the records of `input` (a whole file from its start),
    /// keeping the message payloads `payloads` says.
    pub(crate) fn new(input: R, payloads: Payloads) -> Self {
        let options = LinearReaderOptions::default()
            .with_emit_chunks(true)
            .with_validate_data_section_crc(true)
            .with_record_length_limit(RECORD_LENGTH_LIMIT);
        RecordStream {
            input,
            reader: LinearReader::new_with_options(options),
            payloads,
            channels: HashMap::new(),
            bytes_read: 0,
            pending: VecDeque::new(),
            complete_chunks: 0,
            done: false,
        }
    }

    /// Chunks read completely and verified so far.
    pub(crate) fn complete_chunks(&self) -> u64 {
        self.complete_chunks
    }

    /// Bytes read from the input so far.
    pub(crate) fn bytes_read(&self) -> u64 {
        self.bytes_read
    }

    /// The next record; `Ok(None)` at the end of the file. After an error
    /// the stream is over: later calls return `Ok(None)`.
    pub(crate) fn next_record(&mut self) -> Result<Option<Record>, StreamError> {
        loop {
            if let Some(record) = self.pending.pop_front() {
                return Ok(Some(record));
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

    /// Reads one block or handles one record of the file; `Ok(false)` at its end.
    fn step(&mut self) -> Result<bool, StreamError> {
        let corrupt = |bytes_read, reason| StreamError::Corrupt { bytes_read, reason };
        let bytes_read = self.bytes_read;
        let mut parser = Parser { payloads: &self.payloads, channels: &mut self.channels };
        match self.reader.next_event() {
            None => Ok(false),
            Some(Err(e)) => Err(corrupt(bytes_read, Corruption::Mcap(e))),
            Some(Ok(LinearReadEvent::ReadRequest(need))) => {
                let buf = self.reader.insert(need.clamp(1, READ_BLOCK));
                match read_full(&mut self.input, buf) {
                    Ok(n) => {
                        self.reader.notify_read(n);
                        self.bytes_read += n as u64;
                        Ok(true)
                    }
                    Err(e) => {
                        self.reader.notify_read(0);
                        Err(StreamError::Io(e))
                    }
                }
            }
            Some(Ok(LinearReadEvent::Record { opcode: op::CHUNK, data })) => {
                let records = parser.chunk(data).map_err(|reason| corrupt(bytes_read, reason))?;
                self.complete_chunks += 1;
                self.pending.extend(records);
                Ok(true)
            }
            Some(Ok(LinearReadEvent::Record { opcode, data })) => {
                let record = parser.top_level(opcode, data).map_err(|reason| corrupt(bytes_read, reason))?;
                self.pending.extend(record);
                Ok(true)
            }
        }
    }
}

/// Turns record bodies into owned [`Record`]s.
struct Parser<'a> {
    payloads: &'a Payloads,
    channels: &'a mut HashMap<u16, bool>,
}

impl Parser<'_> {
    /// A record outside chunks; `None` for those nobody reads (indexes,
    /// statistics, the footer, unknown opcodes).
    fn top_level(&mut self, opcode: u8, data: &[u8]) -> Result<Option<Record>, Corruption> {
        match opcode {
            op::HEADER => Ok(Some(Record::Header(data.to_vec()))),
            op::DATA_END => Ok(Some(Record::DataEnd)),
            op::ATTACHMENT => parse_attachment(data).map(|a| Some(Record::Attachment(a))),
            op::METADATA => match parse(opcode, data)? {
                McapRecord::Metadata(m) => Ok(Some(Record::Metadata(m))),
                _ => Ok(None),
            },
            _ => self.data_record(opcode, data),
        }
    }

    /// A schema, channel or message record; `None` for any other.
    fn data_record(&mut self, opcode: u8, data: &[u8]) -> Result<Option<Record>, Corruption> {
        if !matches!(opcode, op::SCHEMA | op::CHANNEL | op::MESSAGE) {
            return Ok(None);
        }
        Ok(match parse(opcode, data)? {
            McapRecord::Schema { header, data } => Some(Record::Schema {
                id: header.id,
                name: header.name,
                encoding: header.encoding,
                data: data.into_owned(),
            }),
            McapRecord::Channel(c) => {
                self.channels.insert(c.id, self.payloads.keeps(&c.topic));
                Some(Record::Channel(c))
            }
            McapRecord::Message { header, data } => {
                let Some(&keep) = self.channels.get(&header.channel_id) else {
                    return Err(Corruption::UndeclaredChannel { channel_id: header.channel_id });
                };
                let data = if keep { data.into_owned() } else { Vec::new() };
                Some(Record::Message { header, data })
            }
            _ => None,
        })
    }

    /// The schemas, channels and messages of a chunk record (`data` is its
    /// body), all of them or an error. Other records in a chunk, which the
    /// MCAP specification does not allow there, are skipped.
    fn chunk(&mut self, data: &[u8]) -> Result<Vec<Record>, Corruption> {
        let mut inner = chunk_reader(data);
        let mut records = Vec::new();
        let mut eof_sent = false;
        while let Some(event) = inner.next_event() {
            match event {
                Ok(LinearReadEvent::ReadRequest(_)) if !eof_sent => {
                    inner.notify_read(0);
                    eof_sent = true;
                }
                Ok(LinearReadEvent::ReadRequest(_)) => return Err(Corruption::ChunkEndsEarly),
                Ok(LinearReadEvent::Record { opcode, data }) => {
                    records.extend(self.data_record(opcode, data)?);
                }
                Err(e) => return Err(Corruption::Chunk(e)),
            }
        }
        Ok(records)
    }
}

fn parse(opcode: u8, data: &[u8]) -> Result<McapRecord<'_>, Corruption> {
    mcap::parse_record(opcode, data).map_err(|source| Corruption::Record { opcode, source })
}

/// The header record of a [`Record::Header`] body.
pub(crate) fn parse_header(body: &[u8]) -> Result<records::Header, Corruption> {
    match parse(op::HEADER, body)? {
        McapRecord::Header(h) => Ok(h),
        // `parse_record` makes a header of every header record it parses.
        _ => Err(Corruption::Record { opcode: op::HEADER, source: mcap::McapError::UnexpectedEof }),
    }
}

/// A reader of one chunk record (`data` is its body) that decompresses the
/// chunk and checks its CRC before yielding any of its records.
fn chunk_reader(data: &[u8]) -> LinearReader {
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

/// An attachment record, parsed by hand (the `mcap` parser can panic on a
/// malformed one): times, name, media type, data. The CRC is not checked
/// (a rewrite recomputes it).
fn parse_attachment(body: &[u8]) -> Result<mcap::Attachment<'static>, Corruption> {
    fn string(buf: &[u8]) -> Option<(String, &[u8])> {
        let (len, rest) = buf.split_first_chunk::<4>()?;
        let len = u32::from_le_bytes(*len) as usize;
        let s = std::str::from_utf8(rest.get(..len)?).ok()?;
        Some((s.to_string(), rest.get(len..)?))
    }
    let parsed = (|| {
        let (log_time, rest) = body.split_first_chunk::<8>()?;
        let (create_time, rest) = rest.split_first_chunk::<8>()?;
        let (name, rest) = string(rest)?;
        let (media_type, rest) = string(rest)?;
        let (len, rest) = rest.split_first_chunk::<8>()?;
        let len = usize::try_from(u64::from_le_bytes(*len)).ok()?;
        let data = rest.get(..len)?;
        // The data, then a 4-byte CRC.
        (rest.len() == len.checked_add(4)?).then(|| mcap::Attachment {
            log_time: u64::from_le_bytes(*log_time),
            create_time: u64::from_le_bytes(*create_time),
            name,
            media_type,
            data: std::borrow::Cow::Owned(data.to_vec()),
        })
    })();
    parsed.ok_or(Corruption::Attachment)
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
