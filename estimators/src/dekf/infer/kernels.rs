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
/// support would be a slow library call); and how a group of eight values
/// is tested for zeros.
pub(super) trait MulAdd: Copy {
    /// `a * b + c`.
    fn mul_add(a: f32, b: f32, c: f32) -> f32;

    /// Bit `k` set where element `k` of any of the groups `xs` is not zero
    /// (NaN included).
    #[inline(always)]
    fn non_zero_mask<const V: usize>(self, xs: [&[f32; 8]; V]) -> u32 {
        let mut mask = 0u32;
        for group in xs {
            for (k, v) in group.iter().enumerate() {
                mask |= u32::from(*v != 0.0) << k;
            }
        }
        mask
    }
}

/// Fused multiply-add and vector compares (only inside [`Isa::V3`]'s
/// dispatch, with its token).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(super) struct Fused(pub(super) pulp::x86::V3);

#[cfg(target_arch = "x86_64")]
impl MulAdd for Fused {
    #[inline(always)]
    fn mul_add(a: f32, b: f32, c: f32) -> f32 {
        a.mul_add(b, c)
    }

    /// One compare and one `movemask` per group (the portable loop compiles
    /// to an extract per element).
    #[inline(always)]
    fn non_zero_mask<const V: usize>(self, xs: [&[f32; 8]; V]) -> u32 {
        use std::arch::x86_64::{__m256, _CMP_NEQ_UQ};
        let avx = self.0.avx;
        let zero = avx._mm256_setzero_ps();
        let mut any = zero;
        for group in xs {
            let v: __m256 = pulp::cast(*group);
            any = avx._mm256_or_ps(any, avx._mm256_cmp_ps::<_CMP_NEQ_UQ>(v, zero));
        }
        avx._mm256_movemask_ps(any) as u32
    }
}

/// A product, then a sum.
#[derive(Clone, Copy)]
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
/// Outputs per block of the product with tangents with AVX2: three sums of
/// 32 floats, 12 of the 16 vector registers.
pub(super) const V3_TANGENT_BLOCK: usize = 32;
/// Outputs per block of the product with tangents with SSE2: three sums of
/// 16 floats, 12 of the 16 vector registers.
pub(super) const PORTABLE_TANGENT_BLOCK: usize = 16;

/// For every mask of eight bits, the places of its set bits in order, one
/// byte each from the lowest (the bytes past its count are zero).
const SET_BITS: [u64; 256] = {
    let mut table = [0u64; 256];
    let mut mask = 0;
    while mask < 256 {
        let (mut k, mut n, mut packed) = (0, 0, 0u64);
        while k < 8 {
            if mask & (1 << k) != 0 {
                packed |= (k as u64) << (8 * n);
                n += 1;
            }
            k += 1;
        }
        table[mask] = packed;
        mask += 1;
    }
    table
};

/// The indices of the non-zero elements of `x`, in order, in `nz` (at least
/// as long as `x`); returns how many.
#[cfg(test)]
fn non_zero<M: MulAdd>(m: M, x: &[f32], nz: &mut [u32]) -> usize {
    non_zero_of_any(m, [x], nz)
}

/// The indices where any of the equally long vectors `xs` is non-zero, in
/// order, in `nz` (at least as long as them); returns how many.
/// Branch-free: each group of eight writes the eight places of its mask's
/// [`SET_BITS`] entry after the indices before it, so that the places past
/// its count are overwritten by the next group's or left past the end.
#[inline(always)]
fn non_zero_of_any<M: MulAdd, const V: usize>(m: M, xs: [&[f32]; V], nz: &mut [u32]) -> usize {
    let len = xs[0].len();
    let nz = &mut nz[..len];
    let mut n = 0;
    let whole = len / 8 * 8;
    for g in 0..len / 8 {
        let groups = xs.map(|x| -> &[f32; 8] { x[g * 8..g * 8 + 8].try_into().expect("a group of eight") });
        let mask = m.non_zero_mask(groups);
        let places = SET_BITS[mask as usize];
        // n <= 8 g, so the eight places are inside the list.
        let out: &mut [u32; 8] = (&mut nz[n..n + 8]).try_into().expect("eight places");
        for (k, o) in out.iter_mut().enumerate() {
            *o = (g * 8) as u32 + ((places >> (8 * k)) & 0xff) as u32;
        }
        n += mask.count_ones() as usize;
    }
    for i in whole..len {
        nz[n] = i as u32;
        n += usize::from(xs.iter().any(|x| x[i] != 0.0));
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
    isa: M,
    m: &[f32],
    init: Option<&[f32]>,
    x: &[f32],
    y: &mut [f32],
    nz: &mut [u32],
) {
    let n = y.len();
    debug_assert_eq!(m.len(), n * x.len());
    let count = non_zero_of_any(isa, [x], nz);
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

/// `y = b + M x` and the tangents `t_y = M t_x` of the two tangents of `x`
/// (the derivatives of `x` with respect to two inputs), for the matrix `m`
/// stored as `x.len()` contiguous columns of `y.len()` elements: forward-mode
/// differentiation, each weight read once for the three products. An input
/// is skipped only when its value and both tangents are zero (after a ReLU,
/// the inputs it zeroed), so `y` is the sum [`mat_vec`] computes, term for
/// term, in the same order. `nz` is scratch, at least `x.len()` long.
#[inline(always)]
pub(super) fn mat_vec_tangents<M: MulAdd, const B: usize>(
    isa: M,
    m: &[f32],
    bias: &[f32],
    [x, t0, t1]: [&[f32]; 3],
    [y, u0, u1]: [&mut [f32]; 3],
    nz: &mut [u32],
) {
    let n = y.len();
    debug_assert_eq!(m.len(), n * x.len());
    debug_assert!(t0.len() == x.len() && t1.len() == x.len());
    debug_assert!(u0.len() == n && u1.len() == n);
    let count = non_zero_of_any(isa, [x, t0, t1], nz);
    let nz = &nz[..count];
    let mut o = 0;
    while o + B <= n {
        let mut acc: [f32; B] = bias[o..o + B].try_into().expect("a whole block");
        let (mut acc0, mut acc1) = ([0.0f32; B], [0.0f32; B]);
        for &i in nz {
            let i = i as usize;
            let (xi, a, b) = (x[i], t0[i], t1[i]);
            let c: &[f32; B] = m[i * n + o..i * n + o + B].try_into().expect("a whole block");
            for k in 0..B {
                acc[k] = M::mul_add(c[k], xi, acc[k]);
                acc0[k] = M::mul_add(c[k], a, acc0[k]);
                acc1[k] = M::mul_add(c[k], b, acc1[k]);
            }
        }
        y[o..o + B].copy_from_slice(&acc);
        u0[o..o + B].copy_from_slice(&acc0);
        u1[o..o + B].copy_from_slice(&acc1);
        o += B;
    }
    if o < n {
        let (y, u0, u1) = (&mut y[o..], &mut u0[o..], &mut u1[o..]);
        y.copy_from_slice(&bias[o..]);
        u0.fill(0.0);
        u1.fill(0.0);
        for &i in nz {
            let i = i as usize;
            let (xi, a, b) = (x[i], t0[i], t1[i]);
            for (k, w) in m[i * n + o..(i + 1) * n].iter().enumerate() {
                y[k] = M::mul_add(*w, xi, y[k]);
                u0[k] = M::mul_add(*w, a, u0[k]);
                u1[k] = M::mul_add(*w, b, u1[k]);
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
                mat_vec::<_, PORTABLE_BLOCK>(Separate, &m, init, &x, &mut got, &mut nz);
                got_fused.copy_from_slice(&got);
                #[cfg(target_arch = "x86_64")]
                if let Some(simd) = pulp::x86::V3::try_new() {
                    mat_vec::<_, V3_BLOCK>(Fused(simd), &m, init, &x, &mut got_fused, &mut nz);
                }
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
                let n = non_zero(Separate, &x, &mut nz);
                assert_eq!(&nz[..n], &want[..], "length {len}, pattern {pattern}");
                #[cfg(target_arch = "x86_64")]
                if let Some(simd) = pulp::x86::V3::try_new() {
                    let mut nz = vec![u32::MAX; len];
                    let n = non_zero(Fused(simd), &x, &mut nz);
                    assert_eq!(&nz[..n], &want[..], "AVX2, length {len}, pattern {pattern}");
                }
            }
        }
    }

    /// The list over several vectors is where any of them is non-zero,
    /// -0.0 counting as zero and NaN as non-zero, for the portable and the
    /// vector mask; catches a mask of one vector only, or a compare that
    /// drops NaN (which must propagate, not vanish).
    #[test]
    fn the_list_of_several_vectors_is_the_union_of_their_non_zeros() {
        let len = 27;
        let x: Vec<f32> = (0..len).map(|i| if i % 4 == 0 { 1.5 } else { -0.0 }).collect();
        let t0: Vec<f32> = (0..len).map(|i| if i % 5 == 1 { -2.0 } else { 0.0 }).collect();
        let t1: Vec<f32> = (0..len).map(|i| if i == 10 || i == 26 { f32::NAN } else { 0.0 }).collect();
        let want: Vec<u32> = (0..len as u32)
            .filter(|&i| {
                let i = i as usize;
                i.is_multiple_of(4) || i % 5 == 1 || i == 10 || i == 26
            })
            .collect();
        let mut nz = vec![u32::MAX; len];
        let n = non_zero_of_any(Separate, [&x, &t0, &t1], &mut nz);
        assert_eq!(&nz[..n], &want[..]);
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = pulp::x86::V3::try_new() {
            let mut nz = vec![u32::MAX; len];
            let n = non_zero_of_any(Fused(simd), [&x, &t0, &t1], &mut nz);
            assert_eq!(&nz[..n], &want[..], "AVX2");
        }
    }

    /// The product with tangents: its value is [`mat_vec`]'s bit for bit
    /// (the same terms in the same order), its tangents the plain sums, for
    /// whole blocks and a tail, with an input that is zero while its
    /// tangent is not (a tanh at 0: skipping it would lose the tangent).
    #[test]
    fn the_product_with_tangents_is_the_product_of_each_vector() {
        for (outputs, inputs) in [(64, 64), (70, 5), (12, 12), (40, 2), (1, 3)] {
            let m: Vec<f32> = (0..outputs * inputs).map(|k| ((k * 37 % 101) as f32 - 50.0) / 25.0).collect();
            let b: Vec<f32> = (0..outputs).map(|k| k as f32 * 0.1 - 1.0).collect();
            let x: Vec<f32> =
                (0..inputs).map(|i| if i % 3 == 1 { 0.0 } else { i as f32 * 0.3 - 0.7 }).collect();
            let t0: Vec<f32> =
                (0..inputs).map(|i| if i % 2 == 0 { 0.0 } else { 1.0 - i as f32 * 0.1 }).collect();
            let t1: Vec<f32> =
                (0..inputs).map(|i| if i % 3 == 2 { 0.0 } else { 0.5 + i as f32 * 0.2 }).collect();
            let zeros = vec![0.0f32; outputs];
            let want = [reference(&m, &b, &x), reference(&m, &zeros, &t0), reference(&m, &zeros, &t1)];
            let mut nz = vec![0u32; inputs];
            let check = |name: &str, got: [Vec<f32>; 3], value: Vec<f32>| {
                assert_eq!(got[0], value, "{name} {outputs}x{inputs}: the value differs from mat_vec's");
                for (w, g) in want.iter().zip(&got) {
                    for o in 0..outputs {
                        assert!((f64::from(g[o]) - w[o]).abs() < 1e-4 * (1.0 + w[o].abs()), "{name} {o}");
                    }
                }
            };
            let mut value = vec![f32::NAN; outputs];
            let mut got = [vec![f32::NAN; outputs], vec![f32::NAN; outputs], vec![f32::NAN; outputs]];
            mat_vec::<_, PORTABLE_BLOCK>(Separate, &m, Some(&b), &x, &mut value, &mut nz);
            let [g0, g1, g2] = &mut got;
            mat_vec_tangents::<_, PORTABLE_TANGENT_BLOCK>(
                Separate,
                &m,
                &b,
                [&x, &t0, &t1],
                [g0, g1, g2],
                &mut nz,
            );
            check("portable", got, value);
            #[cfg(target_arch = "x86_64")]
            if let Some(simd) = pulp::x86::V3::try_new() {
                let mut value = vec![f32::NAN; outputs];
                let mut got = [vec![f32::NAN; outputs], vec![f32::NAN; outputs], vec![f32::NAN; outputs]];
                mat_vec::<_, V3_BLOCK>(Fused(simd), &m, Some(&b), &x, &mut value, &mut nz);
                let [g0, g1, g2] = &mut got;
                mat_vec_tangents::<_, V3_TANGENT_BLOCK>(
                    Fused(simd),
                    &m,
                    &b,
                    [&x, &t0, &t1],
                    [g0, g1, g2],
                    &mut nz,
                );
                check("AVX2", got, value);
            }
        }
    }

    #[test]
    fn dot_counts_the_elements_past_the_last_group_of_eight() {
        let a: Vec<f32> = (0..13).map(|i| i as f32 * 0.5 - 2.0).collect();
        let b: Vec<f32> = (0..13).map(|i| 1.0 + i as f32).collect();
        let naive: f32 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
        #[cfg(target_arch = "x86_64")]
        let fused = dot::<Fused>(&a, &b);
        #[cfg(not(target_arch = "x86_64"))]
        let fused = dot::<Separate>(&a, &b);
        for d in [dot::<Separate>(&a, &b), fused] {
            assert!((d - naive).abs() < 1e-4, "{d} vs {naive}");
        }
    }
}
