//! The growing pose graph and its current estimate.
//!
//! Nodes are added as rotations arrive, with the dead-reckoning odometry
//! edge and, when accepted, the sequential match edge to the previous node;
//! accepted loop edges come and go as the set of mutually consistent loops
//! changes. A new node's pose is the previous node's current pose composed
//! with the odometry (whose heading is tied to the compass), so the
//! estimate stays corrected between solves; [`Estimate::solved_view`]
//! gives the graph solved with the new node's own edges as well, without
//! moving the estimate (what the online engine emits).
//!
//! Incremental solves start from the current estimate
//! (`Initialisation::Current`) with a small iteration limit, reusing one
//! [`Solver`], which keeps its symbolic factorisation while the pattern is
//! unchanged. The final batch solve starts from the configured
//! initialisation (chordal by default, from the trusted edges only).

use super::SlamError;
use super::config::BackendConfig;
use echofield_backend::{RobustSolveSummary, SolveSummary, Solver, optimize_robust};
use echofield_frontend::uncertainty::{LinkGraph, information};
use echofield_graph::{Edge, EdgeKind, Node, NodeId, PoseGraph, Se2};
use nalgebra::Matrix3;
use std::collections::BTreeMap;

/// The edges, current poses and link structure of the graph.
pub struct Estimate {
    stamps_s: Vec<f64>,
    poses: Vec<Se2>,
    /// Odometry and sequential edges, in insertion order.
    chain: Vec<Edge>,
    /// Accepted loop edges by loop id (the candidate's record index).
    loops: BTreeMap<usize, Edge>,
    links: LinkGraph,
    solver: Solver,
    /// The solver of [`Self::solved_view`], apart from `solver` so that
    /// the view leaves the incremental solves' state as it was.
    view_solver: Solver,
    pub incremental_solves: usize,
    pub incremental_symbolic_reused: usize,
    pub incremental_time_s: f64,
}

impl Estimate {
    pub fn new(backend: &BackendConfig) -> Result<Self, SlamError> {
        Ok(Self {
            stamps_s: Vec::new(),
            poses: Vec::new(),
            chain: Vec::new(),
            loops: BTreeMap::new(),
            links: LinkGraph::new(),
            solver: Solver::new(backend.incremental_solver())?,
            view_solver: Solver::new(backend.incremental_solver())?,
            incremental_solves: 0,
            incremental_symbolic_reused: 0,
            incremental_time_s: 0.0,
        })
    }

    pub fn len(&self) -> usize {
        self.poses.len()
    }

    pub fn is_empty(&self) -> bool {
        self.poses.is_empty()
    }

    /// The current estimate of every node, `world_from_node`.
    pub fn poses(&self) -> &[Se2] {
        &self.poses
    }

    pub fn links(&self) -> &LinkGraph {
        &self.links
    }

    /// Adds a node at `pose`; returns its id.
    pub fn add_node(&mut self, stamp_s: f64, pose: Se2) -> usize {
        self.stamps_s.push(stamp_s);
        self.poses.push(pose);
        self.links.add_node();
        self.poses.len() - 1
    }

    /// Adds an odometry or sequential edge `from -> to` measuring
    /// `from_from_to` with covariance `cov` (positive definite).
    pub fn add_chain_edge(
        &mut self,
        kind: EdgeKind,
        from: usize,
        to: usize,
        from_from_to: Se2,
        cov: &Matrix3<f64>,
        metadata: Option<serde_json::Value>,
    ) -> Result<(), SlamError> {
        let edge = make_edge(kind, from, to, from_from_to, cov, metadata)?;
        self.links.add(from, to, &from_from_to, cov);
        self.chain.push(edge);
        Ok(())
    }

    /// Adds a heading prior on node `k`: its dead-reckoning heading with
    /// standard deviation `sigma_rad`, and no information on position
    /// beyond a negligible `1e-12 / m²` (which keeps the information matrix
    /// positive definite, as the graph requires).
    pub fn add_heading_prior(
        &mut self,
        k: usize,
        world_from_node: Se2,
        sigma_rad: f64,
    ) -> Result<(), SlamError> {
        let info = Matrix3::from_diagonal(&nalgebra::Vector3::new(
            PRIOR_POSITION_INFORMATION,
            PRIOR_POSITION_INFORMATION,
            1.0 / (sigma_rad * sigma_rad),
        ));
        let cov = info.try_inverse().expect("diagonal and positive");
        let edge = make_edge(EdgeKind::Prior, k, k, world_from_node, &cov, None)?;
        self.chain.push(edge);
        Ok(())
    }

    /// Makes the accepted loops exactly `accepted` (id, from, to,
    /// `from_from_to`, covariance, metadata; ids ascending); returns
    /// whether anything changed (an id, or the weight of a loop kept). The
    /// loop closer passes edges without metadata and attaches it once,
    /// before the final solve ([`Self::attach_loop_metadata`]):
    /// the loops change at nearly every node of a long mission, and making
    /// and dropping every loop's metadata each time grew with the square of
    /// the mission.
    pub fn set_loops(&mut self, accepted: Vec<(usize, Edge, Matrix3<f64>)>) -> bool {
        let unchanged = accepted.len() == self.loops.len()
            && accepted
                .iter()
                .zip(&self.loops)
                .all(|((id, new, _), (old_id, old))| {
                    id == old_id && new.information == old.information
                });
        if unchanged {
            return false;
        }
        for (_, edge) in std::mem::take(&mut self.loops) {
            self.links.remove(edge.from as usize, edge.to as usize);
        }
        for (id, edge, cov) in accepted {
            self.insert_loop(id, edge, &cov);
        }
        true
    }

    /// Adds loop `id` (its edge and its link for the path covariances).
    fn insert_loop(&mut self, id: usize, edge: Edge, cov: &Matrix3<f64>) {
        self.links
            .add(edge.from as usize, edge.to as usize, &edge.measurement, cov);
        self.loops.insert(id, edge);
    }

    /// Takes the loops `left` out and adds `joined` (id, edge, covariance):
    /// the state [`Self::set_loops`] would leave with the accepted loops
    /// minus `left` plus `joined`, without touching the loops that stay.
    /// Returns whether anything changed (ids of `left` that are not loops
    /// here are ignored; an id of `joined` already here is replaced).
    pub fn update_loops(
        &mut self,
        left: &[usize],
        joined: Vec<(usize, Edge, Matrix3<f64>)>,
    ) -> bool {
        let mut changed = false;
        for &id in left {
            changed |= self.remove_loop(id);
        }
        for (id, edge, cov) in joined {
            self.remove_loop(id);
            self.insert_loop(id, edge, &cov);
            changed = true;
        }
        changed
    }

    /// Takes loop `id` out (its edge and its link); whether it was here.
    fn remove_loop(&mut self, id: usize) -> bool {
        let Some(edge) = self.loops.remove(&id) else {
            return false;
        };
        self.links.remove(edge.from as usize, edge.to as usize);
        true
    }

    /// Sets every loop edge's metadata to `metadata(id)` (the provenance
    /// of loop `id`'s match), for the graphs that leave the estimate.
    pub fn attach_loop_metadata(&mut self, metadata: impl Fn(usize) -> Option<serde_json::Value>) {
        for (&id, edge) in &mut self.loops {
            edge.metadata = metadata(id);
        }
    }

    /// Ids of the accepted loops.
    pub fn loop_ids(&self) -> impl Iterator<Item = usize> + '_ {
        self.loops.keys().copied()
    }

    /// The graph at the current estimate, node 0 fixed.
    pub fn graph(&self) -> Result<PoseGraph, SlamError> {
        self.build_graph(true)
    }

    /// [`Self::graph`], with the edges' metadata when `with_metadata`
    /// (no solve reads it: the incremental solves go without copying it).
    fn build_graph(&self, with_metadata: bool) -> Result<PoseGraph, SlamError> {
        let mut graph = PoseGraph::new();
        for (i, (pose, stamp_s)) in self.poses.iter().zip(&self.stamps_s).enumerate() {
            graph.add_node(Node {
                id: i as NodeId,
                pose: *pose,
                stamp_s: Some(*stamp_s),
            })?;
        }
        for edge in self.chain.iter().chain(self.loops.values()) {
            graph.add_edge(if with_metadata {
                edge.clone()
            } else {
                Edge::new(
                    edge.kind,
                    edge.from,
                    edge.to,
                    edge.measurement,
                    edge.information,
                )
            })?;
        }
        if !self.poses.is_empty() {
            graph.fix(0)?;
        }
        Ok(graph)
    }

    /// An incremental solve from the current estimate.
    pub fn optimise_incremental(&mut self) -> Result<SolveSummary, SlamError> {
        let mut graph = self.build_graph(false)?;
        let summary = self.solver.optimize(&mut graph)?;
        self.poses = graph.poses();
        self.incremental_solves += 1;
        self.incremental_symbolic_reused += usize::from(summary.symbolic_reused);
        self.incremental_time_s += summary.time_s;
        Ok(summary)
    }

    /// The graph as it stands (every edge so far) solved as an incremental
    /// solve would, without changing the estimate: the poses, `world_from_node`.
    /// Starts from `warm` (an earlier view, which may hold fewer nodes),
    /// each node after it placed from the one before by the estimate's own
    /// relative pose; from the estimate itself when `warm` is empty.
    /// The estimate, which gates and places the loop candidates, keeps
    /// being solved only when the accepted loops change
    /// ([`super::engine`]'s solve schedule). Errors: a failed solve.
    pub fn solved_view(&mut self, warm: &[Se2]) -> Result<Vec<Se2>, SlamError> {
        let mut graph = self.build_graph(false)?;
        graph.set_poses(&self.extended(warm));
        self.view_solver.optimize(&mut graph)?;
        Ok(graph.poses())
    }

    /// `view` (an earlier view of the first nodes, or empty) extended to
    /// every node: each node after it placed from the one before by the
    /// estimate's own relative pose (the odometry, or a solve's result);
    /// the estimate itself when `view` is empty.
    pub fn extended(&self, view: &[Se2]) -> Vec<Se2> {
        let mut poses: Vec<Se2> = view.iter().take(self.poses.len()).copied().collect();
        for k in poses.len()..self.poses.len() {
            let pose = match k {
                0 => self.poses[0],
                _ => poses[k - 1].compose(&self.poses[k - 1].inverse().compose(&self.poses[k])),
            };
            poses.push(pose);
        }
        poses
    }

    /// The final batch solve with `backend.solver`; returns the optimised
    /// graph and the summary, and keeps the solution as the estimate.
    pub fn optimise_batch(
        &mut self,
        backend: &BackendConfig,
    ) -> Result<(PoseGraph, SolveSummary), SlamError> {
        let mut graph = self.graph()?;
        let summary = Solver::new(backend.solver.clone())?.optimize(&mut graph)?;
        self.poses = graph.poses();
        Ok((graph, summary))
    }

    /// The final solve with false loops switched off
    /// ([`echofield_backend::optimize_robust`] with `backend.outliers`);
    /// keeps the solution as the estimate. The returned graph still holds
    /// every loop edge.
    pub fn optimise_robust(
        &mut self,
        backend: &BackendConfig,
    ) -> Result<(PoseGraph, RobustSolveSummary), SlamError> {
        let mut graph = self.graph()?;
        let summary = optimize_robust(&mut graph, &backend.solver, &backend.outliers)?;
        self.poses = graph.poses();
        Ok((graph, summary))
    }
}

/// Position information of a heading prior, 1/m².
const PRIOR_POSITION_INFORMATION: f64 = 1e-12;

/// An edge with information `cov⁻¹`; a covariance that is not positive
/// definite is an error naming the edge.
pub fn make_edge(
    kind: EdgeKind,
    from: usize,
    to: usize,
    from_from_to: Se2,
    cov: &Matrix3<f64>,
    metadata: Option<serde_json::Value>,
) -> Result<Edge, SlamError> {
    let info = information(cov).ok_or(SlamError::Graph(
        echofield_graph::GraphError::InformationNotPositiveDefinite {
            from: from as NodeId,
            to: to as NodeId,
        },
    ))?;
    Ok(Edge {
        kind,
        from: from as NodeId,
        to: to as NodeId,
        measurement: from_from_to,
        information: info,
        metadata,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// Four nodes on a square's sides with noisy odometry (sequential
    /// edges with metadata) and two loops back to node 0.
    fn square() -> (Estimate, Vec<(usize, Edge, Matrix3<f64>)>) {
        let mut estimate = Estimate::new(&BackendConfig::default()).unwrap();
        let cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(0.01, 0.01, 0.001));
        let step = Se2::new(1.05, 0.02, std::f64::consts::FRAC_PI_2 + 0.03);
        let mut pose = Se2::identity();
        for k in 0..4 {
            estimate.add_node(k as f64, pose);
            if k > 0 {
                let metadata = Some(json!({ "points": k }));
                estimate
                    .add_chain_edge(EdgeKind::Sequential, k - 1, k, step, &cov, metadata)
                    .unwrap();
            }
            pose = pose.compose(&step);
        }
        let loops = [
            (7, 3, Se2::new(1.0, 0.0, std::f64::consts::FRAC_PI_2)),
            (9, 2, Se2::new(1.0, 1.0, std::f64::consts::PI)),
        ]
        .map(|(id, from, z)| {
            let edge = make_edge(EdgeKind::Loop, from, 0, z, &cov, None).unwrap();
            (id, edge, cov)
        });
        (estimate, loops.to_vec())
    }

    #[test]
    fn loop_metadata_is_attached_once_and_no_solve_reads_metadata() {
        let (mut estimate, loops) = square();
        assert!(estimate.set_loops(loops.clone()));
        assert!(!estimate.set_loops(loops));
        // Set without metadata; attached on demand, per loop id.
        let loop_edges = |graph: &PoseGraph| -> Vec<Option<serde_json::Value>> {
            graph
                .edges()
                .filter(|e| e.kind == EdgeKind::Loop)
                .map(|e| e.metadata.clone())
                .collect()
        };
        assert_eq!(loop_edges(&estimate.graph().unwrap()), [None, None]);
        estimate.attach_loop_metadata(|id| Some(json!({ "score": id })));
        let full = estimate.graph().unwrap();
        assert_eq!(
            loop_edges(&full),
            [Some(json!({ "score": 7 })), Some(json!({ "score": 9 }))]
        );
        assert!(full.edges().all(|e| e.metadata.is_some()));
        // The solves' graph: the same edges, no metadata.
        let bare = estimate.build_graph(false).unwrap();
        assert!(bare.edges().all(|e| e.metadata.is_none()));
        let strip = |e: &Edge| Edge::new(e.kind, e.from, e.to, e.measurement, e.information);
        assert!(full.edges().map(strip).eq(bare.edges().cloned()));
        // Solved with and without metadata: the same poses, bit for bit.
        let config = BackendConfig::default().incremental_solver();
        let solve = |mut graph: PoseGraph| {
            Solver::new(config.clone())
                .unwrap()
                .optimize(&mut graph)
                .unwrap();
            graph.poses()
        };
        let (with, without) = (solve(full), solve(bare));
        assert_eq!(with, without);
        assert!(estimate.optimise_incremental().is_ok());
        assert_eq!(estimate.poses(), &without[..]);
    }
    #[test]
    fn a_solved_view_is_the_incremental_solve_and_leaves_the_estimate_as_it_was() {
        let (mut estimate, loops) = square();
        estimate.set_loops(loops.clone());
        let before = estimate.poses().to_vec();
        // From the estimate itself, and from an earlier view of fewer
        // nodes (the estimate's relative poses carry it to the others).
        let view = estimate.solved_view(&[]).unwrap();
        let from_partial = estimate.solved_view(&view[..2]).unwrap();
        assert_eq!(estimate.poses(), &before[..], "the estimate is not moved");
        assert_eq!(estimate.incremental_solves, 0);
        let (mut solved, _) = square();
        solved.set_loops(loops);
        solved.optimise_incremental().unwrap();
        for (a, b) in view.iter().zip(solved.poses()) {
            assert!((a.to_vector() - b.to_vector()).norm() < 1e-9, "{a:?} {b:?}");
        }
        for (a, b) in from_partial.iter().zip(&view) {
            assert!((a.to_vector() - b.to_vector()).norm() < 1e-6, "{a:?} {b:?}");
        }
        // The loops moved the nodes: the view is not the estimate.
        assert!((view[2].to_vector() - before[2].to_vector()).norm() > 0.01);
    }
}
