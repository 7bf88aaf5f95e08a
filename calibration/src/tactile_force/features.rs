//! The terms of a taxel's map and the map itself.

use serde::{Deserialize, Serialize};

/// Which terms of the tared counts a taxel's map uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ForceModelKind {
    /// `F = offset + M c`: a 3x3 matrix (gains and cross-talk) and an offset.
    Linear,
    /// The linear terms and the six second-order terms
    /// `[cx², cy², cz², cx cy, cx cz, cy cz]` (the magnet's inverse-cube
    /// normal response, shear sensitivity growing with indentation).
    #[default]
    Quadratic,
}

impl ForceModelKind {
    /// The name in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ForceModelKind::Linear => "linear",
            ForceModelKind::Quadratic => "quadratic",
        }
    }

    /// Terms per output axis, the constant included.
    pub fn terms(self) -> usize {
        match self {
            ForceModelKind::Linear => 4,
            ForceModelKind::Quadratic => 10,
        }
    }

    /// The terms of `counts` (tared counts `[x, y, z]`): `1, cx, cy, cz`,
    /// then for `quadratic` `cx², cy², cz², cx cy, cx cz, cy cz`.
    pub fn features(self, counts: [f64; 3], out: &mut Vec<f64>) {
        let [x, y, z] = counts;
        out.clear();
        out.extend([1.0, x, y, z]);
        if self == ForceModelKind::Quadratic {
            out.extend(second_order(counts));
        }
    }
}

/// `[cx², cy², cz², cx cy, cx cz, cy cz]`.
fn second_order([x, y, z]: [f64; 3]) -> [f64; 6] {
    [x * x, y * y, z * z, x * y, x * z, y * z]
}

/// The map of one taxel from tared counts to force (N, in the taxel's frame).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TaxelForceMap {
    /// Force at zero tared counts `[x, y, z]` (N).
    pub offset_n: [f64; 3],
    /// Row `i`: the force along axis `i` per count of `[cx, cy, cz]`
    /// (N/count); off the diagonal, the cross-talk.
    pub linear_n_per_count: [[f64; 3]; 3],
    /// Row `i`: the force along axis `i` per `[cx², cy², cz², cx cy, cx cz,
    /// cy cz]` (N/count²); only in the `quadratic` model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quadratic_n_per_count2: Option<[[f64; 6]; 3]>,
}

impl TaxelForceMap {
    /// The map whose coefficients per axis are `rows` in the order of
    /// [`ForceModelKind::features`].
    pub(crate) fn from_rows(kind: ForceModelKind, rows: [&[f64]; 3]) -> TaxelForceMap {
        let quadratic = (kind == ForceModelKind::Quadratic)
            .then(|| rows.map(|r| std::array::from_fn(|k| r.get(4 + k).copied().unwrap_or(0.0))));
        TaxelForceMap {
            offset_n: rows.map(|r| r[0]),
            linear_n_per_count: rows.map(|r| [r[1], r[2], r[3]]),
            quadratic_n_per_count2: quadratic,
        }
    }

    /// The model this map is of.
    pub fn kind(&self) -> ForceModelKind {
        match self.quadratic_n_per_count2 {
            Some(_) => ForceModelKind::Quadratic,
            None => ForceModelKind::Linear,
        }
    }

    /// The force (N, `[x, y, z]` in the taxel's frame) at tared `counts`.
    pub fn force_n(&self, counts: [f64; 3]) -> [f64; 3] {
        let q = second_order(counts);
        std::array::from_fn(|i| {
            let m = &self.linear_n_per_count[i];
            let mut f = self.offset_n[i] + m[0] * counts[0] + m[1] * counts[1] + m[2] * counts[2];
            if let Some(quadratic) = &self.quadratic_n_per_count2 {
                f += quadratic[i].iter().zip(&q).map(|(a, b)| a * b).sum::<f64>();
            }
            f
        })
    }

    /// True when every coefficient is finite.
    pub fn is_finite(&self) -> bool {
        let quadratic = self.quadratic_n_per_count2.iter().flatten().flatten();
        self.offset_n
            .iter()
            .chain(self.linear_n_per_count.iter().flatten())
            .chain(quadratic)
            .all(|v| v.is_finite())
    }
}
