//! A batch's gradient on any number of threads with the same bits: the
//! batch splits into parts of a fixed number of windows, each part's
//! gradient is computed on whichever thread rayon gives it, and the parts'
//! gradients are added along a fixed binary tree over the part index. The
//! parts and the tree depend only on the batch and the part size, never on
//! the threads or on scheduling, so the floating-point sums, and with them
//! the model, are the same on 1, 2, 3 or 32 threads; a batch of `B`
//! windows in parts of `w` keeps up to `ceil(B / w)` threads busy.

use super::batch::{BatchGrad, Sequence, Window};
use super::bptt::batch_grad;
use super::model::DekfModel;

/// Windows per part of a batch's gradient (see [`super::TrainConfig::part_windows`]).
///
/// 16 keeps the matrix products 16 windows wide, where they are cheapest
/// per window, and keeps the models trained before the thin kernels: a
/// batch of 32 keeps 2 threads busy. With the thin kernels of `thin.rs`,
/// thinner parts cost per window, on one thread, 1.23x (4 windows), 1.51x
/// (2) and 1.95x (1) as much (docs/dekf.md); on many cores `train
/// --part-windows 2` keeps 16 threads busy at batch 32. The part size is
/// written into the model (it changes the sums' rounding), never taken
/// from the thread count. Compare with `slidetrack bench --what
/// dekf-training --part-windows 16,4,2,1`.
pub const DEFAULT_PART_WINDOWS: usize = 16;

/// Adds `b` into `a`: the squared errors and state counts, and the
/// gradient element by element (`a + b` in that order, so that a fixed
/// tree of these additions fixes every rounding).
pub fn add_into(a: &mut BatchGrad, b: &BatchGrad) {
    a.squared_error += b.squared_error;
    a.squared_error_pv[0] += b.squared_error_pv[0];
    a.squared_error_pv[1] += b.squared_error_pv[1];
    a.states += b.states;
    for (x, y) in a.grad.iter_mut().zip(&b.grad) {
        *x += y;
    }
}

/// The sum of `count` leaves along the fixed tree: one leaf is itself;
/// more are split at `count / 2` (the first half smaller or equal), both
/// halves summed (in parallel through `rayon::join`), and the second added
/// into the first. `leaf(i)` makes leaf `i`, `0 <= i < count`.
///
/// `count` must be at least 1.
pub fn tree_sum<L>(first: usize, count: usize, leaf: &L) -> BatchGrad
where
    L: Fn(usize) -> BatchGrad + Sync,
{
    if count <= 1 {
        return leaf(first);
    }
    let half = count / 2;
    let (mut left, right) =
        rayon::join(|| tree_sum(first, half, leaf), || tree_sum(first + half, count - half, leaf));
    add_into(&mut left, &right);
    left
}

/// Gradient of the batch `windows` in parts of `part_windows` windows (at
/// least 1), the parts computed on `pool` (rayon's global pool when `None`)
/// and summed along [`tree_sum`]'s tree: the same bits whatever the number
/// of threads. An empty batch has a zero gradient.
pub fn parallel_grad(
    model: &DekfModel,
    data: &[Sequence],
    windows: &[Window],
    length: usize,
    part_windows: usize,
    pool: Option<&rayon::ThreadPool>,
) -> BatchGrad {
    let part_windows = part_windows.max(1);
    let parts = windows.len().div_ceil(part_windows);
    if parts == 0 {
        return BatchGrad {
            squared_error: 0.0,
            squared_error_pv: [0.0; 2],
            states: 0,
            grad: vec![0.0; model.params.len()],
        };
    }
    let leaf = |i: usize| {
        let end = ((i + 1) * part_windows).min(windows.len());
        batch_grad(model, data, &windows[i * part_windows..end], length)
    };
    let sum = || tree_sum(0, parts, &leaf);
    match pool {
        Some(pool) => pool.install(sum),
        None => sum(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leaf(g: f32) -> BatchGrad {
        BatchGrad {
            squared_error: f64::from(g),
            squared_error_pv: [f64::from(g), 0.0],
            states: 1,
            grad: vec![g],
        }
    }

    /// The tree is `((0 + 1) + (2 + (3 + 4)))` for five leaves, whatever
    /// the threads: values chosen so that any other order of the additions
    /// (left to right, or a split at another index) rounds differently in
    /// `f32`. Catches a reduction whose shape follows the threads or the
    /// scheduling (rayon's `reduce`/`sum` split where work is stolen).
    #[test]
    fn the_parts_are_summed_along_one_fixed_tree_on_any_number_of_threads() {
        let values = [1.0e8f32, 3.0, -1.0e8, 3.0, 1.0];
        let expected = (values[0] + values[1]) + (values[2] + (values[3] + values[4]));
        let left_to_right = values.iter().fold(0.0f32, |a, b| a + b);
        assert_ne!(expected.to_bits(), left_to_right.to_bits(), "the values must tell the orders apart");
        for threads in [1, 2, 3, 5] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("a pool");
            let sum = pool.install(|| tree_sum(0, values.len(), &|i| leaf(values[i])));
            assert_eq!(sum.grad[0].to_bits(), expected.to_bits(), "{threads} threads");
            assert_eq!(sum.states, 5);
        }
    }
}
