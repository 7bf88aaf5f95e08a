//! Every message of every channel, as recorded, is valid against the JSON
//! Schema its channel carries in the file (checked with the `jsonschema`
//! validator), and wrong messages are not.

use std::collections::{BTreeMap, BTreeSet};

use jsonschema::Validator;
use serde_json::{Value, json};

use super::other_channels::log_other_channels;
use super::*;

/// The validators of a channel's schema.
pub(super) struct ChannelSchema {
    /// The schema as written.
    exact: Validator,
    /// For Foxglove's schemas, which allow other properties, the schema with
    /// every object closed (`additionalProperties: false`): messages add no
    /// field of their own. The `slidetrack.*` schemas are closed already.
    closed: Option<Validator>,
}

impl ChannelSchema {
    pub(super) fn new(schema: Value) -> ChannelSchema {
        let exact = jsonschema::draft202012::new(&schema).unwrap();
        let foxglove = schema["title"].as_str().is_some_and(|t| t.starts_with("foxglove."));
        let closed = foxglove.then(|| {
            let mut closed = schema.clone();
            close_objects(&mut closed);
            jsonschema::draft202012::new(&closed).unwrap()
        });
        ChannelSchema { exact, closed }
    }

    /// `Err` with the validators' messages unless `message` is valid.
    pub(super) fn check(&self, message: &Value) -> Result<(), String> {
        let closed = self.closed.iter().flat_map(|v| v.iter_errors(message));
        let errors: Vec<String> =
            self.exact.iter_errors(message).chain(closed).map(|e| e.to_string()).collect();
        if errors.is_empty() { Ok(()) } else { Err(errors.join("; ")) }
    }
}

fn close_objects(schema: &mut Value) {
    if let Value::Object(map) = schema {
        if map.contains_key("properties") {
            map.insert("additionalProperties".into(), json!(false));
        }
        map.values_mut().for_each(close_objects);
    } else if let Value::Array(items) = schema {
        items.iter_mut().for_each(close_objects);
    }
}

/// Records a session with a message on every channel of [`channel_specs`];
/// returns, per topic, the channel's schema from the file and its messages.
fn recorded_channels(dir: &TestDir) -> BTreeMap<String, (Value, Vec<Value>)> {
    let path = dir.file("every-schema.mcap");
    let options = RecorderOptions { chunk_size_bytes: 8 << 10, ..RecorderOptions::default() };
    record_every_channel_and(&path, &EveryChannel::new(40), options, log_other_channels);
    let bytes = std::fs::read(&path).unwrap();
    let mut channels: BTreeMap<String, (Value, Vec<Value>)> = BTreeMap::new();
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        let schema = message.channel.schema.as_ref().unwrap();
        assert_eq!(schema.encoding, "jsonschema", "{}", message.channel.topic);
        let entry = channels
            .entry(message.channel.topic.clone())
            .or_insert_with(|| (serde_json::from_slice(&schema.data).unwrap(), Vec::new()));
        entry.1.push(serde_json::from_slice(&message.data).unwrap());
    }
    channels
}

#[test]
fn every_message_of_every_channel_is_valid_against_its_schema_in_the_file() {
    let dir = TestDir::new("validate");
    let channels = recorded_channels(&dir);
    let specs = channel_specs();
    let expected: BTreeSet<&str> = specs.iter().map(|s| s.topic).collect();
    let recorded: BTreeSet<&str> = channels.keys().map(String::as_str).collect();
    assert_eq!(recorded, expected, "a message on every channel, and no other");

    for spec in &specs {
        let (schema, messages) = &channels[spec.topic];
        assert_eq!(schema, &spec.schema, "{}: the file holds the channel's schema", spec.topic);
        assert_eq!(schema["title"], spec.schema_name, "{}", spec.topic);
        let validator = ChannelSchema::new(schema.clone());
        for message in messages {
            if let Err(e) = validator.check(message) {
                panic!("{} does not match {}: {e}\n{message}", spec.topic, spec.schema_name);
            }
        }
    }
}

/// Wrong versions of `message`: a stray field, each field left out, and each
/// leaf replaced by a value of another JSON type.
fn wrong_versions(message: &Value) -> Vec<(String, Value)> {
    let mut wrong = Vec::new();
    let mut stray = message.clone();
    stray["unexpected_field"] = json!(1.0);
    wrong.push(("a stray field".to_string(), stray));
    for key in message.as_object().unwrap().keys() {
        let mut missing = message.clone();
        missing.as_object_mut().unwrap().remove(key);
        wrong.push((format!("without {key}"), missing));
    }
    let mut leaves = Vec::new();
    leaf_pointers(message, String::new(), &mut leaves);
    for pointer in leaves {
        let mut retyped = message.clone();
        let leaf = retyped.pointer_mut(&pointer).unwrap();
        *leaf = if leaf.is_string() { json!(1) } else { json!("1") };
        wrong.push((format!("{pointer} of another type"), retyped));
    }
    wrong
}

fn leaf_pointers(value: &Value, at: String, out: &mut Vec<String>) {
    match value {
        Value::Object(map) => map.iter().for_each(|(k, v)| leaf_pointers(v, format!("{at}/{k}"), out)),
        Value::Array(items) => {
            items.iter().enumerate().for_each(|(i, v)| leaf_pointers(v, format!("{at}/{i}"), out))
        }
        Value::Null => {}
        _ => out.push(at),
    }
}

#[test]
fn wrong_messages_are_refused_by_every_channels_schema() {
    let dir = TestDir::new("validate-wrong");
    let channels = recorded_channels(&dir);
    let mut refused = 0;
    for (topic, (schema, messages)) in &channels {
        let validator = ChannelSchema::new(schema.clone());
        // The last message: a detected marker on /aruco/detections (no nulls).
        let message = messages.last().unwrap();
        for (what, wrong) in wrong_versions(message) {
            assert!(validator.check(&wrong).is_err(), "{topic}: accepted with {what}: {wrong}");
            refused += 1;
        }
    }
    assert!(refused > 300, "{refused} wrong messages checked");
}

#[test]
fn integer_bounds_and_nulls_are_exactly_those_of_the_rust_types() {
    let schema = |s: Value| ChannelSchema::new(s);
    let raw = schema(TactileRaw::json_schema());
    let mut m = serde_json::to_value(super::raw(3)).unwrap();
    m["sensors"][0]["taxels"][0]["x"] = json!(65535);
    m["sequence"] = json!(u64::MAX);
    assert_eq!(raw.check(&m), Ok(()));
    m["sensors"][0]["taxels"][0]["x"] = json!(65536);
    assert!(raw.check(&m).is_err(), "a u16 count above 65535");
    m["sensors"][0]["taxels"][0]["x"] = json!(-1);
    assert!(raw.check(&m).is_err(), "a negative count");
    m["sensors"][0]["taxels"][0]["x"] = json!(1.5);
    assert!(raw.check(&m).is_err(), "a fractional count");

    let tare = schema(TactileTare::json_schema());
    let mut m = serde_json::to_value(TactileTare::default()).unwrap();
    m["samples"] = json!(u64::from(u32::MAX) + 1);
    assert!(tare.check(&m).is_err(), "a u32 above its range");

    // A missed detection is all nulls; a found one has no nulls; nothing else is nullable.
    let aruco = schema(ArucoDetection::json_schema());
    let missed = serde_json::to_value(ArucoDetection::missed()).unwrap();
    assert_eq!(aruco.check(&missed), Ok(()));
    let mut m = missed.clone();
    m["detected"] = Value::Null;
    assert!(aruco.check(&m).is_err(), "detected is never null");
    m = missed.clone();
    m["position_in_camera_m"] = json!([0.1, 0.2]);
    assert!(aruco.check(&m).is_err(), "a position of two coordinates");
    m = missed;
    m["marker_id"] = json!(-1);
    assert!(aruco.check(&m).is_err(), "a negative marker id");
    for spec in channel_specs() {
        let mut nullable = Vec::new();
        nullable_properties(&spec.schema, String::new(), &mut nullable);
        nullable.sort_unstable();
        let expected: &[&str] = if spec.schema_name == ArucoDetection::SCHEMA_NAME {
            &[
                "/corners_px",
                "/marker_id",
                "/orientation_in_camera",
                "/position_in_camera_m",
                "/position_on_axis_m",
                "/reprojection_error_px",
            ]
        } else if spec.schema_name == HandState::SCHEMA_NAME {
            &["/gripper", "/opening"]
        } else {
            &[]
        };
        assert_eq!(nullable, expected, "{}", spec.topic);
    }
}

fn nullable_properties(schema: &Value, at: String, out: &mut Vec<String>) {
    let types = &schema["type"];
    if types == "null" || types.as_array().is_some_and(|t| t.contains(&json!("null"))) {
        out.push(at.clone());
    }
    if let Some(properties) = schema["properties"].as_object() {
        for (k, v) in properties {
            nullable_properties(v, format!("{at}/{k}"), out);
        }
    }
}

#[test]
fn the_slidetrack_schemas_are_closed_bounded_and_described() {
    for spec in channel_specs().into_iter().filter(|s| s.schema_name.starts_with("slidetrack.")) {
        let at = spec.topic;
        jsonschema::meta::validate(&spec.schema).unwrap_or_else(|e| panic!("{at}: not a valid schema: {e}"));
        assert_eq!(spec.schema["$schema"], JSON_SCHEMA_DIALECT, "{at}");
        assert_eq!(spec.schema["title"], spec.schema_name, "{at}");
        check_node(&spec.schema, at);
    }
}

/// Every object requires exactly its properties and allows no other, every
/// property is described, every integer is bounded, no Rust format is left.
fn check_node(schema: &Value, at: &str) {
    assert!(schema.get("format").is_none(), "{at}: format {}", schema["format"]);
    let types = &schema["type"];
    let is = |t: &str| types == t || types.as_array().is_some_and(|a| a.contains(&json!(t)));
    if is("integer") {
        assert!(schema["minimum"].is_number() && schema["maximum"].is_number(), "{at}: unbounded integer");
    }
    if let Some(properties) = schema["properties"].as_object() {
        assert_eq!(schema["additionalProperties"], json!(false), "{at}");
        let mut required: Vec<&str> =
            schema["required"].as_array().unwrap().iter().filter_map(Value::as_str).collect();
        required.sort_unstable();
        let names: Vec<&str> = properties.keys().map(String::as_str).collect();
        assert_eq!(required, names, "{at}: every property required");
        for (name, property) in properties {
            let described = property["description"].as_str().is_some_and(|d| !d.trim().is_empty());
            assert!(described, "{at}.{name} has no description");
            assert!(!property["description"].as_str().unwrap_or_default().contains('\n'), "{at}.{name}");
            check_node(property, &format!("{at}.{name}"));
        }
    }
    if let Some(items) = schema.get("items") {
        check_node(items, &format!("{at}[]"));
    }
}

#[test]
fn the_foxglove_schemas_are_the_vendored_files() {
    use crate::schema::Foxglove;
    let vendored = [
        (Foxglove::CompressedImage, "foxglove.CompressedImage"),
        (Foxglove::CameraCalibration, "foxglove.CameraCalibration"),
        (Foxglove::RawImage, "foxglove.RawImage"),
        (Foxglove::PoseInFrame, "foxglove.PoseInFrame"),
        (Foxglove::FrameTransform, "foxglove.FrameTransform"),
    ];
    for (schema, name) in vendored {
        let text: Value = serde_json::from_str(schema.text()).unwrap();
        assert_eq!(text["title"], name);
        assert!(text["$comment"].as_str().unwrap().contains("foxglove-sdk"), "{name}: as published");
        jsonschema::draft202012::meta::validate(&text).unwrap();
    }
    let mut names: Vec<&str> = vendored.iter().map(|(_, n)| *n).collect();
    names.sort_unstable();
    let mut used: Vec<&str> =
        channel_specs().iter().map(|s| s.schema_name).filter(|n| n.starts_with("foxglove.")).collect();
    used.sort_unstable();
    used.dedup();
    assert_eq!(used, names, "every foxglove.* schema the channels use is vendored");
    for spec in channel_specs().into_iter().filter(|s| s.schema_name.starts_with("foxglove.")) {
        let (schema, _) = vendored.iter().find(|(_, n)| *n == spec.schema_name).unwrap();
        assert_eq!(spec.schema, schema.schema(), "{}", spec.topic);
    }
}
