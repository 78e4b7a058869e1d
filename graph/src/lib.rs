//! # echofield-graph
//!
//! The shared vocabulary of echofield: rigid transforms of the plane
//! ([`Se2`], on nalgebra), pose graphs ([`PoseGraph`], on petgraph), the g2o
//! and TORO file formats ([`io`]), trajectory export (TUM, CSV, KITTI-style
//! rows), the optimised trajectory at the navigation's rate
//! ([`corrected`]) and seeded synthetic pose graphs for tests and
//! benchmarks ([`synthetic`]).
//!
//! ```
//! use echofield_graph::Se2;
//! let world_from_a = Se2::new(1.0, 2.0, 0.5);
//! let world_from_b = Se2::new(3.0, -1.0, -2.0);
//! let a_from_b = world_from_a.between(&world_from_b);
//! let back = world_from_a.compose(&a_from_b);
//! assert!((back.to_vector() - world_from_b.to_vector()).norm() < 1e-12);
//! ```

pub mod corrected;
pub mod io;
pub mod pose_graph;
pub mod se2;
pub mod synthetic;

pub use pose_graph::{Edge, EdgeKind, GraphError, Node, NodeId, PoseGraph};
pub use se2::{Se2, wrap_angle};
