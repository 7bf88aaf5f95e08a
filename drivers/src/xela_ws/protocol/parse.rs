//! One message's JSON to a [`XelaEvent`], every field checked.

use serde_json::{Map, Value};

use super::error::XelaParseError;
use super::message::{TaxelCounts, TaxelForce, WELCOME, XelaEvent, XelaScan, XelaSensorScan, XelaWelcome};

/// What `"message"` must be.
const COUNTER: &str = "a message counter (integer ≥ 0) or \"Welcome\"";

/// Parses one WebSocket text message.
///
/// # Contract
/// - Any text is accepted: what is not a welcome nor a well-formed data
///   message is a [`XelaParseError`]; nothing panics.
/// - A welcome is recognised by `"message": "Welcome"` (any letter case),
///   nothing else. (`"type"` is not used: one published 1.7.7 example shows
///   `"type": "welcome"` on a message that carries scans, while 1.8.0 data
///   messages carry `"type": "routine"`.)
/// - A data message needs a counter and at least one sensor. Keys made of
///   digits are sensors; the other keys (`time`, `sensors`, `type`,
///   `version`, `complete`, `sendtime`, ...) are ignored except `time` and
///   `sensors`, which must be a number and the count of sensor objects when
///   present. Sensors come out in increasing number.
/// - A sensor's raw counts are read from `data` (hex string or integer
///   list); a sensor without `data` is read from `integer` (the list 1.8.0
///   sends beside the hex string). `taxels`, when present, must be a
///   third of their number; `calibrated` must then have as many values.
pub fn parse_message(text: &str) -> Result<XelaEvent, XelaParseError> {
    let value: Value = serde_json::from_str(text).map_err(|e| XelaParseError::Json {
        reason: e.to_string(),
        line: e.line(),
        column: e.column(),
    })?;
    let Value::Object(top) = value else {
        return Err(XelaParseError::NotAnObject { found: kind(&value) });
    };
    match top.get("message") {
        None => Err(XelaParseError::Missing { field: "message".into() }),
        Some(Value::String(s)) if s.eq_ignore_ascii_case(WELCOME) => {
            let version = top.get("version").and_then(Value::as_str).map(str::to_owned);
            Ok(XelaEvent::Welcome(XelaWelcome { version }))
        }
        Some(Value::String(s)) => Err(XelaParseError::UnknownMessage { text: clip(s, 64) }),
        Some(Value::Number(n)) => match n.as_u64() {
            Some(message) => parse_scan(message, &top).map(XelaEvent::Data),
            None => Err(wrong("message", COUNTER, "a negative or fractional number")),
        },
        Some(other) => Err(wrong("message", COUNTER, kind(other))),
    }
}

fn parse_scan(message: u64, top: &Map<String, Value>) -> Result<XelaScan, XelaParseError> {
    let server_time_s = optional_number(top.get("time"), "time")?;
    let mut sensors = Vec::new();
    for (key, value) in top {
        if key.is_empty() || !key.bytes().all(|b| b.is_ascii_digit()) {
            continue;
        }
        let number = key.parse::<u32>().ok().filter(|n| *n > 0 && n.to_string() == *key);
        let Some(number) = number else {
            return Err(XelaParseError::SensorKey { key: clip(key, 64) });
        };
        sensors.push(parse_sensor(number, value)?);
    }
    if sensors.is_empty() {
        return Err(XelaParseError::NoSensors { message });
    }
    match top.get("sensors") {
        None => {}
        Some(Value::Number(n)) => match n.as_u64() {
            Some(declared) if declared == sensors.len() as u64 => {}
            Some(declared) => return Err(XelaParseError::SensorCount { declared, found: sensors.len() }),
            None => return Err(wrong("sensors", "a sensor count", "a negative or fractional number")),
        },
        Some(other) => return Err(wrong("sensors", "a sensor count", kind(other))),
    }
    sensors.sort_by_key(|s| s.sensor);
    Ok(XelaScan { message, server_time_s, sensors })
}

fn parse_sensor(number: u32, value: &Value) -> Result<XelaSensorScan, XelaParseError> {
    let field = |name: &str| format!("{number}.{name}");
    let Value::Object(obj) = value else {
        return Err(wrong(&number.to_string(), "a sensor object", kind(value)));
    };
    check_sensor_number(number, obj.get("sensor"))?;
    let model = match obj.get("model") {
        Some(Value::String(s)) => s.clone(),
        Some(other) => return Err(wrong(&field("model"), "a model name", kind(other))),
        None => return Err(XelaParseError::Missing { field: field("model") }),
    };
    let time_s = optional_number(obj.get("time"), &field("time"))?;
    let declared = match obj.get("taxels") {
        None => None,
        Some(v) => match v.as_u64() {
            Some(n) if n > 0 => Some(n),
            _ => {
                let found = if v.is_number() { "0, negative or fractional" } else { kind(v) };
                return Err(wrong(&field("taxels"), "a taxel count ≥ 1", found));
            }
        },
    };
    let (name, values) = match (obj.get("data"), obj.get("integer")) {
        (Some(Value::String(s)), _) => ("data", hex_counts(s, &field("data"))?),
        (Some(Value::Array(a)), _) => ("data", list_counts(a, &field("data"))?),
        (Some(other), _) => {
            return Err(wrong(&field("data"), "a hex string or a list of counts", kind(other)));
        }
        (None, Some(Value::Array(a))) => ("integer", list_counts(a, &field("integer"))?),
        (None, Some(other)) => return Err(wrong(&field("integer"), "a list of counts", kind(other))),
        (None, None) => return Err(XelaParseError::Missing { field: field("data") }),
    };
    let taxels = triples(&values, &field(name), declared)?;
    let calibrated = match obj.get("calibrated") {
        None | Some(Value::Null) => None,
        Some(Value::Array(a)) if a.is_empty() => None,
        Some(Value::Array(a)) => Some(forces(a, &field("calibrated"), taxels.len())?),
        Some(other) => return Err(wrong(&field("calibrated"), "a list of forces or null", kind(other))),
    };
    Ok(XelaSensorScan { sensor: number, model, time_s, taxels, calibrated })
}

/// `"sensor"` inside sensor `number`'s object, when present, must name it
/// (as a string, as the server writes it, or as an integer).
fn check_sensor_number(number: u32, value: Option<&Value>) -> Result<(), XelaParseError> {
    let matches = match value {
        None => true,
        Some(Value::String(s)) => s.trim().parse::<u32>() == Ok(number),
        Some(Value::Number(n)) => n.as_u64() == Some(u64::from(number)),
        Some(_) => false,
    };
    match value {
        Some(v) if !matches => {
            Err(XelaParseError::SensorNumber { key: number, found: clip(&v.to_string(), 64) })
        }
        _ => Ok(()),
    }
}

/// A comma-separated hex string: `"8197,829A,91E6"`. Blanks around a value
/// and empty values (a trailing comma) are skipped; `0x` prefixes accepted.
fn hex_counts(s: &str, field: &str) -> Result<Vec<u16>, XelaParseError> {
    let mut values = Vec::with_capacity(s.len() / 5 + 1);
    for (index, token) in s.split(',').map(str::trim).filter(|t| !t.is_empty()).enumerate() {
        let digits = token.strip_prefix("0x").or_else(|| token.strip_prefix("0X")).unwrap_or(token);
        let value =
            (!digits.is_empty() && digits.len() <= 4 && digits.bytes().all(|b| b.is_ascii_hexdigit()))
                .then(|| u16::from_str_radix(digits, 16).ok())
                .flatten();
        match value {
            Some(v) => values.push(v),
            None => return Err(XelaParseError::Hex { field: field.into(), index, token: clip(token, 16) }),
        }
    }
    Ok(values)
}

/// A list of integer counts: `[33175, 33434, 37350]`.
fn list_counts(a: &[Value], field: &str) -> Result<Vec<u16>, XelaParseError> {
    a.iter()
        .enumerate()
        .map(|(index, v)| {
            v.as_u64().and_then(|n| u16::try_from(n).ok()).ok_or_else(|| XelaParseError::Count {
                field: field.into(),
                index,
                value: clip(&v.to_string(), 32),
            })
        })
        .collect()
}

fn triples(values: &[u16], field: &str, declared: Option<u64>) -> Result<Vec<TaxelCounts>, XelaParseError> {
    match declared {
        Some(taxels) if taxels.checked_mul(3) != Some(values.len() as u64) => {
            Err(XelaParseError::Length { field: field.into(), values: values.len(), taxels })
        }
        None if values.is_empty() || !values.len().is_multiple_of(3) => {
            Err(XelaParseError::NotTriples { field: field.into(), values: values.len() })
        }
        _ => Ok(values.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()),
    }
}

/// `calibrated`: x, y, z (N) per taxel, as many taxels as the raw counts.
fn forces(a: &[Value], field: &str, taxels: usize) -> Result<Vec<TaxelForce>, XelaParseError> {
    if a.len() != 3 * taxels {
        return Err(XelaParseError::Length { field: field.into(), values: a.len(), taxels: taxels as u64 });
    }
    let mut values = Vec::with_capacity(a.len());
    for (index, v) in a.iter().enumerate() {
        match v.as_f64() {
            Some(f) => values.push(f),
            None => return Err(XelaParseError::NotANumber { field: field.into(), index, found: kind(v) }),
        }
    }
    Ok(values.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

fn optional_number(value: Option<&Value>, field: &str) -> Result<Option<f64>, XelaParseError> {
    match value {
        None | Some(Value::Null) => Ok(None),
        Some(v) => v.as_f64().map(Some).ok_or_else(|| wrong(field, "a time in seconds", kind(v))),
    }
}

fn wrong(field: &str, expected: &'static str, found: &'static str) -> XelaParseError {
    XelaParseError::WrongType { field: field.into(), expected, found }
}

/// The JSON type of `v`, for messages.
fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "a list",
        Value::Object(_) => "an object",
    }
}

/// The first `n` characters of `s`.
fn clip(s: &str, n: usize) -> String {
    s.chars().take(n).collect()
}
