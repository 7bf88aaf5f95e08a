//! The first pass of a rewrite: reads the whole input once, checks it and
//! finds the ids in use.

use std::collections::BTreeSet;
use std::io::Read;
use std::path::Path;

use crate::error::SessionError;
use crate::reader::ReadOptions;
use crate::records::{Payloads, Record, RecordStream, parse_header};
use crate::scan::{footer_summary_start, open_session, truncated_error};

/// One record to copy: the header (parsed), or any other record up to the
/// end of the data section.
pub(super) enum Item {
    Header(mcap::records::Header),
    Record(Record),
}

/// The next record of `records` to copy; `Ok(None)` at the end of the data
/// section. Indexes, statistics and the summary are rebuilt by the writer.
pub(super) fn next_item<R: Read>(
    path: &Path,
    records: &mut RecordStream<R>,
) -> Result<Option<Item>, SessionError> {
    match records.next_record().map_err(|e| e.into_session_error(path))? {
        None | Some(Record::DataEnd) => Ok(None),
        Some(Record::Header(body)) => parse_header(&body).map(|h| Some(Item::Header(h))).map_err(|source| {
            SessionError::Corrupt { path: path.to_path_buf(), bytes_read: records.bytes_read(), source }
        }),
        Some(record) => Ok(Some(Item::Record(record))),
    }
}

/// What the first pass learned.
pub(super) struct Survey {
    /// Records to copy (all, or those before the corrupt part with `recover`).
    pub(super) items: u64,
    pub(super) truncated: bool,
    pub(super) dropped_channels: BTreeSet<u16>,
    pub(super) dropped_schemas: BTreeSet<u16>,
    pub(super) next_schema_id: u32,
    pub(super) next_channel_id: u32,
}

/// Reads the whole input once: checks it, and finds the ids in use.
pub(super) fn survey(
    path: &Path,
    options: ReadOptions,
    dropped: &dyn Fn(&str) -> bool,
) -> Result<Survey, SessionError> {
    let (mut file, size) = open_session(path)?;
    let complete = footer_summary_start(&mut file, size)
        .map_err(|source| SessionError::Read { path: path.to_path_buf(), source })?
        .is_some();
    if !complete && !options.recover {
        return Err(truncated_error(path, file));
    }
    let mut records = RecordStream::new(file, Payloads::None);
    let (mut count, mut truncated) = (0u64, false);
    let mut schemas = BTreeSet::new();
    let mut kept_schemas = BTreeSet::new();
    let mut schemas_of_dropped = BTreeSet::new();
    let mut dropped_channels = BTreeSet::new();
    let mut max_channel = None::<u32>;
    loop {
        let item = match next_item(path, &mut records) {
            Ok(Some(Item::Record(record))) => record,
            Ok(Some(Item::Header(_))) => {
                count += 1;
                continue;
            }
            Ok(None) => break,
            Err(_) if options.recover => {
                truncated = true;
                break;
            }
            Err(e) => return Err(e),
        };
        count += 1;
        match item {
            Record::Channel(c) if dropped(&c.topic) => {
                dropped_channels.insert(c.id);
                schemas_of_dropped.insert(c.schema_id);
            }
            Record::Channel(c) => {
                kept_schemas.insert(c.schema_id);
                max_channel = max_channel.max(Some(u32::from(c.id)));
            }
            Record::Schema { id, .. } => {
                schemas.insert(id);
            }
            _ => {}
        }
    }
    let dropped_schemas: BTreeSet<u16> = schemas_of_dropped.difference(&kept_schemas).copied().collect();
    let max_kept_schema = schemas.difference(&dropped_schemas).max().map_or(0, |&id| u32::from(id));
    Ok(Survey {
        items: count,
        truncated: truncated || !complete,
        dropped_channels,
        next_schema_id: max_kept_schema + 1,
        next_channel_id: max_channel.map_or(0, |c| c + 1),
        dropped_schemas,
    })
}
