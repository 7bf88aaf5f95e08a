//! The ground-truth plot (`plot --what ground-truth`): the marker position, its Kalman-filtered and
//! its smoothed versions, and the velocity by finite differences, filtered
//! and smoothed (thesis Fig. 6.5), up to the release of the hand (after it
//! the object falls out of the hand). The filtered track is recomputed from
//! the stored measurements with the parameters in the channel metadata.

use std::path::Path;

use super::{PALETTE, Panel, Series};
use anyhow::{Context, Result, bail};
use slidetrack_calibration::ground_truth::{params_from_record, smooth_ground_truth};
use slidetrack_core::TimeNs;
use slidetrack_session::{
    ChannelMessage, GroundTruthMeasurement, GroundTruthParameters, GroundTruthSliding, ReadOptions,
    SessionError, SessionInfo, SimTruth, read_channel,
};

const GREY: plotters::style::RGBColor = plotters::style::RGBColor(110, 110, 110);

/// What the ground-truth plot shows, up to the release.
struct Tracks {
    sliding: Vec<(TimeNs, GroundTruthSliding)>,
    measured: Vec<(TimeNs, GroundTruthMeasurement)>,
    filtered: Vec<(TimeNs, GroundTruthSliding)>,
    truth: Vec<(TimeNs, SimTruth)>,
}

/// Reads the ground truth of `file` and recomputes its filtered track.
fn read_tracks(file: &Path, opts: ReadOptions) -> Result<Tracks> {
    let sliding = match read_channel::<GroundTruthSliding>(file, opts) {
        Err(SessionError::NoSuchTopic { .. }) => {
            bail!(
                "{} has no ground truth yet: run `slidetrack label {}` first",
                file.display(),
                file.display()
            )
        }
        other => other?,
    };
    let measured = read_channel::<GroundTruthMeasurement>(file, opts)?;
    let info = SessionInfo::read(file, opts)?;
    let record = info
        .channels
        .iter()
        .find(|c| c.topic == GroundTruthSliding::TOPIC)
        .and_then(|c| GroundTruthParameters::from_channel_metadata(&c.metadata))
        .context("/ground_truth/sliding has no `parameters` metadata")?
        .context("the `parameters` metadata of /ground_truth/sliding does not decode")?;
    let params = params_from_record(&record);
    let scans: Vec<TimeNs> = sliding.iter().map(|(t, _)| *t).collect();
    let positions: Vec<(TimeNs, f64)> = measured.iter().map(|(t, m)| (*t, m.position)).collect();
    let filtered = smooth_ground_truth(&scans, &positions, &params)
        .context("cannot recompute the filtered track from the stored measurements")?
        .filtered();
    let truth = match read_channel::<SimTruth>(file, opts) {
        Err(SessionError::NoSuchTopic { .. }) => Vec::new(),
        other => other?,
    };
    let end = slidetrack_session::release_time(file, opts)?.unwrap_or(TimeNs(u64::MAX));
    let before = |t: &TimeNs| *t <= end;
    Ok(Tracks {
        sliding: sliding.into_iter().filter(|(t, _)| before(t)).collect(),
        measured: measured.into_iter().filter(|(t, _)| before(t)).collect(),
        filtered: filtered.into_iter().filter(|(t, _)| before(t)).collect(),
        truth: truth.into_iter().filter(|(t, _)| before(t)).collect(),
    })
}

fn secs(t: &TimeNs) -> f64 {
    t.as_secs_f64()
}

/// The ground-truth plot of `file`: position (cm) and velocity (cm/s).
pub fn ground_truth_panels(file: &Path, opts: ReadOptions) -> Result<Vec<Panel>> {
    let tracks = read_tracks(file, opts)?;
    let (mut position, mut velocity) = (position_series(&tracks), velocity_series(&tracks));
    let first = tracks.measured.iter().find(|(_, m)| !m.rejected);
    if let (Some(first), false) = (first, tracks.truth.is_empty()) {
        // The simulator's position, shifted to 0 at the first marker sample as the marker's is.
        let truth = &tracks.truth;
        let k = truth.partition_point(|(t, _)| *t < first.0).min(truth.len() - 1);
        let origin = truth[k].1.position;
        let shifted = truth.iter().map(|(t, s)| (secs(t), (s.position - origin) * 100.0)).collect();
        position.insert(0, Series::line("simulator truth", GREY, shifted));
        let v = truth.iter().map(|(t, s)| (secs(t), s.velocity * 100.0)).collect();
        velocity.insert(0, Series::line("simulator truth", GREY, v));
    }
    Ok(vec![
        Panel {
            title: "object position along the sliding axis".into(),
            y_label: "position (cm)".into(),
            series: position,
        },
        Panel {
            title: "object velocity along the sliding axis".into(),
            y_label: "velocity (cm/s)".into(),
            series: velocity,
        },
    ])
}

/// Marker positions (accepted and rejected), filtered and smoothed (cm).
fn position_series(tracks: &Tracks) -> Vec<Series> {
    let accepted = tracks.measured.iter().filter(|(_, m)| !m.rejected);
    let rejected: Vec<(f64, f64)> = tracks
        .measured
        .iter()
        .filter(|(_, m)| m.rejected)
        .map(|(t, m)| (secs(t), m.position * 100.0))
        .collect();
    let mut series = vec![
        Series::dots(
            "ArUco marker",
            PALETTE[3],
            accepted.map(|(t, m)| (secs(t), m.position * 100.0)).collect(),
        ),
        Series::line(
            "Kalman filter",
            PALETTE[1],
            tracks.filtered.iter().map(|(t, g)| (secs(t), g.position * 100.0)).collect(),
        ),
        Series::line(
            "RTS smoother (ground truth)",
            PALETTE[0],
            tracks.sliding.iter().map(|(t, g)| (secs(t), g.position * 100.0)).collect(),
        ),
    ];
    if !rejected.is_empty() {
        series.push(Series::dots("rejected outliers", PALETTE[4], rejected));
    }
    series
}

/// Finite differences of the accepted marker positions, filtered and smoothed velocity (cm/s).
fn velocity_series(tracks: &Tracks) -> Vec<Series> {
    let accepted: Vec<&(TimeNs, GroundTruthMeasurement)> =
        tracks.measured.iter().filter(|(_, m)| !m.rejected).collect();
    // Finite differences of consecutive accepted marker positions, at the midpoints.
    let differences: Vec<(f64, f64)> = accepted
        .windows(2)
        .map(|w| {
            let (t0, t1) = (secs(&w[0].0), secs(&w[1].0));
            ((t0 + t1) / 2.0, (w[1].1.position - w[0].1.position) / (t1 - t0) * 100.0)
        })
        .collect();
    vec![
        Series::dots("finite differences", PALETTE[3], differences),
        Series::line(
            "Kalman filter",
            PALETTE[1],
            tracks.filtered.iter().map(|(t, g)| (secs(t), g.velocity * 100.0)).collect(),
        ),
        Series::line(
            "RTS smoother (ground truth)",
            PALETTE[0],
            tracks.sliding.iter().map(|(t, g)| (secs(t), g.velocity * 100.0)).collect(),
        ),
    ]
}
