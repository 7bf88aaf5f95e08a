//! [`ObjectPoints`]: the points `{A_j}` sampled on an object's surface, in the
//! object frame, with a 3D k-d tree (kiddo) for nearest-neighbour queries:
//! the projection of (4.9) in MaskUKF and the `min_k` of the ADI metric (3.55).

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::Point3;
use thiserror::Error;

use crate::orientation::Symmetry;

/// Why a point model could not be built.
#[derive(Clone, Debug, Error, PartialEq)]
#[non_exhaustive]
pub enum ModelError {
    /// No points at all.
    #[error("the object model has no points")]
    Empty,
    /// A point holds NaN or infinity.
    #[error("model point {index} is not finite: {point:?}")]
    NonFinite {
        /// Index of the point.
        index: usize,
        /// The point (m).
        point: [f64; 3],
    },
    /// The k-d tree refused the points.
    #[error("the k-d tree could not be built: {detail}")]
    Tree {
        /// kiddo's message.
        detail: String,
    },
}

/// Neighbours of the first query tried by [`ObjectPoints::nearest_cluster`].
const CLUSTER_CANDIDATES: usize = 8;

/// Points on an object's surface in the object frame (m) and their k-d tree.
pub struct ObjectPoints {
    points_in_object: Vec<Point3<f64>>,
    tree: ImmutableKdTree<f32, 3>,
    symmetry: Symmetry,
}

impl std::fmt::Debug for ObjectPoints {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ObjectPoints").field("points", &self.points_in_object.len()).finish()
    }
}

impl ObjectPoints {
    /// Builds the tree over `points_in_object` (m, object frame).
    pub fn new(points_in_object: Vec<Point3<f64>>) -> Result<ObjectPoints, ModelError> {
        if points_in_object.is_empty() {
            return Err(ModelError::Empty);
        }
        if let Some((index, p)) =
            points_in_object.iter().enumerate().find(|(_, p)| !p.iter().all(|v| v.is_finite()))
        {
            return Err(ModelError::NonFinite { index, point: [p.x, p.y, p.z] });
        }
        let coords: Vec<[f32; 3]> =
            points_in_object.iter().map(|p| [p.x as f32, p.y as f32, p.z as f32]).collect();
        let tree = ImmutableKdTree::new_from_slice(&coords)
            .map_err(|e| ModelError::Tree { detail: format!("{e:?}") })?;
        Ok(ObjectPoints { points_in_object, tree, symmetry: Symmetry::None })
    }

    /// The same points with the shape's rotational symmetry (for the
    /// metrics that discount it).
    pub fn with_symmetry(mut self, symmetry: Symmetry) -> ObjectPoints {
        self.symmetry = symmetry;
        self
    }

    /// The shape's rotational symmetry ([`Symmetry::None`] unless given).
    pub fn symmetry(&self) -> &Symmetry {
        &self.symmetry
    }

    /// The points, object frame (m).
    pub fn points(&self) -> &[Point3<f64>] {
        &self.points_in_object
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points_in_object.len()
    }

    /// Never true (a model has at least one point).
    pub fn is_empty(&self) -> bool {
        self.points_in_object.is_empty()
    }

    /// The model point nearest to `query_in_object` (object frame, m). The
    /// tree works in f32; the returned point is the exact f64 model point.
    pub fn nearest(&self, query_in_object: &Point3<f64>) -> &Point3<f64> {
        let q = [query_in_object.x as f32, query_in_object.y as f32, query_in_object.z as f32];
        let found = self.tree.query(&q).nearest_one::<SquaredEuclidean<f32>>().execute();
        &self.points_in_object[found.item as usize]
    }

    /// The nearest model point (its index) of each of `queries` (object
    /// frame, m), exactly, for queries that lie close together, such as one
    /// measured point seen from every sigma point of a filter. The `K`
    /// nearest neighbours of `queries[0]` are found once; a query within
    /// `δ` of it, with `2δ <= r_K - r_1` (the radii of the farthest and
    /// nearest of those neighbours), has its nearest neighbour among them
    /// (any point outside the ball of radius `r_K` is at least `r_K - δ`
    /// away, the nearest neighbour at most `r_1 + δ`); other queries use the
    /// tree. Indices go to `out`, one per query.
    pub fn nearest_cluster(&self, queries: &[Point3<f64>], out: &mut Vec<usize>) {
        out.clear();
        let Some(centre) = queries.first() else {
            return;
        };
        let k = CLUSTER_CANDIDATES.min(self.points_in_object.len());
        let Some(k_nonzero) = std::num::NonZero::new(k) else {
            return;
        };
        let c = [centre.x as f32, centre.y as f32, centre.z as f32];
        let found = self.tree.query(&c).nearest_n::<SquaredEuclidean<f32>>(k_nonzero).execute();
        let candidates: Vec<usize> = found.iter().map(|f| f.item as usize).collect();
        let distance = |i: usize, q: &Point3<f64>| (self.points_in_object[i] - q).norm();
        let r_1 = candidates.iter().map(|i| distance(*i, centre)).fold(f64::INFINITY, f64::min);
        let r_k = if k == self.points_in_object.len() {
            f64::INFINITY
        } else {
            candidates.iter().map(|i| distance(*i, centre)).fold(0.0, f64::max)
        };
        // f32 rounding in the tree: keep a margin.
        let reach = (r_k - r_1) / 2.0 - 1e-6;
        // Candidates as structure-of-arrays, for a vectorisable distance loop.
        let xs: Vec<f64> = candidates.iter().map(|i| self.points_in_object[*i].x).collect();
        let ys: Vec<f64> = candidates.iter().map(|i| self.points_in_object[*i].y).collect();
        let zs: Vec<f64> = candidates.iter().map(|i| self.points_in_object[*i].z).collect();
        let mut d2 = vec![0.0f64; k];
        for q in queries {
            let delta = (q - centre).norm();
            let index = if delta <= reach {
                for n in 0..k {
                    d2[n] = (xs[n] - q.x) * (xs[n] - q.x)
                        + (ys[n] - q.y) * (ys[n] - q.y)
                        + (zs[n] - q.z) * (zs[n] - q.z);
                }
                let best = d2
                    .iter()
                    .enumerate()
                    .fold((f64::INFINITY, 0), |b, (n, d)| if *d < b.0 { (*d, n) } else { b });
                candidates[best.1]
            } else {
                let qf = [q.x as f32, q.y as f32, q.z as f32];
                self.tree.query(&qf).nearest_one::<SquaredEuclidean<f32>>().execute().item as usize
            };
            out.push(index);
        }
    }

    /// The radius (m) of the smallest origin-centred sphere holding the model.
    pub fn radius(&self) -> f64 {
        self.points_in_object.iter().map(|p| p.coords.norm()).fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_matches_brute_force() {
        let points: Vec<Point3<f64>> = (0..500)
            .map(|i| {
                let t = i as f64;
                Point3::new((t * 0.37).sin() * 0.1, (t * 0.91).cos() * 0.05, (t * 0.13).sin() * 0.08)
            })
            .collect();
        let model = ObjectPoints::new(points.clone()).unwrap();
        for k in 0..200 {
            let t = k as f64;
            let q = Point3::new((t * 1.7).sin() * 0.12, (t * 0.3).cos() * 0.07, (t * 2.1).cos() * 0.1);
            let brute = points.iter().map(|p| (p - q).norm()).fold(f64::INFINITY, f64::min);
            assert!(((model.nearest(&q) - q).norm() - brute).abs() < 1e-6);
        }
    }

    #[test]
    fn cluster_queries_are_exact() {
        let points: Vec<Point3<f64>> = (0..2000)
            .map(|i| {
                let t = i as f64;
                Point3::new((t * 0.37).sin() * 0.1, (t * 0.91).cos() * 0.05, (t * 0.13).sin() * 0.08)
            })
            .collect();
        let model = ObjectPoints::new(points.clone()).unwrap();
        let mut out = Vec::new();
        for spread in [0.0005, 0.003, 0.02, 0.2] {
            for k in 0..50 {
                let t = k as f64;
                let centre =
                    Point3::new((t * 1.7).sin() * 0.1, (t * 0.3).cos() * 0.05, (t * 2.1).cos() * 0.08);
                let queries: Vec<Point3<f64>> = (0..25)
                    .map(|i| {
                        centre
                            + nalgebra::Vector3::new(
                                (i as f64).sin(),
                                (2.0 * i as f64).cos(),
                                (0.7 * i as f64).sin(),
                            ) * spread
                    })
                    .collect();
                model.nearest_cluster(&queries, &mut out);
                for (q, i) in queries.iter().zip(&out) {
                    let brute = points.iter().map(|p| (p - q).norm()).fold(f64::INFINITY, f64::min);
                    assert!(((points[*i] - q).norm() - brute).abs() < 1e-6, "spread {spread}");
                }
            }
        }
    }

    #[test]
    fn bad_models_are_refused() {
        assert_eq!(ObjectPoints::new(vec![]).unwrap_err(), ModelError::Empty);
        let err = ObjectPoints::new(vec![Point3::origin(), Point3::new(f64::NAN, 0.0, 0.0)]).unwrap_err();
        assert!(matches!(err, ModelError::NonFinite { index: 1, .. }));
    }
}
