//! Parsing and validating the `[hw]` table.

use super::*;

fn parse(text: &str) -> Result<HwRigConfig, slidetrack_core::ConfigError> {
    slidetrack_core::parse_toml(text, "rig.toml")
}

#[test]
fn the_defaults_are_the_simulated_devices() {
    let cfg = parse("").unwrap();
    assert_eq!(cfg, HwRigConfig::default());
    cfg.validate().unwrap();
}

#[test]
fn a_real_rig_parses_with_hex_ids_and_round_trips_through_toml() {
    let cfg = parse(
        r#"
name = "lab"
[tactile]
kind = "can"
interface = "can1"
board = 2
taxel_base_id = 0x710
taxels = 48
fingers = { thumb = { module = 0, taxel = 5 }, index = { module = 1, taxel = 5 }, middle = { module = 2, taxel = 6 } }
[camera]
kind = "v4l2"
device = "/dev/video2"
pixel_format = "YUYV"
intrinsics = { width = 640, height = 480, fx = 600.0, fy = 600.0, cx = 320.0, cy = 240.0, distortion = [0.0, 0.0, 0.0, 0.0, 0.0] }
[hand]
kind = "can"
setpoint_id = 0x310
"#,
    )
    .unwrap();
    cfg.validate().unwrap();
    let TactileDevice::Can(c) = &cfg.tactile else { panic!("can") };
    assert_eq!((c.board, c.taxel_base_id, c.board_taxels()), (2, 0x710, [5, 21, 38]));
    let HandDevice::Can(h) = &cfg.hand else { panic!("hand") };
    assert_eq!((h.setpoint_id, h.heartbeat_id), (0x310, 0x301));
    let text = toml::to_string(&cfg).unwrap();
    assert_eq!(parse(&text).unwrap(), cfg, "{text}");
}

#[test]
fn mistakes_name_the_field() {
    let e = parse("[tactile]\nkind = \"serial\"\nbaudrate = 9600\n").unwrap_err();
    assert!(e.to_string().contains("baudrate"), "{e}");
    let e = parse("[tactile]\nkind = \"usb\"\n").unwrap_err();
    assert!(e.to_string().contains("usb"), "{e}");
    let fingers = "fingers = { thumb = { module = 0, taxel = 0 }, index = { module = 1, taxel = 16 }, \
                   middle = { module = 2, taxel = 0 } }";
    let cfg = parse(&format!("[tactile]\nkind = \"serial\"\n{fingers}\n")).unwrap();
    let e = cfg.validate().unwrap_err().to_string();
    assert!(e.contains("fingers.index") && e.contains("16"), "{e}");
    let cfg = parse("[camera]\nkind = \"v4l2\"\n").unwrap();
    assert!(cfg.validate().unwrap_err().to_string().contains("intrinsics"));
    let cfg = parse("[hand]\nkind = \"can\"\nrelease_id = 0x300\n").unwrap();
    assert!(cfg.validate().is_err());
    let cfg = parse("[tactile]\nkind = \"can\"\ntaxels = 16\n").unwrap();
    assert!(cfg.validate().unwrap_err().to_string().contains("fingers.index"), "module 1 of 16 taxels");
}
