//! The hand actuator: one voltage per finger proximal joint.

use crate::DeviceError;

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
