//! The prior map of `echofield localize`, rebuilt from a finished run
//! (read from its output folder by [`super::run_folder`]).
//!
//! The nodes' acoustic images `I_j` are not stored by a run (they are the
//! bulk of its memory), so they are rebuilt here exactly as the run built
//! them: the same mission, the same config, the batch (smoothed)
//! navigation, the same rotations and [`build_node`]. Each node
//! is matched to its optimised pose by its stamp; rotations that did not
//! become nodes of the run are left out.
//!
//! The images are then placed at the optimised poses in one world grid
//! ([`build_mosaic`], blended as `field_blend` says) and turned into the
//! likelihood field ([`LikelihoodField`]), covered within each node's
//! footprint; when `refine_blend` differs, a second mosaic so blended is
//! the field's refine raster (the refined estimate's).
//! Why one field rather than the node images themselves: a particle is
//! then scored with one bilinear lookup per scan point, whatever the
//! number of map nodes it overlaps.

use crate::slam::SlamConfig;
use crate::slam::outputs::mosaic::{MosaicBlend, MosaicConfig, build_mosaic};
use crate::slam::pipeline::prepare;
use anyhow::{Context, Result, bail};
use echofield_frontend::dead_reckoning;
use echofield_frontend::image::Grid;
use echofield_frontend::localization::{FieldBlend, LikelihoodField, LocalizationConfig};
use echofield_frontend::nodes::{NodeData, Skip, build_node};
use echofield_frontend::rotation::assemble_rotations;
use echofield_frontend::sensors::Mission;
use echofield_graph::Se2;
use echofield_graph::io::TrajectoryPose;
use rayon::prelude::*;
use std::path::PathBuf;

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
    let nodes = rebuild_nodes(mission, config, trajectory)?;
    let field = likelihood_field(&nodes, localize)?;
    Ok(PriorMap {
        field,
        nodes: nodes.iter().map(|(_, p)| *p).collect(),
        mission: PathBuf::from(&mission.name),
        config: config.clone(),
        truth_from_map,
    })
}

/// The nodes of `mission` that the run with `config` made, rebuilt as it
/// built them, each with its optimised pose from `trajectory`; rotations
/// without a pose there are left out (a warning when some node of the run
/// is missing). Errors: bad records, no node rebuilt.
fn rebuild_nodes(
    mission: &Mission,
    config: &SlamConfig,
    trajectory: &[TrajectoryPose],
) -> Result<Vec<(NodeData, Se2)>> {
    let (mission, config, _, _) = prepare(mission, config)?;
    let navigation = dead_reckoning::run(&mission, &config.dead_reckoning)
        .with_context(|| format!("dead reckoning of the map mission {}", mission.name))?;
    let rotations = assemble_rotations(&mission.beams, &config.rotation)
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
                &config.segmentation,
                &config.image,
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
    Ok(nodes)
}

/// The node images placed at their poses and turned into the likelihood
/// field, covered within each node's footprint: the particles' field
/// blended as `localize.field_blend` says; when `localize.refine_blend`
/// differs, a second mosaic so blended, on the first one's cells, is the
/// field the estimate is refined on.
fn likelihood_field(
    nodes: &[(NodeData, Se2)],
    localize: &LocalizationConfig,
) -> Result<LikelihoodField> {
    // Freshly built nodes hold their images: reading them rebuilds nothing.
    let resident = nodes
        .iter()
        .map(|(n, p)| Ok((n.image.image()?, *p)))
        .collect::<Result<Vec<_>, echofield_frontend::FrontendError>>()?;
    let images: Vec<_> = resident.iter().map(|(i, p)| (i.grid(), *p)).collect();
    let mosaic_config = MosaicConfig::likelihood_field(localize.field_cell_m);
    let mosaic = |blend: FieldBlend| {
        let blend = match blend {
            FieldBlend::Max => MosaicBlend::Max,
            FieldBlend::Mean => MosaicBlend::Mean,
        };
        build_mosaic(
            &images,
            &MosaicConfig {
                blend,
                ..mosaic_config.clone()
            },
        )
    };
    let particles = mosaic(localize.field_blend)?;
    let refine = (localize.refine_blend != localize.field_blend)
        .then(|| mosaic(localize.refine_blend).map(|m| on_raster_of(&m, &particles)))
        .transpose()?;
    let footprints: Vec<(Se2, f64)> = nodes.iter().map(|(n, p)| (*p, n.footprint_m)).collect();
    let field = LikelihoodField::new(particles, &footprints, localize.field_smoothing_m)?;
    Ok(match refine {
        Some(r) => field.with_refine_raster(r, localize.field_smoothing_m)?,
        None => field,
    })
}

/// `source` resampled (nearest cell) onto the raster of `like` (0 where
/// `source` has no cell). The mosaics of one map share the cell size and
/// the lattice; only their crops differ (each is cropped to its own
/// echoes), so this copies cells.
fn on_raster_of(source: &Grid, like: &Grid) -> Grid {
    let (x0, y0) = like.origin_m();
    let mut out = Grid::zeros(x0, y0, like.cell_size_m(), like.width(), like.height());
    let width = like.width();
    for (k, v) in out.values_mut().iter_mut().enumerate() {
        let (cx, cy) = like.cell_centre_m((k % width) as i64, (k / width) as i64);
        let (ix, iy) = source.cell_of(cx, cy);
        *v = source.cell(ix, iy);
    }
    out
}

/// The pose of `trajectory` stamped within [`STAMP_MATCH_S`] of `stamp_s`.
pub(super) fn pose_at_stamp(trajectory: &[TrajectoryPose], stamp_s: f64) -> Option<Se2> {
    let i = trajectory.partition_point(|p| p.stamp_s < stamp_s - STAMP_MATCH_S);
    trajectory
        .get(i)
        .filter(|p| (p.stamp_s - stamp_s).abs() <= STAMP_MATCH_S)
        .map(|p| p.pose)
}
