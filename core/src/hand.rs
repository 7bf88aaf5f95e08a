//! The hand actuator: one voltage per finger proximal joint.

use crate::{DeviceError, TimeNs};

/// Voltages for the proximal joints, `[thumb, index, middle]` (V).
pub type FingerVolts = [f64; 3];

/// A hand whose fingers close under a voltage.
///
/// # Contract
/// - `command` sets the proximal-joint voltages and returns at once; a
///   positive voltage closes a finger. Values beyond `±max_volts()` are
///   saturated by the backend (never sent).
/// - `release` opens the hand safely (fingers away from the object, then zero
///   voltage) and must be callable at any time, repeatedly, also after an
///   error. Backends call it themselves when dropped.
/// - Errors: [`crate::ErrorKind::Disconnected`] when the hand is gone.
pub trait HandActuator: Send {
    /// Sets the proximal-joint voltages (V), `[thumb, index, middle]`.
    fn command(&mut self, volts: FingerVolts) -> Result<(), DeviceError>;
    /// Opens the hand safely.
    fn release(&mut self) -> Result<(), DeviceError>;
    /// The largest voltage magnitude the hand accepts (V).
    fn max_volts(&self) -> f64;
    /// Name of the device, for messages.
    fn device(&self) -> &str;
}

/// Clamps each voltage to `±max_volts`; NaN becomes 0 (never sent to a motor).
pub fn saturate(volts: FingerVolts, max_volts: f64) -> FingerVolts {
    volts.map(|v| if v.is_nan() { 0.0 } else { v.clamp(-max_volts, max_volts) })
}

/// What a hand reports about itself: whatever part of it the device can
/// tell without being commanded.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HandStatus {
    /// When the status was read, on the session clock.
    pub t: TimeNs,
    /// Each finger's travel from its open rest position towards the object
    /// (m), in the hand's finger order; empty when the hand does not report it.
    pub finger_travel_m: Vec<f64>,
    /// Opening between the fingertips (m), for grippers that report it.
    pub opening_m: Option<f64>,
}

/// Reads a hand's status without commanding it (`slidetrack record`, which
/// records a hand that something else drives).
///
/// # Contract
/// - `status` returns at once: the latest status, or `None` when nothing
///   new is known since the previous call.
/// - Errors: [`crate::ErrorKind::Disconnected`] when the hand is gone.
pub trait HandMonitor: Send {
    /// The latest status, if there is a new one.
    fn status(&mut self) -> Result<Option<HandStatus>, DeviceError>;
    /// Name of the device, for messages.
    fn device(&self) -> &str;
}
