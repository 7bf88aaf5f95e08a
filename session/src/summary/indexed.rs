//! The fast path of [`SessionInfo::read`](crate::SessionInfo::read): the
//! summary section, parsed by mcap's own [`SummaryReader`], plus the message
//! indexes after each chunk (for per-channel first and last log times) and
//! the metadata records the metadata indexes point at.

use std::collections::{BTreeMap, HashMap};
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use mcap::Summary;
use mcap::records::{Record, op};
use mcap::sans_io::{SummaryReadEvent, SummaryReader, SummaryReaderOptions};
use slidetrack_core::TimeNs;

use super::info::{ChannelTally, Parts, SessionInfo};
use crate::error::{Corruption, SessionError};
use crate::records::{RECORD_LENGTH_LIMIT, read_full};
use crate::scan::FOOTER_AND_MAGIC;
use crate::stored::{AttachmentSummary, ChannelDesc};

/// Records that never stand in a summary section and that mcap's summary
/// reader cannot be given: it opens a chunk and parses the records in it, and
/// its attachment parser panics on a malformed attachment. Any other record
/// is parsed or skipped as the MCAP specification says.
const NOT_IN_SUMMARY: [u8; 2] = [op::CHUNK, op::ATTACHMENT];

/// The info from the summary section starting at `summary_start`, or
/// `Ok(None)` when the summary lacks what is needed (statistics, an index of
/// every channel, chunk, attachment and metadata record, message indexes)
/// and the file must be scanned.
pub(super) fn from_summary<R: Read + Seek>(
    path: &Path,
    input: &mut R,
    size: u64,
    summary_start: u64,
) -> Result<Option<SessionInfo>, SessionError> {
    let Some(summary) = read_summary(path, input, size, summary_start)? else {
        return Ok(None);
    };
    let Some(stats) = &summary.stats else { return Ok(None) };
    // The statistics count what the summary should index; a summary that
    // lacks some of it (a writer may leave any index out) is not used.
    let indexes_all = summary.channels.len() == stats.channel_count as usize
        && summary.chunk_indexes.len() == stats.chunk_count as usize
        && summary.attachment_indexes.len() == stats.attachment_count as usize
        && summary.metadata_indexes.len() == stats.metadata_count as usize;
    if !indexes_all {
        return Ok(None);
    }
    let mut file = IndexedFile { path, input, size };
    let Some(tallies) = file.message_tallies(&summary)? else { return Ok(None) };
    let indexed: u64 = tallies.values().map(|t| t.count).sum();
    if indexed != stats.message_count {
        return Ok(None);
    }
    let metadata = file.metadata(&summary)?;
    let mut channels: Vec<ChannelDesc> = summary
        .channels
        .values()
        .map(|c| ChannelDesc {
            id: c.id,
            topic: c.topic.clone(),
            schema_name: c.schema.as_ref().map(|s| s.name.clone()).unwrap_or_default(),
            schema_encoding: c.schema.as_ref().map(|s| s.encoding.clone()).unwrap_or_default(),
            message_encoding: c.message_encoding.clone(),
            metadata: c.metadata.clone(),
        })
        .collect();
    channels.sort_by_key(|c| c.id);
    let attachments = summary
        .attachment_indexes
        .iter()
        .map(|a| AttachmentSummary {
            name: a.name.clone(),
            media_type: a.media_type.clone(),
            size_bytes: a.data_size,
        })
        .collect();
    let chunk_count = u64::from(stats.chunk_count);
    let parts = Parts { channels, tallies, metadata, attachments, chunk_count };
    Ok(Some(parts.assemble(path, size, false)))
}

/// The summary section parsed by mcap's [`SummaryReader`], once it is known
/// to hold none of the records [`NOT_IN_SUMMARY`]. `None` when the file has
/// no summary.
fn read_summary<R: Read + Seek>(
    path: &Path,
    input: &mut R,
    size: u64,
    summary_start: u64,
) -> Result<Option<Summary>, SessionError> {
    let corrupt =
        |source| SessionError::Corrupt { path: path.to_path_buf(), bytes_read: summary_start, source };
    let footer_start = size.saturating_sub(FOOTER_AND_MAGIC);
    if summary_start > footer_start {
        return Err(corrupt(Corruption::SummaryStart { summary_start }));
    }
    // The summary section, the footer and the end magic.
    let tail = read_at(path, input, size, summary_start, size - summary_start)?
        .ok_or(corrupt(Corruption::SummaryTooLarge { length: footer_start - summary_start }))?;
    let summary_len = (footer_start - summary_start) as usize;
    for record in raw_records(&tail[..summary_len]) {
        let Ok((opcode, _)) = record else {
            return Err(corrupt(Corruption::Summary(mcap::McapError::UnexpectedEof)));
        };
        if NOT_IN_SUMMARY.contains(&opcode) {
            return Err(corrupt(Corruption::SummaryRecord { opcode }));
        }
    }

    let options =
        SummaryReaderOptions::default().with_file_size(size).with_record_length_limit(RECORD_LENGTH_LIMIT);
    let mut reader = SummaryReader::new_with_options(options);
    let mut pos = summary_start;
    while let Some(event) = reader.next_event() {
        match event.map_err(|e| corrupt(Corruption::Summary(e)))? {
            SummaryReadEvent::SeekRequest(to) => {
                let to = match to {
                    SeekFrom::Start(p) => Some(p),
                    SeekFrom::End(d) => size.checked_add_signed(d),
                    SeekFrom::Current(d) => pos.checked_add_signed(d),
                };
                // The reader only ever seeks to the footer and to the summary.
                pos = to
                    .filter(|p| (summary_start..=size).contains(p))
                    .ok_or(corrupt(Corruption::Summary(mcap::McapError::BadFooter)))?;
                reader.notify_seeked(pos);
            }
            SummaryReadEvent::ReadRequest(n) => {
                let from = usize::try_from(pos - summary_start).unwrap_or(usize::MAX).min(tail.len());
                let available = &tail[from..];
                let n = n.min(available.len());
                reader.insert(n).copy_from_slice(&available[..n]);
                reader.notify_read(n);
                pos += n as u64;
            }
        }
    }
    Ok(reader.finish())
}

/// Index lookups in the file, record by record.
struct IndexedFile<'a, R> {
    path: &'a Path,
    input: &'a mut R,
    size: u64,
}

impl<R: Read + Seek> IndexedFile<'_, R> {
    /// Per-channel counts and first and last log times, from the message
    /// indexes after each chunk; `None` when a chunk has no message index.
    fn message_tallies(
        &mut self,
        summary: &Summary,
    ) -> Result<Option<HashMap<u16, ChannelTally>>, SessionError> {
        let mut tallies: HashMap<u16, ChannelTally> = HashMap::new();
        for chunk in &summary.chunk_indexes {
            if chunk.message_index_offsets.is_empty() && chunk.message_index_length == 0 {
                return Ok(None);
            }
            let offset = chunk.chunk_start_offset.saturating_add(chunk.chunk_length);
            let length = chunk.message_index_length;
            let indexes = self.record_at("message", offset, length)?;
            for record in raw_records(&indexes) {
                let Ok((opcode, body)) = record else {
                    return Err(self.bad_index("message", offset, length));
                };
                if opcode != op::MESSAGE_INDEX {
                    continue;
                }
                if let Ok(Record::MessageIndex(index)) = mcap::parse_record(opcode, body) {
                    let tally = tallies.entry(index.channel_id).or_default();
                    index.records.iter().for_each(|e| tally.add(TimeNs(e.log_time)));
                }
            }
        }
        Ok(Some(tallies))
    }

    /// The metadata records, by name, that the metadata indexes point at.
    fn metadata(
        &mut self,
        summary: &Summary,
    ) -> Result<BTreeMap<String, BTreeMap<String, String>>, SessionError> {
        let mut metadata = BTreeMap::new();
        for index in &summary.metadata_indexes {
            let record = self.record_at("metadata", index.offset, index.length)?;
            let parsed = raw_records(&record).next().and_then(Result::ok);
            match parsed.map(|(opcode, body)| (opcode, mcap::parse_record(opcode, body))) {
                Some((op::METADATA, Ok(Record::Metadata(m)))) => {
                    metadata.insert(m.name, m.metadata);
                }
                _ => return Err(self.bad_index("metadata", index.offset, index.length)),
            }
        }
        Ok(metadata)
    }

    /// The `length` bytes at `offset` that an index of kind `index` points at.
    fn record_at(&mut self, index: &'static str, offset: u64, length: u64) -> Result<Vec<u8>, SessionError> {
        read_at(self.path, self.input, self.size, offset, length)?
            .ok_or_else(|| self.bad_index(index, offset, length))
    }

    fn bad_index(&self, index: &'static str, offset: u64, length: u64) -> SessionError {
        let source = Corruption::Index { index, offset, length };
        SessionError::Corrupt { path: self.path.to_path_buf(), bytes_read: offset, source }
    }
}

/// The `len` bytes at `offset`; `None` when they lie beyond the end of the
/// file or exceed the record length limit.
fn read_at(
    path: &Path,
    input: &mut (impl Read + Seek),
    size: u64,
    offset: u64,
    len: u64,
) -> Result<Option<Vec<u8>>, SessionError> {
    if len > RECORD_LENGTH_LIMIT as u64 || offset.checked_add(len).is_none_or(|end| end > size) {
        return Ok(None);
    }
    let read_err = |source| SessionError::Read { path: path.to_path_buf(), source };
    let mut buf = vec![0u8; len as usize];
    input.seek(SeekFrom::Start(offset)).map_err(read_err)?;
    let got = read_full(input, &mut buf).map_err(read_err)?;
    Ok((got == buf.len()).then_some(buf))
}

/// Splits a buffer of raw records into `(opcode, body)`; `Err(())` at the
/// first record that runs past the end of the buffer.
fn raw_records(mut buf: &[u8]) -> impl Iterator<Item = Result<(u8, &[u8]), ()>> {
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
