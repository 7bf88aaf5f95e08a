//! `slidetrack emulate`: emulated devices served where the real ones would
//! be (a pseudo-terminal, a local WebSocket server), for trying the
//! drivers and other programs without hardware.

use std::path::PathBuf;

use clap::{Args, Subcommand};

/// `slidetrack emulate`.
#[derive(Debug, Args)]
pub struct EmulateArgs {
    /// The device to emulate.
    #[command(subcommand)]
    pub device: EmulateDevice,
}

/// The emulated devices.
#[derive(Debug, Subcommand)]
pub enum EmulateDevice {
    /// A Robotiq 2F-85/2F-140/Hand-E gripper answering Modbus RTU on a
    /// pseudo-terminal (prints its path); runs until Ctrl-C.
    Robotiq(EmulateRobotiqArgs),
    /// Whichever tactile device `[hw.tactile]` names, fed by simulated
    /// trials, where a program would find it (prints its path or URL).
    Tactile(EmulateTactileArgs),
    /// The serial tactile modules of `[hw.tactile] kind = "serial"`, fed by
    /// simulated trials, on a pseudo-terminal (prints its path).
    Serial(EmulateTactileArgs),
    /// The CAN tactile board of `[hw.tactile] kind = "can"` behind an
    /// emulated SLCAN adapter, fed by simulated trials (prints its path).
    Slcan(EmulateTactileArgs),
    /// XELA's `xela_server` for `[hw.tactile] kind = "xela_ws"`, fed by
    /// simulated trials, on localhost (prints its URL).
    #[command(name = "xela-server")]
    XelaServer(EmulateTactileArgs),
}

/// `slidetrack emulate robotiq`.
#[derive(Debug, Args)]
pub struct EmulateRobotiqArgs {
    /// The model: 2f85, 2f140 or hand-e (stroke, speeds, forces).
    #[arg(long, default_value = "2f85", value_parser = ["2f85", "2f140", "hand-e"])]
    pub model: String,
    /// Width of an object between the fingers (mm): closing stops there
    /// with gOBJ = 2. Without it the fingers close fully.
    #[arg(long, value_name = "W")]
    pub object_width_mm: Option<f64>,
    /// Modbus device id.
    #[arg(long, default_value_t = 9)]
    pub device_id: u8,
    /// Time from rACT = 1 to gSTA = 3 (s).
    #[arg(long, default_value_t = 1.5)]
    pub activation_s: f64,
    /// Answer bad functions and addresses with Modbus exception responses
    /// (the Robotiq manual says the gripper does not; default: silence).
    #[arg(long)]
    pub exceptions: bool,
    /// Answer at once instead of at the pace of a 115200-baud line.
    #[arg(long)]
    pub unpaced: bool,
    /// Report this gFLT fault code (1-15) `--fault-after-s` after the activation.
    #[arg(long, value_name = "CODE", value_parser = clap::value_parser!(u8).range(1..=15))]
    pub fault: Option<u8>,
    /// When the fault appears (s after the activation).
    #[arg(long, default_value_t = 0.0, requires = "fault")]
    pub fault_after_s: f64,
}

/// `slidetrack emulate tactile|serial|slcan|xela-server`.
#[derive(Debug, Args)]
pub struct EmulateTactileArgs {
    /// Rig configuration: its `[sim]` tables make the data, its `[hw.tactile]`
    /// table the device (its `port` or `url` is ignored).
    #[arg(long, value_name = "RIG.toml")]
    pub config: PathBuf,
    /// The object of the simulated trials.
    #[arg(long, default_value = "box")]
    pub object: String,
    /// Seed of the first simulated trial.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Duration of each trial's sliding cycles (s).
    #[arg(long, default_value_t = 20.0)]
    pub duration: f64,
}
