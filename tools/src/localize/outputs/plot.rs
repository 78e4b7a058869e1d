//! `localization.png` of `echofield localize`.

use super::map_echoes;
use crate::localize::map::PriorMap;
use crate::localize::replay::{Localized, LocalizedRotation};
use crate::plots::{
    Chart, draw_grid, draw_legend, equal_aspect_ranges, legend_corner, legend_line,
    map_chart_builder, map_plot_area_px, plot_error, render_png,
};
use anyhow::Result;
use echofield_frontend::localization::LocalizationState;
use echofield_graph::io::TrajectoryPose;
use plotters::prelude::*;

const ESTIMATE: RGBColor = RGBColor(30, 90, 200);
const TRUTH: RGBColor = RGBColor(40, 40, 40);
const NOT_LOCALISED: RGBColor = RGBColor(220, 30, 30);
const COASTING: RGBColor = RGBColor(240, 150, 0);
const MAP_NODES: RGBColor = RGBColor(0, 170, 120);

/// `localization.png`: the map's echoes (grey), the map's nodes (green
/// dots), the estimate's track (blue), rotations not localised (red
/// crosses) and coasting (orange dots), the ground truth in the map frame
/// dashed on top.
pub(super) fn localization_png(
    localized: &Localized,
    map: &PriorMap,
    truth: &[TrajectoryPose],
    mission: &str,
) -> Result<Vec<u8>> {
    let caption = format!("{mission} localised on the map");
    let echoes = map_echoes(map, 150_000);
    let track: Vec<(f64, f64)> = localized
        .rotations
        .iter()
        .map(|r| (r.step.estimate.x(), r.step.estimate.y()))
        .collect();
    let truth: Vec<(f64, f64)> = truth.iter().map(|t| (t.pose.x(), t.pose.y())).collect();
    render_png(1400, 1100, |root| {
        let area = map_plot_area_px(root, &caption)?;
        let extent = echoes
            .iter()
            .map(|&(x, y, _)| (x, y))
            .chain(track.iter().copied())
            .chain(truth.iter().copied());
        let (xs, ys) = equal_aspect_ranges(extent, area, 0.03);
        let corner = legend_corner(track.iter().copied(), &xs, &ys);
        let mut chart = map_chart_builder(root, &caption)
            .build_cartesian_2d(xs, ys)
            .map_err(plot_error)?;
        draw_grid(&mut chart, "x (m, map frame)", "y (m)")?;
        draw_map(&mut chart, &echoes, map)?;
        draw_track(&mut chart, &track, &localized.rotations)?;
        if !truth.is_empty() {
            chart
                .draw_series(DashedLineSeries::new(
                    truth.iter().copied(),
                    7,
                    5,
                    TRUTH.stroke_width(2),
                ))
                .map_err(plot_error)?
                .label("ground truth")
                .legend(legend_line(TRUTH));
        }
        draw_legend(&mut chart, corner)?;
        Ok(())
    })
}

/// The map's echoes `(x, y, value)` in grey (darker: stronger) and its
/// nodes as green dots.
fn draw_map(chart: &mut Chart<'_, '_>, echoes: &[(f64, f64, f32)], map: &PriorMap) -> Result<()> {
    chart
        .draw_series(echoes.iter().map(|&(x, y, v)| {
            let g = (200.0 - 160.0 * f64::from(v)) as u8;
            Pixel::new((x, y), RGBColor(g, g, g))
        }))
        .map_err(plot_error)?;
    chart
        .draw_series(
            map.nodes
                .iter()
                .map(|n| Circle::new((n.x(), n.y()), 2, MAP_NODES.filled())),
        )
        .map_err(plot_error)?
        .label("map nodes")
        .legend(legend_line(MAP_NODES));
    Ok(())
}

/// The estimate's `track` (blue), the rotations not localised (red
/// crosses) and those coasting (orange dots).
fn draw_track(
    chart: &mut Chart<'_, '_>,
    track: &[(f64, f64)],
    rotations: &[LocalizedRotation],
) -> Result<()> {
    chart
        .draw_series(LineSeries::new(
            track.iter().copied(),
            ESTIMATE.stroke_width(2),
        ))
        .map_err(plot_error)?
        .label("estimate")
        .legend(legend_line(ESTIMATE));
    let at = |r: &LocalizedRotation| (r.step.estimate.x(), r.step.estimate.y());
    chart
        .draw_series(
            rotations
                .iter()
                .filter(|r| !r.step.state.is_localised())
                .map(|r| Cross::new(at(r), 5, NOT_LOCALISED.stroke_width(2))),
        )
        .map_err(plot_error)?
        .label("not localised")
        .legend(legend_line(NOT_LOCALISED));
    chart
        .draw_series(
            rotations
                .iter()
                .filter(|r| r.step.state == LocalizationState::Coasting)
                .map(|r| Circle::new(at(r), 4, COASTING.filled())),
        )
        .map_err(plot_error)?
        .label("coasting (little map in view)")
        .legend(legend_line(COASTING));
    Ok(())
}
