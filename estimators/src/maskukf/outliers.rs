//! Outlier rejection of MaskUKF (thesis Sec. 4.1.5, (4.12)-(4.13)).
//!
//! Each measured point `z_i` is paired with its furthest point `z_f` in the
//! cloud; `π_i`, `π_f` are their projections on the object at the previous
//! estimate. On a clean cloud the distance between the points is about the
//! distance between the projections; when `|d_if - d^π_if| > δ` (4.12) the one
//! further from its projection is an outlier (4.13) and is removed, and the
//! point is paired again with its new furthest point, until every remaining
//! point has been visited.
//!
//! The furthest point is found exactly with a triangle-inequality bound: with
//! `c` the centroid, `|z_i - z_k| <= |z_i - c| + |z_k - c|`, so scanning the
//! points by decreasing `|z_k - c|` stops as soon as the bound cannot beat the
//! best distance found (a few candidates for compact clouds).

use nalgebra::Point3;

/// Marks outliers; returns the indices of the points kept, in order.
///
/// `points` are the measured points and `projections` their nearest points on
/// the object at the previous estimate (same length, camera frame, m);
/// `threshold_m` is `δ^outlier`.
pub fn reject_outliers(points: &[Point3<f64>], projections: &[Point3<f64>], threshold_m: f64) -> Vec<usize> {
    let n = points.len().min(projections.len());
    if n < 2 {
        return (0..n).collect();
    }
    let centroid = points[..n].iter().fold(Point3::origin(), |c, p| c + p.coords / n as f64);
    let radius: Vec<f64> = points[..n].iter().map(|p| (p - centroid).norm()).collect();
    let mut by_radius: Vec<usize> = (0..n).collect();
    by_radius.sort_by(|a, b| radius[*b].total_cmp(&radius[*a]));
    let residual: Vec<f64> = (0..n).map(|i| (points[i] - projections[i]).norm()).collect();
    let mut removed = vec![false; n];
    for i in 0..n {
        while !removed[i] {
            let Some(f) = furthest(i, points, &radius, &by_radius, &removed) else {
                break;
            };
            let d = (points[i] - points[f]).norm();
            let d_pi = (projections[i] - projections[f]).norm();
            if (d - d_pi).abs() <= threshold_m {
                break; // (4.12) holds: the pair is consistent.
            }
            // (4.13): the point further from its projection is the outlier.
            let outlier = if residual[i] > residual[f] { i } else { f };
            removed[outlier] = true;
        }
    }
    (0..n).filter(|i| !removed[*i]).collect()
}

/// The index of the point furthest from `points[i]` among those not removed.
fn furthest(
    i: usize,
    points: &[Point3<f64>],
    radius: &[f64],
    by_radius: &[usize],
    removed: &[bool],
) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for &k in by_radius {
        if let Some((_, d)) = best
            && radius[i] + radius[k] <= d
        {
            break;
        }
        if k == i || removed[k] {
            continue;
        }
        let d = (points[i] - points[k]).norm();
        if best.is_none_or(|(_, b)| d > b) {
            best = Some((k, d));
        }
    }
    best.map(|(k, _)| k)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points on a plane patch whose projections are themselves, plus stray
    /// points off the surface whose projections are on the plane.
    #[test]
    fn stray_points_are_rejected_and_surface_points_kept() {
        let mut points = Vec::new();
        for i in 0..20 {
            for j in 0..20 {
                points.push(Point3::new(i as f64 * 0.005, j as f64 * 0.005, 0.6));
            }
        }
        let mut projections = points.clone();
        let strays =
            [Point3::new(0.05, 0.05, 0.75), Point3::new(0.0, 0.09, 0.40), Point3::new(0.09, 0.0, 0.66)];
        for s in strays {
            points.push(s);
            projections.push(Point3::new(s.x, s.y, 0.6));
        }
        let kept = reject_outliers(&points, &projections, 0.01);
        assert_eq!(kept, (0..400).collect::<Vec<_>>());
    }

    #[test]
    fn the_furthest_point_search_is_exact() {
        let points: Vec<Point3<f64>> = (0..300)
            .map(|i| Point3::new((i as f64 * 0.7).sin(), (i as f64 * 1.3).cos(), (i as f64 * 0.1).sin()))
            .collect();
        let n = points.len();
        let centroid = points.iter().fold(Point3::origin(), |c, p| c + p.coords / n as f64);
        let radius: Vec<f64> = points.iter().map(|p| (p - centroid).norm()).collect();
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|a, b| radius[*b].total_cmp(&radius[*a]));
        let removed = vec![false; n];
        for i in 0..n {
            let f = furthest(i, &points, &radius, &order, &removed).unwrap();
            let brute =
                (0..n).filter(|k| *k != i).map(|k| (points[i] - points[k]).norm()).fold(0.0, f64::max);
            assert!(((points[i] - points[f]).norm() - brute).abs() < 1e-12);
        }
    }

    #[test]
    fn tiny_clouds_pass_through() {
        assert!(reject_outliers(&[], &[], 0.01).is_empty());
        assert_eq!(reject_outliers(&[Point3::origin()], &[Point3::origin()], 0.01), vec![0]);
    }
}
