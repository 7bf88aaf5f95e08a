//! What a marker detector reports: a marker's id and corners, and the pixel
//! rectangle a search is limited to.

/// One detected marker.
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerDetection {
    /// Marker id in the detector's dictionary.
    pub id: u32,
    /// Corners in image pixels (OpenCV convention: integer positions are pixel
    /// centres), in OpenCV's order: top-left, top-right, bottom-right,
    /// bottom-left of the marker as printed.
    pub corners_px: [[f64; 2]; 4],
}

impl MarkerDetection {
    /// Mean of the four corners (px).
    pub fn centre_px(&self) -> [f64; 2] {
        let sum = self.corners_px.iter().fold([0.0, 0.0], |s, c| [s[0] + c[0], s[1] + c[1]]);
        [sum[0] / 4.0, sum[1] / 4.0]
    }

    /// Mean side length (px).
    pub fn side_px(&self) -> f64 {
        (0..4)
            .map(|k| {
                let (a, b) = (self.corners_px[k], self.corners_px[(k + 1) % 4]);
                (a[0] - b[0]).hypot(a[1] - b[1])
            })
            .sum::<f64>()
            / 4.0
    }
}

/// A pixel rectangle of an image: columns `x..x + width`, rows `y..y + height`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelRoi {
    /// First column (px).
    pub x: u32,
    /// First row (px).
    pub y: u32,
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
}
