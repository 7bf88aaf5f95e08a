//! End-to-end training (Sec. 2.5.3, 6.2.4): backpropagation through time over
//! subsequences of increasing length, Adam, loss (2.149).

use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use super::batch::{Sequence, Window};
use super::model::DekfModel;
use super::parts::{DEFAULT_PART_WINDOWS, parallel_grad};

/// One stage of the schedule: subsequences of `length` steps for `epochs` epochs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Stage {
    /// Subsequence length `T_s` (steps).
    pub length: usize,
    /// Epochs at this length.
    pub epochs: usize,
}

/// How the windows of an epoch are grouped into batches.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Batching {
    /// Every window of every sequence shuffled together, then cut into
    /// batches of `batch_size` (the last one may be smaller).
    #[default]
    Windows,
    /// As thesis Sec. 2.5.3 reads: the sequences shuffled and cut into sets
    /// of `batch_size`; a batch is one window position of every sequence of
    /// a set, and each set steps through all its window positions
    /// (shuffled). The windows are the same as with [`Batching::Windows`];
    /// a batch holds windows of different sequences at the same time.
    Sequences,
}

/// Training settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrainConfig {
    /// The schedule; the thesis: lengths 2, 4, 8, 16, 32 with 5 epochs each.
    pub schedule: Vec<Stage>,
    /// Subsequences per batch `B`.
    pub batch_size: usize,
    /// How windows are grouped into batches.
    #[serde(default)]
    pub batching: Batching,
    /// Adam's step size.
    pub learning_rate: f64,
    /// Adam's `beta1`, `beta2`, `epsilon`.
    pub adam: [f64; 3],
    /// Largest global norm of a batch's (mean-loss) gradient; larger
    /// gradients are scaled down. `None`: no clipping.
    pub clip_norm: Option<f64>,
    /// Seed of the shuffling and of the initial-state draws.
    pub seed: u64,
    /// Worker threads (0: as many as the machine has). Not written to model
    /// files: the model does not depend on it.
    #[serde(skip_serializing)]
    pub threads: usize,
    /// Windows per part of a batch's gradient (at least 1; see
    /// [`super::parts`]). The parts' gradients are summed along a tree
    /// fixed by their number, so the model depends on this (by float
    /// rounding) but not on `threads`; a batch keeps up to
    /// `batch_size / part_windows` threads busy.
    pub part_windows: usize,
    /// Half-width of the uniform random shift of each window along the
    /// sliding axis (cm); 0 trains on the recorded positions only.
    pub position_shift_cm: f64,
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            schedule: [2, 4, 8, 16, 32].into_iter().map(|length| Stage { length, epochs: 5 }).collect(),
            batch_size: 32,
            batching: Batching::Windows,
            learning_rate: 1e-3,
            adam: [0.9, 0.999, 1e-8],
            clip_norm: Some(10.0),
            seed: 1,
            threads: 0,
            part_windows: DEFAULT_PART_WINDOWS,
            position_shift_cm: 0.0,
        }
    }
}

/// Progress after a batch.
#[derive(Clone, Debug, PartialEq)]
pub struct Progress {
    /// Stage index in the schedule.
    pub stage: usize,
    /// Its subsequence length.
    pub length: usize,
    /// Epoch within the stage (from 0).
    pub epoch: usize,
    /// Batches done in this epoch, and in it in all.
    pub batch: (usize, usize),
    /// Batches done since the start, and in the whole training.
    pub overall: (usize, usize),
    /// Running state RMSE of this epoch, position (cm) and velocity (cm/s).
    pub rmse: [f64; 2],
}

/// The outcome of one epoch.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EpochReport {
    /// Subsequence length.
    pub length: usize,
    /// Epoch number from the start of training (from 1).
    pub epoch: usize,
    /// Mean loss (2.149) over the epoch.
    pub loss: f64,
    /// State RMSE over the epoch, position (cm) and velocity (cm/s).
    pub rmse: [f64; 2],
    /// Batches skipped because their loss or gradient was not finite.
    pub skipped_batches: usize,
    /// The selection score after the epoch (see [`train_with_selection`]),
    /// when there was one.
    #[serde(default)]
    pub selection_score: Option<f64>,
}

/// Adam with bias correction on the trainable elements.
struct Adam {
    m: Vec<f32>,
    v: Vec<f32>,
    t: i32,
}

impl Adam {
    fn step(&mut self, params: &mut [f32], grad: &[f32], mask: &[bool], lr: f64, [b1, b2, eps]: [f64; 3]) {
        self.t += 1;
        let c1 = 1.0 - b1.powi(self.t);
        let c2 = 1.0 - b2.powi(self.t);
        for i in 0..params.len() {
            if !mask[i] {
                continue;
            }
            let g = f64::from(grad[i]);
            let m = b1 * f64::from(self.m[i]) + (1.0 - b1) * g;
            let v = b2 * f64::from(self.v[i]) + (1.0 - b2) * g * g;
            self.m[i] = m as f32;
            self.v[i] = v as f32;
            params[i] -= (lr * (m / c1) / ((v / c2).sqrt() + eps)) as f32;
        }
    }
}

/// The window starts of `sequence`: consecutive subsequences of `length`
/// steps, each starting at a step with a truth (every step of a sliding
/// sequence; a planar one has none where the marker was not seen).
fn starts(sequence: &Sequence, length: usize) -> impl Iterator<Item = usize> + '_ {
    (0..sequence.len().saturating_sub(length))
        .step_by(length)
        .filter(|&t| sequence.truth_at(t)[0].is_finite())
}

/// The batches of one epoch, `(sequence, start)` each: every sequence cut
/// into consecutive subsequences of `length` steps, grouped as `batching` says.
fn epoch_batches(
    data: &[Sequence],
    length: usize,
    batch_size: usize,
    batching: Batching,
    rng: &mut ChaCha8Rng,
) -> Vec<Vec<(usize, usize)>> {
    let batch_size = batch_size.max(1);
    match batching {
        Batching::Windows => {
            let mut w: Vec<(usize, usize)> =
                data.iter().enumerate().flat_map(|(i, s)| starts(s, length).map(move |t0| (i, t0))).collect();
            w.shuffle(rng);
            w.chunks(batch_size).map(<[(usize, usize)]>::to_vec).collect()
        }
        Batching::Sequences => {
            let mut order: Vec<usize> = (0..data.len()).collect();
            order.shuffle(rng);
            let mut batches = Vec::new();
            for set in order.chunks(batch_size) {
                let longest = set.iter().map(|&i| data[i].len()).max().unwrap_or(0);
                let mut positions: Vec<usize> = (0..longest.saturating_sub(length)).step_by(length).collect();
                positions.shuffle(rng);
                for t0 in positions {
                    let batch: Vec<(usize, usize)> = set
                        .iter()
                        .filter(|&&i| t0 < data[i].len().saturating_sub(length))
                        .filter(|&&i| data[i].truth_at(t0)[0].is_finite())
                        .map(|&i| (i, t0))
                        .collect();
                    if !batch.is_empty() {
                        batches.push(batch);
                    }
                }
            }
            batches
        }
    }
}

/// The windows of one batch: each starts from an initial state drawn around
/// the truth at its start (eq. 2.148), shifted along the sliding axis by
/// up to `cfg.position_shift_cm`.
fn batch_windows(
    chunk: &[(usize, usize)],
    data: &[Sequence],
    cfg: &TrainConfig,
    p0: &[f64],
    rng: &mut ChaCha8Rng,
) -> Vec<Window> {
    let dim = p0.len();
    let dofs = dim / 2;
    chunk
        .iter()
        .map(|&(sequence, start)| {
            let truth = data[sequence].truth_at(start);
            // One draw per component, then one shift per degree of freedom
            // (for a sliding state: n0, n1, shift, the order of the thesis's
            // one-dimensional training, so its models stay what they were).
            let noise: Vec<f64> = (0..dim).map(|_| StandardNormal.sample(rng)).collect();
            let position_shift: Vec<f64> = (0..dofs)
                .map(|_| {
                    if cfg.position_shift_cm > 0.0 {
                        rng.random_range(-cfg.position_shift_cm..=cfg.position_shift_cm)
                    } else {
                        0.0
                    }
                })
                .collect();
            let mean0 = (0..dim)
                .map(|i| {
                    let shifted = if i < dofs { truth[i] + position_shift[i] } else { truth[i] };
                    shifted + noise[i] * p0[i].sqrt()
                })
                .collect();
            Window { sequence, start, mean0, position_shift }
        })
        .collect()
}

/// Trains `model` on `data` (sequences at the filter rate, measurements
/// already normalised with the model's normalisation). Calls `progress`
/// after every batch; returns one report per epoch.
pub fn train(
    model: &mut DekfModel,
    data: &[Sequence],
    cfg: &TrainConfig,
    progress: &mut dyn FnMut(&Progress),
) -> Vec<EpochReport> {
    train_with_selection(model, data, cfg, progress, None)
}

/// Epoch selection of [`train_with_selection`]: the first stage whose epochs
/// are scored, and the score (lower is better).
pub type Selection<'a> = (usize, &'a mut dyn FnMut(&DekfModel) -> f64);

/// [`train`], scoring the model with `select` after every epoch of the
/// stages `select_from..` (lower is better; a non-finite score never wins)
/// and ending with the parameters of the best-scoring epoch. The windowed
/// loss cannot see what happens over a whole session; a score on whole
/// sessions (the position RMSE of the filter run from their start) can.
pub fn train_with_selection(
    model: &mut DekfModel,
    data: &[Sequence],
    cfg: &TrainConfig,
    progress: &mut dyn FnMut(&Progress),
    mut select: Option<Selection>,
) -> Vec<EpochReport> {
    let mut best: Option<(f64, Vec<f32>)> = None;
    // A pool of its own only when a thread count is asked for (and can be
    // had); the model is the same either way.
    let pool = (cfg.threads > 0)
        .then(|| rayon::ThreadPoolBuilder::new().num_threads(cfg.threads).build().ok())
        .flatten();
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let mask = model.layout.trainable_mask();
    let mut adam = Adam { m: vec![0.0; model.params.len()], v: vec![0.0; model.params.len()], t: 0 };
    let p0 = model.meta.p0_diag.clone();
    let dim = model.state().dim();
    let total_batches: usize = cfg
        .schedule
        .iter()
        .map(|s| {
            s.epochs * epoch_batches(data, s.length, cfg.batch_size, cfg.batching, &mut rng.clone()).len()
        })
        .sum();
    let mut done = 0;
    let mut reports = Vec::new();
    for (stage, st) in cfg.schedule.iter().enumerate() {
        for epoch in 0..st.epochs {
            let grouped = epoch_batches(data, st.length, cfg.batch_size, cfg.batching, &mut rng);
            let batches = grouped.len();
            let (mut sq, mut states, mut skipped) = ([0.0f64; 2], 0usize, 0usize);
            for (b, chunk) in grouped.iter().enumerate() {
                let batch = batch_windows(chunk, data, cfg, &p0, &mut rng);
                let mut g = parallel_grad(model, data, &batch, st.length, cfg.part_windows, pool.as_ref());
                // Loss (2.149): mean over steps, batch and state components.
                let scale = 1.0 / (st.length * batch.len() * dim) as f64;
                let norm: f64 =
                    g.grad.iter().map(|x| f64::from(*x) * f64::from(*x)).sum::<f64>().sqrt() * scale;
                if !(g.squared_error.is_finite() && norm.is_finite()) {
                    skipped += 1;
                } else {
                    let clip = match cfg.clip_norm {
                        Some(max) if norm > max => max / norm,
                        _ => 1.0,
                    };
                    g.grad.iter_mut().for_each(|x| *x = (f64::from(*x) * scale * clip) as f32);
                    adam.step(&mut model.params, &g.grad, &mask, cfg.learning_rate, cfg.adam);
                    sq[0] += g.squared_error_pv[0];
                    sq[1] += g.squared_error_pv[1];
                    states += g.states;
                }
                done += 1;
                let rmse = [(sq[0] / states.max(1) as f64).sqrt(), (sq[1] / states.max(1) as f64).sqrt()];
                progress(&Progress {
                    stage,
                    length: st.length,
                    epoch,
                    batch: (b + 1, batches),
                    overall: (done, total_batches),
                    rmse,
                });
            }
            let n = states.max(1) as f64;
            reports.push(EpochReport {
                length: st.length,
                epoch: reports.len() + 1,
                loss: (sq[0] + sq[1]) / (dim as f64 * n),
                rmse: [(sq[0] / n).sqrt(), (sq[1] / n).sqrt()],
                skipped_batches: skipped,
                selection_score: None,
            });
            if let Some((from, score)) = select.as_mut()
                && stage >= *from
            {
                let s = score(model);
                if let Some(r) = reports.last_mut() {
                    r.selection_score = Some(s);
                }
                if s.is_finite() && best.as_ref().is_none_or(|(b, _)| s < *b) {
                    best = Some((s, model.params.clone()));
                }
            }
        }
    }
    if let Some((_, params)) = best {
        model.params = params;
    }
    reports
}
