//! Parameters of loop closing: candidate gating, match checks and mutual
//! consistency (TOML section `[loops]`).

use crate::config_check::{check_positive_window, check_range, check_window, check_window_order};
use crate::error::FrontendError;
use crate::matcher::SearchWindow as Window;
use serde::{Deserialize, Serialize};

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
    /// Search half-width in standard deviations of the relative
    /// uncertainty of the two nodes (propagated along the most certain path
    /// of the current graph). Default 3.
    pub n_sigma: f64,
    /// Smallest search half-widths `[x_m, y_m, theta_rad]`. Default 0.5 m,
    /// 0.5 m, 3°.
    #[serde(with = "crate::matcher::window_key")]
    pub min_window: Window,
    /// The largest search half-widths. A candidate whose window would
    /// exceed this on any axis is *deferred*: tried again when the graph
    /// has become more certain (after other loops are accepted), and
    /// reported as `deferred` if it never qualifies; except for the first
    /// `wide_searches_per_node` of them per node, which are searched over
    /// this window at once. Default 10 m, 10 m, 10°.
    #[serde(with = "crate::matcher::window_key")]
    pub max_window: Window,
    /// When none of a node's candidates can be searched in a window within
    /// `max_window` (a first contact with a place seen long ago, when
    /// dead-reckoning drift makes the relative uncertainty large), this
    /// many of them, the best-overlapping, are searched over `max_window`
    /// at once instead of being deferred. Each costs a few milliseconds.
    /// Default 1.
    pub wide_searches_per_node: usize,
    /// A candidate of the mission pass (not a wide search, not
    /// densification) whose predicted overlap is at least
    /// `escalate_min_predicted_overlap` but whose match fails the quality
    /// gate, or finds nothing, is searched once more over a window this
    /// many times larger per axis (at most `max_window`); the second match
    /// replaces the first only when it passes the individual checks. Where
    /// the estimate says two scans overlap almost entirely, a match that
    /// lands on nothing suggests the prior is further off than its
    /// covariance says: dead-reckoning errors in sharp turns are larger
    /// than its noise model (up to 1.6 m per rotation on the real St Pere
    /// navigation). 1 disables it. Default 3.
    pub escalate_window_factor: f64,
    /// See `escalate_window_factor`. Default 0.8.
    pub escalate_min_predicted_overlap: f64,
    /// Matches whose mean image intensity under the points is below this
    /// (`MatchQuality::mean_intensity`, 0-1) are rejected (`quality`).
    /// Default 0.30, set with the images' off-axis suppression
    /// (`image.off_axis`), which lowers the intensity around the walls that a
    /// slightly distorted scan lands on (measured: EXPERIMENTS.md § Loop
    /// closures).
    pub min_mean_intensity: f64,
    /// ... or whose fraction of points inside the image is below this.
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
    /// Smallest standard deviations of a loop edge `[x_m, y_m,
    /// theta_rad]` (the covariance of the score surface is inflated to at
    /// least these). Default 0.05 m, 0.05 m, 0.5°.
    #[serde(with = "crate::matcher::window_key")]
    pub min_sigma: Window,
    /// A match that ends within this fraction of the window's half-width
    /// from its edge is rejected (`window_edge`): the true peak may lie
    /// outside the searched window. Default 0.05.
    pub window_edge_fraction: f64,
    /// Symmetric check: `S_j` is matched against `I_k` by a climb from the
    /// inverse of the forward match to the nearest maximum, within this
    /// window `[x_m, y_m, theta_rad]`.
    /// Default 0.5 m, 0.5 m, 3°.
    #[serde(with = "crate::matcher::window_key")]
    pub reverse_window: Window,
    /// The forward match and the inverse of the reverse match must agree
    /// to within this distance (m) ... Default 0.6. Two right matches of one
    /// pair disagree by a few decimetres (the strongest echo of a wall seen
    /// from two places is not the same spot), and often by just over 0.5 m; a
    /// looser limit keeps the near misses (measured: EXPERIMENTS.md § Loop
    /// closures).
    pub reverse_max_translation_m: f64,
    /// ... and this angle (rad). Default 2°.
    pub reverse_max_rotation_rad: f64,
    /// Mutual consistency: two loops are consistent when the cycle they
    /// close with the dead-reckoning motions between their ends has a
    /// squared Mahalanobis distance below this (3 degrees of freedom;
    /// 11.34 is the 99% quantile). Default 11.34.
    pub consistency_max_chi2: f64,
    /// Model error added to dead-reckoning motions (in search windows and
    /// in the consistency test) that the EKF's covariance does not hold
    /// (DVL scale error, a wandering compass error): a standard deviation
    /// of this fraction of the distance travelled, per axis. Default 0.02.
    pub drift_fraction: f64,
    /// ... plus this heading standard deviation (and its lever arm over
    /// the distance between the two poses), rad. Default 2°.
    pub drift_heading_sigma_rad: f64,
    /// After the mission, match every overlapping pair not yet examined
    /// whose relative pose the optimised estimate already knows well
    /// (loop densification, `LoopCloser::densify` (tools crate, `slam::loops`)):
    /// loops between all the rotations of a revisited place, not only the
    /// `max_candidates_per_node` best. A pair costs a local climb instead of a
    /// search of the window. Default true: it buys recall over node pairs for
    /// time, at the same ATE, provided the densified loops are down-weighted
    /// (`densify_correlation`) and held to `densify_max_sigma` (measured:
    /// EXPERIMENTS.md § Loop densification).
    pub densify: bool,
    /// Densification considers a pair only when its search window
    /// (`n_sigma` standard deviations of the relative uncertainty) is
    /// within these half-widths `[x_m, y_m, theta_rad]`; it then climbs
    /// within `min_window` of the estimate. Default 2 m, 2 m, 6°.
    #[serde(with = "crate::matcher::window_key")]
    pub densify_max_window: Window,
    /// Correlation `ρ` (0-1) assumed between the errors of loops that share
    /// a node, applied to densified loops: a densified loop `(j, k)` enters
    /// the graph with its covariance multiplied by the design effect
    /// `1 + ρ·(m_j + m_k − 2)`, `m_x` the accepted loops at node `x`
    /// (module doc of `slam::loops` in the tools crate). Default 1.0: the densified
    /// loops at a node count together about as much as one loop.
    pub densify_correlation: f64,
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
    /// Smallest predicted overlap (as for `min_predicted_overlap`) of a
    /// pair matched by `densify`. Default 0.4, the ground-truth overlap
    /// above which the evaluation counts a pair for recall
    /// (`evaluation.recall_min_overlap`). The candidates while the mission
    /// runs keep `min_predicted_overlap`: lowering that one as well cost
    /// accuracy on the St Pere replay (measured: EXPERIMENTS.md § Loop
    /// densification).
    pub densify_min_predicted_overlap: f64,
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
}

impl Default for LoopConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            min_separation_nodes: 10,
            min_predicted_overlap: 0.5,
            max_candidates_per_node: 4,
            n_sigma: 3.0,
            min_window: Window::new(0.5, 0.5, 3.0_f64.to_radians()),
            max_window: Window::new(10.0, 10.0, 10.0_f64.to_radians()),
            wide_searches_per_node: 1,
            escalate_window_factor: 3.0,
            escalate_min_predicted_overlap: 0.8,
            min_mean_intensity: 0.30,
            min_inside_fraction: 0.75,
            max_sigma: Window::new(0.5, 0.5, 3.0_f64.to_radians()),
            min_sigma: Window::new(0.05, 0.05, 0.5_f64.to_radians()),
            window_edge_fraction: 0.05,
            reverse_window: Window::new(0.5, 0.5, 3.0_f64.to_radians()),
            reverse_max_translation_m: 0.6,
            reverse_max_rotation_rad: 2.0_f64.to_radians(),
            consistency_max_chi2: 11.34,
            drift_fraction: 0.02,
            drift_heading_sigma_rad: 2.0_f64.to_radians(),
            densify: true,
            densify_max_window: Window::new(2.0, 2.0, 6.0_f64.to_radians()),
            densify_correlation: 1.0,
            densify_max_sigma: Window::new(0.35, 0.35, 3.0_f64.to_radians()),
            densify_partial: true,
            densify_min_predicted_overlap: 0.4,
            cover_spacing_m: 0.0,
        }
    }
}

impl LoopConfig {
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
        check_range(
            "loops.densify_min_predicted_overlap",
            self.densify_min_predicted_overlap,
            0.0,
            1.0,
        )?;
        if self.max_candidates_per_node == 0 {
            return Err(FrontendError::config(
                "loops.max_candidates_per_node",
                "must be at least 1 (set `enabled = false` to close no loops)",
            ));
        }
        check_range("loops.n_sigma", self.n_sigma, 0.1, 100.0)?;
        check_range("loops.cover_spacing_m", self.cover_spacing_m, 0.0, 1000.0)?;
        check_range(
            "loops.escalate_window_factor",
            self.escalate_window_factor,
            1.0,
            100.0,
        )?;
        check_range(
            "loops.escalate_min_predicted_overlap",
            self.escalate_min_predicted_overlap,
            0.0,
            1.0,
        )?;
        check_window("loops.min_window", &self.min_window)?;
        check_window("loops.max_window", &self.max_window)?;
        check_positive_window("loops.max_window", &self.max_window)?;
        check_window_order(
            "loops.min_window",
            &self.min_window,
            "loops.max_window",
            &self.max_window,
        )?;
        check_range(
            "loops.min_mean_intensity",
            self.min_mean_intensity,
            0.0,
            1.0,
        )?;
        check_range(
            "loops.min_inside_fraction",
            self.min_inside_fraction,
            0.0,
            1.0,
        )?;
        check_window("loops.max_sigma", &self.max_sigma)?;
        check_window("loops.min_sigma", &self.min_sigma)?;
        check_range(
            "loops.window_edge_fraction",
            self.window_edge_fraction,
            0.0,
            0.5,
        )?;
        check_window("loops.reverse_window", &self.reverse_window)?;
        check_range(
            "loops.reverse_max_translation_m",
            self.reverse_max_translation_m,
            0.0,
            100.0,
        )?;
        check_range(
            "loops.reverse_max_rotation_rad",
            self.reverse_max_rotation_rad,
            0.0,
            std::f64::consts::PI,
        )?;
        check_range(
            "loops.consistency_max_chi2",
            self.consistency_max_chi2,
            0.0,
            1e12,
        )?;
        check_range("loops.drift_fraction", self.drift_fraction, 0.0, 10.0)?;
        check_window("loops.densify_max_window", &self.densify_max_window)?;
        check_positive_window("loops.densify_max_window", &self.densify_max_window)?;
        check_window("loops.densify_max_sigma", &self.densify_max_sigma)?;
        check_positive_window("loops.densify_max_sigma", &self.densify_max_sigma)?;
        check_positive_window("loops.max_sigma", &self.max_sigma)?;
        check_range(
            "loops.densify_correlation",
            self.densify_correlation,
            0.0,
            1.0,
        )?;
        check_range(
            "loops.drift_heading_sigma_rad",
            self.drift_heading_sigma_rad,
            0.0,
            std::f64::consts::PI,
        )?;
        Ok(())
    }
}
