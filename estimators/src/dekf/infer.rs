//! Fast evaluation of one sample (the online path): value plus up to two
//! tangent columns, with plain loops that the compiler vectorises.

use super::params::{HIDDEN, LinearAt, NetAt};

/// Up to three columns of activations: value and two tangents.
#[derive(Clone, Copy)]
struct Cols {
    v: [[f32; HIDDEN]; 3],
    n: usize,
}

fn dot(w: &[f32], x: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let chunks = w.len() / 8;
    for k in 0..chunks {
        for l in 0..8 {
            acc[l] += w[8 * k + l] * x[8 * k + l];
        }
    }
    let mut s: f32 = acc.iter().sum();
    for k in 8 * chunks..w.len() {
        s += w[k] * x[k];
    }
    s
}

/// One network with its weights copied row-major for contiguous dot products.
#[derive(Clone, Debug)]
pub struct FastNet {
    layers: Vec<(Vec<f32>, Vec<f32>, usize, usize)>,
}

impl FastNet {
    /// Copies network `net` out of the flat parameters `p`.
    pub fn new(p: &[f32], net: &NetAt) -> FastNet {
        let layers = net
            .layers
            .iter()
            .map(|l: &LinearAt| {
                // Column-major [out, in] -> row-major.
                let mut w = vec![0.0f32; l.out * l.inp];
                for o in 0..l.out {
                    for i in 0..l.inp {
                        w[o * l.inp + i] = p[l.weight + i * l.out + o];
                    }
                }
                (w, p[l.bias..l.bias + l.out].to_vec(), l.out, l.inp)
            })
            .collect();
        FastNet { layers }
    }

    fn linear(&self, k: usize, x: &Cols, inp: &[f32]) -> Cols {
        let (w, b, out, n_in) = &self.layers[k];
        let mut y = Cols { v: [[0.0; HIDDEN]; 3], n: x.n };
        for o in 0..*out {
            let row = &w[o * n_in..(o + 1) * n_in];
            for c in 0..x.n {
                let src = if k == 0 { &inp[c * n_in..(c + 1) * n_in] } else { &x.v[c][..*n_in] };
                y.v[c][o] = dot(row, src);
            }
            y.v[0][o] += b[o];
        }
        y
    }

    fn relu(y: &mut Cols) {
        for i in 0..HIDDEN {
            if y.v[0][i] <= 0.0 {
                for c in 0..y.n {
                    y.v[c][i] = 0.0;
                }
            }
        }
    }

    fn block(&self, k: usize, h: &Cols) -> Cols {
        let mut a = self.linear(k, h, &[]);
        Self::relu(&mut a);
        let mut s = self.linear(k + 1, &a, &[]);
        for c in 0..s.n {
            for i in 0..HIDDEN {
                s.v[c][i] += h.v[c][i];
            }
        }
        Self::relu(&mut s);
        s
    }

    /// Evaluates the network on `input` (value, then tangents, each of the
    /// input size, concatenated; `columns` of them). Returns the output of
    /// each column: the value, then the Jacobian row.
    pub fn eval(&self, input: &[f32], columns: usize) -> [f32; 3] {
        let x = Cols { v: [[0.0; HIDDEN]; 3], n: columns };
        let mut h = self.linear(0, &x, input);
        Self::relu(&mut h);
        h = self.block(1, &h);
        h = self.linear(3, &h, &[]);
        for k in [4, 6, 8] {
            h = self.block(k, &h);
        }
        let y = self.linear(10, &h, &[]);
        [y.v[0][0], y.v[1][0], y.v[2][0]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dekf::mlp::forward;
    use crate::dekf::params::Layout;
    use nalgebra::DMatrix;
    use rand::SeedableRng;

    #[test]
    fn the_fast_path_equals_the_batched_forward() {
        let layout = Layout::new(6);
        let p = layout.init(&mut rand::rngs::StdRng::seed_from_u64(3));
        let fast = FastNet::new(&p, &layout.motion);
        let x = [0.7f32, -0.4];
        let mut m = DMatrix::<f32>::zeros(2, 3);
        m[(0, 0)] = x[0];
        m[(1, 0)] = x[1];
        m[(0, 1)] = 1.0;
        m[(1, 2)] = 1.0;
        let (y, _) = forward(&p, &layout.motion, m, 3, false);
        let f = fast.eval(&[x[0], x[1], 1.0, 0.0, 0.0, 1.0], 3);
        for c in 0..3 {
            assert!(
                (f[c] - y[(0, c)]).abs() < 1e-5 * (1.0 + y[(0, c)].abs()),
                "{c}: {} vs {}",
                f[c],
                y[(0, c)]
            );
        }
        let fast3 = FastNet::new(&p, &layout.feature);
        let z = [0.1f32, -2.0, 0.3, 1.5, -0.2, 0.9];
        let (y3, _) = forward(&p, &layout.feature, DMatrix::from_column_slice(6, 1, &z), 1, false);
        assert!((fast3.eval(&z, 1)[0] - y3[(0, 0)]).abs() < 1e-5);
    }
}
