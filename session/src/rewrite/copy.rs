//! The second pass of a rewrite: copies the kept records into the new file
//! and merges the new channels in.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use slidetrack_core::TimeNs;

use super::merge::Merge;
use super::survey::{Item, Survey, next_item};
use super::types::{NewChannel, RewriteReport, Writer};
use crate::error::{SessionError, WriteFailure};
use crate::records::{Payloads, Record, RecordStream};
use crate::scan::open_session;

/// Chunks of the rewritten file close at this uncompressed size (bytes), as the recorder's do.
const CHUNK_SIZE_BYTES: u64 = 4 << 20;

/// Writes the merged file into `out`.
pub(super) fn copy(
    path: &Path,
    out: &File,
    survey: &Survey,
    add: Vec<NewChannel>,
) -> Result<RewriteReport, SessionError> {
    let fail = |e: mcap::McapError| {
        let source = WriteFailure::from(e);
        SessionError::Write { path: path.to_path_buf(), kind: source.io_kind(), source }
    };
    let (file, _) = open_session(path)?;
    let mut records = RecordStream::new(file, Payloads::All);
    let mut writer: Option<Writer<'_>> = None;
    let mut merge = Merge::new(path, add, survey)?;
    let mut report = RewriteReport { truncated: survey.truncated, ..RewriteReport::default() };
    for _ in 0..survey.items {
        let Some(item) = next_item(path, &mut records)? else { break };
        let record = match (&mut writer, item) {
            (None, Item::Header(h)) => {
                writer = Some(new_writer(out, &h.profile, &h.library).map_err(fail)?);
                continue;
            }
            (Some(_), Item::Header(_)) => continue,
            (_, Item::Record(record)) => record,
        };
        let w = match &mut writer {
            Some(w) => w,
            None => writer.insert(new_writer(out, "", "").map_err(fail)?),
        };
        write_record(w, record, survey, &mut merge, &mut report).map_err(fail)?;
    }
    let w = match &mut writer {
        Some(w) => w,
        None => writer.insert(new_writer(out, "", "").map_err(fail)?),
    };
    report.messages_added += merge.write_before(w, TimeNs(u64::MAX)).map_err(fail)?;
    merge.declare_empty(w).map_err(fail)?;
    if let Some(mut w) = writer {
        w.finish().map_err(fail)?;
        let buffered = w.into_inner();
        buffered.into_inner().map_err(|e| fail(mcap::McapError::Io(e.into_error())))?;
    }
    Ok(report)
}

/// Copies one record unless its channel or schema is dropped, after the new
/// messages that come before it.
fn write_record(
    w: &mut Writer<'_>,
    record: Record,
    survey: &Survey,
    merge: &mut Merge,
    report: &mut RewriteReport,
) -> Result<(), mcap::McapError> {
    match record {
        Record::Header(_) | Record::DataEnd => {}
        Record::Schema { id, .. } if survey.dropped_schemas.contains(&id) => {}
        Record::Schema { id, name, encoding, data } => {
            w.add_schema_with_id(id, &name, &encoding, &data)?;
        }
        Record::Channel(c) if survey.dropped_channels.contains(&c.id) => {}
        Record::Channel(c) => {
            w.add_channel_with_id(c.id, c.schema_id, &c.topic, &c.message_encoding, &c.metadata)?;
        }
        Record::Message { header, .. } if survey.dropped_channels.contains(&header.channel_id) => {
            report.messages_dropped += 1;
        }
        Record::Message { header, data } => {
            report.messages_added += merge.write_before(w, TimeNs(header.log_time))?;
            w.write_to_known_channel(&header, &data)?;
            report.messages_copied += 1;
        }
        Record::Attachment(a) => w.attach(&a)?,
        Record::Metadata(m) => w.write_metadata(&m)?,
    }
    Ok(())
}

fn new_writer<'a>(out: &'a File, profile: &str, library: &str) -> Result<Writer<'a>, mcap::McapError> {
    let options = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .compression_level(1)
        .compression_threads(0)
        .chunk_size(Some(CHUNK_SIZE_BYTES))
        .profile(profile)
        .library(library);
    mcap::Writer::with_options(BufWriter::with_capacity(256 << 10, out), options)
}
