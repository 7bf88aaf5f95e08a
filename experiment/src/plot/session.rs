//! Panels of a session's recorded channels: the grasp (thesis Fig. 6.4), the
//! tactile channels and the marker position (Fig. 6.8).

use anyhow::{Context, Result};
use slidetrack_core::{AXES, Finger, TactileInfo, TimeNs};
use slidetrack_session::{
    ArucoDetection, GraspControl, ReadOptions, SessionError, SessionInfo, SimTruth, TactileZeroed,
    read_channel, scan_of,
};

use super::{PALETTE, Panel, Series};
use crate::channels::{ChannelPicker, recorded_tactile};

fn secs(t: TimeNs) -> f64 {
    t.as_secs_f64()
}

/// A channel that may be absent (a session without camera has no marker).
fn optional<T>(r: Result<Vec<T>, SessionError>) -> Result<Vec<T>> {
    match r {
        Ok(v) => Ok(v),
        Err(SessionError::NoSuchTopic { .. }) => Ok(Vec::new()),
        Err(e) => Err(e.into()),
    }
}

/// Desired vs achieved grasp per finger (Fig. 6.4), one panel per finger.
pub fn grasp_panels(file: &std::path::Path, opts: ReadOptions) -> Result<Vec<Panel>> {
    let grasp = read_channel::<GraspControl>(file, opts).context("the grasp plot needs /control/grasp")?;
    Ok(Finger::ALL
        .iter()
        .map(|&f| Panel {
            title: format!("{}: desired and achieved z", f.name()),
            y_label: "z (counts)".into(),
            series: vec![
                Series::line(
                    "desired",
                    PALETTE[0],
                    grasp.iter().map(|(t, g)| (secs(*t), g.fingers[f].desired)).collect(),
                ),
                Series::line(
                    "achieved",
                    PALETTE[1],
                    grasp.iter().map(|(t, g)| (secs(*t), g.fingers[f].achieved)).collect(),
                ),
            ],
        })
        .collect())
}

/// The reference grasp strength and each finger's achieved z, in one panel.
pub fn grasp_overview(file: &std::path::Path, opts: ReadOptions) -> Result<Panel> {
    let grasp = read_channel::<GraspControl>(file, opts).context("the overview needs /control/grasp")?;
    let mut series = vec![Series::line(
        "reference tau_g",
        RGB_GREY,
        grasp.iter().map(|(t, g)| (secs(*t), g.reference)).collect(),
    )];
    for (k, f) in Finger::ALL.into_iter().enumerate() {
        series.push(Series::line(
            format!("{} achieved", f.name()),
            PALETTE[k],
            grasp.iter().map(|(t, g)| (secs(*t), g.fingers[f].achieved)).collect(),
        ));
    }
    Ok(Panel { title: "grasp strength (baseline-subtracted z)".into(), y_label: "counts".into(), series })
}

const RGB_GREY: plotters::style::RGBColor = plotters::style::RGBColor(110, 110, 110);

/// Baseline-subtracted x, y, z of each finger's reading (Fig. 6.8): its
/// taxel, or the mean of its patch, as the session's taxel layout says.
pub fn tactile_panels(file: &std::path::Path, opts: ReadOptions) -> Result<Vec<Panel>> {
    let zeroed =
        read_channel::<TactileZeroed>(file, opts).context("the tactile plot needs /tactile/zeroed")?;
    let info = SessionInfo::read(file, opts)?;
    let tactile = recorded_tactile(file, &info)?
        .unwrap_or_else(|| TactileInfo::one_module_per_finger("recorded", 100.0, "sim"));
    let mut scans = Vec::with_capacity(zeroed.len());
    for (t, z) in &zeroed {
        let scan = scan_of(&tactile.layout, &z.sensors)
            .with_context(|| format!("{}: /tactile/zeroed at {t}", file.display()))?;
        scans.push((secs(*t), scan));
    }
    Finger::ALL
        .iter()
        .map(|&f| {
            let names: Vec<String> = AXES.iter().map(|a| format!("{}.{a}", f.name())).collect();
            let picker = ChannelPicker::new(&names, &tactile)?;
            let mut xyz = [0.0; 3];
            let mut per_axis: [Vec<(f64, f64)>; 3] = Default::default();
            for (t, scan) in &scans {
                picker.pick(scan, &mut xyz);
                for a in 0..3 {
                    per_axis[a].push((*t, xyz[a]));
                }
            }
            let series = per_axis
                .into_iter()
                .zip(AXES)
                .enumerate()
                .map(|(a, (pts, n))| Series::line(n, PALETTE[a], pts));
            Ok(Panel {
                title: format!("{} tactile channels", f.name()),
                y_label: "counts - baseline".into(),
                series: series.collect(),
            })
        })
        .collect()
}

/// Session time at which the hand opened, if it did: after it the object
/// falls out of the hand, which is not what the plots are about.
fn release_time(file: &std::path::Path, opts: ReadOptions) -> Result<TimeNs> {
    Ok(slidetrack_session::release_time(file, opts)?.unwrap_or(TimeNs(u64::MAX)))
}

/// Marker position along the sliding axis, and the simulator's truth when
/// recorded, up to the release.
pub fn position_panel(file: &std::path::Path, opts: ReadOptions) -> Result<Panel> {
    let end = release_time(file, opts)?;
    let mut marker = optional(read_channel::<ArucoDetection>(file, opts))?;
    let mut truth = optional(read_channel::<SimTruth>(file, opts))?;
    marker.retain(|(t, _)| *t <= end);
    truth.retain(|(t, _)| *t <= end);
    let mut series = Vec::new();
    if !truth.is_empty() {
        series.push(Series::line(
            "simulator truth",
            RGB_GREY,
            truth.iter().map(|(t, s)| (secs(*t), s.position * 100.0)).collect(),
        ));
    }
    let seen: Vec<_> =
        marker.iter().filter_map(|(t, d)| d.position_on_axis_m.map(|p| (secs(*t), p * 100.0))).collect();
    series.push(Series::dots("ArUco marker", PALETTE[3], seen));
    Ok(Panel {
        title: "object position along the sliding axis".into(),
        y_label: "position (cm)".into(),
        series,
    })
}
