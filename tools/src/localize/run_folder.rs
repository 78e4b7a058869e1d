//! A finished run's output folder read as the prior map of `echofield
//! localize`: its optimised node poses (`trajectory_tum.txt`), its
//! effective config (`config.toml`), the mission it read (`report.json` →
//! `run.inputs`) and, when it had ground truth, its fit onto it
//! (`ground_truth_tum.txt`). The map itself is rebuilt by
//! [`super::map::build_prior_map`].

use super::map::{PriorMap, build_prior_map, pose_at_stamp};
use crate::eval::align_se2;
use crate::slam::{SlamConfig, load_mission_with_keyframes};
use anyhow::{Context, Result, bail};
use echofield_frontend::localization::LocalizationConfig;
use echofield_graph::Se2;
use echofield_graph::io::{TrajectoryPose, read_tum};
use std::path::{Path, PathBuf};

/// Reads the map of the run in `run_dir` (see the module doc) with the
/// field parameters of `localize`. Errors name the file and field at fault;
/// a map mission that moved since the run is an error naming it.
pub fn load_prior_map(run_dir: &Path, localize: &LocalizationConfig) -> Result<PriorMap> {
    let (mission_path, keyframes) = run_inputs(run_dir)?;
    let config = SlamConfig::from_toml_file(&run_dir.join("config.toml"))?;
    let trajectory_path = run_dir.join("trajectory_tum.txt");
    let trajectory = read_tum(&trajectory_path)?;
    if trajectory.is_empty() {
        bail!("{}: no pose", trajectory_path.display());
    }
    let mission =
        load_mission_with_keyframes(&mission_path, keyframes.as_deref(), config.mounting.sweep)
            .with_context(|| {
                format!(
                    "rebuilding the map of {}: reading its mission {}",
                    run_dir.display(),
                    mission_path.display()
                )
            })?;
    let truth_from_map = truth_from_map(run_dir, &trajectory)?;
    let mut map = build_prior_map(&mission, &config, &trajectory, truth_from_map, localize)
        .with_context(|| format!("the map of {}", run_dir.display()))?;
    map.mission = mission_path;
    Ok(map)
}

/// The mission path and keyframes folder a run read (`report.json` →
/// `run.inputs`).
fn run_inputs(run_dir: &Path) -> Result<(PathBuf, Option<PathBuf>)> {
    let path = run_dir.join("report.json");
    let text = std::fs::read_to_string(&path).with_context(|| {
        format!(
            "cannot read {} (is it a run's output folder?)",
            path.display()
        )
    })?;
    let report: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{}: not JSON", path.display()))?;
    let inputs = report
        .get("run")
        .and_then(|r| r.get("inputs"))
        .and_then(|i| i.as_array())
        .with_context(|| {
            format!(
                "{}: field `run.inputs` missing: the map must be the output of `echofield run`",
                path.display()
            )
        })?;
    let as_path = |k: usize| inputs.get(k).and_then(|v| v.as_str()).map(PathBuf::from);
    let Some(mission) = as_path(0) else {
        bail!("{}: field `run.inputs` is empty", path.display());
    };
    Ok((mission, as_path(1)))
}

/// The SE(2) fit of the run's nodes onto its `ground_truth_tum.txt` (same
/// stamps), `None` without one.
fn truth_from_map(run_dir: &Path, trajectory: &[TrajectoryPose]) -> Result<Option<Se2>> {
    let path = run_dir.join("ground_truth_tum.txt");
    if !path.exists() {
        return Ok(None);
    }
    let truth = read_tum(&path)?;
    let (mut p, mut q) = (Vec::new(), Vec::new());
    for t in &truth {
        if let Some(pose) = pose_at_stamp(trajectory, t.stamp_s) {
            p.push(pose.translation());
            q.push(t.pose.translation());
        }
    }
    if p.len() < 2 {
        return Ok(None);
    }
    Ok(Some(align_se2(&p, &q)))
}
