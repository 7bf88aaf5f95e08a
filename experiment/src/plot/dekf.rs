//! Plots of the dEKF: estimates against the truth (thesis Fig. 6.9) and the
//! training curve (Fig. 6.6).

use std::path::Path;

use anyhow::Result;
use slidetrack_core::TimeNs;
use slidetrack_estimators::dekf::{DekfOutput, EpochReport};

use super::{PALETTE, Panel, Series, draw_stacked, draw_stacked_x};
use crate::dataset::{TruthSource, load};
use crate::dekf_run::CM;

/// Estimated position and velocity against the ground truth and the
/// simulator's truth when present (Fig. 6.9).
pub fn plot_replay(file: &Path, outputs: &[(TimeNs, DekfOutput)], out: &Path) -> Result<()> {
    let t0 = outputs.first().map_or(0.0, |(t, _)| t.as_secs_f64());
    let mut pos = vec![Series::line(
        "dEKF estimate",
        PALETTE[3],
        outputs.iter().map(|(t, o)| (t.as_secs_f64(), o.mean[0])).collect(),
    )];
    let mut vel = vec![Series::line(
        "dEKF estimate",
        PALETTE[3],
        outputs.iter().map(|(t, o)| (t.as_secs_f64(), o.mean[1])).collect(),
    )];
    for (source, label, colour) in [
        (TruthSource::GroundTruth, "ground truth", PALETTE[0]),
        (TruthSource::Sim, "simulator truth", PALETTE[2]),
    ] {
        if let Ok(d) = load(file, Some(source)) {
            let truth: Vec<&[f64]> = (0..d.times.len()).filter_map(|k| d.truth_at(k)).collect();
            let start = d.times.iter().position(|t| t.as_secs_f64() >= t0).unwrap_or(0);
            let origin = truth.get(start).map_or(0.0, |x| x[0]);
            pos.insert(
                0,
                Series::line(
                    label,
                    colour,
                    d.times
                        .iter()
                        .zip(&truth)
                        .map(|(t, x)| (t.as_secs_f64(), (x[0] - origin) * CM))
                        .collect(),
                ),
            );
            vel.insert(
                0,
                Series::line(
                    label,
                    colour,
                    d.times.iter().zip(&truth).map(|(t, x)| (t.as_secs_f64(), x[1] * CM)).collect(),
                ),
            );
        }
    }
    let name = file.file_name().map_or(String::new(), |n| n.to_string_lossy().into_owned());
    draw_stacked(
        out,
        &format!("{name}: dEKF replay"),
        &[
            Panel { title: "position along the sliding axis".into(), y_label: "cm".into(), series: pos },
            Panel { title: "velocity along the sliding axis".into(), y_label: "cm/s".into(), series: vel },
        ],
    )
}

/// State RMSE per epoch (Fig. 6.6).
pub fn plot_training_curve(epochs: &[EpochReport], out: &Path) -> Result<()> {
    let pos: Vec<(f64, f64)> = epochs.iter().map(|e| (e.epoch as f64, e.rmse[0])).collect();
    let vel: Vec<(f64, f64)> = epochs.iter().map(|e| (e.epoch as f64, e.rmse[1])).collect();
    let whole: Vec<(f64, f64)> =
        epochs.iter().filter_map(|e| e.selection_score.map(|s| (e.epoch as f64, s))).collect();
    let mut position = vec![Series::line("training windows", PALETTE[0], pos)];
    if !whole.is_empty() {
        position.push(Series::line("whole training sessions (epoch selection)", PALETTE[3], whole));
    }
    let panels = [
        Panel { title: "position RMSE on the training data".into(), y_label: "cm".into(), series: position },
        Panel {
            title: "velocity RMSE on the training data".into(),
            y_label: "cm/s".into(),
            series: vec![Series::line("velocity", PALETTE[1], vel)],
        },
    ];
    draw_stacked_x(out, "dEKF training", "epoch", &panels)
}
