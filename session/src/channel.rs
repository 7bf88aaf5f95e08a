//! What makes a message type the message of a channel: its topic, schema
//! name and JSON Schema ([`ChannelMessage`]).

use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::Value;

/// Schema encoding of every JSON channel.
pub const SCHEMA_ENCODING_JSONSCHEMA: &str = "jsonschema";
/// Message encoding of every JSON channel.
pub const MESSAGE_ENCODING_JSON: &str = "json";

/// A message type with its own channel: JSON-encoded, described by a JSON Schema.
pub trait ChannelMessage: Serialize + DeserializeOwned {
    /// The channel's topic, for example `/tactile/raw`.
    const TOPIC: &'static str;
    /// The schema name, for example `slidetrack.TactileRaw`.
    const SCHEMA_NAME: &'static str;
    /// The JSON Schema describing exactly the serialized message.
    fn json_schema() -> Value;
}

/// The topic, schema name and schema of one channel, for listings and docs.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelSpec {
    /// The channel's topic.
    pub topic: &'static str,
    /// The schema name.
    pub schema_name: &'static str,
    /// The JSON Schema.
    pub schema: Value,
}

impl ChannelSpec {
    /// The spec of `T`'s channel.
    pub fn of<T: ChannelMessage>() -> ChannelSpec {
        ChannelSpec { topic: T::TOPIC, schema_name: T::SCHEMA_NAME, schema: T::json_schema() }
    }
}

/// Declares a channel type wrapping a message type with its own topic
/// (`$name(pub $inner)`, serde-transparent). The caller's module must have
/// `Serialize`, `Deserialize`, `Value` and `ChannelMessage` in scope.
macro_rules! channel {
    ($(#[$doc:meta])* $name:ident($inner:ty), $topic:literal, $schema_name:literal, $schema:expr) => {
        $(#[$doc])*
        #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
        #[serde(transparent)]
        pub struct $name(pub $inner);

        impl ChannelMessage for $name {
            const TOPIC: &'static str = $topic;
            const SCHEMA_NAME: &'static str = $schema_name;
            fn json_schema() -> Value {
                $schema
            }
        }
    };
}
pub(crate) use channel;
