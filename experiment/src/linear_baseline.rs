//! The linear-map baseline every dEKF is judged beside: a ridge regression
//! ([`LinearMap`]) from the model's own tactile channels to its state,
//! fitted on the model's own training sessions at the same filter steps.
//!
//! Inputs at a filter step, for each of the model's channels: the
//! baseline-subtracted value minus its value at the session's first step
//! (counts; the truth's positions are relative to that step too), then the
//! channel's derivative from the model's own derivative filter (counts/s).
//! Outputs: the model's state in its units (`p`, `v` in cm, cm/s; planar
//! `x`, `y`, `theta`, `vx`, `vy`, `omega` in cm, deg, cm/s, deg/s). The
//! penalty of each output is chosen by cross-validation grouped by session.
//! A map sees one step at a time: it has no memory, so a slow drift of the
//! counts is the only way it can carry a position.
//!
//! `train` writes the map beside the model (`MODEL.linear.safetensors`,
//! [`path_for`]); `eval` scores it on the same steps as the dEKF.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde_json::json;
use slidetrack_core::TimeNs;
use slidetrack_estimators::dekf::{DekfInput, DekfModel, Measurement, StateKind};
use slidetrack_estimators::derivative::DerivativeFilterConfig;
use slidetrack_estimators::linear_map::{FitOptions, LinearMap};

use crate::channels::ChannelPicker;
use crate::dataset::SessionData;
use crate::dekf_run::{inputs, write_atomically};

/// Metadata key of the map holding what it was fitted for.
const BASELINE_KEY: &str = "slidetrack_baseline";

/// The linear map with what it needs to make its inputs.
#[derive(Clone, Debug)]
pub struct LinearBaseline {
    /// The fitted map.
    pub map: LinearMap,
    /// The model channels it reads.
    pub channels: Vec<String>,
    /// Its filter steps: every `decimation`-th scan.
    pub decimation: usize,
    /// The derivative filter of its derivative inputs.
    pub filter: DerivativeFilterConfig,
    /// The state it predicts.
    pub state: StateKind,
}

/// Where `train` writes the baseline of the model at `model`:
/// `box.safetensors` -> `box.linear.safetensors`.
pub fn path_for(model: &Path) -> PathBuf {
    let stem = model.file_stem().map_or_else(|| "model".into(), |s| s.to_string_lossy().into_owned());
    model.with_file_name(format!("{stem}.linear.safetensors"))
}

/// The inputs at every `decimation`-th scan of `session` from scan `start`:
/// times and rows of `2 channels` values (see the module documentation).
fn features(
    session: &SessionData,
    channels: &[String],
    filter: DerivativeFilterConfig,
    decimation: usize,
    start: usize,
) -> Result<(Vec<TimeNs>, Vec<f64>)> {
    let picker = ChannelPicker::new(channels, &session.tactile)
        .with_context(|| format!("{}: the channels {}", session.path.display(), channels.join(", ")))?;
    let c = picker.len();
    let mut derivative = DekfInput::new(Measurement::Derivative, filter, c, decimation);
    let (mut values, mut last, mut first) = (vec![0.0; c], vec![0.0; c], None::<Vec<f64>>);
    let (mut times, mut rows) = (Vec::new(), Vec::new());
    for (t, z) in session.times.iter().zip(session.scans()).skip(start) {
        picker.pick(z, &mut values);
        // A missing sample keeps the channel's last value.
        for (l, v) in last.iter_mut().zip(&values) {
            if v.is_finite() {
                *l = *v;
            }
        }
        let Some(step) = derivative.on_scan(t.as_secs_f64(), &values) else { continue };
        let origin = first.get_or_insert_with(|| last.clone());
        times.push(*t);
        rows.extend(last.iter().zip(origin.iter()).map(|(v, o)| v - o));
        rows.extend(step.measurement);
    }
    Ok((times, rows))
}

/// Input names: `<channel>.value`, then `<channel>.rate`.
fn input_names(channels: &[String]) -> Vec<String> {
    let value = channels.iter().map(|c| format!("{c}.value_counts"));
    value.chain(channels.iter().map(|c| format!("{c}.rate_counts_per_s"))).collect()
}

/// Output names: the state's components with their units.
fn output_names(state: StateKind) -> Vec<String> {
    state
        .components()
        .iter()
        .zip(state.units())
        .map(|(c, u)| format!("{c}_{}", u.replace('/', "_per_")))
        .collect()
}

impl LinearBaseline {
    /// Fits the baseline of `model` on its training `sessions` (loaded with
    /// the model's truth), on the model's own channels and filter steps.
    pub fn fit(model: &DekfModel, sessions: &[SessionData]) -> Result<LinearBaseline> {
        let m = &model.meta;
        let (state, dim) = (model.state(), model.state().dim());
        let (mut x, mut y, mut groups) = (Vec::new(), Vec::new(), Vec::new());
        for (g, s) in sessions.iter().enumerate() {
            let (times, rows) = features(s, &m.channels, m.derivative_filter, m.decimation, 0)?;
            let truth = inputs(s, &m.channels, m.measurement, m.derivative_filter, m.decimation)?;
            let Some(t) = truth.truth.as_ref() else {
                bail!("{}: no truth to fit against", s.path.display())
            };
            if truth.times != times || truth.truth_dim != dim {
                bail!("{}: the baseline's steps differ from the model's", s.path.display());
            }
            x.extend(rows);
            y.extend_from_slice(t);
            groups.extend(std::iter::repeat_n(g, times.len()));
        }
        let (mut map, _) = LinearMap::fit(
            &x,
            &y,
            &groups,
            &input_names(&m.channels),
            &output_names(state),
            &FitOptions::default(),
        )
        .context("fitting the linear-map baseline")?;
        let files: Vec<String> = sessions.iter().map(|s| s.path.display().to_string()).collect();
        if let Some(meta) = map.meta.as_object_mut() {
            meta.insert(
                BASELINE_KEY.into(),
                json!({
                    "channels": m.channels,
                    "decimation": m.decimation,
                    "derivative_filter": m.derivative_filter,
                    "state": state,
                    "inputs": "per channel: the baseline-subtracted value minus its value at the first step (counts), then per channel its derivative (counts/s)",
                    "sessions": files,
                }),
            );
        }
        Ok(LinearBaseline {
            map,
            channels: m.channels.clone(),
            decimation: m.decimation,
            filter: m.derivative_filter,
            state,
        })
    }

    /// The baseline's predictions on `session` from scan `start` (its first
    /// step there): times and states in the model's units.
    pub fn predict(&self, session: &SessionData, start: usize) -> Result<Vec<(TimeNs, Vec<f64>)>> {
        let (times, rows) = features(session, &self.channels, self.filter, self.decimation, start)?;
        let width = 2 * self.channels.len();
        let mut out = vec![0.0; self.state.dim()];
        Ok(times
            .into_iter()
            .zip(rows.chunks_exact(width))
            .map(|(t, row)| {
                self.map.apply(row, &mut out);
                (t, out.clone())
            })
            .collect())
    }

    /// Writes the baseline atomically.
    pub fn save(&self, path: &Path) -> Result<()> {
        write_atomically(path, &self.map.to_bytes()?)
    }

    /// Reads a baseline written by [`LinearBaseline::save`].
    pub fn load(path: &Path) -> Result<LinearBaseline> {
        let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
        let map = LinearMap::from_bytes(&bytes)
            .with_context(|| format!("invalid linear map {}", path.display()))?;
        let meta = map.meta.get(BASELINE_KEY).cloned().with_context(|| {
            format!("{}: not a slidetrack baseline (no `{BASELINE_KEY}` metadata)", path.display())
        })?;
        let field = |k: &str| meta.get(k).cloned().with_context(|| format!("{}: no `{k}`", path.display()));
        let channels: Vec<String> = serde_json::from_value(field("channels")?)?;
        let decimation: usize = serde_json::from_value(field("decimation")?)?;
        let filter: DerivativeFilterConfig = serde_json::from_value(field("derivative_filter")?)?;
        let state: StateKind = serde_json::from_value(field("state")?)?;
        if map.inputs() != 2 * channels.len() || map.outputs() != state.dim() || decimation == 0 {
            bail!("{}: the map's shape does not match its channels and state", path.display());
        }
        Ok(LinearBaseline { map, channels, decimation, filter, state })
    }

    /// The baseline of the model at `model_path`, when `train` wrote one
    /// beside it and it was made for the same channels, steps and state.
    pub fn beside(model: &DekfModel, model_path: &Path) -> Result<Option<LinearBaseline>> {
        let path = path_for(model_path);
        if !path.exists() {
            return Ok(None);
        }
        let b = LinearBaseline::load(&path)?;
        let m = &model.meta;
        if b.channels != m.channels || b.decimation != m.decimation || b.state != model.state() {
            bail!(
                "{} was fitted for other channels, steps or state than {}; train again",
                path.display(),
                model_path.display()
            );
        }
        Ok(Some(b))
    }
}
