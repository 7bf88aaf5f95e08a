//! Why the camera's pose in the hand frame cannot be estimated.

use thiserror::Error;

/// Why [`crate::hand_eye::estimate_hand_from_camera`] gives no result.
#[derive(Clone, Debug, Error, PartialEq)]
#[non_exhaustive]
pub enum HandEyeError {
    /// Too few frames saw the target with a low enough reprojection error.
    #[error(
        "only {usable} of {total} frames saw the hand's target with a usable pose; at least {needed} needed"
    )]
    TooFewFrames {
        /// Frames with a usable pose.
        usable: usize,
        /// Fewest frames needed.
        needed: usize,
        /// Frames given.
        total: usize,
    },
    /// Too many frames disagree with the first average (the target or the
    /// camera moved, or single-marker poses flipped).
    #[error(
        "only {kept} of {usable} usable frames agree with their average; at least {needed} needed (did the hand or the camera move?)"
    )]
    TooManyOutliers {
        /// Frames within the outlier limits.
        kept: usize,
        /// Fewest frames needed.
        needed: usize,
        /// Frames with a usable pose.
        usable: usize,
    },
}
