//! Why a solve failed.

use crate::config::ConfigError;
use echofield_graph::NodeId;
use thiserror::Error;

/// A failed solve. The graph's poses are left unchanged.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum SolveError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error("the graph has no edges: nothing constrains the poses")]
    NoEdges,
    /// Some nodes are not linked, through edges, to a fixed node, a prior or
    /// (when the graph has neither) the first node; `node` is one of them.
    #[error(
        "the graph is disconnected ({components} components): node {node} is not linked to a fixed node or prior"
    )]
    Disconnected { components: usize, node: NodeId },
    #[error("node {node}: pose is not finite")]
    NonFinitePose { node: NodeId },
    #[error("edge {from} -> {to}: measurement is not finite")]
    NonFiniteMeasurement { from: NodeId, to: NodeId },
    #[error("edge {from} -> {to}: information matrix is not symmetric positive definite")]
    InformationNotPositiveDefinite { from: NodeId, to: NodeId },
    /// The normal equations could not be factorised: the pose of `node` is
    /// not determined (e.g. every edge to it was down-weighted to zero by a
    /// robust kernel, or the information is numerically degenerate).
    #[error("the linear system is not positive definite at node {node}")]
    SystemNotPositiveDefinite { node: NodeId },
    /// A residual or cost became infinite or NaN during the iterations.
    #[error("the cost became non-finite at iteration {iteration}")]
    NonFiniteCost { iteration: usize },
    #[error("sparse linear algebra failed: {0}")]
    Linear(String),
}
