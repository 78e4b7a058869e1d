//! `loops_pr.png`: precision against recall of the loop-closure gate, one
//! curve per swept quality metric, with the best-F1 threshold marked.

use super::{FONT, draw_grid, draw_legend, legend_line, plot_error, render_png};
use anyhow::Result;
use plotters::prelude::*;

const COLOURS: [RGBColor; 4] = [
    RGBColor(30, 90, 200),
    RGBColor(220, 100, 20),
    RGBColor(0, 150, 70),
    RGBColor(150, 40, 160),
];

/// One curve: `(recall, precision)` points in threshold order.
#[derive(Clone, Debug)]
pub struct PrCurve {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    /// The best-F1 point `(recall, precision)` and its threshold, ringed
    /// on the curve and named in the legend.
    pub best: Option<(f64, f64, f64)>,
}

/// The precision axis: from just below the lowest precision drawn (on a
/// multiple of 0.05, at most 0.95) to just above 1, so that curves whose
/// precision stays near 1 use the plot's height.
fn precision_axis(curves: &[PrCurve]) -> std::ops::Range<f64> {
    let lowest = curves
        .iter()
        .flat_map(|c| c.points.iter().map(|p| p.1).chain(c.best.map(|b| b.1)))
        .filter(|p| p.is_finite())
        .fold(1.0, f64::min);
    let bottom = (((lowest - 0.02) / 0.05).floor() * 0.05).clamp(0.0, 0.95);
    bottom..1.0 + 0.02 * (1.0 - bottom)
}

/// Draws the curves as a PNG of `size_px`: recall on 0-1, precision on
/// [`precision_axis`].
pub fn precision_recall_png(
    curves: &[PrCurve],
    caption: &str,
    size_px: (u32, u32),
) -> Result<Vec<u8>> {
    render_png(size_px.0, size_px.1, |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(caption, (FONT, 24))
            .margin(16)
            .x_label_area_size(44)
            .y_label_area_size(56)
            .build_cartesian_2d(0.0..1.02, precision_axis(curves))
            .map_err(plot_error)?;
        draw_grid(&mut chart, "recall", "precision")?;
        for (k, curve) in curves.iter().enumerate() {
            let colour = COLOURS[k % COLOURS.len()];
            let label = match curve.best {
                Some((_, _, t)) => format!("{} (best F1 at t = {t:.4})", curve.label),
                None => curve.label.clone(),
            };
            chart
                .draw_series(LineSeries::new(
                    curve.points.iter().copied(),
                    colour.stroke_width(2),
                ))
                .map_err(plot_error)?
                .label(label)
                .legend(legend_line(colour));
            // Few points: show each threshold; many: the line says enough.
            if curve.points.len() <= 40 {
                chart
                    .draw_series(
                        curve
                            .points
                            .iter()
                            .map(|&p| Circle::new(p, 3, colour.filled())),
                    )
                    .map_err(plot_error)?;
            }
            if let Some((r, p, _)) = curve.best {
                chart
                    .draw_series([Circle::new((r, p), 9, colour.stroke_width(2))])
                    .map_err(plot_error)?;
            }
        }
        draw_legend(&mut chart, SeriesLabelPosition::LowerLeft)?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn precision_axis_starts_just_below_the_lowest_precision() {
        let curve = |points: Vec<(f64, f64)>| PrCurve {
            label: "q".into(),
            points,
            best: None,
        };
        let high = precision_axis(&[curve(vec![(0.1, 1.0), (0.8, 0.975)])]);
        assert!(
            (high.start - 0.95).abs() < 1e-12 && high.end > 1.0,
            "{high:?}"
        );
        let low = precision_axis(&[curve(vec![(0.1, 1.0), (1.0, 0.31)])]);
        assert!((low.start - 0.25).abs() < 1e-12, "{low:?}");
        let none = precision_axis(&[curve(vec![(0.5, 0.0)])]);
        assert_eq!(none.start, 0.0);
    }

    #[test]
    fn curve_is_drawn_in_its_colour() {
        let curve = PrCurve {
            label: "mean intensity".into(),
            points: vec![(0.25, 1.0), (0.5, 1.0), (0.75, 0.75), (1.0, 0.5)],
            best: Some((0.75, 0.75, 0.42)),
        };
        let png = precision_recall_png(&[curve], "PR", (400, 300)).unwrap();
        let rgb = image::load_from_memory(&png).unwrap().to_rgb8();
        assert_eq!(rgb.dimensions(), (400, 300));
        let c = COLOURS[0];
        assert!(rgb.pixels().any(|p| p.0 == [c.0, c.1, c.2]));
    }
}
