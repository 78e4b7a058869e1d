//! The output folder of a run of several missions. Missions are numbered
//! from 1 in input order (the `mission` column and the file names).
//!
//! | file | content |
//! |---|---|
//! | `config.toml` | the effective configuration (the first mission's) |
//! | `trajectory_M_tum.txt` | mission M's node poses, TUM: in the map frame (the first mission's world frame) when merged, else in its own frame |
//! | `ground_truth_M_tum.txt` | mission M's ground truth at its node stamps (its own frame), when it has any |
//! | `poses.csv` | every node: `mission,node,stamp_s,x_m,y_m,theta_rad,merged` |
//! | `loops.csv` | every loop candidate, each mission's own and the cross-mission ones: `mission_from,node_from,mission_to,node_to,cross,accepted,rejected_by,x_m,y_m,theta_rad` (the measurement `from_from_to`, empty when none) |
//! | `trajectory.png` | the missions' trajectories, one colour each, with their ground truth (fitted together onto the merged nodes) dashed |
//! | `report.json` | [`super::MultiReport`] |
//!
//! Every file is written atomically into the fresh output folder; the
//! folder replaces the target as `run`'s does.

use super::MultiOutput;
use crate::eval::align_se2;
use crate::output::write_atomic;
use crate::plots::trajectory::{GROUND_TRUTH, OPTIMISED, Track, trajectory_png};
use anyhow::Result;
use echofield_graph::Se2;
use echofield_graph::io::{TrajectoryPose, write_tum};
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
        "trajectory.png",
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
    for (m, run) in output.runs.iter().enumerate() {
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
    }
    write_atomic(&dir.join("poses.csv"), |w| {
        Ok(w.write_all(poses_csv(output).as_bytes())?)
    })?;
    write_atomic(&dir.join("loops.csv"), |w| {
        Ok(w.write_all(loops_csv(output).as_bytes())?)
    })?;
    let png = trajectory_png(&tracks(output), &caption(output), PLOT_SIZE_PX)?;
    write_atomic(&dir.join("trajectory.png"), |w| Ok(w.write_all(&png)?))?;
    write_atomic(&dir.join("report.json"), |w| {
        serde_json::to_writer_pretty(&mut *w, &output.report)?;
        Ok(w.write_all(b"\n")?)
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

fn caption(output: &MultiOutput) -> String {
    let names: Vec<String> = output
        .runs
        .iter()
        .enumerate()
        .map(|(m, r)| format!("{}: {}", m + 1, r.mission_name))
        .collect();
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
    let (mut p, mut q) = (Vec::new(), Vec::new());
    for (m, run) in output.runs.iter().enumerate() {
        let poses = output.poses(m);
        let merged = output.report.missions.get(m).is_some_and(|r| r.merged);
        let label = format!(
            "mission {} {}",
            m + 1,
            if merged { "(merged)" } else { "(own frame)" }
        );
        tracks.push(Track::from_poses(
            &label,
            &poses,
            COLOURS[m % COLOURS.len()],
            2,
        ));
        if merged {
            for (n, pose) in run.nodes.iter().zip(&poses) {
                if let Some(g) = n.ground_truth {
                    p.push(g.translation());
                    q.push(pose.translation());
                }
            }
        }
    }
    if p.len() >= 2 {
        let map_from_truth = align_se2(&p, &q);
        for (m, run) in output.runs.iter().enumerate() {
            if !output.report.missions.get(m).is_some_and(|r| r.merged) {
                continue;
            }
            let truth: Vec<Se2> = run
                .nodes
                .iter()
                .filter_map(|n| n.ground_truth.map(|g| map_from_truth.compose(&g)))
                .collect();
            let mut t =
                Track::from_poses(&format!("ground truth {}", m + 1), &truth, GROUND_TRUTH, 2);
            t.dashed = true;
            tracks.push(t);
        }
    }
    tracks
}
