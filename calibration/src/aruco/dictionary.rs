//! OpenCV's predefined ArUco (and AprilTag) dictionaries and their markers' bits.

use opencv::aruco::{self, DictionaryTraitConst};
use opencv::core::{Mat, MatTraitConst, Ptr};
use slidetrack_core::MarkerPattern;

use crate::error::{MarkerError, OpenCvContext};

/// Every predefined dictionary of OpenCV 4.6, by its OpenCV name.
const PREDEFINED: [(&str, i32); 21] = [
    ("DICT_4X4_50", aruco::DICT_4X4_50),
    ("DICT_4X4_100", aruco::DICT_4X4_100),
    ("DICT_4X4_250", aruco::DICT_4X4_250),
    ("DICT_4X4_1000", aruco::DICT_4X4_1000),
    ("DICT_5X5_50", aruco::DICT_5X5_50),
    ("DICT_5X5_100", aruco::DICT_5X5_100),
    ("DICT_5X5_250", aruco::DICT_5X5_250),
    ("DICT_5X5_1000", aruco::DICT_5X5_1000),
    ("DICT_6X6_50", aruco::DICT_6X6_50),
    ("DICT_6X6_100", aruco::DICT_6X6_100),
    ("DICT_6X6_250", aruco::DICT_6X6_250),
    ("DICT_6X6_1000", aruco::DICT_6X6_1000),
    ("DICT_7X7_50", aruco::DICT_7X7_50),
    ("DICT_7X7_100", aruco::DICT_7X7_100),
    ("DICT_7X7_250", aruco::DICT_7X7_250),
    ("DICT_7X7_1000", aruco::DICT_7X7_1000),
    ("DICT_ARUCO_ORIGINAL", aruco::DICT_ARUCO_ORIGINAL),
    ("DICT_APRILTAG_16h5", aruco::DICT_APRILTAG_16h5),
    ("DICT_APRILTAG_25h9", aruco::DICT_APRILTAG_25h9),
    ("DICT_APRILTAG_36h10", aruco::DICT_APRILTAG_36h10),
    ("DICT_APRILTAG_36h11", aruco::DICT_APRILTAG_36h11),
];

/// One of OpenCV's predefined ArUco (or AprilTag) dictionaries.
pub struct Dictionary {
    name: &'static str,
    inner: Ptr<aruco::Dictionary>,
}

impl std::fmt::Debug for Dictionary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Dictionary").field("name", &self.name).finish()
    }
}

impl Dictionary {
    /// Every valid dictionary name (`DICT_4X4_50` ... `DICT_APRILTAG_36h11`).
    pub fn names() -> impl Iterator<Item = &'static str> {
        PREDEFINED.iter().map(|(name, _)| *name)
    }

    /// The predefined dictionary of that exact OpenCV name (for example `DICT_6X6_250`).
    pub fn from_name(name: &str) -> Result<Dictionary, MarkerError> {
        let Some(&(name, id)) = PREDEFINED.iter().find(|(n, _)| *n == name) else {
            return Err(MarkerError::UnknownDictionary {
                name: name.to_owned(),
                valid: Dictionary::names().collect(),
            });
        };
        let inner = aruco::get_predefined_dictionary_i32(id).cv("getPredefinedDictionary")?;
        Ok(Dictionary { name, inner })
    }

    /// The OpenCV name of the dictionary.
    pub fn name(&self) -> &'static str {
        self.name
    }

    /// The OpenCV dictionary itself.
    pub(crate) fn opencv(&self) -> &Ptr<aruco::Dictionary> {
        &self.inner
    }

    /// Inner cells per marker side (without the black border).
    pub fn cells(&self) -> usize {
        self.inner.marker_size().max(0) as usize
    }

    /// Number of markers; valid ids are `0..count`.
    pub fn count(&self) -> u32 {
        self.inner.bytes_list().rows().max(0) as u32
    }

    /// The bits of marker `id`, read back from OpenCV's own drawing of it.
    pub fn marker_pattern(&self, id: u32) -> Result<MarkerPattern, MarkerError> {
        let count = self.count();
        if id >= count {
            return Err(MarkerError::IdOutOfRange { dictionary: self.name, id, count });
        }
        let cells = self.cells();
        let side = cells as i32 + 2;
        let mut drawn = Mat::default();
        // One pixel per cell, one border cell: the inner cells are the bits.
        aruco::draw_marker(&self.inner, id as i32, side, &mut drawn, 1).cv("drawMarker")?;
        let mut bits = Vec::with_capacity(cells * cells);
        for row in 0..cells as i32 {
            for col in 0..cells as i32 {
                let value = *drawn.at_2d::<u8>(row + 1, col + 1).cv("Mat::at")?;
                bits.push(u8::from(value > 127));
            }
        }
        Ok(MarkerPattern { dictionary: self.name.to_owned(), id, cells, bits })
    }
}

/// The bits of marker `id` of the predefined dictionary `dictionary_name`
/// (row-major from the top-left as printed, 1 = white), for the simulator.
pub fn marker_pattern(dictionary_name: &str, id: u32) -> Result<MarkerPattern, MarkerError> {
    Dictionary::from_name(dictionary_name)?.marker_pattern(id)
}
