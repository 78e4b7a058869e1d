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
//! The loops are then searched for a **maximum clique** of the consistency
//! graph (one vertex per loop that passed its own checks), the largest set
//! of pairwise consistent loops. Conflicts are the exception, so the graph
//! keeps them instead (no graph crate: the search works on plain lists and
//! bit sets), and the clique is computed as the complement of a
//! **minimum vertex cover of the conflict graph**, exactly, per connected
//! component, by branch and bound (degree-0 and degree-1 reductions, a
//! matching lower bound, branching on the vertex of most conflicts). Loops
//! in no conflict never enter the search, so its cost follows the
//! conflicts, not the loops: with a thousand loops and a few hundred
//! conflicts it is milliseconds (Bron-Kerbosch on the near-complete
//! consistency graph, which this replaced, did not finish such searches).
//! Exponential in the worst case: after `MAX_CLIQUE_WORK` (bit-set words
//! visited, over all components) the search stops and keeps the best
//! cover found (reported). Ties keep the previous clique, then go to the
//! cover found first with vertices taken in insertion order, so the result
//! is deterministic.

use crate::uncertainty::{DriftModel, compose, invert, mahalanobis2};
use echofield_graph::Se2;
use nalgebra::Matrix3;
use std::collections::HashMap;

/// Limit on the work of one clique search over all its components, in
/// bit-set words visited (each call of the cover search visits its alive
/// vertices' rows once or a few times). Real missions' searches stay far
/// below it; on random graphs of mostly wrong loops it stops a search within a
/// fraction of a second in release builds (EXPERIMENTS.md § Speed notes).
pub const MAX_CLIQUE_WORK: usize = 100_000_000;

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

    /// Distance travelled by dead reckoning from node 0 to each node, m
    /// (non-decreasing).
    pub fn distances(&self) -> &[f64] {
        &self.distance_m
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
/// as of the last search. Vertex `v` is the `v`-th loop added. Consistent
/// loops are the rule and conflicts the exception, so the graph keeps the
/// *conflicts* (the complement's edges) as lists: a maximum clique of the
/// consistency graph is the complement of a minimum vertex cover of the
/// conflict graph, and that cover only concerns the few loops that
/// conflict with anything.
#[derive(Clone, Debug, Default)]
pub struct ConsistencyGraph {
    measurements: Vec<LoopMeasurement>,
    /// Vertex of each record id.
    vertex_of: HashMap<usize, usize>,
    /// `conflicts[v]`: the vertices inconsistent with `v`, ascending.
    conflicts: Vec<Vec<usize>>,
    /// `in_cover[v]`: `v` was left out of the last maximum clique.
    in_cover: Vec<bool>,
}

/// The result of a clique search.
#[derive(Clone, Debug, PartialEq)]
pub struct Clique {
    /// Record ids of the members, ascending.
    pub ids: Vec<usize>,
    /// False when the cover search ran past `MAX_CLIQUE_WORK` (the
    /// clique is then the largest found, not necessarily the maximum).
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

    /// Adds a vertex joined to `neighbours` (existing vertices, ascending)
    /// and in conflict with every other one.
    fn push_vertex(&mut self, loop_: LoopMeasurement, neighbours: &[usize]) {
        let v = self.measurements.len();
        let mut next = neighbours.iter().copied().peekable();
        let mut conflicts = Vec::new();
        for u in 0..v {
            if next.next_if_eq(&u).is_none() {
                conflicts.push(u);
                self.conflicts[u].push(v);
            }
        }
        self.conflicts.push(conflicts);
        self.in_cover.push(false);
        self.vertex_of.insert(loop_.id, v);
        self.measurements.push(loop_);
    }

    /// The measurement of a vertex by record id.
    pub fn measurement(&self, id: usize) -> Option<&LoopMeasurement> {
        self.vertex_of.get(&id).map(|&v| &self.measurements[v])
    }

    /// The maximum clique (see the struct doc): every loop minus a minimum
    /// vertex cover of the conflict graph, found exactly per connected
    /// component by branch and bound (`MinCover`). The previous cover,
    /// completed with the new vertices where it leaves a conflict
    /// uncovered, is each component's first incumbent, and only a strictly
    /// smaller cover replaces it: a clique of the same size as the
    /// previous one does not replace it.
    pub fn max_clique(&mut self) -> Clique {
        self.max_clique_within(MAX_CLIQUE_WORK)
    }

    /// [`Self::max_clique`] with a work limit of `budget`.
    fn max_clique_within(&mut self, budget: usize) -> Clique {
        let n = self.measurements.len();
        let mut work = 0;
        let mut seen = vec![false; n];
        for root in 0..n {
            if seen[root] || self.conflicts[root].is_empty() {
                continue;
            }
            let component = self.component_of(root, &mut seen);
            work = self.cover_component(&component, work, budget);
        }
        let exact = work <= budget;
        let mut ids: Vec<usize> = (0..n)
            .filter(|&v| !self.in_cover[v])
            .map(|v| self.measurements[v].id)
            .collect();
        ids.sort_unstable();
        Clique { ids, exact }
    }

    /// The members of the last maximum clique ([`Self::max_clique`] ran
    /// since the last [`Self::add`]) whose place in it is not decided yet,
    /// by record id, ascending. A loop `u` left out of the clique conflicts
    /// with some members; the largest clique that takes `u` must drop all
    /// of them. When that clique is smaller than the maximum by fewer than
    /// `margin` loops, the members `u` conflicts with are *contested*: two
    /// groups of loops that exclude each other (e.g. two fits of one
    /// place's walls) are nearly as well supported, and the maximum may
    /// turn as more loops arrive. Per component of the conflict graph, one
    /// bounded cover search per left-out loop (only covers smaller than the
    /// maximum's plus `margin` are looked for, so most end at once); past
    /// `MAX_CLIQUE_WORK` the remaining members count as decided.
    pub fn contested(&self, margin: usize) -> Vec<usize> {
        let n = self.measurements.len();
        let mut contested = vec![false; n];
        let mut seen = vec![false; n];
        let mut work = 0;
        for root in 0..n {
            if seen[root] || self.conflicts[root].is_empty() {
                continue;
            }
            let component = self.component_of(root, &mut seen);
            let adjacency = self.adjacency(&component);
            let words = component.len().div_ceil(64);
            let best = component.iter().filter(|&&v| self.in_cover[v]).count();
            for (i, &u) in component.iter().enumerate() {
                let rivals: Vec<usize> = adjacency[i]
                    .iter()
                    .map(|j| component[j])
                    .filter(|&w| !self.in_cover[w])
                    .collect();
                if !self.in_cover[u] || rivals.iter().all(|&w| contested[w]) {
                    continue;
                }
                // `u` in the clique, so all its conflicts in the cover.
                let mut alive = BitSet::empty(words);
                (0..component.len())
                    .filter(|&j| j != i)
                    .for_each(|j| alive.insert(j));
                let alive = alive.difference(&adjacency[i]);
                let mut search = MinCover {
                    adjacency: &adjacency,
                    best: BitSet::empty(words),
                    best_size: best + margin,
                    work,
                    budget: MAX_CLIQUE_WORK,
                };
                let forced = adjacency[i].count();
                search.branch(alive, adjacency[i].clone(), forced);
                work = search.work;
                if work > MAX_CLIQUE_WORK {
                    break;
                }
                if search.best_size < best + margin {
                    rivals.iter().for_each(|&w| contested[w] = true);
                }
            }
        }
        let mut ids: Vec<usize> = (0..n)
            .filter(|&v| contested[v])
            .map(|v| self.measurements[v].id)
            .collect();
        ids.sort_unstable();
        ids
    }

    /// The conflict component of `root`, in ascending vertex order; marks
    /// its vertices in `seen`.
    fn component_of(&self, root: usize, seen: &mut [bool]) -> Vec<usize> {
        let mut component = vec![root];
        seen[root] = true;
        let mut head = 0;
        while head < component.len() {
            for &u in &self.conflicts[component[head]] {
                if !seen[u] {
                    seen[u] = true;
                    component.push(u);
                }
            }
            head += 1;
        }
        component.sort_unstable();
        component
    }

    /// The conflict rows of `component`'s vertices, over their positions
    /// in it.
    fn adjacency(&self, component: &[usize]) -> Vec<BitSet> {
        let local: HashMap<usize, usize> =
            component.iter().enumerate().map(|(i, &v)| (v, i)).collect();
        let m = component.len();
        component
            .iter()
            .map(|&v| {
                let mut row = BitSet::empty(m.div_ceil(64));
                self.conflicts[v].iter().for_each(|u| row.insert(local[u]));
                row
            })
            .collect()
    }

    /// Updates `in_cover` over one conflict component, with `work` of the
    /// search's budget spent already; returns the work spent after it.
    /// Past the budget a component keeps its incumbent.
    fn cover_component(&mut self, component: &[usize], work: usize, budget: usize) -> usize {
        let m = component.len();
        let adjacency = self.adjacency(component);
        // The incumbent: the previous cover, plus the later endpoint of
        // every conflict it leaves uncovered (a new vertex).
        let mut incumbent = BitSet::empty(m.div_ceil(64));
        for (i, &v) in component.iter().enumerate() {
            if self.in_cover[v] {
                incumbent.insert(i);
            }
        }
        for (i, row) in adjacency.iter().enumerate() {
            if !incumbent.contains(i) && row.iter().any(|j| j < i && !incumbent.contains(j)) {
                incumbent.insert(i);
            }
        }
        let mut search = MinCover {
            adjacency: &adjacency,
            best_size: incumbent.count(),
            best: incumbent,
            work,
            budget,
        };
        let mut alive = BitSet::empty(m.div_ceil(64));
        (0..m).for_each(|i| alive.insert(i));
        search.branch(alive, BitSet::empty(m.div_ceil(64)), 0);
        for (i, &v) in component.iter().enumerate() {
            self.in_cover[v] = search.best.contains(i);
        }
        search.work
    }
}

/// Branch and bound for a minimum vertex cover of a small graph.
struct MinCover<'a> {
    adjacency: &'a [BitSet],
    best: BitSet,
    best_size: usize,
    /// Bit-set words visited so far, and the limit (see `MAX_CLIQUE_WORK`).
    work: usize,
    budget: usize,
}

impl MinCover<'_> {
    /// `alive`: vertices not yet decided; `cover`: the vertices taken so
    /// far (`size` of them). Edges between a decided vertex and an alive
    /// one are covered already (a vertex is only left out of the cover
    /// with all its neighbours in), so only the edges among `alive` remain.
    fn branch(&mut self, mut alive: BitSet, mut cover: BitSet, mut size: usize) {
        if self.work > self.budget {
            return;
        }
        let words = alive.0.len();
        size += self.reduce(&mut alive, &mut cover);
        if size >= self.best_size {
            return;
        }
        if alive.is_empty() {
            self.best = cover;
            self.best_size = size;
            return;
        }
        if size + self.matching_bound(&alive) >= self.best_size {
            return;
        }
        // Branch on the vertex of most conflicts (ties: the lowest): it is
        // in the cover, or all its neighbours are.
        let alive_count = alive.count();
        self.work += 2 * words * alive_count;
        let v = alive
            .iter()
            .max_by_key(|&v| (alive.intersection_count(&self.adjacency[v]), usize::MAX - v))
            .expect("alive is not empty");
        let neighbours = alive.intersection(&self.adjacency[v]);
        let mut rest = alive;
        rest.remove(v);
        let mut with_v = cover.clone();
        with_v.insert(v);
        self.branch(rest.clone(), with_v, size + 1);
        let k = neighbours.count();
        if size + k < self.best_size {
            for u in neighbours.iter() {
                cover.insert(u);
            }
            self.branch(rest.difference(&neighbours), cover, size + k);
        }
    }
}

impl MinCover<'_> {
    /// Reductions, repeated until none applies: a vertex without alive
    /// neighbours stays out; the neighbour of a degree-one vertex goes in
    /// (some minimum cover takes it). Decided vertices leave `alive`;
    /// returns how many went into `cover`.
    fn reduce(&mut self, alive: &mut BitSet, cover: &mut BitSet) -> usize {
        let words = alive.0.len();
        let mut added = 0;
        loop {
            let mut changed = false;
            for v in alive.clone().iter() {
                if !alive.contains(v) {
                    continue;
                }
                self.work += words;
                match alive.intersection_count(&self.adjacency[v]) {
                    0 => {
                        alive.remove(v);
                        changed = true;
                    }
                    1 => {
                        let u = alive
                            .first_common(&self.adjacency[v])
                            .expect("one neighbour");
                        alive.remove(u);
                        alive.remove(v);
                        cover.insert(u);
                        added += 1;
                        changed = true;
                    }
                    _ => {}
                }
            }
            if !changed {
                return added;
            }
        }
    }

    /// A lower bound on the cover of the edges among `alive`: the edges of
    /// a greedy matching need a cover vertex each.
    fn matching_bound(&self, alive: &BitSet) -> usize {
        let mut unmatched = alive.clone();
        let mut matching = 0;
        for v in alive.iter() {
            if unmatched.contains(v)
                && let Some(u) = unmatched.first_common(&self.adjacency[v])
            {
                unmatched.remove(u);
                unmatched.remove(v);
                matching += 1;
            }
        }
        matching
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

    fn contains(&self, i: usize) -> bool {
        self.0[i / 64] & (1 << (i % 64)) != 0
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

    fn intersection(&self, other: &BitSet) -> BitSet {
        self.zip(other, |a, b| a & b)
    }

    fn difference(&self, other: &BitSet) -> BitSet {
        self.zip(other, |a, b| a & !b)
    }

    /// The smallest member of `self ∩ other`, without building it.
    fn first_common(&self, other: &BitSet) -> Option<usize> {
        self.0
            .iter()
            .zip(&other.0)
            .enumerate()
            .find_map(|(w, (a, b))| {
                let both = a & b;
                (both != 0).then(|| w * 64 + both.trailing_zeros() as usize)
            })
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

    /// Each pair `(a, b)`, `a < b < n`, with probability `density`.
    fn random_edges(rng: &mut ChaCha8Rng, n: usize, density: f64) -> Vec<(usize, usize)> {
        (0..n)
            .flat_map(|a| (a + 1..n).map(move |b| (a, b)))
            .filter(|_| rng.random_bool(density))
            .collect()
    }

    /// The maximum clique size by trying every subset (small n).
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

    /// Graph of `groups` (sizes): loops within a group consistent, every
    /// two groups in conflict, plus `free` loops consistent with all.
    fn rival_groups(groups: &[usize], free: usize) -> (usize, Vec<(usize, usize)>) {
        let mut group_of = Vec::new();
        for (g, &size) in groups.iter().enumerate() {
            group_of.extend(std::iter::repeat_n(Some(g), size));
        }
        group_of.extend(std::iter::repeat_n(None, free));
        let n = group_of.len();
        let edges = (0..n)
            .flat_map(|a| (a + 1..n).map(move |b| (a, b)))
            .filter(|&(a, b)| match (group_of[a], group_of[b]) {
                (Some(x), Some(y)) => x == y,
                _ => true,
            })
            .collect();
        (n, edges)
    }

    #[test]
    fn a_group_that_leads_its_rival_by_less_than_the_margin_is_contested() {
        // Three loops against two (and three that agree with both): the
        // three win the clique, by one loop.
        let (n, edges) = rival_groups(&[3, 2], 3);
        let mut g = graph_with_edges(n, &edges);
        assert_eq!(g.max_clique().ids, vec![0, 1, 2, 5, 6, 7]);
        assert_eq!(g.contested(2), vec![0, 1, 2]);
        assert!(g.contested(1).is_empty());
        // Against one loop, a lead of two: decided.
        let (n, edges) = rival_groups(&[3, 1], 3);
        let mut g = graph_with_edges(n, &edges);
        assert_eq!(g.max_clique().ids, vec![0, 1, 2, 4, 5, 6]);
        assert!(g.contested(2).is_empty());
        // A tie keeps the first group and contests it.
        let (n, edges) = rival_groups(&[2, 2], 0);
        let mut g = graph_with_edges(n, &edges);
        assert_eq!(g.max_clique().ids, vec![0, 1]);
        assert_eq!(g.contested(1), vec![0, 1]);
        // No conflict, nothing contested.
        let (n, edges) = rival_groups(&[4], 2);
        let mut g = graph_with_edges(n, &edges);
        assert_eq!(g.max_clique().ids.len(), 6);
        assert!(g.contested(2).is_empty());
    }

    #[test]
    fn contested_members_match_brute_force_on_random_graphs() {
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        for trial in 0..60 {
            let n = rng.random_range(2..=11);
            let density = rng.random_range(0.4..0.95);
            let edges = random_edges(&mut rng, n, density);
            let adjacent = |a: usize, b: usize| edges.contains(&(a, b)) || edges.contains(&(b, a));
            let mut g = graph_with_edges(n, &edges);
            let clique = g.max_clique().ids;
            let margin = rng.random_range(1..=3);
            // The largest clique that takes `u`, by brute force.
            let best_with = |u: usize| {
                let others: Vec<usize> = (0..n).filter(|&v| v != u && adjacent(u, v)).collect();
                let sub: Vec<(usize, usize)> = edges
                    .iter()
                    .filter_map(|&(a, b)| {
                        let (i, j) = (
                            others.iter().position(|&v| v == a)?,
                            others.iter().position(|&v| v == b)?,
                        );
                        Some((i, j))
                    })
                    .collect();
                1 + brute_force(others.len(), &sub)
            };
            let mut expected: Vec<usize> = (0..n)
                .filter(|&w| clique.contains(&w))
                .filter(|&w| {
                    (0..n).any(|u| {
                        !clique.contains(&u)
                            && !adjacent(u, w)
                            && best_with(u) + margin > clique.len()
                    })
                })
                .collect();
            expected.sort_unstable();
            assert_eq!(
                g.contested(margin),
                expected,
                "trial {trial}, margin {margin}"
            );
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
            let edges = random_edges(&mut rng, n, density);
            let found = graph_with_edges(n, &edges).max_clique();
            assert_eq!(found.ids.len(), brute_force(n, &edges), "trial {trial}");
            assert_is_clique(&found.ids, &edges);
        }
    }

    #[test]
    fn matches_brute_force_on_sparse_conflicts() {
        // The pipeline's regime: nearly every pair consistent, the
        // conflicts in a few small components.
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for trial in 0..40 {
            let n = rng.random_range(8..=16);
            let density = rng.random_range(0.8..0.98);
            let edges = random_edges(&mut rng, n, density);
            let found = graph_with_edges(n, &edges).max_clique();
            assert_eq!(found.ids.len(), brute_force(n, &edges), "trial {trial}");
            assert_is_clique(&found.ids, &edges);
            assert!(found.exact);
        }
    }

    #[test]
    fn finds_a_large_planted_clique_among_outliers() {
        // 400 loops consistent with each other but for 60 random
        // conflicts, and 40 outliers each in conflict with a third of all.
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (good, bad) = (400, 40);
        let n = good + bad;
        let mut conflict = vec![vec![false; n]; n];
        let mut set = |a: usize, b: usize| {
            conflict[a][b] = true;
            conflict[b][a] = true;
        };
        for _ in 0..60 {
            let (a, b) = (rng.random_range(0..good), rng.random_range(0..good));
            if a != b {
                set(a, b);
            }
        }
        for v in good..n {
            for u in 0..n {
                if u != v && rng.random_bool(1.0 / 3.0) {
                    set(u, v);
                }
            }
        }
        let mut g = ConsistencyGraph::new();
        for (v, row) in conflict.iter().enumerate() {
            let neighbours: Vec<usize> = (0..v).filter(|&u| !row[u]).collect();
            g.push_vertex(measurement(v), &neighbours);
        }
        let found = g.max_clique();
        assert!(found.exact);
        for (i, &a) in found.ids.iter().enumerate() {
            for &b in &found.ids[i + 1..] {
                assert!(!conflict[a][b], "{a} - {b}");
            }
        }
        // The good loops minus one end of each of their conflicts is a
        // clique of at least good - 60 members; no outlier can be in the
        // maximum one here.
        assert!(found.ids.len() >= good - 60, "{}", found.ids.len());
        assert!(found.ids.iter().all(|&id| id < good));
    }

    #[test]
    fn a_search_past_its_work_limit_still_returns_a_clique() {
        // Dense conflicts: a hard cover problem, cut short.
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let n = 120;
        let mut edges = Vec::new();
        let mut g = ConsistencyGraph::new();
        for v in 0..n {
            let neighbours: Vec<usize> = (0..v).filter(|_| rng.random_bool(0.5)).collect();
            edges.extend(neighbours.iter().map(|&u| (u, v)));
            g.push_vertex(measurement(v), &neighbours);
        }
        let found = g.max_clique_within(100_000);
        assert!(!found.exact);
        assert!(!found.ids.is_empty());
        assert_is_clique(&found.ids, &edges);
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
