//! Line plots of session channels, drawn with plotters into PNG files.

pub mod dekf;
pub mod ground_truth;
pub mod session;

use std::path::Path;
use std::sync::OnceLock;

use anyhow::{Context, Result, bail};
use plotters::coord::Shift;
use plotters::prelude::*;

/// Fonts tried for the text of plots, first found wins; `SLIDETRACK_FONT` overrides.
const FONT_PATHS: [&str; 5] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/liberation-sans/LiberationSans-Regular.ttf",
];

/// Registers a system font as plotters' `sans-serif` (once per process).
pub fn ensure_font() -> Result<()> {
    static FONT: OnceLock<Result<(), String>> = OnceLock::new();
    FONT.get_or_init(|| {
        let env = std::env::var("SLIDETRACK_FONT").ok();
        let candidates = env.iter().map(String::as_str).chain(FONT_PATHS);
        for path in candidates {
            if let Ok(bytes) = std::fs::read(path) {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                    return Ok(());
                }
            }
        }
        Err(format!(
            "no TrueType font found for plot text (tried {}); install fonts-dejavu-core or set SLIDETRACK_FONT",
            FONT_PATHS.join(", ")
        ))
    })
    .clone()
    .map_err(anyhow::Error::msg)
}

/// One line of a panel.
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Colour.
    pub colour: RGBColor,
    /// `(x, y)` points.
    pub points: Vec<(f64, f64)>,
    /// Draw as markers instead of a line.
    pub dots: bool,
}

impl Series {
    /// A line.
    pub fn line(label: impl Into<String>, colour: RGBColor, points: Vec<(f64, f64)>) -> Series {
        Series { label: label.into(), colour, points, dots: false }
    }

    /// Markers (for sparse or noisy data).
    pub fn dots(label: impl Into<String>, colour: RGBColor, points: Vec<(f64, f64)>) -> Series {
        Series { label: label.into(), colour, points, dots: true }
    }
}

/// A panel: title, axis labels and lines.
pub struct Panel {
    /// Title above the panel.
    pub title: String,
    /// Label of the y axis (with units).
    pub y_label: String,
    /// The lines.
    pub series: Vec<Series>,
}

/// Colours for up to six lines, then repeating.
pub const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

fn bounds(panels: &[Panel]) -> (f64, f64) {
    let xs = panels.iter().flat_map(|p| p.series.iter().flat_map(|s| s.points.iter().map(|q| q.0)));
    let (lo, hi) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| (lo.min(x), hi.max(x)));
    if lo.is_finite() && hi > lo { (lo, hi) } else { (0.0, 1.0) }
}

fn y_bounds(panel: &Panel) -> (f64, f64) {
    let ys = panel.series.iter().flat_map(|s| s.points.iter().map(|q| q.1)).filter(|y| y.is_finite());
    let (lo, hi) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), y| (lo.min(y), hi.max(y)));
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-9);
    (lo - pad, hi + pad)
}

/// Draws `panels` stacked vertically, sharing the time axis (s), into `out` (PNG).
pub fn draw_stacked(out: &Path, title: &str, panels: &[Panel]) -> Result<()> {
    draw_stacked_x(out, title, "time (s)", panels)
}

/// Draws `panels` stacked vertically, sharing an x axis labelled `x_label`, into `out` (PNG).
pub fn draw_stacked_x(out: &Path, title: &str, x_label: &str, panels: &[Panel]) -> Result<()> {
    ensure_font()?;
    if panels.iter().all(|p| p.series.iter().all(|s| s.points.is_empty())) {
        bail!("nothing to plot: the session has no data for this plot");
    }
    let height = 60 + 300 * panels.len() as u32;
    let root = BitMapBackend::new(out, (1400, height)).into_drawing_area();
    let draw = || -> Result<(), Box<dyn std::error::Error + '_>> {
        root.fill(&WHITE)?;
        let (root_title, body) = root.split_vertically(50);
        root_title.titled(title, ("sans-serif", 26))?;
        let areas = body.split_evenly((panels.len(), 1));
        let x_range = bounds(panels);
        for (area, panel) in areas.iter().zip(panels) {
            draw_panel(area, panel, x_range, x_label)?;
        }
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| anyhow::anyhow!("{e}")).with_context(|| format!("cannot draw {}", out.display()))
}

fn draw_panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    panel: &Panel,
    (x0, x1): (f64, f64),
    x_label: &str,
) -> Result<(), Box<dyn std::error::Error>> {
    let (y0, y1) = y_bounds(panel);
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart.configure_mesh().x_desc(x_label).y_desc(&panel.y_label).light_line_style(WHITE.mix(0.0)).draw()?;
    for s in &panel.series {
        let colour = s.colour;
        if s.dots {
            chart
                .draw_series(s.points.iter().map(|&p| Circle::new(p, 2, colour.filled())))?
                .label(&s.label)
                .legend(move |(x, y)| Circle::new((x + 10, y), 3, colour.filled()));
        } else {
            chart
                .draw_series(LineSeries::new(s.points.iter().copied(), colour.stroke_width(2)))?
                .label(&s.label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .label_font(("sans-serif", 15))
        .draw()?;
    Ok(())
}
