//! The output folder of `echofield localize`.
//!
//! | file | content |
//! |---|---|
//! | `config.toml` | the effective `[localize]` section |
//! | `trajectory_tum.txt` | the estimate (particles' weighted mean) per rotation, map frame, TUM |
//! | `dead_reckoning_tum.txt` | the forward dead reckoning at the same stamps (the mission's own frame), TUM |
//! | `ground_truth_tum.txt` | ground truth at the same stamps moved into the map frame (by the map run's fit); only with ground truth and a map run that had it |
//! | `localization.csv` | per rotation: stamp, state, estimate, spread, particles, fit, coverage, distance to the map, error |
//! | `localization.png` | the map's field, the estimate's track, the ground truth dashed on top, rotations not localised marked |
//! | `localization.mcap` | the map's echoes and nodes, and per rotation the particle cloud and the estimate, for Foxglove |
//! | `report.json` | the [`LocalizeReport`], written last |
//!
//! The folder is written whole ([`OutputFolder`]): into a fresh folder
//! swapped in at the end.

use super::map::PriorMap;
use super::replay::Localized;
use super::report::LocalizeReport;
use crate::output::write_atomic;
use crate::plots::{
    draw_grid, draw_legend, equal_aspect_ranges, legend_corner, legend_line, map_chart_builder,
    map_plot_area_px, plot_error, render_png,
};
use crate::slam::outputs::foxglove::FRAME_WORLD;
use anyhow::{Context, Result};
use echofield_datasets::mcap::MissionWriter;
use echofield_datasets::mcap::foxglove::ScanPoint;
use echofield_frontend::localization::LocalizationState;
use echofield_graph::Se2;
use echofield_graph::io::{TrajectoryPose, write_tum};
use plotters::prelude::*;
use std::io::Write;
use std::path::Path;

/// Every file the folder may hold.
pub const FOLDER_FILES: &[&str] = &[
    "config.toml",
    "trajectory_tum.txt",
    "dead_reckoning_tum.txt",
    "ground_truth_tum.txt",
    "localization.csv",
    "localization.png",
    "localization.mcap",
    "report.json",
];

/// Field values drawn as map echoes in the plot and the MCAP.
const MAP_ECHO_LEVEL: f32 = 0.35;

/// Writes every file into `dir` (report.json last).
pub fn write_files(
    dir: &Path,
    localized: &Localized,
    map: &PriorMap,
    report: &LocalizeReport,
    config_toml: &str,
) -> Result<()> {
    write_atomic(&dir.join("config.toml"), |w| {
        Ok(w.write_all(config_toml.as_bytes())?)
    })?;
    let stamped = |pose: &dyn Fn(usize) -> Se2| -> Vec<TrajectoryPose> {
        (0..localized.rotations.len())
            .map(|k| TrajectoryPose {
                stamp_s: localized.rotations[k].stamp_s,
                pose: pose(k),
            })
            .collect()
    };
    let estimate = stamped(&|k| localized.rotations[k].step.estimate);
    let dead_reckoning = stamped(&|k| localized.rotations[k].dead_reckoning);
    write_atomic(&dir.join("trajectory_tum.txt"), |w| {
        Ok(write_tum(&estimate, w)?)
    })?;
    write_atomic(&dir.join("dead_reckoning_tum.txt"), |w| {
        Ok(write_tum(&dead_reckoning, w)?)
    })?;
    let truth = truth_in_map(localized, map);
    if !truth.is_empty() {
        write_atomic(&dir.join("ground_truth_tum.txt"), |w| {
            Ok(write_tum(&truth, w)?)
        })?;
    }
    write_atomic(&dir.join("localization.csv"), |w| write_csv(report, w))?;
    let png = localization_png(localized, map, &truth, &report.mission)?;
    crate::output::write_bytes_atomic(&dir.join("localization.png"), &png)?;
    write_mcap(&dir.join("localization.mcap"), localized, map, &truth)?;
    write_atomic(&dir.join("report.json"), |w| {
        serde_json::to_writer_pretty(&mut *w, report)?;
        Ok(writeln!(w)?)
    })
}

/// Ground truth at the rotations' stamps in the map frame (empty without
/// ground truth or without the map run's fit).
fn truth_in_map(localized: &Localized, map: &PriorMap) -> Vec<TrajectoryPose> {
    let Some(truth_from_map) = map.truth_from_map else {
        return Vec::new();
    };
    let map_from_truth = truth_from_map.inverse();
    localized
        .rotations
        .iter()
        .filter_map(|r| {
            crate::matching::ground_truth_at(&localized.ground_truth, r.stamp_s).map(|t| {
                TrajectoryPose {
                    stamp_s: r.stamp_s,
                    pose: map_from_truth.compose(&t),
                }
            })
        })
        .collect()
}

fn write_csv(report: &LocalizeReport, w: &mut dyn Write) -> Result<()> {
    writeln!(
        w,
        "rotation_index,stamp_s,state,x_m,y_m,theta_rad,spread_m,heading_spread_rad,particles,fit,coverage,reseeded,distance_to_map_m,error_m,filter_ms,build_ms"
    )?;
    for r in &report.per_rotation {
        let state = serde_json::to_value(r.state)?;
        writeln!(
            w,
            "{},{:.6},{},{:.4},{:.4},{:.6},{:.4},{:.5},{},{:.4},{:.4},{},{:.3},{},{:.3},{:.3}",
            r.rotation_index,
            r.stamp_s,
            state.as_str().unwrap_or("?"),
            r.x_m,
            r.y_m,
            r.theta_rad,
            r.spread_m,
            r.heading_spread_rad,
            r.particles,
            r.fit,
            r.coverage,
            r.reseeded,
            r.distance_to_map_m,
            r.error_m.map_or(String::new(), |e| format!("{e:.4}")),
            r.filter_ms,
            r.build_ms
        )?;
    }
    Ok(())
}

/// The map's echoes (field cells above [`MAP_ECHO_LEVEL`]) as world points,
/// every n-th so that at most `max` remain.
fn map_echoes(map: &PriorMap, max: usize) -> Vec<(f64, f64, f32)> {
    let grid = map.field.grid();
    let w = grid.width();
    let cells: Vec<(usize, f32)> = grid
        .values()
        .iter()
        .enumerate()
        .filter(|(_, v)| **v >= MAP_ECHO_LEVEL)
        .map(|(k, v)| (k, *v))
        .collect();
    let stride = cells.len().div_ceil(max.max(1)).max(1);
    cells
        .iter()
        .step_by(stride)
        .map(|&(k, v)| {
            let (x, y) = grid.cell_centre_m((k % w) as i64, (k / w) as i64);
            (x, y, v)
        })
        .collect()
}

const ESTIMATE: RGBColor = RGBColor(30, 90, 200);
const TRUTH: RGBColor = RGBColor(40, 40, 40);
const NOT_LOCALISED: RGBColor = RGBColor(220, 30, 30);
const COASTING: RGBColor = RGBColor(240, 150, 0);
const MAP_NODES: RGBColor = RGBColor(0, 170, 120);

/// `localization.png`: the map's echoes (grey), the map's nodes (green
/// dots), the estimate's track (blue), rotations not localised (red
/// crosses) and coasting (orange dots), the ground truth in the map frame
/// dashed on top.
fn localization_png(
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
        chart
            .draw_series(LineSeries::new(
                track.iter().copied(),
                ESTIMATE.stroke_width(2),
            ))
            .map_err(plot_error)?
            .label("estimate (particles' mean)")
            .legend(legend_line(ESTIMATE));
        chart
            .draw_series(
                localized
                    .rotations
                    .iter()
                    .filter(|r| !r.step.state.is_localised())
                    .map(|r| {
                        Cross::new(
                            (r.step.estimate.x(), r.step.estimate.y()),
                            5,
                            NOT_LOCALISED.stroke_width(2),
                        )
                    }),
            )
            .map_err(plot_error)?
            .label("not localised")
            .legend(legend_line(NOT_LOCALISED));
        chart
            .draw_series(
                localized
                    .rotations
                    .iter()
                    .filter(|r| r.step.state == LocalizationState::Coasting)
                    .map(|r| {
                        Circle::new(
                            (r.step.estimate.x(), r.step.estimate.y()),
                            4,
                            COASTING.filled(),
                        )
                    }),
            )
            .map_err(plot_error)?
            .label("coasting (little map in view)")
            .legend(legend_line(COASTING));
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

/// `localization.mcap`: `/map/echoes` and `/map/nodes` once (point
/// clouds), then per rotation `/localize/particles` (point cloud,
/// intensity = weight relative to the largest), `/localize/pose` and, with
/// ground truth, `/localize/ground_truth`; all in frame `world` (the map's).
fn write_mcap(
    path: &Path,
    localized: &Localized,
    map: &PriorMap,
    truth: &[TrajectoryPose],
) -> Result<()> {
    let Some(first) = localized.rotations.first() else {
        anyhow::bail!("no rotation was localised");
    };
    let name = format!("{} (echofield localize)", localized.mission_name);
    let mut w = MissionWriter::create(path, &name, &localized.mounting)?;
    let t0 = first.stamp_s;
    let echoes: Vec<ScanPoint> = map_echoes(map, 200_000)
        .into_iter()
        .map(|(x, y, v)| ScanPoint {
            x_m: x,
            y_m: y,
            intensity: v,
        })
        .collect();
    w.write_point_cloud("/map/echoes", t0, FRAME_WORLD, &Se2::identity(), &echoes)?;
    let nodes: Vec<ScanPoint> = map
        .nodes
        .iter()
        .map(|n| ScanPoint {
            x_m: n.x(),
            y_m: n.y(),
            intensity: 1.0,
        })
        .collect();
    w.write_point_cloud("/map/nodes", t0, FRAME_WORLD, &Se2::identity(), &nodes)?;
    let estimate: Vec<Se2> = localized
        .rotations
        .iter()
        .map(|r| r.step.estimate)
        .collect();
    w.write_poses_in_frame("/localize/trajectory", t0, FRAME_WORLD, &estimate)?;
    let mut truth = truth.iter().peekable();
    for r in &localized.rotations {
        w.write_point_cloud(
            "/localize/particles",
            r.stamp_s,
            FRAME_WORLD,
            &Se2::identity(),
            &r.cloud,
        )?;
        w.write_pose_in_frame("/localize/pose", r.stamp_s, FRAME_WORLD, &r.step.estimate)?;
        if let Some(t) = truth.next_if(|t| t.stamp_s <= r.stamp_s) {
            w.write_pose_in_frame("/localize/ground_truth", t.stamp_s, FRAME_WORLD, &t.pose)?;
        }
    }
    w.complete()?
        .persist()
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}
