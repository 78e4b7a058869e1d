//! Mutual consistency of loop closures (pairwise consistency maximisation,
//! in the spirit of Mangelson et al., "Pairwise Consistent Measurement Set
//! Maximization for Robust Multi-robot Map Merging", ICRA 2018).
//!
//! Two loops `a = (j₁, k₁, z₁)` and `b = (j₂, k₂, z₂)` (`z = j_from_k`)
//! close a cycle with the dead-reckoning motions between their ends:
//!
//! `C = z₁ ⊕ D(k₁, k₂) ⊕ z₂⁻¹ ⊕ D(j₂, j₁)`,  `D(a, b) = a_from_b`,
//!
//! which is the identity when both are right. Its covariance is propagated
//! to first order from the loops' covariances and the dead-reckoning
//! motions' ([`DeadReckoningChain::relative`]); the loops are *consistent*
//! when `vec(C)ᵀ Σ⁻¹ vec(C)` is at most `consistency_max_chi2`.
//!
//! The consistency graph (a petgraph `UnGraph`, one vertex per loop that
//! passed its own checks) is searched for a **maximum clique**, the largest
//! set of pairwise consistent loops, with the exact Bron-Kerbosch algorithm
//! with Tomita pivoting and a size bound, on bit sets. Exponential in the
//! worst case; after `MAX_CLIQUE_CALLS` recursive calls the search stops
//! and the best clique found so far is used (a greedy answer; reported).
//! Ties go to the clique found first, with vertices visited in insertion
//! order, so the result is deterministic.

use crate::slam::uncertainty::{DriftModel, compose, invert, mahalanobis2};
use echofield_graph::Se2;
use nalgebra::Matrix3;
use petgraph::graph::{NodeIndex, UnGraph};

/// Limit on the recursive calls of one clique search.
pub const MAX_CLIQUE_CALLS: usize = 200_000;

/// Dead reckoning at the nodes, for the motions of the cycle test.
#[derive(Clone, Debug)]
pub struct DeadReckoningChain {
    /// `world_from_node` from dead reckoning.
    poses: Vec<Se2>,
    /// Distance travelled from node 0, metres.
    distance_m: Vec<f64>,
    /// Prefix sums of the per-axis translational variance of the odometry
    /// edges (m²), and of their heading variance (rad²).
    translation_var: Vec<f64>,
    heading_var: Vec<f64>,
    /// The EKF's absolute heading variance at each node, rad².
    absolute_heading_var: Vec<f64>,
    drift: DriftModel,
}

impl DeadReckoningChain {
    pub fn new(drift: DriftModel) -> Self {
        Self {
            poses: Vec::new(),
            distance_m: Vec::new(),
            translation_var: Vec::new(),
            heading_var: Vec::new(),
            absolute_heading_var: Vec::new(),
            drift,
        }
    }

    /// Appends a node: its dead-reckoning pose and absolute heading
    /// variance, and the covariance of the odometry edge from the previous
    /// node (ignored for the first).
    pub fn push(&mut self, pose: Se2, heading_var: f64, odometry_cov: &Matrix3<f64>) {
        let (d, t, h) = match self.poses.last() {
            None => (0.0, 0.0, 0.0),
            Some(prev) => (
                self.distance_m[self.poses.len() - 1]
                    + (pose.translation() - prev.translation()).norm(),
                self.translation_var[self.poses.len() - 1]
                    + 0.5 * (odometry_cov[(0, 0)] + odometry_cov[(1, 1)]),
                self.heading_var[self.poses.len() - 1] + odometry_cov[(2, 2)],
            ),
        };
        self.poses.push(pose);
        self.distance_m.push(d);
        self.translation_var.push(t);
        self.heading_var.push(h);
        self.absolute_heading_var.push(heading_var);
    }

    /// Distance travelled by dead reckoning from node 0 to node `i`, m.
    pub fn distance_at(&self, i: usize) -> f64 {
        self.distance_m[i]
    }

    /// `a_from_b` by dead reckoning and its covariance: isotropic
    /// translational variance (the odometry edges' between the nodes), the
    /// heading variance (the smaller of the chained one and the two nodes'
    /// absolute ones: a compass bounds it), and the drift model's
    /// inflation.
    pub fn relative(&self, a: usize, b: usize) -> (Se2, Matrix3<f64>) {
        let pose = self.poses[a].between(&self.poses[b]);
        if a == b {
            return (pose, Matrix3::zeros());
        }
        let (lo, hi) = (a.min(b), a.max(b));
        let t = self.translation_var[hi] - self.translation_var[lo];
        let chained = self.heading_var[hi] - self.heading_var[lo];
        let absolute = self.absolute_heading_var[lo] + self.absolute_heading_var[hi];
        let base = Matrix3::from_diagonal(&nalgebra::Vector3::new(t, t, chained.min(absolute)));
        let distance = self.distance_m[hi] - self.distance_m[lo];
        (pose, self.drift.inflate(&pose, &base, distance))
    }
}

/// A loop that passed its own checks: `z = from_from_to` with covariance.
#[derive(Clone, Debug)]
pub struct LoopMeasurement {
    /// The candidate's record index.
    pub id: usize,
    pub from: usize,
    pub to: usize,
    pub z: Se2,
    pub covariance: Matrix3<f64>,
}

/// The squared Mahalanobis distance of the cycle closed by two loops.
pub fn cycle_chi2(a: &LoopMeasurement, b: &LoopMeasurement, chain: &DeadReckoningChain) -> f64 {
    let (d_k, cov_dk) = chain.relative(a.to, b.to);
    let (d_j, cov_dj) = chain.relative(b.from, a.from);
    let (zb_inv, cov_zb_inv) = invert(&b.z, &b.covariance);
    let (c, cov) = compose(&a.z, &a.covariance, &d_k, &cov_dk);
    let (c, cov) = compose(&c, &cov, &zb_inv, &cov_zb_inv);
    let (c, cov) = compose(&c, &cov, &d_j, &cov_dj);
    mahalanobis2(&c, &cov).unwrap_or(f64::INFINITY)
}

/// The consistency graph of the loops seen so far.
#[derive(Clone, Debug, Default)]
pub struct ConsistencyGraph {
    graph: UnGraph<LoopMeasurement, f64>,
}

/// The result of a clique search.
#[derive(Clone, Debug, PartialEq)]
pub struct Clique {
    /// Record ids of the members, ascending.
    pub ids: Vec<usize>,
    /// False when the search hit `MAX_CLIQUE_CALLS` (the clique is then
    /// the largest found, not necessarily the maximum).
    pub exact: bool,
}

impl ConsistencyGraph {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn len(&self) -> usize {
        self.graph.node_count()
    }

    pub fn is_empty(&self) -> bool {
        self.graph.node_count() == 0
    }

    /// Adds a loop and its consistency edges to every loop already in.
    pub fn add(&mut self, loop_: LoopMeasurement, chain: &DeadReckoningChain, max_chi2: f64) {
        let others: Vec<(NodeIndex, f64)> = self
            .graph
            .node_indices()
            .map(|i| (i, cycle_chi2(&loop_, &self.graph[i], chain)))
            .collect();
        let index = self.graph.add_node(loop_);
        for (other, chi2) in others {
            if chi2 <= max_chi2 {
                self.graph.add_edge(index, other, chi2);
            }
        }
    }

    /// The measurement of a vertex by record id.
    pub fn measurement(&self, id: usize) -> Option<&LoopMeasurement> {
        self.graph.node_weights().find(|m| m.id == id)
    }

    /// The maximum clique (see the module doc).
    pub fn max_clique(&self) -> Clique {
        let n = self.graph.node_count();
        let words = n.div_ceil(64);
        let mut adjacency = vec![BitSet::empty(words); n];
        for edge in self.graph.raw_edges() {
            let (a, b) = (edge.source().index(), edge.target().index());
            adjacency[a].insert(b);
            adjacency[b].insert(a);
        }
        let mut search = CliqueSearch {
            adjacency: &adjacency,
            best: Vec::new(),
            calls: 0,
        };
        let mut all = BitSet::empty(words);
        (0..n).for_each(|i| all.insert(i));
        search.expand(&mut Vec::new(), all, BitSet::empty(words));
        let mut ids: Vec<usize> = search
            .best
            .iter()
            .map(|&i| self.graph[NodeIndex::new(i)].id)
            .collect();
        ids.sort_unstable();
        Clique {
            ids,
            exact: search.calls <= MAX_CLIQUE_CALLS,
        }
    }
}

struct CliqueSearch<'a> {
    adjacency: &'a [BitSet],
    best: Vec<usize>,
    calls: usize,
}

impl CliqueSearch<'_> {
    /// Bron-Kerbosch with Tomita pivoting; `r` the clique so far, `p` the
    /// candidates, `x` the excluded vertices.
    fn expand(&mut self, r: &mut Vec<usize>, mut p: BitSet, mut x: BitSet) {
        self.calls += 1;
        if self.calls > MAX_CLIQUE_CALLS {
            return;
        }
        if p.is_empty() {
            if x.is_empty() && r.len() > self.best.len() {
                self.best = r.clone();
            }
            return;
        }
        // Bound: even taking every candidate cannot beat the best.
        if r.len() + p.count() <= self.best.len() {
            return;
        }
        let pivot = p
            .union(&x)
            .iter()
            .max_by_key(|&u| (p.intersection(&self.adjacency[u]).count(), usize::MAX - u))
            .expect("p is not empty");
        let branch: Vec<usize> = p.difference(&self.adjacency[pivot]).iter().collect();
        for v in branch {
            r.push(v);
            self.expand(
                r,
                p.intersection(&self.adjacency[v]),
                x.intersection(&self.adjacency[v]),
            );
            r.pop();
            p.remove(v);
            x.insert(v);
        }
    }
}

/// A fixed-size bit set over `0..64·words`.
#[derive(Clone, Debug, PartialEq)]
struct BitSet(Vec<u64>);

impl BitSet {
    fn empty(words: usize) -> Self {
        BitSet(vec![0; words])
    }

    fn insert(&mut self, i: usize) {
        self.0[i / 64] |= 1 << (i % 64);
    }

    fn remove(&mut self, i: usize) {
        self.0[i / 64] &= !(1 << (i % 64));
    }

    fn is_empty(&self) -> bool {
        self.0.iter().all(|w| *w == 0)
    }

    fn count(&self) -> usize {
        self.0.iter().map(|w| w.count_ones() as usize).sum()
    }

    fn zip(&self, other: &BitSet, f: impl Fn(u64, u64) -> u64) -> BitSet {
        BitSet(
            self.0
                .iter()
                .zip(&other.0)
                .map(|(a, b)| f(*a, *b))
                .collect(),
        )
    }

    fn union(&self, other: &BitSet) -> BitSet {
        self.zip(other, |a, b| a | b)
    }

    fn intersection(&self, other: &BitSet) -> BitSet {
        self.zip(other, |a, b| a & b)
    }

    fn difference(&self, other: &BitSet) -> BitSet {
        self.zip(other, |a, b| a & !b)
    }

    /// Members in increasing order.
    fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        self.0.iter().enumerate().flat_map(|(w, &word)| {
            let mut bits = word;
            std::iter::from_fn(move || {
                if bits == 0 {
                    return None;
                }
                let b = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                Some(w * 64 + b)
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn graph_with_edges(n: usize, edges: &[(usize, usize)]) -> ConsistencyGraph {
        let mut g = ConsistencyGraph::new();
        for id in 0..n {
            g.graph.add_node(LoopMeasurement {
                id,
                from: 0,
                to: 1,
                z: Se2::identity(),
                covariance: Matrix3::identity(),
            });
        }
        for &(a, b) in edges {
            g.graph.add_edge(NodeIndex::new(a), NodeIndex::new(b), 0.0);
        }
        g
    }

    /// The maximum clique size by trying every subset (n ≤ 12).
    fn brute_force(n: usize, edges: &[(usize, usize)]) -> usize {
        let adjacent = |a: usize, b: usize| edges.contains(&(a, b)) || edges.contains(&(b, a));
        (0u32..1 << n)
            .filter(|mask| {
                let members: Vec<usize> = (0..n).filter(|i| mask & (1 << i) != 0).collect();
                members
                    .iter()
                    .enumerate()
                    .all(|(i, &a)| members[i + 1..].iter().all(|&b| adjacent(a, b)))
            })
            .map(|mask| mask.count_ones() as usize)
            .max()
            .unwrap_or(0)
    }

    #[test]
    fn finds_the_planted_clique() {
        // A 5-clique {1, 3, 4, 7, 8} among a triangle and a path.
        let mut edges = vec![(0, 2), (2, 5), (0, 5), (5, 6), (6, 9)];
        let clique = [1, 3, 4, 7, 8];
        for (i, &a) in clique.iter().enumerate() {
            for &b in &clique[i + 1..] {
                edges.push((a, b));
            }
        }
        let found = graph_with_edges(10, &edges).max_clique();
        assert_eq!(found.ids, vec![1, 3, 4, 7, 8]);
        assert!(found.exact);
    }

    #[test]
    fn matches_brute_force_on_random_graphs() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for trial in 0..60 {
            let n = rng.random_range(1..=12);
            let density = rng.random_range(0.1..0.9);
            let mut edges = Vec::new();
            for a in 0..n {
                for b in a + 1..n {
                    if rng.random_bool(density) {
                        edges.push((a, b));
                    }
                }
            }
            let found = graph_with_edges(n, &edges).max_clique();
            assert_eq!(found.ids.len(), brute_force(n, &edges), "trial {trial}");
            // And it is a clique.
            for (i, &a) in found.ids.iter().enumerate() {
                for &b in &found.ids[i + 1..] {
                    assert!(edges.contains(&(a, b)) || edges.contains(&(b, a)));
                }
            }
        }
    }

    #[test]
    fn cycle_test_accepts_agreeing_loops_and_rejects_an_offset_one() {
        // Dead reckoning: a straight line, 1 m per node, 0.01 m² per edge.
        let mut chain = DeadReckoningChain::new(DriftModel {
            drift_fraction: 0.0,
            heading_sigma_rad: 0.0,
        });
        let odo = Matrix3::from_diagonal(&nalgebra::Vector3::new(1e-4, 1e-4, 1e-6));
        for i in 0..30 {
            chain.push(Se2::new(i as f64, 0.0, 0.0), 1e-6, &odo);
        }
        let cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(0.01, 0.01, 1e-4));
        // Loops j -> k whose z agrees with dead reckoning.
        let make = |id, from: usize, to: usize, dx: f64| LoopMeasurement {
            id,
            from,
            to,
            z: Se2::new((to - from) as f64 + dx, 0.0, 0.0),
            covariance: cov,
        };
        let a = make(0, 2, 20, 0.0);
        let b = make(1, 3, 21, 0.05);
        let c = make(2, 4, 22, 2.0);
        assert!(cycle_chi2(&a, &b, &chain) < 1.0);
        assert!(cycle_chi2(&a, &c, &chain) > 50.0);
        let mut g = ConsistencyGraph::new();
        for m in [a, b, c] {
            g.add(m, &chain, 11.34);
        }
        assert_eq!(g.max_clique().ids, vec![0, 1]);
    }
}
