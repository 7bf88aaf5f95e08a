//! Scans back to the server's JSON, in each of its encodings of `data`:
//! fixtures for tests and the emulator's messages.

use serde_json::{Map, Value, json};

use super::message::{WELCOME, XelaScan, XelaSensorScan};

/// How a data message writes the raw counts, as the server versions do.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum WireStyle {
    /// `"data": "8197,829A,91E6,..."`: comma-separated 4-digit upper-case
    /// hex (server 1.7.6 and earlier, per the published notes).
    HexString,
    /// `"data": [33175, 33434, 37350, ...]`: a list of integers (server
    /// 1.7.7, per the published notes; not seen in a capture).
    IntegerList,
    /// The hex string in `"data"` and the same counts as a list in
    /// `"integer"`, with `"type": "routine"` and `"sendtime"` (as captured
    /// from server 1.8.0b).
    HexAndInteger,
}

/// The welcome message as the clients recognise it: `{"message": "Welcome"}`,
/// with `"version"` when given (the real welcome's other fields are not public).
pub fn encode_welcome(version: Option<&str>) -> String {
    let mut obj = Map::new();
    obj.insert("message".into(), json!(WELCOME));
    if let Some(v) = version {
        obj.insert("version".into(), json!(v));
    }
    Value::Object(obj).to_string()
}

/// One data message carrying `scan`, its counts written in `style`. Sensors
/// without calibrated forces get no `"calibrated"` key, as a server whose
/// calibration is off sends them.
pub fn encode_scan(scan: &XelaScan, style: WireStyle) -> String {
    let mut top = Map::new();
    top.insert("message".into(), json!(scan.message));
    if let Some(t) = scan.server_time_s {
        top.insert("time".into(), json!(t));
    }
    top.insert("sensors".into(), json!(scan.sensors.len()));
    if style == WireStyle::HexAndInteger {
        top.insert("type".into(), json!("routine"));
        if let Some(t) = scan.server_time_s {
            top.insert("sendtime".into(), json!(t));
        }
    }
    for sensor in &scan.sensors {
        top.insert(sensor.sensor.to_string(), sensor_object(sensor, style));
    }
    Value::Object(top).to_string()
}

fn sensor_object(sensor: &XelaSensorScan, style: WireStyle) -> Value {
    let counts = || sensor.taxels.iter().flatten().copied();
    let hex = || counts().map(|v| format!("{v:04X}")).collect::<Vec<_>>().join(",");
    let mut obj = Map::new();
    if let Some(t) = sensor.time_s {
        obj.insert("time".into(), json!(t));
    }
    obj.insert("sensor".into(), json!(sensor.sensor.to_string()));
    match style {
        WireStyle::HexString => {
            obj.insert("data".into(), json!(hex()));
        }
        WireStyle::IntegerList => {
            obj.insert("data".into(), json!(counts().collect::<Vec<_>>()));
        }
        WireStyle::HexAndInteger => {
            obj.insert("data".into(), json!(hex()));
            obj.insert("integer".into(), json!(counts().collect::<Vec<_>>()));
        }
    }
    obj.insert("model".into(), json!(sensor.model));
    obj.insert("taxels".into(), json!(sensor.taxels.len()));
    if let Some(forces) = &sensor.calibrated {
        obj.insert("calibrated".into(), json!(forces.iter().flatten().copied().collect::<Vec<f64>>()));
    }
    Value::Object(obj)
}
