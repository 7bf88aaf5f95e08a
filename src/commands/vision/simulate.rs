//! `slidetrack vision simulate`: a simulated RGB-D session of a fast object.

use std::path::PathBuf;
use std::time::SystemTime;

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use slidetrack_session::{Recorder, RecorderOptions, SessionMetadata};
use slidetrack_sim::rgbd::{FastSequence, FastSequenceConfig, SimObjectKind};
use slidetrack_vision::cloud::mask;
use slidetrack_vision::record::RgbdChannels;
use slidetrack_vision::sources::{FrameTruth, MeasurementSource, PoseConfig, SlowNetwork, SlowNetworkConfig};

use crate::cli::VisionSimulateArgs as SimulateArgs;

pub fn run(args: &SimulateArgs, quiet: bool) -> Result<()> {
    let kind = SimObjectKind::from_name(&args.object).with_context(|| {
        let known: Vec<&str> = SimObjectKind::ALL.iter().map(|k| k.name()).collect();
        format!("unknown object '{}' (known: {})", args.object, known.join(", "))
    })?;
    anyhow::ensure!(args.duration > 0.0 && args.duration <= 600.0, "--duration must be in (0, 600] s");
    let mut config = FastSequenceConfig::new(kind, args.duration, args.seed);
    config.motion.max_speed_mps = args.max_speed;
    config.motion.max_angular_speed_dps = args.max_angular_speed;
    let mut sequence = FastSequence::new(config)?;
    let aruco_config = args.marker.as_deref().map(|m| print_marker(&mut sequence, m, args)).transpose()?;
    let network_config = SlowNetworkConfig { seed: args.seed ^ 0x6e65_7477, ..SlowNetworkConfig::default() };
    let rig_config = format!(
        "[rgbd]\nobject = \"{}\"\nduration_s = {}\nfps = 30.0\nmax_speed_mps = {}\nmax_angular_speed_dps = {}\n\n[network]\nlatency_s = {}\nposition_noise_m = {}\nrotation_noise_deg = {}\noutlier_probability = {}\n",
        kind.name(),
        args.duration,
        args.max_speed,
        args.max_angular_speed,
        network_config.latency_s,
        network_config.position_noise_m,
        network_config.rotation_noise_deg,
        network_config.outlier_probability,
    );
    let rig_config = match &aruco_config {
        Some((_, toml)) => {
            format!("{rig_config}\n# The marker on the object (--aruco-config):\n[aruco]\n{toml}")
        }
        None => rig_config,
    };
    let metadata = SessionMetadata {
        software_version: env!("CARGO_PKG_VERSION").into(),
        rig: "sim-rgbd".into(),
        rig_config,
        object: kind.name().into(),
        object_config: String::new(),
        trial: "0".into(),
        seed: args.seed,
        started_at: humantime::format_rfc3339_seconds(SystemTime::now()).to_string(),
    };
    let options = RecorderOptions { overwrite: args.overwrite, ..RecorderOptions::default() };
    let recorder = Recorder::create_with_options(&args.out, metadata.to_map(), options)?;
    let logger = recorder.logger();
    let channels = RgbdChannels::register(&logger, sequence.intrinsics())?;
    let mut network = SlowNetwork::new(network_config);
    let bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new(sequence.len() as u64) };
    bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} frames {eta}")?);
    for k in 0..sequence.len() {
        let (frame, inside, truth) = sequence.frame(k);
        let true_mask = mask(frame.depth.width, frame.depth.height, &inside)?;
        let jpeg = slidetrack_calibration::codec::encode_jpeg(&frame.color, 95)?;
        channels.log_frame(&logger, &frame, &jpeg, Some(&truth), Some(&true_mask))?;
        let arrivals = network.on_frame(
            frame.t,
            Some(FrameTruth { camera_from_object: &truth.camera_from_object, mask: &true_mask }),
        )?;
        for m in &arrivals.masks {
            channels.log_vision_mask(&logger, m.frame_t, m.arrival_t, &m.value)?;
        }
        for p in &arrivals.poses {
            channels.log_vision_pose(&logger, p.frame_t, p.arrival_t, &p.value)?;
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    recorder.finish()?;
    println!(
        "{}: {} frames of {} at 30 Hz, network results {} ({} outliers)",
        args.out.display(),
        sequence.len(),
        kind.name(),
        sequence.len() / 6,
        network.outliers_delivered()
    );
    if let Some((path, toml)) = aruco_config {
        std::fs::write(&path, toml).with_context(|| format!("cannot write {}", path.display()))?;
        println!("marker configuration for --measurements aruco: {}", path.display());
    }
    Ok(())
}

/// Prints the marker `spec` (DICTIONARY:ID) on the object; returns where its
/// `--aruco-config` goes and its text.
fn print_marker(sequence: &mut FastSequence, spec: &str, args: &SimulateArgs) -> Result<(PathBuf, String)> {
    let (dictionary, id) = spec
        .split_once(':')
        .and_then(|(d, i)| Some((d, i.parse::<u32>().ok()?)))
        .with_context(|| format!("--marker {spec:?}: expected DICTIONARY:ID, for example DICT_4X4_50:0"))?;
    anyhow::ensure!(
        args.marker_size.is_finite() && args.marker_size > 0.0,
        "--marker-size must be a positive size in metres"
    );
    let pattern = slidetrack_calibration::marker_pattern(dictionary, id)?;
    let decal = sequence.print_marker(pattern, args.marker_size).cloned().with_context(|| {
        format!("--marker-size {} m: no face of the object is wide enough", args.marker_size)
    })?;
    let camera_from_marker = sequence.truth(0).camera_from_object * decal.object_from_marker;
    let towards_camera = -camera_from_marker.translation.vector.normalize();
    let facing = (camera_from_marker.rotation * nalgebra::Vector3::z()).dot(&towards_camera);
    if facing < 0.3 {
        eprintln!(
            "warning: the marker's face is seen at {:.0} degrees in the first frame and will rarely be detected; \
             try another --seed or a smaller --marker-size",
            facing.clamp(-1.0, 1.0).acos().to_degrees()
        );
    }
    let marker_from_object = PoseConfig::of(&decal.object_from_marker.inverse());
    let [x, y, z] = marker_from_object.translation_m;
    let [qx, qy, qz, qw] = marker_from_object.rotation_xyzw;
    let toml = format!(
        "dictionary = \"{dictionary}\"\nmarker_id = {id}\nmarker_size_m = {}\nmask_depth_tolerance_m = 0.03\n# Results at their frame's time: replays are repeatable (\"measured\" adds the detection time).\ndelay = \"none\"\n\n[marker_from_object]\ntranslation_m = [{x}, {y}, {z}]\nrotation_xyzw = [{qx}, {qy}, {qz}, {qw}]\n",
        args.marker_size
    );
    Ok((args.out.with_extension("aruco.toml"), toml))
}
