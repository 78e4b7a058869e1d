//! Turning parsed records into a [`PoseGraph`], shared by the g2o and TORO
//! readers: duplicate and missing vertices are reported with their line, and
//! files without vertices get a spanning-tree initialisation.

use super::IoError;
use crate::{Edge, EdgeKind, GraphError, Node, NodeId, PoseGraph, Se2};
use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::path::Path;

/// Records of one file, in file order, each with its 1-based line.
#[derive(Default)]
pub(crate) struct RawGraph {
    pub vertices: Vec<(usize, NodeId, Se2)>,
    pub edges: Vec<(usize, Edge)>,
    pub fixed: Vec<(usize, NodeId)>,
}

impl RawGraph {
    pub fn into_graph(self, path: &Path) -> Result<PoseGraph, IoError> {
        if self.vertices.is_empty() && self.edges.is_empty() {
            return Err(IoError::Empty {
                path: path.to_path_buf(),
            });
        }
        let mut graph = PoseGraph::new();
        if self.vertices.is_empty() {
            for (id, pose) in spanning_tree_poses(&self.edges) {
                graph
                    .add_node(Node {
                        id,
                        pose,
                        stamp_s: None,
                    })
                    .map_err(|e| IoError::graph(path, 0, e))?;
            }
        } else {
            for (line, id, pose) in self.vertices {
                graph
                    .add_node(Node {
                        id,
                        pose,
                        stamp_s: None,
                    })
                    .map_err(|e| IoError::graph(path, line, e))?;
            }
        }
        for (line, edge) in self.edges {
            graph
                .add_edge(edge)
                .map_err(|e| IoError::graph(path, line, e))?;
        }
        for (line, id) in self.fixed {
            graph.fix(id).map_err(|e| match e {
                GraphError::UnknownNode { .. } => IoError::parse(
                    path,
                    line,
                    "id",
                    format!("FIX refers to missing vertex {id}"),
                ),
                other => IoError::graph(path, line, other),
            })?;
        }
        Ok(graph)
    }
}

/// Initial poses for a file without vertices: the smallest id of each
/// connected component sits at its prior (if it has one) or the identity, and
/// every other node is reached by composing edge measurements along a
/// spanning tree that uses as few non-chain edges as possible (a 0-1
/// breadth-first search where chain edges `i <-> i+1` cost 0 and others 1).
/// A file with a complete odometry chain is thus initialised purely by
/// composing the chain, the customary start for manhattan, CSAIL and
/// city10000.
pub(crate) fn spanning_tree_poses(edges: &[(usize, Edge)]) -> Vec<(NodeId, Se2)> {
    let mut ids = BTreeSet::new();
    let mut neighbours: BTreeMap<NodeId, Vec<(NodeId, Se2)>> = BTreeMap::new();
    let mut priors: BTreeMap<NodeId, Se2> = BTreeMap::new();
    for (_, edge) in edges {
        ids.insert(edge.from);
        ids.insert(edge.to);
        if edge.kind == EdgeKind::Prior {
            priors.entry(edge.from).or_insert(edge.measurement);
            continue;
        }
        neighbours
            .entry(edge.from)
            .or_default()
            .push((edge.to, edge.measurement));
        neighbours
            .entry(edge.to)
            .or_default()
            .push((edge.from, edge.measurement.inverse()));
    }
    let is_chain = |a: NodeId, b: NodeId| a.abs_diff(b) == 1;
    // Number of non-chain edges on the best path found so far, and the pose.
    let mut best: BTreeMap<NodeId, (usize, Se2)> = BTreeMap::new();
    for &root in &ids {
        if best.contains_key(&root) {
            continue;
        }
        best.insert(root, (0, priors.get(&root).copied().unwrap_or_default()));
        let mut deque = VecDeque::from([root]);
        while let Some(current) = deque.pop_front() {
            let (cost, world_from_current) = best[&current];
            for &(other, current_from_other) in neighbours.get(&current).into_iter().flatten() {
                let chain = is_chain(current, other);
                let other_cost = cost + usize::from(!chain);
                if best.get(&other).is_some_and(|&(c, _)| c <= other_cost) {
                    continue;
                }
                best.insert(
                    other,
                    (other_cost, world_from_current.compose(&current_from_other)),
                );
                if chain {
                    deque.push_front(other);
                } else {
                    deque.push_back(other);
                }
            }
        }
    }
    best.into_iter().map(|(id, (_, pose))| (id, pose)).collect()
}
