//! Emulated tactile devices fed by simulated trials (`slidetrack emulate
//! serial|slcan|xela-server`): the controlled-sliding protocol runs on the
//! simulated rig in real time, in a thread of its own, trial after trial,
//! and its tactile scans go out through the device emulators, so that a
//! program reading the emulated device sees real grasps.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

use anyhow::{Context, Result, bail};
use slidetrack_control::{ObserverError, ProtocolEvent, TrialObserver, run_trial};
use slidetrack_core::{
    ActuatorCommand, DeviceError, ErrorKind, Frame, SimTruth, TactileInfo, TactileSample, TactileSource,
    TimeNs,
};
pub use slidetrack_sim::ObjectConfig;

use crate::rig::{TrialSpec, build_sim_rig, protocol_for};
use crate::rig_config::RigConfig;

/// Which tactile device to emulate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EmulatedTactile {
    /// Whichever device the `[hw.tactile]` table names.
    Configured,
    /// uSkin-style modules on a serial port (`kind = "serial"`).
    Serial,
    /// A CAN board behind an SLCAN adapter (`kind = "can"`).
    Slcan,
    /// XELA's `xela_server` (`kind = "xela_ws"`).
    XelaServer,
}

impl EmulatedTactile {
    /// The `[hw.tactile]` kind this emulator serves and, when the table
    /// must have another, what to write there; `None`: any kind.
    fn needs(self) -> Option<(&'static str, &'static str)> {
        match self {
            EmulatedTactile::Configured => None,
            EmulatedTactile::Serial => Some(("serial", "serial")),
            EmulatedTactile::Slcan => Some(("can", "can\" with an slcan = { ... } adapter")),
            EmulatedTactile::XelaServer => Some(("xela_ws", "xela_ws")),
        }
    }
}

/// A running emulator and the simulated trials feeding it; dropping it
/// stops both.
pub struct TactileEmulator {
    /// Where to find the device: a pseudo-terminal's path or a URL.
    pub endpoint: String,
    _device: Box<dyn Send>,
    trials: SimulatedTrials,
}

impl TactileEmulator {
    /// The number of simulated trials started so far.
    pub fn trials(&self) -> u32 {
        self.trials.started.load(Ordering::SeqCst) as u32
    }
}

/// Starts the emulator of `kind` configured by `rig`'s `[hw.tactile]`
/// table, fed by trials of `object` from `seed` on, whose sliding cycles
/// last `duration_s`.
pub fn start_tactile_emulator(
    kind: EmulatedTactile,
    rig: &RigConfig,
    object: &ObjectConfig,
    seed: u64,
    duration_s: f64,
) -> Result<TactileEmulator> {
    let hw = rig.hw.clone().unwrap_or_default();
    let (trials, source) = SimulatedTrials::start(rig, object, seed, duration_s)?;
    if let Some((kind_name, table)) = kind.needs()
        && hw.tactile.kind() != kind_name
    {
        bail!("emulating {kind:?} needs a rig configuration whose [hw.tactile] has kind = \"{table}\"");
    }
    let served = hw.tactile.emulate(Box::new(source))?;
    let (endpoint, device) = (served.endpoint, served.emulator);
    Ok(TactileEmulator { endpoint, _device: device, trials })
}

/// Simulated trials in a thread (`simulated-trials`), one after another
/// until stopped, their scans sent on a channel.
struct SimulatedTrials {
    stop: Arc<AtomicBool>,
    started: Arc<AtomicU64>,
    thread: Option<JoinHandle<()>>,
}

impl SimulatedTrials {
    fn start(
        rig: &RigConfig,
        object: &ObjectConfig,
        seed: u64,
        duration_s: f64,
    ) -> Result<(Self, ChannelTactile)> {
        let info = build_sim_rig(&emulated_trial(rig, object, seed, 0, duration_s))?.tactile_info;
        let (tx, rx) = sync_channel(64);
        let stop = Arc::new(AtomicBool::new(false));
        let started = Arc::new(AtomicU64::new(0));
        let (rig, object) = (rig.clone(), object.clone());
        let (stop_flag, count) = (Arc::clone(&stop), Arc::clone(&started));
        let thread = std::thread::Builder::new()
            .name("simulated-trials".into())
            .spawn(move || {
                for trial in 0.. {
                    if stop_flag.load(Ordering::SeqCst) {
                        return;
                    }
                    count.fetch_add(1, Ordering::SeqCst);
                    let spec = emulated_trial(&rig, &object, seed, trial, duration_s);
                    if let Err(e) = run_one(&spec, &tx, &stop_flag) {
                        tracing::warn!("simulated trial {trial}: {e:#}");
                        return;
                    }
                }
            })
            .context("cannot start the simulated trials")?;
        Ok((
            SimulatedTrials { stop, started, thread: Some(thread) },
            ChannelTactile { rx, info, sequence: 0 },
        ))
    }
}

impl Drop for SimulatedTrials {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take()
            && t.join().is_err()
        {
            tracing::warn!("the simulated trials' thread panicked");
        }
    }
}

/// Trial `trial` of the simulated rig behind an emulator: on the wall
/// clock, without camera, recording nothing.
fn emulated_trial<'a>(
    rig: &'a RigConfig,
    object: &'a ObjectConfig,
    seed: u64,
    trial: u32,
    duration_s: f64,
) -> TrialSpec<'a> {
    TrialSpec {
        rig,
        object,
        seed,
        trial,
        duration_s,
        camera: false,
        realtime: true,
        overwrite: false,
        path: PathBuf::new(),
        live: None,
    }
}

/// One trial of the protocol on the simulated rig, its scans teed to `tx`.
fn run_one(spec: &TrialSpec, tx: &SyncSender<TactileSample>, stop: &AtomicBool) -> Result<()> {
    let mut setup = build_sim_rig(spec)?;
    let fingers = setup.tactile_info.finger_map().context("the simulated taxel layout")?;
    let mut protocol = protocol_for(spec.rig, spec.object, spec.duration_s, fingers, &setup.rig.hand.spec());
    let mut observer = Teed { tx: tx.clone() };
    run_trial(&mut setup.rig, &mut protocol, &mut observer, stop);
    Ok(())
}

/// Receives a trial's products and passes its scans on (dropped when the
/// emulator does not keep up: the trial never waits for it).
struct Teed {
    tx: SyncSender<TactileSample>,
}

impl TrialObserver for Teed {
    fn on_tactile(&mut self, sample: &TactileSample) -> Result<(), ObserverError> {
        let _ = self.tx.try_send(sample.clone());
        Ok(())
    }
    fn on_truth(&mut self, _: &SimTruth) -> Result<(), ObserverError> {
        Ok(())
    }
    fn on_tare(&mut self, _: TimeNs, _: &slidetrack_control::Tare) -> Result<(), ObserverError> {
        Ok(())
    }
    fn on_zeroed(&mut self, _: TimeNs, _: &slidetrack_control::Baseline) -> Result<(), ObserverError> {
        Ok(())
    }
    fn on_control(&mut self, _: TimeNs, _: &slidetrack_control::ControlRecord) -> Result<(), ObserverError> {
        Ok(())
    }
    fn on_command(&mut self, _: TimeNs, _: &ActuatorCommand, _: bool) -> Result<(), ObserverError> {
        Ok(())
    }
    fn on_frame(&mut self, _: Frame) -> Result<Option<f64>, ObserverError> {
        Ok(None)
    }
    fn on_event(&mut self, _: TimeNs, _: &ProtocolEvent) -> Result<(), ObserverError> {
        Ok(())
    }
}

/// The trials' scans as one source: sequence numbers continue across trials.
struct ChannelTactile {
    rx: Receiver<TactileSample>,
    info: TactileInfo,
    sequence: u64,
}

impl TactileSource for ChannelTactile {
    fn read(&mut self) -> Result<TactileSample, DeviceError> {
        let mut sample = self.rx.recv().map_err(|_| {
            DeviceError::new(ErrorKind::Disconnected, "simulated trials", "the simulated trials ended")
        })?;
        sample.sequence = self.sequence;
        self.sequence += 1;
        Ok(sample)
    }

    fn info(&self) -> TactileInfo {
        self.info.clone()
    }
}
