//! What connects to a server or serves one (feature `devices`, Linux): the
//! client, the rig's tactile source over it, the local emulator and the
//! source fed by the simulated rig through it.

pub mod client;
pub mod emulated;
pub mod emulator;
pub mod source;

pub use client::{ReconnectPolicy, XelaReceived, XelaWsClient, XelaWsOptions};
pub use emulated::{EmulatedXelaWsTactile, XelaWsLiveEmulator};
pub use emulator::{EmulatedMessage, LiveMessage, XelaWsEmulator, XelaWsEmulatorConfig};
pub use source::XelaWsTactile;
