//! The output folder of a run of several missions. Missions are numbered
//! from 1 in input order (the `mission` column and the file names); the
//! map frame is the anchor's world frame (`report.json` → `anchor`).
//!
//! | file | content |
//! |---|---|
//! | `config.toml` | the effective configuration (the first mission's) |
//! | `trajectory_M_tum.txt` | mission M's node poses, TUM: in the map frame when merged, else in its own frame |
//! | `ground_truth_M_tum.txt` | mission M's ground truth at its node stamps (its own frame), when it has any |
//! | `poses.csv` | every node: `mission,node,stamp_s,x_m,y_m,theta_rad,merged` |
//! | `loops.csv` | every loop candidate, each mission's own and the cross-mission ones: `mission_from,node_from,mission_to,node_to,cross,accepted,rejected_by,x_m,y_m,theta_rad` (the measurement `from_from_to`, empty when none) |
//! | `graph.g2o` | the merged pose graph (mission M's node k has id `first_M + k`, `first_M` from the order of `report.json` → `order`; `FIX` last), when something was merged; else none |
//! | `trajectory.png` | the missions' trajectories, one colour each, with their ground truth (fitted together onto the merged nodes) dashed |
//! | `mosaic.png`, `mosaic.pgw` | the acoustic mosaic of every merged mission's nodes at their merged poses (map frame; the anchor's alone when nothing was merged) and its world file |
//! | `mission.mcap` | the merged results for Foxglove, as `run`'s (see [`write_mcap`]): one set of topics per mission, `/mission_M/...`, in frame `world` (the map frame) for merged missions and `world_M` for a mission left in its own frame |
//! | `report.json` | [`super::MultiReport`] |
//!
//! Every file is written atomically into the fresh output folder; the
//! folder replaces the target as `run`'s does.

use super::MultiOutput;
use super::merge::Merged;
use crate::eval::align_se2;
use crate::output::write_atomic;
use crate::plots::trajectory::{GROUND_TRUTH, OPTIMISED, Track, trajectory_png};
use crate::slam::outputs::foxglove::{FRAME_WORLD, image_png, scan_points, segment, write_mosaic};
use crate::slam::outputs::mosaic::{
    MosaicCanvas, MosaicConfig, mosaic_png_tracks, placeable, world_file,
};
use anyhow::{Context, Result};
use echofield_datasets::mcap::MissionWriter;
use echofield_datasets::mcap::foxglove::LineSegment;
use echofield_frontend::image::Grid;
use echofield_frontend::sensors::SensorMounting;
use echofield_graph::Se2;
use echofield_graph::io::{TrajectoryPose, write_g2o, write_tum};
use plotters::prelude::RGBColor;
use std::fmt::Write as _;
use std::path::Path;

/// Missions whose per-mission files a folder may hold and still be
/// replaced by a later run.
const MAX_MISSION_FILES: usize = 64;
const PLOT_SIZE_PX: (u32, u32) = (1100, 1000);

/// One colour per mission (cycled).
const COLOURS: [RGBColor; 5] = [
    OPTIMISED,
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
];

/// The names of the files a multi-mission output folder may hold.
pub fn folder_files() -> Vec<String> {
    let mut names: Vec<String> = [
        "config.toml",
        "poses.csv",
        "loops.csv",
        "graph.g2o",
        "trajectory.png",
        "mosaic.png",
        "mosaic.pgw",
        "mission.mcap",
        "report.json",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    for m in 1..=MAX_MISSION_FILES {
        names.push(format!("trajectory_{m}_tum.txt"));
        names.push(format!("ground_truth_{m}_tum.txt"));
    }
    names
}

/// Writes every file of the module doc into `dir`.
pub fn write_files(dir: &Path, output: &MultiOutput) -> Result<()> {
    if let Some(first) = output.runs.first() {
        write_atomic(&dir.join("config.toml"), |w| {
            Ok(w.write_all(first.config.to_toml_string().as_bytes())?)
        })?;
    }
    for m in 0..output.runs.len() {
        write_mission_tum(dir, output, m)?;
    }
    write_atomic(&dir.join("poses.csv"), |w| {
        Ok(w.write_all(poses_csv(output).as_bytes())?)
    })?;
    write_atomic(&dir.join("loops.csv"), |w| {
        Ok(w.write_all(loops_csv(output).as_bytes())?)
    })?;
    if let Some(merged) = &output.merged {
        write_atomic(&dir.join("graph.g2o"), |w| Ok(write_g2o(&merged.graph, w)?))?;
    }
    let png = trajectory_png(&tracks(output), &caption(output), PLOT_SIZE_PX)?;
    write_atomic(&dir.join("trajectory.png"), |w| Ok(w.write_all(&png)?))?;
    let mosaic = mosaic(output).context("the merged mosaic")?;
    if let Some(grid) = &mosaic {
        write_mosaic_png(dir, output, grid)?;
    }
    write_mcap(&dir.join("mission.mcap"), output, mosaic.as_ref())
        .context("while writing mission.mcap")?;
    write_atomic(&dir.join("report.json"), |w| {
        serde_json::to_writer_pretty(&mut *w, &output.report)?;
        Ok(w.write_all(b"\n")?)
    })
}

/// Mission `m`'s optimised trajectory, and its ground truth where it has
/// one, as `trajectory_{m+1}_tum.txt` and `ground_truth_{m+1}_tum.txt`.
fn write_mission_tum(dir: &Path, output: &MultiOutput, m: usize) -> Result<()> {
    let run = &output.runs[m];
    let poses = output.poses(m);
    let trajectory: Vec<TrajectoryPose> = run
        .nodes
        .iter()
        .zip(&poses)
        .map(|(n, p)| TrajectoryPose {
            stamp_s: n.stamp_s,
            pose: *p,
        })
        .collect();
    write_atomic(&dir.join(format!("trajectory_{}_tum.txt", m + 1)), |w| {
        Ok(write_tum(&trajectory, w)?)
    })?;
    let truth: Vec<TrajectoryPose> = run
        .nodes
        .iter()
        .filter_map(|n| {
            n.ground_truth.map(|g| TrajectoryPose {
                stamp_s: n.stamp_s,
                pose: g,
            })
        })
        .collect();
    if !truth.is_empty() {
        write_atomic(&dir.join(format!("ground_truth_{}_tum.txt", m + 1)), |w| {
            Ok(write_tum(&truth, w)?)
        })?;
    }
    Ok(())
}

/// `mosaic.png` (with the merged missions' tracks) and its world file.
fn write_mosaic_png(dir: &Path, output: &MultiOutput, grid: &Grid) -> Result<()> {
    let tracks: Vec<Vec<(f64, f64)>> = output
        .order
        .iter()
        .filter(|&&m| in_map(output, m))
        .map(|&m| output.poses(m).iter().map(|p| (p.x(), p.y())).collect())
        .collect();
    let tracks: Vec<&[(f64, f64)]> = tracks.iter().map(Vec::as_slice).collect();
    let png = mosaic_png_tracks(grid, &tracks)?;
    write_atomic(&dir.join("mosaic.png"), |w| Ok(w.write_all(&png)?))?;
    write_atomic(&dir.join("mosaic.pgw"), |w| {
        Ok(w.write_all(world_file(grid).as_bytes())?)
    })
}

fn poses_csv(output: &MultiOutput) -> String {
    let mut s = String::from("mission,node,stamp_s,x_m,y_m,theta_rad,merged\n");
    for (m, run) in output.runs.iter().enumerate() {
        let merged = output.report.missions.get(m).is_some_and(|r| r.merged);
        for (n, p) in run.nodes.iter().zip(output.poses(m)) {
            let _ = writeln!(
                s,
                "{},{},{:.6},{:.6},{:.6},{:.8},{merged}",
                m + 1,
                n.id,
                n.stamp_s,
                p.x(),
                p.y(),
                p.theta()
            );
        }
    }
    s
}

fn loops_csv(output: &MultiOutput) -> String {
    let mut s = String::from(
        "mission_from,node_from,mission_to,node_to,cross,accepted,rejected_by,x_m,y_m,theta_rad\n",
    );
    let mut row = |mf: usize,
                   nf: u64,
                   mt: usize,
                   nt: u64,
                   cross: bool,
                   r: &echofield_frontend::loops::records::LoopRecord| {
        let rejected = r
            .rejected_by
            .map(|x| {
                serde_json::to_value(x)
                    .ok()
                    .and_then(|v| v.as_str().map(str::to_string))
                    .unwrap_or_default()
            })
            .unwrap_or_default();
        let z = r.measurement.map_or(",,".to_string(), |z| {
            format!("{:.6},{:.6},{:.8}", z.x(), z.y(), z.theta())
        });
        let _ = writeln!(
            s,
            "{mf},{nf},{mt},{nt},{cross},{},{rejected},{z}",
            r.accepted
        );
    };
    for (m, run) in output.runs.iter().enumerate() {
        for r in &run.loops {
            row(m + 1, r.from, m + 1, r.to, false, r);
        }
    }
    if let Some(merged) = &output.merged {
        for l in &merged.cross_loops {
            row(
                l.from_mission + 1,
                l.from_node as u64,
                l.to_mission + 1,
                l.to_node as u64,
                true,
                &l.record,
            );
        }
    }
    s
}

/// "M: name" of every mission, in input order.
fn mission_names(output: &MultiOutput) -> Vec<String> {
    output
        .runs
        .iter()
        .enumerate()
        .map(|(m, r)| format!("{}: {}", m + 1, r.mission_name))
        .collect()
}

fn caption(output: &MultiOutput) -> String {
    let names = mission_names(output);
    let state = if output.report.merged {
        "merged"
    } else {
        "not merged, each in its own frame"
    };
    format!("{} ({state})", names.join(", "))
}

/// One track per mission, then the ground truth of the merged missions,
/// fitted together onto their merged nodes (dashed).
fn tracks(output: &MultiOutput) -> Vec<Track> {
    let mut tracks = Vec::new();
    for (m, _) in output.runs.iter().enumerate() {
        let poses = output.poses(m);
        let merged = output.report.missions.get(m).is_some_and(|r| r.merged);
        let label = format!(
            "mission {} {}",
            m + 1,
            if merged { "(merged)" } else { "(own frame)" }
        );
        // Earlier missions are drawn wider, so that a later mission on the
        // same route does not hide them.
        let width_px = 2 + 2 * (output.runs.len() - 1 - m).min(3) as u32;
        tracks.push(Track::from_poses(
            &label,
            &poses,
            COLOURS[m % COLOURS.len()],
            width_px,
        ));
    }
    let merged: Vec<usize> = (0..output.runs.len())
        .filter(|&m| output.report.missions.get(m).is_some_and(|r| r.merged))
        .collect();
    if let Some(map_from_truth) = frame_from_truth(output, &merged) {
        for (m, run) in output.runs.iter().enumerate() {
            if !output.report.missions.get(m).is_some_and(|r| r.merged) {
                continue;
            }
            let truth: Vec<Se2> = run
                .nodes
                .iter()
                .filter_map(|n| n.ground_truth.map(|g| map_from_truth.compose(&g)))
                .collect();
            // One legend entry for the ground truth of every mission.
            let label = if tracks.iter().any(|t| t.colour == GROUND_TRUTH) {
                ""
            } else {
                "ground truth (SE(2)-aligned)"
            };
            let mut t = Track::from_poses(label, &truth, GROUND_TRUTH, 2);
            t.dashed = true;
            tracks.push(t);
        }
    }
    tracks
}

/// The SE(2) fit `frame_from_truth` of the ground truth of `missions` at
/// their nodes onto their written poses ([`MultiOutput::poses`], one
/// frame), or `None` with fewer than two such nodes.
fn frame_from_truth(output: &MultiOutput, missions: &[usize]) -> Option<Se2> {
    let (mut p, mut q) = (Vec::new(), Vec::new());
    for &m in missions {
        for (n, pose) in output.runs[m].nodes.iter().zip(output.poses(m)) {
            if let Some(g) = n.ground_truth {
                p.push(g.translation());
                q.push(pose.translation());
            }
        }
    }
    (p.len() >= 2).then(|| align_se2(&p, &q))
}

/// `frame_from_own` of mission `m`: its own world frame in the frame its
/// poses are written in (the map frame by its placement when it is in
/// the map, the identity for the anchor and for a mission in its own
/// frame).
fn frame_from_own(output: &MultiOutput, m: usize) -> Se2 {
    if in_map(output, m) {
        output
            .placements
            .get(m)
            .and_then(Option::as_ref)
            .and_then(|p| p.map_from_mission)
            .unwrap_or_else(Se2::identity)
    } else {
        Se2::identity()
    }
}

/// Whether mission `m`'s poses are in the map frame: a member of the
/// merged graph, or the anchor.
fn in_map(output: &MultiOutput, m: usize) -> bool {
    output.order.first() == Some(&m) || output.report.missions.get(m).is_some_and(|r| r.merged)
}

/// The mosaic of every node image of the missions in the map frame
/// ([`in_map`]) at their poses there, blended as `run`'s mosaic; `None`
/// when no node has an image. Errors: an image that cannot be rebuilt.
fn mosaic(output: &MultiOutput) -> Result<Option<Grid>> {
    let mut placed: Vec<(usize, usize, Se2)> = Vec::new();
    for &m in output.order.iter().filter(|&&m| in_map(output, m)) {
        let run = &output.runs[m];
        for (k, pose) in output.poses(m).into_iter().enumerate() {
            if let Some(image) = run.images.get(k)
                && !image.is_empty()
                && placeable(&image.extent(), &pose)
            {
                placed.push((m, k, pose));
            }
        }
    }
    if placed.is_empty() {
        return Ok(None);
    }
    let mut canvas = MosaicCanvas::new(
        placed
            .iter()
            .map(|&(m, k, pose)| (output.runs[m].images[k].extent(), pose)),
        &MosaicConfig::default(),
    )?;
    for &(m, k, pose) in &placed {
        let grid = output.runs[m].images[k]
            .grid_once()
            .with_context(|| format!("acoustic image of mission {} node {k}", m + 1))?;
        canvas.place(&grid, &pose);
    }
    Ok(Some(canvas.finish()))
}

/// Frame of mission `m`'s poses: [`FRAME_WORLD`] (the map frame) when it
/// is in the map, else `world_M` (its own world frame).
fn frame_of(output: &MultiOutput, m: usize) -> String {
    if in_map(output, m) {
        FRAME_WORLD.to_string()
    } else {
        format!("world_{}", m + 1)
    }
}

/// `mission.mcap` of a run of several missions: `run`'s topics
/// ([`crate::slam::outputs::foxglove`]) once per mission M under
/// `/mission_M` (`/mission_M/slam/trajectory`, `/mission_M/slam/pose`,
/// `/mission_M/slam/scan`, `/mission_M/slam/acoustic_image`, its own loops
/// on `/mission_M/slam/loops/accepted`, `/tf` `world` → `vehicle_M`, and
/// [`write_mission_navigation`]'s dead reckoning, ground truth and
/// `vehicle_M` → `sonar_M`), the
/// merged mosaic on `/slam/mosaic` and the accepted cross-mission loops
/// on `/slam/loops/cross`, both at the anchor's first stamp. The file's
/// name (its `echofield.mission` metadata) lists the missions by number;
/// its mounting is the first mission's when known
/// ([`MultiOutput::mountings`]), else the default. Atomic, as every file
/// of the folder. Errors: a write failing, naming the topic's record.
pub fn write_mcap(
    path: &std::path::Path,
    output: &MultiOutput,
    mosaic: Option<&Grid>,
) -> Result<()> {
    let names = mission_names(output);
    let default_mounting = SensorMounting::default();
    let mounting = output
        .mountings
        .first()
        .and_then(Option::as_ref)
        .unwrap_or(&default_mounting);
    let mut w = MissionWriter::create(
        path,
        &format!("{} (echofield merged results)", names.join(", ")),
        mounting,
    )?;
    let t0 = output
        .order
        .first()
        .and_then(|&a| output.runs[a].nodes.first())
        .map_or(0.0, |n| n.stamp_s);
    if let Some(grid) = mosaic.filter(|g| g.width() > 0 && g.height() > 0) {
        write_mosaic(&mut w, t0, grid)?;
    }
    let all_poses: Vec<Vec<Se2>> = (0..output.runs.len()).map(|m| output.poses(m)).collect();
    if let Some(merged) = &output.merged {
        write_cross_loops(&mut w, t0, merged, &all_poses)?;
    }
    let mut pixels = Vec::new();
    let in_map_missions: Vec<usize> = (0..output.runs.len())
        .filter(|&m| in_map(output, m))
        .collect();
    let map_from_truth = frame_from_truth(output, &in_map_missions);
    for (m, poses) in all_poses.iter().enumerate() {
        write_mission(&mut w, output, m, poses, &mut pixels)?;
        let placed_truth = if in_map(output, m) {
            map_from_truth
        } else {
            frame_from_truth(output, &[m])
        };
        write_mission_navigation(&mut w, output, m, placed_truth)?;
    }
    w.complete()?.persist()?;
    Ok(())
}

/// The accepted cross-mission loops on `/slam/loops/cross`, between the
/// merged poses `all_poses` (per mission).
fn write_cross_loops(
    w: &mut MissionWriter,
    t0: f64,
    merged: &Merged,
    all_poses: &[Vec<Se2>],
) -> Result<()> {
    let segments: Vec<LineSegment> = merged
        .cross_loops
        .iter()
        .filter(|l| l.record.accepted)
        .filter_map(|l| {
            let a = all_poses.get(l.from_mission)?.get(l.from_node)?;
            let b = all_poses.get(l.to_mission)?.get(l.to_node)?;
            Some(segment(a, b, [0.9, 0.2, 0.9, 0.9]))
        })
        .collect();
    w.write_scene_lines(
        "/slam/loops/cross",
        t0,
        FRAME_WORLD,
        "cross",
        2.0,
        &segments,
    )?;
    Ok(())
}

/// Mission `m`'s navigation topics, as `run`'s at its first node's stamp:
/// `/mission_M/dead_reckoning/trajectory` (its dead reckoning at its
/// nodes, moved into its frame by [`frame_from_own`]),
/// `/mission_M/ground_truth/trajectory` (its whole ground truth placed by
/// `frame_from_truth`, the fit of the ground truth onto the poses, when
/// it has one) and the `/tf` transform `vehicle_M` → `sonar_M` (its
/// mounting, when known).
fn write_mission_navigation(
    w: &mut MissionWriter,
    output: &MultiOutput,
    m: usize,
    frame_from_truth: Option<Se2>,
) -> Result<()> {
    let run = &output.runs[m];
    let Some(first) = run.nodes.first() else {
        return Ok(());
    };
    let (t0, prefix, frame) = (
        first.stamp_s,
        format!("/mission_{}", m + 1),
        frame_of(output, m),
    );
    let from_own = frame_from_own(output, m);
    let dead_reckoning: Vec<Se2> = run
        .nodes
        .iter()
        .map(|n| from_own.compose(&n.dead_reckoning))
        .collect();
    w.write_poses_in_frame(
        &format!("{prefix}/dead_reckoning/trajectory"),
        t0,
        &frame,
        &dead_reckoning,
    )?;
    if let (Some(truth), Some(from_truth)) = (&run.ground_truth, frame_from_truth) {
        let poses: Vec<Se2> = truth.iter().map(|(_, p)| from_truth.compose(p)).collect();
        w.write_poses_in_frame(
            &format!("{prefix}/ground_truth/trajectory"),
            t0,
            &frame,
            &poses,
        )?;
    }
    if let Some(mounting) = output.mountings.get(m).and_then(Option::as_ref) {
        w.write_frame_transform(
            "/tf",
            t0,
            &format!("vehicle_{}", m + 1),
            &format!("sonar_{}", m + 1),
            &mounting.vehicle_from_sonar,
        )?;
    }
    Ok(())
}

/// Mission `m`'s topics under `/mission_{m+1}`: its trajectory and
/// accepted loops at `poses`, and per node the transform, pose, scan and
/// acoustic image (`pixels` is the PNG encoder's scratch buffer).
fn write_mission(
    w: &mut MissionWriter,
    output: &MultiOutput,
    m: usize,
    poses: &[Se2],
    pixels: &mut Vec<u8>,
) -> Result<()> {
    let run = &output.runs[m];
    let prefix = format!("/mission_{}", m + 1);
    let frame = frame_of(output, m);
    let vehicle = format!("vehicle_{}", m + 1);
    let Some(first) = run.nodes.first() else {
        return Ok(());
    };
    w.write_poses_in_frame(
        &format!("{prefix}/slam/trajectory"),
        first.stamp_s,
        &frame,
        poses,
    )?;
    let own: Vec<LineSegment> = run
        .loops
        .iter()
        .filter(|r| r.accepted)
        .filter_map(|r| {
            let a = poses.get(usize::try_from(r.from).ok()?)?;
            let b = poses.get(usize::try_from(r.to).ok()?)?;
            Some(segment(a, b, [0.2, 0.4, 0.9, 0.9]))
        })
        .collect();
    w.write_scene_lines(
        &format!("{prefix}/slam/loops/accepted"),
        first.stamp_s,
        &frame,
        &format!("{prefix}/loops"),
        2.0,
        &own,
    )?;
    for (k, (node, pose)) in run.nodes.iter().zip(poses).enumerate() {
        let t = node.stamp_s;
        w.write_frame_transform("/tf", t, &frame, &vehicle, pose)?;
        w.write_pose_in_frame(&format!("{prefix}/slam/pose"), t, &frame, pose)?;
        if let Some(scan) = run.scans.get(k).filter(|s| !s.is_empty()) {
            let points = scan_points(scan);
            w.write_point_cloud(&format!("{prefix}/slam/scan"), t, &frame, pose, &points)?;
        }
        if let Some(image) = run.images.get(k).filter(|i| !i.is_empty()) {
            let grid = image
                .grid_once()
                .with_context(|| format!("acoustic image of mission {} node {k}", m + 1))?;
            let png = image_png(&grid, pixels)?;
            w.write_compressed_image(
                &format!("{prefix}/slam/acoustic_image"),
                t,
                &vehicle,
                "png",
                &png,
            )?;
        }
    }
    Ok(())
}
