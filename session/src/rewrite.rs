//! Rewriting a finished session in place, atomically: every record is
//! copied unchanged (header, schemas, channels with their ids, messages with
//! their times, sequence numbers and payload bytes, attachments, metadata, in
//! file order) except the channels being replaced; new channels are merged in
//! by log time. The result goes to a temporary file in the same directory,
//! is synced, and renamed over the original. On any error the temporary file
//! is removed and the original is left as it was.
//!
//! The output depends only on the kept records and the new channels, so
//! rewriting a file twice with the same new channels gives the same bytes.

mod copy;
mod merge;
mod survey;
mod types;

use std::collections::BTreeSet;
use std::fs::File;
use std::path::{Path, PathBuf};

use super::error::{ReplaceStep, SessionError};
use super::reader::ReadOptions;
use copy::copy;
use survey::survey;
pub use types::{NewChannel, NewMessage, RewriteReport};

/// Replaces the channels whose topic `drop` accepts (and those on the topics
/// of `add`) by the channels of `add`, rewriting `path` atomically.
///
/// # Contract
/// - Without `options.recover`, a truncated or corrupt input fails before
///   anything is written. With it, the complete chunks of a truncated file
///   are kept and the output is a complete file.
/// - Kept schemas and channels keep their ids; new ones get ids above the
///   largest kept id. A schema used only by dropped channels is dropped.
/// - New messages go before the first kept message with a larger log time.
/// - The file's permissions are kept. On error the original is untouched.
pub fn rewrite_session(
    path: impl AsRef<Path>,
    options: ReadOptions,
    drop: &dyn Fn(&str) -> bool,
    mut add: Vec<NewChannel>,
) -> Result<RewriteReport, SessionError> {
    let path = path.as_ref();
    let replaced: BTreeSet<String> = add.iter().map(|c| c.topic.clone()).collect();
    let dropped = |topic: &str| drop(topic) || replaced.contains(topic);
    let survey = survey(path, options, &dropped)?;
    for channel in &mut add {
        channel.messages.sort_by_key(|m| m.log_time);
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path.file_name().map_or_else(|| "session".into(), |n| n.to_string_lossy().into_owned());
    let temp = tempfile::Builder::new()
        .prefix(&format!(".{name}."))
        .suffix(".tmp")
        .tempfile_in(&dir)
        .map_err(|source| SessionError::Create { path: dir.join(format!(".{name}.*.tmp")), source })?;
    let report = copy(path, temp.as_file(), &survey, add)?;
    let replace = |step| move |source| SessionError::Replace { path: path.to_path_buf(), step, source };
    temp.as_file().sync_all().map_err(replace(ReplaceStep::Sync))?;
    let permissions = std::fs::metadata(path).map_err(replace(ReplaceStep::ReadPermissions))?.permissions();
    std::fs::set_permissions(temp.path(), permissions).map_err(replace(ReplaceStep::SetPermissions))?;
    temp.persist(path).map_err(|e| replace(ReplaceStep::Rename)(e.error))?;
    if let Ok(d) = File::open(&dir) {
        // Makes the rename durable; not all file systems allow it.
        let _ = d.sync_all();
    }
    Ok(report)
}

#[cfg(test)]
mod tests;
