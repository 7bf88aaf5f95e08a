//! The error type of the marker pipeline (dictionaries, detection, pose).

use thiserror::Error;

/// What went wrong while handling ArUco markers.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum MarkerError {
    /// The dictionary name is not one of OpenCV's predefined dictionaries.
    #[error("unknown ArUco dictionary {name:?}; valid names: {}", valid.join(", "))]
    UnknownDictionary {
        /// The name as given.
        name: String,
        /// Every valid name.
        valid: Vec<&'static str>,
    },
    /// The marker id is not in the dictionary.
    #[error("marker id {id} is not in {dictionary} (valid ids 0..{count})")]
    IdOutOfRange {
        /// Dictionary name.
        dictionary: &'static str,
        /// The id asked for.
        id: u32,
        /// Number of markers in the dictionary.
        count: u32,
    },
    /// The image's byte count does not match its size and pixel format.
    #[error("image {width}x{height} ({channels} channel(s)) should hold {expected} bytes, holds {len}")]
    BadImage {
        /// Width (px).
        width: u32,
        /// Height (px).
        height: u32,
        /// Channels per pixel.
        channels: usize,
        /// Bytes expected.
        expected: usize,
        /// Bytes present.
        len: usize,
    },
    /// The marker side length is not a positive finite number.
    #[error("marker size {size_m} m must be positive and finite")]
    BadMarkerSize {
        /// The size given (m).
        size_m: f64,
    },
    /// A detection has a non-finite corner.
    #[error("marker {id}: corner {corners_px:?} px is not finite")]
    NonFiniteCorner {
        /// Marker id.
        id: u32,
        /// The corners given (px).
        corners_px: [[f64; 2]; 4],
    },
    /// `solvePnP` found no pose.
    #[error("marker {id}: solvePnP (IPPE_SQUARE) found no pose")]
    NoPose {
        /// Marker id.
        id: u32,
    },
    /// A board layout that cannot be printed.
    #[error(transparent)]
    BadBoard(slidetrack_core::BadBoardLayout),
    /// Too few board points for a pose.
    #[error("board: {points} point(s) seen, at least {needed} needed for a pose")]
    TooFewBoardPoints {
        /// Points seen.
        points: usize,
        /// Points needed.
        needed: usize,
    },
    /// `solvePnP` found no board pose.
    #[error("board: solvePnP (ITERATIVE) found no pose from {points} point(s)")]
    NoBoardPose {
        /// Points given.
        points: usize,
    },
    /// An OpenCV call failed.
    #[error("OpenCV {operation} failed: {source}")]
    OpenCv {
        /// The OpenCV function, for example `detectMarkers`.
        operation: &'static str,
        /// OpenCV's error.
        #[source]
        source: opencv::Error,
    },
    /// An image that could not be encoded (JPEG, PNG).
    #[error("{format} encoding failed: {detail}")]
    Encode {
        /// `JPEG` or `PNG`.
        format: &'static str,
        /// The encoder's message.
        detail: String,
    },
    /// Image bytes that could not be decoded.
    #[error(transparent)]
    Decode(#[from] CodecError),
}

/// Attaches the OpenCV function name to OpenCV errors.
pub(crate) trait OpenCvContext<T> {
    /// Maps an OpenCV error to [`MarkerError::OpenCv`].
    fn cv(self, operation: &'static str) -> Result<T, MarkerError>;
}

impl<T> OpenCvContext<T> for opencv::Result<T> {
    fn cv(self, operation: &'static str) -> Result<T, MarkerError> {
        self.map_err(|source| MarkerError::OpenCv { operation, source })
    }
}

impl MarkerError {
    /// [`MarkerError::BadImage`] unless `image` holds exactly the bytes of
    /// its pixels.
    pub(crate) fn check_bytes(image: &slidetrack_core::Image) -> Result<(), MarkerError> {
        let channels = image.format.channels();
        let expected = image.width as usize * image.height as usize * channels;
        if image.data.len() != expected {
            return Err(MarkerError::BadImage {
                width: image.width,
                height: image.height,
                channels,
                expected,
                len: image.data.len(),
            });
        }
        Ok(())
    }
}

/// Why image bytes could not be decoded or encoded.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CodecError {
    /// Neither JPEG nor PNG (read from the first bytes).
    #[error("not a JPEG or PNG image (it starts with {start:02x?})")]
    UnknownFormat {
        /// Up to the first 8 bytes.
        start: Vec<u8>,
    },
    /// libjpeg-turbo refused the bytes or the image.
    #[error("JPEG: {0}")]
    Jpeg(#[from] turbojpeg::Error),
    /// A PNG that does not decode.
    #[error("PNG: {0}")]
    PngDecode(#[from] png::DecodingError),
    /// A PNG that could not be written.
    #[error("PNG: {0}")]
    PngEncode(#[from] png::EncodingError),
    /// A valid image of a kind this reading does not take.
    #[error("{0}")]
    Unsupported(String),
}
