//! What became of each match: the records of sequential matches and loop
//! candidates, and why a match was not used. `from`/`to` are node ids,
//! poses are `from_from_to` in the `from` node's vehicle frame (x, y in
//! metres, θ in radians), covariances over `(x, y, θ)`.

use crate::matcher::{MatchQuality, SearchWindow};
use echofield_graph::{NodeId, Se2};
use nalgebra::Matrix3;
use serde::Serialize;

/// The outcome of one sequential match `S_k` vs `I_{k-1}`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SequentialRecord {
    pub from: NodeId,
    pub to: NodeId,
    /// Dead-reckoning `from_from_to` (the prior) and its covariance.
    pub prior: Se2,
    pub prior_covariance: Matrix3<f64>,
    pub window: SearchWindow,
    /// The matched `from_from_to`, when the matcher found one.
    pub matched: Option<Se2>,
    /// The relative pose of the sequential edge: the information-weighted
    /// mean ([`Fusion::InformationWeighted`](crate::matcher::symmetric::Fusion))
    /// of `matched` and the inverse of the reverse match (`S_from` vs
    /// `I_to`) when they agree, else `matched`.
    pub measurement: Option<Se2>,
    pub quality: Option<MatchQuality>,
    pub covariance: Option<Matrix3<f64>>,
    /// The symmetric match, when `sequential.symmetric` is set.
    pub reverse: Option<ReverseCheck>,
    /// Squared Mahalanobis distance between match and prior.
    pub prior_chi2: Option<f64>,
    /// Whether a sequential edge was added.
    pub accepted: bool,
    /// Why not, when not.
    pub rejected_by: Option<RejectReason>,
    /// The matcher's reason for "no match", when it gave one.
    pub no_match: Option<String>,
}

/// Why a loop candidate (or a sequential match) was not used.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RejectReason {
    /// The search window stayed too large (the relative uncertainty of the
    /// two nodes never became small enough); never matched.
    Deferred,
    /// One of the scans has too few points, or an image is empty.
    NoData,
    /// One of the rotations spans a gap in the DVL data: its scan and
    /// image are distorted by the extrapolated motion, so it is not
    /// matched.
    DvlGap,
    /// The matcher found no pose in the window with any overlap.
    NoMatch,
    /// Mean intensity, inside fraction or second-peak ratio out of bounds.
    Quality,
    /// The match covariance is not positive definite or too large.
    Covariance,
    /// The match lies at the edge of its search window.
    WindowEdge,
    /// The match disagrees with its prior beyond the chi-square gate
    /// (sequential matches only).
    Prior,
    /// `S_j` vs `I_k` found nothing or disagrees with `S_k` vs `I_j`.
    ReverseMismatch,
    /// Passed every check on its own but is not in the maximum set of
    /// mutually consistent loops.
    Inconsistent,
    /// Accepted into the graph, but switched off by the final solve
    /// (`echofield_backend::optimize_robust`): it disagrees with the rest of
    /// the graph, alone and together with the other switched-off loops.
    RobustKernel,
}

impl RejectReason {
    /// The mission pass rejected the pair for how it was searched, not for
    /// what the match showed: the window was too large (`Deferred`), the
    /// peak lay at its edge (`WindowEdge`) or the match was unsure along
    /// some direction (`Covariance`). Densification matches such a pair
    /// again from the optimised estimate, where the window is small and a
    /// match blind along one direction can be a partial loop. A match that
    /// failed on its quality, its symmetric match or the mutual consistency
    /// is evidence against the pair and is not retried.
    pub fn densification_retries(self) -> bool {
        matches!(
            self,
            RejectReason::Deferred | RejectReason::WindowEdge | RejectReason::Covariance
        )
    }
}

/// The symmetric check of a loop candidate: `S_j` matched against `I_k`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReverseCheck {
    /// The matched `k_from_j`, when the matcher found one.
    pub matched: Option<Se2>,
    /// Its quality, evaluated on the raster
    /// ([`QualityModel::Raster`](crate::matcher::QualityModel::Raster)).
    pub quality: Option<MatchQuality>,
    /// `|t|` and `|θ|` of `forward ⊕ reverse`, which is the identity when
    /// both matches agree; `None` without a reverse match.
    pub translation_diff_m: Option<f64>,
    pub rotation_diff_rad: Option<f64>,
}

/// One loop-closure candidate: `S_to` matched against `I_from`
/// (`from < to`, `from` the older node).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LoopRecord {
    pub from: NodeId,
    pub to: NodeId,
    /// Index of the newest node when the candidate was examined (equals
    /// `to` unless it was deferred and retried later).
    pub examined_at: NodeId,
    /// Prior `from_from_to` from the current estimate at that time.
    pub prior: Se2,
    /// Covariance of the prior (relative uncertainty of the two nodes).
    pub prior_covariance: Matrix3<f64>,
    /// Predicted overlap (see `LoopConfig::min_predicted_overlap`).
    pub predicted_overlap: f64,
    /// The searched half-widths around the prior.
    pub window: SearchWindow,
    /// The matched `from_from_to` (`S_to` vs `I_from`).
    pub matched: Option<Se2>,
    /// The relative pose a loop edge would carry: the mean of `matched`
    /// and the inverse of the reverse match when that one agrees (the two
    /// matches' biases, which depend on the viewpoint, largely cancel),
    /// else `matched`. Evaluated against ground truth.
    pub measurement: Option<Se2>,
    /// `s(x*)` of eq. (5).
    pub score: Option<f64>,
    pub quality: Option<MatchQuality>,
    /// Covariance of `measurement` `(x, y, θ)` (before the `min_sigma`
    /// floor): the match's, or for a partial loop the match's marginal
    /// across `unconstrained_direction` with a standard deviation of
    /// [`PARTIAL_SIGMA_M`](crate::loops::checks::PARTIAL_SIGMA_M)
    /// along it.
    pub covariance: Option<Matrix3<f64>>,
    /// `S_from` vs `I_to`, when the forward match passed its checks.
    pub reverse: Option<ReverseCheck>,
    /// Whether the loop is an edge of the final graph.
    pub accepted: bool,
    /// The first check that failed, for rejected candidates.
    pub rejected_by: Option<RejectReason>,
    /// Found by the densification pass after the mission
    /// (`LoopConfig::densify`), not while the mission ran.
    pub densified: bool,
    /// For a *partial* loop (`LoopConfig::densify_partial`), the unit
    /// direction `[x, y]` in `from`'s frame along which the match could not
    /// place `S_to` (a wall seen along its length): `measurement` takes
    /// that component from `prior` and carries no information along it.
    /// `None` for a loop constrained on every axis.
    pub unconstrained_direction: Option<[f64; 2]>,
    /// The matcher's reason for "no match", when it gave one.
    pub no_match: Option<String>,
    /// Weight of the edge under the robust kernel at the final solution
    /// (1 = fully trusted), for loops in the graph.
    pub robust_weight: Option<f64>,
    /// Ground-truth `from_from_to`, when the mission has ground truth.
    pub ground_truth: Option<Se2>,
    /// Error of `matched` against the ground truth: translation (m) and
    /// rotation (deg) of `ground_truth⁻¹ ⊕ matched`.
    pub gt_error_m: Option<f64>,
    pub gt_error_deg: Option<f64>,
    /// `matched` within the true-positive tolerances
    /// (`evaluation.true_positive_*`).
    pub true_positive: Option<bool>,
    /// Ground-truth scan overlap of the pair (see `EvaluationConfig`).
    pub gt_overlap: Option<f64>,
}
