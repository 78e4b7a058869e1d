//! `mission.mcap`: the run's results for MCAP viewers (Foxglove), written
//! with the datasets crate's streaming [`MissionWriter`] (atomic: a
//! temporary file renamed into place when complete).
//!
//! Everything is in frame `world` (the run's dead-reckoning world frame;
//! ground truth is moved into it by the SE(2) alignment of the optimised
//! nodes onto it). Topics and Foxglove schemas:
//!
//! | topic | schema | when | content |
//! |---|---|---|---|
//! | `/slam/trajectory` | `foxglove.PosesInFrame` | first node | optimised node poses |
//! | `/dead_reckoning/trajectory` | `foxglove.PosesInFrame` | first node | dead reckoning at the node stamps |
//! | `/ground_truth/trajectory` | `foxglove.PosesInFrame` | first node | ground truth at the node stamps (aligned) |
//! | `/online/trajectory` | `foxglove.PosesInFrame` | first node, online runs | each node's estimate as it was emitted |
//! | `/slam/loops/accepted` | `foxglove.SceneUpdate` | first node | accepted loops as lines between the optimised node positions: green = true, red = false (against ground truth), blue = no ground truth |
//! | `/slam/loops/rejected` | `foxglove.SceneUpdate` | first node | rejected candidates as thin lines: grey, orange where the rejected match was in fact correct against ground truth (a missed loop) |
//! | `/slam/mosaic` | `foxglove.Grid` | first node | the acoustic mosaic of `mosaic.png` (every `I_k` at its optimised pose), field `intensity` 0-255 |
//! | `/tf` | `foxglove.FrameTransform` | first node, then each node | `vehicle` → `sonar` (the mounting's `vehicle_from_sonar`) once; `world` → `vehicle`, the optimised pose, per node |
//! | `/slam/pose` | `foxglove.PoseInFrame` | each node | the optimised pose |
//! | `/slam/scan` | `foxglove.PointCloud` | each node | `S_k` placed at the optimised pose; `intensity` 0-255 |
//! | `/slam/acoustic_image` | `foxglove.CompressedImage` | each node | `I_k` as a grey PNG in the vehicle frame (x right, y up, one pixel per 2 x 2 cells, max-pooled) |
//!
//! Whole-run messages sit at the first node's stamp so that they stay on
//! screen over the whole playback (a viewer shows the latest message of a
//! topic).

use super::loops_csv::LoopRow;
use crate::plots::encode_png;
use crate::slam::SlamOutput;
use anyhow::{Context, Result};
use echofield_datasets::mcap::foxglove::{GridCells, LineSegment, ScanPoint};
use echofield_datasets::mcap::{CompletedMcap, MissionWriter};
use echofield_frontend::image::Grid;
use echofield_frontend::scan::Scan;
use echofield_frontend::sensors::SensorMounting;
use echofield_graph::Se2;
use image::ExtendedColorType;
use rayon::prelude::*;
use std::path::Path;

pub const FRAME_WORLD: &str = "world";
pub const FRAME_VEHICLE: &str = "vehicle";
pub const FRAME_SONAR: &str = "sonar";

/// Writes `path` from a run's output. `world_from_ground_truth` maps the
/// ground-truth frame into the run's world frame.
pub fn write_results_mcap(
    path: &Path,
    output: &SlamOutput,
    mounting: &SensorMounting,
    loops: &[LoopRow],
    world_from_ground_truth: Option<Se2>,
    mosaic: Option<&Grid>,
) -> Result<()> {
    complete_results_mcap(
        path,
        output,
        mounting,
        loops,
        world_from_ground_truth,
        mosaic,
        None,
    )?
    .persist()?;
    Ok(())
}

/// [`write_results_mcap`] up to the last step: the file is complete at a
/// temporary path, and replaces `path` only when persisted. `mosaic` is the
/// world-frame mosaic grid (`None`: no `/slam/mosaic`). `pictures` are the
/// nodes' images already encoded with [`image_png`], one per node (`None`
/// in it: a node without an image); `None`: encoded here.
pub fn complete_results_mcap(
    path: &Path,
    output: &SlamOutput,
    mounting: &SensorMounting,
    loops: &[LoopRow],
    world_from_ground_truth: Option<Se2>,
    mosaic: Option<&Grid>,
    pictures: Option<&[Option<Vec<u8>>]>,
) -> Result<CompletedMcap> {
    let Some(first) = output.nodes.first() else {
        anyhow::bail!("the run has no nodes");
    };
    let t0 = first.stamp_s;
    let name = format!("{} (echofield results)", output.mission_name);
    let mut w = MissionWriter::create(path, &name, mounting)?;

    write_trajectories(&mut w, t0, output, loops, world_from_ground_truth)?;
    if let Some(grid) = mosaic.filter(|g| g.width() > 0 && g.height() > 0) {
        write_mosaic(&mut w, t0, grid)?;
    }
    w.write_frame_transform(
        "/tf",
        t0,
        FRAME_VEHICLE,
        FRAME_SONAR,
        &mounting.vehicle_from_sonar,
    )?;

    // The images are encoded in parallel (with rayon) and written in node
    // order; an error names the first node whose image failed.
    let encoded;
    let pictures = match pictures {
        Some(p) if p.len() == output.nodes.len() => p,
        _ => {
            encoded = encode_pictures(output)?;
            &encoded[..]
        }
    };
    write_nodes(&mut w, output, pictures)?;
    Ok(w.complete()?)
}

/// The per-node topics, at each node's stamp: its optimised pose (as the
/// `/tf` world-to-vehicle transform and as a pose), its scan placed by it,
/// and its picture (`pictures`, one per node).
fn write_nodes(
    w: &mut MissionWriter,
    output: &SlamOutput,
    pictures: &[Option<Vec<u8>>],
) -> Result<()> {
    let mut pngs = pictures.iter();
    for (k, node) in output.nodes.iter().enumerate() {
        let t = node.stamp_s;
        w.write_frame_transform("/tf", t, FRAME_WORLD, FRAME_VEHICLE, &node.optimised)?;
        w.write_pose_in_frame("/slam/pose", t, FRAME_WORLD, &node.optimised)?;
        if let Some(scan) = output.scans.get(k).filter(|s| !s.is_empty()) {
            let points = scan_points(scan);
            w.write_point_cloud("/slam/scan", t, FRAME_WORLD, &node.optimised, &points)?;
        }
        if let Some(png) = pngs.next().and_then(Option::as_ref) {
            w.write_compressed_image("/slam/acoustic_image", t, FRAME_VEHICLE, "png", png)?;
        }
    }
    Ok(())
}

/// The whole-mission topics at `t0`: the optimised, dead-reckoning,
/// (placed in the world frame by `world_from_ground_truth`) ground-truth
/// and (online runs) emitted trajectories, and the accepted and rejected
/// loops as line segments between optimised poses.
fn write_trajectories(
    w: &mut MissionWriter,
    t0: f64,
    output: &SlamOutput,
    loops: &[LoopRow],
    world_from_ground_truth: Option<Se2>,
) -> Result<()> {
    let optimised: Vec<Se2> = output.nodes.iter().map(|n| n.optimised).collect();
    let dead_reckoning: Vec<Se2> = output.nodes.iter().map(|n| n.dead_reckoning).collect();
    w.write_poses_in_frame("/slam/trajectory", t0, FRAME_WORLD, &optimised)?;
    w.write_poses_in_frame(
        "/dead_reckoning/trajectory",
        t0,
        FRAME_WORLD,
        &dead_reckoning,
    )?;
    if let (Some(gt), Some(world_from_gt)) = (&output.ground_truth, world_from_ground_truth) {
        let poses: Vec<Se2> = gt.iter().map(|(_, p)| world_from_gt.compose(p)).collect();
        w.write_poses_in_frame("/ground_truth/trajectory", t0, FRAME_WORLD, &poses)?;
    }
    if let Some(emitted) = &output.emitted {
        let poses: Vec<Se2> = emitted.iter().map(|e| e.pose).collect();
        w.write_poses_in_frame("/online/trajectory", t0, FRAME_WORLD, &poses)?;
    }
    for (topic, accepted, thickness_px) in [
        ("/slam/loops/accepted", true, 2.0),
        ("/slam/loops/rejected", false, 1.0),
    ] {
        let segments = loop_segments(loops, accepted, &optimised);
        w.write_scene_lines(topic, t0, FRAME_WORLD, topic, thickness_px, &segments)?;
    }
    Ok(())
}

/// `/slam/mosaic` at `t0`: the world-frame mosaic (not empty) as an
/// occupancy-style grid of intensity levels.
pub fn write_mosaic(w: &mut MissionWriter, t0: f64, grid: &Grid) -> Result<()> {
    let (x0, y0) = grid.origin_m();
    let cells: Vec<u8> = grid.values().iter().map(|&v| intensity_level(v)).collect();
    let cells = GridCells {
        origin: Se2::new(x0, y0, 0.0),
        column_count: grid.width(),
        cell_size_m: grid.cell_size_m(),
        cells: &cells,
    };
    w.write_grid("/slam/mosaic", t0, FRAME_WORLD, &cells)?;
    Ok(())
}

/// Every node's picture ([`image_png`]; `None`: no image), in parallel;
/// an error names the first node, in order, whose image failed.
fn encode_pictures(output: &SlamOutput) -> Result<Vec<Option<Vec<u8>>>> {
    let pngs: Vec<Result<Option<Vec<u8>>>> = output
        .images
        .par_iter()
        .enumerate()
        .map_init(Vec::new, |pixels, (k, image)| {
            (!image.is_empty())
                .then(|| image_png(&image.grid_once()?, pixels))
                .transpose()
                .with_context(|| format!("acoustic image of node {k}"))
        })
        .collect();
    pngs.into_iter().collect()
}

/// Colours of loop lines (red, green, blue, alpha).
const TRUE_LOOP: [f32; 4] = [0.1, 0.8, 0.2, 0.9];
const FALSE_LOOP: [f32; 4] = [0.9, 0.1, 0.1, 1.0];
const UNJUDGED_LOOP: [f32; 4] = [0.2, 0.4, 0.9, 0.9];
const REJECTED: [f32; 4] = [0.6, 0.6, 0.6, 0.5];
const REJECTED_OVERLAPPING: [f32; 4] = [1.0, 0.6, 0.1, 0.7];

/// The segments between the optimised positions of the loop candidates'
/// nodes, accepted or rejected ones, coloured by their ground-truth verdict
/// (see the module doc). False loops come last, so that they are drawn on
/// top of true ones.
fn loop_segments(loops: &[LoopRow], accepted: bool, optimised: &[Se2]) -> Vec<LineSegment> {
    let mut segments: Vec<(bool, LineSegment)> = loops
        .iter()
        .filter(|l| l.accepted == accepted)
        .filter_map(|l| {
            let a = optimised.get(l.from as usize)?;
            let b = optimised.get(l.to as usize)?;
            let rgba = match (accepted, l.gt_correct) {
                (true, Some(true)) => TRUE_LOOP,
                (true, Some(false)) => FALSE_LOOP,
                (true, None) => UNJUDGED_LOOP,
                (false, Some(true)) => REJECTED_OVERLAPPING,
                (false, _) => REJECTED,
            };
            Some((rgba == FALSE_LOOP, segment(a, b, rgba)))
        })
        .collect();
    segments.sort_by_key(|(on_top, _)| *on_top);
    segments.into_iter().map(|(_, s)| s).collect()
}

/// A normalised intensity (0-1, clamped) as an 8-bit level.
fn intensity_level(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0) as u8
}

/// A scan's points (scan frame) with their intensities, as a point cloud
/// message takes them.
pub fn scan_points(scan: &Scan) -> Vec<ScanPoint> {
    scan.points
        .iter()
        .zip(&scan.intensities)
        .map(|(p, &i)| ScanPoint {
            x_m: p.x,
            y_m: p.y,
            intensity: i,
        })
        .collect()
}

/// The line from `a` to `b` (positions only) in colour `rgba`.
pub fn segment(a: &Se2, b: &Se2, rgba: [f32; 4]) -> LineSegment {
    LineSegment {
        from_m: (a.x(), a.y()),
        to_m: (b.x(), b.y()),
        rgba,
    }
}

/// `I_k` (its search raster,
/// [`AcousticImage::grid`](echofield_frontend::image::AcousticImage::grid)) as an 8-bit grey
/// PNG, x to the right and y up (row 0 is the largest y), max-pooled over
/// 2 x 2 cells: a quarter of the pixels to encode and store, and no echo
/// lost. `pixels` is scratch space reused between calls.
pub fn image_png(grid: &Grid, pixels: &mut Vec<u8>) -> Result<Vec<u8>> {
    let (w, h) = (grid.width(), grid.height());
    let (pw, ph) = (w.div_ceil(2), h.div_ceil(2));
    pixels.clear();
    pixels.resize(pw * ph, 0);
    let values = grid.values();
    let level = intensity_level;
    for (py, pair) in values.chunks(2 * w).enumerate() {
        // Pooled row `py` from the bottom is picture row `ph - 1 - py`.
        let dst = &mut pixels[(ph - 1 - py) * pw..(ph - py) * pw];
        let (lower, upper) = pair.split_at(w);
        let upper = if upper.is_empty() { lower } else { upper };
        for ((a, b), p) in lower
            .chunks_exact(2)
            .zip(upper.chunks_exact(2))
            .zip(dst.iter_mut())
        {
            *p = level(a[0].max(a[1]).max(b[0]).max(b[1]));
        }
        if w % 2 == 1 {
            dst[pw - 1] = level(lower[w - 1].max(upper[w - 1]));
        }
    }
    encode_png(pixels, pw as u32, ph as u32, ExtendedColorType::L8)
}

#[cfg(test)]
mod tests {
    use super::*;
    use echofield_frontend::image::Grid;

    #[test]
    fn image_png_max_pools_2x2_with_y_up() {
        // 3 x 3 cells, row 0 at the bottom.
        let mut grid = Grid::zeros(0.0, 0.0, 0.2, 3, 3);
        grid.values_mut().copy_from_slice(&[
            0.1, 0.2, 0.9, //
            0.4, 0.3, 0.0, //
            1.5, 0.0, 0.5, // clamped to 1
        ]);
        let png = image_png(&grid, &mut Vec::new()).unwrap();
        let picture = image::load_from_memory(&png).unwrap().to_luma8();
        assert_eq!(picture.dimensions(), (2, 2));
        let level = |v: f32| (v * 255.0) as u8;
        // Top picture row: the pooled top cell row (row 2 alone).
        assert_eq!(picture.get_pixel(0, 0).0[0], 255);
        assert_eq!(picture.get_pixel(1, 0).0[0], level(0.5));
        // Bottom picture row: rows 0-1.
        assert_eq!(picture.get_pixel(0, 1).0[0], level(0.4));
        assert_eq!(picture.get_pixel(1, 1).0[0], level(0.9));
    }
}
