//! What the messages of `xela_server` carry: the welcome, the scans and
//! the units of their values.

/// The value of `"message"` in the welcome message.
pub const WELCOME: &str = "Welcome";

/// Raw counts of one taxel: `[x, y, z]` (16-bit magnetometer counts, not
/// calibrated).
pub type TaxelCounts = [u16; 3];

/// Calibrated force on one taxel: `[x, y, z]` in newtons.
pub type TaxelForce = [f64; 3];

/// What one WebSocket text message from `xela_server` carries.
#[derive(Clone, Debug, PartialEq)]
pub enum XelaEvent {
    /// The welcome sent when a client connects; it carries no scan.
    Welcome(XelaWelcome),
    /// One scan of every sensor the server reads.
    Data(XelaScan),
}

/// The welcome message.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct XelaWelcome {
    /// Its `"version"`, when it has one (server version and build, for
    /// example `1.7.7_161703`; not documented for the welcome).
    pub version: Option<String>,
}

/// One data message: a scan of every sensor.
#[derive(Clone, Debug, PartialEq)]
pub struct XelaScan {
    /// The server's message counter (`"message"`).
    pub message: u64,
    /// The server's clock when it sent the message (`"time"`, Unix time in
    /// seconds), when present. Kept as the server wrote it; the client's
    /// arrival instant is the time to use on the session clock.
    pub server_time_s: Option<f64>,
    /// The sensors, by increasing sensor number.
    pub sensors: Vec<XelaSensorScan>,
}

impl XelaScan {
    /// The scan of sensor `number`, if the message has it.
    pub fn sensor(&self, number: u32) -> Option<&XelaSensorScan> {
        self.sensors.iter().find(|s| s.sensor == number)
    }
}

/// One sensor's part of a data message.
#[derive(Clone, Debug, PartialEq)]
pub struct XelaSensorScan {
    /// The sensor's number: its key in the message (`"1"` is sensor 1), the
    /// position the server's configuration gives it.
    pub sensor: u32,
    /// The model the server reports (`"model"`, for example `uSPa44`; the
    /// server may write it in capitals, as `USPA35`).
    pub model: String,
    /// The sensor's own time stamp (`"time"`, Unix time in seconds), when present.
    pub time_s: Option<f64>,
    /// Raw counts, one `[x, y, z]` per taxel, in the server's taxel order.
    pub taxels: Vec<TaxelCounts>,
    /// Calibrated forces (N), one `[x, y, z]` per taxel, when the server's
    /// force calibration is on (`"calibrated"` absent, `null` or empty: `None`).
    pub calibrated: Option<Vec<TaxelForce>>,
}
