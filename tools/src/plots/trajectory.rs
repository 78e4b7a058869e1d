//! `trajectory.png`: the trajectories of a run in the world frame (x east,
//! y north, metres, equal aspect), with a legend.

use super::{
    draw_grid, draw_legend, equal_aspect_ranges, legend_corner, legend_line, map_chart_builder,
    map_plot_area_px, plot_error, render_png,
};
use anyhow::Result;
use echofield_graph::Se2;
use plotters::prelude::*;

/// Dead reckoning: orange.
pub const DEAD_RECKONING: RGBColor = RGBColor(230, 120, 20);
/// Optimised (SLAM): blue.
pub const OPTIMISED: RGBColor = RGBColor(30, 90, 200);
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
}

impl Track {
    /// A track through the positions of `poses`.
    pub fn from_poses(label: &str, poses: &[Se2], colour: RGBColor, width_px: u32) -> Self {
        Self {
            label: label.to_string(),
            points: poses.iter().map(|p| (p.x(), p.y())).collect(),
            colour,
            width_px,
        }
    }
}

/// The three usual tracks: ground truth (when given) under dead reckoning
/// under the optimised trajectory.
pub fn standard_tracks(
    dead_reckoning: &[Se2],
    optimised: &[Se2],
    ground_truth: Option<&[Se2]>,
) -> Vec<Track> {
    let mut tracks = Vec::with_capacity(3);
    if let Some(gt) = ground_truth {
        tracks.push(Track::from_poses("ground truth", gt, GROUND_TRUTH, 3));
    }
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
            chart
                .draw_series(LineSeries::new(track.points.iter().copied(), style))
                .map_err(plot_error)?
                .label(track.label.clone())
                .legend(legend_line(colour));
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
        for colour in [DEAD_RECKONING, OPTIMISED] {
            assert!(
                rgb.pixels().any(|p| p.0 == [colour.0, colour.1, colour.2]),
                "no pixel of {colour:?}"
            );
        }
    }
}
