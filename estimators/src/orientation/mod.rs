//! Orientation in Kalman filters (thesis Sec. 2.3): Euler-angle operators
//! (Algorithm 8), unit-quaternion operators (Algorithm 9), and [`Composite`],
//! a state or measurement made of Euclidean, angular and quaternion blocks on
//! which the UKF of [`crate::ukf`] runs with those operators.

pub mod euler;
pub mod odometry;
pub mod pose;
pub mod quaternion;
pub mod symmetry;

pub use pose::PoseVelocity;
pub use symmetry::{Symmetry, rotation_error_modulo_symmetry_deg};

use nalgebra::{DVector, Quaternion, UnitQuaternion, Vector3};

use crate::EstimatorError;
use crate::ukf::Manifold;

/// One block of a [`Composite`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Component {
    /// `n` Euclidean coordinates: `+`, `-` and the weighted sum.
    Euclidean(usize),
    /// `n` angles (rad): `⊕`, `⊖` and the circular mean of Algorithm 8.
    Angles(usize),
    /// A unit quaternion stored as `(x, y, z, w)` with a 3-dimensional tangent
    /// (rotation vectors): `⊕`, `⊖` and the eigenvector mean of Algorithm 9.
    Quaternion,
}

impl Component {
    /// Coordinates stored.
    pub fn ambient(self) -> usize {
        match self {
            Component::Euclidean(n) | Component::Angles(n) => n,
            Component::Quaternion => 4,
        }
    }

    /// Degrees of freedom (size of the tangent space).
    pub fn dof(self) -> usize {
        match self {
            Component::Euclidean(n) | Component::Angles(n) => n,
            Component::Quaternion => 3,
        }
    }
}

/// A point of a product of Euclidean, angle and unit-quaternion blocks, laid
/// out by a static `layout`. Its covariance lives in the tangent space
/// (`dof` rows and columns, quaternion blocks as rotation vectors).
#[derive(Clone, Debug, PartialEq)]
pub struct Composite {
    layout: &'static [Component],
    coords: DVector<f64>,
}

impl Composite {
    /// A point from its stored coordinates (quaternions as `x, y, z, w`; they
    /// are normalised here). Fails when the length does not match the layout
    /// or a quaternion has no usable norm.
    pub fn new(layout: &'static [Component], coords: DVector<f64>) -> Result<Composite, EstimatorError> {
        let expected: usize = layout.iter().map(|c| c.ambient()).sum();
        if coords.len() != expected {
            return Err(EstimatorError::DimensionMismatch {
                what: "composite coordinates",
                expected,
                got: coords.len(),
            });
        }
        let mut point = Composite { layout, coords };
        let mut offset = 0;
        for c in layout {
            if *c == Component::Quaternion {
                let norm = point.coords.rows(offset, 4).norm();
                if !(norm.is_finite() && norm > 1e-12) {
                    return Err(EstimatorError::NonFiniteState { what: "quaternion" });
                }
                point.coords.rows_mut(offset, 4).unscale_mut(norm);
            }
            offset += c.ambient();
        }
        Ok(point)
    }

    /// A point whose coordinates the caller guarantees to match `layout`
    /// (length, unit quaternions).
    pub(crate) fn new_unchecked(layout: &'static [Component], coords: DVector<f64>) -> Composite {
        debug_assert_eq!(coords.len(), layout.iter().map(|c| c.ambient()).sum::<usize>());
        Composite { layout, coords }
    }

    /// The stored coordinates.
    pub fn coords(&self) -> &DVector<f64> {
        &self.coords
    }

    /// The layout.
    pub fn layout(&self) -> &'static [Component] {
        self.layout
    }

    /// The unit quaternion stored at coordinate `offset`.
    pub fn quaternion_at(&self, offset: usize) -> UnitQuaternion<f64> {
        let c = &self.coords;
        UnitQuaternion::new_normalize(Quaternion::new(c[offset + 3], c[offset], c[offset + 1], c[offset + 2]))
    }

    /// Three coordinates starting at `offset`.
    pub fn vector3_at(&self, offset: usize) -> Vector3<f64> {
        Vector3::new(self.coords[offset], self.coords[offset + 1], self.coords[offset + 2])
    }
}

/// Writes `q` as `(x, y, z, w)` at `offset` of `coords`.
pub fn put_quaternion(coords: &mut DVector<f64>, offset: usize, q: &UnitQuaternion<f64>) {
    let v = q.quaternion().coords; // (i, j, k, w)
    coords.rows_mut(offset, 4).copy_from(&v);
}

impl Manifold for Composite {
    fn dof(&self) -> usize {
        self.layout.iter().map(|c| c.dof()).sum()
    }

    fn oplus(&self, delta: &[f64]) -> Composite {
        let mut coords = self.coords.clone();
        let (mut a, mut d) = (0, 0);
        for c in self.layout {
            match *c {
                Component::Euclidean(n) => {
                    for k in 0..n {
                        coords[a + k] += delta[d + k];
                    }
                }
                Component::Angles(n) => {
                    for k in 0..n {
                        coords[a + k] = euler::oplus(coords[a + k], delta[d + k]);
                    }
                }
                Component::Quaternion => {
                    let omega = Vector3::new(delta[d], delta[d + 1], delta[d + 2]);
                    let q = quaternion::oplus(&self.quaternion_at(a), &omega);
                    put_quaternion(&mut coords, a, &q);
                }
            }
            a += c.ambient();
            d += c.dof();
        }
        Composite { layout: self.layout, coords }
    }

    fn ominus(&self, other: &Composite) -> DVector<f64> {
        let mut out = DVector::zeros(self.dof());
        let (mut a, mut d) = (0, 0);
        for c in self.layout {
            match *c {
                Component::Euclidean(n) => {
                    for k in 0..n {
                        out[d + k] = self.coords[a + k] - other.coords[a + k];
                    }
                }
                Component::Angles(n) => {
                    for k in 0..n {
                        out[d + k] = euler::ominus(self.coords[a + k], other.coords[a + k]);
                    }
                }
                Component::Quaternion => {
                    let w = quaternion::ominus(&self.quaternion_at(a), &other.quaternion_at(a));
                    out.rows_mut(d, 3).copy_from(&w);
                }
            }
            a += c.ambient();
            d += c.dof();
        }
        out
    }

    fn weighted_mean(points: &[Composite], weights: &[f64]) -> Option<Composite> {
        let first = points.first()?;
        if points.len() != weights.len() {
            return None;
        }
        let mut coords = DVector::zeros(first.coords.len());
        let mut a = 0;
        for c in first.layout {
            match *c {
                Component::Euclidean(n) => {
                    for (p, w) in points.iter().zip(weights) {
                        for k in 0..n {
                            coords[a + k] += w * p.coords[a + k];
                        }
                    }
                }
                Component::Angles(n) => {
                    for k in 0..n {
                        let angles: Vec<f64> = points.iter().map(|p| p.coords[a + k]).collect();
                        coords[a + k] = euler::circular_mean(&angles, weights)?;
                    }
                }
                Component::Quaternion => {
                    let qs: Vec<UnitQuaternion<f64>> = points.iter().map(|p| p.quaternion_at(a)).collect();
                    put_quaternion(&mut coords, a, &quaternion::weighted_mean(&qs, weights)?);
                }
            }
            a += c.ambient();
        }
        Some(Composite { layout: first.layout, coords })
    }

    fn is_finite(&self) -> bool {
        self.coords.iter().all(|v| v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    const LAYOUT: &[Component] = &[Component::Euclidean(2), Component::Angles(1), Component::Quaternion];

    fn point(x: f64, angle: f64, rotation: [f64; 3]) -> Composite {
        let mut coords = DVector::zeros(7);
        coords[0] = x;
        coords[1] = -x;
        coords[2] = angle;
        put_quaternion(&mut coords, 3, &UnitQuaternion::from_scaled_axis(Vector3::from(rotation)));
        Composite::new(LAYOUT, coords).unwrap()
    }

    #[test]
    fn oplus_then_ominus_gives_the_step_back() {
        let p = point(0.5, 3.0, [0.1, 0.2, -0.3]);
        let delta = [0.25, -1.0, 0.5, 0.01, -0.02, 0.03];
        let q = p.oplus(&delta);
        assert_eq!(p.dof(), 6);
        assert_relative_eq!(q.ominus(&p), DVector::from_column_slice(&delta), epsilon = 1e-12);
        // The angle wrapped past π.
        assert!(q.coords()[2] < 0.0);
    }

    #[test]
    fn the_mean_works_block_by_block() {
        let a = point(1.0, std::f64::consts::PI - 0.1, [0.0, 0.0, 0.2]);
        let b = point(3.0, -std::f64::consts::PI + 0.1, [0.0, 0.0, 0.4]);
        let m = Composite::weighted_mean(&[a, b], &[0.5, 0.5]).unwrap();
        assert_relative_eq!(m.coords()[0], 2.0, epsilon = 1e-12);
        assert_relative_eq!(m.coords()[2].abs(), std::f64::consts::PI, epsilon = 1e-12);
        assert_relative_eq!(
            quaternion::log(&m.quaternion_at(3)),
            Vector3::new(0.0, 0.0, 0.3),
            epsilon = 1e-12
        );
    }

    #[test]
    fn bad_coordinates_are_refused() {
        assert!(Composite::new(LAYOUT, DVector::zeros(6)).is_err());
        assert!(Composite::new(LAYOUT, DVector::zeros(7)).is_err(), "zero quaternion");
    }
}
