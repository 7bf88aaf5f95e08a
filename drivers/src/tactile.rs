//! The `[hw.tactile]` table: which transport carries the fingertip sensors,
//! and everything the rest of the workspace asks of it. Every question is a
//! method here with one arm per kind and no wildcard, so that a new kind is
//! a compile error at each place that must handle it, and nowhere else.
//!
//! A new transport is a folder (see `crate::serial` for the shape: its
//! configuration, sans-IO protocol, `backend` and emulator) and one variant
//! here; `docs/architecture.md` ("Adding a tactile transport") lists the
//! files it takes.

use serde::{Deserialize, Serialize};

use crate::can::config::CanTactileConfig;
use crate::can_hand::protocol::HandCanIds;
use crate::config::error::{HwConfigError, IdCollision};
use crate::emulated::EMULATED_PORT;
use crate::serial::config::SerialTactileConfig;
use crate::xela_ros2::XelaRos2TactileConfig;
use crate::xela_ws::config::{EMULATED_URL, XelaWsTactileConfig};

/// The fingertip sensors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum TactileDevice {
    /// The simulated modules (`[sim]` table), on the wall clock.
    Sim,
    /// uSkin-style modules streaming the serial format.
    Serial(SerialTactileConfig),
    /// Taxel frames on CAN (SocketCAN or an SLCAN adapter), in a
    /// configured layout.
    Can(CanTactileConfig),
    /// XELA sensors read through XELA's `xela_server` (WebSocket JSON).
    #[serde(rename = "xela_ws")]
    XelaWs(XelaWsTactileConfig),
    /// XELA sensors read from XELA's ROS 2 server `xela_server_ros2` over
    /// DDS (its `SensStream` topic); opened by `experiment` through
    /// `slidetrack_ros2::xela`.
    Ros2(XelaRos2TactileConfig),
}

impl TactileDevice {
    /// The table's `kind`, as written in the rig TOML.
    pub fn kind(&self) -> &'static str {
        match self {
            TactileDevice::Sim => "sim",
            TactileDevice::Serial(_) => "serial",
            TactileDevice::Can(_) => "can",
            TactileDevice::XelaWs(_) => "xela_ws",
            TactileDevice::Ros2(_) => "ros2",
        }
    }

    /// A few words for the log: the kind and where the device is
    /// (`serial /dev/ttyACM0`, `CAN can0`).
    pub fn describe(&self) -> String {
        match self {
            TactileDevice::Sim => "sim".to_string(),
            TactileDevice::Serial(s) => format!("serial {}", s.port),
            TactileDevice::Can(c) => match &c.slcan {
                Some(s) => format!("CAN via SLCAN adapter {}", s.port),
                None => format!("CAN {}", c.interface),
            },
            TactileDevice::XelaWs(x) => format!("xela_server {}", x.url),
            TactileDevice::Ros2(r) => format!("xela_server_ros2 topic {}", r.topic),
        }
    }

    /// True for the simulated modules themselves (`kind = "sim"`).
    pub fn is_simulated(&self) -> bool {
        match self {
            TactileDevice::Sim => true,
            TactileDevice::Serial(_)
            | TactileDevice::Can(_)
            | TactileDevice::XelaWs(_)
            | TactileDevice::Ros2(_) => false,
        }
    }

    /// True when the device is the simulated rig behind the transport's
    /// emulator (`port = "emulated"`, `slcan = { port = "emulated" }`,
    /// `url = "emulated"`).
    pub fn is_emulated(&self) -> bool {
        match self {
            TactileDevice::Sim => false,
            TactileDevice::Serial(s) => s.port == EMULATED_PORT,
            TactileDevice::Can(c) => c.slcan.as_ref().is_some_and(|s| s.port == EMULATED_PORT),
            TactileDevice::XelaWs(x) => x.url == EMULATED_URL,
            TactileDevice::Ros2(_) => false,
        }
    }

    /// True when the scans come from the simulated world (simulated or
    /// emulated): the simulated truth then describes them.
    pub fn feels_simulated_world(&self) -> bool {
        self.is_simulated() || self.is_emulated()
    }

    /// Nominal scan rate (Hz): the configured one of a real device,
    /// `sim_rate_hz` for the simulated and emulated sensors.
    pub fn rate_hz(&self, sim_rate_hz: f64) -> f64 {
        if self.feels_simulated_world() {
            return sim_rate_hz;
        }
        match self {
            TactileDevice::Sim => sim_rate_hz,
            TactileDevice::Serial(s) => s.rate_hz,
            TactileDevice::Can(c) => c.rate_hz,
            TactileDevice::XelaWs(x) => x.rate_hz,
            TactileDevice::Ros2(r) => r.rate_hz,
        }
    }

    /// Checks what serde's types cannot.
    pub fn validate(&self) -> Result<(), HwConfigError> {
        match self {
            TactileDevice::Sim => Ok(()),
            TactileDevice::Serial(s) => s.validate(),
            TactileDevice::Can(c) => c.validate(),
            TactileDevice::XelaWs(x) => Ok(x.validate()?),
            TactileDevice::Ros2(r) => Ok(r.validate()?),
        }
    }

    /// A CAN id that both these sensors and the hand on `hand_interface`
    /// use, when both are on one SocketCAN interface.
    pub fn can_collision_with_hand(&self, hand_interface: &str, hand: &HandCanIds) -> Option<IdCollision> {
        match self {
            TactileDevice::Can(c) => c.collision_with_hand(hand_interface, hand),
            TactileDevice::Sim
            | TactileDevice::Serial(_)
            | TactileDevice::XelaWs(_)
            | TactileDevice::Ros2(_) => None,
        }
    }

    /// The same device found at `endpoint` (a serial port, an SLCAN
    /// adapter's port or a SocketCAN interface, a server's URL), as a
    /// program finds an emulator that `slidetrack emulate` serves.
    pub fn at(&self, endpoint: &str) -> TactileDevice {
        let mut device = self.clone();
        match &mut device {
            TactileDevice::Sim => {}
            TactileDevice::Serial(s) => s.port = endpoint.into(),
            TactileDevice::Can(c) => match &mut c.slcan {
                Some(s) => s.port = endpoint.into(),
                None => c.interface = endpoint.into(),
            },
            TactileDevice::XelaWs(x) => x.url = endpoint.into(),
            TactileDevice::Ros2(r) => r.topic = endpoint.into(),
        }
        device
    }

    /// The table of a serial device, for decoding serial captures.
    pub fn as_serial(&self) -> Option<&SerialTactileConfig> {
        match self {
            TactileDevice::Serial(s) => Some(s),
            TactileDevice::Sim
            | TactileDevice::Can(_)
            | TactileDevice::XelaWs(_)
            | TactileDevice::Ros2(_) => None,
        }
    }

    /// The table of a CAN device, for decoding candump logs.
    pub fn as_can(&self) -> Option<&CanTactileConfig> {
        match self {
            TactileDevice::Can(c) => Some(c),
            TactileDevice::Sim
            | TactileDevice::Serial(_)
            | TactileDevice::XelaWs(_)
            | TactileDevice::Ros2(_) => None,
        }
    }
}

/// What starts a device: its backend on the real device or on its emulator
/// fed by the simulated rig, or the emulator alone for other programs.
#[cfg(all(feature = "devices", target_os = "linux"))]
impl TactileDevice {
    /// Opens the device on `clock`. The simulated modules and the emulated
    /// devices read `simulated` (the simulated rig's sensors, at
    /// `sim_rate_hz`); a real device reads its port, bus or server at its
    /// configured rate and drops `simulated`.
    pub fn open(
        &self,
        simulated: Option<Box<dyn slidetrack_core::TactileSource>>,
        sim_rate_hz: f64,
        clock: std::sync::Arc<dyn slidetrack_core::Clock>,
    ) -> Result<Box<dyn slidetrack_core::TactileSource>, slidetrack_core::DeviceError> {
        use slidetrack_core::{DeviceError, ErrorKind};

        use crate::can::backend::CanTactile;
        use crate::serial::backend::{EmulatedSerialTactile, SerialTactile};
        use crate::slcan::backend::emulated::EmulatedSlcanTactile;
        use crate::xela_ws::backend::{EmulatedXelaWsTactile, XelaWsTactile};

        let emulated = self.is_emulated();
        Ok(match (self, simulated) {
            (TactileDevice::Sim, Some(t)) => t,
            (TactileDevice::Sim, None) => {
                let why = "internal: the simulated tactile modules were not built";
                return Err(DeviceError::new(ErrorKind::Other, "sim tactile", why));
            }
            (TactileDevice::Serial(s), Some(t)) if emulated => {
                Box::new(EmulatedSerialTactile::start(t, s, sim_rate_hz, clock)?)
            }
            (TactileDevice::Serial(s), _) => Box::new(SerialTactile::open(&s.port, s, s.rate_hz, clock)?),
            (TactileDevice::Can(c), Some(t)) if emulated => {
                Box::new(EmulatedSlcanTactile::start(t, c, sim_rate_hz, clock)?)
            }
            (TactileDevice::Can(c), _) => Box::new(CanTactile::open(c, clock)?),
            (TactileDevice::XelaWs(x), Some(t)) if emulated => {
                Box::new(EmulatedXelaWsTactile::start(t, x, sim_rate_hz, clock)?)
            }
            (TactileDevice::XelaWs(x), _) => Box::new(XelaWsTactile::connect(&x.url, x, x.rate_hz, clock)?),
            (TactileDevice::Ros2(r), _) => {
                let why =
                    "internal: a ROS 2 source is opened by experiment (slidetrack_ros2::xela), not here";
                return Err(DeviceError::new(ErrorKind::Other, r.topic.clone(), why));
            }
        })
    }

    /// Starts the transport's emulator alone, serving `source`'s scans
    /// where a program would find the device (`slidetrack emulate`): a
    /// pseudo-terminal of the serial modules or of an SLCAN adapter, or a
    /// local `xela_server`. The table's port or URL is ignored.
    pub fn emulate(
        &self,
        source: Box<dyn slidetrack_core::TactileSource>,
    ) -> Result<crate::emulated::ServedEmulator, slidetrack_core::DeviceError> {
        use slidetrack_core::{DeviceError, ErrorKind};

        use crate::emulated::ServedEmulator;
        use crate::emulated::{check_emulated_sensors, sensor_grids};
        use crate::serial::backend::EmulatedPort;
        use crate::xela_ws::backend::XelaWsLiveEmulator;

        match self {
            TactileDevice::Sim => Err(DeviceError::new(
                ErrorKind::Other,
                EMULATED_PORT,
                "the simulated modules have no wire to emulate: give [hw.tactile] a kind",
            )),
            TactileDevice::Serial(s) => {
                check_emulated_sensors(&source.info(), &sensor_grids(&s.sensors), "serial emulator")?;
                let port = EmulatedPort::open()?;
                let modules = s.sensors.iter().map(|x| x.module).collect();
                let emulator = port.stream(source, modules, s.taxels_per_module, s.emulator.clone())?;
                Ok(ServedEmulator { endpoint: emulator.path().to_string(), emulator: Box::new(emulator) })
            }
            TactileDevice::Can(c) => {
                let emulator = crate::slcan::backend::emulated::serve(source, c)?;
                Ok(ServedEmulator { endpoint: emulator.path().to_string(), emulator: Box::new(emulator) })
            }
            TactileDevice::XelaWs(x) => {
                let emulator = XelaWsLiveEmulator::start(source, x)?;
                Ok(ServedEmulator { endpoint: emulator.url(), emulator: Box::new(emulator) })
            }
            TactileDevice::Ros2(_) => Err(DeviceError::new(
                ErrorKind::Other,
                EMULATED_PORT,
                "kind = \"ros2\" has no emulator: publish SensStream with any ROS 2 node (see docs/ros2.md)",
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One device of every kind, each at its defaults.
    fn every_kind() -> Vec<TactileDevice> {
        vec![
            TactileDevice::Sim,
            TactileDevice::Serial(SerialTactileConfig::default()),
            TactileDevice::Can(CanTactileConfig::default()),
            TactileDevice::XelaWs(XelaWsTactileConfig::default()),
            TactileDevice::Ros2(XelaRos2TactileConfig::default()),
        ]
    }

    #[test]
    fn the_kind_is_the_tag_of_the_table() {
        for device in every_kind() {
            let table = toml::Value::try_from(&device).unwrap();
            assert_eq!(table["kind"].as_str(), Some(device.kind()), "{device:?}");
            device.validate().unwrap();
        }
    }

    #[test]
    fn an_emulated_device_runs_at_the_simulated_rate_until_it_is_found_at_an_endpoint() {
        let emulated = [
            "kind = \"serial\"\nport = \"emulated\"",
            "kind = \"can\"\nslcan = { port = \"emulated\" }",
            "kind = \"xela_ws\"\nurl = \"emulated\"",
        ];
        for text in emulated {
            let device: TactileDevice = slidetrack_core::parse_toml(text, "rig.toml").unwrap();
            assert!(device.is_emulated() && device.feels_simulated_world(), "{text}");
            assert_eq!(device.rate_hz(250.0), 250.0, "{text}");
            let found = device.at("/dev/pts/7");
            assert!(!found.is_emulated() && !found.feels_simulated_world(), "{found:?}");
            assert_eq!(found.rate_hz(250.0), 100.0, "{found:?}");
            assert_eq!(found.kind(), device.kind());
        }
        assert!(TactileDevice::Sim.feels_simulated_world() && !TactileDevice::Sim.is_emulated());
        assert_eq!(TactileDevice::Sim.at("/dev/null"), TactileDevice::Sim);
    }

    #[test]
    fn a_device_describes_where_it_is() {
        let described: Vec<String> = every_kind().iter().map(TactileDevice::describe).collect();
        assert_eq!(
            described,
            [
                "sim",
                "serial /dev/ttyACM0",
                "CAN can0",
                "xela_server ws://127.0.0.1:5000",
                "xela_server_ros2 topic /xServTopic"
            ]
        );
    }
}
