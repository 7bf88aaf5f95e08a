//! A printed chessboard for intrinsics calibration.

use serde::{Deserialize, Serialize};

use super::blocks::{PlanarPattern, disjoint, in_box, inside};

/// A chessboard as OpenCV's `findChessboardCorners` sees it: `inner_corners`
/// corners per row and per column, squares of `square_size_m`, a white margin
/// around the squares.
///
/// Board frame (as in OpenCV's calibration examples): origin at the first
/// inner corner, x along a row of inner corners, y along a column, z into the
/// board; the printed side faces -z. The square on the `(+x, +y)` side of
/// the origin is black.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Chessboard {
    /// Inner corners `[per row (along x), per column (along y)]`.
    pub inner_corners: [u32; 2],
    /// Side of one square (m).
    pub square_size_m: f64,
    /// White margin around the outer squares (m).
    pub margin_m: f64,
}

impl Default for Chessboard {
    /// OpenCV's sample board: 9x6 inner corners, 25 mm squares.
    fn default() -> Self {
        Chessboard { inner_corners: [9, 6], square_size_m: 0.025, margin_m: 0.025 }
    }
}

impl Chessboard {
    /// The inner corners in the board frame (m), row by row (x fastest), the
    /// order of OpenCV's object points.
    pub fn corners_in_board(&self) -> Vec<[f64; 3]> {
        let [nx, ny] = self.inner_corners;
        let s = self.square_size_m;
        (0..ny).flat_map(|j| (0..nx).map(move |i| [f64::from(i) * s, f64::from(j) * s, 0.0])).collect()
    }
}

/// The board as a planar pattern. Parts: 0 = outside (transparent; hole: the
/// board), 1 = white margin (hole: the squares), `2 + qy * (nx + 1) + qx` =
/// square (qx, qy), squares counted from the outer one at the board's -x, -y
/// corner.
pub(super) struct BoardPattern {
    squares: [i64; 2],
    square_m: f64,
    board_box_m: [f64; 4],
    squares_box_m: [f64; 4],
}

impl BoardPattern {
    pub(super) fn new(board: &Chessboard) -> BoardPattern {
        let squares = board.inner_corners.map(|n| i64::from(n) + 1);
        let s = board.square_size_m.abs().max(1e-6);
        let m = board.margin_m.max(0.0);
        // Square qx spans x in [(qx - 1) s, qx s].
        let squares_box_m = [-s, (squares[0] - 1) as f64 * s, -s, (squares[1] - 1) as f64 * s];
        let [a0, a1, b0, b1] = squares_box_m;
        BoardPattern { squares, square_m: s, board_box_m: [a0 - m, a1 + m, b0 - m, b1 + m], squares_box_m }
    }

    /// The board's outline (with margin) in board coordinates (m). The plane
    /// renderer looks at the board's z = 0 plane from either side.
    pub(super) fn outline(&self) -> [(f64, f64); 4] {
        let [a0, a1, b0, b1] = self.board_box_m;
        [(a0, b0), (a1, b0), (a1, b1), (a0, b1)]
    }
}

impl PlanarPattern for BoardPattern {
    fn part(&self, a: f64, b: f64) -> u32 {
        if !in_box(a, b, self.board_box_m) {
            return 0;
        }
        if !in_box(a, b, self.squares_box_m) {
            return 1;
        }
        let qx = ((a / self.square_m).floor() as i64 + 1).clamp(0, self.squares[0] - 1);
        let qy = ((b / self.square_m).floor() as i64 + 1).clamp(0, self.squares[1] - 1);
        2 + (qy * self.squares[0] + qx) as u32
    }

    fn part_count(&self) -> u32 {
        2 + (self.squares[0] * self.squares[1]) as u32
    }

    fn colour(&self, part: u32) -> Option<[f32; 3]> {
        const WHITE: [f32; 3] = [225.0; 3];
        const BLACK: [f32; 3] = [30.0; 3];
        match part {
            0 => None,
            1 => Some(WHITE),
            _ => {
                let k = i64::from(part - 2);
                let (qx, qy) = (k % self.squares[0], k / self.squares[0]);
                // Square (1, 1), on the +x, +y side of the origin, is black.
                Some(if (qx + qy) % 2 == 0 { BLACK } else { WHITE })
            }
        }
    }

    fn hole(&self, part: u32) -> Option<[f64; 4]> {
        match part {
            0 => Some(self.board_box_m),
            1 => Some(self.squares_box_m),
            _ => None,
        }
    }

    fn colour_in_box(&self, bounds: [f64; 4]) -> Option<u32> {
        if disjoint(bounds, self.board_box_m) {
            return Some(0);
        }
        if !inside(bounds, self.board_box_m) {
            return None;
        }
        if disjoint(bounds, self.squares_box_m) {
            return Some(1);
        }
        // Neighbouring squares differ: one colour only within one square.
        let (first, last) = (self.part(bounds[0], bounds[2]), self.part(bounds[1], bounds[3]));
        (inside(bounds, self.squares_box_m) && first == last && first >= 2).then_some(first)
    }
}
