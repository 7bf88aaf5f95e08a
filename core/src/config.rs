//! Reading TOML configuration files with errors that name the file and line.

use serde::de::DeserializeOwned;
use thiserror::Error;

/// A configuration that could not be parsed.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
#[error("{origin}{}: {detail}", line.map(|l| format!(" line {l}")).unwrap_or_default())]
pub struct ConfigError {
    /// The file (or other source) of the configuration.
    pub origin: String,
    /// The line of the error, 1-based, when known.
    pub line: Option<usize>,
    /// What is wrong.
    pub detail: String,
}

/// Parses `text` as TOML into `T`; `origin` names the source in errors.
pub fn parse_toml<T: DeserializeOwned>(text: &str, origin: &str) -> Result<T, ConfigError> {
    toml::from_str(text).map_err(|e| ConfigError {
        origin: origin.to_string(),
        line: e.span().map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1),
        detail: e.message().to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[expect(dead_code, reason = "only deserialized, to check the error of an unknown field")]
    struct Example {
        a: f64,
    }

    #[test]
    fn errors_name_the_origin_and_line() {
        let e = parse_toml::<Example>("# comment\n\nb = 1\n", "rig.toml").unwrap_err();
        assert_eq!(e.line, Some(3));
        assert!(e.to_string().starts_with("rig.toml line 3: unknown field `b`"), "{e}");
    }
}
