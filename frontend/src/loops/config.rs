//! Parameters of loop closing: candidate gating, match checks and mutual
//! consistency (TOML section `[loops]`), and the constants that were keys
//! of this section before issue 36, each with the reason it is fixed.

use crate::config_check::{check_positive_window, check_range, check_window};
use crate::error::FrontendError;
use crate::matcher::MatchGate;
use crate::matcher::SearchWindow as Window;
use serde::{Deserialize, Serialize};

/// When none of a node's candidates can be searched in a window within
/// `gate.max_window`, this many of them (the best-overlapping) are searched
/// over `gate.max_window` at once instead of being deferred. One: a first
/// contact with a place seen long ago needs one loop to shrink the
/// relative uncertainty of the others, which are then searched in their
/// own windows; each wide search costs a full search of the largest window.
pub const WIDE_SEARCHES_PER_NODE: usize = 1;

/// A mission-pass candidate whose predicted overlap is at least this, but
/// whose match fails the quality gate or finds nothing, is searched once
/// more over a window `escalate_window_factor` times larger (module doc of
/// `checks`): where the estimate says two scans overlap almost entirely,
/// a match that lands on nothing says the prior is further off than its
/// covariance. 0.8 keeps the retry to those near-certain overlaps.
pub const ESCALATE_MIN_PREDICTED_OVERLAP: f64 = 0.8;

/// A match that ends within this fraction of the window's half-width from
/// its edge is rejected (`window_edge`): the true peak may lie outside the
/// searched window. 5%: about one search step of the smallest windows.
pub const WINDOW_EDGE_FRACTION: f64 = 0.05;

/// Mutual consistency: two loops are consistent when the cycle they close
/// with the dead-reckoning motions between their ends has a squared
/// Mahalanobis distance at most this: 11.34, the 99% quantile of χ² with
/// 3 degrees of freedom (a test level, not a tuning value).
pub const CONSISTENCY_MAX_CHI2: f64 = 11.34;

/// Correlation `ρ` (0-1) assumed between the errors of loops that share a
/// node, applied to densified loops: a densified loop `(j, k)` enters the
/// graph with its covariance multiplied by the design effect
/// `1 + ρ·(m_j + m_k − 2)`, `m_x` the accepted loops at node `x` (module
/// doc of `slam::loops` in the tools crate). 1: the densified loops at a
/// node match the same walls from nearly the same place, so together they
/// count about as much as one loop.
pub const DENSIFY_CORRELATION: f64 = 1.0;

/// Smallest predicted overlap (as for `min_predicted_overlap`) of a pair
/// matched by densification: 0.4, the ground-truth overlap above which the
/// evaluation counts a pair for recall (`evaluation.recall_min_overlap`).
pub const DENSIFY_MIN_PREDICTED_OVERLAP: f64 = 0.4;

/// Densification considers a pair only when its search window (`n_sigma`
/// standard deviations of the relative uncertainty) is within these
/// half-widths `[x_m, y_m, theta_rad]` (2 m, 2 m, 6°); it then climbs
/// within `gate.min_window` of the estimate. A climb finds the nearest
/// maximum, which is the right one only when the estimate is already
/// within a few cells of a wall's width of it.
pub fn densify_max_window() -> Window {
    Window::new(2.0, 2.0, 6.0_f64.to_radians())
}

/// Loop-closure candidates, their checks and their mutual consistency.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LoopConfig {
    /// Look for loop closures at all. Default true.
    pub enabled: bool,
    /// Two nodes are loop candidates only when at least this many
    /// rotations apart (closer pairs are linked by the sequential chain
    /// anyway). Default 10 (about 2.3 min at 13.8 s per rotation).
    pub min_separation_nodes: usize,
    /// Smallest predicted overlap of a candidate: the fraction of the
    /// points of `S_k`, placed at the current estimate of `j_from_k`, that
    /// lie within the sonar footprint of node `j` (the range of its
    /// farthest returns). Default 0.5; a larger gate never tries the revisits
    /// whose best predicted overlap falls short (measured: EXPERIMENTS.md §
    /// Loop closures).
    pub min_predicted_overlap: f64,
    /// At most this many candidates are matched per new node, the ones
    /// with the largest predicted overlap first. Default 4. It sets the recall
    /// over node pairs against time; `densify` matches the overlapping pairs
    /// left over after the mission (measured: EXPERIMENTS.md § Loop closures).
    pub max_candidates_per_node: usize,
    /// The search window and acceptance gate of a loop match
    /// ([`MatchGate`], `[loops.gate]`; defaults [`MatchGate::loops`]). A
    /// candidate whose window would exceed `gate.max_window` on any axis is
    /// *deferred*: tried again when the graph has become more certain
    /// (after other loops are accepted), and reported as `deferred` if it
    /// never qualifies; except for the first [`WIDE_SEARCHES_PER_NODE`] of
    /// them per node, which are searched over `gate.max_window` at once.
    pub gate: MatchGate,
    /// A candidate of the mission pass (not a wide search, not
    /// densification) whose predicted overlap is at least
    /// [`ESCALATE_MIN_PREDICTED_OVERLAP`] but whose match fails the quality
    /// gate, or finds nothing, is searched once more over a window this
    /// many times larger per axis (at most `gate.max_window`); the second
    /// match replaces the first only when it passes the individual checks.
    /// Where the estimate says two scans overlap almost entirely, a match
    /// that lands on nothing suggests the prior is further off than its
    /// covariance says: dead-reckoning errors in sharp turns are larger
    /// than its noise model. 1 disables it. Default 3.
    pub escalate_window_factor: f64,
    /// Matches whose fraction of points inside the image is below this are
    /// rejected (`quality`), as are those below `gate.min_mean_intensity`.
    /// Default 0.75. Nearly every loop that the quality gate rejects on the
    /// simulated marina fails this test, not the intensity one, and most of
    /// them are right; lowering it trades accuracy for recall (measured:
    /// EXPERIMENTS.md § Loop closures).
    pub min_inside_fraction: f64,
    /// Matches whose standard deviation exceeds `[x_m, y_m, theta_rad]` on
    /// any axis, or whose covariance is not positive definite, are
    /// rejected (`covariance`). Default 0.5 m, 0.5 m, 3°.
    #[serde(with = "crate::matcher::window_key")]
    pub max_sigma: Window,
    /// Model error added to dead-reckoning motions (in search windows and
    /// in the consistency test) that the EKF's covariance does not hold
    /// (DVL scale error, a wandering compass error): a standard deviation
    /// of this fraction of the distance travelled, per axis, plus
    /// `drift_heading_sigma_rad` in heading. Default 0.02.
    pub drift_fraction: f64,
    /// The heading standard deviation of that model error (and its lever
    /// arm over the distance between the two poses), rad. Default 2°.
    ///
    /// Not a config key (`#[serde(skip)]`): derived from
    /// `dead_reckoning.heading_bias_sigma_rad` (`SlamConfig::derive` in the
    /// tools crate), the same wandering compass error.
    #[serde(skip)]
    pub drift_heading_sigma_rad: f64,
    /// After the mission, match every overlapping pair not yet examined
    /// whose relative pose the optimised estimate already knows well
    /// (loop densification, `LoopCloser::densify` (tools crate, `slam::loops`)):
    /// loops between all the rotations of a revisited place, not only the
    /// `max_candidates_per_node` best. A pair costs a local climb instead of a
    /// search of the window. Default true: it buys recall over node pairs for
    /// time, at the same ATE, provided the densified loops are down-weighted
    /// ([`DENSIFY_CORRELATION`]) and held to `densify_max_sigma` (measured:
    /// EXPERIMENTS.md § Loop densification).
    pub densify: bool,
    /// `max_sigma` for the densification pairs: densified matches whose
    /// standard deviation exceeds `[x_m, y_m, theta_rad]` on any axis are
    /// rejected (`covariance`). Default 0.35 m, 0.35 m, 3°: the marina's false
    /// positives are near misses from matches whose σ is a few decimetres along
    /// a quay (measured: EXPERIMENTS.md § Loop densification).
    #[serde(with = "crate::matcher::window_key")]
    pub densify_max_sigma: Window,
    /// Partial loops: a densified match that fails `densify_max_sigma`
    /// along one horizontal direction only (its covariance's largest xy
    /// axis; the smallest and θ pass) is accepted as a *partial* loop
    /// instead of being rejected (`covariance`). Such a match sees walls of
    /// one direction, a quay along its length: it places `S_k` well across
    /// them and in heading, but not along them, where its peak is wherever
    /// the score surface happens to be flattest. The loop's measurement
    /// takes that one component from the estimate (the prior), and its
    /// covariance is the match's marginal across it with a standard
    /// deviation of [`PARTIAL_SIGMA_M`](crate::loops::checks::PARTIAL_SIGMA_M)
    /// along it: the "solution remapping" of degenerate directions (Zhang,
    /// Kaess and Singh, ICRA 2016). The edge then constrains the two
    /// components the sonar measured and nothing else. Default true.
    ///
    /// The true-positive verdict still compares the whole measurement with
    /// the ground truth, so a partial loop counts as false when the
    /// estimate is off by more than 0.5 m along the wall, although its own
    /// components are right; `report.json` counts partial loops and their
    /// constrained-component verdicts apart (`loop_evaluation`).
    ///
    /// Partial loops while the mission runs, whose prior is the dead
    /// reckoning's, were false more often and are not made (measured:
    /// EXPERIMENTS.md § Loop densification).
    pub densify_partial: bool,
    /// Loop sparsification ([`cover`](crate::loops::cover)), metres
    /// of track travelled by dead reckoning: a pair `(j, k)` is neither
    /// matched nor kept when an accepted loop joins a node within this
    /// distance along the track of `j` to one within it of `k`. It bounds
    /// the loops per metre of track, so that slower vehicles (more
    /// rotations per place) and long missions do not match every pair of
    /// every revisit; with it, densification also takes at most
    /// `3 · max_candidates_per_node` pairs per node. 0 keeps every pair.
    /// Default 0: the recall over node
    /// pairs that the evaluation reports (and the St Pere replay's tests
    /// require) counts every overlapping pair; long or slow missions set
    /// about 2 m (`echofield bench-long` uses `--cover-spacing-m`).
    pub cover_spacing_m: f64,
    /// Whether the clique's loops (the mission pass's), too, enter the
    /// final graph with the design effect of their place,
    /// `1 + ρ·(m_j + m_k − 2)` ([`DENSIFY_CORRELATION`],
    /// [`places`](crate::loops::places)), as the densified ones always do.
    /// Thresholded scans make loops that share a place share an error:
    /// the loops between two places measure their displacement long by
    /// about the same amount (in simulated point sets, from the far part
    /// of the bands, which grows with range), which independent loops
    /// would pile up into a stretched map. Applied from the end of the
    /// mission pass (after densification, before the final solve);
    /// during the pass the clique's loops enter as matched, so that the
    /// running estimate, which sets the next loops' priors and their
    /// consistency, keeps their full weight.
    ///
    /// Not a config key (`#[serde(skip)]`): derived from the data, true
    /// for binary (scan-only) intensities, false otherwise (the pipeline's
    /// scan-only preparation in the tools crate; measured: EXPERIMENTS.md
    /// § Where the loops' excess length comes from).
    #[serde(skip)]
    pub shared_place_errors: bool,
}

impl Default for LoopConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            min_separation_nodes: 10,
            min_predicted_overlap: 0.5,
            max_candidates_per_node: 4,
            gate: MatchGate::loops(),
            escalate_window_factor: 3.0,
            min_inside_fraction: 0.75,
            max_sigma: Window::new(0.5, 0.5, 3.0_f64.to_radians()),
            drift_fraction: 0.02,
            drift_heading_sigma_rad: 2.0_f64.to_radians(),
            densify: true,
            densify_max_sigma: Window::new(0.35, 0.35, 3.0_f64.to_radians()),
            densify_partial: true,
            cover_spacing_m: 0.0,
            shared_place_errors: false,
        }
    }
}

impl LoopConfig {
    /// Checks every key; errors name it by its TOML path
    /// (`loops.gate.max_window[0] (x_m)`).
    pub fn validate(&self) -> Result<(), FrontendError> {
        if self.min_separation_nodes < 2 {
            return Err(FrontendError::config(
                "loops.min_separation_nodes",
                "must be at least 2 (consecutive nodes are matched sequentially)",
            ));
        }
        check_range(
            "loops.min_predicted_overlap",
            self.min_predicted_overlap,
            0.0,
            1.0,
        )?;
        if self.max_candidates_per_node == 0 {
            return Err(FrontendError::config(
                "loops.max_candidates_per_node",
                "must be at least 1 (set `enabled = false` to close no loops)",
            ));
        }
        self.gate.validate("loops")?;
        check_range("loops.cover_spacing_m", self.cover_spacing_m, 0.0, 1000.0)?;
        check_range(
            "loops.escalate_window_factor",
            self.escalate_window_factor,
            1.0,
            100.0,
        )?;
        check_range(
            "loops.min_inside_fraction",
            self.min_inside_fraction,
            0.0,
            1.0,
        )?;
        check_window("loops.max_sigma", &self.max_sigma)?;
        check_positive_window("loops.max_sigma", &self.max_sigma)?;
        check_range("loops.drift_fraction", self.drift_fraction, 0.0, 10.0)?;
        check_window("loops.densify_max_sigma", &self.densify_max_sigma)?;
        check_positive_window("loops.densify_max_sigma", &self.densify_max_sigma)?;
        check_range(
            "loops.drift_heading_sigma_rad",
            self.drift_heading_sigma_rad,
            0.0,
            std::f64::consts::PI,
        )?;
        Ok(())
    }
}
