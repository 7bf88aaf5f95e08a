//! The JSON Schemas describe the messages exactly, and the docs list them.

use serde_json::Value;

use super::*;

/// Checks `value` against the subset of JSON Schema the channel schemas use
/// (type, properties, required, additionalProperties, items, min/maxItems,
/// minimum/maximum). Returns the first violation.
fn validate(schema: &Value, value: &Value, at: &str) -> Result<(), String> {
    let types: Vec<&str> = match &schema["type"] {
        Value::String(t) => vec![t.as_str()],
        Value::Array(ts) => ts.iter().filter_map(Value::as_str).collect(),
        _ => return Err(format!("{at}: schema without a type")),
    };
    let matches = |t: &str| match t {
        "object" => value.is_object(),
        "array" => value.is_array(),
        "string" => value.is_string(),
        "boolean" => value.is_boolean(),
        "integer" => value.is_u64() || value.is_i64(),
        "number" => value.is_number(),
        "null" => value.is_null(),
        _ => false,
    };
    if !types.iter().any(|t| matches(t)) {
        return Err(format!("{at}: {value} is not of type {types:?}"));
    }
    let min = schema.get("minimum").and_then(Value::as_f64);
    if let (Some(min), Some(v)) = (min, value.as_f64())
        && v < min
    {
        return Err(format!("{at}: {value} < {min}"));
    }
    let max = schema.get("maximum").and_then(Value::as_u64);
    if let (Some(max), Some(v)) = (max, value.as_u64())
        && v > max
    {
        return Err(format!("{at}: {value} > {max}"));
    }
    match value {
        Value::Object(fields) => {
            let props = schema["properties"].as_object().ok_or(format!("{at}: no properties"))?;
            for (k, v) in fields {
                let Some(s) = props.get(k) else {
                    return Err(format!("{at}: field {k} is not in the schema"));
                };
                validate(s, v, &format!("{at}.{k}"))?;
            }
            for k in schema["required"].as_array().into_iter().flatten() {
                let k = k.as_str().unwrap_or_default();
                if !fields.contains_key(k) {
                    return Err(format!("{at}: required field {k} missing"));
                }
            }
            if schema["additionalProperties"] == Value::Bool(false) {
                for k in props.keys() {
                    if !fields.contains_key(k) {
                        return Err(format!("{at}: schema property {k} not in the message"));
                    }
                }
            }
        }
        Value::Array(items) => {
            let len = items.len() as u64;
            if schema.get("minItems").and_then(Value::as_u64).is_some_and(|m| len < m)
                || schema.get("maxItems").and_then(Value::as_u64).is_some_and(|m| len > m)
            {
                return Err(format!("{at}: {len} items"));
            }
            for (i, item) in items.iter().enumerate() {
                validate(&schema["items"], item, &format!("{at}.{i}"))?;
            }
        }
        _ => {}
    }
    Ok(())
}

fn check_all<T: ChannelMessage>(messages: &[(TimeNs, T)]) {
    let schema = T::json_schema();
    assert!(!messages.is_empty());
    for (_, m) in messages {
        let value = serde_json::to_value(m).unwrap();
        if let Err(e) = validate(&schema, &value, T::TOPIC) {
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
    let schema = HandCommand::json_schema();
    let mut value = serde_json::to_value(HandCommand::default()).unwrap();
    value["extra"] = Value::Bool(true);
    assert!(validate(&schema, &value, "").is_err());
    value.as_object_mut().unwrap().remove("extra");
    value.as_object_mut().unwrap().remove("thumb");
    assert!(validate(&schema, &value, "").is_err());
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
