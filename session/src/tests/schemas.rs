//! The JSON Schemas describe the messages exactly (checked with the
//! `jsonschema` validator), and the docs list them.

use serde_json::Value;

use super::schema_validation::ChannelSchema;
use super::*;

fn check_all<T: ChannelMessage>(messages: &[(TimeNs, T)]) {
    let schema = ChannelSchema::new(T::json_schema());
    assert!(!messages.is_empty());
    for (_, m) in messages {
        let value = serde_json::to_value(m).unwrap();
        if let Err(e) = schema.check(&value) {
            panic!("{} does not match its schema: {e}", T::SCHEMA_NAME);
        }
    }
}

#[test]
fn every_message_matches_its_schema_exactly() {
    let e = EveryChannel::new(40);
    check_all(&e.raw);
    check_all(&e.tare);
    check_all(&e.zeroed);
    check_all(&e.grasp);
    check_all(&e.hand);
    check_all(&e.image);
    check_all(&e.calibration);
    check_all(&e.aruco);
    check_all(&e.truth);
    check_all(&e.events);
    check_all(&[(TimeNs::ZERO, RecorderStats::default())]);

    // The validator does catch a stray or a missing field.
    let schema = ChannelSchema::new(HandCommand::json_schema());
    let mut value = serde_json::to_value(HandCommand::default()).unwrap();
    value["extra"] = Value::Bool(true);
    assert!(schema.check(&value).is_err());
    value.as_object_mut().unwrap().remove("extra");
    value.as_object_mut().unwrap().remove("thumb");
    assert!(schema.check(&value).is_err());
}

#[test]
fn schemas_name_themselves_and_declare_their_dialect() {
    for spec in channel_specs() {
        assert_eq!(spec.schema["title"], spec.schema_name, "{}", spec.topic);
        if spec.schema_name.starts_with("slidetrack.") {
            assert_eq!(spec.schema["$schema"], JSON_SCHEMA_DIALECT);
            assert_eq!(spec.schema["additionalProperties"], Value::Bool(false));
        }
    }
    let topics: Vec<&str> = channel_specs().iter().map(|s| s.topic).collect();
    let mut unique = topics.clone();
    unique.sort_unstable();
    unique.dedup();
    assert_eq!(unique.len(), topics.len(), "topics are unique");
}

/// Every property name in a schema, nested ones included.
fn property_names(schema: &Value, out: &mut Vec<String>) {
    if let Some(props) = schema.get("properties").and_then(Value::as_object) {
        for (k, v) in props {
            out.push(k.clone());
            property_names(v, out);
        }
    }
    if let Some(items) = schema.get("items") {
        property_names(items, out);
    }
}

#[test]
fn the_format_doc_lists_every_channel_schema_and_field() {
    let doc_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/session-format.md");
    let doc = std::fs::read_to_string(&doc_path).unwrap();
    for spec in channel_specs() {
        assert!(doc.contains(&format!("`{}`", spec.topic)), "docs lack topic {}", spec.topic);
        assert!(doc.contains(&format!("`{}`", spec.schema_name)), "docs lack {}", spec.schema_name);
        let mut names = Vec::new();
        property_names(&spec.schema, &mut names);
        for name in names {
            assert!(doc.contains(&format!("`{name}`")), "docs lack field {name} of {}", spec.topic);
        }
    }
    let metadata_keys =
        session_metadata().to_map().into_keys().chain(SessionOutcome::default().to_map().into_keys());
    for key in metadata_keys {
        assert!(doc.contains(&format!("`{key}`")), "docs lack metadata key {key}");
    }
    for name in [SESSION_METADATA, OUTCOME_METADATA, "taxel_layout"] {
        assert!(doc.contains(&format!("`{name}`")), "docs lack {name}");
    }
}
