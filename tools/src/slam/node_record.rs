//! The record of one graph node as a run reports it (`report.json` →
//! `nodes`, `poses.csv`): poses are `world_from_vehicle`, stamps in seconds.

use echofield_graph::{NodeId, Se2};
use serde::Serialize;
use std::ops::Range;

/// One node of the graph: a sonar rotation at its central (reference) time.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NodeRecord {
    /// Node id in the graph (0, 1, 2, ...).
    pub id: NodeId,
    /// Index of the rotation in the mission's rotation list.
    pub rotation_index: usize,
    /// The rotation's reference (central) time, s.
    pub stamp_s: f64,
    /// The rotation's beams: indices into `mission.beams`.
    pub beams: Range<usize>,
    /// `world_from_vehicle` from dead reckoning at `stamp_s`.
    pub dead_reckoning: Se2,
    /// `world_from_vehicle` after the final optimisation.
    pub optimised: Se2,
    /// Ground truth at `stamp_s` (ground-truth frame), when covered.
    pub ground_truth: Option<Se2>,
    /// Points of `S_k` (0 when the rotation gave too few ranges).
    pub scan_points: usize,
    /// The rotation spans a gap in the DVL data (not matched).
    pub in_dvl_gap: bool,
}
