//! Object models: read from OBJ, PLY or XYZ files (metres, object frame);
//! the points `{A_j}` MaskUKF and the metrics use, and the depth renderer
//! ROFT's outlier test uses (the mesh when there is one, else point splats).

mod parse;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use nalgebra::{Isometry3, Point3};
use slidetrack_core::CameraIntrinsics;
use slidetrack_estimators::maskukf::ObjectPoints;
use slidetrack_estimators::orientation::Symmetry;
use slidetrack_estimators::roft::DepthRenderer;
use slidetrack_render::{Rasterizer, TriangleMesh};

use crate::VisionError;

/// Points sampled on a mesh for MaskUKF and the metrics (the YCB-Video
/// models have 2621).
pub const MESH_SAMPLES: usize = 2621;

/// An object model.
#[derive(Clone, Debug)]
pub struct ObjectModel {
    /// Where it came from, for messages.
    pub origin: String,
    /// Surface points in the object frame (m).
    pub points: Vec<Point3<f64>>,
    /// The triangle mesh, when the file has faces.
    pub mesh: Option<TriangleMesh>,
    /// The shape's rotational symmetry, for the metrics that discount it
    /// (see [`symmetry_of`]).
    pub symmetry: Symmetry,
}

/// The continuous rotational symmetry of the objects known by name: the
/// YCB-Video models of a purely cylindrical or bowl shape, about their own
/// axes (the master chef, tomato soup and tuna fish cans and the bowl about
/// z, the large marker about y; checked against the model points by a test)
/// and the simulator's soup can (z). Other names: none. Discrete symmetries
/// (the foam brick, the wood block) are left to the ADI metric.
pub fn symmetry_of(name: &str) -> Symmetry {
    let axis = match name {
        "002_master_chef_can" | "005_tomato_soup_can" | "007_tuna_fish_can" | "024_bowl" | "soup_can" => {
            nalgebra::Vector3::z_axis()
        }
        "040_large_marker" => nalgebra::Vector3::y_axis(),
        _ => return Symmetry::None,
    };
    Symmetry::Axis { axis_in_object: axis }
}

impl ObjectModel {
    /// Reads `.xyz`, `.obj` or `.ply`, scaling coordinates by `scale` (1 for
    /// metres, 0.001 for millimetres).
    pub fn load(path: &Path, scale: f64) -> Result<ObjectModel, VisionError> {
        let bytes =
            std::fs::read(path).map_err(|source| VisionError::Io { path: path.to_path_buf(), source })?;
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
        let text = || String::from_utf8_lossy(&bytes).into_owned();
        let parsed = match ext.as_str() {
            "xyz" | "txt" => parse::xyz(&text()),
            "obj" => parse::obj(&text()),
            "ply" => parse::ply(&bytes),
            _ => return Err(VisionError::UnsupportedModel { path: path.to_path_buf() }),
        }
        .map_err(|detail| bad(path, detail))?;
        if parsed.vertices.is_empty() {
            return Err(bad(path, "no vertices".into()));
        }
        let vertices: Vec<Point3<f64>> = parsed.vertices.iter().map(|p| p * scale).collect();
        if !vertices.iter().all(|p| p.iter().all(|v| v.is_finite())) {
            return Err(bad(path, "a vertex is not finite".into()));
        }
        let mesh = (!parsed.triangles.is_empty())
            .then(|| TriangleMesh { vertices: vertices.clone(), triangles: parsed.triangles });
        let points = match &mesh {
            Some(m) => m.sample_surface(MESH_SAMPLES, 0x006d_6f64_656c),
            None => vertices,
        };
        // YCB-Video models sit in a directory named after their class.
        let name = path.parent().and_then(Path::file_name).and_then(|n| n.to_str()).unwrap_or_default();
        Ok(ObjectModel { origin: path.display().to_string(), points, mesh, symmetry: symmetry_of(name) })
    }

    /// A model from a mesh (points sampled on it); `origin` names it (and
    /// its symmetry, [`symmetry_of`]).
    pub fn from_mesh(origin: &str, mesh: TriangleMesh) -> ObjectModel {
        ObjectModel {
            origin: origin.into(),
            points: mesh.sample_surface(MESH_SAMPLES, 0x006d_6f64_656c),
            mesh: Some(mesh),
            symmetry: symmetry_of(origin),
        }
    }

    /// The points with their k-d tree and the model's symmetry.
    pub fn object_points(&self) -> Result<Arc<ObjectPoints>, VisionError> {
        Ok(Arc::new(ObjectPoints::new(self.points.clone())?.with_symmetry(self.symmetry)))
    }

    /// Radius of the smallest origin-centred sphere holding the points (m).
    pub fn radius_m(&self) -> f64 {
        self.points.iter().map(|p| p.coords.norm()).fold(0.0, f64::max)
    }

    /// A depth renderer of the model for `intrinsics`: the mesh when there is
    /// one, else a splat per point.
    pub fn depth_renderer(&self, intrinsics: &CameraIntrinsics) -> Box<dyn DepthRenderer> {
        match &self.mesh {
            Some(mesh) => Box::new(MeshDepth { rasterizer: Rasterizer::new(intrinsics), mesh: mesh.clone() }),
            None => Box::new(SplatDepth::new(intrinsics, &self.points)),
        }
    }
}

fn bad(path: &Path, detail: String) -> VisionError {
    VisionError::BadFile { path: PathBuf::from(path), detail }
}

/// Depth of a mesh through the rasterizer.
struct MeshDepth {
    rasterizer: Rasterizer,
    mesh: TriangleMesh,
}

impl DepthRenderer for MeshDepth {
    fn render(&mut self, camera_from_object: &Isometry3<f64>, pixels: &[(u32, u32)], depth_m: &mut Vec<f32>) {
        self.rasterizer.depth_at(&self.mesh, camera_from_object, pixels, depth_m);
    }
}

/// Depth of a point model: each point is a square splat whose side covers
/// the typical spacing of the points at its depth; the nearest wins.
struct SplatDepth {
    intrinsics: CameraIntrinsics,
    points: Vec<Point3<f64>>,
    /// Typical distance between neighbouring points (m).
    spacing_m: f64,
    buffer: Vec<f32>,
}

impl SplatDepth {
    fn new(intrinsics: &CameraIntrinsics, points: &[Point3<f64>]) -> SplatDepth {
        // Spacing of points spread evenly on a sphere of the model's radius.
        let radius = points.iter().map(|p| p.coords.norm()).fold(0.0, f64::max);
        let spacing_m = (4.0 * std::f64::consts::PI * radius * radius / points.len().max(1) as f64).sqrt();
        SplatDepth { intrinsics: intrinsics.clone(), points: points.to_vec(), spacing_m, buffer: Vec::new() }
    }
}

impl DepthRenderer for SplatDepth {
    fn render(&mut self, camera_from_object: &Isometry3<f64>, pixels: &[(u32, u32)], depth_m: &mut Vec<f32>) {
        depth_m.clear();
        let Some((u0, v0, u1, v1)) = bounds(pixels) else {
            return;
        };
        let (w, h) = ((u1 - u0) as usize, (v1 - v0) as usize);
        self.buffer.clear();
        self.buffer.resize(w * h, f32::INFINITY);
        let c = &self.intrinsics;
        for a in &self.points {
            let p = camera_from_object * a;
            if p.z < 1e-3 {
                continue;
            }
            let (u, v) = (c.fx * p.x / p.z + c.cx, c.fy * p.y / p.z + c.cy);
            let half = (0.5 * self.spacing_m * c.fx / p.z).clamp(0.5, 12.0);
            let (ua, ub) =
                ((u - half).round().max(f64::from(u0)), (u + half).round().min(f64::from(u1) - 1.0));
            let (va, vb) =
                ((v - half).round().max(f64::from(v0)), (v + half).round().min(f64::from(v1) - 1.0));
            if ua > ub || va > vb {
                continue;
            }
            for y in va as u32..=vb as u32 {
                for x in ua as u32..=ub as u32 {
                    let i = (y - v0) as usize * w + (x - u0) as usize;
                    self.buffer[i] = self.buffer[i].min(p.z as f32);
                }
            }
        }
        depth_m.extend(pixels.iter().map(|(u, v)| {
            let d = self.buffer[(v - v0) as usize * w + (u - u0) as usize];
            if d.is_finite() { d } else { 0.0 }
        }));
    }
}

/// `[u0, u1) x [v0, v1)` around `pixels`.
fn bounds(pixels: &[(u32, u32)]) -> Option<(u32, u32, u32, u32)> {
    let (&(u, v), rest) = pixels.split_first()?;
    Some(
        rest.iter().fold((u, v, u + 1, v + 1), |(a, b, c, d), &(u, v)| {
            (a.min(u), b.min(v), c.max(u + 1), d.max(v + 1))
        }),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn intrinsics() -> CameraIntrinsics {
        CameraIntrinsics {
            width: 160,
            height: 120,
            fx: 140.0,
            fy: 140.0,
            cx: 79.5,
            cy: 59.5,
            distortion: [0.0; 5],
        }
    }

    #[test]
    fn models_load_from_every_format_and_refuse_bad_files() {
        let dir = tempfile::tempdir().unwrap();
        let xyz = dir.path().join("a.xyz");
        std::fs::write(&xyz, "0 0 0\n0.1 0 0\n").unwrap();
        let m = ObjectModel::load(&xyz, 1.0).unwrap();
        assert_eq!(m.points.len(), 2);
        assert!(m.mesh.is_none());
        let obj = dir.path().join("b.OBJ");
        std::fs::write(&obj, "v 0 0 0\nv 100 0 0\nv 0 100 0\nf 1 2 3\n").unwrap();
        let m = ObjectModel::load(&obj, 0.001).unwrap();
        assert_eq!(m.points.len(), MESH_SAMPLES);
        assert!(m.points.iter().all(|p| p.x >= -1e-12 && p.y >= -1e-12 && p.x + p.y <= 0.1 + 1e-12));
        let missing = ObjectModel::load(&dir.path().join("none.ply"), 1.0).unwrap_err();
        assert!(matches!(missing, VisionError::Io { .. }), "{missing}");
        let other = dir.path().join("c.stl");
        std::fs::write(&other, "solid").unwrap();
        assert!(matches!(ObjectModel::load(&other, 1.0), Err(VisionError::UnsupportedModel { .. })));
        let empty = dir.path().join("d.xyz");
        std::fs::write(&empty, "# nothing\n").unwrap();
        assert!(matches!(ObjectModel::load(&empty, 1.0), Err(VisionError::BadFile { .. })));
    }

    /// The splat renderer of a dense point model agrees with the mesh
    /// renderer of the same box on its front face.
    #[test]
    fn splats_and_meshes_render_the_same_depth() {
        let mesh = TriangleMesh::cuboid([0.1, 0.1, 0.1]);
        let mesh_model = ObjectModel::from_mesh("box", mesh.clone());
        let point_model = ObjectModel {
            origin: "points".into(),
            points: mesh.sample_surface(6000, 3),
            mesh: None,
            symmetry: Symmetry::None,
        };
        let pose = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 0.5),
            UnitQuaternion::from_euler_angles(0.0, 0.3, 0.0),
        );
        let pixels: Vec<(u32, u32)> = (70..90).flat_map(|u| (50..70).map(move |v| (u, v))).collect();
        let (mut a, mut b) = (Vec::new(), Vec::new());
        mesh_model.depth_renderer(&intrinsics()).render(&pose, &pixels, &mut a);
        point_model.depth_renderer(&intrinsics()).render(&pose, &pixels, &mut b);
        let mean_gap: f32 = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.len() as f32;
        assert!(a.iter().all(|d| *d > 0.4 && *d < 0.5));
        assert!(mean_gap < 0.01, "{mean_gap}");
    }
}
