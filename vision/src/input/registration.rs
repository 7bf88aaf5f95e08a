//! Depth registered to the colour camera. An RGB-D camera whose depth comes
//! from its own node (a RealSense's `Z16` stream, from the left infrared
//! imager) sees the scene from another place than its colour camera: a
//! depth pixel `(u, v)` is not the colour pixel `(u, v)`. [`register_depth_to_color`]
//! moves every depth pixel to where the colour camera sees its point, with
//! the depth-to-colour extrinsics (rotation and translation) and both
//! cameras' intrinsics, as librealsense's `align` to colour does:
//!
//! 1. back-project the depth pixel's four corners `(u ± ½, v ± ½)` at its
//!    depth (pinhole, depth intrinsics) into the depth camera's frame;
//! 2. move them with `color_from_depth` and project them with the colour
//!    intrinsics;
//! 3. write the point's colour-frame depth `z` into every colour pixel whose
//!    centre lies in the box around the four projections, keeping the nearest surface
//!    where several depth pixels land on one colour pixel (a z-buffer).
//!
//! Splatting the pixel's footprint rather than its centre leaves no cracks
//! when the colour image is finer than the depth image. Colour pixels that
//! no depth pixel reaches (parts of the scene the depth camera does not see,
//! outside its view or hidden behind a nearer object) stay 0, as invalid
//! depth does everywhere in this crate. Lens distortion is not modelled: the
//! streams are taken as rectified pinhole images (true of RealSense depth
//! streams; the colour stream's small distortion is ignored).

use nalgebra::{Isometry3, Point3};
use slidetrack_core::{CameraIntrinsics, DepthImage};

use crate::VisionError;

/// Depth registered to the colour camera: an image of the colour camera's
/// size whose pixel `(u, v)` holds the depth along the colour camera's
/// optical axis (in the input's units, `depth.scale_m` metres each) of the
/// surface the colour camera sees there, or 0 where no depth pixel lands.
///
/// `depth_intrinsics` are the depth image's (its size must match),
/// `color_intrinsics` the colour camera's, and `color_from_depth` maps
/// points in the depth camera's optical frame (m) to the colour camera's.
/// Fails on a size mismatch or intrinsics that are not positive and finite.
pub fn register_depth_to_color(
    depth: &DepthImage,
    depth_intrinsics: &CameraIntrinsics,
    color_intrinsics: &CameraIntrinsics,
    color_from_depth: &Isometry3<f64>,
) -> Result<DepthImage, VisionError> {
    check_inputs(depth, depth_intrinsics, color_intrinsics, color_from_depth)?;
    let (width, height) = (color_intrinsics.width, color_intrinsics.height);
    let mut out =
        DepthImage { width, height, data: vec![0; width as usize * height as usize], scale_m: depth.scale_m };
    let back_project = |u: f64, v: f64, z_m: f64| {
        let k = depth_intrinsics;
        Point3::new((u - k.cx) / k.fx * z_m, (v - k.cy) / k.fy * z_m, z_m)
    };
    let project = |p_in_color: &Point3<f64>| {
        let k = color_intrinsics;
        (k.fx * p_in_color.x / p_in_color.z + k.cx, k.fy * p_in_color.y / p_in_color.z + k.cy)
    };
    for v in 0..depth.height {
        for u in 0..depth.width {
            let raw = depth.data[(v * depth.width + u) as usize];
            if raw == 0 {
                continue;
            }
            let z_in_depth_m = f64::from(raw) * depth.scale_m;
            let (u, v) = (f64::from(u), f64::from(v));
            let centre_in_color = color_from_depth * back_project(u, v, z_in_depth_m);
            if centre_in_color.z <= 0.0 {
                continue;
            }
            // The footprint: the box around the four corners' projections.
            let mut footprint = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
            let mut behind = false;
            for (du, dv) in [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)] {
                let corner_in_color = color_from_depth * back_project(u + du, v + dv, z_in_depth_m);
                behind |= corner_in_color.z <= 0.0;
                let (uc, vc) = project(&corner_in_color);
                footprint =
                    [footprint[0].min(uc), footprint[1].min(vc), footprint[2].max(uc), footprint[3].max(vc)];
            }
            if behind {
                continue;
            }
            // Colour pixels whose centres lie in the footprint (at least the
            // one under the centre).
            let (uc, vc) = project(&centre_in_color);
            let range = |lo: f64, hi: f64, centre: f64, size: u32| -> Option<(u32, u32)> {
                let first = lo.ceil().min(centre.round()).max(0.0);
                let last = (hi.ceil() - 1.0).max(centre.round()).min(f64::from(size) - 1.0);
                (first <= last && first.is_finite() && last.is_finite())
                    .then_some((first as u32, last as u32))
            };
            let (Some((u0, u1)), Some((v0, v1))) =
                (range(footprint[0], footprint[2], uc, width), range(footprint[1], footprint[3], vc, height))
            else {
                continue;
            };
            let z_raw = (centre_in_color.z / depth.scale_m).round().clamp(1.0, f64::from(u16::MAX)) as u16;
            for row in v0..=v1 {
                for column in u0..=u1 {
                    let cell = &mut out.data[(row * width + column) as usize];
                    if *cell == 0 || z_raw < *cell {
                        *cell = z_raw;
                    }
                }
            }
        }
    }
    Ok(out)
}

/// The sizes, intrinsics, depth scale and extrinsics are usable.
fn check_inputs(
    depth: &DepthImage,
    depth_intrinsics: &CameraIntrinsics,
    color_intrinsics: &CameraIntrinsics,
    color_from_depth: &Isometry3<f64>,
) -> Result<(), VisionError> {
    if (depth.width, depth.height) != (depth_intrinsics.width, depth_intrinsics.height)
        || depth.data.len() != depth.width as usize * depth.height as usize
    {
        return Err(VisionError::SizeMismatch {
            what: "depth image",
            width: depth.width,
            height: depth.height,
            expected_width: depth_intrinsics.width,
            expected_height: depth_intrinsics.height,
        });
    }
    for (what, k) in [("depth intrinsics", depth_intrinsics), ("colour intrinsics", color_intrinsics)] {
        let usable = [k.fx, k.fy].iter().all(|f| f.is_finite() && *f > 0.0)
            && k.cx.is_finite()
            && k.cy.is_finite()
            && k.width > 0
            && k.height > 0;
        if !usable {
            return Err(VisionError::BadImage {
                what,
                detail: format!(
                    "fx {}, fy {}, cx {}, cy {} px are not positive and finite",
                    k.fx, k.fy, k.cx, k.cy
                ),
            });
        }
    }
    let finite_extrinsics = color_from_depth.to_homogeneous().iter().all(|v| v.is_finite());
    if !(depth.scale_m.is_finite() && depth.scale_m > 0.0 && finite_extrinsics) {
        return Err(VisionError::BadImage {
            what: "depth registration",
            detail: format!("depth scale {} m or the extrinsics are not finite", depth.scale_m),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    use super::*;

    /// The scene, in the depth camera's frame (m): a wall at z = 1.2 and a
    /// card facing the cameras at z = 0.6 over x in [-0.08, 0.06], y in
    /// [-0.05, 0.07].
    const WALL_Z_M: f64 = 1.2;
    const CARD_Z_M: f64 = 0.6;

    /// The depth (along the viewing camera's axis, m) of the surface a ray
    /// from `origin` along `direction` (both in the depth frame; `direction`
    /// has unit z in the viewing camera) hits first, and whether it is the card.
    fn ray_cast(origin: &Point3<f64>, direction: &Vector3<f64>) -> (f64, bool) {
        let t_card = (CARD_Z_M - origin.z) / direction.z;
        let hit = origin + direction * t_card;
        if t_card > 0.0 && (-0.08..=0.06).contains(&hit.x) && (-0.05..=0.07).contains(&hit.y) {
            return (t_card, true);
        }
        ((WALL_Z_M - origin.z) / direction.z, false)
    }

    /// The depth image a camera with `k` at `depth_from_camera` sees, metres.
    fn render(k: &CameraIntrinsics, depth_from_camera: &Isometry3<f64>) -> Vec<(f64, bool)> {
        let origin = Point3::from(depth_from_camera.translation.vector);
        let mut out = Vec::new();
        for v in 0..k.height {
            for u in 0..k.width {
                let ray_in_camera =
                    Vector3::new((f64::from(u) - k.cx) / k.fx, (f64::from(v) - k.cy) / k.fy, 1.0);
                out.push(ray_cast(&origin, &(depth_from_camera.rotation * ray_in_camera)));
            }
        }
        out
    }

    fn intrinsics(width: u32, height: u32, f: f64, cx: f64, cy: f64) -> CameraIntrinsics {
        CameraIntrinsics { width, height, fx: f, fy: f * 1.01, cx, cy, distortion: [0.0; 5] }
    }

    /// The centroid and extent (px) of the card's pixels.
    fn card_footprint(is_card: impl Fn(usize) -> bool, k: &CameraIntrinsics) -> ([f64; 2], [u32; 4]) {
        let (mut sum, mut n) = ([0.0, 0.0], 0.0);
        let mut extent = [u32::MAX, u32::MAX, 0, 0];
        for v in 0..k.height {
            for u in 0..k.width {
                if is_card((v * k.width + u) as usize) {
                    sum[0] += f64::from(u);
                    sum[1] += f64::from(v);
                    n += 1.0;
                    extent = [extent[0].min(u), extent[1].min(v), extent[2].max(u), extent[3].max(v)];
                }
            }
        }
        ([sum[0] / n, sum[1] / n], extent)
    }

    /// A RealSense-like pair: depth (Z16, mm) from an imager 15 mm to the
    /// side of a 640x480 colour camera, turned by about 2 degrees. The
    /// registered depth puts the card where the colour camera sees it (its
    /// centroid within 1 px, every edge within `edge_px`), has the colour
    /// camera's depth everywhere but within `edge_px` of the card's edges,
    /// and leaves holes only in the strip of wall the card hides from the
    /// depth camera.
    fn registers_within(depth_k: &CameraIntrinsics, edge_px: u32) {
        let depth_k = depth_k.clone();
        let color_k = intrinsics(640, 480, 610.0, 322.4, 241.7);
        let color_from_depth = Isometry3::from_parts(
            Translation3::new(-0.015, 0.0012, 0.0008),
            UnitQuaternion::from_euler_angles(-1.0f64.to_radians(), 1.5f64.to_radians(), 0.5f64.to_radians()),
        );
        let seen_by_depth = render(&depth_k, &Isometry3::identity());
        let depth = DepthImage {
            width: depth_k.width,
            height: depth_k.height,
            data: seen_by_depth.iter().map(|(z, _)| (z * 1000.0).round() as u16).collect(),
            scale_m: 0.001,
        };
        let registered = register_depth_to_color(&depth, &depth_k, &color_k, &color_from_depth).unwrap();
        assert_eq!((registered.width, registered.height, registered.scale_m), (640, 480, 0.001));
        let truth = render(&color_k, &color_from_depth.inverse());

        // The card: centroid and edges.
        let near = |i: usize| registered.data[i] != 0 && registered.data[i] < 900;
        let (centroid, extent) = card_footprint(near, &color_k);
        let (true_centroid, true_extent) = card_footprint(|i| truth[i].1, &color_k);
        let error_px =
            ((centroid[0] - true_centroid[0]).powi(2) + (centroid[1] - true_centroid[1]).powi(2)).sqrt();
        assert!(error_px < 1.0, "card centroid {centroid:?} vs {true_centroid:?}");
        for (a, b) in extent.iter().zip(&true_extent) {
            assert!(a.abs_diff(*b) <= edge_px, "card extent {extent:?} vs {true_extent:?}");
        }

        // Depth values: right (within 1 cm) except next to an edge.
        let w = color_k.width as usize;
        let near_edge = |i: usize, radius: usize| {
            let (u, v) = ((i % w) as isize, (i / w) as isize);
            let r = radius as isize;
            (-r..=r).any(|dv| {
                (-r..=r).any(|du| {
                    let (a, b) = (u + du, v + dv);
                    a >= 0
                        && b >= 0
                        && (a as usize) < w
                        && (b as usize) < color_k.height as usize
                        && truth[b as usize * w + a as usize].1 != truth[i].1
                })
            })
        };
        let (mut holes, mut wrong) = (0, 0);
        for (i, raw) in registered.data.iter().enumerate() {
            let z_m = f64::from(*raw) * 0.001;
            if *raw == 0 {
                holes += 1;
                // The strip of wall behind the card's edge that the depth
                // camera, 15 mm away, cannot see: 610 px * 15 mm * (1/0.6 -
                // 1/1.2) m = 7.6 px wide.
                assert!(
                    !truth[i].1 && near_edge(i, 9),
                    "hole at pixel {} {} away from the card",
                    i % w,
                    i / w
                );
            } else if (z_m - truth[i].0).abs() > 0.01 {
                wrong += 1;
                assert!(
                    near_edge(i, edge_px as usize),
                    "pixel {} {}: {z_m} m, truth {} m",
                    i % w,
                    i / w,
                    truth[i].0
                );
            }
        }
        println!("{holes} holes, {wrong} pixels off by more than 1 cm next to an edge");
        assert!(holes > 0, "the card hides part of the wall from the depth camera");

        // Without the extrinsics the card lands 10+ px away.
        let unregistered =
            register_depth_to_color(&depth, &depth_k, &color_k, &Isometry3::identity()).unwrap();
        let (c, _) = card_footprint(|i| unregistered.data[i] != 0 && unregistered.data[i] < 900, &color_k);
        assert!(
            (c[0] - true_centroid[0]).hypot(c[1] - true_centroid[1]) > 10.0,
            "{c:?} vs {true_centroid:?}"
        );
    }

    /// Depth at 848x480 (finer than colour, a D435's default): 1 px.
    #[test]
    fn a_finer_depth_image_registers_within_a_pixel() {
        registers_within(&intrinsics(848, 480, 424.0, 423.1, 239.4), 1);
    }

    /// Depth at 424x240 (coarser than colour: each depth pixel covers 2.9
    /// colour pixels, splatted without cracks): edges within half a depth
    /// pixel (2 colour px), the centroid within 1 px.
    #[test]
    fn a_coarser_depth_image_registers_without_cracks() {
        registers_within(&intrinsics(424, 240, 212.0, 211.3, 119.6), 2);
    }

    #[test]
    fn bad_sizes_and_intrinsics_are_errors() {
        let k = intrinsics(4, 3, 2.0, 1.5, 1.0);
        let depth = DepthImage { width: 4, height: 3, data: vec![1000; 12], scale_m: 0.001 };
        let other = intrinsics(5, 3, 2.0, 1.5, 1.0);
        let identity = Isometry3::identity();
        assert!(matches!(
            register_depth_to_color(&depth, &other, &k, &identity),
            Err(VisionError::SizeMismatch { .. })
        ));
        let bad = CameraIntrinsics { fx: 0.0, ..k.clone() };
        assert!(register_depth_to_color(&depth, &k, &bad, &identity).is_err());
        let short = DepthImage { data: vec![0; 5], ..depth.clone() };
        assert!(register_depth_to_color(&short, &k, &k, &identity).is_err());
        // Identity extrinsics and intrinsics: the image itself.
        let same = register_depth_to_color(&depth, &k, &k, &identity).unwrap();
        assert_eq!(same.data, depth.data);
        // A point behind the colour camera is dropped.
        let behind = Isometry3::from_parts(Translation3::new(0.0, 0.0, -2.0), UnitQuaternion::identity());
        assert!(register_depth_to_color(&depth, &k, &k, &behind).unwrap().data.iter().all(|d| *d == 0));
    }
}
