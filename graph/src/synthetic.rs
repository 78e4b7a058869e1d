//! Seeded synthetic pose graphs with known ground truth, for tests and
//! benchmarks.
//!
//! Measurements are the ground-truth relative poses perturbed by zero-mean
//! Gaussian noise (standard deviations in [`Noise`]); every edge carries the
//! matching information `diag(1/σ_t², 1/σ_t², 1/σ_θ²)`. Initial node poses are
//! the composition of the noisy odometry chain, i.e. dead reckoning, which
//! drifts away from the truth as in a real mission.

use crate::{Edge, EdgeKind, GraphError, Node, NodeId, PoseGraph, Se2};
use nalgebra::Matrix3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::collections::HashMap;
use std::f64::consts::TAU;

/// Measurement noise of the synthetic edges.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Noise {
    /// Standard deviation of each translation component, metres.
    pub translation_m: f64,
    /// Standard deviation of the rotation, radians.
    pub rotation_rad: f64,
}

impl Noise {
    pub fn new(translation_m: f64, rotation_rad: f64) -> Self {
        Self {
            translation_m,
            rotation_rad,
        }
    }

    fn information(&self) -> Matrix3<f64> {
        let t = 1.0 / (self.translation_m * self.translation_m);
        let r = 1.0 / (self.rotation_rad * self.rotation_rad);
        Matrix3::from_diagonal(&nalgebra::Vector3::new(t, t, r))
    }
}

/// A synthetic graph and the poses it was generated from.
#[derive(Clone, Debug)]
pub struct SyntheticGraph {
    /// Nodes at the dead-reckoning start, edges with noisy measurements.
    pub graph: PoseGraph,
    /// `world_from_node` of every node, in node order.
    pub ground_truth: Vec<Se2>,
}

/// `n` poses around a circle of radius 10 m, travelled `laps` times, with an
/// odometry edge between consecutive poses and a loop closure between poses
/// one lap apart.
///
/// # Panics
/// If `n < 3`, `laps == 0` or a noise deviation is not positive (fixtures
/// are built by tests, so a bad argument is a programming error).
pub fn circle_pose_graph(n: usize, laps: usize, noise: Noise, seed: u64) -> SyntheticGraph {
    assert!(n >= 3 && laps >= 1, "need n >= 3 and laps >= 1");
    let per_lap = n.div_ceil(laps);
    let truth: Vec<Se2> = (0..n)
        .map(|i| {
            let a = TAU * i as f64 / per_lap as f64;
            Se2::new(10.0 * a.cos(), 10.0 * a.sin(), a + TAU / 4.0)
        })
        .collect();
    let mut loops = Vec::new();
    for i in per_lap..n {
        loops.push((i - per_lap, i));
    }
    build(truth, &loops, noise, seed)
}

/// A random walk of `n` poses on a square grid with 1 m spacing (turns of
/// ±90° or straight on), with a loop closure whenever the walk returns to a
/// grid point visited at least 3 steps earlier: a small "manhattan" world.
///
/// # Panics
/// As [`circle_pose_graph`].
pub fn grid_pose_graph(n: usize, noise: Noise, seed: u64) -> SyntheticGraph {
    assert!(n >= 3, "need n >= 3");
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x9e37_79b9_7f4a_7c15);
    let mut truth = Vec::with_capacity(n);
    let (mut x, mut y, mut heading) = (0i64, 0i64, 0i64); // heading in quarter turns
    let mut visits: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    let mut loops = Vec::new();
    for i in 0..n {
        truth.push(Se2::new(x as f64, y as f64, heading as f64 * TAU / 4.0));
        let seen = visits.entry((x, y)).or_default();
        if let Some(&j) = seen.iter().rev().find(|&&j| j + 3 <= i) {
            loops.push((j, i));
        }
        seen.push(i);
        heading += match rand::Rng::random_range(&mut rng, 0..6) {
            0 => 1,
            1 => -1,
            _ => 0,
        };
        // Stay within a 10 x 10 block so the walk revisits places.
        let (dx, dy) = [(1, 0), (0, 1), (-1, 0), (0, -1)][heading.rem_euclid(4) as usize];
        if !(-5..=5).contains(&(x + dx)) || !(-5..=5).contains(&(y + dy)) {
            heading += 2;
        }
        let (dx, dy) = [(1, 0), (0, 1), (-1, 0), (0, -1)][heading.rem_euclid(4) as usize];
        x += dx;
        y += dy;
    }
    build(truth, &loops, noise, seed)
}

fn build(truth: Vec<Se2>, loops: &[(usize, usize)], noise: Noise, seed: u64) -> SyntheticGraph {
    assert!(
        noise.translation_m > 0.0 && noise.rotation_rad > 0.0,
        "noise deviations must be positive"
    );
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let t_noise = Normal::new(0.0, noise.translation_m).expect("positive sigma");
    let r_noise = Normal::new(0.0, noise.rotation_rad).expect("positive sigma");
    let mut measure = |a: &Se2, b: &Se2| {
        let exact = a.between(b);
        exact.compose(&Se2::new(
            t_noise.sample(&mut rng),
            t_noise.sample(&mut rng),
            r_noise.sample(&mut rng),
        ))
    };
    let information = noise.information();
    let mut edges = Vec::new();
    let mut start = vec![truth[0]];
    for i in 1..truth.len() {
        let z = measure(&truth[i - 1], &truth[i]);
        start.push(start[i - 1].compose(&z));
        edges.push(Edge::new(
            EdgeKind::Odometry,
            i as u64 - 1,
            i as u64,
            z,
            information,
        ));
    }
    for &(i, j) in loops {
        let z = measure(&truth[i], &truth[j]);
        edges.push(Edge::new(
            EdgeKind::Loop,
            i as u64,
            j as u64,
            z,
            information,
        ));
    }
    let mut graph = PoseGraph::new();
    for (i, pose) in start.into_iter().enumerate() {
        graph
            .add_node(Node {
                id: i as u64,
                pose,
                stamp_s: Some(i as f64),
            })
            .expect("fresh ids are unique");
    }
    for edge in edges {
        graph.add_edge(edge).expect("edges join existing nodes");
    }
    SyntheticGraph {
        graph,
        ground_truth: truth,
    }
}

/// How [`add_false_loops`] draws its outliers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FalseLoops {
    /// Number of false loop closures to add.
    pub count: usize,
    /// Each translation component of a false measurement is drawn uniformly
    /// from `[-max_translation_m, max_translation_m]`, metres.
    pub max_translation_m: f64,
    /// Seed of the draw.
    pub seed: u64,
}

/// Why [`add_false_loops`] could not add its outliers.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum FalseLoopsError {
    #[error("false loops need a graph of at least 3 nodes, this one has {nodes}")]
    TooFewNodes { nodes: usize },
    #[error("false loops copy the information of an existing edge, and the graph has none")]
    NoEdges,
    #[error("max_translation_m must be finite and positive, got {value}")]
    MaxTranslation { value: f64 },
    #[error(transparent)]
    Graph(#[from] GraphError),
}

/// Adds `spec.count` false loop closures to `graph`, in the style of the
/// vertigo benchmarks' random outliers (Sünderhauf and Protzel, "Switchable
/// Constraints for Robust Pose Graph SLAM", IROS 2012): each joins a random
/// pair of distinct nodes that are not consecutive in node order, with a
/// measurement whose translation is uniform in
/// `[-max_translation_m, max_translation_m]²` and whose rotation is uniform
/// in `(-π, π]`, and with the information of a randomly chosen loop closure
/// already in the graph (the first edge's when there is none), so the
/// outliers look as confident as the true loops.
///
/// Returns the `(from, to)` node ids of the added edges, in the order added.
/// Deterministic for a given graph and seed.
///
/// # Errors
/// [`FalseLoopsError`] when the graph has fewer than three nodes or no
/// edge, or `max_translation_m` is not finite and positive.
pub fn add_false_loops(
    graph: &mut PoseGraph,
    spec: FalseLoops,
) -> Result<Vec<(NodeId, NodeId)>, FalseLoopsError> {
    let n = graph.node_count();
    let first_information = graph
        .edges()
        .next()
        .map(|e| e.information)
        .ok_or(FalseLoopsError::NoEdges)?;
    if n < 3 {
        return Err(FalseLoopsError::TooFewNodes { nodes: n });
    }
    if !(spec.max_translation_m.is_finite() && spec.max_translation_m > 0.0) {
        return Err(FalseLoopsError::MaxTranslation {
            value: spec.max_translation_m,
        });
    }
    let loop_information: Vec<Matrix3<f64>> = graph
        .edges()
        .filter(|e| e.kind == EdgeKind::Loop)
        .map(|e| e.information)
        .collect();
    let ids: Vec<NodeId> = graph.nodes().map(|node| node.id).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    let translation =
        rand_distr::Uniform::new_inclusive(-spec.max_translation_m, spec.max_translation_m)
            .map_err(|_| FalseLoopsError::MaxTranslation {
                value: spec.max_translation_m,
            })?;
    let rotation =
        rand_distr::Uniform::new(-std::f64::consts::PI, std::f64::consts::PI).map_err(|_| {
            FalseLoopsError::MaxTranslation {
                value: spec.max_translation_m,
            }
        })?;
    let mut added = Vec::with_capacity(spec.count);
    while added.len() < spec.count {
        let a = rand::Rng::random_range(&mut rng, 0..n);
        let b = rand::Rng::random_range(&mut rng, 0..n);
        if a.abs_diff(b) < 2 {
            continue;
        }
        let (from, to) = (ids[a.min(b)], ids[a.max(b)]);
        let z = Se2::new(
            translation.sample(&mut rng),
            translation.sample(&mut rng),
            rotation.sample(&mut rng),
        );
        let information = if loop_information.is_empty() {
            first_information
        } else {
            loop_information[rand::Rng::random_range(&mut rng, 0..loop_information.len())]
        };
        graph.add_edge(Edge::new(EdgeKind::Loop, from, to, z, information))?;
        added.push((from, to));
    }
    Ok(added)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_graph() {
        let noise = Noise::new(0.05, 0.01);
        let a = grid_pose_graph(200, noise, 7);
        let b = grid_pose_graph(200, noise, 7);
        assert_eq!(a.graph.poses(), b.graph.poses());
        assert_eq!(a.graph.edge_count(), b.graph.edge_count());
        assert!(a.graph.edge_count() > 200, "the walk should revisit places");
        let c = circle_pose_graph(90, 3, noise, 1);
        assert_eq!(c.graph.edge_count(), 89 + 60);
        assert!(c.graph.is_connected());
    }
}
