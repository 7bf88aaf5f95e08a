//! Parsing and validating the `[hw]` table.

use super::*;
use crate::can::protocol::CanFrame;

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
fingers = { thumb = { sensor = "thumb", taxel = 5 }, index = { sensor = "index", taxel = 5 }, middle = { sensor = "middle" } }
[[tactile.sensors]]
name = "thumb"
module = 0
finger = "thumb"
model = "uSPa44"
rows = 4
cols = 4
[[tactile.sensors]]
name = "index"
module = 1
finger = "index"
model = "uSPa44"
rows = 4
cols = 4
[[tactile.sensors]]
name = "middle"
module = 2
finger = "middle"
model = "uSPa44"
rows = 1
cols = 2
taxel_positions_mm = [[0.0, 0.0], [4.7, 0.0]]
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
    let ids: Vec<u32> = (0x710..0x712 + 32).collect();
    let layout = c.layout().unwrap();
    assert_eq!(layout.slots.iter().map(|((id, _), _)| *id).collect::<Vec<_>>(), ids);
    assert_eq!(c.board, 2);
    assert_eq!(layout.start[0].0, CanFrame::standard(0x202, &[7, 0]).unwrap(), "the legacy start command");
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
    let fingers = "fingers = { thumb = { sensor = \"thumb\" }, index = { sensor = \"index\", taxel = 16 }, \
                   middle = { sensor = \"middle\" } }";
    let cfg = parse(&format!("[tactile]\nkind = \"serial\"\n{fingers}\n")).unwrap();
    let e = cfg.validate().unwrap_err().to_string();
    assert!(e.contains("finger `index` reads taxel 16 of tactile sensor `index`, which has 16"), "{e}");
    let e =
        parse("[tactile]\nkind = \"serial\"\nfingers = { thumb = { module = 0, taxel = 0 } }\n").unwrap_err();
    assert!(e.to_string().contains("module"), "the old finger map is refused by name: {e}");
    let cfg = parse("[camera]\nkind = \"v4l2\"\n").unwrap();
    assert!(cfg.validate().unwrap_err().to_string().contains("intrinsics"));
    let cfg = parse("[hand]\nkind = \"can\"\nrelease_id = 0x300\n").unwrap();
    assert!(cfg.validate().is_err());
    let cfg = parse("[tactile]\nkind = \"can\"\ntaxels = 16\n").unwrap();
    let e = cfg.validate().unwrap_err().to_string();
    assert!(e.contains("sensors `index` (module 1) ends at board taxel 32, beyond the board's 16"), "{e}");
}
