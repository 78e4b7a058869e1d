//! The output folder of a run ([`write_outputs`]).
//!
//! | file | content |
//! |---|---|
//! | `config.toml` | the effective configuration (`echofield run --config` reads it back) |
//! | `trajectory_tum.txt` | optimised node poses, TUM `stamp x y z qx qy qz qw` |
//! | `dead_reckoning_tum.txt` | dead reckoning at the node stamps, TUM |
//! | `trajectory_nav_tum.txt` | the optimised trajectory at the navigation's rate (the dead reckoning corrected by the optimised nodes, [`navigation_rate`](crate::slam::navigation_rate)), TUM |
//! | `trajectory_nav_kitti.txt`, `trajectory_nav_times.txt` | the same as KITTI odometry rows (3x4 `[R \| t]`, row-major) and their stamps, one per line |
//! | `ground_truth_tum.txt` | ground truth at the node stamps (its own frame), TUM; only with ground truth |
//! | `online_tum.txt` | `run --online`: each node's estimate as it was when emitted, TUM |
//! | `poses.csv` | optimised node poses, `stamp_s,x_m,y_m,theta_rad` |
//! | `graph.g2o` | the optimised pose graph (`VERTEX_SE2`, `EDGE_SE2`, `EDGE_PRIOR_SE2`, `FIX` last) |
//! | `loops.csv` | every loop-closure candidate ([`loops_csv`]) |
//! | `trajectory.png` | dead reckoning, the online estimates as emitted (online runs), optimised and (aligned) ground truth, dashed on top |
//! | `trajectory_error.png` | the optimised nodes coloured by their position error against the aligned ground truth; only with ground truth |
//! | `loops.png` | loop candidates over the trajectory, coloured by outcome |
//! | `mosaic.png`, `mosaic.pgw` | acoustic mosaic at the optimised poses and its world file ([`mosaic`]) |
//! | `mission.mcap` | poses, scans, images and loops for Foxglove ([`foxglove`]) |
//! | `report.json` | the run's [`Report`](crate::slam::Report), written last |
//!
//! The TUM files share their stamps (the nodes' reference times), so
//! `evo_ape tum ground_truth_tum.txt trajectory_tum.txt -a` and
//! `echofield eval` associate every pose exactly.
//!
//! The folder is written whole: [`write_outputs`] writes into a fresh
//! folder beside the target and swaps it in at the end
//! ([`OutputFolder`]), so the target is always the previous complete
//! output or the new complete one, never a mix, and an error leaves no
//! trace. Commands that must check the target before their work (`run`,
//! `demo`) prepare the [`OutputFolder`] themselves and write into it with
//! [`write_output_files`]. A folder is replaced only when it is empty or
//! an earlier output (a `report.json` of echofield's, and nothing but
//! [`FOLDER_FILES`]); `report.json` → `run` says which run wrote it.
//! Within the fresh folder every file is still written atomically, in the
//! order above; `mission.mcap` is encoded while the files before it are
//! written, on another thread when the pool has one.

pub mod demo;
pub mod foxglove;
pub mod loops_csv;
pub mod mosaic;
pub mod precision_recall;

use crate::eval::align_se2;
use crate::output::folder::OutputFolder;
use crate::output::write_atomic;
use crate::plots::loops::{LoopClass, LoopSegment, loops_png};
use crate::plots::trajectory::{
    DEAD_RECKONING, GROUND_TRUTH, ONLINE, OPTIMISED, Track, error_png, trajectory_png,
};
use crate::slam::{NodeRecord, SlamOutput};
use anyhow::{Context, Result};
use echofield_frontend::image::Grid;
use echofield_frontend::sensors::Mission;
use echofield_graph::Se2;
use echofield_graph::io::{TrajectoryPose, write_csv, write_g2o, write_kitti, write_tum};
use loops_csv::{LoopRow, write_loops_csv};
use mosaic::{MosaicCanvas, MosaicConfig, mosaic_png, world_file};
use nalgebra::Vector2;
use std::path::Path;
use std::time::Instant;

/// Size of `trajectory.png` and `loops.png`, pixels.
pub const PLOT_SIZE_PX: (u32, u32) = (1100, 1000);

/// Every file name an output folder of `echofield run` or `demo` may hold:
/// the outputs above, the demo's input and the curves `echofield
/// eval-loops` writes beside them by default. A folder holding anything
/// else is not replaced ([`OutputFolder::prepare`]).
pub const FOLDER_FILES: &[&str] = &[
    "config.toml",
    "trajectory_tum.txt",
    "dead_reckoning_tum.txt",
    "trajectory_nav_tum.txt",
    "trajectory_nav_kitti.txt",
    "trajectory_nav_times.txt",
    "ground_truth_tum.txt",
    "online_tum.txt",
    "poses.csv",
    "graph.g2o",
    "loops.csv",
    "trajectory.png",
    "trajectory_error.png",
    "loops.png",
    "mosaic.png",
    "mosaic.pgw",
    "mission.mcap",
    "report.json",
    demo::SIMULATED_MISSION,
    "loops_pr.csv",
    "loops_pr.png",
];

/// Writes every output of `output` as the folder `target`, whole (see the
/// module doc): prepares a fresh folder beside it, writes the files into
/// it with [`write_output_files`] and swaps it in. `mission` is the run's
/// input (its sensor mounting goes into `mission.mcap`).
pub fn write_outputs(target: &Path, output: &SlamOutput, mission: &Mission) -> Result<()> {
    let folder = OutputFolder::prepare(target, FOLDER_FILES)?;
    write_output_files(folder.path(), output, mission)?;
    folder.commit()
}

/// Writes every output of `output` into the existing folder `dir` (the
/// fresh folder of an [`OutputFolder`]), each file atomically, in the order
/// of the module doc, `report.json` last.
pub fn write_output_files(dir: &Path, output: &SlamOutput, mission: &Mission) -> Result<()> {
    let start = Instant::now();
    let loops: Vec<LoopRow> = output.loops.iter().map(LoopRow::from_record).collect();
    let world_from_gt = world_from_ground_truth(output);
    // `mission.mcap`, the largest, is encoded beside the other files (on
    // another thread when there is one) and renamed into place only after
    // them, which keeps the order of the module doc.
    let mcap_path = dir.join("mission.mcap");
    // The mosaic goes into `mosaic.png` and `mission.mcap`: built once,
    // in the same pass over the node images as the MCAP's pictures.
    let (mosaic, pictures) = timed("node images", || mosaic_and_pictures(output))?;
    let (others, mcap) = rayon::join(
        || -> Result<()> {
            timed("tables", || write_tables(dir, output, &loops))?;
            timed("plots", || write_plots(dir, output, &loops, world_from_gt))?;
            timed("mosaic", || write_mosaic(dir, output, &mosaic))
        },
        || {
            timed("mcap", || {
                foxglove::complete_results_mcap(
                    &mcap_path,
                    output,
                    &mission.mounting,
                    &loops,
                    world_from_gt,
                    Some(&mosaic),
                    Some(&pictures),
                )
            })
        },
    );
    others?;
    mcap.and_then(|m| Ok(m.persist()?))
        .with_context(|| format!("while writing {}", mcap_path.display()))?;
    let mut report = output.report.clone();
    report.timings.writing_s = Some(start.elapsed().as_secs_f64());
    write_atomic(&dir.join("report.json"), |w| {
        serde_json::to_writer_pretty(&mut *w, &report)?;
        Ok(w.write_all(b"\n")?)
    })
}

/// Runs one group of outputs and logs its time.
fn timed<T>(what: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
    let t = Instant::now();
    let result = f()?;
    tracing::debug!(
        "outputs: {what} in {:.1} ms",
        t.elapsed().as_secs_f64() * 1e3
    );
    Ok(result)
}

/// The node poses as trajectory rows, one pose per node stamp.
fn node_trajectory(output: &SlamOutput, pose: impl Fn(&NodeRecord) -> Se2) -> Vec<TrajectoryPose> {
    output
        .nodes
        .iter()
        .map(|n| TrajectoryPose {
            stamp_s: n.stamp_s,
            pose: pose(n),
        })
        .collect()
}

/// `config.toml`, the TUM files, the navigation-rate trajectory (TUM,
/// KITTI and its stamps), `poses.csv`, `graph.g2o`, `loops.csv`.
fn write_tables(dir: &Path, output: &SlamOutput, loops: &[LoopRow]) -> Result<()> {
    write_atomic(&dir.join("config.toml"), |w| {
        Ok(w.write_all(output.config.to_toml_string().as_bytes())?)
    })?;
    let optimised = node_trajectory(output, |n| n.optimised);
    let dead_reckoning = node_trajectory(output, |n| n.dead_reckoning);
    write_atomic(&dir.join("trajectory_tum.txt"), |w| {
        Ok(write_tum(&optimised, w)?)
    })?;
    write_atomic(&dir.join("dead_reckoning_tum.txt"), |w| {
        Ok(write_tum(&dead_reckoning, w)?)
    })?;
    if let Some(emitted) = &output.emitted {
        write_atomic(&dir.join("online_tum.txt"), |w| Ok(write_tum(emitted, w)?))?;
    }
    let dense: Vec<TrajectoryPose> = output
        .navigation_rate_trajectory()
        .into_iter()
        .map(|(stamp_s, pose)| TrajectoryPose { stamp_s, pose })
        .collect();
    write_atomic(&dir.join("trajectory_nav_tum.txt"), |w| {
        Ok(write_tum(&dense, w)?)
    })?;
    write_atomic(&dir.join("trajectory_nav_kitti.txt"), |w| {
        Ok(write_kitti(&dense, w)?)
    })?;
    write_atomic(&dir.join("trajectory_nav_times.txt"), |w| {
        for p in &dense {
            writeln!(w, "{:.6}", p.stamp_s)?;
        }
        Ok(())
    })?;
    if let Some(gt) = &output.ground_truth {
        let poses: Vec<TrajectoryPose> = gt
            .iter()
            .map(|&(stamp_s, pose)| TrajectoryPose { stamp_s, pose })
            .collect();
        write_atomic(&dir.join("ground_truth_tum.txt"), |w| {
            Ok(write_tum(&poses, w)?)
        })?;
    }
    write_atomic(&dir.join("poses.csv"), |w| Ok(write_csv(&optimised, w)?))?;
    write_atomic(&dir.join("graph.g2o"), |w| Ok(write_g2o(&output.graph, w)?))?;
    write_atomic(&dir.join("loops.csv"), |w| Ok(write_loops_csv(loops, w)?))
}

/// `trajectory.png` and `loops.png`.
fn write_plots(
    dir: &Path,
    output: &SlamOutput,
    loops: &[LoopRow],
    world_from_gt: Option<Se2>,
) -> Result<()> {
    let png = trajectory_png(
        &trajectory_tracks(output, world_from_gt),
        &format!("{}: trajectories", output.mission_name),
        PLOT_SIZE_PX,
    )?;
    write_atomic(&dir.join("trajectory.png"), |w| Ok(w.write_all(&png)?))?;
    if let Some(t) = world_from_gt
        && let Some(png) = error_plot(output, t)?
    {
        write_atomic(
            &dir.join("trajectory_error.png"),
            |w| Ok(w.write_all(&png)?),
        )?;
    }
    let optimised: Vec<Se2> = output.nodes.iter().map(|n| n.optimised).collect();
    let tolerance =
        (output.report.loop_evaluation.as_ref()).map(|e| (e.tolerance_m, e.tolerance_deg));
    let png = loops_png(
        &positions(optimised.iter().copied()),
        &loop_segments(loops, &optimised),
        tolerance,
        &format!("{}: loop closures", output.mission_name),
        PLOT_SIZE_PX,
    )?;
    write_atomic(&dir.join("loops.png"), |w| Ok(w.write_all(&png)?))
}

/// `mosaic.png` and its world file `mosaic.pgw`.
fn write_mosaic(dir: &Path, output: &SlamOutput, grid: &Grid) -> Result<()> {
    let track = positions(output.nodes.iter().map(|n| n.optimised));
    let png = mosaic_png(grid, &track)?;
    write_atomic(&dir.join("mosaic.png"), |w| Ok(w.write_all(&png)?))?;
    write_atomic(&dir.join("mosaic.pgw"), |w| {
        Ok(w.write_all(world_file(grid).as_bytes())?)
    })
}

/// `world_from_ground_truth`: the inverse of the SE(2) alignment of the
/// optimised nodes onto their ground truth (the alignment of the ATE).
pub fn world_from_ground_truth(output: &SlamOutput) -> Option<Se2> {
    let (estimate, reference): (Vec<Vector2<f64>>, Vec<Vector2<f64>>) = output
        .nodes
        .iter()
        .filter_map(|n| {
            n.ground_truth
                .map(|gt| (n.optimised.translation(), gt.translation()))
        })
        .unzip();
    (!estimate.is_empty()).then(|| align_se2(&estimate, &reference).inverse())
}

fn positions(poses: impl Iterator<Item = Se2>) -> Vec<(f64, f64)> {
    poses.map(|p| (p.x(), p.y())).collect()
}

/// Ground truth (aligned into the world frame) under dead reckoning under
/// the optimised poses, all at the node stamps (as in the TUM files).
fn trajectory_tracks(output: &SlamOutput, world_from_gt: Option<Se2>) -> Vec<Track> {
    let mut tracks = vec![
        Track {
            label: "dead reckoning".into(),
            points: positions(output.nodes.iter().map(|n| n.dead_reckoning)),
            colour: DEAD_RECKONING,
            width_px: 2,
            dashed: false,
        },
        Track {
            label: "optimised (SLAM nodes)".into(),
            points: positions(output.nodes.iter().map(|n| n.optimised)),
            colour: OPTIMISED,
            width_px: 2,
            dashed: false,
        },
    ];
    if let Some(emitted) = &output.emitted {
        // Under the optimised track: where the two agree, the final one
        // shows.
        tracks.insert(
            1,
            Track {
                label: "online (each node as emitted)".into(),
                points: positions(emitted.iter().map(|e| e.pose)),
                colour: ONLINE,
                width_px: 2,
                dashed: false,
            },
        );
    }
    if let (Some(gt), Some(t)) = (&output.ground_truth, world_from_gt) {
        tracks.push(Track {
            label: "ground truth (SE(2)-aligned)".into(),
            points: positions(gt.iter().map(|(_, p)| t.compose(p))),
            colour: GROUND_TRUTH,
            width_px: 2,
            dashed: true,
        });
    }
    tracks
}

/// `trajectory_error.png`: the optimised nodes that have ground truth,
/// coloured by their distance to it after the alignment `world_from_gt`.
fn error_plot(output: &SlamOutput, world_from_gt: Se2) -> Result<Option<Vec<u8>>> {
    let (mut estimate, mut reference, mut errors) = (Vec::new(), Vec::new(), Vec::new());
    for n in &output.nodes {
        if let Some(gt) = n.ground_truth {
            let truth = world_from_gt.compose(&gt);
            estimate.push((n.optimised.x(), n.optimised.y()));
            reference.push((truth.x(), truth.y()));
            errors.push((n.optimised.translation() - truth.translation()).norm());
        }
    }
    if estimate.len() < 2 {
        return Ok(None);
    }
    let caption = format!(
        "{}: position error of the optimised nodes",
        output.mission_name
    );
    error_png(&estimate, &errors, &reference, &caption, PLOT_SIZE_PX).map(Some)
}

/// Every candidate as a segment between its nodes' optimised positions.
fn loop_segments(loops: &[LoopRow], optimised: &[Se2]) -> Vec<LoopSegment> {
    loops
        .iter()
        .filter_map(|l| {
            let a = optimised.get(usize::try_from(l.from).ok()?)?;
            let b = optimised.get(usize::try_from(l.to).ok()?)?;
            let class = if l.accepted {
                LoopClass::Accepted(l.gt_correct)
            } else {
                LoopClass::Rejected(l.rejected_by.clone().unwrap_or_else(|| "unknown".into()))
            };
            Some(LoopSegment {
                from: (a.x(), a.y()),
                to: (b.x(), b.y()),
                class,
            })
        })
        .collect()
}

/// Images built at once for the mosaic (in parallel), then placed and
/// dropped: bounds the memory of the output of a long mission, whose
/// images are mostly released ([`echofield_frontend::image::residency`]).
const MOSAIC_BATCH: usize = 16;

/// The mosaic's world grid: every node's `I_k` at its optimised pose.
pub fn mosaic_grid(output: &SlamOutput) -> Result<Grid> {
    node_images(output, false).map(|(grid, _)| grid)
}

/// [`mosaic_grid`] and each node's picture for `mission.mcap`
/// ([`foxglove::image_png`]; `None` for a node without an image), in one
/// pass that builds each released image's raster once
/// ([`StoredImage::grid_once`](echofield_frontend::image::StoredImage::grid_once)).
pub fn mosaic_and_pictures(output: &SlamOutput) -> Result<(Grid, Vec<Option<Vec<u8>>>)> {
    node_images(output, true)
}

/// The mosaic and, with `pictures`, the nodes' pictures (else none).
fn node_images(output: &SlamOutput, pictures: bool) -> Result<(Grid, Vec<Option<Vec<u8>>>)> {
    use rayon::prelude::*;
    let placeable: Vec<bool> = output
        .nodes
        .iter()
        .zip(&output.images)
        .map(|(node, image)| {
            !image.is_empty() && mosaic::placeable(&image.extent(), &node.optimised)
        })
        .collect();
    let extents = (0..output.nodes.len())
        .filter(|&k| placeable[k])
        .map(|k| (output.images[k].extent(), output.nodes[k].optimised));
    let mut canvas = MosaicCanvas::new(extents, &MosaicConfig::default())?;
    let looked: Vec<usize> = (0..output.nodes.len())
        .filter(|&k| placeable[k] || (pictures && !output.images[k].is_empty()))
        .collect();
    let mut encoded: Vec<Option<Vec<u8>>> = vec![None; output.nodes.len()];
    for batch in looked.chunks(MOSAIC_BATCH) {
        let looks = batch
            .par_iter()
            .map_init(Vec::new, |pixels, &k| -> Result<_> {
                let grid = output.images[k]
                    .grid_once()
                    .with_context(|| format!("acoustic image of node {k}"))?;
                let png = pictures
                    .then(|| foxglove::image_png(&grid, pixels))
                    .transpose()
                    .with_context(|| format!("picture of node {k}"))?;
                Ok((grid, png))
            })
            .collect::<Vec<_>>();
        for (&k, look) in batch.iter().zip(looks) {
            let (grid, png) = look?;
            if placeable[k] {
                canvas.place(&grid, &output.nodes[k].optimised);
            }
            encoded[k] = png;
        }
    }
    Ok((canvas.finish(), encoded))
}
