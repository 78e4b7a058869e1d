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
//! The consistency graph (one vertex per loop that passed its own checks,
//! neighbours as bit sets: what the clique search works on, so no graph
//! crate is used here) is searched for a **maximum clique**, the largest
//! set of pairwise consistent loops, with the exact Bron-Kerbosch algorithm
//! with Tomita pivoting and a size bound, on bit sets. Exponential in the
//! worst case; after `MAX_CLIQUE_CALLS` recursive calls the search stops
//! and the best clique found so far is used (a greedy answer; reported).
//! Ties go to the clique found first, with vertices visited in insertion
//! order, so the result is deterministic.

use crate::slam::uncertainty::{DriftModel, compose, invert, mahalanobis2};
use echofield_graph::Se2;
use nalgebra::Matrix3;
use std::collections::HashMap;

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

/// The consistency graph of the loops seen so far, and its maximum clique
/// as of the last search. Vertex `v` is the `v`-th loop added; its
/// neighbours are kept as a bit set, so the clique search never rebuilds
/// the graph.
#[derive(Clone, Debug, Default)]
pub struct ConsistencyGraph {
    measurements: Vec<LoopMeasurement>,
    /// Vertex of each record id.
    vertex_of: HashMap<usize, usize>,
    /// `adjacency[v]`: the vertices consistent with `v`.
    adjacency: Vec<BitSet>,
    /// Vertex indices of the last maximum clique.
    best: Vec<usize>,
    /// Vertices added since the last search.
    fresh: Vec<usize>,
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
        self.measurements.len()
    }

    pub fn is_empty(&self) -> bool {
        self.measurements.is_empty()
    }

    /// Adds a loop and its consistency edges to every loop already in.
    pub fn add(&mut self, loop_: LoopMeasurement, chain: &DeadReckoningChain, max_chi2: f64) {
        let consistent: Vec<usize> = self
            .measurements
            .iter()
            .enumerate()
            .filter(|(_, other)| cycle_chi2(&loop_, other, chain) <= max_chi2)
            .map(|(u, _)| u)
            .collect();
        self.push_vertex(loop_, &consistent);
    }

    /// Adds a vertex joined to `neighbours` (existing vertices).
    fn push_vertex(&mut self, loop_: LoopMeasurement, neighbours: &[usize]) {
        let v = self.measurements.len();
        let words = (v + 1).div_ceil(64);
        if words > v.div_ceil(64) {
            for row in &mut self.adjacency {
                row.0.resize(words, 0);
            }
        }
        let mut row = BitSet::empty(words);
        for &u in neighbours {
            row.insert(u);
            self.adjacency[u].insert(v);
        }
        self.adjacency.push(row);
        self.vertex_of.insert(loop_.id, v);
        self.measurements.push(loop_);
        self.fresh.push(v);
    }

    /// The measurement of a vertex by record id.
    pub fn measurement(&self, id: usize) -> Option<&LoopMeasurement> {
        self.vertex_of.get(&id).map(|&v| &self.measurements[v])
    }

    /// The maximum clique (see the module doc), updated incrementally.
    ///
    /// The graph only grows, so the previous maximum clique is still a
    /// clique, and a larger one must contain a vertex added since: the
    /// search starts from the previous clique as the best so far and only
    /// explores cliques through each new vertex (its neighbourhood), the
    /// new vertices in insertion order. The first search is over the whole
    /// graph. A clique of the same size as the previous one does not
    /// replace it.
    pub fn max_clique(&mut self) -> Clique {
        let n = self.measurements.len();
        let words = n.div_ceil(64);
        let adjacency = &self.adjacency;
        let mut search = CliqueSearch {
            adjacency,
            best: std::mem::take(&mut self.best),
            calls: 0,
        };
        let fresh = std::mem::take(&mut self.fresh);
        if search.best.is_empty() {
            let mut all = BitSet::empty(words);
            (0..n).for_each(|i| all.insert(i));
            search.expand(&mut Vec::new(), all, BitSet::empty(words));
        } else {
            // Cliques through an earlier new vertex were searched already:
            // exclude them from the later ones' searches.
            let mut excluded = BitSet::empty(words);
            for &v in &fresh {
                // No vertex is its own neighbour, so `v` is in neither set.
                let candidates = adjacency[v].difference(&excluded);
                let x = adjacency[v].intersection(&excluded);
                search.expand(&mut vec![v], candidates, x);
                excluded.insert(v);
            }
        }
        let exact = search.calls <= MAX_CLIQUE_CALLS;
        self.best = search.best;
        let mut ids: Vec<usize> = self.best.iter().map(|&v| self.measurements[v].id).collect();
        ids.sort_unstable();
        Clique { ids, exact }
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
            .max_by_key(|&u| (p.intersection_count(&self.adjacency[u]), usize::MAX - u))
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

    /// `|self ∩ other|` without building the intersection.
    fn intersection_count(&self, other: &BitSet) -> usize {
        self.0
            .iter()
            .zip(&other.0)
            .map(|(a, b)| (a & b).count_ones() as usize)
            .sum()
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

    fn measurement(id: usize) -> LoopMeasurement {
        LoopMeasurement {
            id,
            from: 0,
            to: 1,
            z: Se2::identity(),
            covariance: Matrix3::identity(),
        }
    }

    fn graph_with_edges(n: usize, edges: &[(usize, usize)]) -> ConsistencyGraph {
        let mut g = ConsistencyGraph::new();
        for v in 0..n {
            let neighbours: Vec<usize> = edges
                .iter()
                .filter_map(|&(a, b)| match (a, b) {
                    (a, b) if b == v && a < v => Some(a),
                    (a, b) if a == v && b < v => Some(b),
                    _ => None,
                })
                .collect();
            g.push_vertex(measurement(v), &neighbours);
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

    /// Every two of `ids` are joined by one of `edges`.
    fn assert_is_clique(ids: &[usize], edges: &[(usize, usize)]) {
        for (i, &a) in ids.iter().enumerate() {
            for &b in &ids[i + 1..] {
                assert!(
                    edges.contains(&(a, b)) || edges.contains(&(b, a)),
                    "{a} - {b}"
                );
            }
        }
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
            assert_is_clique(&found.ids, &edges);
        }
    }

    #[test]
    fn incremental_search_finds_the_maximum_as_the_graph_grows() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for trial in 0..40 {
            let n = rng.random_range(2..=12);
            let density = rng.random_range(0.2..0.9);
            let mut edges = Vec::new();
            let mut g = ConsistencyGraph::new();
            let mut previous = 0;
            // Vertices arrive in batches of 1-3, a search after each batch.
            let mut v = 0;
            while v < n {
                for _ in 0..rng.random_range(1..=3).min(n - v) {
                    let neighbours: Vec<usize> =
                        (0..v).filter(|_| rng.random_bool(density)).collect();
                    edges.extend(neighbours.iter().map(|&u| (u, v)));
                    g.push_vertex(measurement(v), &neighbours);
                    v += 1;
                }
                let found = g.max_clique();
                assert_eq!(
                    found.ids.len(),
                    brute_force(v, &edges),
                    "trial {trial}, {v} vertices"
                );
                assert!(found.ids.len() >= previous);
                previous = found.ids.len();
                assert_is_clique(&found.ids, &edges);
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
