//! Error budget of a run against ground truth: how far the measurements of
//! each kind of edge of the final graph are from the ground-truth relative
//! poses, and how much of the trajectory error each kind causes.
//!
//! - **Edge errors** (per kind: odometry, sequential, loop): the error of a
//!   measurement `z` is its translation minus the true one (x, y in the
//!   `from` node's frame) and its heading minus the true one, the truth
//!   being the ground-truth relative pose of the two nodes. The table gives
//!   its mean (a bias survives the averaging of the graph, noise does
//!   not), its RMS, the RMS of each component of the backend's error
//!   (`z⁻¹ ∘ truth`, the coordinates of the edge's information) divided by
//!   that component's standard deviation (1 for a well-calibrated
//!   covariance, below 1 for a cautious one), the mean NEES (`eᵀ Ω e` at
//!   the true poses, 3 for a well-calibrated covariance) and,
//!   over edges at least [`MIN_SCALE_DISTANCE_M`] long, the mean error
//!   along the true displacement and the scale `Σ |t|·a / Σ |t|²` of those
//!   along-track errors `a`. Priors hold absolute headings in the dead
//!   reckoning's frame and are left out.
//! - **Oracle solves**: the final graph solved again (the configured
//!   solver, from its configured initialisation) with the measurements of
//!   some kinds replaced by their ground-truth values, information and
//!   robust kernels unchanged; the ATE of each solve (RMSE after the best
//!   SE(2) alignment, as `report.json`'s) shows what the errors of those
//!   kinds cost. The first row solves the graph unchanged, for a like-for-
//!   like reference; the last replaces every relative edge, so what it
//!   leaves comes from the heading priors. One more solve keeps every
//!   measurement but divides the odometry's information by
//!   [`WEAK_ODOMETRY`]: the motion the sonar's edges make of the mission
//!   on their own. Each solve also gives the scale of its motion, the
//!   least-squares `s` of `t ≈ s · t_true` over the consecutive nodes'
//!   translations (below 1: the solution moves less than the vehicle).
//!
//! Edges with a node the ground truth does not cover keep their
//! measurement and are left out of the statistics; the ATE is over the
//! nodes with ground truth.

use super::SlamError;
use super::evaluation::MAX_TIME_DIFF_S;
use super::result::SlamOutput;
use crate::eval::{Alignment, ate};
use echofield_backend::{SolverConfig, edge_error, optimize};
use echofield_graph::io::TrajectoryPose;
use echofield_graph::{Edge, EdgeKind, PoseGraph, Se2, wrap_angle};
use nalgebra::Vector3;
use serde::Serialize;

/// Edges shorter than this are left out of the along-track statistics, m.
pub const MIN_SCALE_DISTANCE_M: f64 = 0.5;

/// Factor on the odometry's information in the solve that shows the
/// sonar's own motion.
pub const WEAK_ODOMETRY: f64 = 0.01;

/// The relative edge kinds of a SLAM graph, in table order.
const RELATIVE_KINDS: [EdgeKind; 3] = [EdgeKind::Odometry, EdgeKind::Sequential, EdgeKind::Loop];

/// Errors of the measurements of one edge kind against ground truth.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct KindErrors {
    pub kind: EdgeKind,
    /// Edges of this kind whose two nodes have ground truth (at least 1).
    pub edges: usize,
    /// Mean error `[x_m, y_m, theta_deg]`.
    pub mean_error: [f64; 3],
    /// RMS error `[x_m, y_m, theta_deg]`.
    pub rms_error: [f64; 3],
    /// RMS of the error divided by the edge's standard deviation, per
    /// component `[x, y, theta]`.
    pub rms_normalised_error: [f64; 3],
    /// Mean `eᵀ Ω e` at the ground-truth poses.
    pub mean_nees: f64,
    /// Edges at least [`MIN_SCALE_DISTANCE_M`] long.
    pub scale_edges: usize,
    /// Mean error along the true displacement, m.
    pub along_track_bias_m: f64,
    /// `Σ |t|·a / Σ |t|²` of the along-track errors `a` (0.001 = 0.1% long).
    pub scale_error: f64,
}

/// One solve with some kinds' measurements set to their ground truth.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OracleSolve {
    /// The kinds whose measurements were replaced (none: the graph as is).
    pub replaced: Vec<EdgeKind>,
    /// Factor on the odometry edges' information: 1, or [`WEAK_ODOMETRY`].
    pub odometry_information_factor: f64,
    /// ATE RMSE of the solution, SE(2)-aligned, m.
    pub ate_rmse_m: f64,
    /// Scale of the solution's motion against the true motion (module
    /// doc); none with fewer than two consecutive nodes with ground truth.
    pub motion_scale: Option<f64>,
}

/// The error budget of a run (module doc).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ErrorBudget {
    /// Nodes with ground truth.
    pub nodes_with_ground_truth: usize,
    /// The kinds with at least one edge between nodes with ground truth.
    pub edges: Vec<KindErrors>,
    /// The graph as is; odometry, sequential and loop edges alone;
    /// sequential and loop; all three (variants reduced to the kinds
    /// present, without repeats); last, the graph as is with the weakened
    /// odometry.
    pub oracle_solves: Vec<OracleSolve>,
}

/// The error budget of `output`; `None` when the mission has no ground
/// truth. Fails when a solve fails.
pub fn error_budget(output: &SlamOutput) -> Result<Option<ErrorBudget>, SlamError> {
    let truth: Vec<Option<Se2>> = output.nodes.iter().map(|n| n.ground_truth).collect();
    let stamps: Vec<f64> = output.nodes.iter().map(|n| n.stamp_s).collect();
    budget(
        &output.graph,
        &truth,
        &stamps,
        &output.config.backend.solver,
    )
}

/// The error budget of `graph` (node `i` at index `i`, true pose
/// `truth[i]`, stamp `stamps_s[i]`) solved with `solver`.
pub fn budget(
    graph: &PoseGraph,
    truth: &[Option<Se2>],
    stamps_s: &[f64],
    solver: &SolverConfig,
) -> Result<Option<ErrorBudget>, SlamError> {
    let nodes_with_ground_truth = truth.iter().flatten().count();
    if nodes_with_ground_truth == 0 {
        return Ok(None);
    }
    let edges: Vec<KindErrors> = RELATIVE_KINDS
        .iter()
        .map(|&kind| kind_errors(graph, truth, kind))
        .filter(|k| k.edges > 0)
        .collect();
    let present: Vec<EdgeKind> = edges.iter().map(|k| k.kind).collect();
    let mut variants: Vec<Vec<EdgeKind>> = Vec::new();
    for variant in [
        &[][..],
        &[EdgeKind::Odometry],
        &[EdgeKind::Sequential],
        &[EdgeKind::Loop],
        &[EdgeKind::Sequential, EdgeKind::Loop],
        &RELATIVE_KINDS,
    ] {
        let kept: Vec<EdgeKind> = variant
            .iter()
            .copied()
            .filter(|k| present.contains(k))
            .collect();
        if (variant.is_empty() || !kept.is_empty()) && !variants.contains(&kept) {
            variants.push(kept);
        }
    }
    let oracle_solves = variants
        .iter()
        .map(|replaced| (replaced, 1.0))
        .chain(std::iter::once((&Vec::new(), WEAK_ODOMETRY)))
        .map(|(replaced, factor)| {
            let mut g = with_true_measurements(graph, truth, replaced, factor)?;
            optimize(&mut g, solver)?;
            let poses = g.poses();
            Ok(OracleSolve {
                replaced: replaced.clone(),
                odometry_information_factor: factor,
                ate_rmse_m: trajectory_error(&poses, truth, stamps_s)?,
                motion_scale: motion_scale(&poses, truth),
            })
        })
        .collect::<Result<Vec<_>, SlamError>>()?;
    Ok(Some(ErrorBudget {
        nodes_with_ground_truth,
        edges,
        oracle_solves,
    }))
}

/// The true relative pose of a relative edge, when both nodes have one.
fn true_relative(edge: &Edge, truth: &[Option<Se2>]) -> Option<Se2> {
    let from = truth.get(usize::try_from(edge.from).ok()?).copied()??;
    let to = truth.get(usize::try_from(edge.to).ok()?).copied()??;
    Some(from.between(&to))
}

fn kind_errors(graph: &PoseGraph, truth: &[Option<Se2>], kind: EdgeKind) -> KindErrors {
    let (mut n, mut sum, mut sq, mut norm_sq, mut nees) = (
        0usize,
        Vector3::zeros(),
        Vector3::zeros(),
        Vector3::zeros(),
        0.0,
    );
    let (mut scale_n, mut along_sum, mut num, mut den) = (0usize, 0.0, 0.0, 0.0);
    for edge in graph.edges().filter(|e| e.kind == kind) {
        let Some(t) = true_relative(edge, truth) else {
            continue;
        };
        let dt = edge.measurement.translation() - t.translation();
        let dtheta = wrap_angle(edge.measurement.theta() - t.theta());
        let e = Vector3::new(dt.x, dt.y, dtheta.to_degrees());
        n += 1;
        sum += e;
        sq += e.component_mul(&e);
        // The backend's error, in the coordinates of the edge's information.
        let g = edge_error(edge, &Se2::identity(), &t);
        nees += g.dot(&(edge.information * g));
        if let Some(cov) = edge.information.try_inverse() {
            for i in 0..3 {
                let sd = cov[(i, i)].max(0.0).sqrt();
                if sd > 0.0 {
                    norm_sq[i] += (g[i] / sd).powi(2);
                }
            }
        }
        let length = t.translation().norm();
        if length >= MIN_SCALE_DISTANCE_M {
            let along = edge.measurement.translation().dot(&t.translation()) / length - length;
            scale_n += 1;
            along_sum += along;
            num += length * along;
            den += length * length;
        }
    }
    let mean = |v: Vector3<f64>| -> [f64; 3] { (v / n.max(1) as f64).into() };
    let root = |v: [f64; 3]| v.map(f64::sqrt);
    KindErrors {
        kind,
        edges: n,
        mean_error: mean(sum),
        rms_error: root(mean(sq)),
        rms_normalised_error: root(mean(norm_sq)),
        mean_nees: nees / n.max(1) as f64,
        scale_edges: scale_n,
        along_track_bias_m: if scale_n == 0 {
            0.0
        } else {
            along_sum / scale_n as f64
        },
        scale_error: if den > 0.0 { num / den } else { 0.0 },
    }
}

/// A copy of `graph` whose edges of the kinds in `replaced` measure the
/// ground-truth relative pose (where both nodes have one) and whose
/// odometry edges' information is multiplied by `odometry_factor`.
fn with_true_measurements(
    graph: &PoseGraph,
    truth: &[Option<Se2>],
    replaced: &[EdgeKind],
    odometry_factor: f64,
) -> Result<PoseGraph, SlamError> {
    let mut g = PoseGraph::new();
    for node in graph.nodes() {
        g.add_node(node.clone())?;
    }
    for edge in graph.edges() {
        let mut edge = edge.clone();
        if replaced.contains(&edge.kind)
            && let Some(t) = true_relative(&edge, truth)
        {
            edge.measurement = t;
        }
        if edge.kind == EdgeKind::Odometry {
            edge.information *= odometry_factor;
        }
        g.add_edge(edge)?;
    }
    for &id in graph.fixed() {
        g.fix(id)?;
    }
    Ok(g)
}

/// The least-squares scale of the motion between consecutive `poses`
/// against the true motion (module doc).
fn motion_scale(poses: &[Se2], truth: &[Option<Se2>]) -> Option<f64> {
    let (mut st, mut tt, mut pairs) = (0.0, 0.0, 0);
    for (p, t) in poses.windows(2).zip(truth.windows(2)) {
        if let [Some(t0), Some(t1)] = t {
            let true_step = t0.between(t1).translation();
            st += p[0].between(&p[1]).translation().dot(&true_step);
            tt += true_step.norm_squared();
            pairs += 1;
        }
    }
    (pairs >= 2 && tt > 0.0).then(|| st / tt)
}

/// ATE RMSE (SE(2)-aligned) of `poses` against the nodes' ground truth.
fn trajectory_error(
    poses: &[Se2],
    truth: &[Option<Se2>],
    stamps_s: &[f64],
) -> Result<f64, SlamError> {
    let (estimate, reference): (Vec<TrajectoryPose>, Vec<TrajectoryPose>) = poses
        .iter()
        .zip(truth)
        .zip(stamps_s)
        .filter_map(|((&pose, t), &stamp_s)| {
            Some((
                TrajectoryPose { stamp_s, pose },
                TrajectoryPose {
                    stamp_s,
                    pose: (*t)?,
                },
            ))
        })
        .unzip();
    ate(&estimate, &reference, Alignment::Se2, MAX_TIME_DIFF_S)
        .map(|a| a.rmse_m)
        .map_err(|e| SlamError::Evaluation(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use echofield_graph::Node;
    use nalgebra::Matrix3;

    const SCALE: f64 = 1.02;

    /// A 20-node arc (1 m steps, turning 5° per step), node 0 fixed at its
    /// true pose. Odometry measures every step 2% long; sequential edges
    /// measure the true steps, and two loops the true relative poses.
    fn arc() -> (PoseGraph, Vec<Option<Se2>>, Vec<f64>) {
        let truth: Vec<Se2> = (0..20)
            .scan(Se2::identity(), |pose, _| {
                let here = *pose;
                *pose = pose.compose(&Se2::new(1.0, 0.0, 5.0_f64.to_radians()));
                Some(here)
            })
            .collect();
        let stamps: Vec<f64> = (0..20).map(f64::from).collect();
        let mut graph = PoseGraph::new();
        for (i, pose) in truth.iter().enumerate() {
            graph
                .add_node(Node {
                    id: i as u64,
                    pose: *pose,
                    stamp_s: Some(stamps[i]),
                })
                .unwrap();
        }
        let info = Matrix3::from_diagonal(&Vector3::new(100.0, 100.0, 1000.0));
        let mut add = |kind, i: usize, j: usize, z: Se2| {
            graph
                .add_edge(Edge::new(kind, i as u64, j as u64, z, info))
                .unwrap();
        };
        for i in 0..19 {
            let t = truth[i].between(&truth[i + 1]);
            let long = Se2::new(SCALE * t.x(), SCALE * t.y(), t.theta());
            add(EdgeKind::Odometry, i, i + 1, long);
            add(EdgeKind::Sequential, i, i + 1, t);
        }
        for (i, j) in [(0, 12), (4, 19)] {
            add(EdgeKind::Loop, i, j, truth[i].between(&truth[j]));
        }
        graph.fix(0).unwrap();
        (graph, truth.into_iter().map(Some).collect(), stamps)
    }

    fn kind(budget: &ErrorBudget, kind: EdgeKind) -> &KindErrors {
        budget.edges.iter().find(|k| k.kind == kind).unwrap()
    }

    #[test]
    fn edges_are_compared_with_the_true_relative_poses() {
        let (graph, truth, stamps) = arc();
        let b = budget(&graph, &truth, &stamps, &SolverConfig::default())
            .unwrap()
            .unwrap();
        assert_eq!(b.nodes_with_ground_truth, 20);
        let odometry = kind(&b, EdgeKind::Odometry);
        assert_eq!((odometry.edges, odometry.scale_edges), (19, 19));
        // Every step is 1 m along x and measured 1.02 m long: 2 cm along
        // track and in x, and a scale of exactly 2%.
        assert!((odometry.scale_error - 0.02).abs() < 1e-12);
        assert!((odometry.along_track_bias_m - 0.02).abs() < 1e-12);
        assert!((odometry.mean_error[0] - 0.02).abs() < 1e-12);
        assert!(odometry.mean_error[1].abs() < 1e-12 && odometry.mean_error[2].abs() < 1e-9);
        // σ = 0.1 m on x and y: 0.02 m is 0.2 σ, and the NEES 100 · 0.02².
        // The backend's error is in the measured step's end frame, turned
        // by 5° from the start frame: 0.02·cos 5° on x, 0.02·sin 5° on y.
        let (c, s) = (5.0_f64.to_radians().cos(), 5.0_f64.to_radians().sin());
        assert!((odometry.rms_normalised_error[0] - 0.2 * c).abs() < 1e-9);
        assert!((odometry.rms_normalised_error[1] - 0.2 * s).abs() < 1e-9);
        assert!((odometry.mean_nees - 0.04).abs() < 1e-9);
        for exact in [EdgeKind::Sequential, EdgeKind::Loop] {
            let k = kind(&b, exact);
            assert!(k.edges > 0);
            assert!(k.rms_error.iter().all(|e| e.abs() < 1e-9), "{k:?}");
            assert!(k.mean_nees < 1e-12);
        }
        assert_eq!(kind(&b, EdgeKind::Loop).edges, 2);
    }

    #[test]
    fn oracle_solves_show_what_each_kind_costs() {
        let (graph, truth, stamps) = arc();
        let b = budget(&graph, &truth, &stamps, &SolverConfig::default())
            .unwrap()
            .unwrap();
        let ate = |replaced: &[EdgeKind]| {
            b.oracle_solves
                .iter()
                .find(|o| o.replaced == replaced)
                .unwrap()
                .ate_rmse_m
        };
        assert_eq!(b.oracle_solves.len(), 7);
        assert_eq!(b.edges.len(), 3);
        // The long odometry pulls the solution away from the truth and
        // makes it move too far ...
        assert!(ate(&[]) > 1e-3, "{:?}", b.oracle_solves);
        let as_is = &b.oracle_solves[0];
        assert!(as_is.replaced.is_empty() && as_is.odometry_information_factor == 1.0);
        let long = as_is.motion_scale.unwrap();
        assert!(long > 1.001 && long < SCALE, "{long}");
        // ... less so with its information divided by 100, where the exact
        // sequential edges hold the motion ...
        let weak = b.oracle_solves.last().unwrap();
        assert!(weak.replaced.is_empty() && weak.odometry_information_factor == WEAK_ODOMETRY);
        let weak_scale = weak.motion_scale.unwrap();
        assert!(
            weak_scale > 1.0 && weak_scale - 1.0 < 0.05 * (long - 1.0),
            "{weak_scale}"
        );
        assert!(
            weak.ate_rmse_m < 0.1 * as_is.ate_rmse_m,
            "{:?}",
            b.oracle_solves
        );
        // ... and nothing else does: with it set to the truth, every edge
        // agrees with the true poses.
        assert!(ate(&[EdgeKind::Odometry]) < 1e-6);
        assert!(ate(&RELATIVE_KINDS) < 1e-6);
        for exact in &b.oracle_solves[1..6] {
            if exact.replaced.contains(&EdgeKind::Odometry) {
                assert!(
                    (exact.motion_scale.unwrap() - 1.0).abs() < 1e-9,
                    "{exact:?}"
                );
            }
        }
        // The other kinds were exact already.
        let same = (ate(&[EdgeKind::Loop]) - ate(&[])).abs();
        assert!(same < 1e-9, "{:?}", b.oracle_solves);
    }

    #[test]
    fn nodes_without_ground_truth_are_left_out() {
        let (graph, mut truth, stamps) = arc();
        truth[19] = None;
        let b = budget(&graph, &truth, &stamps, &SolverConfig::default())
            .unwrap()
            .unwrap();
        assert_eq!(b.nodes_with_ground_truth, 19);
        assert_eq!(kind(&b, EdgeKind::Odometry).edges, 18);
        assert_eq!(kind(&b, EdgeKind::Loop).edges, 1);
        // Without ground truth at node 12 nor 19 no loop is left: the loop
        // kind and the solves that would only replace it go (the last one
        // is the weakened odometry's).
        truth[12] = None;
        let b = budget(&graph, &truth, &stamps, &SolverConfig::default())
            .unwrap()
            .unwrap();
        assert!(b.edges.iter().all(|k| k.kind != EdgeKind::Loop));
        let replaced: Vec<Vec<EdgeKind>> =
            b.oracle_solves.iter().map(|o| o.replaced.clone()).collect();
        use EdgeKind::{Odometry, Sequential};
        assert_eq!(
            replaced,
            [
                vec![],
                vec![Odometry],
                vec![Sequential],
                vec![Odometry, Sequential],
                vec![]
            ]
        );
        let none = vec![None; 20];
        assert!(
            budget(&graph, &none, &stamps, &SolverConfig::default())
                .unwrap()
                .is_none()
        );
    }
}
