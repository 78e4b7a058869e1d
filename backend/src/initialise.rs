//! Chordal initialisation: orientations first, then positions, each by one
//! sparse linear least-squares solve.
//!
//! 1. Orientations. Each free pose's heading is represented by an
//!    unconstrained vector `r_i ∈ R²` (standing for `(cos θ_i, sin θ_i)`).
//!    An edge `i -> j` with measured rotation `θ_z` asks for
//!    `r_j = R(θ_z) r_i`, a prior for `r_i = (cos θ_z, sin θ_z)`, each
//!    weighted by the information of the angle. The relaxation is linear, so
//!    no angle wrap-around has to be resolved, and the solution is
//!    projected back with `θ_i = atan2(r_i)`. (Chordal relaxation of
//!    rotation averaging, Carlone, Tron, Daniilidis, Dellaert, ICRA 2015,
//!    written for SO(2).)
//! 2. Positions given the orientations: `t_j − t_i = R_i t_z` (a prior:
//!    `t_i = t_z`), weighted by the translational information rotated into
//!    the world frame; again linear.
//!
//! Both problems have one 2x2 block per pose and the sparsity of the pose
//! graph, so they share one symbolic factorisation (and the fill-reducing
//! ordering of the main 3x3 system).

use crate::error::SolveError;
use crate::linear::{BlockSystem, LinearError};
use crate::problem::{Problem, ProblemEdge};
use echofield_graph::Se2;
use nalgebra::{Matrix2, Vector2};

/// The sparsity of the initialisation problem: the block pairs of the edges
/// it uses.
pub(crate) fn init_pairs(problem: &Problem, used: &[bool]) -> Vec<(usize, usize)> {
    problem
        .edges
        .iter()
        .zip(used)
        .filter(|(e, u)| **u && !e.is_prior())
        .filter_map(|(e, _)| Some((problem.variable_of[e.from]?, problem.variable_of[e.to]?)))
        .filter(|(a, b)| a != b)
        .collect()
}

/// Replaces the free poses of `poses` by the chordal initialisation built
/// from the edges flagged in `used`. Fixed poses keep their values.
pub(crate) fn chordal(
    problem: &Problem,
    used: &[bool],
    system: &mut BlockSystem<2>,
    poses: &mut [Se2],
) -> Result<(), SolveError> {
    let mut rhs = vec![0.0; 2 * problem.variables()];
    orientations(problem, used, system, poses, &mut rhs)?;
    for (v, &node) in problem.node_of_variable.iter().enumerate() {
        let theta = rhs[2 * v + 1].atan2(rhs[2 * v]);
        poses[node] = Se2::new(poses[node].x(), poses[node].y(), theta);
    }
    positions(problem, used, system, poses, &mut rhs)?;
    for (v, &node) in problem.node_of_variable.iter().enumerate() {
        poses[node] = Se2::new(rhs[2 * v], rhs[2 * v + 1], poses[node].theta());
    }
    Ok(())
}

/// Step 1: the relaxed heading vectors `r_i`, left in `rhs`.
fn orientations(
    problem: &Problem,
    used: &[bool],
    system: &mut BlockSystem<2>,
    poses: &[Se2],
    rhs: &mut [f64],
) -> Result<(), SolveError> {
    system.clear();
    rhs.fill(0.0);
    let heading = |p: &Se2| Vector2::new(p.theta().cos(), p.theta().sin());
    for edge in used_edges(problem, used) {
        let kappa = Matrix2::identity() * edge.information[(2, 2)];
        let z = heading(&edge.measurement);
        let term = if edge.is_prior() {
            Term::unary(edge.from, Matrix2::identity(), -z)
        } else {
            let rot_z = Matrix2::new(z.x, -z.y, z.y, z.x);
            Term::binary(
                edge.from,
                -rot_z,
                edge.to,
                Matrix2::identity(),
                Vector2::zeros(),
            )
        };
        term.add(problem, values_of(poses, heading), &kappa, system, rhs);
    }
    solve(problem, system, rhs)
}

/// Step 2: the positions `t_i` given the headings in `poses`, left in `rhs`.
fn positions(
    problem: &Problem,
    used: &[bool],
    system: &mut BlockSystem<2>,
    poses: &[Se2],
    rhs: &mut [f64],
) -> Result<(), SolveError> {
    system.clear();
    rhs.fill(0.0);
    let position = |p: &Se2| p.translation();
    let identity = Matrix2::identity();
    for edge in used_edges(problem, used) {
        let info_t = edge.information.fixed_view::<2, 2>(0, 0).into_owned();
        let z_t = edge.measurement.translation();
        // The translation error is expressed in the frame `q` (the measured
        // frame of the edge's target); rotate its information to the world.
        let (term, q) = if edge.is_prior() {
            let q = edge.measurement.rotation_matrix();
            (Term::unary(edge.from, identity, -z_t), q)
        } else {
            let r_i = poses[edge.from].rotation_matrix();
            let q = r_i * edge.measurement.rotation_matrix();
            let term = Term::binary(edge.from, -identity, edge.to, identity, -(r_i * z_t));
            (term, q)
        };
        let weight = q * info_t * q.transpose();
        term.add(problem, values_of(poses, position), &weight, system, rhs);
    }
    solve(problem, system, rhs)
}

fn used_edges<'a>(problem: &'a Problem, used: &'a [bool]) -> impl Iterator<Item = &'a ProblemEdge> {
    problem
        .edges
        .iter()
        .zip(used)
        .filter(|(_, u)| **u)
        .map(|(e, _)| e)
}

/// The current value, in the unknowns of one sub-problem, of every pose
/// (used for the fixed ones).
fn values_of<'a>(
    poses: &'a [Se2],
    f: impl Fn(&Se2) -> Vector2<f64> + 'a,
) -> impl Fn(usize) -> Vector2<f64> + 'a {
    move |node| f(&poses[node])
}

/// A residual `A x_i + B x_j + c` in the 2-vectors of nodes `i` (and `j`).
struct Term {
    first: (usize, Matrix2<f64>),
    second: Option<(usize, Matrix2<f64>)>,
    constant: Vector2<f64>,
}

impl Term {
    fn unary(node: usize, a: Matrix2<f64>, constant: Vector2<f64>) -> Self {
        Self {
            first: (node, a),
            second: None,
            constant,
        }
    }

    fn binary(
        i: usize,
        a: Matrix2<f64>,
        j: usize,
        b: Matrix2<f64>,
        constant: Vector2<f64>,
    ) -> Self {
        Self {
            first: (i, a),
            second: Some((j, b)),
            constant,
        }
    }

    /// Adds `JᵀWJ` to the system and `−JᵀWc` to the right-hand side, with the
    /// contributions of fixed nodes (values from `known`) moved into `c`.
    fn add(
        &self,
        problem: &Problem,
        known: impl Fn(usize) -> Vector2<f64>,
        weight: &Matrix2<f64>,
        system: &mut BlockSystem<2>,
        rhs: &mut [f64],
    ) {
        let mut c = self.constant;
        // At most two free nodes: a fixed-size list, no allocation per edge.
        let mut slots = [(0, Matrix2::zeros()); 2];
        let mut count = 0;
        for (node, m) in std::iter::once(self.first).chain(self.second) {
            match problem.variable_of[node] {
                Some(v) => {
                    slots[count] = (v, m);
                    count += 1;
                }
                None => c += m * known(node),
            }
        }
        let free = &slots[..count];
        let wc = weight * c;
        for &(v, m) in free {
            let g = m.transpose() * wc;
            rhs[2 * v] -= g.x;
            rhs[2 * v + 1] -= g.y;
            let slot = system.slot(v, v).expect("diagonal is stored");
            system.add(slot, &(m.transpose() * weight * m));
        }
        if let [(va, ma), (vb, mb)] = *free {
            let slot = system.slot(va, vb).expect("edge blocks are in the pattern");
            system.add(slot, &(ma.transpose() * weight * mb));
        }
    }
}

fn solve(
    problem: &Problem,
    system: &mut BlockSystem<2>,
    rhs: &mut [f64],
) -> Result<(), SolveError> {
    let damping = vec![0.0; system.dim()];
    system.factorise(&damping).map_err(|e| match e {
        LinearError::NotPositiveDefinite { block } => SolveError::SystemNotPositiveDefinite {
            node: problem.node_ids[problem.node_of_variable[block]],
        },
        other => SolveError::Linear(other.to_string()),
    })?;
    system.solve(rhs);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linear::fill_reducing_ordering;
    use echofield_graph::synthetic::{Noise, circle_pose_graph, grid_pose_graph};
    use echofield_graph::{Edge, EdgeKind, PoseGraph, wrap_angle};

    /// Without noise the relaxation is exact: the chordal start alone is the
    /// ground truth, headings wrapping through ±π included (the circle turns
    /// three times).
    #[test]
    fn noise_free_graphs_are_recovered_without_iterating() {
        let noise = Noise::new(1e-9, 1e-9);
        for fixture in [
            circle_pose_graph(90, 3, noise, 1),
            grid_pose_graph(200, noise, 2),
        ] {
            let graph = reverse_every_other_edge(&fixture.graph);
            let problem = Problem::new(&graph).unwrap();
            let used = vec![true; problem.edges.len()];
            let pairs = init_pairs(&problem, &used);
            let ordering = fill_reducing_ordering(problem.variables(), &pairs).unwrap();
            let mut system =
                BlockSystem::<2>::new(problem.variables(), &pairs, &ordering, 1).unwrap();
            // Start far from the truth: all free poses at the origin.
            let mut poses = graph.poses();
            for &node in &problem.node_of_variable {
                poses[node] = Se2::identity();
            }
            chordal(&problem, &used, &mut system, &mut poses).unwrap();
            for (p, t) in poses.iter().zip(&fixture.ground_truth) {
                assert!((p.translation() - t.translation()).norm() < 1e-6);
                assert!(wrap_angle(p.theta() - t.theta()).abs() < 1e-7);
            }
        }
    }

    /// The same graph with every other edge stored in the opposite
    /// direction (`j -> i` with the inverse measurement), so that both
    /// orientations of off-diagonal blocks are exercised.
    fn reverse_every_other_edge(graph: &PoseGraph) -> PoseGraph {
        let mut out = PoseGraph::new();
        for node in graph.nodes() {
            out.add_node(node.clone()).unwrap();
        }
        for (k, edge) in graph.edges().enumerate() {
            let mut edge = edge.clone();
            if k % 2 == 1 && edge.kind != EdgeKind::Prior {
                edge = Edge::new(
                    edge.kind,
                    edge.to,
                    edge.from,
                    edge.measurement.inverse(),
                    edge.information,
                );
            }
            out.add_edge(edge).unwrap();
        }
        out
    }
}
