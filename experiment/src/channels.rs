//! The dEKF's input channels: names resolved against a tactile layout.
//!
//! A channel is one axis of a finger's reading or of a taxel:
//! - `finger.axis` (`thumb.x`): the finger's reading as the rig defines it
//!   (`fingers` in the taxel layout: one taxel, as in the thesis's Sec.
//!   6.2.1, or the mean of a patch);
//! - `sensor.taxel.axis` (`left.5.z`): one taxel of a sensor;
//! - `sensor.mean.axis` (`left.mean.z`): the mean of every taxel of a sensor.
//!
//! A model file records its channel names, so a model runs on any session
//! whose layout resolves them.

use std::ops::Range;

use anyhow::{Context, Result, bail};
use slidetrack_core::{AXES, Finger, TactileInfo};
use slidetrack_session::{ChannelMessage, SessionInfo, TactileRaw, TaxelLayout};

/// The tactile source that recorded a session, from the taxel layout of its
/// `/tactile/raw` channel; `None` without the channel or the layout.
pub fn recorded_tactile(path: &std::path::Path, info: &SessionInfo) -> Result<Option<TactileInfo>> {
    let layout = info
        .channel(TactileRaw::TOPIC)
        .and_then(|c| TaxelLayout::from_channel_metadata(&c.metadata))
        .transpose()
        .with_context(|| format!("{}: bad taxel layout on {}", path.display(), TactileRaw::TOPIC))?;
    Ok(layout.map(|l| l.info()))
}

/// The channels of Table 6.2's sets, per finger (`thumb.x`, ...).
pub fn finger_channels(axes: &[&str]) -> Vec<String> {
    Finger::ALL.iter().flat_map(|f| axes.iter().map(move |a| format!("{}.{a}", f.name()))).collect()
}

/// Every taxel of every sensor of `info` on `axes` (`sensor.taxel.axis`),
/// for models that read whole patches.
pub fn taxel_channels(info: &TactileInfo, axes: &[&str]) -> Vec<String> {
    info.layout
        .sensors
        .iter()
        .flat_map(|s| {
            (0..s.taxels()).flat_map(move |t| axes.iter().map(move |a| format!("{}.{t}.{a}", s.name)))
        })
        .collect()
}

/// Channel names resolved to the taxels (averaged) and axis each reads.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelPicker {
    picks: Vec<(Range<usize>, usize)>,
}

impl ChannelPicker {
    /// Resolves `names` against `info`; an error names the channel that
    /// does not resolve and what the layout offers.
    pub fn new(names: &[String], info: &TactileInfo) -> Result<ChannelPicker> {
        let fingers = info.finger_map().context("the tactile layout")?;
        let picks = names.iter().map(|n| resolve(n, info, &fingers)).collect::<Result<_>>()?;
        Ok(ChannelPicker { picks })
    }

    /// Number of channels.
    pub fn len(&self) -> usize {
        self.picks.len()
    }

    /// True without channels.
    pub fn is_empty(&self) -> bool {
        self.picks.is_empty()
    }

    /// The channels' values in `scan` (`[taxel][x, y, z]`, layout order)
    /// into `out`; a scan too short for a channel gives NaN there.
    pub fn pick(&self, scan: &[[f64; 3]], out: &mut [f64]) {
        for ((taxels, axis), o) in self.picks.iter().zip(out.iter_mut()) {
            *o = match scan.get(taxels.clone()) {
                Some(values) if !values.is_empty() => {
                    values.iter().map(|v| v[*axis]).sum::<f64>() / values.len() as f64
                }
                _ => f64::NAN,
            };
        }
    }
}

fn resolve(
    name: &str,
    info: &TactileInfo,
    fingers: &slidetrack_core::FingerMap,
) -> Result<(Range<usize>, usize)> {
    let parts: Vec<&str> = name.split('.').collect();
    let axis_of = |a: &str| AXES.iter().position(|x| *x == a);
    let unknown = || {
        format!(
            "unknown tactile channel `{name}`: expected `finger.axis` (fingers {}), `sensor.taxel.axis` or \
             `sensor.mean.axis` (sensors {}), axes x, y, z",
            Finger::ALL.map(Finger::name).join(", "),
            info.layout.sensor_names()
        )
    };
    match parts.as_slice() {
        [finger, axis] => {
            let f = Finger::ALL.into_iter().find(|f| f.name() == *finger).with_context(unknown)?;
            Ok((fingers.taxels(f), axis_of(axis).with_context(unknown)?))
        }
        [sensor, which, axis] => {
            let axis = axis_of(axis).with_context(unknown)?;
            let (s, range) = info.layout.sensor(sensor).with_context(unknown)?;
            if *which == "mean" {
                return Ok((range, axis));
            }
            let taxel: usize = which.parse().ok().with_context(unknown)?;
            if taxel >= s.taxels() {
                bail!(
                    "tactile channel `{name}`: sensor `{sensor}` has {} taxels (0..={})",
                    s.taxels(),
                    s.taxels() - 1
                );
            }
            Ok((range.start + taxel..range.start + taxel + 1, axis))
        }
        _ => bail!(unknown()),
    }
}

#[cfg(test)]
mod tests {
    use slidetrack_core::{FingerReading, PerFinger, SensorLayout, TactileLayout};

    use super::*;

    /// Two 2x2 patches; the thumb reads the mean of `left`, index and middle taxel 3 of `right`.
    fn info() -> TactileInfo {
        TactileInfo {
            device: "test".into(),
            rate_hz: 100.0,
            layout: TactileLayout {
                sensors: vec![
                    SensorLayout::grid("left", "p", "thumb", 2, 2),
                    SensorLayout::grid("right", "p", "index", 2, 2),
                ],
            },
            fingers: PerFinger {
                thumb: FingerReading::mean("left"),
                index: FingerReading::taxel("right", 3),
                middle: FingerReading::taxel("right", 3),
            },
        }
    }

    #[test]
    fn names_resolve_to_finger_readings_taxels_and_means() {
        let scan: Vec<[f64; 3]> = (0..8).map(|t| [t as f64, 10.0 * t as f64, -1.0]).collect();
        let names: Vec<String> =
            ["thumb.x", "index.y", "right.1.x", "left.mean.y", "left.0.z"].map(String::from).to_vec();
        let picker = ChannelPicker::new(&names, &info()).unwrap();
        let mut out = vec![0.0; picker.len()];
        picker.pick(&scan, &mut out);
        assert_eq!(out, [1.5, 70.0, 5.0, 15.0, -1.0]);
        picker.pick(&scan[..4], &mut out);
        assert!(out[1].is_nan() && out[2].is_nan(), "a short scan gives NaN, not a panic");
    }

    #[test]
    fn unknown_channels_are_one_clear_error() {
        for bad in ["ring.x", "thumb.w", "left.4.x", "up.0.x", "left.x.y.z", "left.first.x"] {
            let err = ChannelPicker::new(&[bad.to_string()], &info()).unwrap_err();
            assert!(format!("{err:#}").contains(bad), "{bad}: {err:#}");
        }
        assert_eq!(taxel_channels(&info(), &["z"])[..2], ["left.0.z".to_string(), "left.1.z".to_string()]);
    }
}
