//! The optimisation problem extracted from a [`PoseGraph`]: validated edges
//! with dense endpoint indices, the gauge (which poses are held fixed) and
//! the map from nodes to blocks of unknowns.

use crate::error::SolveError;
use echofield_graph::pose_graph::is_symmetric_positive_definite;
use echofield_graph::{Edge, EdgeKind, NodeId, PoseGraph, Se2};
use nalgebra::Matrix3;

/// One edge with dense node indices. A prior has `from == to`.
#[derive(Clone, Debug)]
pub(crate) struct ProblemEdge {
    pub kind: EdgeKind,
    pub from: usize,
    pub to: usize,
    /// `Z⁻¹`, precomputed.
    pub measurement_inverse: Se2,
    pub measurement: Se2,
    pub information: Matrix3<f64>,
}

impl ProblemEdge {
    pub fn is_prior(&self) -> bool {
        self.kind == EdgeKind::Prior
    }
}

/// A validated problem.
#[derive(Clone, Debug)]
pub(crate) struct Problem {
    pub node_ids: Vec<NodeId>,
    pub edges: Vec<ProblemEdge>,
    /// Block of unknowns of each node, `None` when the node is held fixed.
    pub variable_of: Vec<Option<usize>>,
    /// Node of each block of unknowns.
    pub node_of_variable: Vec<usize>,
}

impl Problem {
    /// Validates `graph` and fixes the gauge: the graph's fixed nodes, and
    /// if it has neither fixed nodes nor priors, its first node.
    pub fn new(graph: &PoseGraph) -> Result<Self, SolveError> {
        if graph.edge_count() == 0 {
            return Err(SolveError::NoEdges);
        }
        let node_ids: Vec<NodeId> = graph.nodes().map(|n| n.id).collect();
        for node in graph.nodes() {
            if !node.pose.is_finite() {
                return Err(SolveError::NonFinitePose { node: node.id });
            }
        }
        let mut edges = Vec::with_capacity(graph.edge_count());
        for (from, to, edge) in graph.indexed_edges() {
            validate_edge(edge)?;
            edges.push(ProblemEdge {
                kind: edge.kind,
                from,
                to,
                measurement_inverse: edge.measurement.inverse(),
                measurement: edge.measurement,
                information: edge.information,
            });
        }
        // Held fixed: the graph's fixed nodes, or the first node when
        // nothing else (fixed node or prior) removes the gauge freedom.
        let mut fixed = vec![false; node_ids.len()];
        for id in graph.fixed() {
            if let Some(i) = graph.index_of(*id) {
                fixed[i] = true;
            }
        }
        let has_prior = edges.iter().any(ProblemEdge::is_prior);
        if !has_prior && graph.fixed().is_empty() {
            fixed[0] = true;
        }
        check_anchored(&node_ids, edges.iter(), &fixed)?;
        let mut variable_of = vec![None; node_ids.len()];
        let mut node_of_variable = Vec::new();
        for (i, _) in fixed.iter().enumerate().filter(|(_, f)| !**f) {
            variable_of[i] = Some(node_of_variable.len());
            node_of_variable.push(i);
        }
        Ok(Self {
            node_ids,
            edges,
            variable_of,
            node_of_variable,
        })
    }

    pub fn variables(&self) -> usize {
        self.node_of_variable.len()
    }

    /// Whether the edges flagged in `used` alone tie every pose to a fixed
    /// node or prior.
    pub fn is_anchored_by(&self, used: &[bool]) -> bool {
        let fixed: Vec<bool> = self.variable_of.iter().map(Option::is_none).collect();
        let edges = self
            .edges
            .iter()
            .zip(used)
            .filter(|(_, u)| **u)
            .map(|(e, _)| e);
        check_anchored(&self.node_ids, edges, &fixed).is_ok()
    }

    /// The off-diagonal block pairs of the normal equations (both endpoints
    /// free), one per relative edge.
    pub fn block_pairs(&self) -> Vec<(usize, usize)> {
        self.edges
            .iter()
            .filter_map(|e| Some((self.variable_of[e.from]?, self.variable_of[e.to]?)))
            .filter(|(a, b)| a != b)
            .collect()
    }
}

/// A finite measurement and a symmetric positive definite information.
/// [`PoseGraph::add_edge`] already enforces both; the solver checks again
/// because its arithmetic depends on them.
fn validate_edge(edge: &Edge) -> Result<(), SolveError> {
    let (from, to) = (edge.from, edge.to);
    if !edge.measurement.is_finite() {
        return Err(SolveError::NonFiniteMeasurement { from, to });
    }
    if !is_symmetric_positive_definite(&edge.information) {
        return Err(SolveError::InformationNotPositiveDefinite { from, to });
    }
    Ok(())
}

/// Every connected component (edges, direction ignored) must hold an
/// anchor: a fixed node, a node with a prior, or the gauge node.
fn check_anchored<'a>(
    node_ids: &[NodeId],
    edges: impl Iterator<Item = &'a ProblemEdge>,
    anchored: &[bool],
) -> Result<(), SolveError> {
    let mut sets = DisjointSets::new(node_ids.len());
    let mut has_anchor = anchored.to_vec();
    for e in edges {
        if e.is_prior() {
            has_anchor[e.from] = true;
        } else {
            sets.union(e.from, e.to);
        }
    }
    let mut root_anchored = vec![false; node_ids.len()];
    for (i, &a) in has_anchor.iter().enumerate() {
        if a {
            root_anchored[sets.find(i)] = true;
        }
    }
    let mut roots: Vec<usize> = (0..node_ids.len()).map(|i| sets.find(i)).collect();
    let unanchored = (0..node_ids.len()).find(|&i| !root_anchored[roots[i]]);
    if let Some(i) = unanchored {
        roots.sort_unstable();
        roots.dedup();
        return Err(SolveError::Disconnected {
            components: roots.len(),
            node: node_ids[i],
        });
    }
    Ok(())
}

/// Union-find with path halving.
struct DisjointSets {
    parent: Vec<usize>,
}

impl DisjointSets {
    fn new(n: usize) -> Self {
        Self {
            parent: (0..n).collect(),
        }
    }

    fn find(&mut self, mut i: usize) -> usize {
        while self.parent[i] != i {
            self.parent[i] = self.parent[self.parent[i]];
            i = self.parent[i];
        }
        i
    }

    fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.parent[ra.max(rb)] = ra.min(rb);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_information_and_measurements() {
        let z = Se2::new(1.0, 0.0, 0.0);
        let good = Edge::new(EdgeKind::Loop, 3, 4, z, Matrix3::identity());
        assert_eq!(validate_edge(&good), Ok(()));
        let indefinite = Matrix3::new(1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        let bad = Edge::new(EdgeKind::Loop, 3, 4, z, indefinite);
        assert_eq!(
            validate_edge(&bad),
            Err(SolveError::InformationNotPositiveDefinite { from: 3, to: 4 })
        );
        let mut nan_info = Matrix3::identity();
        nan_info[(2, 2)] = f64::NAN;
        let bad = Edge::new(EdgeKind::Odometry, 3, 4, z, nan_info);
        assert!(matches!(
            validate_edge(&bad),
            Err(SolveError::InformationNotPositiveDefinite { .. })
        ));
        let bad = Edge::new(
            EdgeKind::Odometry,
            5,
            6,
            Se2::new(f64::NAN, 0.0, 0.0),
            Matrix3::identity(),
        );
        assert_eq!(
            validate_edge(&bad),
            Err(SolveError::NonFiniteMeasurement { from: 5, to: 6 })
        );
    }
}
