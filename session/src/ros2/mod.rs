//! Sessions as ROS 2 bags: [`export_ros2_bag`] writes a session's messages
//! as CDR-encoded ROS 2 messages with `ros2msg` schemas, in MCAP (the
//! format `ros2 bag` records by default).

mod bag;
mod cdr;
mod convert;
mod definitions;

pub use bag::{Ros2BagReport, export_ros2_bag};
pub use cdr::{CDR_LE_HEADER, CdrWriter};
pub use convert::{Ros2Message, convert, ros2_type};
pub use definitions::complete_definition;
