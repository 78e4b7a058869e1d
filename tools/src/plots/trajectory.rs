//! `trajectory.png`: the trajectories of a run in the world frame (x east,
//! y north, metres, equal aspect), with a legend; the ground truth dashed
//! on top, so that it stays visible where the estimate covers it.
//! `trajectory_error.png` ([`error_png`]): the optimised track coloured by
//! its position error against the aligned ground truth, with a colour
//! bar, in the manner of evo's `--plot_colormap`.

use super::{
    FONT, draw_grid, draw_legend, equal_aspect_ranges, legend_corner, legend_line,
    map_chart_builder, map_plot_area_px, plot_error, render_png,
};
use anyhow::Result;
use echofield_graph::Se2;
use plotters::prelude::*;
use plotters::style::colors::colormaps::{ColorMap, ViridisRGB};

/// Dead reckoning: orange.
pub const DEAD_RECKONING: RGBColor = RGBColor(230, 120, 20);
/// Optimised (SLAM): blue.
pub const OPTIMISED: RGBColor = RGBColor(30, 90, 200);
/// Online, each node as emitted: green.
pub const ONLINE: RGBColor = RGBColor(40, 160, 80);
/// Ground truth: dark grey.
pub const GROUND_TRUTH: RGBColor = RGBColor(60, 60, 60);

/// One polyline of the plot.
#[derive(Clone, Debug)]
pub struct Track {
    pub label: String,
    /// `(x, y)` in metres, in order.
    pub points: Vec<(f64, f64)>,
    pub colour: RGBColor,
    /// Line width in pixels.
    pub width_px: u32,
    /// Drawn dashed (the ground truth, on top of the others).
    pub dashed: bool,
}

impl Track {
    /// A track through the positions of `poses`.
    pub fn from_poses(label: &str, poses: &[Se2], colour: RGBColor, width_px: u32) -> Self {
        Self {
            label: label.to_string(),
            points: poses.iter().map(|p| (p.x(), p.y())).collect(),
            colour,
            width_px,
            dashed: false,
        }
    }
}

/// The three usual tracks: dead reckoning under the optimised trajectory
/// under the ground truth (when given, dashed).
pub fn standard_tracks(
    dead_reckoning: &[Se2],
    optimised: &[Se2],
    ground_truth: Option<&[Se2]>,
) -> Vec<Track> {
    let mut tracks = Vec::with_capacity(3);
    tracks.push(Track::from_poses(
        "dead reckoning",
        dead_reckoning,
        DEAD_RECKONING,
        2,
    ));
    tracks.push(Track::from_poses(
        "optimised (SLAM)",
        optimised,
        OPTIMISED,
        2,
    ));
    if let Some(gt) = ground_truth {
        let mut truth = Track::from_poses("ground truth", gt, GROUND_TRUTH, 2);
        truth.dashed = true;
        tracks.push(truth);
    }
    tracks
}

/// Draws `tracks` (in order, later on top) as a PNG of `size_px`; each
/// track's start is marked by a circle. Empty tracks are left out.
pub fn trajectory_png(tracks: &[Track], caption: &str, size_px: (u32, u32)) -> Result<Vec<u8>> {
    render_png(size_px.0, size_px.1, |root| {
        let area_px = map_plot_area_px(root, caption)?;
        let (xs, ys) = equal_aspect_ranges(
            tracks.iter().flat_map(|t| t.points.iter().copied()),
            area_px,
            0.04,
        );
        let corner = legend_corner(
            tracks.iter().flat_map(|t| t.points.iter().copied()),
            &xs,
            &ys,
        );
        let mut chart = map_chart_builder(root, caption)
            .build_cartesian_2d(xs, ys)
            .map_err(plot_error)?;
        draw_grid(&mut chart, "x (m)", "y (m)")?;
        for track in tracks.iter().filter(|t| !t.points.is_empty()) {
            let style = track.colour.stroke_width(track.width_px);
            let colour = track.colour;
            let points = track.points.iter().copied();
            let series = if track.dashed {
                chart.draw_series(DashedLineSeries::new(points, DASH_PX, GAP_PX, style))
            } else {
                chart.draw_series(LineSeries::new(points, style))
            };
            let series = series.map_err(plot_error)?;
            // A track without a label has no legend entry (e.g. the
            // second of several tracks of one kind).
            if !track.label.is_empty() {
                series
                    .label(track.label.clone())
                    .legend(legend_line(colour));
            }
            chart
                .draw_series(std::iter::once(Circle::new(
                    track.points[0],
                    5,
                    track.colour.filled(),
                )))
                .map_err(plot_error)?;
        }
        draw_legend(&mut chart, corner)?;
        Ok(())
    })
}

/// Dashes of a dashed track: drawn and left out, pixels.
const DASH_PX: i32 = 7;
const GAP_PX: i32 = 5;
/// Width of the colour bar's area on the right of [`error_png`], pixels.
const COLOUR_BAR_AREA_PX: u32 = 110;

/// The optimised track `estimate` coloured by `errors_m` (one per point,
/// metres; viridis from 0 to the largest error), over the aligned
/// `reference` (dashed), with a colour bar. Preconditions: `errors_m` as
/// long as `estimate`; both tracks non-empty.
pub fn error_png(
    estimate: &[(f64, f64)],
    errors_m: &[f64],
    reference: &[(f64, f64)],
    caption: &str,
    size_px: (u32, u32),
) -> Result<Vec<u8>> {
    let max_error = errors_m.iter().copied().fold(0.0, f64::max).max(1e-6);
    let colour = |e: f64| ViridisRGB.get_color_normalized(e, 0.0, max_error);
    render_png(size_px.0, size_px.1, |root| {
        let (map, bar) = root.split_horizontally(size_px.0.saturating_sub(COLOUR_BAR_AREA_PX));
        let area_px = map_plot_area_px(&map, caption)?;
        let all = || estimate.iter().chain(reference).copied();
        let (xs, ys) = equal_aspect_ranges(all(), area_px, 0.04);
        let corner = legend_corner(all(), &xs, &ys);
        let mut chart = map_chart_builder(&map, caption)
            .build_cartesian_2d(xs, ys)
            .map_err(plot_error)?;
        draw_grid(&mut chart, "x (m)", "y (m)")?;
        let segments = estimate.windows(2).zip(errors_m.windows(2));
        chart
            .draw_series(segments.map(|(p, e)| {
                PathElement::new([p[0], p[1]], colour(0.5 * (e[0] + e[1])).stroke_width(4))
            }))
            .map_err(plot_error)?
            .label("optimised, coloured by error")
            .legend(legend_line(colour(0.5 * max_error)));
        let style = GROUND_TRUTH.stroke_width(2);
        chart
            .draw_series(DashedLineSeries::new(
                reference.iter().copied(),
                DASH_PX,
                GAP_PX,
                style,
            ))
            .map_err(plot_error)?
            .label("ground truth (SE(2)-aligned)")
            .legend(legend_line(GROUND_TRUTH));
        draw_legend(&mut chart, corner)?;
        draw_colour_bar(&bar, max_error, area_px.1)
    })
}

/// A vertical viridis bar from 0 (bottom) to `max_error` m (top), with
/// five labels, about `height_px` high.
fn draw_colour_bar(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    max_error: f64,
    height_px: u32,
) -> Result<()> {
    let (top, left, width) = (60_i32, 12_i32, 22_i32);
    let height = i32::try_from(height_px).unwrap_or(400).max(50);
    for row in 0..height {
        let e = max_error * f64::from(height - 1 - row) / f64::from(height - 1);
        let c = ViridisRGB.get_color_normalized(e, 0.0, max_error);
        area.draw(&Rectangle::new(
            [(left, top + row), (left + width, top + row + 1)],
            c.filled(),
        ))
        .map_err(plot_error)?;
    }
    area.draw(&Rectangle::new(
        [(left, top), (left + width, top + height)],
        BLACK.stroke_width(1),
    ))
    .map_err(plot_error)?;
    area.draw(&Text::new("error (m)", (left - 4, top - 28), (FONT, 15)))
        .map_err(plot_error)?;
    for k in 0..=4 {
        let e = max_error * f64::from(k) / 4.0;
        let y = top + height - 1 - (height - 1) * k / 4;
        area.draw(&Text::new(
            format!("{e:.2}"),
            (left + width + 6, y - 7),
            (FONT, 14),
        ))
        .map_err(plot_error)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_each_track_in_its_colour() {
        let square: Vec<Se2> = (0..40)
            .map(|i| {
                let t = f64::from(i) / 10.0;
                match i / 10 {
                    0 => Se2::new(t * 10.0, 0.0, 0.0),
                    1 => Se2::new(10.0, (t - 1.0) * 10.0, 0.0),
                    2 => Se2::new(10.0 - (t - 2.0) * 10.0, 10.0, 0.0),
                    _ => Se2::new(0.0, 10.0 - (t - 3.0) * 10.0, 0.0),
                }
            })
            .collect();
        let drifted: Vec<Se2> = square
            .iter()
            .enumerate()
            .map(|(i, p)| Se2::new(p.x() + 0.05 * i as f64, p.y(), 0.0))
            .collect();
        let tracks = standard_tracks(&drifted, &square, Some(&square));
        let png = trajectory_png(&tracks, "test", (400, 400)).unwrap();
        let rgb = image::load_from_memory(&png).unwrap().to_rgb8();
        assert_eq!(rgb.dimensions(), (400, 400));
        for colour in [DEAD_RECKONING, OPTIMISED, GROUND_TRUTH] {
            assert!(
                rgb.pixels().any(|p| p.0 == [colour.0, colour.1, colour.2]),
                "no pixel of {colour:?}"
            );
        }
    }

    #[test]
    fn error_plot_colours_the_track_from_small_to_large_errors() {
        let track: Vec<(f64, f64)> = (0..50).map(|i| (f64::from(i), 0.0)).collect();
        let errors: Vec<f64> = (0..50).map(|i| f64::from(i) * 0.02).collect();
        let png = error_png(&track, &errors, &track, "test", (600, 400)).unwrap();
        let rgb = image::load_from_memory(&png).unwrap().to_rgb8();
        assert_eq!(rgb.dimensions(), (600, 400));
        // Both ends of the colour map are drawn.
        for e in [0.0, 0.98] {
            let c = ViridisRGB.get_color_normalized(e, 0.0, 0.98);
            let near = |p: &image::Rgb<u8>| {
                (i32::from(p.0[0]) - i32::from(c.0)).abs() < 12
                    && (i32::from(p.0[1]) - i32::from(c.1)).abs() < 12
                    && (i32::from(p.0[2]) - i32::from(c.2)).abs() < 12
            };
            assert!(rgb.pixels().any(near), "no pixel near {c:?}");
        }
    }
}
