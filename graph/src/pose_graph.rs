//! The pose graph: nodes carry world poses, edges carry relative-pose
//! measurements with a 3x3 information matrix. Topology lives in a
//! `petgraph::Graph`; node ids are the user's (g2o vertex ids, rotation
//! indices) and are mapped to dense indices `0..node_count()` in insertion
//! order, which is the order the backend uses for its unknowns.
//!
//! Frames: a node's `pose` is `world_from_node`. An edge `from -> to` measures
//! `from_from_to = ⊖ world_from_from ⊕ world_from_to`. A prior is an edge of
//! kind [`EdgeKind::Prior`] from a node to itself whose measurement is the
//! absolute pose `world_from_node`.

use crate::se2::Se2;
use nalgebra::Matrix3;
use petgraph::graph::{DiGraph, NodeIndex};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeSet, HashMap};
use thiserror::Error;

/// A user-visible node identifier (g2o vertex id, rotation index, ...).
pub type NodeId = u64;

/// One pose of the graph.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Node {
    pub id: NodeId,
    /// `world_from_node`.
    pub pose: Se2,
    /// Time of the pose in seconds (Unix or mission time), when known.
    pub stamp_s: Option<f64>,
}

/// What produced an edge; the backend can pick a robust kernel per kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EdgeKind {
    /// Dead reckoning between consecutive nodes.
    Odometry,
    /// Scan match between consecutive nodes.
    Sequential,
    /// Scan match between non-consecutive nodes.
    Loop,
    /// Absolute pose of one node (`from == to`).
    Prior,
}

impl EdgeKind {
    pub const ALL: [EdgeKind; 4] = [
        EdgeKind::Odometry,
        EdgeKind::Sequential,
        EdgeKind::Loop,
        EdgeKind::Prior,
    ];
}

/// A relative-pose measurement between two nodes (or an absolute one for a
/// prior).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Edge {
    pub kind: EdgeKind,
    pub from: NodeId,
    pub to: NodeId,
    /// `from_from_to` (for a prior: `world_from_node`).
    pub measurement: Se2,
    /// Inverse covariance of the measurement in the error coordinates
    /// `(x, y, θ)`; symmetric positive definite.
    pub information: Matrix3<f64>,
    /// Free-form provenance (match score, quality, ...). Not written to g2o.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metadata: Option<serde_json::Value>,
}

impl Edge {
    /// An edge without metadata.
    pub fn new(
        kind: EdgeKind,
        from: NodeId,
        to: NodeId,
        measurement: Se2,
        information: Matrix3<f64>,
    ) -> Self {
        Self {
            kind,
            from,
            to,
            measurement,
            information,
            metadata: None,
        }
    }
}

/// Errors from building a graph.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum GraphError {
    #[error("duplicate node id {id}")]
    DuplicateNode { id: NodeId },
    #[error("edge {from} -> {to} refers to missing node {missing}")]
    MissingNode {
        from: NodeId,
        to: NodeId,
        missing: NodeId,
    },
    #[error("node {id}: pose is not finite")]
    NonFinitePose { id: NodeId },
    #[error("edge {from} -> {to}: measurement is not finite")]
    NonFiniteMeasurement { from: NodeId, to: NodeId },
    #[error("edge {from} -> {to}: information matrix is not symmetric positive definite")]
    InformationNotPositiveDefinite { from: NodeId, to: NodeId },
    #[error("edge {from} -> {to}: a prior must connect a node to itself")]
    PriorNotUnary { from: NodeId, to: NodeId },
    #[error("edge {from} -> {to}: a relative edge must connect two different nodes")]
    SelfLoop { from: NodeId, to: NodeId },
    #[error("unknown node id {id}")]
    UnknownNode { id: NodeId },
}

/// Checks that a 3x3 matrix is finite, symmetric (to a relative 1e-9) and
/// positive definite (Cholesky succeeds).
pub fn is_symmetric_positive_definite(m: &Matrix3<f64>) -> bool {
    if m.iter().any(|v| !v.is_finite()) {
        return false;
    }
    let scale = m.abs().max().max(f64::MIN_POSITIVE);
    if (m - m.transpose()).abs().max() > 1e-9 * scale {
        return false;
    }
    m.cholesky().is_some()
}

/// A pose graph over SE(2).
#[derive(Clone, Debug, Default)]
pub struct PoseGraph {
    graph: DiGraph<Node, Edge>,
    index_of: HashMap<NodeId, NodeIndex>,
    fixed: BTreeSet<NodeId>,
}

impl PoseGraph {
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a node; its dense index is the number of nodes before it.
    pub fn add_node(&mut self, node: Node) -> Result<usize, GraphError> {
        if self.index_of.contains_key(&node.id) {
            return Err(GraphError::DuplicateNode { id: node.id });
        }
        if !node.pose.is_finite() {
            return Err(GraphError::NonFinitePose { id: node.id });
        }
        let id = node.id;
        let index = self.graph.add_node(node);
        self.index_of.insert(id, index);
        Ok(index.index())
    }

    /// Adds an edge after checking its endpoints, measurement and information.
    pub fn add_edge(&mut self, edge: Edge) -> Result<(), GraphError> {
        let (from, to) = (edge.from, edge.to);
        let missing = |missing| GraphError::MissingNode { from, to, missing };
        let a = *self.index_of.get(&from).ok_or_else(|| missing(from))?;
        let b = *self.index_of.get(&to).ok_or_else(|| missing(to))?;
        match (edge.kind, from == to) {
            (EdgeKind::Prior, false) => return Err(GraphError::PriorNotUnary { from, to }),
            (EdgeKind::Prior, true) => {}
            (_, true) => return Err(GraphError::SelfLoop { from, to }),
            (_, false) => {}
        }
        if !edge.measurement.is_finite() {
            return Err(GraphError::NonFiniteMeasurement { from, to });
        }
        if !is_symmetric_positive_definite(&edge.information) {
            return Err(GraphError::InformationNotPositiveDefinite { from, to });
        }
        self.graph.add_edge(a, b, edge);
        Ok(())
    }

    /// Holds a node at its current pose during optimisation (g2o `FIX`).
    pub fn fix(&mut self, id: NodeId) -> Result<(), GraphError> {
        if !self.index_of.contains_key(&id) {
            return Err(GraphError::UnknownNode { id });
        }
        self.fixed.insert(id);
        Ok(())
    }

    pub fn fixed(&self) -> &BTreeSet<NodeId> {
        &self.fixed
    }

    pub fn node_count(&self) -> usize {
        self.graph.node_count()
    }

    pub fn edge_count(&self) -> usize {
        self.graph.edge_count()
    }

    pub fn contains(&self, id: NodeId) -> bool {
        self.index_of.contains_key(&id)
    }

    /// Dense index (`0..node_count()`, insertion order) of a node.
    pub fn index_of(&self, id: NodeId) -> Option<usize> {
        self.index_of.get(&id).map(|i| i.index())
    }

    pub fn node(&self, id: NodeId) -> Option<&Node> {
        self.index_of.get(&id).map(|&i| &self.graph[i])
    }

    /// The node at a dense index.
    pub fn node_at(&self, index: usize) -> &Node {
        &self.graph[NodeIndex::new(index)]
    }

    /// Nodes in insertion (dense index) order.
    pub fn nodes(&self) -> impl Iterator<Item = &Node> + '_ {
        self.graph.node_weights()
    }

    /// Edges in insertion order.
    pub fn edges(&self) -> impl Iterator<Item = &Edge> + '_ {
        self.graph.edge_weights()
    }

    /// Edges with the dense indices of their endpoints, in insertion order.
    pub fn indexed_edges(&self) -> impl Iterator<Item = (usize, usize, &Edge)> + '_ {
        self.graph
            .raw_edges()
            .iter()
            .map(|e| (e.source().index(), e.target().index(), &e.weight))
    }

    /// Replaces the pose of a node.
    pub fn set_pose(&mut self, id: NodeId, pose: Se2) -> Result<(), GraphError> {
        let index = *self
            .index_of
            .get(&id)
            .ok_or(GraphError::UnknownNode { id })?;
        if !pose.is_finite() {
            return Err(GraphError::NonFinitePose { id });
        }
        self.graph[index].pose = pose;
        Ok(())
    }

    /// Replaces all poses, in dense index order.
    ///
    /// # Panics
    /// If `poses.len() != node_count()` (a programming error, not bad input).
    pub fn set_poses(&mut self, poses: &[Se2]) {
        assert_eq!(poses.len(), self.node_count(), "one pose per node");
        for (node, pose) in self.graph.node_weights_mut().zip(poses) {
            node.pose = *pose;
        }
    }

    /// Poses in dense index order.
    pub fn poses(&self) -> Vec<Se2> {
        self.nodes().map(|n| n.pose).collect()
    }

    /// Number of connected components, edge direction ignored.
    pub fn connected_components(&self) -> usize {
        petgraph::algo::connected_components(&self.graph)
    }

    /// True when every node can be reached from every other (ignoring edge
    /// direction). An empty graph is connected.
    pub fn is_connected(&self) -> bool {
        self.node_count() == 0 || self.connected_components() == 1
    }

    /// The underlying petgraph graph, for topology algorithms.
    pub fn topology(&self) -> &DiGraph<Node, Edge> {
        &self.graph
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(id: NodeId) -> Node {
        Node {
            id,
            pose: Se2::new(id as f64, 0.0, 0.0),
            stamp_s: None,
        }
    }

    #[test]
    fn rejects_bad_edges() {
        let mut g = PoseGraph::new();
        g.add_node(node(0)).unwrap();
        g.add_node(node(5)).unwrap();
        assert_eq!(
            g.add_node(node(5)),
            Err(GraphError::DuplicateNode { id: 5 })
        );
        let z = Se2::new(1.0, 0.0, 0.0);
        let eye = Matrix3::identity();
        assert!(matches!(
            g.add_edge(Edge::new(EdgeKind::Odometry, 0, 7, z, eye)),
            Err(GraphError::MissingNode { missing: 7, .. })
        ));
        let not_pd = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0);
        assert!(matches!(
            g.add_edge(Edge::new(EdgeKind::Odometry, 0, 5, z, not_pd)),
            Err(GraphError::InformationNotPositiveDefinite { .. })
        ));
        assert!(!g.is_connected());
        g.add_edge(Edge::new(EdgeKind::Odometry, 0, 5, z, eye))
            .unwrap();
        assert!(g.is_connected());
        assert_eq!(g.index_of(5), Some(1));
    }
}
