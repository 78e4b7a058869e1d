//! The output folder of `echofield localize`.
//!
//! | file | content |
//! |---|---|
//! | `config.toml` | the effective `[localize]` section |
//! | `trajectory_tum.txt` | the estimate per rotation (`[localize] estimate`), map frame, TUM |
//! | `trajectory_smoothed_tum.txt` | offline: the filter's fixes and the dead reckoning between rotations smoothed over the whole mission ([`super::smooth`]), map frame, TUM; absent when the smoothing failed |
//! | `dead_reckoning_tum.txt` | the forward dead reckoning at the same stamps (the mission's own frame), TUM |
//! | `ground_truth_tum.txt` | ground truth at the same stamps moved into the map frame (by the map run's fit); only with ground truth and a map run that had it |
//! | `localization.csv` | per rotation: stamp, state, estimate, spread, particles, fit, coverage, distance to the map, error |
//! | `localization.png` | ([`plot`]) the map's field, the estimate's track, the ground truth dashed on top, rotations not localised marked |
//! | `localization.mcap` | the map's echoes and nodes, and per rotation the particle cloud and the estimate, for Foxglove |
//! | `report.json` | the [`LocalizeReport`], written last |
//!
//! The folder is written whole
//! ([`OutputFolder`](crate::output::folder::OutputFolder)): into a fresh
//! folder swapped in at the end.

mod mcap;
mod plot;

use super::map::PriorMap;
use super::replay::Localized;
use super::report::LocalizeReport;
use crate::output::write_atomic;
use anyhow::Result;
use echofield_graph::Se2;
use echofield_graph::io::{TrajectoryPose, write_tum};
use std::io::Write;
use std::path::Path;

/// Every file the folder may hold.
pub const FOLDER_FILES: &[&str] = &[
    "config.toml",
    "trajectory_tum.txt",
    "trajectory_smoothed_tum.txt",
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
    if let Some(smoothed) = &localized.smoothed {
        let smoothed: Vec<TrajectoryPose> = (localized.rotations.iter().zip(smoothed))
            .map(|(r, pose)| TrajectoryPose {
                stamp_s: r.stamp_s,
                pose: *pose,
            })
            .collect();
        write_atomic(&dir.join("trajectory_smoothed_tum.txt"), |w| {
            Ok(write_tum(&smoothed, w)?)
        })?;
    }
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
    let png = plot::localization_png(localized, map, &truth, &report.mission)?;
    crate::output::write_bytes_atomic(&dir.join("localization.png"), &png)?;
    mcap::write_mcap(&dir.join("localization.mcap"), localized, map, &truth)?;
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
