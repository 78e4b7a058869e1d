//! The innovation χ² of an edge against a least-squares estimate: the test
//! by which [`super::optimize_robust`] switches edges back on.

use crate::error::SolveError;
use crate::linear::{BlockSystem, fill_reducing_ordering};
use crate::linearize::{edge_slots, error_and_jacobians, linearise};
use crate::problem::{Problem, ProblemEdge};
use crate::robust::RobustKernel;
use crate::solver::{linear_error, normalise};
use echofield_graph::PoseGraph;
use nalgebra::Matrix3;

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
        let blocks = [
            (problem.variable_of[i], a),
            (problem.variable_of[j].filter(|_| !candidate.is_prior()), b),
        ];
        let predicted = predicted_covariance(&mut system, &blocks, &mut column);
        let total = covariance + 0.5 * (predicted + predicted.transpose());
        out.push(match total.cholesky() {
            Some(ch) => e.dot(&ch.solve(&e)),
            None => f64::INFINITY,
        });
    }
    Ok(out)
}

/// `J H⁻¹ Jᵀ`, the covariance the factorised `system` (`H`) predicts for
/// an edge whose Jacobian has the 3×3 `blocks` at the given variables
/// (`None`: a fixed pose, no block), one column of `Jᵀ` at a time.
/// `column` is scratch space of the system's dimension.
fn predicted_covariance(
    system: &mut BlockSystem<3>,
    blocks: &[(Option<usize>, Matrix3<f64>); 2],
    column: &mut [f64],
) -> Matrix3<f64> {
    let mut predicted = Matrix3::<f64>::zeros();
    for c in 0..3 {
        column.fill(0.0);
        for (v, jac) in blocks {
            if let Some(v) = v {
                for r in 0..3 {
                    column[3 * v + r] += jac[(c, r)];
                }
            }
        }
        system.solve(column);
        for (v, jac) in blocks {
            if let Some(v) = v {
                for r in 0..3 {
                    for k in 0..3 {
                        predicted[(r, c)] += jac[(r, k)] * column[3 * v + k];
                    }
                }
            }
        }
    }
    predicted
}
