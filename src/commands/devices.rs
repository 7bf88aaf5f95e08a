//! `slidetrack devices`: the cameras (with formats), serial ports and CAN
//! interfaces present, to fill in the `[hw]` table of a rig TOML.

use std::fmt::Write;

use anyhow::Result;
use slidetrack_experiment::devices::{DeviceList, list_devices};

use crate::cli::DevicesArgs;

pub fn run(args: &DevicesArgs) -> Result<()> {
    let list = list_devices();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&list)?);
    } else {
        print!("{}", render(&list));
    }
    Ok(())
}

/// The listing for people: one section per kind, "no ... found" when empty.
pub fn render(list: &DeviceList) -> String {
    let mut out = String::new();
    // Writing to a String cannot fail.
    let _ = writeln!(out, "Cameras (V4L2):");
    if list.cameras.is_empty() {
        let _ = writeln!(out, "  no cameras found");
    }
    for c in &list.cameras {
        let what =
            if c.name.is_empty() { String::new() } else { format!(" {} ({}, {})", c.name, c.driver, c.bus) };
        let _ = writeln!(out, "  {}{what}", c.path);
        if let Some(e) = &c.error {
            let _ = writeln!(out, "    {e}");
        }
        if c.formats.is_empty() && c.error.is_none() {
            let _ = writeln!(out, "    no capture formats (a metadata node)");
        }
        for f in &c.formats {
            let sizes: Vec<String> = f
                .sizes
                .iter()
                .map(|s| {
                    let fps: Vec<String> = s.fps.iter().map(|r| format!("{r:.0}")).collect();
                    if fps.is_empty() {
                        format!("{}x{}", s.width, s.height)
                    } else {
                        format!("{}x{}@{}", s.width, s.height, fps.join("/"))
                    }
                })
                .collect();
            let _ = writeln!(out, "    {} ({}): {}", f.fourcc.trim_end(), f.description, sizes.join(", "));
        }
    }
    let _ = writeln!(out, "Serial ports:");
    if list.serial_ports.is_empty() {
        let _ = writeln!(out, "  no serial ports found");
    }
    for p in &list.serial_ports {
        let usb = p.usb.as_deref().map(|u| format!(" {u}")).unwrap_or_default();
        let _ = writeln!(out, "  {} ({}){usb}", p.path, p.kind);
    }
    let _ = writeln!(out, "CAN interfaces:");
    if list.can_interfaces.is_empty() {
        let _ = writeln!(out, "  no CAN interfaces found");
    }
    for c in &list.can_interfaces {
        let virt = if c.virtual_interface { ", virtual" } else { "" };
        let _ = writeln!(out, "  {} ({}{virt})", c.name, c.state);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use slidetrack_experiment::devices::{CameraListing, CanListing, FormatListing, SizeListing};

    #[test]
    fn an_empty_machine_says_that_nothing_was_found() {
        let text = render(&DeviceList::default());
        for what in ["no cameras found", "no serial ports found", "no CAN interfaces found"] {
            assert!(text.contains(what), "{text}");
        }
    }

    #[test]
    fn devices_show_their_formats_and_state() {
        let list = DeviceList {
            cameras: vec![CameraListing {
                path: "/dev/video0".into(),
                name: "HD Webcam".into(),
                driver: "uvcvideo".into(),
                bus: "usb-1".into(),
                formats: vec![FormatListing {
                    fourcc: "MJPG".into(),
                    description: "Motion-JPEG".into(),
                    sizes: vec![SizeListing { width: 640, height: 480, fps: vec![30.0, 15.0] }],
                }],
                error: None,
            }],
            serial_ports: vec![],
            can_interfaces: vec![CanListing {
                name: "can0".into(),
                state: "up".into(),
                virtual_interface: false,
            }],
        };
        let text = render(&list);
        assert!(text.contains("/dev/video0 HD Webcam (uvcvideo, usb-1)"), "{text}");
        assert!(text.contains("MJPG (Motion-JPEG): 640x480@30/15"), "{text}");
        assert!(text.contains("no serial ports found") && text.contains("can0 (up)"), "{text}");
    }
}
