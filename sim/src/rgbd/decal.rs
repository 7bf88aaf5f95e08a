//! [`MarkerDecal`]: an ArUco marker printed on a face of the simulated
//! object, so that recorded RGB-D sequences can feed marker-based pose
//! sources (`vision track --measurements aruco`).

use nalgebra::{Isometry3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use slidetrack_core::MarkerPattern;
use slidetrack_render::TriangleMesh;

/// A marker (black square `size_m` per side, border cells included) with
/// one white cell of margin, printed flat on a face of the object.
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerDecal {
    /// The marker's bits.
    pub pattern: MarkerPattern,
    /// Side of the black square (m), border cells included.
    pub size_m: f64,
    /// Marker frame (OpenCV ArUco: origin at the centre, x right, y up as
    /// printed, z out of the face) in the object frame.
    pub object_from_marker: Isometry3<f64>,
}

impl MarkerDecal {
    /// The decal centred on the flat face of `mesh` that faces the camera
    /// most at `camera_from_object` among the faces wide enough for the
    /// sticker; `None` when no face fits. Faces are those of the mesh's
    /// bounding box that carry triangles (every face of a box, the caps of a
    /// cylinder).
    pub fn on_face_seen_at(
        pattern: MarkerPattern,
        size_m: f64,
        mesh: &TriangleMesh,
        camera_from_object: &Isometry3<f64>,
    ) -> Option<MarkerDecal> {
        let (lo, hi) = bounds(mesh)?;
        let sticker_m = size_m * (1.0 + 2.0 / (pattern.cells as f64 + 2.0));
        let camera_in_object = camera_from_object.inverse() * Point3::origin();
        let mut best: Option<(f64, Isometry3<f64>)> = None;
        for axis in 0..3 {
            for sign in [-1.0, 1.0] {
                let mut normal = Vector3::zeros();
                normal[axis] = sign;
                let plane = if sign > 0.0 { hi[axis] } else { lo[axis] };
                let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
                if hi[a] - lo[a] < sticker_m || hi[b] - lo[b] < sticker_m || !has_face(mesh, axis, plane) {
                    continue;
                }
                let mut centre = Point3::from((lo.coords + hi.coords) / 2.0);
                centre[axis] = plane;
                let facing = (camera_in_object - centre).normalize().dot(&normal);
                // x along the face's first in-plane axis, z out of the face.
                let mut x = Vector3::zeros();
                x[a] = 1.0;
                let y = normal.cross(&x);
                let rotation = Rotation3::from_basis_unchecked(&[x, y, normal]);
                let pose = Isometry3::from_parts(
                    Translation3::from(centre.coords),
                    UnitQuaternion::from_rotation_matrix(&rotation),
                );
                if best.as_ref().is_none_or(|(f, _)| facing > *f) {
                    best = Some((facing, pose));
                }
            }
        }
        best.map(|(_, object_from_marker)| MarkerDecal { pattern, size_m, object_from_marker })
    }

    /// The printed colour at `point_in_object` on a face with outward
    /// `normal_in_object`: `Some(true)` white, `Some(false)` black, `None`
    /// off the sticker.
    pub fn shade_at(&self, point_in_object: &Point3<f64>, normal_in_object: &Vector3<f64>) -> Option<bool> {
        let z = self.object_from_marker.rotation * Vector3::z();
        if normal_in_object.dot(&z) < 0.99 {
            return None;
        }
        let p = self.object_from_marker.inverse_transform_point(point_in_object);
        if p.z.abs() > 1e-3 {
            return None;
        }
        let cells = self.pattern.cells as f64 + 2.0;
        let cell_m = self.size_m / cells;
        let half = self.size_m / 2.0;
        if p.x.abs() > half + cell_m || p.y.abs() > half + cell_m {
            return None;
        }
        if p.x.abs() >= half || p.y.abs() >= half {
            return Some(true);
        }
        let col = ((p.x + half) / cell_m).floor() as usize;
        let row = ((half - p.y) / cell_m).floor() as usize;
        if row == 0 || col == 0 || row as f64 >= cells - 1.0 || col as f64 >= cells - 1.0 {
            return Some(false);
        }
        Some(self.pattern.is_white(row - 1, col - 1))
    }
}

/// The mesh's bounding box.
fn bounds(mesh: &TriangleMesh) -> Option<(Point3<f64>, Point3<f64>)> {
    let first = *mesh.vertices.first()?;
    Some(mesh.vertices.iter().fold((first, first), |(lo, hi), v| (lo.inf(v), hi.sup(v))))
}

/// Whether some triangle lies in the plane `coordinate[axis] = plane`.
fn has_face(mesh: &TriangleMesh, axis: usize, plane: f64) -> bool {
    mesh.triangles.iter().any(|t| t.iter().all(|&i| (mesh.vertices[i as usize][axis] - plane).abs() < 1e-9))
}
