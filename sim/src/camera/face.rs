//! The object's marker face as a planar pattern.

use slidetrack_core::MarkerPattern;

use super::blocks::{PlanarPattern, disjoint, in_box, inside};
use super::object::ObjectAppearance;
use super::raster::PlaneInCamera;

/// Number of parts before the marker cells: outside the face, face, sticker.
const CELLS_START: u32 = 3;

/// The marker face: face colour, white sticker, marker cells.
///
/// Parts: 0 = outside the face (transparent; hole: the face), 1 = face
/// (hole: the sticker), 2 = sticker paper (hole: the marker), and `3 + row *
/// (cells + 2) + col` for marker cell (row, col) counted with the black
/// border, row 0 at the top as printed.
pub(super) struct FacePattern<'a> {
    marker: &'a MarkerPattern,
    face_box_m: [f64; 4],
    sticker_box_m: [f64; 4],
    marker_box_m: [f64; 4],
    inv_cell_m: f64,
    face_rgb: [f32; 3],
    paper_rgb: [f32; 3],
    ink_rgb: [f32; 3],
}

/// The face's, the paper's and the ink's colour on `plane`, lit by a light
/// next to the camera: 75 % ambient, 25 % Lambertian.
pub(super) fn lit_face_colours(appearance: &ObjectAppearance, plane: &PlaneInCamera) -> [[f32; 3]; 3] {
    let centre = plane.point(0.0, 0.0);
    let cos = (-plane.normal().dot(&centre) / centre.norm().max(1e-12)).clamp(0.0, 1.0);
    let shade = (0.75 + 0.25 * cos) as f32;
    let gray = |g: u8| [f32::from(g) * shade; 3];
    [
        appearance.face_rgb.map(|c| f32::from(c) * shade),
        gray(appearance.paper_gray),
        gray(appearance.ink_gray),
    ]
}

impl<'a> FacePattern<'a> {
    /// Lit by a light next to the camera: 75 % ambient, 25 % Lambertian.
    pub(super) fn new(
        appearance: &ObjectAppearance,
        marker: &'a MarkerPattern,
        plane: &PlaneInCamera,
    ) -> FacePattern<'a> {
        let [face_rgb, paper_rgb, ink_rgb] = lit_face_colours(appearance, plane);
        let cell_m = appearance.cell_size_m(marker.cells);
        let [ma, mb] = appearance.marker_centre_on_face_m;
        let half_marker_m = appearance.marker_size_m / 2.0;
        let half_sticker_m = half_marker_m + appearance.sticker_margin_cells * cell_m;
        let [hw, hh] = appearance.face_size_m.map(|s| s / 2.0);
        let around = |h: f64| [ma - h, ma + h, mb - h, mb + h];
        FacePattern {
            marker,
            face_box_m: [-hw, hw, -hh, hh],
            sticker_box_m: around(half_sticker_m),
            marker_box_m: around(half_marker_m),
            inv_cell_m: 1.0 / cell_m,
            face_rgb,
            paper_rgb,
            ink_rgb,
        }
    }

    fn side(&self) -> usize {
        self.marker.cells + 2
    }

    /// Cell column and row (clamped to the marker) of a point of the marker.
    fn cell(&self, a: f64, b: f64) -> (usize, usize) {
        let last = self.side() - 1;
        // Columns from the marker's left edge, rows from its top edge (b grows upwards).
        let col = (((a - self.marker_box_m[0]) * self.inv_cell_m).max(0.0) as usize).min(last);
        let row = (((self.marker_box_m[3] - b) * self.inv_cell_m).max(0.0) as usize).min(last);
        (col, row)
    }

    fn cell_is_white(&self, col: usize, row: usize) -> bool {
        row.checked_sub(1).zip(col.checked_sub(1)).is_some_and(|(r, c)| self.marker.is_white(r, c))
    }
}

impl PlanarPattern for FacePattern<'_> {
    #[inline]
    fn part(&self, a: f64, b: f64) -> u32 {
        if !in_box(a, b, self.face_box_m) {
            return 0;
        }
        if !in_box(a, b, self.sticker_box_m) {
            return 1;
        }
        if !in_box(a, b, self.marker_box_m) {
            return 2;
        }
        let (col, row) = self.cell(a, b);
        CELLS_START + (row * self.side() + col) as u32
    }

    fn part_count(&self) -> u32 {
        CELLS_START + (self.side() * self.side()) as u32
    }

    fn colour(&self, part: u32) -> Option<[f32; 3]> {
        match part {
            0 => None,
            1 => Some(self.face_rgb),
            2 => Some(self.paper_rgb),
            _ => {
                let k = (part - CELLS_START) as usize;
                let white = self.cell_is_white(k % self.side(), k / self.side());
                Some(if white { self.paper_rgb } else { self.ink_rgb })
            }
        }
    }

    fn hole(&self, part: u32) -> Option<[f64; 4]> {
        match part {
            0 => Some(self.face_box_m),
            1 => Some(self.sticker_box_m),
            2 => Some(self.marker_box_m),
            _ => None,
        }
    }

    fn colour_in_box(&self, bounds: [f64; 4]) -> Option<u32> {
        let nested = [self.face_box_m, self.sticker_box_m, self.marker_box_m];
        for (part, level) in nested.into_iter().enumerate() {
            if disjoint(bounds, level) {
                return Some(part as u32);
            }
            if !inside(bounds, level) {
                return None;
            }
        }
        // Inside the marker: one colour if every cell the box touches has it.
        let (c0, r0) = self.cell(bounds[0], bounds[3]);
        let (c1, r1) = self.cell(bounds[1], bounds[2]);
        let white = self.cell_is_white(c0, r0);
        let one_colour = (r0..=r1).all(|r| (c0..=c1).all(|c| self.cell_is_white(c, r) == white));
        one_colour.then(|| CELLS_START + (r0 * self.side() + c0) as u32)
    }
}
