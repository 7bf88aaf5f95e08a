//! The inner loops of the online path ([`super::FastNet`]), written once and
//! compiled twice: for AVX2 with fused multiply-adds where the CPU has them
//! (chosen at run time through `pulp`'s safe dispatch, [`Isa`]), and for the
//! build's baseline (SSE2 on x86-64) elsewhere.
//!
//! A matrix-vector product `y = b + sum_i x_i w_i` over the columns `w_i`
//! is register-blocked: `B` outputs at a time stay in a local array (that
//! the compiler keeps in vector registers) while every non-zero input's
//! column is added, and are stored once. The non-zero inputs are listed
//! first, without branches, so the loop over them has no unpredictable
//! branch (after a ReLU about half the inputs are zero). The reverse
//! product `W^T g` is the same kernel on the transposed matrix.

/// How a multiply-add is computed: fused (one rounding) where the CPU has
/// FMA, a product and a sum otherwise (a fused one without hardware
/// support would be a slow library call).
pub(super) trait MulAdd {
    /// `a * b + c`.
    fn mul_add(a: f32, b: f32, c: f32) -> f32;
}

/// Fused multiply-add (only inside [`Isa::V3`]'s dispatch).
pub(super) struct Fused;

impl MulAdd for Fused {
    #[inline(always)]
    fn mul_add(a: f32, b: f32, c: f32) -> f32 {
        a.mul_add(b, c)
    }
}

/// A product, then a sum.
pub(super) struct Separate;

impl MulAdd for Separate {
    #[inline(always)]
    fn mul_add(a: f32, b: f32, c: f32) -> f32 {
        a * b + c
    }
}

/// The instruction set the kernels run with, found once per network.
#[derive(Clone, Copy, Debug)]
pub(super) enum Isa {
    /// AVX2 and FMA (x86-64-v3).
    #[cfg(target_arch = "x86_64")]
    V3(pulp::x86::V3),
    /// The build's baseline.
    Portable,
}

impl Isa {
    /// The best the running CPU supports.
    pub(super) fn detect() -> Isa {
        #[cfg(target_arch = "x86_64")]
        if let Some(v3) = pulp::x86::V3::try_new() {
            return Isa::V3(v3);
        }
        Isa::Portable
    }
}

/// Outputs per block with AVX2: 64 floats, 8 of the 16 vector registers.
pub(super) const V3_BLOCK: usize = 64;
/// Outputs per block with SSE2: 32 floats, 8 of the 16 vector registers.
pub(super) const PORTABLE_BLOCK: usize = 32;

/// The indices of the non-zero elements of `x`, in order, in `nz` (at least
/// as long as `x`); returns how many. Branch-free: in each group of eight,
/// every element's index is written where it would go were it non-zero
/// (after the non-zero ones before it), so that a zero one's is
/// overwritten by the next non-zero one's or left past the end; the places
/// do not depend on each other, only on the group's mask.
#[inline(always)]
fn non_zero(x: &[f32], nz: &mut [u32]) -> usize {
    let nz = &mut nz[..x.len()];
    let mut n = 0;
    let groups = x.chunks_exact(8);
    let tail = groups.remainder();
    for (g, group) in groups.enumerate() {
        let mut mask = 0u32;
        for (k, v) in group.iter().enumerate() {
            mask |= u32::from(*v != 0.0) << k;
        }
        for k in 0..8 {
            let place = n + (mask & ((1 << k) - 1)).count_ones() as usize;
            nz[place] = (g * 8 + k) as u32;
        }
        n += mask.count_ones() as usize;
    }
    let start = x.len() - tail.len();
    for (i, v) in tail.iter().enumerate() {
        nz[n] = (start + i) as u32;
        n += usize::from(*v != 0.0);
    }
    n
}

/// `y = init + M x` for the matrix `m` stored as `x.len()` contiguous
/// columns of `y.len()` elements, `init` the bias (or `None` for zero),
/// adding the columns in input order (so each output is the same sum as a
/// column-by-column loop) and skipping zero inputs. `nz` is scratch, at
/// least `x.len()` long.
#[inline(always)]
pub(super) fn mat_vec<M: MulAdd, const B: usize>(
    m: &[f32],
    init: Option<&[f32]>,
    x: &[f32],
    y: &mut [f32],
    nz: &mut [u32],
) {
    let n = y.len();
    debug_assert_eq!(m.len(), n * x.len());
    let count = non_zero(x, nz);
    let nz = &nz[..count];
    let mut o = 0;
    while o + B <= n {
        let mut acc = [0.0f32; B];
        if let Some(b) = init {
            acc.copy_from_slice(&b[o..o + B]);
        }
        for &i in nz {
            let i = i as usize;
            let xi = x[i];
            let c: &[f32; B] = m[i * n + o..i * n + o + B].try_into().expect("a whole block");
            for k in 0..B {
                acc[k] = M::mul_add(c[k], xi, acc[k]);
            }
        }
        y[o..o + B].copy_from_slice(&acc);
        o += B;
    }
    if o < n {
        let y = &mut y[o..];
        match init {
            Some(b) => y.copy_from_slice(&b[o..]),
            None => y.fill(0.0),
        }
        for &i in nz {
            let i = i as usize;
            let xi = x[i];
            for (yo, w) in y.iter_mut().zip(&m[i * n + o..(i + 1) * n]) {
                *yo = M::mul_add(*w, xi, *yo);
            }
        }
    }
}

/// `a . b` in eight lanes (vectorised), plus the elements past the last
/// whole group of eight when the length is not a multiple of it.
#[inline(always)]
pub(super) fn dot<M: MulAdd>(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f32 = ca.remainder().iter().zip(cb.remainder()).map(|(x, y)| x * y).sum();
    for (ca, cb) in ca.zip(cb) {
        for l in 0..8 {
            acc[l] = M::mul_add(ca[l], cb[l], acc[l]);
        }
    }
    acc.iter().sum::<f32>() + tail
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `y = b + M x`, column by column, in f64.
    fn reference(m: &[f32], b: &[f32], x: &[f32]) -> Vec<f64> {
        let n = b.len();
        (0..n)
            .map(|o| {
                f64::from(b[o]) + (0..x.len()).map(|i| f64::from(m[i * n + o]) * f64::from(x[i])).sum::<f64>()
            })
            .collect()
    }

    /// Every path of the kernel (whole blocks, the outputs past the last
    /// block, zero inputs skipped, no bias) against the plain sum; catches
    /// a wrong column offset in a block or in the tail.
    #[test]
    fn the_blocked_product_equals_the_plain_one_for_every_shape() {
        for (outputs, inputs) in [(64, 64), (70, 5), (12, 12), (2, 64), (1, 3), (130, 7)] {
            let m: Vec<f32> = (0..outputs * inputs).map(|k| ((k * 37 % 101) as f32 - 50.0) / 25.0).collect();
            let b: Vec<f32> = (0..outputs).map(|k| k as f32 * 0.1 - 1.0).collect();
            let x: Vec<f32> =
                (0..inputs).map(|i| if i % 3 == 1 { 0.0 } else { i as f32 * 0.3 - 0.7 }).collect();
            let want = reference(&m, &b, &x);
            let mut nz = vec![0u32; inputs];
            for bias in [true, false] {
                let mut got = vec![f32::NAN; outputs];
                let mut got_fused = vec![f32::NAN; outputs];
                let init = bias.then_some(&b[..]);
                mat_vec::<Separate, PORTABLE_BLOCK>(&m, init, &x, &mut got, &mut nz);
                mat_vec::<Fused, V3_BLOCK>(&m, init, &x, &mut got_fused, &mut nz);
                for o in 0..outputs {
                    let w = want[o] - if bias { 0.0 } else { f64::from(b[o]) };
                    for g in [got[o], got_fused[o]] {
                        assert!(
                            (f64::from(g) - w).abs() < 1e-4 * (1.0 + w.abs()),
                            "{outputs}x{inputs} {o}: {g} vs {w}"
                        );
                    }
                }
            }
        }
    }

    /// Groups of eight all zero, all non-zero and mixed, and a tail; the
    /// indices a zero element wrote must all be overwritten or past the
    /// count.
    #[test]
    fn the_non_zero_list_is_the_non_zero_indices_in_order() {
        for len in [0, 3, 8, 16, 21, 64] {
            for pattern in 0..4 {
                let x: Vec<f32> = (0..len)
                    .map(|i| match pattern {
                        0 => 0.0,
                        1 => 1.0 + i as f32,
                        2 => {
                            if (i * 7) % 5 < 2 {
                                0.0
                            } else {
                                -0.5
                            }
                        }
                        _ => {
                            if i / 8 % 2 == 0 {
                                0.0
                            } else {
                                2.0
                            }
                        }
                    })
                    .collect();
                let want: Vec<u32> = (0..len as u32).filter(|&i| x[i as usize] != 0.0).collect();
                let mut nz = vec![u32::MAX; len];
                let n = non_zero(&x, &mut nz);
                assert_eq!(&nz[..n], &want[..], "length {len}, pattern {pattern}");
            }
        }
    }

    #[test]
    fn dot_counts_the_elements_past_the_last_group_of_eight() {
        let a: Vec<f32> = (0..13).map(|i| i as f32 * 0.5 - 2.0).collect();
        let b: Vec<f32> = (0..13).map(|i| 1.0 + i as f32).collect();
        let naive: f32 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
        for d in [dot::<Separate>(&a, &b), dot::<Fused>(&a, &b)] {
            assert!((d - naive).abs() < 1e-4, "{d} vs {naive}");
        }
    }
}
