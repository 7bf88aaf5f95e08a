//! `slidetrack emulate`: serves an emulated device and prints where to
//! find it (first line of stdout), until Ctrl-C.

use std::io::Write;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use slidetrack_experiment::devices::{RobotiqEmulator, RobotiqEmulatorOptions, RobotiqModel};
use slidetrack_experiment::emulate::{EmulatedTactile, ObjectConfig, start_tactile_emulator};
use slidetrack_experiment::rig_config::RigConfig;

use super::stop_flag;
use crate::cli::{EmulateArgs, EmulateDevice, EmulateRobotiqArgs, EmulateTactileArgs};

pub fn run(args: &EmulateArgs) -> Result<()> {
    match &args.device {
        EmulateDevice::Robotiq(a) => robotiq(a),
        EmulateDevice::Tactile(a) => tactile(EmulatedTactile::Configured, a),
        EmulateDevice::Serial(a) => tactile(EmulatedTactile::Serial, a),
        EmulateDevice::Slcan(a) => tactile(EmulatedTactile::Slcan, a),
        EmulateDevice::XelaServer(a) => tactile(EmulatedTactile::XelaServer, a),
    }
}

fn robotiq(a: &EmulateRobotiqArgs) -> Result<()> {
    let Some(model) = RobotiqModel::from_name(&a.model) else {
        bail!("--model {}: not a Robotiq model", a.model)
    };
    let stroke_mm = model.spec().stroke_m * 1000.0;
    if let Some(w) = a.object_width_mm
        && !(w.is_finite() && (0.0..stroke_mm).contains(&w))
    {
        bail!("--object-width-mm {w}: must be within the {} stroke, 0 to {stroke_mm} mm", a.model);
    }
    let non_negative = |t: f64| t.is_finite() && t >= 0.0;
    if !non_negative(a.activation_s) || !non_negative(a.fault_after_s) {
        bail!("--activation-s and --fault-after-s must be >= 0 s");
    }
    if a.device_id == 0 || a.device_id > 247 {
        bail!("--device-id {}: Modbus devices have ids 1 to 247", a.device_id);
    }
    let options = RobotiqEmulatorOptions {
        device_id: a.device_id,
        activation: Duration::from_secs_f64(a.activation_s),
        exceptions: a.exceptions,
        pace_baud: (!a.unpaced).then_some(115_200),
        fault: a.fault.map(|code| (Duration::from_secs_f64(a.fault_after_s), code)),
        ..RobotiqEmulatorOptions::default()
    };
    let emulator = RobotiqEmulator::kinematic(model, a.object_width_mm.map(|w| w / 1000.0), options)?;
    let object = a.object_width_mm.map_or("no object".to_string(), |w| format!("an object {w} mm wide"));
    serve(
        emulator.path(),
        &format!(
            "emulated Robotiq {} (device id {}, {object}): use port = \"{}\" (115200 baud 8N1); Ctrl-C to stop",
            a.model,
            a.device_id,
            emulator.path()
        ),
    )?;
    let r = emulator.record();
    eprintln!(
        "answered {} requests, ignored {}, passed {} requests to the fingers",
        r.answered, r.ignored, r.server.commands
    );
    Ok(())
}

fn tactile(kind: EmulatedTactile, a: &EmulateTactileArgs) -> Result<()> {
    let rig = RigConfig::load(Some(&a.config))?;
    let object = ObjectConfig::load(&a.object)?;
    if !(a.duration.is_finite() && a.duration > 0.0) {
        bail!("--duration {}: must be > 0 s", a.duration);
    }
    let emulator = start_tactile_emulator(kind, &rig, &object, a.seed, a.duration)
        .with_context(|| format!("cannot emulate {kind:?} from {}", a.config.display()))?;
    serve(
        &emulator.endpoint,
        &format!(
            "emulated {kind:?} tactile device fed by simulated trials of {}: {}; Ctrl-C to stop",
            a.object, emulator.endpoint
        ),
    )?;
    eprintln!("{} simulated trials", emulator.trials());
    Ok(())
}

/// Prints `endpoint` alone on stdout (for scripts), `hint` on stderr, and
/// waits for Ctrl-C.
fn serve(endpoint: &str, hint: &str) -> Result<()> {
    let stop = stop_flag("closing the emulated devices");
    let mut out = std::io::stdout().lock();
    writeln!(out, "{endpoint}").and_then(|()| out.flush()).context("cannot write to stdout")?;
    drop(out);
    eprintln!("{hint}");
    while !stop.load(std::sync::atomic::Ordering::SeqCst) {
        std::thread::sleep(Duration::from_millis(50));
    }
    Ok(())
}
