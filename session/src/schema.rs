//! The JSON Schemas of the session channels.
//!
//! The `slidetrack.*` schemas are derived from the message types by
//! [schemars](https://docs.rs/schemars) ([`derived`]), so a field added to a
//! type is in its schema, with the field's doc comment as its description.
//! They are then closed: every property is required, objects allow no other
//! properties, unsigned integers carry their bounds, and the schema declares
//! the draft 2020-12 dialect and is titled with its schema name. The schema
//! thus describes the serialized message exactly.
//!
//! The `foxglove.*` schemas are Foxglove's published ones ([`Foxglove`]),
//! vendored under `schemas/foxglove/`, so Foxglove shows those channels.

use std::borrow::Cow;
use std::marker::PhantomData;

use schemars::generate::{Contract, SchemaSettings};
use schemars::{JsonSchema, Schema, SchemaGenerator, json_schema};
use serde_json::{Map, Value, json};
use slidetrack_core::{Finger, Phase};

/// The JSON Schema dialect of the `slidetrack.*` schemas.
pub const JSON_SCHEMA_DIALECT: &str = "https://json-schema.org/draft/2020-12/schema";

/// The number formats schemars adds for Rust's number types, with the bounds
/// of the integer ones. They are not JSON Schema formats; the bounds go into
/// `minimum` and `maximum` instead (schemars leaves out some of them).
const RUST_NUMBER_FORMATS: [(&str, Option<(i64, u64)>); 12] = [
    ("int8", Some((i8::MIN as i64, i8::MAX as u64))),
    ("int16", Some((i16::MIN as i64, i16::MAX as u64))),
    ("int32", Some((i32::MIN as i64, i32::MAX as u64))),
    ("int64", Some((i64::MIN, i64::MAX as u64))),
    ("int", Some((i64::MIN, i64::MAX as u64))),
    ("uint8", Some((0, u8::MAX as u64))),
    ("uint16", Some((0, u16::MAX as u64))),
    ("uint32", Some((0, u32::MAX as u64))),
    ("uint64", Some((0, u64::MAX))),
    ("uint", Some((0, u64::MAX))),
    ("float", None),
    ("double", None),
];

/// The closed schema (see the module docs) of `T` as it serializes, titled `name`.
pub(crate) fn derived<T: JsonSchema>(name: &str) -> Value {
    let mut settings = SchemaSettings::draft2020_12();
    settings.inline_subschemas = true;
    settings.contract = Contract::Serialize;
    let mut schema = settings.into_generator().into_root_schema_for::<T>().to_value();
    close(&mut schema);
    if let Value::Object(map) = &mut schema {
        map.insert("$schema".into(), json!(JSON_SCHEMA_DIALECT));
        map.insert("title".into(), json!(name));
    }
    schema
}

/// Makes every object in `schema` require all its properties and allow no
/// others, bounds every integer by its Rust type in place of schemars'
/// number formats, and joins the lines of each paragraph of the descriptions.
fn close(schema: &mut Value) {
    let Value::Object(map) = schema else { return };
    if let Some(Value::Object(properties)) = map.get("properties") {
        let names: Vec<Value> = properties.keys().map(|k| json!(k)).collect();
        let required = map.entry("required").or_insert_with(|| json!([]));
        if let Value::Array(required) = required {
            for name in names {
                if !required.contains(&name) {
                    required.push(name);
                }
            }
        }
        map.insert("additionalProperties".into(), json!(false));
    }
    let format = map.get("format").and_then(Value::as_str);
    if let Some((_, bounds)) = RUST_NUMBER_FORMATS.iter().find(|(name, _)| Some(*name) == format) {
        if let Some((min, max)) = bounds {
            map.entry("minimum").or_insert(json!(min));
            map.entry("maximum").or_insert(json!(max));
        }
        map.remove("format");
    }
    if let Some(Value::String(description)) = map.get_mut("description") {
        *description =
            description.split("\n\n").map(|p| p.replace('\n', " ")).collect::<Vec<_>>().join("\n\n");
    }
    if let Some(Value::Object(properties)) = map.get_mut("properties") {
        properties.values_mut().for_each(close);
    }
    if let Some(items) = map.get_mut("items") {
        close(items);
    }
    for key in ["prefixItems", "anyOf", "oneOf", "allOf"] {
        if let Some(Value::Array(subschemas)) = map.get_mut(key) {
            subschemas.iter_mut().for_each(close);
        }
    }
}

/// The schema of a [`PerFinger<T>`](slidetrack_core::PerFinger): an object
/// with one `T` per finger of [`Finger::ALL`], by name. Use it with
/// `#[schemars(with = "Fingers<T>")]` on a `PerFinger<T>` field.
pub(crate) struct Fingers<T>(PhantomData<T>);

impl<T: JsonSchema> JsonSchema for Fingers<T> {
    fn schema_name() -> Cow<'static, str> {
        format!("Fingers_{}", T::schema_name()).into()
    }

    fn inline_schema() -> bool {
        true
    }

    fn json_schema(generator: &mut SchemaGenerator) -> Schema {
        let mut properties = Map::new();
        for finger in Finger::ALL {
            let mut value = generator.subschema_for::<T>();
            value.insert("description".into(), json!(format!("The {}'s value.", finger_noun(finger))));
            properties.insert(finger.name().into(), value.to_value());
        }
        let names: Vec<&str> = Finger::ALL.iter().map(|f| f.name()).collect();
        json_schema!({ "type": "object", "properties": properties, "required": names })
    }
}

fn finger_noun(finger: Finger) -> &'static str {
    match finger {
        Finger::Thumb => "thumb",
        Finger::Index => "index finger",
        Finger::Middle => "middle finger",
    }
}

/// A transform that describes the per-finger properties of a schema with
/// `text`, `{finger}` replaced by the finger's name. For flattened
/// [`Fingers`] fields, whose own doc comment schemars does not keep:
/// `#[schemars(transform = describe_fingers("{finger} command (V)"))]` on the
/// message type.
pub(crate) fn describe_fingers(text: &'static str) -> impl FnMut(&mut Schema) {
    move |schema: &mut Schema| {
        if let Some(Value::Object(properties)) = schema.get_mut("properties") {
            for finger in Finger::ALL {
                if let Some(Value::Object(property)) = properties.get_mut(finger.name()) {
                    let description = text.replace("{finger}", finger.name());
                    property.insert("description".into(), json!(description));
                }
            }
        }
    }
}

/// The schema of a [`Phase`]: its lower-case name. Use it with
/// `#[schemars(with = "PhaseName")]` on a `Phase` field.
pub(crate) struct PhaseName;

impl JsonSchema for PhaseName {
    fn schema_name() -> Cow<'static, str> {
        "PhaseName".into()
    }

    fn inline_schema() -> bool {
        true
    }

    fn json_schema(_: &mut SchemaGenerator) -> Schema {
        let names = Phase::ALL.map(Phase::name);
        json_schema!({ "type": "string", "enum": names })
    }
}

/// Foxglove's published JSON Schemas that the session channels use, vendored
/// from the foxglove-sdk repository (`schemas/jsonschema/`, MIT license; see
/// `schemas/foxglove/README.md` and `docs/session-format.md`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Foxglove {
    /// `foxglove.CompressedImage`.
    CompressedImage,
    /// `foxglove.CameraCalibration`.
    CameraCalibration,
    /// `foxglove.RawImage`.
    RawImage,
    /// `foxglove.PoseInFrame`.
    PoseInFrame,
    /// `foxglove.FrameTransform`.
    FrameTransform,
}

impl Foxglove {
    /// The vendored file, as published.
    pub(crate) fn text(self) -> &'static str {
        match self {
            Foxglove::CompressedImage => include_str!("../schemas/foxglove/CompressedImage.json"),
            Foxglove::CameraCalibration => include_str!("../schemas/foxglove/CameraCalibration.json"),
            Foxglove::RawImage => include_str!("../schemas/foxglove/RawImage.json"),
            Foxglove::PoseInFrame => include_str!("../schemas/foxglove/PoseInFrame.json"),
            Foxglove::FrameTransform => include_str!("../schemas/foxglove/FrameTransform.json"),
        }
    }

    /// The schema.
    pub(crate) fn schema(self) -> Value {
        // A constant of the crate, not input: a test parses every one of them.
        serde_json::from_str(self.text()).expect("the vendored Foxglove schemas are valid JSON")
    }
}
