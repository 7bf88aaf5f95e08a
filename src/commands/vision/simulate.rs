//! `slidetrack vision simulate`: a simulated RGB-D session of a fast object.

use std::time::SystemTime;

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use slidetrack_session::{Recorder, RecorderOptions, SessionMetadata};
use slidetrack_sim::rgbd::{FastSequence, FastSequenceConfig, SimObjectKind};
use slidetrack_vision::cloud::mask;
use slidetrack_vision::record::RgbdChannels;
use slidetrack_vision::sources::{FrameTruth, MeasurementSource, SlowNetwork, SlowNetworkConfig};

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
    let sequence = FastSequence::new(config)?;
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
    Ok(())
}
