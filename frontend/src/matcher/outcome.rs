//! What a match returns: the pose, score, quality and covariance, or why
//! there is no match.

use echofield_graph::Se2;
use nalgebra::Matrix3;
use serde::Serialize;

/// Why a scan could not be matched.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum NoMatchReason {
    /// The scan has fewer points than `min_points`.
    TooFewPoints { points: usize, required: usize },
    /// The image holds no echo at all.
    EmptyImage,
    /// No pose in the window puts a single point on an echo (the prior
    /// places the scan outside the image, or they do not overlap).
    NoOverlap,
}

impl std::fmt::Display for NoMatchReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NoMatchReason::TooFewPoints { points, required } => {
                write!(
                    f,
                    "the scan has {points} points, at least {required} are needed"
                )
            }
            NoMatchReason::EmptyImage => write!(f, "the acoustic image holds no echo"),
            NoMatchReason::NoOverlap => {
                write!(
                    f,
                    "no pose in the search window puts any scan point on an echo"
                )
            }
        }
    }
}

/// Normalised quality metrics of a match, for validation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MatchQuality {
    /// `s(x*) / N`: mean image intensity under the points, 0-1.
    pub mean_intensity: f64,
    /// Fraction of the points inside the image's extent at `x*`.
    pub inside_fraction: f64,
    /// Scan points used (after thinning).
    pub points: usize,
    /// RMS residual of the quadratic fit of the surface, relative to its
    /// range on the fit lattice (0 = perfectly quadratic peak).
    pub surface_fit_residual: f64,
}

/// Diagnostics of the search.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MatchStats {
    /// Angular step of the coarse search, radians.
    pub angle_step_rad: f64,
    /// Branch-and-bound nodes evaluated (both searches).
    pub search_nodes: usize,
}

/// A successful match.
#[derive(Clone, Debug, PartialEq)]
pub struct MatchResult {
    /// `x*`: the pose of the scan frame in the image frame.
    pub image_from_scan: Se2,
    /// The peak found on the searched image, which the score and the
    /// quality are read at; `image_from_scan` is it moved by the last
    /// step's fit on the image's pose-fit raster (by at most half a
    /// lattice step; the same pose when the image has none, see
    /// `ImageConfig::pose_fit`).
    pub searched_peak: Se2,
    /// `s` of eq. (5) at `searched_peak` (sum over the used points,
    /// bilinear lookup).
    pub score: f64,
    pub quality: MatchQuality,
    /// Covariance of `(x, y, θ)` of `image_from_scan`, m² and rad².
    pub covariance: Matrix3<f64>,
    /// The best pose of the coarse search (before the sub-cell fit).
    pub coarse: Se2,
    pub stats: MatchStats,
}

/// The outcome of [`match_scan`](crate::matcher::match_scan).
#[derive(Clone, Debug, PartialEq)]
pub enum MatchOutcome {
    Match(Box<MatchResult>),
    NoMatch { reason: NoMatchReason },
}

impl MatchOutcome {
    pub fn matched(&self) -> Option<&MatchResult> {
        match self {
            MatchOutcome::Match(m) => Some(m),
            MatchOutcome::NoMatch { .. } => None,
        }
    }
}
