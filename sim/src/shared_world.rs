//! The world the simulated devices of one trial share.

use std::sync::{Arc, Mutex, MutexGuard};

use slidetrack_core::{DeviceError, ErrorKind};

use super::world::SimWorld;

/// The world shared by the simulated devices of one trial.
pub type SharedWorld = Arc<Mutex<SimWorld>>;

/// The world, locked for `device`; a fault when an earlier panic poisoned it.
pub(crate) fn lock<'a>(
    world: &'a SharedWorld,
    device: &str,
) -> Result<MutexGuard<'a, SimWorld>, DeviceError> {
    world.lock().map_err(|_| {
        DeviceError::new(ErrorKind::Fault, device, "simulation state poisoned by an earlier panic")
    })
}
