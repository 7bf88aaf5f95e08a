//! `slidetrack info`: what a session holds.

use anyhow::Result;
use serde_json::json;
use slidetrack_session::{ChannelMessage, ReadOptions, SessionInfo, TactileRaw, TaxelLayout};

use crate::cli::InfoArgs;

pub fn run(args: &InfoArgs) -> Result<()> {
    let info = SessionInfo::read(&args.file, ReadOptions { recover: args.recover })?;
    if info.truncated {
        eprintln!(
            "warning: {} is truncated (its writer did not finish); showing its {} complete chunk(s)",
            info.path.display(),
            info.chunk_count
        );
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&to_json(&info))?);
    } else {
        print!("{}", to_text(&info));
    }
    Ok(())
}

fn secs(t: Option<slidetrack_core::TimeNs>) -> Option<f64> {
    t.map(|t| t.as_secs_f64())
}

/// The JSON form of `info --json`.
pub fn to_json(info: &SessionInfo) -> serde_json::Value {
    let channels: Vec<_> = info
        .channels
        .iter()
        .map(|c| {
            json!({
                "topic": c.topic,
                "schema": c.schema_name,
                "encoding": c.message_encoding,
                "messages": c.message_count,
                "first_s": secs(c.first_log_time),
                "last_s": secs(c.last_log_time),
                "rate_hz": c.mean_rate_hz,
                "metadata": c.metadata,
            })
        })
        .collect();
    let attachments: Vec<_> = info
        .attachments
        .iter()
        .map(|a| json!({"name": a.name, "media_type": a.media_type, "bytes": a.size_bytes}))
        .collect();
    json!({
        "file": info.path,
        "bytes": info.file_size_bytes,
        "messages": info.message_count,
        "start_s": secs(info.start),
        "end_s": secs(info.end),
        "duration_s": info.duration.as_secs_f64(),
        "chunks": info.chunk_count,
        "truncated": info.truncated,
        "channels": channels,
        "metadata": info.metadata,
        "attachments": attachments,
    })
}

fn to_text(info: &SessionInfo) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let mb = info.file_size_bytes as f64 / 1e6;
    let _ = writeln!(s, "file:      {} ({mb:.1} MB, {} chunks)", info.path.display(), info.chunk_count);
    let _ = writeln!(s, "duration:  {:.3} s, {} messages", info.duration.as_secs_f64(), info.message_count);
    if let Some(m) = info.session_metadata() {
        let _ = writeln!(
            s,
            "session:   object {}, rig {}, trial {}, seed {}, slidetrack {}, started {}",
            m.object, m.rig, m.trial, m.seed, m.software_version, m.started_at
        );
    }
    if let Some(o) = info.outcome() {
        let status = match (&o.abort_reason, o.completed) {
            (Some(r), _) => format!("aborted: {r}"),
            (None, true) => "complete".into(),
            (None, false) => "incomplete".into(),
        };
        let _ = writeln!(s, "outcome:   {status}; {} images dropped", o.images_dropped);
    }
    let _ = writeln!(s, "channels:");
    let _ = writeln!(s, "  {:<22} {:<30} {:>9} {:>10}", "topic", "schema", "messages", "rate (Hz)");
    for c in &info.channels {
        let rate = c.mean_rate_hz.map_or("-".to_string(), |r| format!("{r:.2}"));
        let _ = writeln!(s, "  {:<22} {:<30} {:>9} {:>10}", c.topic, c.schema_name, c.message_count, rate);
    }
    if let Some(layout) = info
        .channel(TactileRaw::TOPIC)
        .and_then(|c| TaxelLayout::from_channel_metadata(&c.metadata))
        .and_then(Result::ok)
    {
        let sensors: Vec<String> =
            layout.sensors.iter().map(|l| format!("{} {} {}x{}", l.name, l.model, l.rows, l.cols)).collect();
        let taxels: u32 = layout.sensors.iter().map(|l| l.rows * l.cols).sum();
        let _ = writeln!(
            s,
            "tactile:   {} sensor(s) ({}), {taxels} taxels, {} values per scan",
            sensors.len(),
            sensors.join(", "),
            3 * taxels
        );
    }
    let other: Vec<_> = info.metadata.keys().filter(|k| !k.starts_with("slidetrack")).collect();
    if !other.is_empty() {
        let _ = writeln!(s, "metadata:  {}", other.iter().map(|k| k.as_str()).collect::<Vec<_>>().join(", "));
    }
    for a in &info.attachments {
        let _ = writeln!(s, "attachment: {} ({}, {} bytes)", a.name, a.media_type, a.size_bytes);
    }
    s
}
