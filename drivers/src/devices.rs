//! What is plugged in: V4L2 cameras with their formats, serial ports and
//! CAN interfaces, for `slidetrack devices`.

use std::fs;
use std::path::Path;

use serde::Serialize;
use v4l::Device;
use v4l::frameinterval::FrameIntervalEnum;
use v4l::framesize::FrameSizeEnum;
use v4l::video::Capture;

/// ARPHRD_CAN: the `type` of a CAN network interface in sysfs.
const ARPHRD_CAN: u32 = 280;

/// Everything found.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct DeviceList {
    /// Video capture devices.
    pub cameras: Vec<CameraListing>,
    /// Serial ports.
    pub serial_ports: Vec<SerialPortListing>,
    /// CAN network interfaces.
    pub can_interfaces: Vec<CanListing>,
}

/// One `/dev/video*` node.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CameraListing {
    /// Device node.
    pub path: String,
    /// Card name, as the driver reports it.
    pub name: String,
    /// Kernel driver (`uvcvideo`).
    pub driver: String,
    /// Bus (`usb-0000:00:14.0-1`).
    pub bus: String,
    /// Capture formats; empty for metadata nodes.
    pub formats: Vec<FormatListing>,
    /// Why the node could not be queried, if it could not.
    pub error: Option<String>,
}

/// A pixel format and the sizes and rates offered in it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FormatListing {
    /// Four-character code (`MJPG`, `YUYV`, `Z16 `).
    pub fourcc: String,
    /// The driver's description.
    pub description: String,
    /// `WIDTHxHEIGHT` with the frame rates (Hz) offered at that size.
    pub sizes: Vec<SizeListing>,
}

/// One frame size.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SizeListing {
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
    /// Frame rates (Hz); for a continuous range, its ends.
    pub fps: Vec<f64>,
}

/// A serial port.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SerialPortListing {
    /// Device path.
    pub path: String,
    /// `usb`, `pci`, `bluetooth` or `unknown`.
    pub kind: String,
    /// USB vendor and product (`0483:5740 STMicroelectronics Virtual COM Port`), when USB.
    pub usb: Option<String>,
}

/// A CAN interface.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CanListing {
    /// Interface name.
    pub name: String,
    /// `up`, `down` or `unknown` (from `operstate`).
    pub state: String,
    /// True for a virtual interface (no device behind it, like `vcan`).
    pub virtual_interface: bool,
}

/// Lists every device under the real `/dev` and `/sys`.
pub fn list_devices() -> DeviceList {
    DeviceList {
        cameras: list_cameras(Path::new("/dev")),
        serial_ports: list_serial_ports(),
        can_interfaces: list_can_interfaces(Path::new("/sys/class/net")),
    }
}

/// The `video*` nodes under `dev_dir`, queried one by one.
pub fn list_cameras(dev_dir: &Path) -> Vec<CameraListing> {
    let Ok(entries) = fs::read_dir(dev_dir) else { return Vec::new() };
    let mut paths: Vec<_> = entries
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.file_name().and_then(|n| n.to_str()).is_some_and(|n| n.starts_with("video")))
        .collect();
    paths.sort();
    paths.iter().map(|p| query_camera(p)).collect()
}

fn query_camera(path: &Path) -> CameraListing {
    let mut listing = CameraListing {
        path: path.display().to_string(),
        name: String::new(),
        driver: String::new(),
        bus: String::new(),
        formats: Vec::new(),
        error: None,
    };
    let dev = match Device::with_path(path) {
        Ok(d) => d,
        Err(e) => {
            listing.error = Some(format!("cannot open: {e}"));
            return listing;
        }
    };
    match dev.query_caps() {
        Ok(caps) => {
            listing.name = caps.card;
            listing.driver = caps.driver;
            listing.bus = caps.bus;
        }
        Err(e) => listing.error = Some(format!("cannot query: {e}")),
    }
    // Metadata nodes of UVC cameras have no capture formats: an error here is not news.
    for f in dev.enum_formats().unwrap_or_default() {
        let mut sizes = Vec::new();
        for size in dev.enum_framesizes(f.fourcc).unwrap_or_default() {
            let discrete: Vec<(u32, u32)> = match size.size {
                FrameSizeEnum::Discrete(d) => vec![(d.width, d.height)],
                FrameSizeEnum::Stepwise(s) => vec![(s.min_width, s.min_height), (s.max_width, s.max_height)],
            };
            for (width, height) in discrete {
                let mut fps: Vec<f64> = dev
                    .enum_frameintervals(f.fourcc, width, height)
                    .unwrap_or_default()
                    .into_iter()
                    .flat_map(|i| match i.interval {
                        FrameIntervalEnum::Discrete(r) => vec![r],
                        FrameIntervalEnum::Stepwise(s) => vec![s.min, s.max],
                    })
                    .filter(|r| r.numerator > 0)
                    .map(|r| f64::from(r.denominator) / f64::from(r.numerator))
                    .collect();
                fps.sort_by(|a, b| b.total_cmp(a));
                fps.dedup();
                sizes.push(SizeListing { width, height, fps });
            }
        }
        let fourcc = f.fourcc.str().map(str::to_string).unwrap_or_else(|_| format!("{:?}", f.fourcc.repr));
        listing.formats.push(FormatListing { fourcc, description: f.description, sizes });
    }
    listing
}

/// Serial ports, as the serialport crate finds them in sysfs.
pub fn list_serial_ports() -> Vec<SerialPortListing> {
    // The crate's sysfs scan panics when the directory is missing (containers).
    if !Path::new("/sys/class/tty").is_dir() {
        return Vec::new();
    }
    let ports = serialport::available_ports().unwrap_or_default();
    ports
        .into_iter()
        .map(|p| {
            let (kind, usb) = match p.port_type {
                serialport::SerialPortType::UsbPort(u) => {
                    let product =
                        [u.manufacturer, u.product].into_iter().flatten().collect::<Vec<_>>().join(" ");
                    ("usb", Some(format!("{:04x}:{:04x} {product}", u.vid, u.pid).trim_end().to_string()))
                }
                serialport::SerialPortType::PciPort => ("pci", None),
                serialport::SerialPortType::BluetoothPort => ("bluetooth", None),
                serialport::SerialPortType::Unknown => ("unknown", None),
            };
            SerialPortListing { path: p.port_name, kind: kind.into(), usb }
        })
        .collect()
}

/// The CAN interfaces under `net_dir` (`/sys/class/net`): those whose `type` is 280.
pub fn list_can_interfaces(net_dir: &Path) -> Vec<CanListing> {
    let Ok(entries) = fs::read_dir(net_dir) else { return Vec::new() };
    let mut out: Vec<CanListing> = entries
        .filter_map(Result::ok)
        .filter_map(|e| {
            let dir = e.path();
            let kind: u32 = fs::read_to_string(dir.join("type")).ok()?.trim().parse().ok()?;
            (kind == ARPHRD_CAN).then(|| CanListing {
                name: e.file_name().to_string_lossy().into_owned(),
                state: fs::read_to_string(dir.join("operstate"))
                    .map(|s| s.trim().to_string())
                    .unwrap_or_else(|_| "unknown".into()),
                virtual_interface: !dir.join("device").exists(),
            })
        })
        .collect();
    out.sort_by(|a, b| a.name.cmp(&b.name));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn can_interfaces_are_the_net_devices_of_type_280() {
        let dir = tempfile::tempdir().unwrap();
        for (name, kind, state) in
            [("can0", "280\n", "up\n"), ("eth0", "1\n", "up\n"), ("vcan1", "280", "unknown")]
        {
            let d = dir.path().join(name);
            fs::create_dir(&d).unwrap();
            fs::write(d.join("type"), kind).unwrap();
            fs::write(d.join("operstate"), state).unwrap();
        }
        fs::create_dir(dir.path().join("can0/device")).unwrap();
        fs::create_dir(dir.path().join("broken")).unwrap(); // no type file
        let found = list_can_interfaces(dir.path());
        assert_eq!(
            found,
            vec![
                CanListing { name: "can0".into(), state: "up".into(), virtual_interface: false },
                CanListing { name: "vcan1".into(), state: "unknown".into(), virtual_interface: true },
            ]
        );
        assert!(list_can_interfaces(&dir.path().join("missing")).is_empty());
    }

    #[test]
    fn a_directory_without_video_nodes_has_no_cameras() {
        let dir = tempfile::tempdir().unwrap();
        fs::write(dir.path().join("ttyS0"), "").unwrap();
        assert!(list_cameras(dir.path()).is_empty());
        // A node that is not a V4L2 device is listed with the reason.
        fs::write(dir.path().join("video9"), "").unwrap();
        let cams = list_cameras(dir.path());
        assert_eq!(cams.len(), 1);
        assert!(cams[0].error.is_some(), "{cams:?}");
    }
}
