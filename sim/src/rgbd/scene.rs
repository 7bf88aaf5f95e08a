//! [`RgbdScene`]: one textured object in front of a textured wall, seen by a
//! registered RGB-D camera, with the noise of a structured-light or stereo
//! depth sensor.

use nalgebra::{Isometry3, Point3, Vector3};
use slidetrack_core::{CameraIntrinsics, DepthImage, Image, PixelFormat};
use slidetrack_render::{PixelRegion, Rasterizer, TriangleMesh, splitmix64};

use super::decal::MarkerDecal;
use super::depth_noise::{CleanDepth, DepthNoise};
use super::error::RgbdSimError;
use super::texture::Texture;

/// Settings of a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbdSceneConfig {
    /// Pinhole intrinsics (distortion is ignored).
    pub intrinsics: CameraIntrinsics,
    /// Distance of the wall behind the object (m).
    pub wall_depth_m: f64,
    /// Depth imperfections.
    pub depth_noise: DepthNoise,
    /// Colour noise standard deviation (levels of 255).
    pub color_noise_std: f64,
    /// Direction towards the light, camera frame.
    pub light_in_camera: [f64; 3],
    /// Seed of the textures and the noise.
    pub seed: u64,
}

impl RgbdSceneConfig {
    /// The [`RgbdSceneConfig::vga`] camera at half its resolution, 320x240
    /// (tests that render many frames).
    pub fn qvga_intrinsics() -> CameraIntrinsics {
        CameraIntrinsics {
            width: 320,
            height: 240,
            fx: 277.15,
            fy: 277.15,
            cx: 159.5,
            cy: 119.5,
            distortion: [0.0; 5],
        }
    }

    /// A 640x480 camera with a 60 degree horizontal field of view, the wall
    /// at 1.3 m, default noise.
    pub fn vga(seed: u64) -> RgbdSceneConfig {
        RgbdSceneConfig {
            intrinsics: CameraIntrinsics {
                width: 640,
                height: 480,
                fx: 554.3,
                fy: 554.3,
                cx: 319.5,
                cy: 239.5,
                distortion: [0.0; 5],
            },
            wall_depth_m: 1.3,
            depth_noise: DepthNoise::default(),
            color_noise_std: 2.0,
            light_in_camera: [-0.3, -0.6, -1.0],
            seed,
        }
    }
}

/// One rendered frame.
#[derive(Clone, Debug)]
pub struct RenderedRgbd {
    /// Colour, RGB8.
    pub color: Image,
    /// Depth in millimetres.
    pub depth: DepthImage,
    /// Ground-truth segmentation: 255 where the object is seen, 0 elsewhere.
    pub mask: Vec<u8>,
}

/// Texture frame of one triangle: surface coordinates `(s, t) = (x·e_s, x·e_t) + offset`.
#[derive(Clone, Copy, Debug)]
struct FaceFrame {
    normal: Vector3<f64>,
    e_s: Vector3<f64>,
    e_t: Vector3<f64>,
    offset: (f64, f64),
}

/// One object in front of a wall, rendered by a registered RGB-D camera.
pub struct RgbdScene {
    config: RgbdSceneConfig,
    rasterizer: Rasterizer,
    mesh: TriangleMesh,
    faces: Vec<FaceFrame>,
    texture: Texture,
    wall_rgb: Vec<u8>,
    noise: Vec<f32>,
    uniform: Vec<f32>,
    marker: Option<MarkerDecal>,
}

impl RgbdScene {
    /// Builds the scene; draws the wall and the noise tables once.
    pub fn new(
        config: RgbdSceneConfig,
        mesh: TriangleMesh,
        texture: Texture,
    ) -> Result<RgbdScene, RgbdSimError> {
        let c = &config.intrinsics;
        if c.width == 0 || c.height == 0 || c.width > 8192 || c.height > 8192 || !(c.fx > 0.0 && c.fy > 0.0) {
            return Err(RgbdSimError::BadIntrinsics { width: c.width, height: c.height, fx: c.fx, fy: c.fy });
        }
        if !(config.wall_depth_m > 0.05 && config.wall_depth_m < 60.0) {
            return Err(RgbdSimError::OutOfRange {
                what: "wall_depth_m",
                value: config.wall_depth_m,
                expected: "0.05..60 m",
            });
        }
        let faces = (0..mesh.triangles.len()).map(|i| face_frame(&mesh, i, config.seed)).collect();
        let wall = Texture::packaging(config.seed ^ 0x77a1, [0.55, 0.52, 0.47], [0.25, 0.3, 0.36], 0.6);
        let mut wall_rgb = Vec::with_capacity(c.width as usize * c.height as usize * 3);
        for v in 0..c.height {
            for u in 0..c.width {
                let x = (f64::from(u) - c.cx) / c.fx * config.wall_depth_m;
                let y = (f64::from(v) - c.cy) / c.fy * config.wall_depth_m;
                wall_rgb.extend(wall.sample(x, y).map(|v| (v * 200.0).clamp(0.0, 255.0) as u8));
            }
        }
        let n = c.width as usize * c.height as usize;
        let mut state = config.seed ^ 0x006e_6f69_7365;
        let uniform: Vec<f32> = (0..4 * n + 7919)
            .map(|_| {
                state = splitmix64(state);
                ((state >> 40) as f32 + 0.5) / (1u64 << 24) as f32
            })
            .collect();
        // Box-Muller on pairs of the uniform table.
        let noise: Vec<f32> = uniform
            .chunks_exact(2)
            .flat_map(|p| {
                let r = (-2.0 * p[0].ln()).sqrt();
                let a = std::f32::consts::TAU * p[1];
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        Ok(RgbdScene {
            rasterizer: Rasterizer::new(c).culling_back_faces(),
            config,
            mesh,
            faces,
            texture,
            wall_rgb,
            noise,
            uniform,
            marker: None,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &RgbdSceneConfig {
        &self.config
    }

    /// The object's mesh (object frame).
    pub fn mesh(&self) -> &TriangleMesh {
        &self.mesh
    }

    /// Prints `marker` on the object from now on (`None` removes it).
    pub fn set_marker(&mut self, marker: Option<MarkerDecal>) {
        self.marker = marker;
    }

    /// The marker printed on the object.
    pub fn marker(&self) -> Option<&MarkerDecal> {
        self.marker.as_ref()
    }

    /// Renders frame `sequence` with the object at `camera_from_object`. The
    /// noise depends only on the seed and `sequence`.
    pub fn render(&self, camera_from_object: &Isometry3<f64>, sequence: u64) -> RenderedRgbd {
        let c = &self.config.intrinsics;
        let (w, h) = (c.width as usize, c.height as usize);
        let mut rgb = self.wall_rgb.clone();
        let mut depth = vec![self.config.wall_depth_m as f32; w * h];
        let mut mask = vec![0u8; w * h];
        let mut normal_cos = vec![1.0f32; w * h];
        if let Some(region) = self.object_region(camera_from_object) {
            self.draw_object(camera_from_object, region, &mut rgb, &mut depth, &mut mask, &mut normal_cos);
        }
        let offset = |salt: u64, len: usize| {
            (splitmix64(self.config.seed ^ splitmix64(sequence ^ salt)) % len as u64) as usize
        };
        let color_at = offset(1, self.noise.len() - 3 * w * h);
        let depth_at = offset(3, self.noise.len() - self.config.depth_noise.normals_needed(w, h));
        let uniform_at = offset(2, self.uniform.len() - w * h);
        let color = self.noisy_color(&rgb, &self.noise[color_at..color_at + 3 * w * h]);
        let clean =
            CleanDepth { size: (w, h), fx: c.fx, depth_m: &depth, mask: &mask, normal_cos: &normal_cos };
        let depth = self.config.depth_noise.apply(
            &clean,
            &self.noise[depth_at..],
            &self.uniform[uniform_at..uniform_at + w * h],
        );
        RenderedRgbd { color, depth, mask }
    }

    /// The bounding box of the projected mesh, grown by a pixel, if visible.
    fn object_region(&self, camera_from_object: &Isometry3<f64>) -> Option<PixelRegion> {
        let c = &self.config.intrinsics;
        let mut r: Option<(f64, f64, f64, f64)> = None;
        for v in &self.mesh.vertices {
            let p = camera_from_object * v;
            if p.z < 1e-3 {
                return None;
            }
            let (u, vv) = (c.fx * p.x / p.z + c.cx, c.fy * p.y / p.z + c.cy);
            let b = r.get_or_insert((u, vv, u, vv));
            *b = (b.0.min(u), b.1.min(vv), b.2.max(u), b.3.max(vv));
        }
        let (u0, v0, u1, v1) = r?;
        let clip = |x: f64, max: u32| x.clamp(0.0, f64::from(max)) as u32;
        let region = PixelRegion {
            u0: clip(u0.floor() - 1.0, c.width),
            v0: clip(v0.floor() - 1.0, c.height),
            u1: clip(u1.ceil() + 2.0, c.width),
            v1: clip(v1.ceil() + 2.0, c.height),
        };
        (!region.is_empty()).then_some(region)
    }

    fn draw_object(
        &self,
        camera_from_object: &Isometry3<f64>,
        region: PixelRegion,
        rgb: &mut [u8],
        depth: &mut [f32],
        mask: &mut [u8],
        normal_cos: &mut [f32],
    ) {
        let c = &self.config.intrinsics;
        let (mut zbuf, mut tri) = (Vec::new(), Vec::new());
        self.rasterizer.render(&self.mesh, camera_from_object, region, &mut zbuf, &mut tri);
        let object_from_camera = camera_from_object.inverse();
        let origin = object_from_camera * Point3::origin();
        let light =
            Vector3::from(self.config.light_in_camera).try_normalize(1e-12).unwrap_or_else(|| -Vector3::z());
        let stride = region.width() as usize;
        for v in region.v0..region.v1 {
            for u in region.u0..region.u1 {
                let k = (v - region.v0) as usize * stride + (u - region.u0) as usize;
                let Some(face) = self.faces.get(tri[k] as usize) else {
                    continue;
                };
                let ray_c = Vector3::new((f64::from(u) - c.cx) / c.fx, (f64::from(v) - c.cy) / c.fy, 1.0);
                let ray = object_from_camera.rotation * ray_c;
                let denom = face.normal.dot(&ray);
                let plane_d = face
                    .normal
                    .dot(&self.mesh.vertices[self.mesh.triangles[tri[k] as usize][0] as usize].coords);
                let s = if denom.abs() > 1e-12 {
                    (plane_d - face.normal.dot(&origin.coords)) / denom
                } else {
                    0.0
                };
                let x = origin + ray * s;
                let printed = self.marker.as_ref().and_then(|m| m.shade_at(&x, &face.normal));
                let albedo = match printed {
                    Some(white) => [if white { 0.95 } else { 0.05 }; 3],
                    None => self.texture.sample(
                        x.coords.dot(&face.e_s) + face.offset.0,
                        x.coords.dot(&face.e_t) + face.offset.1,
                    ),
                };
                let n_c = camera_from_object.rotation * face.normal;
                let shade = (0.35 + 0.65 * n_c.dot(&light).max(0.0)) as f32;
                let i = v as usize * c.width as usize + u as usize;
                for ch in 0..3 {
                    rgb[3 * i + ch] = (albedo[ch] * shade * 255.0).clamp(0.0, 255.0) as u8;
                }
                depth[i] = zbuf[k];
                mask[i] = 255;
                normal_cos[i] = (n_c.dot(&ray_c.normalize())).abs() as f32;
            }
        }
    }

    fn noisy_color(&self, rgb: &[u8], noise: &[f32]) -> Image {
        let c = &self.config.intrinsics;
        let std = self.config.color_noise_std as f32;
        let data = rgb
            .iter()
            .zip(noise)
            .map(|(v, n)| (f32::from(*v) + n * std).round().clamp(0.0, 255.0) as u8)
            .collect();
        Image { width: c.width, height: c.height, format: PixelFormat::Rgb8, data }
    }
}

/// The texture frame of triangle `i`: tangent axes and a per-plane offset so
/// that faces do not repeat each other's pattern.
fn face_frame(mesh: &TriangleMesh, i: usize, seed: u64) -> FaceFrame {
    let normal = mesh.normal(i);
    let helper = if normal.z.abs() < 0.9 { Vector3::z() } else { Vector3::x() };
    let e_s = normal.cross(&helper).try_normalize(1e-12).unwrap_or_else(Vector3::x);
    let e_t = normal.cross(&e_s);
    let key = normal.iter().fold(seed, |h, v| splitmix64(h ^ ((v * 1000.0).round() as i64 as u64)));
    let offset =
        ((key >> 8) as f64 / (1u64 << 56) as f64, (splitmix64(key) >> 8) as f64 / (1u64 << 56) as f64);
    FaceFrame { normal, e_s, e_t, offset }
}
