//! A session written by the recorder, read by the official Python reader.

use std::collections::BTreeMap;
use std::process::Command;

use serde_json::{Value, json};

use super::*;

const SCRIPT: &str = r#"
import base64, json, sys
from mcap.reader import make_reader

counts, first, layout = {}, {}, None
with open(sys.argv[1], "rb") as f:
    reader = make_reader(f)
    for schema, channel, message in reader.iter_messages():
        data = json.loads(message.data)
        topic = channel.topic
        props = json.loads(schema.data)["properties"]
        if set(data) != set(props):
            sys.exit(f"{topic}: fields {sorted(data)} != schema properties {sorted(props)}")
        if channel.message_encoding != "json" or schema.encoding != "jsonschema":
            sys.exit(f"{topic}: encodings {channel.message_encoding} {schema.encoding}")
        counts[topic] = counts.get(topic, 0) + 1
        if topic == "/camera/image":
            data["data"] = list(base64.b64decode(data["data"]))
        if topic == "/tactile/raw":
            layout = json.loads(channel.metadata["taxel_layout"])
        first.setdefault(topic, {"data": data, "log_time": message.log_time,
                                 "publish_time": message.publish_time,
                                 "sequence": message.sequence, "schema": schema.name})
    metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    attachments = [[a.name, a.media_type, a.data.decode()] for a in reader.iter_attachments()]
    statistics = reader.get_summary().statistics
print(json.dumps({"counts": counts, "first": first, "metadata": metadata,
                  "attachments": attachments, "message_count": statistics.message_count,
                  "chunk_count": statistics.chunk_count, "layout": layout}))
"#;

/// The project's Python (`target/pyenv`, made by `scripts/setup.sh --test`,
/// or `SLIDETRACK_PYTHON`), which has the official `mcap` package. Never the
/// system's `python3`: a test must not pass only because a package happens
/// to be installed by hand.
fn project_python() -> std::path::PathBuf {
    let python = std::env::var_os("SLIDETRACK_PYTHON").map_or_else(
        || std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/pyenv/bin/python"),
        std::path::PathBuf::from,
    );
    assert!(
        python.exists(),
        "{} does not exist: run `scripts/setup.sh --test` (or `scripts/test`), which makes the \
         project's Python environment with the official MCAP reader",
        python.display()
    );
    python
}

fn first<'a>(report: &'a Value, topic: &str) -> &'a Value {
    &report["first"][topic]
}

#[test]
fn the_official_python_reader_reads_a_recorded_session() {
    let dir = TestDir::new("python");
    let path = dir.file("session.mcap");
    let e = EveryChannel::new(100);
    let options = RecorderOptions { chunk_size_bytes: 8 << 10, ..RecorderOptions::default() };
    record_every_channel(&path, &e, options);

    let out = Command::new(project_python()).arg("-c").arg(SCRIPT).arg(&path).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "the Python reader failed: {stderr}");
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();

    let expected_counts = json!({
        "/tactile/raw": e.raw.len(), "/tactile/tare": e.tare.len(),
        "/tactile/zeroed": e.zeroed.len(), "/control/grasp": e.grasp.len(),
        "/hand/command": e.hand.len(), "/camera/image": e.image.len(),
        "/camera/calibration": e.calibration.len(), "/aruco/detections": e.aruco.len(),
        "/sim/truth": e.truth.len(), "/protocol/events": e.events.len(),
        "/recorder/stats": 1,
    });
    assert_eq!(report["counts"], expected_counts);
    assert_eq!(report["message_count"], e.message_count() + 1);
    assert!(report["chunk_count"].as_u64().unwrap() > 1);

    let raw = first(&report, TactileRaw::TOPIC);
    assert_eq!(raw["data"], serde_json::to_value(&e.raw[0].1).unwrap());
    assert_eq!(raw["schema"], "slidetrack.TactileRaw");
    assert_eq!((raw["log_time"].as_u64(), raw["sequence"].as_u64()), (Some(0), Some(0)));
    let sensors: Vec<&str> =
        report["layout"]["sensors"].as_array().unwrap().iter().map(|s| s["name"].as_str().unwrap()).collect();
    assert_eq!(sensors, ["thumb", "index", "middle"]);
    assert_eq!(report["layout"]["fingers"]["index"], json!({"sensor": "index", "taxel": 0}));

    let grasp = first(&report, GraspControl::TOPIC);
    assert_eq!(grasp["data"], serde_json::to_value(&e.grasp[0].1).unwrap());
    assert_eq!(grasp["data"]["thumb"]["desired"], 500.0);
    let aruco = first(&report, ArucoDetection::TOPIC);
    assert_eq!(aruco["data"]["detected"], false);
    assert_eq!(aruco["data"]["corners_px"], Value::Null, "a miss is nulls, not zeros");
    let image = first(&report, CompressedImage::TOPIC);
    assert_eq!(image["schema"], "foxglove.CompressedImage");
    assert_eq!(image["data"]["data"], json!(e.image[0].1.data));
    assert_eq!(image["data"]["format"], "jpeg");
    let calibration = first(&report, CameraCalibration::TOPIC);
    assert_eq!(calibration["data"]["K"], json!(intrinsics().k()));
    let truth = first(&report, SimTruth::TOPIC);
    assert_eq!(truth["data"]["normal_force"]["middle"], 4.0);

    let metadata: BTreeMap<String, BTreeMap<String, String>> =
        serde_json::from_value(report["metadata"].clone()).unwrap();
    assert_eq!(metadata[SESSION_METADATA], session_metadata().to_map());
    assert_eq!(metadata[OUTCOME_METADATA]["completed"], "true");
    assert_eq!(report["attachments"], json!([["camera.toml", "application/toml", "fx = 600.5\n"]]));
}
