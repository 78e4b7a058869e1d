//! One pose graph over several placed missions: each mission's own graph
//! (its chain of odometry and sequential edges, its loops, its heading
//! priors) with node ids offset, cross-mission loop candidates matched and
//! checked as the run's loops are, and one robust solve.
//!
//! Frames: the merged graph is in the anchor's world frame (the first
//! mission of the order given, [`super::canonical_order`]; its node 0
//! stays fixed, as in a single run). A later mission's nodes start
//! at `map_from_mission ⊕ world_from_node` (its placement, see
//! [`super::placement`]) and are free: only the cross-mission loops tie
//! them to the anchor. Its heading priors (the compass headings of its
//! dead reckoning) keep their heading: every mission's dead reckoning
//! takes its heading from the compass, which the missions share, so a
//! prior says the same thing in the map frame as in the mission's own.
//! The placement's heading is only the starting value of the solve, which
//! takes the missions' relative heading from these priors and the
//! cross-mission loops together (turning the priors by it would make the
//! placement's heading a measurement it is not).
//!
//! Cross-mission candidates: each node of a later mission against the
//! [`CROSS_PER_NODE`] nearest nodes of earlier placed missions within
//! [`CROSS_RADIUS_M`] of it under the placement, matched `S_k` vs `I_j`
//! within the placement's uncertainty and checked by
//! [`echofield_frontend::loops::checks::examine`] (quality, covariance,
//! window edge, the symmetric match). A match that passes but moves the
//! node more than [`CROSS_AGREE_M`] / [`CROSS_AGREE_RAD`] from the
//! placement is rejected as `inconsistent`: the placement was verified by
//! several probes that agree, a single match that disagrees with it is the
//! suspect. The final solve may still switch accepted loops off
//! (`robust_kernel`), as in a single run.

use crate::slam::result::OutliersReport;
use crate::slam::{SlamConfig, SlamOutput};
use anyhow::{Context, Result};
use echofield_backend::{SolveSummary, optimize_robust};
use echofield_frontend::loops::checks::{Candidate, examine};
use echofield_frontend::loops::records::{LoopRecord, RejectReason};
use echofield_frontend::matcher::SearchWindow;
use echofield_frontend::nodes::NodeData;
use echofield_graph::se2::wrap_angle;
use echofield_graph::{Edge, EdgeKind, PoseGraph, Se2};
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use std::collections::{HashMap, HashSet};

/// Nodes of earlier missions each node of a later mission is matched
/// against, at most.
pub const CROSS_PER_NODE: usize = 2;
/// Largest distance between two nodes under the placement for a
/// cross-mission candidate, m.
pub const CROSS_RADIUS_M: f64 = 10.0;
/// ... or, when larger, this share of the smaller of the two nodes'
/// footprints: two nodes this far apart still see half of what either
/// sees, so the candidates spread over the whole overlap of the missions
/// rather than only where their tracks cross.
pub const CROSS_FOOTPRINT_FRACTION: f64 = 0.5;
/// Standard deviation of a placement, per axis (m, m, rad), as the prior
/// covariance of the cross-mission candidates; their window is
/// `loops.n_sigma` of it, clamped as the run's loop windows.
const PLACEMENT_SIGMA: [f64; 3] = [0.5, 0.5, 0.035];
/// A cross-mission match may move its node this far from the placement.
pub const CROSS_AGREE_M: f64 = 1.5;
pub const CROSS_AGREE_RAD: f64 = 0.06;

/// A loop between two missions' nodes (or within one: the runs' own).
#[derive(Clone, Debug)]
pub struct MergedLoop {
    pub from_mission: usize,
    pub from_node: usize,
    pub to_mission: usize,
    pub to_node: usize,
    /// The record, its `from` / `to` the merged graph's ids.
    pub record: LoopRecord,
}

/// The merged graph and what went into it.
pub struct Merged {
    /// The solved graph; mission `m`'s node `k` has id `offsets[m] + k`.
    pub graph: PoseGraph,
    /// Missions in the graph, in order, with their first id.
    pub members: Vec<(usize, usize)>,
    /// Every cross-mission candidate, in the order examined.
    pub cross_loops: Vec<MergedLoop>,
    pub summary: SolveSummary,
    pub outliers: OutliersReport,
}

impl Merged {
    /// The solved poses of mission `m` (map frame), `None` when it is not
    /// in the graph.
    pub fn poses_of(&self, mission: usize, nodes: usize) -> Option<Vec<Se2>> {
        let &(_, first) = self.members.iter().find(|(m, _)| *m == mission)?;
        let poses = self.graph.poses();
        Some(poses[first..first + nodes].to_vec())
    }

    /// Accepted cross-mission loops.
    pub fn accepted_cross(&self) -> usize {
        self.cross_loops
            .iter()
            .filter(|l| l.record.accepted)
            .count()
    }
}

/// The nodes of a run as the loop checks take them.
fn node_data(run: &SlamOutput) -> Vec<NodeData> {
    run.nodes
        .iter()
        .zip(run.scans.iter().zip(&run.images))
        .map(|(n, (scan, image))| NodeData {
            rotation_index: n.rotation_index,
            stamp_s: n.stamp_s,
            beams: n.beams.clone(),
            dead_reckoning: n.dead_reckoning,
            scan: scan.clone(),
            image: image.clone(),
            footprint_m: super::placement::footprint_m(&scan.points),
            in_dvl_gap: n.in_dvl_gap,
        })
        .collect()
}

/// Merges the `runs` whose `placements` (`map_from_mission`) are known
/// into one graph and solves it (see the module doc), taking them in
/// `order` (input indices; the first, the anchor, must be placed at the
/// identity): node ids, candidates and the solve follow `order`, not the
/// input order. `examined`: records [`confirming_loops`] already matched
/// at these placements, taken instead of matching their candidates again
/// (any other candidate is matched here). Errors: a failed match or solve.
pub fn merge(
    runs: &[SlamOutput],
    placements: &[Option<Se2>],
    order: &[usize],
    config: &SlamConfig,
    examined: &[LoopRecord],
) -> Result<Merged> {
    let mut joint = Joint::of(runs, placements, order)?;
    let candidates = cross_candidates(&joint.members, &joint.placed_poses, &joint.nodes, config);
    let records = joint.examine(&candidates, examined, config)?;
    let mut cross_loops: Vec<MergedLoop> = records
        .into_iter()
        .map(|record| joint.judge(record))
        .collect();
    for l in cross_loops.iter().filter(|l| l.record.accepted) {
        let r = &l.record;
        let (Some(z), Some(cov)) = (r.measurement, r.covariance) else {
            continue;
        };
        let Some(information) = cov.try_inverse() else {
            continue;
        };
        joint
            .graph
            .add_edge(Edge::new(EdgeKind::Loop, r.from, r.to, z, information))?;
    }
    let mut graph = joint.graph;
    let summary = optimize_robust(&mut graph, &config.backend.solver, &config.backend.outliers)
        .context("the merged graph's solve")?;
    let switched: HashSet<(u64, u64)> = summary
        .switched_off
        .iter()
        .map(|s| (s.from, s.to))
        .collect();
    for l in &mut cross_loops {
        if l.record.accepted && switched.contains(&(l.record.from, l.record.to)) {
            l.record.accepted = false;
            l.record.rejected_by = Some(RejectReason::RobustKernel);
        }
    }
    Ok(Merged {
        graph,
        members: joint.members,
        cross_loops,
        outliers: OutliersReport::from(&summary),
        summary: summary.least_squares,
    })
}

/// The cross-mission loops that would be accepted for mission `m`, the
/// last of `order` (input indices, the anchor first), at its placement
/// in `placements`: its candidates against the earlier placed missions,
/// matched and judged as [`merge`] does, before any solve; with the
/// matched records, under the joint ids [`merge`] gives the same
/// missions (a later mission's ids come after), for it to reuse. 0 and
/// none when fewer than two of `order` are placed. Errors: a failed
/// match.
pub fn confirming_loops(
    runs: &[SlamOutput],
    placements: &[Option<Se2>],
    order: &[usize],
    config: &SlamConfig,
) -> Result<(usize, Vec<LoopRecord>)> {
    let joint = Joint::of(runs, placements, order)?;
    let Some(&(last, first)) = joint.members.last() else {
        return Ok((0, Vec::new()));
    };
    if joint.members.len() < 2 || order.last() != Some(&last) {
        return Ok((0, Vec::new()));
    }
    let candidates: Vec<Candidate> =
        cross_candidates(&joint.members, &joint.placed_poses, &joint.nodes, config)
            .into_iter()
            .filter(|c| c.to >= first)
            .collect();
    let records = joint.examine(&candidates, &[], config)?;
    let accepted = records
        .iter()
        .filter(|r| r.rejected_by.is_none() && joint.agrees(r))
        .count();
    Ok((accepted, records))
}

/// The placed missions joined, before any cross-mission loop: one graph,
/// the nodes' data and placed poses under joint ids, and each joint id's
/// `(mission, node)`.
struct Joint {
    /// `(mission, first joint id)` in the canonical order.
    members: Vec<(usize, usize)>,
    graph: PoseGraph,
    nodes: Vec<NodeData>,
    placed_poses: Vec<Se2>,
    mission_of: Vec<(usize, usize)>,
}

impl Joint {
    /// The missions of `order` that have a placement, in that order; the
    /// first one keeps its fixed node (the anchor).
    fn of(runs: &[SlamOutput], placements: &[Option<Se2>], order: &[usize]) -> Result<Self> {
        let mut joint = Self {
            members: Vec::new(),
            graph: PoseGraph::new(),
            nodes: Vec::new(),
            placed_poses: Vec::new(),
            mission_of: Vec::new(),
        };
        for &m in order {
            let (run, placement) = (&runs[m], &placements[m]);
            let Some(map_from_mission) = placement else {
                continue;
            };
            let first = joint.nodes.len();
            joint.members.push((m, first));
            let anchor = m == joint.members[0].0;
            add_run(&mut joint.graph, run, map_from_mission, first, anchor)?;
            joint.nodes.extend(node_data(run));
            joint.placed_poses.extend(
                run.graph
                    .poses()
                    .iter()
                    .map(|p| map_from_mission.compose(p)),
            );
            joint
                .mission_of
                .extend((0..run.nodes.len()).map(|k| (m, k)));
        }
        Ok(joint)
    }

    /// The records of `candidates` (joint ids), in their order: the one of
    /// `examined` with the same pair, else matched and checked here (in
    /// parallel). Errors: a failed match.
    fn examine(
        &self,
        candidates: &[Candidate],
        examined: &[LoopRecord],
        config: &SlamConfig,
    ) -> Result<Vec<LoopRecord>> {
        let done: HashMap<(u64, u64), &LoopRecord> =
            examined.iter().map(|r| ((r.from, r.to), r)).collect();
        candidates
            .par_iter()
            .map(|c| match done.get(&(c.from as u64, c.to as u64)) {
                Some(record) => Ok((*record).clone()),
                None => examine(c, c.to, &self.nodes, &config.matcher, &config.loops),
            })
            .collect::<Result<_, _>>()
            .context("cross-mission loop matches")
    }

    /// Whether `record`'s measurement puts its newer node within
    /// `CROSS_AGREE_M` and `CROSS_AGREE_RAD` of where the placement put it
    /// (false without a measurement).
    fn agrees(&self, record: &LoopRecord) -> bool {
        let Some(z) = record.measurement else {
            return false;
        };
        let measured = self.placed_poses[record.from as usize].compose(&z);
        let placed = self.placed_poses[record.to as usize];
        (measured.x() - placed.x()).hypot(measured.y() - placed.y()) <= CROSS_AGREE_M
            && wrap_angle(measured.theta() - placed.theta()).abs() <= CROSS_AGREE_RAD
    }

    /// A cross-mission record that passed the loop checks is accepted when
    /// its measurement agrees with the placement (within `CROSS_AGREE_M`
    /// and `CROSS_AGREE_RAD`), else rejected as inconsistent; the record
    /// under mission-local node numbers.
    fn judge(&self, mut record: LoopRecord) -> MergedLoop {
        if record.rejected_by.is_none() && record.measurement.is_some() {
            if self.agrees(&record) {
                record.accepted = true;
            } else {
                record.rejected_by = Some(RejectReason::Inconsistent);
            }
        }
        let (from_mission, from_node) = self.mission_of[record.from as usize];
        let (to_mission, to_node) = self.mission_of[record.to as usize];
        MergedLoop {
            from_mission,
            from_node,
            to_mission,
            to_node,
            record,
        }
    }
}

/// Adds `run`'s graph with ids offset by `first`, its poses and priors
/// turned by `map_from_mission`; its fixed node stays fixed only for the
/// first mission (`anchor`).
fn add_run(
    graph: &mut PoseGraph,
    run: &SlamOutput,
    map_from_mission: &Se2,
    first: usize,
    anchor: bool,
) -> Result<()> {
    let offset = first as u64;
    for node in run.graph.nodes() {
        let mut node = node.clone();
        node.id += offset;
        node.pose = map_from_mission.compose(&node.pose);
        graph.add_node(node)?;
    }
    for edge in run.graph.edges() {
        let mut edge = edge.clone();
        edge.from += offset;
        edge.to += offset;
        if edge.kind == EdgeKind::Prior {
            // Moved with the mission, heading kept: see the module doc.
            let moved = map_from_mission.compose(&edge.measurement);
            edge.measurement = Se2::new(moved.x(), moved.y(), edge.measurement.theta());
        }
        graph.add_edge(edge)?;
    }
    if anchor {
        for id in run.graph.fixed().iter().copied().collect::<Vec<_>>() {
            graph.fix(id + offset)?;
        }
    }
    Ok(())
}

/// The cross-mission candidates (see the module doc), in the order of
/// the later mission's nodes, the nearer earlier node first.
fn cross_candidates(
    members: &[(usize, usize)],
    poses: &[Se2],
    nodes: &[NodeData],
    config: &SlamConfig,
) -> Vec<Candidate> {
    let covariance = Matrix3::from_diagonal(&Vector3::from(PLACEMENT_SIGMA.map(|s| s * s)));
    let n_sigma = config.loops.gate.n_sigma;
    let raw_window = SearchWindow::new(
        n_sigma * PLACEMENT_SIGMA[0],
        n_sigma * PLACEMENT_SIGMA[1],
        n_sigma * PLACEMENT_SIGMA[2],
    );
    let mut out = Vec::new();
    for (i, &(_, first)) in members.iter().enumerate().skip(1) {
        let end = members.get(i + 1).map_or(nodes.len(), |(_, f)| *f);
        for to in first..end {
            if !nodes[to].matchable() {
                continue;
            }
            let mut near: Vec<(f64, usize)> = (0..first)
                .filter(|&j| nodes[j].matchable())
                .map(|j| {
                    let d = (poses[j].x() - poses[to].x()).hypot(poses[j].y() - poses[to].y());
                    (d, j)
                })
                .filter(|&(d, j)| {
                    d <= CROSS_RADIUS_M.max(
                        CROSS_FOOTPRINT_FRACTION * nodes[j].footprint_m.min(nodes[to].footprint_m),
                    )
                })
                .collect();
            near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            for &(_, from) in near.iter().take(CROSS_PER_NODE) {
                out.push(Candidate {
                    from,
                    to,
                    prior: poses[from].inverse().compose(&poses[to]),
                    prior_covariance: covariance,
                    // Not predicted (no footprint model across missions):
                    // below every escalation threshold.
                    predicted_overlap: 0.0,
                    raw_window,
                    wide: false,
                    densify: false,
                });
            }
        }
    }
    out
}
