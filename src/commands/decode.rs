//! `slidetrack decode`: captured tactile traffic (a can-utils `candump -l`
//! log or candump's console output, or raw serial bytes) turned into a session with the `/tactile/raw`
//! and `/tactile/decoder` channels of a live recording.

use std::collections::BTreeMap;
use std::fs::File;
use std::path::Path;
use std::time::SystemTime;

use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use slidetrack_core::{DecoderCounters, TactileInfo, TactileLayout, TactileSample, TimeNs};
use slidetrack_experiment::devices::{
    CanLogDecoder, HwRigConfig, SerialCaptureDecoder, TactileDevice, tactile_info,
};
use slidetrack_experiment::rig_config::RigConfig;
use slidetrack_session::{
    ChannelHandle, Recorder, RecorderOptions, SessionMetadata, TactileDecoder, TactileRaw, TaxelLayout,
};

use crate::cli::DecodeArgs;

/// Name of the metadata record that says where a decoded session came from.
const SOURCE_METADATA: &str = "slidetrack.source";

pub fn run(args: &DecodeArgs, quiet: bool) -> Result<()> {
    if args.out.exists() && !args.overwrite {
        bail!("{} already exists; pass --overwrite to replace it", args.out.display());
    }
    let configured = configured_tactile(args.config.as_deref())?;
    let (input, can_log) = match (&args.can_log, &args.serial_capture) {
        (Some(p), None) => (p, true),
        (None, Some(p)) => (p, false),
        _ => bail!("give exactly one of --can-log and --serial-capture"),
    };
    let file = File::open(input).with_context(|| format!("cannot open {}", input.display()))?;
    let size = file.metadata().map(|m| m.len()).unwrap_or(0);
    let bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new(size) };
    bar.set_style(
        ProgressStyle::with_template("decoding [{bar:30}] {bytes}/{total_bytes} {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let reader = bar.wrap_read(file);
    let name = input.display().to_string();
    let summary = if can_log {
        decode_can_log(args, configured.as_ref(), reader, &name)?
    } else {
        decode_serial_capture(args, configured.as_ref(), reader, &name)?
    };
    bar.finish_and_clear();
    println!("{summary}");
    Ok(())
}

/// Decodes a can-utils log into a session; returns the summary line.
fn decode_can_log(
    args: &DecodeArgs,
    configured: Option<&TactileDevice>,
    reader: impl std::io::Read,
    name: &str,
) -> Result<String> {
    let mut cfg = configured.and_then(TactileDevice::as_can).cloned().unwrap_or_default();
    if let Some(t) = args.taxels {
        cfg.taxels = t;
    }
    check(TactileDevice::Can(cfg.clone()))?;
    let mut decoder = CanLogDecoder::new(reader, &cfg, args.interface.clone())
        .context("the decoder configuration")?
        .with_deltas(args.time_deltas);
    let info = tactile_info(name, cfg.rate_hz, &cfg.sensors, cfg.fingers.as_ref());
    let mut out = Output::create(args, &info, &TactileDevice::Can(cfg.clone()))?;
    while let Some(sample) = decoder.next() {
        out.scan(&sample, &decoder.counters())?;
    }
    if let Some((line, why)) = decoder.first_error() {
        tracing::warn!("{name} line {line}: {why} ({} lines skipped)", decoder.bad_lines());
    }
    let extra = format!("{} lines, {} unreadable", decoder.lines(), decoder.bad_lines());
    let timing = if decoder.untimed_frames() > 0 {
        "log order: frames without a time spaced as if at the configured rate_hz"
    } else if args.time_deltas {
        "capture timestamps (gaps since the previous frame)"
    } else {
        "capture timestamps"
    };
    out.finish("can-log", name, timing, &decoder.counters(), &extra)
}

/// Decodes raw serial bytes into a session; returns the summary line.
fn decode_serial_capture(
    args: &DecodeArgs,
    configured: Option<&TactileDevice>,
    reader: impl std::io::Read,
    name: &str,
) -> Result<String> {
    let mut cfg = configured.and_then(TactileDevice::as_serial).cloned().unwrap_or_default();
    let rate_hz = args.rate.unwrap_or(cfg.rate_hz);
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        bail!("--rate must be a positive scan rate in Hz, got {rate_hz}");
    }
    cfg.rate_hz = rate_hz;
    check(TactileDevice::Serial(cfg.clone()))?;
    let mut decoder = SerialCaptureDecoder::new(reader, &cfg, rate_hz);
    let info = tactile_info(name, rate_hz, &cfg.sensors, cfg.fingers.as_ref());
    let mut out = Output::create(args, &info, &TactileDevice::Serial(cfg.clone()))?;
    while let Some(sample) = decoder.next() {
        out.scan(&sample, &decoder.counters())?;
    }
    if let Some(e) = decoder.error() {
        bail!("reading {name} failed after {} bytes: {e}", decoder.bytes());
    }
    let extra = format!(
        "{} bytes, {} trailing bytes in no complete frame",
        decoder.bytes(),
        decoder.trailing_bytes()
    );
    let timing = format!("scan counter at {rate_hz} Hz");
    out.finish("serial-capture", name, &timing, &decoder.counters(), &extra)
}

/// The `[hw.tactile]` table of the rig configuration at `path`. Only that
/// table is checked: the protocol's settings do not matter for decoding.
fn configured_tactile(path: Option<&Path>) -> Result<Option<TactileDevice>> {
    let Some(path) = path else { return Ok(None) };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read rig config {}", path.display()))?;
    let rig: RigConfig =
        slidetrack_core::parse_toml(&text, &path.display().to_string()).context("invalid rig config")?;
    Ok(rig.hw.map(|hw| hw.tactile))
}

fn check(tactile: TactileDevice) -> Result<()> {
    HwRigConfig { tactile, ..HwRigConfig::default() }.validate().context("the decoder configuration")?;
    Ok(())
}

#[derive(Serialize)]
struct DecodedRig<'a> {
    hw: DecodedHw<'a>,
}

#[derive(Serialize)]
struct DecodedHw<'a> {
    name: &'a str,
    tactile: &'a TactileDevice,
}

/// The session being written.
struct Output<'a> {
    args: &'a DecodeArgs,
    recorder: Recorder,
    raw: ChannelHandle<TactileRaw>,
    decoder: ChannelHandle<TactileDecoder>,
    layout: TactileLayout,
    scans: u64,
    first: Option<TimeNs>,
    last: TimeNs,
    written: Option<(TimeNs, DecoderCounters)>,
}

impl<'a> Output<'a> {
    fn create(args: &'a DecodeArgs, info: &TactileInfo, tactile: &TactileDevice) -> Result<Output<'a>> {
        let trial = args
            .can_log
            .as_deref()
            .or(args.serial_capture.as_deref())
            .and_then(Path::file_name)
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let rig = DecodedRig { hw: DecodedHw { name: "decoded", tactile } };
        let metadata = SessionMetadata {
            software_version: env!("CARGO_PKG_VERSION").into(),
            rig: "decoded".into(),
            rig_config: toml::to_string(&rig).context("cannot serialise the decoder configuration")?,
            object: "unknown".into(),
            object_config: String::new(),
            trial,
            seed: 0,
            started_at: humantime::format_rfc3339_seconds(SystemTime::now()).to_string(),
        };
        let options = RecorderOptions { overwrite: args.overwrite, ..RecorderOptions::default() };
        let recorder = Recorder::create_with_options(&args.out, metadata.to_map(), options)?;
        let raw = recorder.register::<TactileRaw>(TaxelLayout::new(info).channel_metadata())?;
        let decoder = recorder.register::<TactileDecoder>(BTreeMap::new())?;
        let layout = info.layout.clone();
        Ok(Output {
            args,
            recorder,
            raw,
            decoder,
            layout,
            scans: 0,
            first: None,
            last: TimeNs::ZERO,
            written: None,
        })
    }

    fn scan(&mut self, s: &TactileSample, counters: &DecoderCounters) -> Result<()> {
        let seq = (s.sequence & u64::from(u32::MAX)) as u32;
        self.recorder.log_json(&self.raw, s.t, s.t, seq, &TactileRaw::new(s, &self.layout))?;
        self.scans += 1;
        self.first.get_or_insert(s.t);
        self.last = s.t;
        let due =
            self.written.is_none_or(|(t0, c0)| counters.errors_differ(&c0) || s.t.secs_since(t0) >= 1.0);
        if due {
            self.counters(s.t, counters)?;
        }
        Ok(())
    }

    fn counters(&mut self, t: TimeNs, counters: &DecoderCounters) -> Result<()> {
        self.recorder.log_json(&self.decoder, t, t, 0, &TactileDecoder::from(counters))?;
        self.written = Some((t, *counters));
        Ok(())
    }

    /// Writes the final counters, the source record and the outcome; returns the summary line.
    fn finish(
        mut self,
        kind: &str,
        file: &str,
        timing: &str,
        counters: &DecoderCounters,
        extra: &str,
    ) -> Result<String> {
        if self.written.is_none_or(|(_, c)| c != *counters) {
            self.counters(self.last, counters)?;
        }
        let source = BTreeMap::from([
            ("kind".to_string(), kind.to_string()),
            ("file".to_string(), file.to_string()),
            ("timing".to_string(), timing.to_string()),
            ("decoder".to_string(), counters.to_string()),
        ]);
        self.recorder.metadata(SOURCE_METADATA, source)?;
        let out = self.args.out.display().to_string();
        let scans = self.scans;
        let span_s = self.last.secs_since(self.first.unwrap_or(TimeNs::ZERO));
        let reason = (scans == 0).then(|| "no scan decoded".to_string());
        self.recorder
            .finish_with_outcome(scans > 0, reason)
            .with_context(|| format!("cannot finish {out}"))?;
        if scans == 0 {
            bail!(
                "{file}: no scan decoded ({counters}; {extra}); check the board's ids, taxel count and finger map \
                 (--config); {out} was written empty"
            );
        }
        Ok(format!("{out}: {scans} scans over {span_s:.2} s from {file} ({extra}); decoder: {counters}"))
    }
}
