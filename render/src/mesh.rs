//! [`TriangleMesh`]: the object models of the simulated RGB-D scenes.

use nalgebra::{Point3, Vector3};

/// A triangle mesh in the object frame (m); triangles list vertex indices
/// counter-clockwise seen from outside (outward normals).
#[derive(Clone, Debug, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions, object frame (m).
    pub vertices: Vec<Point3<f64>>,
    /// Vertex indices of each triangle.
    pub triangles: Vec<[u32; 3]>,
}

impl TriangleMesh {
    /// A box of `size_m = [x, y, z]` centred at the origin: 12 triangles.
    pub fn cuboid(size_m: [f64; 3]) -> TriangleMesh {
        let [hx, hy, hz] = size_m.map(|s| s / 2.0);
        let vertices = (0..8)
            .map(|i| {
                Point3::new(
                    if i & 1 == 0 { -hx } else { hx },
                    if i & 2 == 0 { -hy } else { hy },
                    if i & 4 == 0 { -hz } else { hz },
                )
            })
            .collect();
        // Faces as quads (counter-clockwise from outside), split in two.
        let quads: [[u32; 4]; 6] =
            [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        let triangles = quads.iter().flat_map(|[a, b, c, d]| [[*a, *b, *c], [*a, *c, *d]]).collect();
        TriangleMesh { vertices, triangles }
    }

    /// A closed cylinder along z, centred at the origin, with `segments` sides.
    pub fn cylinder(radius_m: f64, height_m: f64, segments: u32) -> TriangleMesh {
        let n = segments.max(3);
        let h = height_m / 2.0;
        let mut vertices = Vec::with_capacity(2 * n as usize + 2);
        for z in [-h, h] {
            for i in 0..n {
                let a = std::f64::consts::TAU * f64::from(i) / f64::from(n);
                vertices.push(Point3::new(radius_m * a.cos(), radius_m * a.sin(), z));
            }
        }
        let (bottom, top) = (2 * n, 2 * n + 1);
        vertices.push(Point3::new(0.0, 0.0, -h));
        vertices.push(Point3::new(0.0, 0.0, h));
        let mut triangles = Vec::with_capacity(4 * n as usize);
        for i in 0..n {
            let j = (i + 1) % n;
            triangles.push([i, j, n + j]);
            triangles.push([i, n + j, n + i]);
            triangles.push([bottom, j, i]);
            triangles.push([top, n + i, n + j]);
        }
        TriangleMesh { vertices, triangles }
    }

    /// The outward unit normal of triangle `index` (zero for a degenerate one).
    pub fn normal(&self, index: usize) -> Vector3<f64> {
        let [a, b, c] = self.corners(index);
        (b - a).cross(&(c - a)).try_normalize(1e-15).unwrap_or_else(Vector3::zeros)
    }

    /// The three corners of triangle `index`.
    pub fn corners(&self, index: usize) -> [Point3<f64>; 3] {
        self.triangles[index].map(|i| self.vertices[i as usize])
    }

    /// Largest distance of a vertex from the origin (m).
    pub fn radius_m(&self) -> f64 {
        self.vertices.iter().map(|v| v.coords.norm()).fold(0.0, f64::max)
    }

    /// `count` points spread uniformly over the surface (area-weighted), drawn
    /// deterministically from `seed`.
    pub fn sample_surface(&self, count: usize, seed: u64) -> Vec<Point3<f64>> {
        let areas: Vec<f64> = (0..self.triangles.len())
            .map(|i| {
                let [a, b, c] = self.corners(i);
                (b - a).cross(&(c - a)).norm() / 2.0
            })
            .collect();
        let total: f64 = areas.iter().sum();
        if total <= 0.0 || count == 0 {
            return Vec::new();
        }
        let mut cumulative = Vec::with_capacity(areas.len());
        let mut acc = 0.0;
        for a in &areas {
            acc += a / total;
            cumulative.push(acc);
        }
        let mut state = seed;
        let mut uniform = move || {
            state = crate::splitmix64(state);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..count)
            .map(|_| {
                let pick = uniform();
                let i = cumulative.partition_point(|c| *c < pick).min(areas.len() - 1);
                let [a, b, c] = self.corners(i);
                let (mut r1, mut r2) = (uniform(), uniform());
                if r1 + r2 > 1.0 {
                    r1 = 1.0 - r1;
                    r2 = 1.0 - r2;
                }
                a + (b - a) * r1 + (c - a) * r2
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The divergence theorem: for a closed mesh with outward normals the
    /// signed volume is positive and equals the solid's volume.
    fn volume(mesh: &TriangleMesh) -> f64 {
        (0..mesh.triangles.len())
            .map(|i| {
                let [a, b, c] = mesh.corners(i);
                a.coords.dot(&b.coords.cross(&c.coords)) / 6.0
            })
            .sum()
    }

    #[test]
    fn meshes_are_closed_with_outward_normals() {
        let b = TriangleMesh::cuboid([0.1, 0.2, 0.3]);
        assert!((volume(&b) - 0.006).abs() < 1e-12);
        let c = TriangleMesh::cylinder(0.05, 0.1, 64);
        let exact = std::f64::consts::PI * 0.05 * 0.05 * 0.1;
        assert!((volume(&c) - exact).abs() < 0.01 * exact);
        for i in 0..b.triangles.len() {
            let [a, _, _] = b.corners(i);
            assert!(b.normal(i).dot(&a.coords) > 0.0, "outward");
        }
    }

    #[test]
    fn surface_samples_lie_on_the_surface() {
        let b = TriangleMesh::cuboid([0.1, 0.2, 0.3]);
        let points = b.sample_surface(500, 7);
        assert_eq!(points.len(), 500);
        for p in points {
            let on_face = (p.x.abs() - 0.05).abs() < 1e-12
                || (p.y.abs() - 0.1).abs() < 1e-12
                || (p.z.abs() - 0.15).abs() < 1e-12;
            assert!(on_face, "{p:?}");
        }
    }
}
