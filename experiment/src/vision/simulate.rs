//! A simulated RGB-D session of a fast-moving object (`vision simulate`),
//! with the true pose, velocity and masks, and the imitated slow network's
//! masks and poses; optionally an ArUco marker printed on the object and
//! its `--aruco-config` written next to the session.

use std::path::PathBuf;
use std::time::SystemTime;

use anyhow::{Context, Result};
use slidetrack_session::{Recorder, RecorderOptions, SessionMetadata};
use slidetrack_sim::rgbd::{FastSequence, FastSequenceConfig, SimObjectKind};
use slidetrack_vision::cloud::mask;
use slidetrack_vision::record::RgbdChannels;
use slidetrack_vision::sources::{FrameTruth, MeasurementSource, PoseConfig, SlowNetwork, SlowNetworkConfig};

/// The options of a simulated RGB-D session.
#[derive(Clone, Debug)]
pub struct SimulateOptions {
    /// The object's name (cracker_box, sugar_box, ...).
    pub object: String,
    /// Length of the sequence (s), at 30 Hz.
    pub duration_s: f64,
    /// Seed of the motion, the noise and the network.
    pub seed: u64,
    /// Peak linear speed (m/s).
    pub max_speed_mps: f64,
    /// Peak angular speed (deg/s).
    pub max_angular_speed_dps: f64,
    /// An ArUco marker to print on the object: DICTIONARY:ID.
    pub marker: Option<String>,
    /// Side of the printed marker's black square (m).
    pub marker_size_m: f64,
    /// Session file to write.
    pub out: PathBuf,
    /// Replace the file if it exists.
    pub overwrite: bool,
}

/// A simulated session being written.
pub struct SimulatedSession {
    out: PathBuf,
    kind: SimObjectKind,
    sequence: FastSequence,
    network: SlowNetwork,
    recorder: Recorder,
    channels: RgbdChannels,
    /// Where the marker's `--aruco-config` goes and its text.
    aruco_config: Option<(PathBuf, String)>,
    /// Why the printed marker will rarely be detected, if it will not.
    marker_warning: Option<String>,
}

/// What was written.
#[derive(Clone, Debug)]
pub struct SimulatedSummary {
    /// The session file.
    pub out: PathBuf,
    /// Frames written, at 30 Hz.
    pub frames: usize,
    /// The object's name.
    pub object: &'static str,
    /// Network results delivered (one every sixth frame).
    pub network_results: usize,
    /// Of them, outliers.
    pub outliers: usize,
    /// The marker configuration written next to the session.
    pub aruco_config: Option<PathBuf>,
}

impl SimulatedSession {
    /// The sequence of `options`, with its session created.
    pub fn create(options: &SimulateOptions) -> Result<SimulatedSession> {
        let kind = SimObjectKind::from_name(&options.object).with_context(|| {
            let known: Vec<&str> = SimObjectKind::ALL.iter().map(|k| k.name()).collect();
            format!("unknown object '{}' (known: {})", options.object, known.join(", "))
        })?;
        anyhow::ensure!(
            options.duration_s > 0.0 && options.duration_s <= 600.0,
            "--duration must be in (0, 600] s"
        );
        let mut config = FastSequenceConfig::new(kind, options.duration_s, options.seed);
        config.motion.max_speed_mps = options.max_speed_mps;
        config.motion.max_angular_speed_dps = options.max_angular_speed_dps;
        let mut sequence = FastSequence::new(config)?;
        let marker =
            options.marker.as_deref().map(|m| print_marker(&mut sequence, m, options)).transpose()?;
        let (aruco_config, marker_warning) = match marker {
            Some((config, warning)) => (Some(config), warning),
            None => (None, None),
        };
        let network_config =
            SlowNetworkConfig { seed: options.seed ^ 0x6e65_7477, ..SlowNetworkConfig::default() };
        let rig_config =
            rig_config(kind, options, &network_config, aruco_config.as_ref().map(|(_, t)| t.as_str()));
        let metadata = SessionMetadata {
            software_version: env!("CARGO_PKG_VERSION").into(),
            rig: "sim-rgbd".into(),
            rig_config,
            object: kind.name().into(),
            object_config: String::new(),
            trial: "0".into(),
            seed: options.seed,
            started_at: humantime::format_rfc3339_seconds(SystemTime::now()).to_string(),
        };
        let recorder_options = RecorderOptions { overwrite: options.overwrite, ..RecorderOptions::default() };
        let recorder = Recorder::create_with_options(&options.out, metadata.to_map(), recorder_options)?;
        let channels = RgbdChannels::register(&recorder.logger(), sequence.intrinsics())?;
        let network = SlowNetwork::new(network_config);
        Ok(SimulatedSession {
            out: options.out.clone(),
            kind,
            sequence,
            network,
            recorder,
            channels,
            aruco_config,
            marker_warning,
        })
    }

    /// Frames to write.
    pub fn len(&self) -> usize {
        self.sequence.len()
    }

    /// True when there is no frame to write.
    pub fn is_empty(&self) -> bool {
        self.sequence.len() == 0
    }

    /// Why the printed marker will rarely be detected, if it will not.
    pub fn marker_warning(&self) -> Option<&str> {
        self.marker_warning.as_deref()
    }

    /// Writes every frame, calling `on_frame` after each, then the marker's
    /// configuration, if any.
    pub fn write(mut self, on_frame: &mut dyn FnMut()) -> Result<SimulatedSummary> {
        let logger = self.recorder.logger();
        for k in 0..self.sequence.len() {
            let (frame, inside, truth) = self.sequence.frame(k);
            let true_mask = mask(frame.depth.width, frame.depth.height, &inside)?;
            let jpeg = slidetrack_calibration::codec::encode_jpeg(&frame.color, 95)?;
            self.channels.log_frame(&logger, &frame, &jpeg, Some(&truth), Some(&true_mask))?;
            let arrivals = self.network.on_frame(
                frame.t,
                Some(FrameTruth { camera_from_object: &truth.camera_from_object, mask: &true_mask }),
            )?;
            for m in &arrivals.masks {
                self.channels.log_vision_mask(&logger, m.frame_t, m.arrival_t, &m.value)?;
            }
            for p in &arrivals.poses {
                self.channels.log_vision_pose(&logger, p.frame_t, p.arrival_t, &p.value)?;
            }
            on_frame();
        }
        self.recorder.finish()?;
        let aruco_config = match self.aruco_config {
            Some((path, toml)) => {
                std::fs::write(&path, toml).with_context(|| format!("cannot write {}", path.display()))?;
                Some(path)
            }
            None => None,
        };
        let frames = self.sequence.len();
        Ok(SimulatedSummary {
            out: self.out,
            frames,
            object: self.kind.name(),
            network_results: frames / 6,
            outliers: self.network.outliers_delivered(),
            aruco_config,
        })
    }
}

/// The session's `rig_config`: the sequence, the network and the marker.
fn rig_config(
    kind: SimObjectKind,
    options: &SimulateOptions,
    network: &SlowNetworkConfig,
    aruco_toml: Option<&str>,
) -> String {
    let rig_config = format!(
        "[rgbd]\nobject = \"{}\"\nduration_s = {}\nfps = 30.0\nmax_speed_mps = {}\nmax_angular_speed_dps = {}\n\n[network]\nlatency_s = {}\nposition_noise_m = {}\nrotation_noise_deg = {}\noutlier_probability = {}\n",
        kind.name(),
        options.duration_s,
        options.max_speed_mps,
        options.max_angular_speed_dps,
        network.latency_s,
        network.position_noise_m,
        network.rotation_noise_deg,
        network.outlier_probability,
    );
    match aruco_toml {
        Some(toml) => format!("{rig_config}\n# The marker on the object (--aruco-config):\n[aruco]\n{toml}"),
        None => rig_config,
    }
}

/// Prints the marker `spec` (DICTIONARY:ID) on the object; returns where its
/// `--aruco-config` goes and its text, and a warning when the marker's face
/// is seen too obliquely in the first frame.
fn print_marker(
    sequence: &mut FastSequence,
    spec: &str,
    options: &SimulateOptions,
) -> Result<((PathBuf, String), Option<String>)> {
    let (dictionary, id) = spec
        .split_once(':')
        .and_then(|(d, i)| Some((d, i.parse::<u32>().ok()?)))
        .with_context(|| format!("--marker {spec:?}: expected DICTIONARY:ID, for example DICT_4X4_50:0"))?;
    anyhow::ensure!(
        options.marker_size_m.is_finite() && options.marker_size_m > 0.0,
        "--marker-size must be a positive size in metres"
    );
    let pattern = slidetrack_calibration::marker_pattern(dictionary, id)?;
    let decal = sequence.print_marker(pattern, options.marker_size_m).cloned().with_context(|| {
        format!("--marker-size {} m: no face of the object is wide enough", options.marker_size_m)
    })?;
    let camera_from_marker = sequence.truth(0).camera_from_object * decal.object_from_marker;
    let towards_camera = -camera_from_marker.translation.vector.normalize();
    let facing = (camera_from_marker.rotation * nalgebra::Vector3::z()).dot(&towards_camera);
    let warning = (facing < 0.3).then(|| {
        format!(
            "warning: the marker's face is seen at {:.0} degrees in the first frame and will rarely be detected; \
             try another --seed or a smaller --marker-size",
            facing.clamp(-1.0, 1.0).acos().to_degrees()
        )
    });
    let marker_from_object = PoseConfig::of(&decal.object_from_marker.inverse());
    let [x, y, z] = marker_from_object.translation_m;
    let [qx, qy, qz, qw] = marker_from_object.rotation_xyzw;
    let toml = format!(
        "dictionary = \"{dictionary}\"\nmarker_id = {id}\nmarker_size_m = {}\nmask_depth_tolerance_m = 0.03\n# Results at their frame's time: replays are repeatable (\"measured\" adds the detection time).\ndelay = \"none\"\n\n[marker_from_object]\ntranslation_m = [{x}, {y}, {z}]\nrotation_xyzw = [{qx}, {qy}, {qz}, {qw}]\n",
        options.marker_size_m
    );
    Ok(((options.out.with_extension("aruco.toml"), toml), warning))
}
