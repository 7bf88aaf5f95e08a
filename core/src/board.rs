//! The layout of a printed ArUco board (OpenCV's GridBoard or ChArUco
//! board): which marker ids sit where, and where the ChArUco chessboard
//! corners are, in the board frame.
//!
//! The geometry is OpenCV 4.6's (`GridBoard::create` in
//! `modules/aruco/src/aruco.cpp` and `CharucoBoard::create` in
//! `modules/aruco/src/charuco.cpp` of opencv_contrib 4.6.0; OpenCV 4.7+
//! keeps it in `objdetect`): **board frame** origin at the top-left corner of
//! the printed board (a GridBoard's first marker's top-left corner, a ChArUco
//! board's top-left square corner), x to the right, y down the print, z into
//! the board. Markers are numbered row by row from the top-left. A ChArUco
//! board's top-left square is black; its markers sit in the white squares
//! (those where `x % 2 != y % 2`), its chessboard corners are the inner
//! corners, row by row, id `y * (squares_x - 1) + x`.
//!
//! The rendering code (the simulated camera) and the detection code (OpenCV,
//! in the calibration crate) share this description.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A board layout that cannot be printed.
#[derive(Clone, Debug, Error, PartialEq)]
#[error("board: {field} = {value} {expected}")]
pub struct BadBoardLayout {
    /// The TOML key.
    pub field: &'static str,
    /// The value given.
    pub value: f64,
    /// What it must be.
    pub expected: &'static str,
}

/// A printed board of ArUco markers.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum BoardLayout {
    /// OpenCV's `GridBoard`: `markers_x` by `markers_y` markers of side
    /// `marker_length_m`, `separation_m` apart, ids from `first_id` row by row.
    Grid {
        /// Markers per row.
        markers_x: u32,
        /// Markers per column.
        markers_y: u32,
        /// Side of a marker's black square (m).
        marker_length_m: f64,
        /// Gap between neighbouring markers (m).
        separation_m: f64,
        /// Id of the top-left marker.
        #[serde(default)]
        first_id: u32,
    },
    /// OpenCV's `CharucoBoard`: `squares_x` by `squares_y` chessboard squares
    /// of side `square_length_m`, a marker of side `marker_length_m` centred
    /// in each white square, ids from 0 row by row.
    Charuco {
        /// Squares per row.
        squares_x: u32,
        /// Squares per column.
        squares_y: u32,
        /// Side of a square (m).
        square_length_m: f64,
        /// Side of a marker's black square (m).
        marker_length_m: f64,
    },
}

/// One marker of a board: its id and its corners in the board frame (m), in
/// OpenCV's order (top-left, top-right, bottom-right, bottom-left as printed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoardMarker {
    /// Dictionary id.
    pub id: u32,
    /// Corners in the board frame (m).
    pub corners_m: [Point3<f64>; 4],
}

impl BoardLayout {
    /// Checks counts and sizes.
    pub fn validate(&self) -> Result<(), BadBoardLayout> {
        let check = |field, value: f64, ok: bool, expected| {
            if ok { Ok(()) } else { Err(BadBoardLayout { field, value, expected }) }
        };
        let positive = |v: f64| v.is_finite() && v > 0.0;
        match *self {
            BoardLayout::Grid { markers_x, markers_y, marker_length_m, separation_m, .. } => {
                check("markers_x", f64::from(markers_x), markers_x >= 1, "must be at least 1")?;
                check("markers_y", f64::from(markers_y), markers_y >= 1, "must be at least 1")?;
                check("marker_length_m", marker_length_m, positive(marker_length_m), "must be > 0 m")?;
                check("separation_m", separation_m, positive(separation_m), "must be > 0 m")
            }
            BoardLayout::Charuco { squares_x, squares_y, square_length_m, marker_length_m } => {
                check("squares_x", f64::from(squares_x), squares_x >= 2, "must be at least 2")?;
                check("squares_y", f64::from(squares_y), squares_y >= 2, "must be at least 2")?;
                check("square_length_m", square_length_m, positive(square_length_m), "must be > 0 m")?;
                let fits = positive(marker_length_m) && marker_length_m < square_length_m;
                check("marker_length_m", marker_length_m, fits, "must be > 0 m and below square_length_m")
            }
        }
    }

    /// Side of one marker's black square (m).
    pub fn marker_length_m(&self) -> f64 {
        match *self {
            BoardLayout::Grid { marker_length_m, .. } | BoardLayout::Charuco { marker_length_m, .. } => {
                marker_length_m
            }
        }
    }

    /// Width and height of the printed pattern (m), without any margin.
    pub fn size_m(&self) -> [f64; 2] {
        match *self {
            BoardLayout::Grid { markers_x, markers_y, marker_length_m: l, separation_m: s, .. } => {
                let side = |n: u32| f64::from(n) * l + f64::from(n.saturating_sub(1)) * s;
                [side(markers_x), side(markers_y)]
            }
            BoardLayout::Charuco { squares_x, squares_y, square_length_m: q, .. } => {
                [f64::from(squares_x) * q, f64::from(squares_y) * q]
            }
        }
    }

    /// Every marker with its corners in the board frame, in OpenCV's order
    /// of the board's markers.
    pub fn markers(&self) -> Vec<BoardMarker> {
        let square = |x0: f64, y0: f64, l: f64| {
            [
                Point3::new(x0, y0, 0.0),
                Point3::new(x0 + l, y0, 0.0),
                Point3::new(x0 + l, y0 + l, 0.0),
                Point3::new(x0, y0 + l, 0.0),
            ]
        };
        match *self {
            BoardLayout::Grid { markers_x, markers_y, marker_length_m: l, separation_m: s, first_id } => (0
                ..markers_y)
                .flat_map(|y| (0..markers_x).map(move |x| (x, y)))
                .enumerate()
                .map(|(k, (x, y))| BoardMarker {
                    id: first_id + k as u32,
                    corners_m: square(f64::from(x) * (l + s), f64::from(y) * (l + s), l),
                })
                .collect(),
            BoardLayout::Charuco { squares_x, squares_y, square_length_m: q, marker_length_m: l } => {
                let inset = (q - l) / 2.0;
                (0..squares_y)
                    .flat_map(|y| (0..squares_x).map(move |x| (x, y)))
                    .filter(|(x, y)| x % 2 != y % 2)
                    .enumerate()
                    .map(|(k, (x, y))| BoardMarker {
                        id: k as u32,
                        corners_m: square(f64::from(x) * q + inset, f64::from(y) * q + inset, l),
                    })
                    .collect()
            }
        }
    }

    /// A ChArUco board's inner chessboard corners in the board frame (m),
    /// indexed by their ChArUco id; empty for a GridBoard.
    pub fn chessboard_corners_m(&self) -> Vec<Point3<f64>> {
        match *self {
            BoardLayout::Grid { .. } => Vec::new(),
            BoardLayout::Charuco { squares_x, squares_y, square_length_m: q, .. } => (1..squares_y)
                .flat_map(|y| {
                    (1..squares_x).map(move |x| Point3::new(f64::from(x) * q, f64::from(y) * q, 0.0))
                })
                .collect(),
        }
    }

    /// The board's centre frame in the board frame: origin at the centre of
    /// the printed pattern, x right, y up, z out of the print (the frame of a
    /// single ArUco marker), so that a board stands in for a marker.
    pub fn board_from_centre(&self) -> Isometry3<f64> {
        let [w, h] = self.size_m();
        // Half a turn about x: y up the print, z out of it.
        let flip = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
        Isometry3::from_parts(Translation3::new(w / 2.0, h / 2.0, 0.0), flip)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> BoardLayout {
        BoardLayout::Grid {
            markers_x: 5,
            markers_y: 7,
            marker_length_m: 0.04,
            separation_m: 0.01,
            first_id: 3,
        }
    }

    fn charuco() -> BoardLayout {
        BoardLayout::Charuco { squares_x: 5, squares_y: 7, square_length_m: 0.04, marker_length_m: 0.02 }
    }

    #[test]
    fn a_grid_board_numbers_its_markers_row_by_row_from_the_top_left() {
        let markers = grid().markers();
        assert_eq!(markers.len(), 35);
        assert_eq!(markers[0].id, 3);
        assert_eq!(markers[0].corners_m[0], Point3::origin());
        // Second marker of the first row: one marker and one gap to the right.
        assert_eq!(markers[1].corners_m[0], Point3::new(0.05, 0.0, 0.0));
        // First marker of the second row: one marker and one gap down (y down).
        assert_eq!(markers[5].corners_m[0], Point3::new(0.0, 0.05, 0.0));
        assert_eq!(markers[0].corners_m[2], Point3::new(0.04, 0.04, 0.0));
        assert_eq!(grid().size_m(), [5.0 * 0.04 + 4.0 * 0.01, 7.0 * 0.04 + 6.0 * 0.01]);
    }

    #[test]
    fn a_charuco_board_has_markers_in_its_white_squares_and_inner_corners() {
        let b = charuco();
        let markers = b.markers();
        // 35 squares, the top-left one black: 17 white squares.
        assert_eq!(markers.len(), 17);
        // Marker 0 sits in square (1, 0), centred.
        assert_eq!(markers[0].corners_m[0], Point3::new(0.04 + 0.01, 0.01, 0.0));
        // Marker 2 starts the second row, in square (0, 1).
        assert_eq!(markers[2].corners_m[0], Point3::new(0.01, 0.05, 0.0));
        let corners = b.chessboard_corners_m();
        assert_eq!(corners.len(), 4 * 6);
        assert_eq!(corners[0], Point3::new(0.04, 0.04, 0.0));
        assert_eq!(corners[4], Point3::new(0.04, 0.08, 0.0));
    }

    #[test]
    fn the_centre_frame_is_a_markers_frame_at_the_middle_of_the_print() {
        let b = grid();
        let c = b.board_from_centre();
        let [w, h] = b.size_m();
        assert!((c * Point3::origin() - Point3::new(w / 2.0, h / 2.0, 0.0)).norm() < 1e-12);
        // Up the print is -y of the board frame; out of it is -z.
        assert!((c * Vector3::y() + Vector3::y()).norm() < 1e-12);
        assert!((c * Vector3::z() + Vector3::z()).norm() < 1e-12);
        assert!((c * Vector3::x() - Vector3::x()).norm() < 1e-12);
    }

    #[test]
    fn bad_layouts_name_their_field() {
        let mut b = charuco();
        if let BoardLayout::Charuco { marker_length_m, .. } = &mut b {
            *marker_length_m = 0.05;
        }
        assert_eq!(b.validate().unwrap_err().field, "marker_length_m");
        let b = BoardLayout::Grid {
            markers_x: 0,
            markers_y: 1,
            marker_length_m: 1.0,
            separation_m: 1.0,
            first_id: 0,
        };
        assert_eq!(b.validate().unwrap_err().field, "markers_x");
        grid().validate().unwrap();
        charuco().validate().unwrap();
    }

    #[test]
    fn the_toml_form_is_tagged_by_kind() {
        let b: BoardLayout = toml::from_str(
            "kind = \"grid\"\nmarkers_x = 5\nmarkers_y = 7\nmarker_length_m = 0.04\nseparation_m = 0.01\n",
        )
        .unwrap();
        assert!(matches!(b, BoardLayout::Grid { first_id: 0, .. }));
        let c: BoardLayout = toml::from_str(
            "kind = \"charuco\"\nsquares_x = 5\nsquares_y = 7\nsquare_length_m = 0.04\nmarker_length_m = 0.02\n",
        )
        .unwrap();
        assert_eq!(c, charuco());
        assert!(toml::from_str::<BoardLayout>("kind = \"grid\"\nmarkers_x = 5\n").is_err());
    }
}
