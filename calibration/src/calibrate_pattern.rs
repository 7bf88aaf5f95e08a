//! Calibration patterns and their textual form
//! (`chessboard:9x6:0.025`, `charuco:5x7:0.04:0.02:DICT_6X6_250`,
//! `circles-asym:4x11:0.02`).

use std::fmt;

use super::error::CalibrationError;

/// A planar calibration pattern.
#[derive(Clone, Debug, PartialEq)]
pub enum Pattern {
    /// A chessboard: `inner_corners = [per row, per column]` (OpenCV's
    /// pattern size, 9x6 for its sample board), squares of `square_m`.
    Chessboard {
        /// Inner corners `[columns, rows]`.
        inner_corners: [u32; 2],
        /// Side of a square (m).
        square_m: f64,
    },
    /// A ChArUco board of `squares = [x, y]` squares of `square_m` with
    /// markers of `marker_m` from `dictionary`.
    Charuco {
        /// Squares `[along x, along y]`.
        squares: [u32; 2],
        /// Side of a square (m).
        square_m: f64,
        /// Side of a marker (m).
        marker_m: f64,
        /// OpenCV predefined dictionary name.
        dictionary: String,
    },
    /// An asymmetric circle grid of `grid = [circles per row, rows]`; the
    /// circles of one row are `2 spacing_m` apart, rows `spacing_m` apart
    /// and every other row shifted by `spacing_m` (OpenCV's `squareSize`).
    CirclesAsym {
        /// `[circles per row, rows]`, OpenCV's pattern size (4x11 for its sample).
        grid: [u32; 2],
        /// OpenCV's `squareSize` for the grid (m).
        spacing_m: f64,
    },
}

impl fmt::Display for Pattern {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Pattern::Chessboard { inner_corners: [c, r], square_m } => {
                write!(f, "chessboard:{c}x{r}:{square_m}")
            }
            Pattern::Charuco { squares: [x, y], square_m, marker_m, dictionary } => {
                write!(f, "charuco:{x}x{y}:{square_m}:{marker_m}:{dictionary}")
            }
            Pattern::CirclesAsym { grid: [c, r], spacing_m } => write!(f, "circles-asym:{c}x{r}:{spacing_m}"),
        }
    }
}

/// Parses a pattern description.
pub(super) fn parse(spec: &str) -> Result<Pattern, CalibrationError> {
    let bad =
        |reason: &str| CalibrationError::BadPattern { spec: spec.to_string(), reason: reason.to_string() };
    let parts: Vec<&str> = spec.split(':').collect();
    let grid = |s: &str, min: u32| -> Result<[u32; 2], CalibrationError> {
        let (a, b) = s.split_once(['x', 'X']).ok_or_else(|| bad(&format!("{s:?} is not COLSxROWS")))?;
        let n = |v: &str| v.trim().parse::<u32>().ok().filter(|n| *n >= min && *n <= 1000);
        match (n(a), n(b)) {
            (Some(a), Some(b)) => Ok([a, b]),
            _ => Err(bad(&format!("{s:?}: both counts must be whole numbers from {min}"))),
        }
    };
    let length = |s: &str, what: &str| -> Result<f64, CalibrationError> {
        s.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && *v > 0.0 && *v < 10.0)
            .ok_or_else(|| bad(&format!("{what} {s:?} must be a length in metres (0 < size < 10)")))
    };
    match parts.as_slice() {
        ["chessboard", g, s] => {
            Ok(Pattern::Chessboard { inner_corners: grid(g, 2)?, square_m: length(s, "square size")? })
        }
        ["charuco", g, s, m, rest @ ..] if rest.len() <= 1 => {
            let square_m = length(s, "square size")?;
            let marker_m = length(m, "marker size")?;
            if marker_m >= square_m {
                return Err(bad("the marker must be smaller than the square"));
            }
            let dictionary = rest.first().map_or("DICT_6X6_250", |d| d.trim()).to_string();
            Ok(Pattern::Charuco { squares: grid(g, 2)?, square_m, marker_m, dictionary })
        }
        ["circles-asym", g, s] => {
            Ok(Pattern::CirclesAsym { grid: grid(g, 2)?, spacing_m: length(s, "spacing")? })
        }
        [kind, ..] if !["chessboard", "charuco", "circles-asym"].contains(kind) => {
            Err(bad(&format!("unknown pattern kind {kind:?} (chessboard, charuco or circles-asym)")))
        }
        _ => Err(bad("wrong number of fields")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_three_kinds_parse_and_print_back() {
        for spec in ["chessboard:9x6:0.025", "charuco:5x7:0.04:0.02:DICT_6X6_250", "circles-asym:4x11:0.02"] {
            let p = parse(spec).unwrap();
            assert_eq!(p.to_string(), spec);
        }
        assert_eq!(
            parse("charuco:5x7:0.04:0.02").unwrap(),
            Pattern::Charuco {
                squares: [5, 7],
                square_m: 0.04,
                marker_m: 0.02,
                dictionary: "DICT_6X6_250".into()
            }
        );
    }

    #[test]
    fn bad_descriptions_say_what_is_wrong() {
        for (spec, needle) in [
            ("chessboard:9x6", "number of fields"),
            ("chessboard:9by6:0.025", "COLSxROWS"),
            ("chessboard:9x1:0.025", "from 2"),
            ("chessboard:9x6:25mm", "metres"),
            ("charuco:5x7:0.02:0.04", "smaller"),
            ("checkerboard:9x6:0.025", "unknown pattern kind"),
        ] {
            let msg = parse(spec).unwrap_err().to_string();
            assert!(msg.contains(needle) && msg.contains(spec), "{spec}: {msg}");
        }
    }
}
