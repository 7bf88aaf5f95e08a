//! Dense optical flow on the CPU with OpenCV's DIS (Dense Inverse Search):
//! the flow `F_t` from the previous colour frame to the current one (thesis
//! (3.33)-(3.35)). ROFT needs it only on the pixels of the object's mask, so
//! it is computed over the mask's bounding box grown by a margin that covers
//! the largest expected displacement; outside that region it is unknown.

use opencv::core::{Mat, Rect, Vec2f, Vec3b};
use opencv::prelude::*;
use opencv::video::{self, DISOpticalFlow};
use slidetrack_core::{Image, PixelFormat};
use slidetrack_estimators::roft::{FlowField, PixelBox};

use crate::VisionError;
use crate::error::OpenCvContext;

/// DIS presets (OpenCV's speed / accuracy trade-offs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DisPreset {
    /// Fastest, coarsest.
    UltraFast,
    /// OpenCV's default trade-off.
    #[default]
    Fast,
    /// Most accurate, slowest.
    Medium,
}

/// Settings of the flow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FlowConfig {
    /// DIS preset.
    pub preset: DisPreset,
    /// Pixels added on every side of the requested region.
    pub margin_px: u32,
    /// Finest pyramid level DIS computes the flow at (0 = full resolution),
    /// overriding the preset's; `None` keeps the preset's.
    pub finest_scale: Option<i32>,
}

impl Default for FlowConfig {
    /// `UltraFast` refined down to half resolution (finest scale 1), 40 px of
    /// margin (an object at 0.5 m moving at 0.6 m/s crosses about 25 px per
    /// frame at 30 Hz with a 640 px, 60 degree camera). On the simulated fast
    /// sequences this halves the error of the angular velocity estimated
    /// from the flow against the `Fast` preset (whose quarter-resolution
    /// flow smooths out the flow gradients of out-of-plane rotations), at
    /// about the same cost.
    fn default() -> FlowConfig {
        FlowConfig { preset: DisPreset::UltraFast, margin_px: 40, finest_scale: Some(1) }
    }
}

/// The flow between consecutive frames of one camera.
pub struct OpticalFlow {
    dis: opencv::core::Ptr<DISOpticalFlow>,
    config: FlowConfig,
    previous: Option<Mat>,
}

impl OpticalFlow {
    /// A DIS instance with `config`.
    pub fn new(config: FlowConfig) -> Result<OpticalFlow, VisionError> {
        let preset = match config.preset {
            DisPreset::UltraFast => video::DISOpticalFlow_PRESET_ULTRAFAST,
            DisPreset::Fast => video::DISOpticalFlow_PRESET_FAST,
            DisPreset::Medium => video::DISOpticalFlow_PRESET_MEDIUM,
        };
        let mut dis = DISOpticalFlow::create(preset).cv("creating DIS optical flow")?;
        if let Some(level) = config.finest_scale {
            dis.set_finest_scale(level.max(0)).cv("DIS finest scale")?;
        }
        Ok(OpticalFlow { dis, config, previous: None })
    }

    /// Forgets the previous frame (the next call returns no flow).
    pub fn reset(&mut self) {
        self.previous = None;
    }

    /// Takes the next colour frame and returns the flow from the previous
    /// frame to it over `region` grown by the margin (the whole image when
    /// `None`); `None` for the first frame or an empty region.
    pub fn next(
        &mut self,
        color: &Image,
        region: Option<PixelBox>,
    ) -> Result<Option<FlowField>, VisionError> {
        let gray = gray(color)?;
        let previous = self.previous.replace(gray);
        let (Some(previous), Some(current)) = (previous, self.previous.as_ref()) else {
            return Ok(None);
        };
        if (previous.cols(), previous.rows()) != (current.cols(), current.rows()) {
            return Err(VisionError::SizeMismatch {
                what: "colour frame",
                width: current.cols() as u32,
                height: current.rows() as u32,
                expected_width: previous.cols() as u32,
                expected_height: previous.rows() as u32,
            });
        }
        let full = PixelBox { u0: 0, v0: 0, u1: color.width, v1: color.height };
        let region = match region {
            Some(r) => r.grown(self.config.margin_px, color.width, color.height),
            None => full,
        };
        // DIS needs a few patches to work with.
        if region.width() < 16 || region.height() < 16 {
            return Ok(None);
        }
        let rect =
            Rect::new(region.u0 as i32, region.v0 as i32, region.width() as i32, region.height() as i32);
        let i0 = Mat::roi(&previous, rect).cv("previous frame region")?.try_clone().cv("copy")?;
        let i1 = Mat::roi(current, rect).cv("current frame region")?.try_clone().cv("copy")?;
        let mut flow = Mat::default();
        self.dis.calc(&i0, &i1, &mut flow).cv("DIS optical flow")?;
        let data = flow.data_typed::<Vec2f>().cv("flow data")?;
        let flow_px = data.iter().map(|v| [v[0], v[1]]).collect();
        Ok(Some(FlowField { region, flow_px }))
    }
}

/// The luma of an RGB (or gray) image as an 8-bit OpenCV matrix.
fn gray(image: &Image) -> Result<Mat, VisionError> {
    let expected = image.width as usize * image.height as usize * image.format.channels();
    if image.data.len() != expected || image.width == 0 || image.height == 0 {
        return Err(VisionError::BadImage {
            what: "colour frame",
            detail: format!("{} bytes for {}x{} px", image.data.len(), image.width, image.height),
        });
    }
    let (rows, cols) = (image.height as i32, image.width as i32);
    match image.format {
        PixelFormat::Gray8 => Mat::new_rows_cols_with_data::<u8>(rows, cols, &image.data)
            .cv("gray frame")?
            .try_clone()
            .cv("copy"),
        PixelFormat::Rgb8 => {
            let rgb = Mat::new_rows_cols_with_bytes::<Vec3b>(rows, cols, &image.data).cv("colour frame")?;
            let mut out = Mat::default();
            opencv::imgproc::cvt_color_def(&rgb, &mut out, opencv::imgproc::COLOR_RGB2GRAY).cv("cvtColor")?;
            Ok(out)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth random texture shifted by (3, -2) px between frames.
    fn textured(width: u32, height: u32, du: i32, dv: i32) -> Image {
        let f = |x: i32, y: i32| -> u8 {
            let (x, y) = (f64::from(x), f64::from(y));
            (128.0
                + 50.0 * (x * 0.21).sin() * (y * 0.17).cos()
                + 40.0 * ((x + 2.0 * y) * 0.09).sin()
                + 30.0 * (x * 0.05 - y * 0.13).cos()) as u8
        };
        let mut data = Vec::with_capacity((width * height * 3) as usize);
        for y in 0..height as i32 {
            for x in 0..width as i32 {
                let g = f(x - du, y - dv);
                data.extend([g, g / 2 + 60, 255 - g]);
            }
        }
        Image { width, height, format: PixelFormat::Rgb8, data }
    }

    #[test]
    fn dis_recovers_a_uniform_shift_in_a_region() {
        let mut flow = OpticalFlow::new(FlowConfig::default()).unwrap();
        assert!(flow.next(&textured(160, 120, 0, 0), None).unwrap().is_none());
        let region = PixelBox { u0: 60, v0: 40, u1: 100, v1: 80 };
        let f = flow.next(&textured(160, 120, 3, -2), Some(region)).unwrap().unwrap();
        assert_eq!(f.region, region.grown(40, 160, 120));
        let centre = f.at(80, 60).unwrap();
        assert!((centre[0] - 3.0).abs() < 0.3 && (centre[1] + 2.0).abs() < 0.3, "{centre:?}");
        assert!(f.at(0, 0).is_none(), "outside the region the flow is unknown");
        let wrong = Image { width: 80, height: 60, format: PixelFormat::Rgb8, data: vec![0; 80 * 60 * 3] };
        assert!(flow.next(&wrong, None).is_err());
        let broken = Image { width: 80, height: 60, format: PixelFormat::Rgb8, data: vec![0; 10] };
        assert!(matches!(flow.next(&broken, None), Err(VisionError::BadImage { .. })));
    }
}
