//! `[hw.tactile] kind = "ros2"`: XELA sensors read from `xela_server_ros2`
//! through `slidetrack_ros2::xela` (the DDS subscriber lives in the ros2
//! crate, the table in drivers; this is where they meet).

use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use slidetrack_core::{Clock, TactileSource};
use slidetrack_drivers::xela_ros2::XelaRos2TactileConfig;
use slidetrack_ros2::xela::{WantedSensor, XelaRos2Options, XelaRos2Tactile};

/// Joins the table's domain and subscribes to its topic.
pub fn open_ros2_tactile(
    cfg: &XelaRos2TactileConfig,
    clock: Arc<dyn Clock>,
) -> Result<Box<dyn TactileSource>> {
    let domain = slidetrack_ros2::domain_id(cfg.domain_id).context("[hw.tactile] kind = \"ros2\"")?;
    let sensors = cfg
        .sensors
        .iter()
        .map(|s| WantedSensor {
            // validate() keeps sensor numbers within 1..=255.
            sensor_pos: u8::try_from(s.sensor).unwrap_or(u8::MAX),
            model: s.model.clone(),
            taxels: s.taxels(),
        })
        .collect();
    let options = XelaRos2Options {
        domain,
        topic: cfg.topic.clone(),
        sensors,
        timeout: Duration::from_millis(cfg.timeout_ms),
        startup_timeout: Duration::from_millis(cfg.startup_timeout_ms.max(cfg.timeout_ms)),
    };
    let device = format!("ros2:{}", cfg.topic);
    let source = XelaRos2Tactile::subscribe(options, cfg.info(&device), clock)
        .with_context(|| format!("[hw.tactile] kind = \"ros2\", topic {}", cfg.topic))?;
    Ok(Box::new(source))
}
