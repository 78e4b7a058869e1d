//! Mutual support of suspect edges: step 1 of [`super::optimize_robust`].

use super::OutlierConfig;
use echofield_graph::{EdgeKind, PoseGraph, Se2};
use nalgebra::Matrix3;

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
pub(super) fn mutual_support(
    graph: &PoseGraph,
    trusted: &[Se2],
    suspect: &[bool],
    config: &OutlierConfig,
) -> Vec<usize> {
    let (mut loops, chain) = loops_and_chain(graph, trusted, suspect);
    loops.sort_by_key(|l| (l.low, l.high));
    let w = config.support_window_nodes;
    let mut support = vec![0usize; graph.edge_count()];
    let mut factors = Vec::new();
    for (rank, first) in loops.iter().enumerate() {
        for second in &loops[rank + 1..] {
            if second.low > first.low + w {
                break;
            }
            if first.high.abs_diff(second.high) > w {
                continue;
            }
            if chain
                .cycle_chi2(first, second, &mut factors)
                .is_some_and(|chi2| chi2 <= config.support_chi2)
            {
                support[first.edge] += 1;
                support[second.edge] += 1;
            }
        }
    }
    support
}

/// A suspect edge oriented from its lower to its higher node index.
#[derive(Clone, Copy)]
struct Loop {
    low: usize,
    high: usize,
    /// The measurement `low_from_high` and its covariance (in the error
    /// coordinates of `low -> high`).
    low_from_high: Se2,
    covariance: Matrix3<f64>,
    /// Index of the edge in the graph's edge order.
    edge: usize,
}

/// The trusted chain: the start poses from the trusted edges and the
/// covariance of each step `k -> k+1` (`None` without a trusted edge
/// between the two nodes).
struct Chain<'a> {
    trusted: &'a [Se2],
    step_covariance: Vec<Option<Matrix3<f64>>>,
}

/// The suspect edges (skipping priors, self-loops and edges without a
/// covariance) and the trusted chain: the summed information of the trusted
/// edges between consecutive nodes, inverted.
fn loops_and_chain<'a>(
    graph: &PoseGraph,
    trusted: &'a [Se2],
    suspect: &[bool],
) -> (Vec<Loop>, Chain<'a>) {
    let n = graph.node_count();
    let mut step_information = vec![Matrix3::<f64>::zeros(); n.saturating_sub(1)];
    let mut has_step = vec![false; n.saturating_sub(1)];
    let mut loops = Vec::new();
    for (k, (i, j, edge)) in graph.indexed_edges().enumerate() {
        if edge.kind == EdgeKind::Prior || i == j {
            continue;
        }
        let Some(covariance) = edge.information.try_inverse() else {
            continue;
        };
        // X_j⁻¹X_i = exp(−e) Z⁻¹ = Z⁻¹ exp(−Ad(Z) e): the covariance of an
        // edge read backwards.
        let ad = edge.measurement.adjoint();
        let reversed_covariance = ad * covariance * ad.transpose();
        if suspect[k] {
            let (low, high, low_from_high, covariance) = if i < j {
                (i, j, edge.measurement, covariance)
            } else {
                (j, i, edge.measurement.inverse(), reversed_covariance)
            };
            loops.push(Loop {
                low,
                high,
                low_from_high,
                covariance,
                edge: k,
            });
        } else if i.abs_diff(j) == 1 {
            // Information is in the error coordinates of i -> j; for a
            // step stored as j -> i use the inverse's (as above).
            let information = if i < j {
                edge.information
            } else {
                match reversed_covariance.try_inverse() {
                    Some(info) => info,
                    None => continue,
                }
            };
            step_information[i.min(j)] += information;
            has_step[i.min(j)] = true;
        }
    }
    let step_covariance = step_information
        .iter()
        .zip(&has_step)
        .map(|(info, has)| if *has { info.try_inverse() } else { None })
        .collect();
    let chain = Chain {
        trusted,
        step_covariance,
    };
    (loops, chain)
}

impl Chain<'_> {
    /// The trusted relative pose of step `k -> k+1`.
    fn step(&self, k: usize) -> Se2 {
        self.trusted[k].between(&self.trusted[k + 1])
    }

    /// Appends the chain from node `u` to node `v` as factors (transform,
    /// covariance); false when a step on the way has no trusted edge.
    fn append(&self, u: usize, v: usize, factors: &mut Vec<(Se2, Matrix3<f64>)>) -> bool {
        if u <= v {
            for k in u..v {
                let Some(c) = self.step_covariance[k] else {
                    return false;
                };
                factors.push((self.step(k), c));
            }
        } else {
            for k in (v..u).rev() {
                let Some(c) = self.step_covariance[k] else {
                    return false;
                };
                let d = self.step(k);
                let ad = d.adjoint();
                factors.push((d.inverse(), ad * c * ad.transpose()));
            }
        }
        true
    }

    /// χ² of the cycle `Z₁ · P(b→d) · Z₂⁻¹ · P(c→a)` closed by the loops
    /// `a -> b` (`first`) and `c -> d` (`second`) with the chain; `None`
    /// when a chain step has no trusted edge or the propagated covariance
    /// is singular. `factors` is scratch space.
    fn cycle_chi2(
        &self,
        first: &Loop,
        second: &Loop,
        factors: &mut Vec<(Se2, Matrix3<f64>)>,
    ) -> Option<f64> {
        factors.clear();
        factors.push((first.low_from_high, first.covariance));
        if !self.append(first.high, second.high, factors) {
            return None;
        }
        let ad2 = second.low_from_high.adjoint();
        factors.push((
            second.low_from_high.inverse(),
            ad2 * second.covariance * ad2.transpose(),
        ));
        if !self.append(second.low, first.low, factors) {
            return None;
        }
        cycle_chi2(factors)
    }
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
