//! XELA's ROS 2 server (`xela_server_ros2`) as a tactile source: its
//! `SensStream` messages decoded from CDR and read over DDS.

mod cdr_read;
mod error;
mod sens_stream;
mod source;

pub use cdr_read::CdrReader;
pub use error::CdrError;
pub use sens_stream::{SENS_STREAM_TOPIC, SENS_STREAM_TYPE, SensStream, SensorFull};
pub use source::{WantedSensor, XelaRos2Options, XelaRos2Tactile, check_sensors};
