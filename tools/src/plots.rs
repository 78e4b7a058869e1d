//! PNG plots of a SLAM run, drawn with plotters' bitmap backend.
//!
//! - [`trajectory`]: dead reckoning, optimised and ground-truth trajectories.
//! - [`loops`]: accepted and rejected loop closures over the trajectory.
//! - [`precision_recall`]: the precision-recall curve of the loop gate.
//!
//! Text is drawn with DejaVu Sans embedded in the binary
//! (`tools/assets/DejaVuSans.ttf`, Bitstream Vera licence), so plots get
//! their labels on machines without any system font. Pictures are drawn into
//! an RGB buffer and encoded here with a fast PNG compression level; callers
//! write the bytes (atomically) where they like.

pub mod loops;
pub mod precision_recall;
pub mod trajectory;

use anyhow::{Result, anyhow};
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::sync::OnceLock;

/// The embedded font, registered as plotters' `sans-serif` family.
static DEJAVU_SANS: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// The font family every plot uses.
pub const FONT: &str = "sans-serif";

/// Registers the embedded font with plotters (once per process).
fn register_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, DEJAVU_SANS).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(anyhow!("the embedded DejaVu Sans font could not be loaded"))
    }
}

/// A plotters error as an `anyhow` error (plotters' error types carry the
/// backend's error, which need not be `Send`).
pub(crate) fn plot_error<E: std::fmt::Display>(err: E) -> anyhow::Error {
    anyhow!("drawing the plot: {err}")
}

/// Draws a `width` x `height` picture on a white background with `draw` and
/// returns it as PNG bytes.
pub fn render_png<F>(width: u32, height: u32, draw: F) -> Result<Vec<u8>>
where
    F: FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<()>,
{
    register_font()?;
    let mut rgb = vec![255u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
        draw(&root)?;
        root.present().map_err(plot_error)?;
    }
    encode_png(&rgb, width, height, ExtendedColorType::Rgb8)
}

/// Draws with `draw` over an existing RGB picture (`width` x `height`,
/// row-major, 3 bytes per pixel) in place. Precondition: `rgb` holds
/// exactly that many bytes.
pub fn draw_over<F>(rgb: &mut [u8], width: u32, height: u32, draw: F) -> Result<()>
where
    F: FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<()>,
{
    register_font()?;
    let root = BitMapBackend::with_buffer(rgb, (width, height)).into_drawing_area();
    draw(&root)?;
    root.present().map_err(plot_error)
}

/// Encodes raw 8-bit pixels (RGB or grey) as PNG with fast compression:
/// output pictures are written on every run, and the default level costs
/// several times more for a few percent smaller files.
pub fn encode_png(
    pixels: &[u8],
    width: u32,
    height: u32,
    colour: ExtendedColorType,
) -> Result<Vec<u8>> {
    let mut bytes = Vec::with_capacity(pixels.len() / 4);
    PngEncoder::new_with_quality(&mut bytes, CompressionType::Fast, FilterType::Sub)
        .write_image(pixels, width, height, colour)
        .map_err(|e| anyhow!("encoding a {width}x{height} PNG: {e}"))?;
    Ok(bytes)
}

/// Axis ranges `(x, y)` in metres covering `points` with a margin, widened
/// so that one metre has the same length in pixels along both axes of a
/// plotting area of `area_px` pixels (equal aspect).
pub fn equal_aspect_ranges(
    points: impl IntoIterator<Item = (f64, f64)>,
    area_px: (u32, u32),
    margin_fraction: f64,
) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for (x, y) in points {
        if x.is_finite() && y.is_finite() {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (-1.0, 1.0, -1.0, 1.0);
    }
    // At least 1 m of span, then the margin on every side.
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let span_x = (x1 - x0).max(1.0) * (1.0 + 2.0 * margin_fraction);
    let span_y = (y1 - y0).max(1.0) * (1.0 + 2.0 * margin_fraction);
    let (w, h) = (f64::from(area_px.0.max(1)), f64::from(area_px.1.max(1)));
    let metres_per_px = (span_x / w).max(span_y / h);
    let (half_x, half_y) = (0.5 * metres_per_px * w, 0.5 * metres_per_px * h);
    ((cx - half_x)..(cx + half_x), (cy - half_y)..(cy + half_y))
}

/// The corner of the chart (ranges `xs` x `ys`) where the legend hides the
/// fewest of `points`: the upper-left unless another corner is emptier.
pub fn legend_corner(
    points: impl IntoIterator<Item = (f64, f64)>,
    xs: &std::ops::Range<f64>,
    ys: &std::ops::Range<f64>,
) -> SeriesLabelPosition {
    // The legend covers about a third of the width and a fifth of the height.
    let (w, h) = (xs.end - xs.start, ys.end - ys.start);
    let mut counts = [0usize; 4]; // upper-left, upper-right, lower-left, lower-right
    for (x, y) in points {
        let left = x < xs.start + 0.35 * w;
        let right = x > xs.end - 0.35 * w;
        let upper = y > ys.end - 0.2 * h;
        let lower = y < ys.start + 0.2 * h;
        for (k, inside) in [left && upper, right && upper, left && lower, right && lower]
            .into_iter()
            .enumerate()
        {
            counts[k] += usize::from(inside);
        }
    }
    match (0..4).min_by_key(|&k| counts[k]) {
        Some(1) => SeriesLabelPosition::UpperRight,
        Some(2) => SeriesLabelPosition::LowerLeft,
        Some(3) => SeriesLabelPosition::LowerRight,
        _ => SeriesLabelPosition::UpperLeft,
    }
}

/// The chart layout every map-like plot (trajectory, loops) shares: a
/// caption, x and y label areas; returns the plotting area's size in pixels
/// for [`equal_aspect_ranges`].
pub(crate) fn map_chart_builder<'a, 'b>(
    root: &'a DrawingArea<BitMapBackend<'b>, Shift>,
    caption: &str,
) -> ChartBuilder<'a, 'b, BitMapBackend<'b>> {
    let mut builder = ChartBuilder::on(root);
    builder
        .caption(caption, (FONT, 24))
        .margin(16)
        .x_label_area_size(44)
        .y_label_area_size(64);
    builder
}

/// Size of the plotting area that [`map_chart_builder`] leaves in `root`.
pub(crate) fn map_plot_area_px(
    root: &DrawingArea<BitMapBackend<'_>, Shift>,
    caption: &str,
) -> Result<(u32, u32)> {
    let chart = map_chart_builder(root, caption)
        .build_cartesian_2d(0.0..1.0, 0.0..1.0)
        .map_err(plot_error)?;
    Ok(chart.plotting_area().dim_in_pixel())
}

/// A chart on a bitmap with `f64` axes, as every plot here draws.
pub(crate) type Chart<'a, 'b> = ChartContext<
    'a,
    BitMapBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// The grid, tick labels and axis names every plot shares.
pub(crate) fn draw_grid(chart: &mut Chart<'_, '_>, x_desc: &str, y_desc: &str) -> Result<()> {
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(210, 210, 210))
        .draw()
        .map_err(plot_error)
}

/// The legend of the labelled series, in a framed box at `position`.
pub(crate) fn draw_legend<'a, 'b: 'a>(
    chart: &mut Chart<'a, 'b>,
    position: SeriesLabelPosition,
) -> Result<()> {
    chart
        .configure_series_labels()
        .position(position)
        .label_font((FONT, 15))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(plot_error)
}

/// A legend entry: a short line in `colour`.
pub(crate) fn legend_line(colour: RGBColor) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| PathElement::new([(x, y), (x + 20, y)], colour.stroke_width(3))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_aspect_ranges_have_equal_metres_per_pixel() {
        let (x, y) = equal_aspect_ranges([(0.0, 0.0), (100.0, 10.0)], (800, 600), 0.0);
        let mx = (x.end - x.start) / 800.0;
        let my = (y.end - y.start) / 600.0;
        assert!((mx - my).abs() < 1e-12, "{mx} vs {my}");
        // The wide axis is exactly covered, the other is centred.
        assert!((x.start - 0.0).abs() < 1e-9 && (x.end - 100.0).abs() < 1e-9);
        assert!(((y.start + y.end) / 2.0 - 5.0).abs() < 1e-9);
    }

    #[test]
    fn legend_goes_to_the_emptiest_corner() {
        let (xs, ys) = (0.0..10.0, 0.0..10.0);
        let upper_left = [(1.0, 9.0), (2.0, 9.5)];
        assert!(matches!(
            legend_corner(upper_left, &xs, &ys),
            SeriesLabelPosition::UpperRight
        ));
        assert!(matches!(
            legend_corner([(5.0, 5.0)], &xs, &ys),
            SeriesLabelPosition::UpperLeft
        ));
    }

    #[test]
    fn rendered_png_decodes_with_its_size() {
        let png = render_png(120, 80, |root| {
            root.draw(&Text::new("label", (10, 10), (FONT, 14)))
                .map_err(plot_error)?;
            Ok(())
        })
        .unwrap();
        let picture = image::load_from_memory(&png).unwrap();
        assert_eq!((picture.width(), picture.height()), (120, 80));
        // The text drew dark pixels on the white background.
        let rgb = picture.to_rgb8();
        assert!(rgb.pixels().any(|p| p.0[0] < 128));
    }
}
