//! `/rgbd/depth` stored as 16-bit PNG (`foxglove.CompressedImage`): every
//! value comes back exactly, through slidetrack's reader and through the
//! official Python MCAP reader with a PNG decoder of its own, in at most a
//! quarter of the bytes of the `16UC1` `foxglove.RawImage` form written
//! before, which both readers still read.
//!
//! The numbers it prints are those of `docs/session-format.md`:
//! `cargo test --test depth_storage -- --nocapture`.

#![expect(clippy::unwrap_used, reason = "test code: a failed unwrap is a failed test")]

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use common::{ok, python, tempdir};
use slidetrack_core::{DepthImage, TimeNs};
use slidetrack_session::{
    ChannelMessage, MessageReader, RawImage, ReadOptions, Recorder, RecorderOptions, RgbdDepth,
};

/// The depth frames of `session`, in log-time order, and each message's bytes.
fn depth_frames(session: &Path) -> Vec<(TimeNs, RgbdDepth, usize)> {
    MessageReader::open(session, &[RgbdDepth::TOPIC], ReadOptions::default())
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            (m.log_time, serde_json::from_slice(&m.data).unwrap(), m.data.len())
        })
        .collect()
}

/// A session holding `frames` on `/rgbd/depth` in the form written before
/// (`foxglove.RawImage`, `16UC1`), as an older slidetrack wrote it.
fn old_form_session(path: &Path, frames: &[(TimeNs, DepthImage)]) {
    let options = RecorderOptions { overwrite: true, ..RecorderOptions::default() };
    let recorder = Recorder::create_with_options(path, BTreeMap::new(), options).unwrap();
    let schema = include_str!("../session/schemas/foxglove/RawImage.json");
    let channel = recorder
        .register_channel(
            "/rgbd/depth",
            "foxglove.RawImage",
            "jsonschema",
            schema.as_bytes(),
            "json",
            BTreeMap::new(),
        )
        .unwrap();
    for (t, depth) in frames {
        let message = serde_json::to_vec(&RawImage::depth(*t, "camera", depth)).unwrap();
        recorder.log(&channel, *t, *t, 0, message).unwrap();
    }
    recorder.finish().unwrap();
}

/// The values of every frame as the Python check decodes them, and its summary.
fn python_values(session: &Path, out: &Path) -> (Vec<u8>, serde_json::Value) {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/check_depth.py");
    let run = std::process::Command::new(python()).arg(script).arg(session).arg(out).output().unwrap();
    assert!(run.status.success(), "check_depth.py: {}", String::from_utf8_lossy(&run.stderr));
    let summary = serde_json::from_slice(&run.stdout).unwrap();
    (std::fs::read(out).unwrap(), summary)
}

fn le_bytes(frames: &[(TimeNs, DepthImage)]) -> Vec<u8> {
    frames.iter().flat_map(|(_, d)| d.data.iter().flat_map(|v| v.to_le_bytes())).collect()
}

fn file_len(path: &Path) -> u64 {
    std::fs::metadata(path).unwrap().len()
}

/// Stores `frames` in both forms under `dir/name-*.mcap`, checks both
/// readers on both and the sizes, and prints them (bytes per frame).
/// Both sessions hold `/rgbd/depth` alone, so that their file sizes compare.
fn stored_both_ways(dir: &Path, name: &str, frames: &[(TimeNs, DepthImage)]) {
    let new = dir.join(format!("{name}-png.mcap"));
    let options = RecorderOptions { overwrite: true, ..RecorderOptions::default() };
    let recorder = Recorder::create_with_options(&new, BTreeMap::new(), options).unwrap();
    let channel = recorder.register::<RgbdDepth>(BTreeMap::new()).unwrap();
    for (t, depth) in frames {
        recorder.log_json(&channel, *t, *t, 0, &RgbdDepth::new(*t, "camera", depth).unwrap()).unwrap();
    }
    recorder.finish().unwrap();
    let old = dir.join(format!("{name}-16uc1.mcap"));
    old_form_session(&old, frames);

    // slidetrack's reader: both forms, every value.
    let (read_new, read_old) = (depth_frames(&new), depth_frames(&old));
    assert_eq!(read_new.len(), frames.len());
    for ((t, expected), ((tn, n, _), (to, o, _))) in frames.iter().zip(read_new.iter().zip(&read_old)) {
        assert!(matches!(n, RgbdDepth::Png(_)) && matches!(o, RgbdDepth::Raw(_)));
        assert_eq!((tn, to), (t, t));
        assert_eq!(&n.to_depth().unwrap(), expected, "PNG form at {t:?}");
        assert_eq!(&o.to_depth().unwrap(), expected, "16UC1 form at {t:?}");
    }
    // The official reader with an independent PNG decoder: both forms, every value.
    let expected = le_bytes(frames);
    let (values, summary) = python_values(&new, &dir.join(format!("{name}-png.u16")));
    assert!(values == expected, "the Python decoder disagrees on the PNG form ({summary})");
    assert_eq!(summary["forms"], serde_json::json!(["png"]));
    let (values, summary) = python_values(&old, &dir.join(format!("{name}-16uc1.u16")));
    assert!(values == expected, "the Python decoder disagrees on the 16UC1 form ({summary})");

    let n = frames.len();
    let message = |r: &[(TimeNs, RgbdDepth, usize)]| r.iter().map(|m| m.2).sum::<usize>() / n;
    let (new_message, old_message) = (message(&read_new), message(&read_old));
    let (new_file, old_file) = (file_len(&new) as usize / n, file_len(&old) as usize / n);
    let (w, h) = (frames[0].1.width, frames[0].1.height);
    println!(
        "{name}: {n} frames {w}x{h} px; bytes per frame: message {old_message} (16UC1) -> {new_message} (PNG), \
         {:.1}x; in the file (zstd chunks) {old_file} -> {new_file}, {:.1}x ({:.1}x below a 16UC1 message)",
        old_message as f64 / new_message as f64,
        old_file as f64 / new_file as f64,
        old_message as f64 / new_file as f64
    );
    // Today's bytes per frame are the 16UC1 message's: a quarter of them at
    // most, in the message and in the file; and never more than the old
    // form in the file after its chunk compression.
    assert!(4 * new_message <= old_message, "{name}: messages {new_message} vs {old_message} bytes");
    assert!(4 * new_file <= old_message, "{name}: file {new_file} vs message {old_message} bytes per frame");
    assert!(new_file <= old_file, "{name}: file {new_file} vs {old_file} bytes per frame");
}

/// The rendered depth of `slidetrack vision simulate`, written by the command.
#[test]
fn simulated_depth_is_exact_and_a_quarter_of_the_old_size() {
    let dir = tempdir();
    let session = dir.path().join("sim.mcap");
    let s = session.to_str().unwrap();
    ok(&["-q", "vision", "simulate", "--duration", "1", "--seed", "3", "--out", s]);
    let frames: Vec<(TimeNs, DepthImage)> =
        depth_frames(&session).into_iter().map(|(t, m, _)| (t, m.to_depth().unwrap())).collect();
    assert_eq!(frames.len(), 30);
    assert!(frames.iter().all(|(_, d)| d.data.iter().any(|v| *v > 0)), "depth in every frame");
    stored_both_ways(dir.path(), "vision simulate", &frames);
}

/// Real sensor depth (YCB-Video, `../shared/testdata/rgbd`), in millimetres
/// as sessions store it: noisier than rendered depth, so it compresses less.
#[test]
fn real_depth_is_exact_and_a_quarter_of_the_old_size() {
    let dir = tempdir();
    let frames_dir =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/testdata/rgbd/ycbv-0000/data/0000");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&frames_dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().ends_with("-depth.png"))
        .collect();
    files.sort();
    assert_eq!(files.len(), 10);
    let frames: Vec<(TimeNs, DepthImage)> = files
        .iter()
        .enumerate()
        .map(|(k, path)| {
            let png = std::fs::read(path).unwrap();
            // YCB-Video stores 0.1 mm units: the session's millimetres.
            let depth = slidetrack_vision::input::decode_depth(&png, 1e-4).unwrap().to_millimetres();
            (TimeNs(k as u64 * 33_333_333), depth)
        })
        .collect();
    stored_both_ways(dir.path(), "YCB-Video 0000", &frames);
}
