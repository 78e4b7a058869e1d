//! Edge errors, their Jacobians, and the normal equations.
//!
//! Error of an edge `i -> j` with measurement `Z` (g2o's definition):
//! `e = vec(Z⁻¹ (X_i⁻¹ X_j))`, the vector form `(x, y, θ)` with θ wrapped
//! to (-π, π]; of a prior on `i`: `e = vec(Z⁻¹ X_i)`. χ² = Σ eᵀ Ω e.
//!
//! The unknowns are additive increments of each pose's vector form
//! `(x, y, θ)` (as g2o's `VertexSE2`), so the Jacobians are those of
//! [`Se2::between_with_jacobians`] chained with
//! [`Se2::compose_with_jacobians`] for the left factor `Z⁻¹`.

use crate::linear::{BlockSlot, BlockSystem};
use crate::problem::{Problem, ProblemEdge};
use crate::robust::RobustKernel;
use echofield_graph::{Edge, EdgeKind, PoseGraph, Se2};
use nalgebra::{Matrix3, Vector3};

/// The g2o error of `edge` when its endpoints are at `world_from_from` and
/// `world_from_to` (for a prior, `world_from_to` is ignored).
pub fn edge_error(edge: &Edge, world_from_from: &Se2, world_from_to: &Se2) -> Vector3<f64> {
    let z_inv = edge.measurement.inverse();
    let predicted = match edge.kind {
        EdgeKind::Prior => *world_from_from,
        _ => world_from_from.between(world_from_to),
    };
    z_inv.compose(&predicted).to_vector()
}

/// χ² = Σ eᵀΩe of a graph at its current poses, with the g2o error.
pub fn graph_chi2(graph: &PoseGraph) -> f64 {
    graph
        .indexed_edges()
        .map(|(i, j, edge)| {
            let e = edge_error(edge, &graph.node_at(i).pose, &graph.node_at(j).pose);
            e.dot(&(edge.information * e))
        })
        .sum()
}

/// Error and Jacobians `(e, ∂e/∂x_from, ∂e/∂x_to)` of one problem edge. For
/// a prior the second Jacobian is zero.
pub(crate) fn error_and_jacobians(
    edge: &ProblemEdge,
    poses: &[Se2],
) -> (Vector3<f64>, Matrix3<f64>, Matrix3<f64>) {
    let xi = &poses[edge.from];
    if edge.is_prior() {
        let (e, _, j) = edge.measurement_inverse.compose_with_jacobians(xi);
        return (e.to_vector(), j, Matrix3::zeros());
    }
    let (between, j_from, j_to) = xi.between_with_jacobians(&poses[edge.to]);
    let (e, _, j_z) = edge.measurement_inverse.compose_with_jacobians(&between);
    (e.to_vector(), j_z * j_from, j_z * j_to)
}

/// The error of one problem edge (no Jacobians).
pub(crate) fn error(edge: &ProblemEdge, poses: &[Se2]) -> Vector3<f64> {
    let xi = &poses[edge.from];
    let predicted = if edge.is_prior() {
        *xi
    } else {
        xi.between(&poses[edge.to])
    };
    edge.measurement_inverse.compose(&predicted).to_vector()
}

/// χ² and robust cost of a set of poses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Cost {
    pub chi2: f64,
    pub robust: f64,
}

impl Cost {
    pub fn is_finite(&self) -> bool {
        self.chi2.is_finite() && self.robust.is_finite()
    }
}

/// The cost of `poses` with one kernel per edge.
pub(crate) fn evaluate(problem: &Problem, kernels: &[RobustKernel], poses: &[Se2]) -> Cost {
    let mut cost = Cost {
        chi2: 0.0,
        robust: 0.0,
    };
    for (edge, kernel) in problem.edges.iter().zip(kernels) {
        let e = error(edge, poses);
        let s = e.dot(&(edge.information * e));
        cost.chi2 += s;
        cost.robust += kernel.evaluate(s).0;
    }
    cost
}

/// Where an edge's blocks go in the normal equations.
#[derive(Clone, Copy, Debug)]
pub(crate) struct EdgeSlots {
    from: Option<(usize, BlockSlot)>,
    to: Option<(usize, BlockSlot)>,
    /// Block (from, to).
    off: Option<BlockSlot>,
}

/// Block slots of every edge, in edge order.
pub(crate) fn edge_slots(problem: &Problem, system: &BlockSystem<3>) -> Vec<EdgeSlots> {
    let diag = |node: usize| {
        problem.variable_of[node].map(|v| (v, system.slot(v, v).expect("diagonal is stored")))
    };
    problem
        .edges
        .iter()
        .map(|e| {
            let from = diag(e.from);
            let to = if e.is_prior() { None } else { diag(e.to) };
            let off = match (from, to) {
                (Some((a, _)), Some((b, _))) => {
                    Some(system.slot(a, b).expect("edge blocks are in the pattern"))
                }
                _ => None,
            };
            EdgeSlots { from, to, off }
        })
        .collect()
}

/// Fills `system` with `H = Σ Jᵀ w Ω J` and `gradient` with `Σ Jᵀ w Ω e`
/// (`w` the robust weight of each edge) at `poses`, and returns the cost.
pub(crate) fn linearise(
    problem: &Problem,
    kernels: &[RobustKernel],
    slots: &[EdgeSlots],
    poses: &[Se2],
    system: &mut BlockSystem<3>,
    gradient: &mut [f64],
) -> Cost {
    system.clear();
    gradient.fill(0.0);
    let mut cost = Cost {
        chi2: 0.0,
        robust: 0.0,
    };
    for ((edge, kernel), slot) in problem.edges.iter().zip(kernels).zip(slots) {
        let (e, a, b) = error_and_jacobians(edge, poses);
        let s = e.dot(&(edge.information * e));
        let (rho, w) = kernel.evaluate(s);
        cost.chi2 += s;
        cost.robust += rho;
        let weighted = edge.information * w;
        let we = weighted * e;
        let wa = weighted * a;
        let wb = weighted * b;
        if let Some((v, diag)) = slot.from {
            system.add(diag, &(a.transpose() * wa));
            add_gradient(gradient, v, &(a.transpose() * we));
        }
        if let Some((v, diag)) = slot.to {
            system.add(diag, &(b.transpose() * wb));
            add_gradient(gradient, v, &(b.transpose() * we));
        }
        if let Some(off) = slot.off {
            system.add(off, &(a.transpose() * wb));
        }
    }
    cost
}

fn add_gradient(gradient: &mut [f64], variable: usize, g: &Vector3<f64>) {
    for k in 0..3 {
        gradient[3 * variable + k] += g[k];
    }
}

/// `poses` with the increment `delta` (3 per free pose) added to the vector
/// form of every free pose.
pub(crate) fn apply_step(problem: &Problem, poses: &[Se2], delta: &[f64], out: &mut [Se2]) {
    out.copy_from_slice(poses);
    for (v, &node) in problem.node_of_variable.iter().enumerate() {
        let p = &poses[node];
        let d = &delta[3 * v..3 * v + 3];
        out[node] = Se2::new(p.x() + d[0], p.y() + d[1], p.theta() + d[2]);
    }
}
