//! The decoder on fixtures written from the published messages (see
//! `fixtures/README.md`), on malformed messages, and on arbitrary text and
//! JSON (proptest).

use proptest::prelude::*;
use serde_json::Value;

use super::*;

const WELCOME_FIXTURE: &str = include_str!("../fixtures/welcome.json");
const V176_HEX: &str = include_str!("../fixtures/v176_hex_uspa44_x2.json");
const V177_LIST: &str = include_str!("../fixtures/v177_list_uspa44_x2.json");
const V180_USPA46: &str = include_str!("../fixtures/v180b_uspa46_x2.json");
const V180_USPA35: &str = include_str!("../fixtures/v180b_uspa35_x2_uncalibrated.json");
const CALIBRATED_NULL: &str = include_str!("../fixtures/calibrated_null.json");

fn scan(text: &str) -> XelaScan {
    match parse_message(text) {
        Ok(XelaEvent::Data(scan)) => scan,
        other => panic!("not a scan: {other:?}"),
    }
}

fn parse_err(text: &str) -> XelaParseError {
    parse_message(text).expect_err("malformed")
}

fn uspa44(sensor: u32) -> ExpectedSensor {
    ExpectedSensor { sensor, model: "uSPa44".into(), taxels: 16 }
}

#[test]
fn the_welcome_is_recognised_by_its_message_field() {
    assert_eq!(parse_message(WELCOME_FIXTURE), Ok(XelaEvent::Welcome(XelaWelcome { version: None })));
    let with_version = r#"{"message": "welcome", "version": "1.7.7_161703"}"#;
    assert_eq!(
        parse_message(with_version),
        Ok(XelaEvent::Welcome(XelaWelcome { version: Some("1.7.7_161703".into()) }))
    );
    assert_eq!(parse_message(&encode_welcome(None)), parse_message(WELCOME_FIXTURE));
}

#[test]
fn hex_strings_decode_to_x_y_z_per_taxel() {
    let s = scan(V176_HEX);
    assert_eq!((s.message, s.server_time_s), (982, Some(1768296808.5523617)));
    assert_eq!(s.sensors.iter().map(|x| x.sensor).collect::<Vec<_>>(), [1, 2]);
    let one = &s.sensors[0];
    assert_eq!((one.model.as_str(), one.taxels.len(), one.time_s), ("uSPa44", 16, Some(1768296808.5465615)));
    // "8197,829A,91E6" is taxel 0's x, y, z; `special[0]` of the note repeats them in decimal.
    assert_eq!(one.taxels[0], [0x8197, 0x829A, 0x91E6]);
    assert_eq!(one.taxels[0], [33175, 33434, 37350]);
    assert_eq!(one.taxels[1], [32801, 33375, 37698]);
    let forces = one.calibrated.as_ref().expect("calibrated");
    assert_eq!(forces.len(), 16);
    assert_eq!(forces[0], [0.0031005585792, -0.0022188552824, 0.017302689426]);
    assert_eq!(forces[1], [-0.0019492148769, 0.0019580317863, 0.004221323262]);
}

#[test]
fn integer_lists_decode_like_hex_strings() {
    let hex = scan(V176_HEX);
    let list = scan(V177_LIST);
    // The 1.7.7 example carries `"type": "welcome"` and scans: it is data.
    assert_eq!(list.message, 983);
    for (h, l) in hex.sensors.iter().zip(&list.sensors) {
        assert_eq!(
            (h.sensor, &h.model, &h.taxels, &h.calibrated),
            (l.sensor, &l.model, &l.taxels, &l.calibrated)
        );
    }
}

#[test]
fn server_1_8_messages_with_hex_and_integer_fields() {
    let s = scan(V180_USPA46);
    assert_eq!((s.message, s.sensors.len()), (19299, 2));
    let one = &s.sensors[0];
    assert_eq!((one.model.as_str(), one.taxels.len()), ("uSPa46", 24));
    assert_eq!(one.taxels[0], [0x8125, 0x81B2, 0x92B8]);
    assert_eq!(one.taxels[0], [33061, 33202, 37560]);
    let forces = one.calibrated.as_ref().expect("calibrated");
    assert_eq!((forces.len(), forces[0], forces[1]), (24, [-0.00066, 0.00026, -0.00095], [0.0, -0.0, 0.0]));
    // `data` and `integer` agree; without `data` the counts come from `integer`.
    let mut v: Value = serde_json::from_str(V180_USPA46).unwrap();
    v["1"].as_object_mut().unwrap().remove("data");
    assert_eq!(scan(&v.to_string()).sensors[0].taxels, one.taxels);
}

#[test]
fn sensors_without_calibration_have_no_forces() {
    let s = scan(V180_USPA35);
    assert_eq!(s.sensors.len(), 2);
    for sensor in &s.sensors {
        assert_eq!((sensor.model.as_str(), sensor.taxels.len(), &sensor.calibrated), ("USPA35", 15, &None));
    }
    assert_eq!(s.sensors[0].taxels[0], [33683, 33237, 36980]);
    let null = scan(CALIBRATED_NULL);
    assert_eq!((null.sensors[0].taxels.len(), &null.sensors[0].calibrated), (16, &None));
    let empty = CALIBRATED_NULL.replace("\"calibrated\": null", "\"calibrated\": []");
    assert_eq!(scan(&empty).sensors[0].calibrated, None);
}

#[test]
fn every_wire_style_round_trips() {
    for fixture in [V176_HEX, V180_USPA46, V180_USPA35, CALIBRATED_NULL] {
        let original = scan(fixture);
        for style in [WireStyle::HexString, WireStyle::IntegerList, WireStyle::HexAndInteger] {
            assert_eq!(scan(&encode_scan(&original, style)), original, "{style:?}");
        }
    }
}

#[test]
fn sensors_come_out_in_numeric_order() {
    let text = r#"{"message": 1, "10": {"model": "m", "data": "1,2,3"}, "2": {"model": "m", "data": [4,5,6]},
                  "sensors": 2}"#;
    let s = scan(text);
    assert_eq!(s.sensors.iter().map(|x| x.sensor).collect::<Vec<_>>(), [2, 10]);
    assert_eq!((s.sensors[1].taxels[0], s.server_time_s), ([1, 2, 3], None));
}

#[test]
fn malformed_json_and_shapes_name_the_field() {
    use XelaParseError as E;
    assert!(matches!(parse_err("{\"message\": 1,"), E::Json { line: 1, .. }));
    assert!(matches!(parse_err(""), E::Json { .. }));
    assert_eq!(parse_err("[1, 2]"), E::NotAnObject { found: "a list" });
    assert_eq!(parse_err("{}"), E::Missing { field: "message".into() });
    assert_eq!(parse_err(r#"{"message": "Bye"}"#), E::UnknownMessage { text: "Bye".into() });
    assert!(matches!(parse_err(r#"{"message": -3}"#), E::WrongType { field, .. } if field == "message"));
    assert!(matches!(parse_err(r#"{"message": 1.5}"#), E::WrongType { field, .. } if field == "message"));
    assert!(matches!(parse_err(r#"{"message": null}"#), E::WrongType { found: "null", .. }));
    assert_eq!(parse_err(r#"{"message": 4, "time": 1.0}"#), E::NoSensors { message: 4 });
    let one = |sensor: &str| format!(r#"{{"message": 1, "time": 2.5, "1": {sensor}}}"#);
    assert!(matches!(parse_err(&one("[]")), E::WrongType { field, .. } if field == "1"));
    assert_eq!(parse_err(&one(r#"{"data": "1,2,3"}"#)), E::Missing { field: "1.model".into() });
    assert_eq!(parse_err(&one(r#"{"model": "uSPa44"}"#)), E::Missing { field: "1.data".into() });
    let bad_data = one(r#"{"model": "uSPa44", "data": {"x": 1}}"#);
    assert!(matches!(parse_err(&bad_data), E::WrongType { field, .. } if field == "1.data"));
    let bad_time = r#"{"message": 1, "time": "now", "1": {"model": "m", "data": "1,2,3"}}"#;
    assert!(matches!(parse_err(bad_time), E::WrongType { field, .. } if field == "time"));
    let bad_taxels = one(r#"{"model": "m", "data": "1,2,3", "taxels": 0}"#);
    assert!(matches!(parse_err(&bad_taxels), E::WrongType { field, .. } if field == "1.taxels"));
}

#[test]
fn sensor_keys_and_numbers_are_checked() {
    use XelaParseError as E;
    let data = r#"{"model": "m", "data": "1,2,3"}"#;
    assert_eq!(parse_err(&format!(r#"{{"message": 1, "01": {data}}}"#)), E::SensorKey { key: "01".into() });
    assert_eq!(parse_err(&format!(r#"{{"message": 1, "0": {data}}}"#)), E::SensorKey { key: "0".into() });
    let huge = format!(r#"{{"message": 1, "99999999999": {data}}}"#);
    assert_eq!(parse_err(&huge), E::SensorKey { key: "99999999999".into() });
    let other = r#"{"message": 1, "2": {"sensor": "3", "model": "m", "data": "1,2,3"}}"#;
    assert_eq!(parse_err(other), E::SensorNumber { key: 2, found: "\"3\"".into() });
    let as_int = r#"{"message": 1, "2": {"sensor": 2, "model": "m", "data": "1,2,3"}}"#;
    assert_eq!(scan(as_int).sensors[0].sensor, 2);
    let count = format!(r#"{{"message": 1, "sensors": 2, "1": {data}}}"#);
    assert_eq!(parse_err(&count), E::SensorCount { declared: 2, found: 1 });
}

#[test]
fn bad_counts_and_lengths_name_the_field() {
    use XelaParseError as E;
    let sensor = |body: &str| format!(r#"{{"message": 1, "2": {{"model": "uSPa44", {body}}}}}"#);
    let hex = |token: &str, index| E::Hex { field: "2.data".into(), index, token: token.into() };
    assert_eq!(parse_err(&sensor(r#""data": "8197,82G1,91E6""#)), hex("82G1", 1));
    assert_eq!(parse_err(&sensor(r#""data": "8197,10000,91E6""#)), hex("10000", 1));
    assert_eq!(parse_err(&sensor(r#""data": "8197,829A,-1""#)), hex("-1", 2));
    assert_eq!(parse_err(&sensor(r#""data": "0x""#)), hex("0x", 0));
    // Blanks, a 0x prefix and a trailing comma are tolerated.
    assert_eq!(
        scan(&sensor(r#""data": " 8197, 0x829A ,91e6,""#)).sensors[0].taxels,
        [[0x8197, 0x829A, 0x91E6]]
    );
    let count = |value: &str, index| E::Count { field: "2.data".into(), index, value: value.into() };
    assert_eq!(parse_err(&sensor(r#""data": [1, 65536, 3]"#)), count("65536", 1));
    assert_eq!(parse_err(&sensor(r#""data": [1, 2, -3]"#)), count("-3", 2));
    assert_eq!(parse_err(&sensor(r#""data": [1.5, 2, 3]"#)), count("1.5", 0));
    assert_eq!(parse_err(&sensor(r#""data": ["8197", 2, 3]"#)), count("\"8197\"", 0));
    let length = |field: &str, values, taxels| E::Length { field: field.into(), values, taxels };
    assert_eq!(parse_err(&sensor(r#""taxels": 2, "data": "1,2,3""#)), length("2.data", 3, 2));
    assert_eq!(parse_err(&sensor(r#""taxels": 1, "integer": [1,2,3,4]"#)), length("2.integer", 4, 1));
    assert_eq!(
        parse_err(&sensor(r#""data": "1,2,3,4""#)),
        E::NotTriples { field: "2.data".into(), values: 4 }
    );
    assert_eq!(parse_err(&sensor(r#""data": """#)), E::NotTriples { field: "2.data".into(), values: 0 });
    let forces = r#""data": "1,2,3,4,5,6", "calibrated": [0.1, 0.2, 0.3]"#;
    assert_eq!(parse_err(&sensor(forces)), length("2.calibrated", 3, 2));
    let not_number = r#""data": "1,2,3", "calibrated": [0.1, "0.2", 0.3]"#;
    let e = E::NotANumber { field: "2.calibrated".into(), index: 1, found: "a string" };
    assert_eq!(parse_err(&sensor(not_number)), e);
    let wrong = r#""data": "1,2,3", "calibrated": 0.1"#;
    assert!(matches!(parse_err(&sensor(wrong)), E::WrongType { field, .. } if field == "2.calibrated"));
}

#[test]
fn the_decoder_counts_and_reports_gaps() {
    let mut d = XelaDecoder::default();
    let at = |n: u64| V176_HEX.replacen("\"message\": 982", &format!("\"message\": {n}"), 1);
    let gap = |d: &mut XelaDecoder, text: &str| d.decode(text).unwrap().gap;
    assert_eq!(d.decode(WELCOME_FIXTURE).unwrap().gap, None);
    assert_eq!(gap(&mut d, &at(10)), None);
    assert_eq!(gap(&mut d, &at(11)), None);
    assert_eq!(gap(&mut d, &at(14)), Some(MessageGap::Skip { expected: 12, got: 14 }));
    assert_eq!(gap(&mut d, &at(14)), Some(MessageGap::Repeat { message: 14 }));
    assert!(matches!(d.decode("{oops"), Err(XelaError::Malformed(XelaParseError::Json { .. }))));
    assert!(matches!(d.reject_binary(12), XelaError::Malformed(XelaParseError::Binary { bytes: 12 })));
    // The welcome after a reconnection leaves the counter alone.
    assert_eq!(d.decode(WELCOME_FIXTURE).unwrap().gap, None);
    assert_eq!(gap(&mut d, &at(2)), Some(MessageGap::Backward { previous: 14, got: 2 }));
    assert_eq!(gap(&mut d, &at(3)), None);
    assert_eq!(d.last_message(), Some(3));
    let c = d.counters();
    assert_eq!((c.messages, c.welcomes, c.scans, c.malformed, c.mismatches), (10, 2, 6, 2, 0));
    assert_eq!((c.gaps, c.lost_messages, c.repeats, c.backward, c.reconnects), (3, 2, 1, 1, 0));
    let core = c.decoder_counters();
    assert_eq!((core.frames, core.gaps, core.incomplete_scans, core.crc_errors), (6, 3, 2, 0));
}

#[test]
fn the_expectation_names_the_sensor_and_both_values() {
    let expected = |sensors| Some(Expected { sensors });
    let mut ok = XelaDecoder::new(expected(vec![uspa44(1), uspa44(2)]));
    assert!(ok.decode(V176_HEX).is_ok());
    let mut model =
        XelaDecoder::new(expected(vec![uspa44(1), ExpectedSensor { model: "uSPa46".into(), ..uspa44(2) }]));
    let Err(XelaError::Mismatch(m)) = model.decode(V176_HEX) else { panic!("a mismatch") };
    assert_eq!(m, XelaMismatch::Model { sensor: 2, configured: "uSPa46".into(), received: "uSPa44".into() });
    assert!(m.to_string().contains("[sensor2]"), "{m}");
    assert_eq!((model.counters().mismatches, model.counters().scans, model.last_message()), (1, 0, None));
    let mut taxels = XelaDecoder::new(expected(vec![ExpectedSensor { taxels: 24, ..uspa44(1) }]));
    let Err(XelaError::Mismatch(m)) = taxels.decode(V176_HEX) else { panic!("a mismatch") };
    let want = XelaMismatch::Taxels { sensor: 1, model: "uSPa44".into(), configured: 24, received: 16 };
    assert_eq!(m, want);
    assert!(!m.to_string().contains('\n'));
    let mut missing = XelaDecoder::new(expected(vec![uspa44(3)]));
    let Err(XelaError::Mismatch(m)) = missing.decode(V176_HEX) else { panic!("a mismatch") };
    assert_eq!(
        m,
        XelaMismatch::MissingSensor { sensor: 3, configured_model: "uSPa44".into(), received: vec![1, 2] }
    );
    // Models compare without letter case: the server reports `USPA35`.
    let mut case =
        XelaDecoder::new(expected(vec![ExpectedSensor { sensor: 2, model: "uSPa35".into(), taxels: 15 }]));
    assert!(case.decode(V180_USPA35).is_ok());
}

/// Arbitrary JSON values, nested a few levels.
fn json_value() -> impl Strategy<Value = Value> {
    let leaf = prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::Bool),
        any::<i64>().prop_map(Value::from),
        any::<u16>().prop_map(Value::from),
        (-1e6f64..1e6).prop_map(Value::from),
        "[0-9A-Fa-f,x ]{0,24}".prop_map(Value::String),
        prop_oneof![Just("Welcome"), Just("1"), Just("uSPa44")].prop_map(Value::from),
    ];
    leaf.prop_recursive(4, 64, 8, |inner| {
        prop_oneof![
            proptest::collection::vec(inner.clone(), 0..8).prop_map(Value::Array),
            proptest::collection::btree_map(
                prop_oneof![
                    "[0-9]{1,3}",
                    Just("message".to_string()),
                    Just("data".to_string()),
                    Just("taxels".to_string()),
                    Just("model".to_string()),
                    Just("calibrated".to_string()),
                    Just("sensors".to_string()),
                    Just("integer".to_string()),
                ],
                inner,
                0..8
            )
            .prop_map(|m| Value::Object(m.into_iter().collect())),
        ]
    })
}

/// One sensor's scan of 1 to 40 taxels, forces or not.
fn sensor_scan() -> impl Strategy<Value = (String, Vec<TaxelCounts>, Option<Vec<TaxelForce>>, Option<f64>)> {
    (1usize..40).prop_flat_map(|n| {
        (
            "[A-Za-z0-9_-]{1,10}",
            proptest::collection::vec(any::<[u16; 3]>(), n),
            proptest::option::of(proptest::collection::vec(any::<[i32; 3]>(), n)),
            proptest::option::of(0.0f64..2e9),
        )
            .prop_map(|(model, taxels, forces, time)| {
                let forces = forces.map(|f| f.iter().map(|v| v.map(|x| f64::from(x) * 1e-4)).collect());
                (model, taxels, forces, time)
            })
    })
}

/// Scans of 1 to 4 sensors numbered 1 to 300.
fn any_scan() -> impl Strategy<Value = XelaScan> {
    let sensors = proptest::collection::btree_map(1u32..300, sensor_scan(), 1..4);
    (any::<u64>(), proptest::option::of(0.0f64..2e9), sensors).prop_map(
        |(message, server_time_s, sensors)| {
            let sensors = sensors
                .into_iter()
                .map(|(sensor, (model, taxels, calibrated, time_s))| XelaSensorScan {
                    sensor,
                    model,
                    time_s,
                    taxels,
                    calibrated,
                })
                .collect();
            XelaScan { message, server_time_s, sensors }
        },
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(
        std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(256)
    ))]

    /// Any scan, written in any of the server's styles, decodes to itself.
    #[test]
    fn any_scan_round_trips_in_every_style(scan in any_scan()) {
        for style in [WireStyle::HexString, WireStyle::IntegerList, WireStyle::HexAndInteger] {
            prop_assert_eq!(parse_message(&encode_scan(&scan, style)), Ok(XelaEvent::Data(scan.clone())));
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(
        std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(256)
    ))]

    /// Arbitrary text: no panic, and the counters add up.
    #[test]
    fn arbitrary_text_never_panics(texts in proptest::collection::vec(any::<String>(), 0..8)) {
        let mut d = XelaDecoder::new(Some(Expected { sensors: vec![uspa44(1)] }));
        for text in &texts {
            let _ = d.decode(text);
        }
        let c = d.counters();
        prop_assert_eq!(c.messages, texts.len() as u64);
        prop_assert_eq!(c.welcomes + c.scans + c.malformed + c.mismatches, c.messages);
    }

    /// Arbitrary JSON, shaped like the server's messages or not: no panic,
    /// and whatever decodes encodes back to itself.
    #[test]
    fn arbitrary_json_never_panics(value in json_value(), message in any::<u64>()) {
        let mut shaped = serde_json::json!({"message": message, "1": value.clone()});
        for text in [value.to_string(), shaped.to_string()] {
            if let Ok(XelaEvent::Data(scan)) = parse_message(&text) {
                let again = parse_message(&encode_scan(&scan, WireStyle::HexAndInteger));
                prop_assert_eq!(again, Ok(XelaEvent::Data(scan)));
            }
        }
        shaped["sensors"] = Value::from(1);
        let _ = XelaDecoder::default().decode(&shaped.to_string());
    }
}
