//! The prior map of `echofield localize`, rebuilt from a finished run's
//! output folder.
//!
//! A run's folder holds its optimised node poses (`trajectory_tum.txt`),
//! its effective config (`config.toml`) and, in `report.json` → `run`, the
//! mission it read. The nodes' acoustic images `I_j` are not stored (they
//! are the bulk of a run's memory), so they are rebuilt here exactly as the
//! run built them: the same mission, the same config, the batch
//! (smoothed) navigation, the same rotations and [`build_node`]. Each node
//! is matched to its optimised pose by its stamp; rotations that did not
//! become nodes of the run are left out.
//!
//! The images are then placed at the optimised poses in one world grid
//! ([`build_mosaic`], blended by max) and turned into the likelihood
//! field ([`LikelihoodField`]), covered within each node's footprint.
//! Why one field rather than the node images themselves: a particle is
//! then scored with one bilinear lookup per scan point, whatever the
//! number of map nodes it overlaps.

use crate::eval::align_se2;
use crate::slam::outputs::mosaic::{MosaicConfig, build_mosaic};
use crate::slam::pipeline::prepare;
use crate::slam::{SlamConfig, load_mission_with_keyframes};
use anyhow::{Context, Result, bail};
use echofield_frontend::dead_reckoning;
use echofield_frontend::localization::{LikelihoodField, LocalizationConfig};
use echofield_frontend::nodes::{NodeData, Skip, build_node};
use echofield_frontend::rotation::assemble_rotations;
use echofield_frontend::sensors::Mission;
use echofield_graph::Se2;
use echofield_graph::io::{TrajectoryPose, read_tum};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Largest difference between a rebuilt rotation's stamp and a run node's
/// stamp for them to be the same node, s (the run writes its stamps with
/// microsecond precision or better).
const STAMP_MATCH_S: f64 = 1e-3;

/// The map: its likelihood field and what the outputs draw and compare.
pub struct PriorMap {
    pub field: LikelihoodField,
    /// The map nodes' optimised `world_from_vehicle`.
    pub nodes: Vec<Se2>,
    /// The mission the map was built from (its path when read from a run
    /// folder, else its name).
    pub mission: PathBuf,
    /// The run's effective config (the localised mission's scans are built
    /// with the same).
    pub config: SlamConfig,
    /// `truth_from_map`: the SE(2) fit of the map run's optimised nodes
    /// onto its ground truth (`ground_truth_tum.txt`), when the run had
    /// ground truth. Estimates in the map frame are compared with ground
    /// truth through it, without fitting them again.
    pub truth_from_map: Option<Se2>,
}

impl PriorMap {
    /// Distance from `(x, y)` (map frame) to the nearest map node, m.
    pub fn distance_to_nodes_m(&self, x: f64, y: f64) -> f64 {
        self.nodes
            .iter()
            .map(|n| (n.x() - x).hypot(n.y() - y))
            .fold(f64::INFINITY, f64::min)
    }
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

/// The map of `mission` whose run with `config` placed its nodes at
/// `trajectory` (stamped optimised poses); `truth_from_map` as
/// [`PriorMap::truth_from_map`]. Rotations without a pose in `trajectory`
/// are left out. Errors: bad records, no node rebuilt, an empty field.
pub fn build_prior_map(
    mission: &Mission,
    config: &SlamConfig,
    trajectory: &[TrajectoryPose],
    truth_from_map: Option<Se2>,
    localize: &LocalizationConfig,
) -> Result<PriorMap> {
    let (mission, config_used, _, _) = prepare(mission, config)?;
    let navigation = dead_reckoning::run(&mission, &config_used.dead_reckoning)
        .with_context(|| format!("dead reckoning of the map mission {}", mission.name))?;
    let rotations = assemble_rotations(&mission.beams, &config_used.rotation)
        .with_context(|| format!("rotations of the map mission {}", mission.name))?;
    // Only the rotations that are nodes of the run.
    let wanted: Vec<(usize, Se2)> = rotations
        .iter()
        .enumerate()
        .filter_map(|(i, r)| pose_at_stamp(trajectory, r.reference_stamp_s).map(|p| (i, p)))
        .collect();
    let built: Vec<Result<Option<(NodeData, Se2)>>> = wanted
        .par_iter()
        .map(|&(i, pose)| {
            let r = &rotations[i];
            match build_node(
                &mission.beams[r.beams.clone()],
                r,
                &navigation,
                &mission.mounting,
                &config_used.segmentation,
                &config_used.image,
            ) {
                Ok(node) => Ok(Some((node, pose))),
                Err(Skip::Outside(_)) => Ok(None),
                Err(Skip::Fatal(e)) => Err(e.into()),
            }
        })
        .collect();
    let mut nodes = Vec::new();
    for b in built {
        nodes.extend(b?);
    }
    if nodes.len() < trajectory.len() {
        tracing::warn!(
            rebuilt = nodes.len(),
            run_nodes = trajectory.len(),
            "not every node of the map run was rebuilt from its mission (the stamps differ): the map has the rebuilt ones"
        );
    }
    if nodes.is_empty() {
        bail!(
            "no node of the run could be rebuilt from its mission {}: has the mission changed since the run?",
            mission.name
        );
    }
    // Freshly built nodes hold their images: reading them rebuilds nothing.
    let resident = nodes
        .iter()
        .map(|(n, p)| Ok((n.image.image()?, *p)))
        .collect::<Result<Vec<_>, echofield_frontend::FrontendError>>()?;
    let images: Vec<_> = resident.iter().map(|(i, p)| (i.grid(), *p)).collect();
    let mosaic = build_mosaic(
        &images,
        &MosaicConfig::likelihood_field(localize.field_cell_m),
    )?;
    let footprints: Vec<(Se2, f64)> = nodes.iter().map(|(n, p)| (*p, n.footprint_m)).collect();
    let field = LikelihoodField::new(mosaic, &footprints, localize.field_smoothing_m)?;
    Ok(PriorMap {
        field,
        nodes: nodes.iter().map(|(_, p)| *p).collect(),
        mission: PathBuf::from(&mission.name),
        config: config.clone(),
        truth_from_map,
    })
}

/// The pose of `trajectory` stamped within [`STAMP_MATCH_S`] of `stamp_s`.
fn pose_at_stamp(trajectory: &[TrajectoryPose], stamp_s: f64) -> Option<Se2> {
    let i = trajectory.partition_point(|p| p.stamp_s < stamp_s - STAMP_MATCH_S);
    trajectory
        .get(i)
        .filter(|p| (p.stamp_s - stamp_s).abs() <= STAMP_MATCH_S)
        .map(|p| p.pose)
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
