//! Small builders for the JSON Schemas (draft 2020-12) of the session channels.
//!
//! Every `slidetrack.*` schema is an object whose properties are all required
//! and which allows no other properties, so the schema describes the message
//! exactly.

use serde_json::{Map, Value, json};

/// The JSON Schema dialect of the `slidetrack.*` schemas.
pub const JSON_SCHEMA_DIALECT: &str = "https://json-schema.org/draft/2020-12/schema";

/// A top-level message schema titled `name`.
pub(crate) fn message(name: &str, description: &str, properties: Vec<(&str, Value)>) -> Value {
    let mut schema = closed_object(description, properties);
    if let Value::Object(map) = &mut schema {
        map.insert("$schema".into(), json!(JSON_SCHEMA_DIALECT));
        map.insert("title".into(), json!(name));
    }
    schema
}

/// An object with exactly these properties, all required.
pub(crate) fn closed_object(description: &str, properties: Vec<(&str, Value)>) -> Value {
    let required: Vec<Value> = properties.iter().map(|(k, _)| json!(k)).collect();
    let props: Map<String, Value> = properties.into_iter().map(|(k, v)| (k.to_string(), v)).collect();
    json!({
        "type": "object",
        "description": description,
        "properties": props,
        "required": required,
        "additionalProperties": false,
    })
}

/// An unsigned integer no larger than `max`.
pub(crate) fn uint(description: &str, max: u64) -> Value {
    json!({ "type": "integer", "minimum": 0, "maximum": max, "description": description })
}

/// A floating-point number.
pub(crate) fn number(description: &str) -> Value {
    json!({ "type": "number", "description": description })
}

/// A unit quaternion `{x, y, z, w}`.
pub(crate) fn quaternion(description: &str) -> Value {
    closed_object(
        description,
        vec![
            ("x", number("vector part x")),
            ("y", number("vector part y")),
            ("z", number("vector part z")),
            ("w", number("scalar part")),
        ],
    )
}

/// A protocol phase: one of the lower-case names of [`Phase`](slidetrack_core::Phase).
pub(crate) fn phase(description: &str) -> Value {
    let names = slidetrack_core::Phase::ALL.map(slidetrack_core::Phase::name);
    json!({ "type": "string", "enum": names, "description": description })
}

/// A boolean.
pub(crate) fn boolean(description: &str) -> Value {
    json!({ "type": "boolean", "description": description })
}

/// A string.
pub(crate) fn string(description: &str) -> Value {
    json!({ "type": "string", "description": description })
}

/// An array of exactly `len` items.
pub(crate) fn array(description: &str, items: Value, len: usize) -> Value {
    json!({
        "type": "array",
        "description": description,
        "items": items,
        "minItems": len,
        "maxItems": len,
    })
}

/// `schema`, or `null`.
pub(crate) fn nullable(mut schema: Value) -> Value {
    if let Some(t) = schema.get_mut("type") {
        let inner = t.take();
        *t = json!([inner, "null"]);
    }
    schema
}

/// `{x, y, z}`, each as `axis`.
pub(crate) fn xyz(description: &str, axis: impl Fn(&str) -> Value) -> Value {
    closed_object(description, vec![("x", axis("x")), ("y", axis("y")), ("z", axis("z"))])
}

/// The three `(thumb, index, middle)` properties, each as `finger`.
pub(crate) fn finger_properties(finger: impl Fn(&str) -> Value) -> Vec<(&'static str, Value)> {
    slidetrack_core::Finger::ALL.iter().map(|f| (f.name(), finger(f.name()))).collect()
}

/// `{thumb, index, middle}`, each as `finger`.
pub(crate) fn per_finger(description: &str, finger: impl Fn(&str) -> Value) -> Value {
    closed_object(description, finger_properties(finger))
}

/// The `time` object of Foxglove schemas.
pub(crate) fn foxglove_time(description: &str) -> Value {
    json!({
        "type": "object",
        "title": "time",
        "properties": {
            "sec": { "type": "integer", "minimum": 0 },
            "nsec": { "type": "integer", "minimum": 0, "maximum": 999_999_999 },
        },
        "description": description,
    })
}
