//! The object's marker face carrying a printed board (GridBoard or ChArUco)
//! instead of one marker.

use slidetrack_core::{BoardLayout, MarkerPattern};

use super::blocks::{PlanarPattern, disjoint, in_box, inside};
use super::face::lit_face_colours;
use super::object::ObjectAppearance;
use super::raster::PlaneInCamera;

/// A board as printed: its layout and the bits of each of its markers.
#[derive(Clone, Debug, PartialEq)]
pub struct BoardPrint {
    /// Where the markers (and a ChArUco board's squares) are.
    pub layout: BoardLayout,
    /// The markers in the order of [`BoardLayout::markers`].
    pub markers: Vec<MarkerPattern>,
}

/// Parts before the tiles: outside the face, face, sticker margin.
const TILES_START: u32 = 3;

/// One tile of the board: a GridBoard's marker with the gaps to its right
/// and below it, or a ChArUco square.
#[derive(Clone, Copy)]
struct Tile {
    /// Box of its marker, if any.
    marker_box: Option<[f64; 4]>,
    /// Index into the print's markers.
    marker: usize,
    /// A black ChArUco square.
    black: bool,
}

/// The face with its board. The board's centre is at
/// `appearance.marker_centre_on_face_m`; the sticker margin
/// (`sticker_margin_cells` marker cells) is white paper around the board.
///
/// Parts: 0 = outside the face (hole: the face), 1 = face (hole: the
/// sticker), 2 = sticker margin (hole: the board), then for tile `t`
/// (row by row) `3 + t * (1 + side^2)` = the tile's paper or black square
/// (hole: its marker) and the next `side^2` parts its marker's cells
/// (`row * side + col`, with the black border; `side = cells + 2`).
pub(super) struct BoardFacePattern<'a> {
    print: &'a BoardPrint,
    side: usize,
    tiles_x: usize,
    tiles_y: usize,
    /// Tile pitch along the board's x and y (m).
    pitch_m: f64,
    tiles: Vec<Tile>,
    face_box_m: [f64; 4],
    sticker_box_m: [f64; 4],
    board_box_m: [f64; 4],
    inv_cell_m: f64,
    face_rgb: [f32; 3],
    paper_rgb: [f32; 3],
    ink_rgb: [f32; 3],
}

impl<'a> BoardFacePattern<'a> {
    /// Lit like the single marker's face: 75 % ambient, 25 % Lambertian.
    pub(super) fn new(
        appearance: &ObjectAppearance,
        print: &'a BoardPrint,
        plane: &PlaneInCamera,
    ) -> BoardFacePattern<'a> {
        let [face_rgb, paper_rgb, ink_rgb] = lit_face_colours(appearance, plane);
        let cells = print.markers.first().map_or(1, |m| m.cells);
        let side = cells + 2;
        let layout = &print.layout;
        let cell_m = layout.marker_length_m() / side as f64;
        let [w, h] = layout.size_m();
        let [ma, mb] = appearance.marker_centre_on_face_m;
        // Board frame (x right, y down, origin top-left) to face (a right, b up).
        let (a0, b0) = (ma - w / 2.0, mb + h / 2.0);
        let to_face = |x0: f64, x1: f64, y0: f64, y1: f64| [a0 + x0, a0 + x1, b0 - y1, b0 - y0];
        let (tiles_x, tiles_y, pitch_m) = match *layout {
            BoardLayout::Grid { markers_x, markers_y, marker_length_m, separation_m, .. } => {
                (markers_x as usize, markers_y as usize, marker_length_m + separation_m)
            }
            BoardLayout::Charuco { squares_x, squares_y, square_length_m, .. } => {
                (squares_x as usize, squares_y as usize, square_length_m)
            }
        };
        let markers = layout.markers();
        let mut tiles = Vec::with_capacity(tiles_x * tiles_y);
        for ty in 0..tiles_y {
            for tx in 0..tiles_x {
                let (x0, y0) = (tx as f64 * pitch_m, ty as f64 * pitch_m);
                let (x1, y1) = ((x0 + pitch_m).min(w), (y0 + pitch_m).min(h));
                // The marker whose top-left corner lies in this tile.
                let found = markers.iter().position(|m| {
                    let c = m.corners_m[0];
                    c.x >= x0 - 1e-12 && c.x < x1 - 1e-12 && c.y >= y0 - 1e-12 && c.y < y1 - 1e-12
                });
                let marker_box = found.map(|k| {
                    let [p, _, q, _] = markers[k].corners_m;
                    to_face(p.x, q.x, p.y, q.y)
                });
                let black = matches!(layout, BoardLayout::Charuco { .. }) && tx % 2 == ty % 2;
                tiles.push(Tile { marker_box, marker: found.unwrap_or(0), black });
            }
        }
        let board_box_m = to_face(0.0, w, 0.0, h);
        let margin = appearance.sticker_margin_cells * cell_m;
        let [hw, hh] = appearance.face_size_m.map(|s| s / 2.0);
        let [ba0, ba1, bb0, bb1] = board_box_m;
        BoardFacePattern {
            print,
            side,
            tiles_x,
            tiles_y,
            pitch_m,
            tiles,
            face_box_m: [-hw, hw, -hh, hh],
            sticker_box_m: [ba0 - margin, ba1 + margin, bb0 - margin, bb1 + margin],
            board_box_m,
            inv_cell_m: 1.0 / cell_m,
            face_rgb,
            paper_rgb,
            ink_rgb,
        }
    }

    fn parts_per_tile(&self) -> u32 {
        1 + (self.side * self.side) as u32
    }

    /// The tile holding a point of the board.
    fn tile_at(&self, a: f64, b: f64) -> usize {
        let x = a - self.board_box_m[0];
        let y = self.board_box_m[3] - b;
        let tx = ((x / self.pitch_m).max(0.0) as usize).min(self.tiles_x - 1);
        let ty = ((y / self.pitch_m).max(0.0) as usize).min(self.tiles_y - 1);
        ty * self.tiles_x + tx
    }

    /// Cell column and row (clamped) of a point of a marker.
    fn cell(&self, marker_box: [f64; 4], a: f64, b: f64) -> (usize, usize) {
        let last = self.side - 1;
        let col = (((a - marker_box[0]) * self.inv_cell_m).max(0.0) as usize).min(last);
        let row = (((marker_box[3] - b) * self.inv_cell_m).max(0.0) as usize).min(last);
        (col, row)
    }

    fn cell_is_white(&self, marker: usize, col: usize, row: usize) -> bool {
        let Some(pattern) = self.print.markers.get(marker) else { return false };
        row.checked_sub(1).zip(col.checked_sub(1)).is_some_and(|(r, c)| pattern.is_white(r, c))
    }

    fn tile_part(&self, tile: usize) -> u32 {
        TILES_START + tile as u32 * self.parts_per_tile()
    }
}

impl PlanarPattern for BoardFacePattern<'_> {
    #[inline]
    fn part(&self, a: f64, b: f64) -> u32 {
        if !in_box(a, b, self.face_box_m) {
            return 0;
        }
        if !in_box(a, b, self.sticker_box_m) {
            return 1;
        }
        if !in_box(a, b, self.board_box_m) {
            return 2;
        }
        let t = self.tile_at(a, b);
        let tile = &self.tiles[t];
        match tile.marker_box {
            Some(m) if in_box(a, b, m) => {
                let (col, row) = self.cell(m, a, b);
                self.tile_part(t) + 1 + (row * self.side + col) as u32
            }
            _ => self.tile_part(t),
        }
    }

    fn part_count(&self) -> u32 {
        TILES_START + self.tiles.len() as u32 * self.parts_per_tile()
    }

    fn colour(&self, part: u32) -> Option<[f32; 3]> {
        match part {
            0 => None,
            1 => Some(self.face_rgb),
            2 => Some(self.paper_rgb),
            _ => {
                let k = part - TILES_START;
                let (t, within) = ((k / self.parts_per_tile()) as usize, k % self.parts_per_tile());
                let tile = self.tiles.get(t)?;
                if within == 0 {
                    return Some(if tile.black { self.ink_rgb } else { self.paper_rgb });
                }
                let cell = (within - 1) as usize;
                let white = self.cell_is_white(tile.marker, cell % self.side, cell / self.side);
                Some(if white { self.paper_rgb } else { self.ink_rgb })
            }
        }
    }

    fn hole(&self, part: u32) -> Option<[f64; 4]> {
        match part {
            0 => Some(self.face_box_m),
            1 => Some(self.sticker_box_m),
            2 => Some(self.board_box_m),
            _ => {
                let k = part - TILES_START;
                if !k.is_multiple_of(self.parts_per_tile()) {
                    return None;
                }
                self.tiles.get((k / self.parts_per_tile()) as usize)?.marker_box
            }
        }
    }

    fn colour_in_box(&self, bounds: [f64; 4]) -> Option<u32> {
        let nested = [self.face_box_m, self.sticker_box_m, self.board_box_m];
        for (part, level) in nested.into_iter().enumerate() {
            if disjoint(bounds, level) {
                return Some(part as u32);
            }
            if !inside(bounds, level) {
                return None;
            }
        }
        // Inside the board: one tile, and within it one colour.
        let t = self.tile_at(bounds[0], bounds[3]);
        if self.tile_at(bounds[1], bounds[2]) != t {
            return None;
        }
        let tile = &self.tiles[t];
        let Some(m) = tile.marker_box else { return Some(self.tile_part(t)) };
        if disjoint(bounds, m) {
            return Some(self.tile_part(t));
        }
        if !inside(bounds, m) {
            return None;
        }
        let (c0, r0) = self.cell(m, bounds[0], bounds[3]);
        let (c1, r1) = self.cell(m, bounds[1], bounds[2]);
        let white = self.cell_is_white(tile.marker, c0, r0);
        let one_colour = (r0..=r1).all(|r| (c0..=c1).all(|c| self.cell_is_white(tile.marker, c, r) == white));
        one_colour.then(|| self.tile_part(t) + 1 + (r0 * self.side + c0) as u32)
    }
}
