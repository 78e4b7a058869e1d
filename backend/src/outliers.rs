//! Optimisation of a graph that holds false loop closures, from no better
//! start than its trusted edges give: [`optimize_robust`].
//!
//! ## Why a robust kernel alone is not enough
//!
//! A robust kernel (Huber, Cauchy, DCS, the switchable constraints it
//! approximates) is a local device: it down-weights the edges that
//! disagree with the *current* estimate. Started from dead reckoning, every
//! loop closure of a long mission disagrees with it, true ones included, so
//! the kernel switches the true loops off as readily as the false ones and
//! the solve stays near dead reckoning (DCS from odometry on manhattan).
//! Started from a least-squares solution over all edges, the false loops
//! have already bent the graph. Graduated non-convexity starts from the
//! latter and relaxes the kernel step by step; it copes while false loops are
//! a minority of the loop closures, not when they outnumber the true ones.
//!
//! ## What is done instead
//!
//! 1. **Mutual support.** Two suspect edges whose ends lie close together
//!    along the trusted chain (`support_window_nodes`) close a short cycle
//!    with the chain; when that cycle is consistent with the propagated
//!    covariances (`support_chi2`) they support each other, in the manner
//!    of pairwise consistency maximisation. Random false loops almost never
//!    find support; a revisit closes a run of loops that support each
//!    other. Suspects with `min_support` partners are *believed*: solved
//!    without a kernel until step 4, so a run of true loops closes a large
//!    loop however far dead reckoning has drifted (the vertigo ring).
//! 2. **Grow the graph in node order** (the order of the mission). The
//!    poses start from the trusted edges (those without a kernel, normally
//!    odometry) by the solver's initialisation. Nodes are added
//!    `growth_step_nodes` at a time, each new node placed by the trusted
//!    start relative to the last solved node, and the graph so far is
//!    re-solved with the kernels (a few iterations, warm-started). A loop is
//!    first judged against an estimate whose drift is only that since the
//!    last closure, as an incremental back end judges it.
//! 3. **Solve the whole graph** from the grown estimate, with the kernel on
//!    the suspects that are not believed.
//! 4. **Switch off, solve, switch back on.** Every suspect whose χ² = eᵀΩe
//!    exceeds the switch-off threshold is switched off and the rest solved
//!    by least squares. The threshold is [`OutlierConfig::switch_off_chi2`],
//!    tightened when the believed loops fit far better than their stated
//!    covariance (`calibrated_threshold`). Then, in rounds: every
//!    switched-off edge that fits, alone, either the solution or what the
//!    graph knows (its *innovation* χ², `eᵀ(Σ + J H⁻¹ Jᵀ)⁻¹e`, which counts
//!    how uncertain the solution is where the edge lands) is a candidate;
//!    the candidates, most consistent first, are switched back on together
//!    when the least-squares χ² rises by no more than the same tail
//!    quantile for their degrees of freedom allows, otherwise the better
//!    half is tried, and so on. Edges that fit alone but not together (a
//!    cluster of false loops, each absorbable by a flexible graph) stay off.
//!    On a graph without outliers the answer is therefore the plain
//!    least-squares optimum, not a kernel-weighted approximation of it
//!    (unless [`OutlierConfig::final_kernel`] keeps the kernel).
//!
//! The graph keeps all its edges; [`RobustSolveSummary::switched_off`] lists
//! the ones the answer ignores.
//!
//! Preconditions: node order is the order of travel (true of g2o and TORO
//! benchmark files and of the graphs `echofield run` builds), and the
//! trusted edges tie every node to the gauge; otherwise the growth is
//! skipped for the nodes they do not reach and those start where the
//! initialisation puts them.

use crate::config::{Initialisation, RobustConfig, SolverConfig};
use crate::error::SolveError;
use crate::linear::{BlockSystem, fill_reducing_ordering};
use crate::linearize::{edge_error, edge_slots, error_and_jacobians, linearise};
use crate::problem::{Problem, ProblemEdge};
use crate::robust::RobustKernel;
use crate::solver::{Solver, linear_error, normalise};
use crate::summary::{SolveSummary, Termination};
use echofield_graph::{EdgeKind, NodeId, PoseGraph, Se2};
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Settings of [`optimize_robust`]; which edges are suspect and their
/// kernel come from [`SolverConfig::robust`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OutlierConfig {
    /// Nodes added per growth step. Smaller steps judge each loop against
    /// less drift and cost more solves (the work grows as the square of
    /// the node count over the step). Default: 100.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): the schedule of the robust solve, not a property of a mission.
    #[serde(skip)]
    pub growth_step_nodes: usize,
    /// Iteration cap of each growth step (the final solves use the solver's
    /// `max_iterations`). Default: 10.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): the schedule of the robust solve, not a property of a mission.
    #[serde(skip)]
    pub growth_iterations: usize,
    /// χ² (eᵀΩe, dimensionless) above which a suspect edge is switched off
    /// after the robust solve, and at or below which (as its own χ² or its
    /// innovation χ²) a switched-off edge may be switched back on; the joint
    /// test of edges switched back on together uses the same tail
    /// probability. Default: 21.11, the 99.99% quantile of χ² with 3
    /// degrees of freedom: a true loop whose covariance is honest is
    /// switched off with probability 1e-4. Tightened per graph by
    /// `calibrated_threshold`.
    pub switch_off_chi2: f64,
    /// Keep the kernel on the loops that stay switched on in the final
    /// solves (rather than plain least squares). Plain least squares returns
    /// the exact optimum of a graph without outliers; the kernel also
    /// damps loops that are slightly off without being switched off, which
    /// scan-matched loops of a real mission can be. Default: false.
    pub final_kernel: bool,
    /// Least-squares solves after the robust one (each may switch edges
    /// back on). Default: 10.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): the schedule of the robust solve, not a property of a mission.
    #[serde(skip)]
    pub max_rounds: usize,
    /// Two suspect edges can support each other when their ends lie at most
    /// this many nodes apart along the trusted chain (node order). Default:
    /// 10.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): the reach of mutual support along the chain, a property of the method.
    #[serde(skip)]
    pub support_window_nodes: usize,
    /// The cycle of two suspect edges and the chain between their ends is
    /// consistent when its χ² (against the propagated covariance) is at most
    /// this. Default: 11.34, the 99% quantile of χ² with 3 degrees of
    /// freedom.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): a test level (99% of χ² with 3 degrees of freedom), not a tuning value.
    #[serde(skip)]
    pub support_chi2: f64,
    /// A suspect edge with at least this many consistent partners is
    /// believed during the growth (solved without a kernel). Default: 3.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): the partners that make a loop believed, a property of the method.
    #[serde(skip)]
    pub min_support: usize,
}

impl Default for OutlierConfig {
    fn default() -> Self {
        Self {
            growth_step_nodes: 100,
            growth_iterations: 10,
            switch_off_chi2: 21.11,
            max_rounds: 10,
            final_kernel: false,
            support_window_nodes: 10,
            support_chi2: 11.34,
            min_support: 3,
        }
    }
}

impl OutlierConfig {
    /// Every value in range; errors name the field.
    pub fn validate(&self) -> Result<(), crate::ConfigError> {
        let out = |field, value: String, expected| crate::ConfigError::OutOfRange {
            field,
            value,
            expected,
        };
        if self.growth_step_nodes == 0 {
            return Err(out("growth_step_nodes", "0".into(), "at least 1"));
        }
        if self.growth_iterations == 0 {
            return Err(out("growth_iterations", "0".into(), "at least 1"));
        }
        if self.max_rounds == 0 {
            return Err(out("max_rounds", "0".into(), "at least 1"));
        }
        for (field, value) in [
            ("switch_off_chi2", self.switch_off_chi2),
            ("support_chi2", self.support_chi2),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(out(field, value.to_string(), "finite and > 0"));
            }
        }
        if self.min_support == 0 {
            return Err(out("min_support", "0".into(), "at least 1"));
        }
        Ok(())
    }
}

/// An edge the answer ignores.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SwitchedOff {
    /// Index of the edge in the graph's edge order.
    pub edge: usize,
    pub from: NodeId,
    pub to: NodeId,
    /// Its χ² at the returned poses.
    pub chi2: f64,
}

/// What [`optimize_robust`] did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RobustSolveSummary {
    /// Edges with a robust kernel (the suspects).
    pub suspect_edges: usize,
    /// Growth steps solved.
    pub growth_steps: usize,
    /// Of which stopped at their iteration cap (expected for some: they are
    /// warm starts, not answers).
    pub growth_steps_at_cap: usize,
    /// The whole-graph solve with the kernels.
    pub robust: SolveSummary,
    /// The last least-squares solve, whose poses are returned.
    pub least_squares: SolveSummary,
    /// Least-squares solves made.
    pub rounds: usize,
    /// Kernelled edges the returned poses ignore, in edge order.
    pub switched_off: Vec<SwitchedOff>,
    /// Wall time of the whole call, seconds.
    pub time_s: f64,
}

impl RobustSolveSummary {
    /// Whether the solve that gave the returned poses ended at its
    /// iteration cap (the answer may not be a minimum). The robust solve
    /// before it (`robust`) may stop at its cap without harm when the
    /// switching-off and re-admission that follow settle the loops.
    pub fn hit_iteration_cap(&self) -> bool {
        self.least_squares.termination == Termination::MaxIterations
    }
}

/// Optimises `graph` in place when some of its edges may be false (see the
/// module documentation): the edges of the kinds that have a kernel in
/// `solver.robust` are the suspects. Without any kernel this is a plain
/// [`crate::optimize`] with nothing switched off.
///
/// On error the graph is left unchanged.
pub fn optimize_robust(
    graph: &mut PoseGraph,
    solver: &SolverConfig,
    outliers: &OutlierConfig,
) -> Result<RobustSolveSummary, SolveError> {
    let start = Instant::now();
    solver.validate()?;
    outliers.validate()?;
    let suspect: Vec<bool> = graph
        .edges()
        .map(|e| solver.robust.kernel(e.kind) != RobustKernel::None)
        .collect();
    let suspect_edges = suspect.iter().filter(|s| **s).count();
    if suspect_edges == 0 {
        let summary = Solver::new(solver.clone())?.optimize(graph)?;
        return Ok(RobustSolveSummary {
            suspect_edges,
            growth_steps: 0,
            growth_steps_at_cap: 0,
            robust: summary.clone(),
            least_squares: summary,
            rounds: 1,
            switched_off: Vec::new(),
            time_s: start.elapsed().as_secs_f64(),
        });
    }

    // 1-2. The trusted start, the mutual support of the suspects, then the
    //      growth with the supported suspects believed.
    let mut work = graph.clone();
    let trusted = Solver::new(solver.clone())?.start_poses(&work)?;
    let support = mutual_support(&work, &trusted, &suspect, outliers);
    let kernels: Vec<RobustKernel> = work
        .edges()
        .zip(&support)
        .map(|(e, n)| match solver.robust.kernel(e.kind) {
            RobustKernel::None => RobustKernel::None,
            _ if *n >= outliers.min_support => RobustKernel::None,
            kernel => kernel,
        })
        .collect();
    tracing::debug!(
        "{} of {suspect_edges} suspect edges are believed (support of {} others)",
        kernels
            .iter()
            .zip(&suspect)
            .filter(|(k, s)| **s && **k == RobustKernel::None)
            .count(),
        outliers.min_support
    );
    let warm = SolverConfig {
        initialisation: Initialisation::Current,
        ..solver.clone()
    };
    let growth = grow(&work, &trusted, &kernels, &warm, outliers)?;

    // 3. The whole graph, from the grown poses.
    work.set_poses(&growth.poses);
    let robust = Solver::new(warm.clone())?.optimize_with(&mut work, Some(&kernels))?;

    // 4. Switch off, solve, switch back on what fits.
    let plain = if outliers.final_kernel {
        warm.clone()
    } else {
        SolverConfig {
            robust: RobustConfig::default(),
            ..warm.clone()
        }
    };
    let chi2 = edge_chi2(&work);
    let believed_chi2: Vec<f64> = suspect
        .iter()
        .zip(&kernels)
        .zip(&chi2)
        .filter(|((s, k), _)| **s && **k == RobustKernel::None)
        .map(|(_, c)| *c)
        .collect();
    let threshold = calibrated_threshold(outliers.switch_off_chi2, &believed_chi2);
    let mut off: Vec<bool> = suspect
        .iter()
        .zip(&chi2)
        .map(|(s, c)| *s && *c > threshold)
        .collect();
    tracing::debug!(
        "{} suspect edges above χ² {threshold:.2} after the robust solve",
        off.iter().filter(|o| **o).count()
    );
    let mut rounds = 0;
    let mut least_squares = robust.clone();
    let mut poses = work.poses();
    // The least-squares solution without the switched-off edges.
    let mut kept = without(&work, &off, &poses);
    match Solver::new(plain.clone())?.optimize(&mut kept) {
        Ok(summary) => {
            least_squares = summary;
            poses = kept.poses();
            rounds += 1;
        }
        // Switching off left some node with no trusted link: keep the
        // kernel's answer for this graph.
        Err(SolveError::Disconnected { .. }) => {
            tracing::warn!(
                "switching off the suspect edges disconnects the graph: the robust solution is returned"
            );
            off.iter_mut().for_each(|o| *o = false);
        }
        Err(e) => return Err(e),
    }
    while rounds < outliers.max_rounds && off.iter().any(|o| *o) {
        work.set_poses(&poses);
        kept.set_poses(&poses);
        let off_edges: Vec<usize> = (0..off.len()).filter(|k| off[*k]).collect();
        let candidates: Vec<echofield_graph::Edge> = work
            .edges()
            .zip(&off)
            .filter(|(_, o)| **o)
            .map(|(e, _)| e.clone())
            .collect();
        let innovation = innovation_chi2(&kept, &candidates, solver.threads)?;
        let plain_chi2 = edge_chi2(&work);
        // Every edge that fits, alone, the point estimate or what the graph
        // knows, most consistent first.
        let mut fitting: Vec<(usize, f64)> = off_edges
            .iter()
            .zip(&innovation)
            .filter(|(k, inn)| plain_chi2[**k] <= threshold || **inn <= threshold)
            .map(|(k, inn)| (*k, inn.min(plain_chi2[*k])))
            .collect();
        fitting.sort_by(|a, b| a.1.total_cmp(&b.1));
        let fitting: Vec<usize> = fitting.into_iter().map(|(k, _)| k).collect();
        // Try all of them together, then the more consistent half, ...
        let mut batches = Vec::new();
        let mut len = fitting.len();
        while len > 0 {
            batches.push(&fitting[..len]);
            len /= 2;
        }
        let mut admitted = false;
        for batch in batches {
            let mut trial_off = off.clone();
            for k in batch.iter() {
                trial_off[*k] = false;
            }
            let mut trial = without(&work, &trial_off, &poses);
            let summary = Solver::new(plain.clone())?.optimize(&mut trial)?;
            let rise = summary.final_chi2 - least_squares.final_chi2;
            let limit = same_tail_quantile(outliers.switch_off_chi2, 3 * batch.len()) * threshold
                / outliers.switch_off_chi2;
            tracing::debug!(
                "round {rounds}: {} edges fit alone; together they raise χ² by {rise:.1} (limit {limit:.1})",
                batch.len()
            );
            if rise <= limit {
                off = trial_off;
                kept = trial;
                poses = kept.poses();
                least_squares = summary;
                rounds += 1;
                admitted = true;
                break;
            }
        }
        if !admitted {
            break;
        }
    }
    work.set_poses(&poses);
    let chi2 = edge_chi2(&work);
    let switched_off = work
        .indexed_edges()
        .enumerate()
        .filter(|(k, _)| off[*k])
        .map(|(k, (_, _, e))| SwitchedOff {
            edge: k,
            from: e.from,
            to: e.to,
            chi2: chi2[k],
        })
        .collect();
    graph.set_poses(&poses);
    Ok(RobustSolveSummary {
        suspect_edges,
        growth_steps: growth.steps,
        growth_steps_at_cap: growth.steps_at_cap,
        robust,
        least_squares,
        rounds,
        switched_off,
        time_s: start.elapsed().as_secs_f64(),
    })
}

/// The poses after growing the graph in node order, and how many solves it
/// took.
struct Growth {
    poses: Vec<Se2>,
    steps: usize,
    steps_at_cap: usize,
}

/// Step 2 of the module documentation. `trusted` are the starting poses
/// from the trusted edges; `warm` solves from the current poses with the
/// kernels.
fn grow(
    graph: &PoseGraph,
    trusted: &[Se2],
    kernels: &[RobustKernel],
    warm: &SolverConfig,
    outliers: &OutlierConfig,
) -> Result<Growth, SolveError> {
    let n = graph.node_count();
    let step_config = SolverConfig {
        max_iterations: outliers.growth_iterations,
        ..warm.clone()
    };
    let mut solver = Solver::new(step_config)?;
    let mut poses = trusted.to_vec();
    let (mut steps, mut steps_at_cap) = (0, 0);
    // Nodes [0, solved) hold solved poses.
    let mut solved = 0;
    while solved < n {
        let end = (solved + outliers.growth_step_nodes).min(n);
        // Place the new nodes by the trusted start relative to the last
        // solved node.
        if solved > 0 {
            let anchor = poses[solved - 1].compose(&trusted[solved - 1].inverse());
            for k in solved..end {
                poses[k] = anchor.compose(&trusted[k]);
            }
        }
        // The final step is the whole graph, which the caller solves.
        if end == n {
            break;
        }
        let (mut part, part_kernels) = prefix(graph, kernels, end, &poses);
        match solver.optimize_with(&mut part, Some(&part_kernels)) {
            Ok(summary) => {
                steps += 1;
                if summary.termination == Termination::MaxIterations {
                    steps_at_cap += 1;
                }
                poses[..end].copy_from_slice(&part.poses());
            }
            // A prefix without edges, or whose nodes the edges so far do not
            // tie together: nothing to solve yet.
            Err(SolveError::NoEdges | SolveError::Disconnected { .. }) => {}
            Err(e) => return Err(e),
        }
        solved = end;
    }
    Ok(Growth {
        poses,
        steps,
        steps_at_cap,
    })
}

/// The first `end` nodes of `graph` (in node order) at `poses`, with the
/// edges among them, their kernels (from `kernels`, one per edge of
/// `graph`) and their fixed flags.
fn prefix(
    graph: &PoseGraph,
    kernels: &[RobustKernel],
    end: usize,
    poses: &[Se2],
) -> (PoseGraph, Vec<RobustKernel>) {
    let part = subgraph(graph, end, poses, |i, j, _| i < end && j < end);
    let part_kernels = graph
        .indexed_edges()
        .zip(kernels)
        .filter(|((i, j, _), _)| *i < end && *j < end)
        .map(|(_, k)| *k)
        .collect();
    (part, part_kernels)
}

/// `graph` at `poses` without the edges flagged in `off`.
fn without(graph: &PoseGraph, off: &[bool], poses: &[Se2]) -> PoseGraph {
    subgraph(graph, graph.node_count(), poses, |_, _, k| !off[k])
}

/// The first `nodes` nodes of `graph` at `poses`, the edges for which
/// `keep(from_index, to_index, edge_index)` holds (both ends must be among
/// those nodes), and the fixed flags of those nodes.
///
/// The additions cannot fail: ids, endpoints and measurements come from a
/// valid graph, so their `Result`s carry no information and are dropped.
fn subgraph(
    graph: &PoseGraph,
    nodes: usize,
    poses: &[Se2],
    keep: impl Fn(usize, usize, usize) -> bool,
) -> PoseGraph {
    let mut part = PoseGraph::new();
    for (node, pose) in graph.nodes().take(nodes).zip(poses) {
        let _ = part.add_node(echofield_graph::Node {
            pose: *pose,
            ..node.clone()
        });
    }
    for (k, (i, j, edge)) in graph.indexed_edges().enumerate() {
        if i < nodes && j < nodes && keep(i, j, k) {
            let _ = part.add_edge(edge.clone());
        }
    }
    for id in graph.fixed() {
        if part.contains(*id) {
            let _ = part.fix(*id);
        }
    }
    part
}

/// χ² of every edge at the graph's poses, in edge order.
fn edge_chi2(graph: &PoseGraph) -> Vec<f64> {
    graph
        .indexed_edges()
        .map(|(i, j, edge)| {
            let e = edge_error(edge, &graph.node_at(i).pose, &graph.node_at(j).pose);
            e.dot(&(edge.information * e))
        })
        .collect()
}

/// For each edge, how many other suspect edges agree with it (0 for the
/// trusted edges): step 1 of the module documentation, in the manner of
/// pairwise consistency maximisation (Mangelson, Dominic, Eustice,
/// Vasudevan, ICRA 2018) restricted to nearby pairs.
///
/// Two suspect edges `a -> b` (measurement `Z₁`) and `c -> d` (`Z₂`), with
/// `|a − c|` and `|b − d|` at most `support_window_nodes` in node order,
/// close the cycle `Z₁ · P(b→d) · Z₂⁻¹ · P(c→a)`, where `P` composes the
/// trusted relative poses between consecutive nodes (from `trusted`, the
/// trusted edges' start). The cycle is the identity when both are right;
/// its covariance is the first-order propagation of both edges' and every
/// chain step's covariance (a chain step's covariance is the inverse of the
/// summed information of the trusted edges between the two nodes). They
/// agree when the cycle's χ² is at most `support_chi2`. A pair whose chain
/// has a step without a trusted edge is not tested.
fn mutual_support(
    graph: &PoseGraph,
    trusted: &[Se2],
    suspect: &[bool],
    config: &OutlierConfig,
) -> Vec<usize> {
    let n = graph.node_count();
    // Covariance of the trusted step k -> k+1, if there is one.
    let mut step_information = vec![Matrix3::<f64>::zeros(); n.saturating_sub(1)];
    let mut has_step = vec![false; n.saturating_sub(1)];
    // Suspect edges as (low, high, low_from_high, covariance, edge index).
    let mut loops = Vec::new();
    for (k, (i, j, edge)) in graph.indexed_edges().enumerate() {
        if edge.kind == EdgeKind::Prior || i == j {
            continue;
        }
        let Some(covariance) = edge.information.try_inverse() else {
            continue;
        };
        if suspect[k] {
            if i < j {
                loops.push((i, j, edge.measurement, covariance, k));
            } else {
                // X_j⁻¹X_i = exp(−e) Z⁻¹ = Z⁻¹ exp(−Ad(Z) e).
                let ad = edge.measurement.adjoint();
                let inverse_covariance = ad * covariance * ad.transpose();
                loops.push((j, i, edge.measurement.inverse(), inverse_covariance, k));
            }
        } else if i.abs_diff(j) == 1 {
            // Information is in the error coordinates of i -> j; for a
            // step stored as j -> i use the inverse's (as above).
            let low = i.min(j);
            let information = if i < j {
                edge.information
            } else {
                let ad = edge.measurement.adjoint();
                match (ad * covariance * ad.transpose()).try_inverse() {
                    Some(info) => info,
                    None => continue,
                }
            };
            step_information[low] += information;
            has_step[low] = true;
        }
    }
    let step_covariance: Vec<Option<Matrix3<f64>>> = step_information
        .iter()
        .zip(&has_step)
        .map(|(info, has)| if *has { info.try_inverse() } else { None })
        .collect();
    let step = |k: usize| trusted[k].between(&trusted[k + 1]);
    // The chain from node u to node v as factors (transform, covariance),
    // or None when a step has no trusted edge.
    let chain = |u: usize, v: usize, factors: &mut Vec<(Se2, Matrix3<f64>)>| -> bool {
        if u <= v {
            for (k, c) in step_covariance.iter().enumerate().take(v).skip(u) {
                let Some(c) = c else {
                    return false;
                };
                factors.push((step(k), *c));
            }
        } else {
            for k in (v..u).rev() {
                let Some(c) = step_covariance[k] else {
                    return false;
                };
                let d = step(k);
                let ad = d.adjoint();
                factors.push((d.inverse(), ad * c * ad.transpose()));
            }
        }
        true
    };
    let mut order: Vec<usize> = (0..loops.len()).collect();
    order.sort_by_key(|&l| (loops[l].0, loops[l].1));
    let w = config.support_window_nodes;
    let mut support = vec![0usize; graph.edge_count()];
    let mut factors = Vec::new();
    for (rank, &l1) in order.iter().enumerate() {
        let (a, b, z1, c1, k1) = loops[l1];
        for &l2 in &order[rank + 1..] {
            let (c, d, z2, c2, k2) = loops[l2];
            if c > a + w {
                break;
            }
            if b.abs_diff(d) > w {
                continue;
            }
            // Z₁ · P(b→d) · Z₂⁻¹ · P(c→a).
            factors.clear();
            factors.push((z1, c1));
            if !chain(b, d, &mut factors) {
                continue;
            }
            let ad2 = z2.adjoint();
            factors.push((z2.inverse(), ad2 * c2 * ad2.transpose()));
            if !chain(c, a, &mut factors) {
                continue;
            }
            if cycle_chi2(&factors).is_some_and(|chi2| chi2 <= config.support_chi2) {
                support[k1] += 1;
                support[k2] += 1;
            }
        }
    }
    support
}

/// χ² of the cycle `F₁ ⋯ F_m` against the identity, each factor perturbed
/// on the right by noise of the given covariance: the product is
/// `(F₁⋯F_m) exp(δ)` with `δ = Σ_k Ad(S_k⁻¹) ε_k`, `S_k = F_{k+1}⋯F_m`.
/// `None` when the propagated covariance is singular.
fn cycle_chi2(factors: &[(Se2, Matrix3<f64>)]) -> Option<f64> {
    let mut after = Se2::identity();
    let mut covariance = Matrix3::<f64>::zeros();
    for (transform, c) in factors.iter().rev() {
        let ad = after.inverse().adjoint();
        covariance += ad * c * ad.transpose();
        after = transform.compose(&after);
    }
    let e = after.to_vector();
    let cholesky = covariance.cholesky()?;
    Some(e.dot(&cholesky.solve(&e)))
}

/// The innovation χ² of each edge of `candidates` against the least-squares
/// estimate of `graph` at its current poses (a minimum):
/// `eᵀ (Σ_edge + J H⁻¹ Jᵀ)⁻¹ e`, where `e` is the candidate's error, `J` its
/// Jacobian and `H` the information of `graph`'s poses (Gauss-Newton,
/// no kernels). It is the rise in the minimum χ² that adding the edge alone
/// would cause (to first order), so it judges the edge against what the
/// graph knows *and how well it knows it*, where the edge's own χ² judges
/// it against the point estimate only. Candidates whose covariance is not
/// defined get `f64::INFINITY`.
pub(crate) fn innovation_chi2(
    graph: &PoseGraph,
    candidates: &[echofield_graph::Edge],
    threads: usize,
) -> Result<Vec<f64>, SolveError> {
    let problem = Problem::new(graph)?;
    let n = problem.variables();
    let pairs = normalise(problem.block_pairs());
    let ordering = fill_reducing_ordering(n, &pairs).map_err(linear_error)?;
    let mut system = BlockSystem::<3>::new(n, &pairs, &ordering, threads).map_err(linear_error)?;
    let slots = edge_slots(&problem, &system);
    let kernels = vec![RobustKernel::None; problem.edges.len()];
    let poses = graph.poses();
    let mut gradient = vec![0.0; system.dim()];
    linearise(
        &problem,
        &kernels,
        &slots,
        &poses,
        &mut system,
        &mut gradient,
    );
    system
        .factorise(&vec![0.0; system.dim()])
        .map_err(linear_error)?;
    let mut column = vec![0.0; system.dim()];
    let mut out = Vec::with_capacity(candidates.len());
    for edge in candidates {
        let (Some(i), Some(j)) = (graph.index_of(edge.from), graph.index_of(edge.to)) else {
            out.push(f64::INFINITY);
            continue;
        };
        let Some(covariance) = edge.information.try_inverse() else {
            out.push(f64::INFINITY);
            continue;
        };
        let candidate = ProblemEdge {
            kind: edge.kind,
            from: i,
            to: j,
            measurement_inverse: edge.measurement.inverse(),
            measurement: edge.measurement,
            information: edge.information,
        };
        let (e, a, b) = error_and_jacobians(&candidate, &poses);
        // J H⁻¹ Jᵀ, one column of Jᵀ at a time.
        let blocks = [
            (problem.variable_of[i], a),
            (problem.variable_of[j].filter(|_| !candidate.is_prior()), b),
        ];
        let mut predicted = Matrix3::<f64>::zeros();
        for c in 0..3 {
            column.fill(0.0);
            for (v, jac) in &blocks {
                if let Some(v) = v {
                    for r in 0..3 {
                        column[3 * v + r] += jac[(c, r)];
                    }
                }
            }
            system.solve(&mut column);
            for (v, jac) in &blocks {
                if let Some(v) = v {
                    for r in 0..3 {
                        for k in 0..3 {
                            predicted[(r, c)] += jac[(r, k)] * column[3 * v + k];
                        }
                    }
                }
            }
        }
        let total = covariance + 0.5 * (predicted + predicted.transpose());
        out.push(match total.cholesky() {
            Some(ch) => e.dot(&ch.solve(&e)),
            None => f64::INFINITY,
        });
    }
    Ok(out)
}

/// Believed suspects (at least this many) calibrate the switch-off
/// threshold; fewer leave it as configured.
const MIN_CALIBRATION_EDGES: usize = 20;
/// The calibrated threshold is this multiple of the believed edges' 99th
/// percentile χ² ...
const CALIBRATION_FACTOR: f64 = 10.0;
/// ... and at least this (the mean of χ² with 3 degrees of freedom), so
/// that noise-free edges do not make every small error an outlier.
const CALIBRATION_FLOOR: f64 = 3.0;

/// The switch-off threshold for this graph: `configured`, or less when the
/// believed suspects (those with mutual support, solved without a kernel)
/// fit far better than their information says. Benchmark graphs often state
/// covariances a hundred times larger than their residuals (M3500, ring,
/// city10000); a χ² gate at the configured value then lets a false loop pass
/// that the graph can absorb by bending within its stated uncertainty. The
/// believed loops show the residual scale the graph's true loops really
/// have, so the gate is tightened to `CALIBRATION_FACTOR` times their 99th
/// percentile, never below `CALIBRATION_FLOOR` and never above
/// `configured`.
fn calibrated_threshold(configured: f64, believed_chi2: &[f64]) -> f64 {
    if believed_chi2.len() < MIN_CALIBRATION_EDGES {
        return configured;
    }
    let mut sorted = believed_chi2.to_vec();
    sorted.sort_by(f64::total_cmp);
    let p99 = sorted[((sorted.len() - 1) as f64 * 0.99).round() as usize];
    (CALIBRATION_FACTOR * p99).clamp(CALIBRATION_FLOOR.min(configured), configured)
}

/// The quantile of χ² with `dof` degrees of freedom that has the same
/// upper-tail probability as `chi2_3` has for χ² with 3 degrees of freedom,
/// by the Wilson-Hilferty approximation (`(χ²/k)^(1/3)` is nearly normal
/// with mean `1 − 2/(9k)` and variance `2/(9k)`; relative error well below
/// 1% from 3 degrees of freedom up).
fn same_tail_quantile(chi2_3: f64, dof: usize) -> f64 {
    let normal_score = |chi2: f64, k: f64| {
        let a = 2.0 / (9.0 * k);
        ((chi2 / k).cbrt() - (1.0 - a)) / a.sqrt()
    };
    let z = normal_score(chi2_3, 3.0);
    let k = dof.max(1) as f64;
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optimize;
    use echofield_graph::synthetic::{FalseLoops, Noise, add_false_loops, grid_pose_graph};

    fn loops_robust(kernel: RobustKernel) -> SolverConfig {
        SolverConfig {
            robust: RobustConfig::loops_only(kernel),
            ..SolverConfig::default()
        }
    }

    fn max_position_difference(a: &PoseGraph, b: &PoseGraph) -> f64 {
        a.poses()
            .iter()
            .zip(b.poses())
            .map(|(p, q)| (p.translation() - q.translation()).norm())
            .fold(0.0, f64::max)
    }

    /// Values from the χ² tables: 16.266 (3 dof), 59.703 (30), 149.449
    /// (100), all at 99.9%.
    #[test]
    fn tail_quantiles_match_the_tables() {
        let q3 = 16.266;
        for (dof, table) in [(3, 16.266), (30, 59.703), (100, 149.449)] {
            let q = same_tail_quantile(q3, dof);
            assert!((q - table).abs() < 0.01 * table, "{dof}: {q} vs {table}");
        }
    }

    #[test]
    fn calibration_tightens_only_with_enough_well_fitting_edges() {
        assert_eq!(calibrated_threshold(21.11, &[0.01; 5]), 21.11);
        assert_eq!(calibrated_threshold(21.11, &[0.01; 100]), CALIBRATION_FLOOR);
        assert_eq!(calibrated_threshold(21.11, &[5.0; 100]), 21.11);
        let mut chi2 = vec![0.1; 90];
        chi2.extend([1.0; 10]);
        let t = calibrated_threshold(21.11, &chi2);
        assert!((t - CALIBRATION_FACTOR * 1.0).abs() < 1e-12, "{t}");
    }

    /// On a graph without false loops nothing is switched off and the
    /// answer is the plain least-squares optimum.
    #[test]
    fn clean_graph_gives_the_plain_optimum() {
        let fixture = grid_pose_graph(400, Noise::new(0.05, 0.01), 3);
        let mut plain = fixture.graph.clone();
        optimize(&mut plain, &SolverConfig::default()).unwrap();
        let mut robust = fixture.graph.clone();
        let summary = optimize_robust(
            &mut robust,
            &loops_robust(RobustKernel::DCS_DEFAULT),
            &OutlierConfig::default(),
        )
        .unwrap();
        assert!(summary.suspect_edges > 100, "{}", summary.suspect_edges);
        assert!(
            summary.switched_off.is_empty(),
            "{:?}",
            summary.switched_off
        );
        assert!(!summary.hit_iteration_cap());
        let d = max_position_difference(&plain, &robust);
        assert!(d < 1e-6, "{d} m from the plain optimum");
    }

    /// Random false loops, more than the true ones, are all switched off,
    /// and the answer is the clean graph's optimum; the kernel alone from
    /// the odometry start is not (the reason this module exists).
    #[test]
    fn false_loops_are_switched_off() {
        let fixture = grid_pose_graph(400, Noise::new(0.05, 0.01), 5);
        let mut clean = fixture.graph.clone();
        optimize(&mut clean, &SolverConfig::default()).unwrap();
        let true_loops = fixture
            .graph
            .edges()
            .filter(|e| e.kind == EdgeKind::Loop)
            .count();
        let mut corrupted = fixture.graph.clone();
        let spec = FalseLoops {
            count: 2 * true_loops,
            max_translation_m: 5.0,
            seed: 11,
        };
        add_false_loops(&mut corrupted, spec).unwrap();
        let config = loops_robust(RobustKernel::DCS_DEFAULT);

        let mut robust = corrupted.clone();
        let summary = optimize_robust(&mut robust, &config, &OutlierConfig::default()).unwrap();
        let clean_edges = fixture.graph.edge_count();
        let false_off = summary
            .switched_off
            .iter()
            .filter(|s| s.edge >= clean_edges)
            .count();
        assert_eq!(false_off, spec.count);
        assert_eq!(
            summary.switched_off.len(),
            spec.count,
            "true loops switched off"
        );
        let d = max_position_difference(&clean, &robust);
        assert!(d < 1e-6, "{d} m from the clean optimum");

        let mut kernel_only = corrupted.clone();
        optimize(&mut kernel_only, &config).unwrap();
        assert!(max_position_difference(&clean, &kernel_only) > 100.0 * d.max(1e-6));
    }

    #[test]
    fn invalid_settings_name_the_field() {
        let bad = OutlierConfig {
            growth_step_nodes: 0,
            ..OutlierConfig::default()
        };
        let err = bad.validate().unwrap_err().to_string();
        assert!(err.contains("growth_step_nodes"), "{err}");
        let bad = OutlierConfig {
            switch_off_chi2: f64::NAN,
            ..OutlierConfig::default()
        };
        let err = bad.validate().unwrap_err().to_string();
        assert!(err.contains("switch_off_chi2"), "{err}");
    }
}
