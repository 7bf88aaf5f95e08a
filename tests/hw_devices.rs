//! `slidetrack devices` works on any machine, with or without devices.

mod common;

use common::ok;

#[test]
fn devices_lists_every_kind_or_says_none_was_found() {
    let text = ok(&["devices"]);
    for (section, none) in [
        ("Cameras (V4L2):", "no cameras found"),
        ("Serial ports:", "no serial ports found"),
        ("CAN interfaces:", "no CAN interfaces found"),
    ] {
        let start = text.find(section).unwrap_or_else(|| panic!("no {section} section:\n{text}"));
        let body = text[start + section.len()..].lines().nth(1).unwrap_or_default();
        assert!(body.starts_with("  "), "{section} lists something or says `{none}`:\n{text}");
    }
    let json: serde_json::Value = serde_json::from_str(&ok(&["devices", "--json"])).unwrap();
    for key in ["cameras", "serial_ports", "can_interfaces"] {
        assert!(json[key].is_array(), "{json}");
    }
    // The text and the JSON agree on what was found.
    if json["cameras"].as_array().unwrap().is_empty() {
        assert!(text.contains("no cameras found"), "{text}");
    }
    if json["can_interfaces"].as_array().unwrap().is_empty() {
        assert!(text.contains("no CAN interfaces found"), "{text}");
    }
}
