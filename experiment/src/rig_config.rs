//! The rig configuration (TOML): simulated hand and sensors, camera, marker,
//! geometry and protocol settings. Every table has defaults; a file names only
//! what it changes.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use slidetrack_control::ProtocolSettings;
use slidetrack_core::BoardLayout;
use slidetrack_drivers::HwRigConfig;
use slidetrack_drivers::config::CameraDevice;
use slidetrack_drivers::rgbd_config::RgbdCameraConfig;
use slidetrack_sim::SimRigConfig;
use slidetrack_sim::camera::SimCameraConfig;

/// A whole rig configuration.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RigConfig {
    /// The simulated hand and tactile sensors.
    pub sim: SimRigConfig,
    /// The simulated camera.
    pub camera: SimCameraConfig,
    /// The ArUco marker on the object.
    pub marker: MarkerConfig,
    /// Where things are in the hand frame.
    pub geometry: Geometry,
    /// The experiment protocol.
    pub protocol: ProtocolSettings,
    /// The real rig's devices (`--rig hw`); absent for the simulated rig.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hw: Option<HwRigConfig>,
    /// The RGB-D camera: of the vision trackers (`vision track --live`,
    /// `track --vision`), and of the marker and the recording too with
    /// `[hw.camera] kind = "rgbd"`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rgbd: Option<RgbdCameraConfig>,
    /// The rig's tactile force calibration file (`slidetrack calibrate
    /// tactile --out`), relative to the rig TOML's directory: with it,
    /// trials record `/tactile/calibrated` (N).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tactile_calibration: Option<PathBuf>,
    /// The marker fixed to the hand for `calibrate hand`; absent by default.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hand_target: Option<crate::hand_target::HandTargetConfig>,
    /// The parallel gripper's geometry in the hand frame (finger and closing
    /// axes, grip point): `label --hand-calibration` takes the sliding axis
    /// and the contact frame from it; absent: the defaults of
    /// [`slidetrack_calibration::hand_frame::HandGeometry`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hand_geometry: Option<slidetrack_calibration::hand_frame::HandGeometry>,
}

/// The ArUco target on the object: one marker (its size comes with the
/// object), or a board of markers (`[marker.board]`, sizes in the table).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MarkerConfig {
    /// OpenCV predefined dictionary name.
    pub dictionary: String,
    /// Marker id (the single marker; unused with a board).
    pub id: u32,
    /// A GridBoard or ChArUco board instead of the single marker: its pose
    /// from every marker or corner seen is the ground truth.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub board: Option<BoardLayout>,
}

impl Default for MarkerConfig {
    fn default() -> Self {
        MarkerConfig { dictionary: "DICT_6X6_250".into(), id: 7, board: None }
    }
}

/// Geometry of the rig in the hand frame (x out of the palm, y left, z up).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Geometry {
    /// Direction the object slides along (unit vector, hand frame).
    pub sliding_axis_in_hand: [f64; 3],
    /// Where the object's origin (the grasp point) is before it slides (m, hand frame).
    pub object_start_in_hand_m: [f64; 3],
}

impl Default for Geometry {
    fn default() -> Self {
        Geometry { sliding_axis_in_hand: [0.0, 0.0, -1.0], object_start_in_hand_m: [0.10, 0.0, 0.0] }
    }
}

impl RigConfig {
    /// Reads a rig configuration, or the defaults when `path` is `None`.
    pub fn load(path: Option<&Path>) -> Result<RigConfig> {
        let Some(path) = path else { return Ok(RigConfig::default()) };
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read rig config {}", path.display()))?;
        let mut cfg: RigConfig =
            slidetrack_core::parse_toml(&text, &path.display().to_string()).context("invalid rig config")?;
        if let (Some(rgbd), Some(dir)) = (cfg.rgbd.as_mut(), path.parent()) {
            resolve_rgbd_paths(rgbd, dir);
        }
        if let Some(cal) = cfg.tactile_calibration.as_mut().filter(|c| c.is_relative()) {
            *cal = path.parent().unwrap_or(Path::new("")).join(&cal);
        }
        cfg.validate().with_context(|| format!("invalid rig config {}", path.display()))?;
        if let Some(cal) = &cfg.tactile_calibration {
            crate::tactile_force::apply::load_calibration(cal)
                .with_context(|| format!("rig config {}: tactile_calibration", path.display()))?;
        }
        Ok(cfg)
    }

    /// Checks values that TOML types cannot.
    pub fn validate(&self) -> Result<()> {
        let axis = self.geometry.sliding_axis_in_hand;
        let norm = axis.iter().map(|a| a * a).sum::<f64>().sqrt();
        anyhow::ensure!(
            norm.is_finite() && (norm - 1.0).abs() < 1e-3,
            "geometry.sliding_axis_in_hand must be a unit vector, got {axis:?}"
        );
        let s = &self.sim;
        anyhow::ensure!(
            s.physics_rate_hz >= s.tactile_rate_hz && s.tactile_rate_hz > 0.0,
            "sim.physics_rate_hz ({}) must be at least sim.tactile_rate_hz ({}) and both positive",
            s.physics_rate_hz,
            s.tactile_rate_hz
        );
        anyhow::ensure!(
            self.protocol.control_rate_hz > 0.0 && self.protocol.control_rate_hz <= s.tactile_rate_hz,
            "protocol.control_rate_hz ({}) must be positive and at most the tactile rate ({})",
            self.protocol.control_rate_hz,
            s.tactile_rate_hz
        );
        s.validate()?;
        self.camera.validate().context("camera")?;
        if let Some(g) = &self.hand_geometry {
            g.axes("the rig config")?;
        }
        if let Some(hw) = &self.hw {
            hw.validate()?;
            let rate = hw.tactile_rate_hz(s.tactile_rate_hz);
            anyhow::ensure!(
                self.protocol.control_rate_hz <= rate,
                "protocol.control_rate_hz ({}) must be at most the hw tactile rate ({rate})",
                self.protocol.control_rate_hz
            );
        }
        if let Some(rgbd) = &self.rgbd {
            rgbd.validate()?;
        }
        let rgbd_marker = self.hw.as_ref().is_some_and(|hw| matches!(hw.camera, CameraDevice::Rgbd(_)));
        anyhow::ensure!(
            !rgbd_marker || self.rgbd.is_some(),
            "hw.camera kind = \"rgbd\" is the camera of the [rgbd] table, and there is none \
             (docs/examples/rgbd-rig.toml shows one)"
        );
        if let Some(board) = &self.marker.board {
            board.validate().context("marker.board")?;
        }
        Ok(())
    }
}

/// The `[rgbd]` table's files relative to `dir` (the rig TOML's directory)
/// made so, wherever the camera is opened from.
fn resolve_rgbd_paths(rgbd: &mut RgbdCameraConfig, dir: &Path) {
    let resolve = |p: &mut Option<std::path::PathBuf>| {
        if let Some(path) = p.as_mut().filter(|p| p.is_relative()) {
            *path = dir.join(&*path);
        }
    };
    match rgbd {
        RgbdCameraConfig::Recording(r) => {
            resolve(&mut r.session);
            resolve(&mut r.directory);
            if let Some(d) = r.depth_to_color.as_mut() {
                resolve(&mut d.file);
            }
        }
        RgbdCameraConfig::V4l2(v) => {
            resolve(&mut v.color.calibration);
            resolve(&mut v.depth.calibration);
            if let Some(d) = v.depth_to_color.as_mut() {
                resolve(&mut d.file);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_empty_file_is_the_default_rig() {
        let cfg: RigConfig = toml::from_str("").unwrap();
        assert_eq!(cfg, RigConfig::default());
        cfg.validate().unwrap();
    }

    #[test]
    fn a_partial_table_overrides_only_what_it_names() {
        let cfg: RigConfig =
            toml::from_str("[sim]\ntactile_rate_hz = 200.0\n[protocol.pi]\nkp_volt_per_count = 1e-3\n")
                .unwrap();
        assert_eq!(cfg.sim.tactile_rate_hz, 200.0);
        assert_eq!(cfg.sim.physics_rate_hz, SimRigConfig::default().physics_rate_hz);
        assert_eq!(cfg.protocol.pi.kp_volt_per_count, 1e-3);
    }

    #[test]
    fn the_docs_configuration_example_is_a_valid_rig_config() {
        let readme = include_str!("../../docs/configuration.md");
        let start = readme.find("```toml\n").expect("a toml block in docs/configuration.md") + 8;
        let end = start + readme[start..].find("```").expect("closed block");
        let cfg: RigConfig =
            slidetrack_core::parse_toml(&readme[start..end], "docs/configuration.md").unwrap();
        cfg.validate().unwrap();
        assert_eq!(cfg.marker.dictionary, "DICT_6X6_250");
    }

    #[test]
    fn a_marker_table_may_describe_a_board_and_the_single_marker_serialises_as_before() {
        let single = toml::to_string(&RigConfig::default()).unwrap();
        assert!(single.contains("[marker]\ndictionary = \"DICT_6X6_250\"\nid = 7\n"), "{single}");
        assert!(!single.contains("board"), "{single}");
        let text = "[marker]\ndictionary = \"DICT_5X5_100\"\n[marker.board]\nkind = \"charuco\"\n\
                    squares_x = 5\nsquares_y = 7\nsquare_length_m = 0.04\nmarker_length_m = 0.02\n";
        let cfg: RigConfig = slidetrack_core::parse_toml(text, "rig.toml").unwrap();
        cfg.validate().unwrap();
        assert!(matches!(cfg.marker.board, Some(BoardLayout::Charuco { squares_x: 5, .. })));
        let back: RigConfig = toml::from_str(&toml::to_string(&cfg).unwrap()).unwrap();
        assert_eq!(back, cfg);
        let bad = text.replace("marker_length_m = 0.02", "marker_length_m = 0.05");
        let cfg: RigConfig = slidetrack_core::parse_toml(&bad, "rig.toml").unwrap();
        let e = format!("{:#}", cfg.validate().unwrap_err());
        assert!(e.contains("marker.board") && e.contains("marker_length_m"), "{e}");
    }

    #[test]
    fn bad_files_give_messages_naming_the_file_and_field() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rig.toml");
        std::fs::write(&path, "[sim]\ntactile_rate = 3\n").unwrap();
        let e = format!("{:#}", RigConfig::load(Some(&path)).unwrap_err());
        assert!(e.contains("rig.toml") && e.contains("tactile_rate"), "{e}");
        std::fs::write(&path, "[geometry]\nsliding_axis_in_hand = [0.0, 0.0, 2.0]\n").unwrap();
        let e = format!("{:#}", RigConfig::load(Some(&path)).unwrap_err());
        assert!(e.contains("sliding_axis_in_hand"), "{e}");
        let e = format!("{:#}", RigConfig::load(Some(&dir.path().join("none.toml"))).unwrap_err());
        assert!(e.contains("none.toml"), "{e}");
    }

    /// `[hw.camera] kind = "rgbd"` names the `[rgbd]` camera: without one it
    /// is refused, naming both; with one, the stand-in's relative path is
    /// from the rig TOML's directory, wherever the command runs.
    #[test]
    fn an_rgbd_marker_camera_needs_the_rgbd_table_and_its_paths_are_the_tomls() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rig.toml");
        let hw = "[hw]\nname = \"x\"\n[hw.tactile]\nkind = \"sim\"\n[hw.camera]\nkind = \"rgbd\"\n";
        std::fs::write(&path, hw).unwrap();
        let e = format!("{:#}", RigConfig::load(Some(&path)).unwrap_err());
        assert!(e.contains("rig.toml") && e.contains("kind = \"rgbd\"") && e.contains("[rgbd]"), "{e}");
        let rgbd = "[rgbd]\nkind = \"recording\"\nsession = \"standin.mcap\"\n";
        std::fs::write(&path, format!("{hw}{rgbd}")).unwrap();
        let cfg = RigConfig::load(Some(&path)).unwrap();
        let Some(RgbdCameraConfig::Recording(r)) = &cfg.rgbd else { panic!("a recording") };
        assert_eq!(r.session.as_deref(), Some(dir.path().join("standin.mcap").as_path()));
        let bad = "[hw]\nname = \"x\"\n[hw.camera]\nkind = \"rgbd\"\ndevice = \"/dev/video0\"\n";
        std::fs::write(&path, format!("{bad}{rgbd}")).unwrap();
        let e = format!("{:#}", RigConfig::load(Some(&path)).unwrap_err());
        assert!(e.contains("device"), "the camera's device is the [rgbd] table's: {e}");
    }

    #[test]
    fn the_rgbd_examples_are_valid_rig_configs_that_round_trip() {
        use slidetrack_drivers::rgbd_config::RgbdCameraConfig;
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/examples/rgbd-rig.toml");
        let cfg = RigConfig::load(Some(Path::new(path))).unwrap();
        let Some(RgbdCameraConfig::V4l2(camera)) = &cfg.rgbd else { panic!("a v4l2 [rgbd] table") };
        assert_eq!(camera.depth.pixel_format, slidetrack_drivers::config::V4l2PixelFormat::Z16);
        assert!(camera.depth_to_color.is_some());
        let back: RigConfig = toml::from_str(&toml::to_string(&cfg).unwrap()).unwrap();
        assert_eq!(back, cfg);
        let readme = include_str!("../../docs/vision.md");
        let section = readme.find("## Vision on a real RGB-D camera").expect("the RGB-D section");
        let start = section + readme[section..].find("```toml\n").expect("a toml block") + 8;
        let end = start + readme[start..].find("```").expect("closed block");
        let cfg: RigConfig = toml::from_str(&readme[start..end]).unwrap();
        cfg.validate().unwrap();
        assert!(cfg.rgbd.is_some());
    }
}
