//! Covariances of relative poses: first-order propagation through `⊕` and
//! `⊖`, floors and information matrices, and the relative uncertainty of
//! two nodes of a growing graph.
//!
//! **Relative uncertainty of two nodes.** The exact marginal covariance of
//! `j_from_k` needs the inverse of the graph's information matrix. The
//! pipeline needs it only to size search windows, so it takes the smaller
//! (by translational trace) of two cheap upper bounds:
//!
//! 1. the *most certain path* of the graph from `k` to `j` (a Dijkstra
//!    projection: edge covariances propagated through `⊕` along the path,
//!    the path chosen greedily by the propagated translational variance);
//!    parallel edges between two nodes (odometry and sequential match) are
//!    fused first (their information matrices add); after a loop closure
//!    the path through the loop edge makes revisits of the same place
//!    certain;
//! 2. dead reckoning between the two nodes at node level
//!    ([`DeadReckoningChain`](crate::loops::consistency::DeadReckoningChain)):
//!    the odometry edges' translational variances summed along the chain,
//!    the heading variance bounded by the two nodes' absolute ones (the
//!    compass does not let it accumulate), inflated by a model error the
//!    EKF does not know about: a standard deviation of `drift_fraction`
//!    times the distance travelled per axis, a heading standard deviation,
//!    and that heading error's lever arm over the distance between the
//!    nodes ([`DriftModel`]). O(1) per pair, where the EKF's own
//!    `Navigation::relative` costs a product over every filter step in
//!    between.

use crate::matcher::SearchWindow as Window;
use echofield_graph::Se2;
use nalgebra::{Matrix2, Matrix3};
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// `a ⊕ b` and its covariance for independent `a`, `b`.
pub fn compose(
    a: &Se2,
    cov_a: &Matrix3<f64>,
    b: &Se2,
    cov_b: &Matrix3<f64>,
) -> (Se2, Matrix3<f64>) {
    let (ab, ja, jb) = a.compose_with_jacobians(b);
    (
        ab,
        symmetric(ja * cov_a * ja.transpose() + jb * cov_b * jb.transpose()),
    )
}

/// `⊖ a` and its covariance.
pub fn invert(a: &Se2, cov: &Matrix3<f64>) -> (Se2, Matrix3<f64>) {
    let (inv, j) = a.inverse_with_jacobian();
    (inv, symmetric(j * cov * j.transpose()))
}

/// `(m + mᵀ) / 2`.
pub fn symmetric(m: Matrix3<f64>) -> Matrix3<f64> {
    (m + m.transpose()) * 0.5
}

/// `cov + diag(σ_x², σ_y², σ_θ²)` with the standard deviations of `min`:
/// every variance is at least the floor's, and a singular covariance
/// becomes positive definite.
pub fn with_floor(cov: &Matrix3<f64>, min: &Window) -> Matrix3<f64> {
    let mut out = symmetric(*cov);
    out[(0, 0)] += min.x_m * min.x_m;
    out[(1, 1)] += min.y_m * min.y_m;
    out[(2, 2)] += min.theta_rad * min.theta_rad;
    out
}

/// The inverse of a covariance, when it is finite and positive definite.
pub fn information(cov: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    if cov.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let chol = symmetric(*cov).cholesky()?;
    Some(symmetric(chol.inverse()))
}

/// Trace of the translational block, m².
pub fn translation_trace(cov: &Matrix3<f64>) -> f64 {
    cov[(0, 0)] + cov[(1, 1)]
}

/// `eᵀ Σ⁻¹ e` of the vector form of `pose` (its deviation from the
/// identity), `None` when `cov` is not positive definite.
pub fn mahalanobis2(pose: &Se2, cov: &Matrix3<f64>) -> Option<f64> {
    let e = pose.to_vector();
    let chol = symmetric(*cov).cholesky()?;
    Some(e.dot(&chol.solve(&e)))
}

/// Model error added to dead-reckoning motions (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriftModel {
    /// Standard deviation per axis per metre travelled.
    pub drift_fraction: f64,
    /// Heading standard deviation, rad.
    pub heading_sigma_rad: f64,
}

impl DriftModel {
    /// Inflates the covariance of a dead-reckoning motion `a_from_b` over
    /// `distance_m` of travel.
    pub fn inflate(&self, a_from_b: &Se2, cov: &Matrix3<f64>, distance_m: f64) -> Matrix3<f64> {
        let along = self.drift_fraction * distance_m;
        let lever = self.heading_sigma_rad * a_from_b.translation().norm();
        let mut out = *cov;
        let extra = Matrix2::identity() * (along * along + lever * lever);
        let mut block = out.fixed_view_mut::<2, 2>(0, 0);
        block += extra;
        out[(2, 2)] += self.heading_sigma_rad * self.heading_sigma_rad;
        out
    }
}

/// One direction of a link between two nodes: the covariance of
/// `this_from_other` (the fused measurements' covariance).
#[derive(Clone, Debug)]
struct Link {
    other: usize,
    covariance: Matrix3<f64>,
}

/// The link structure of the graph for relative-uncertainty queries.
#[derive(Clone, Debug, Default)]
pub struct LinkGraph {
    /// Fused information per unordered pair, kept to fuse further edges.
    links: Vec<Vec<Link>>,
}

impl LinkGraph {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn add_node(&mut self) {
        self.links.push(Vec::new());
    }

    pub fn len(&self) -> usize {
        self.links.len()
    }

    pub fn is_empty(&self) -> bool {
        self.links.is_empty()
    }

    /// Adds a measurement of `from_from_to` with covariance `cov`
    /// (`from_from_to` at the current estimate is used for the reverse
    /// direction's Jacobian). Parallel measurements are fused.
    pub fn add(&mut self, from: usize, to: usize, from_from_to: &Se2, cov: &Matrix3<f64>) {
        let (_, reverse) = invert(from_from_to, cov);
        fuse(&mut self.links[from], to, cov);
        fuse(&mut self.links[to], from, &reverse);
    }

    /// Removes every link between `a` and `b` (a loop edge that was
    /// accepted and later dropped). Links of other kinds between the two
    /// are not kept apart, so only loop pairs may be removed.
    pub fn remove(&mut self, a: usize, b: usize) {
        self.links[a].retain(|l| l.other != b);
        self.links[b].retain(|l| l.other != a);
    }

    /// The covariance of `source_from_j` for every node `j` reachable from
    /// `source` (`None` elsewhere), propagated along the most certain path
    /// with the poses `estimate` for the Jacobians.
    pub fn relative_from(&self, source: usize, estimate: &[Se2]) -> Vec<Option<Matrix3<f64>>> {
        self.search(source, estimate, None)
    }

    /// [`Self::relative_from`]`(source, estimate)[t]` for each `t` of
    /// `targets`, in their order (`None` for a node past the graph): the
    /// same search, stopped once every target's covariance is final (a
    /// node's is when it leaves the queue), so a query about a few nodes
    /// near `source` need not visit the whole graph.
    pub fn relative_to(
        &self,
        source: usize,
        estimate: &[Se2],
        targets: &[usize],
    ) -> Vec<Option<Matrix3<f64>>> {
        let best = self.search(source, estimate, Some(targets));
        targets
            .iter()
            .map(|&t| best.get(t).copied().flatten())
            .collect()
    }

    /// The search of [`Self::relative_from`]; with `targets`, stopped once
    /// all of them are done (the other entries are then partial).
    fn search(
        &self,
        source: usize,
        estimate: &[Se2],
        targets: Option<&[usize]>,
    ) -> Vec<Option<Matrix3<f64>>> {
        let n = self.links.len();
        let mut best: Vec<Option<Matrix3<f64>>> = vec![None; n];
        let mut done = vec![false; n];
        // Targets not done yet (all nodes: never reaches 0 before the end).
        let mut wanted = vec![targets.is_none(); n];
        let mut remaining = match targets {
            None => usize::MAX,
            Some(targets) => {
                let mut count = 0;
                for &t in targets.iter().filter(|&&t| t < n) {
                    count += usize::from(!wanted[t]);
                    wanted[t] = true;
                }
                count
            }
        };
        if remaining == 0 {
            return best;
        }
        let mut heap = BinaryHeap::new();
        best[source] = Some(Matrix3::zeros());
        heap.push(Entry {
            key: 0.0,
            node: source,
        });
        while let Some(Entry { node, .. }) = heap.pop() {
            if done[node] {
                continue;
            }
            done[node] = true;
            if wanted[node] && targets.is_some() {
                remaining -= 1;
                if remaining == 0 {
                    break;
                }
            }
            let cov_u = best[node].expect("set before pushing");
            let source_from_u = estimate[source].between(&estimate[node]);
            for link in &self.links[node] {
                if done[link.other] {
                    continue;
                }
                let u_from_v = estimate[node].between(&estimate[link.other]);
                let (_, cov_v) = compose(&source_from_u, &cov_u, &u_from_v, &link.covariance);
                let key = translation_trace(&cov_v);
                if best[link.other].is_none_or(|c| key < translation_trace(&c)) {
                    best[link.other] = Some(cov_v);
                    heap.push(Entry {
                        key,
                        node: link.other,
                    });
                }
            }
        }
        best
    }
}

fn fuse(links: &mut Vec<Link>, other: usize, cov: &Matrix3<f64>) {
    if let Some(link) = links.iter_mut().find(|l| l.other == other) {
        let fused = information(&link.covariance)
            .zip(information(cov))
            .and_then(|(a, b)| information(&(a + b)));
        if let Some(fused) = fused {
            link.covariance = fused;
        }
    } else {
        links.push(Link {
            other,
            covariance: *cov,
        });
    }
}

/// Min-heap entry by key, ties by node index (deterministic).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Entry {
    key: f64,
    node: usize,
}

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        other
            .key
            .total_cmp(&self.key)
            .then_with(|| other.node.cmp(&self.node))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn composition_of_straight_steps_grows_lateral_variance_with_heading() {
        // Two 1 m steps forward, each with 0.01 rad² heading variance only:
        // the second step's position inherits the first's heading error
        // over its 1 m lever arm: Var(y) = 0.01 exactly.
        let step = Se2::new(1.0, 0.0, 0.0);
        let cov = Matrix3::from_diagonal(&Vector3::new(0.0, 0.0, 0.01));
        let (pose, c) = compose(&step, &cov, &step, &cov);
        assert!((pose.x() - 2.0).abs() < 1e-12);
        assert!((c[(1, 1)] - 0.01).abs() < 1e-12);
        assert!((c[(2, 2)] - 0.02).abs() < 1e-12);
        assert!(c[(0, 0)].abs() < 1e-12);
    }

    #[test]
    fn a_loop_edge_shortens_the_uncertain_path() {
        // A chain 0-1-2-3-4 of 1 m steps with 0.01 m² per axis, and a loop
        // 0-4 with 0.0001 m²: from 4, node 0 is certain through the loop.
        let estimate: Vec<Se2> = (0..5).map(|i| Se2::new(i as f64, 0.0, 0.0)).collect();
        let step_cov = Matrix3::from_diagonal(&Vector3::new(0.01, 0.01, 1e-6));
        let mut g = LinkGraph::new();
        for _ in 0..5 {
            g.add_node();
        }
        for i in 0..4 {
            g.add(i, i + 1, &Se2::new(1.0, 0.0, 0.0), &step_cov);
        }
        let chain = g.relative_from(4, &estimate);
        let loop_cov = Matrix3::from_diagonal(&Vector3::new(1e-4, 1e-4, 1e-6));
        g.add(0, 4, &Se2::new(4.0, 0.0, 0.0), &loop_cov);
        let with_loop = g.relative_from(4, &estimate);
        let before = translation_trace(&chain[0].unwrap());
        let after = translation_trace(&with_loop[0].unwrap());
        assert!(before > 0.079, "{before}");
        // Inverting the 4 m loop edge moves its heading variance (1e-6)
        // into y over the 4 m lever: 1e-4 + 1e-4 + 16e-6.
        assert!((after - 2.16e-4).abs() < 1e-12, "{after}");
        // Node 2 is two steps from either end.
        assert!(translation_trace(&with_loop[2].unwrap()) < 0.041);
        // Asked for a few nodes, the search gives their covariances alone,
        // the same.
        let few = g.relative_to(4, &estimate, &[2, 0, 9, 2]);
        assert_eq!(few, [with_loop[2], with_loop[0], None, with_loop[2]]);
        assert_eq!(g.relative_to(4, &estimate, &[4]), [Some(Matrix3::zeros())]);
        assert!(g.relative_to(4, &estimate, &[]).is_empty());
        g.remove(0, 4);
        let removed = g.relative_from(4, &estimate);
        assert!((translation_trace(&removed[0].unwrap()) - before).abs() < 1e-12);
    }

    #[test]
    fn floor_and_information() {
        let floor = Window::new(0.1, 0.2, 0.01);
        let cov = with_floor(&Matrix3::zeros(), &floor);
        let info = information(&cov).unwrap();
        assert!((info[(0, 0)] - 100.0).abs() < 1e-9);
        assert!((info[(1, 1)] - 25.0).abs() < 1e-9);
        assert!(information(&Matrix3::zeros()).is_none());
        let e = mahalanobis2(&Se2::new(0.1, 0.0, 0.0), &cov).unwrap();
        assert!((e - 1.0).abs() < 1e-9);
    }
}
