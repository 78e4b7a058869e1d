//! Matching one loop candidate and the checks it must pass on its own.
//!
//! `S_k` (the newer node) is matched against `I_j` around the prior
//! `j_from_k` (eq. 5-6). The checks, in order, each naming the
//! [`RejectReason`] of a failure:
//! 1. `no_data` / `no_match`: a scan or image without echoes, or no pose in
//!    the window with any overlap;
//! 2. `quality`: mean intensity under the points, fraction of points inside
//!    the image, and the second-peak ratio (a distinct maximum);
//! 3. `covariance`: positive definite, standard deviations within
//!    `max_sigma` (`densify_max_sigma` for a densification pair). With
//!    `densify_partial`, a densification match that fails only along one
//!    horizontal direction passes as a *partial* loop ([`unconstrained`],
//!    [`partial_measurement`]);
//! 4. `window_edge`: the maximum is not at the border of the searched
//!    window (where the true peak may lie outside it); a match at the
//!    border is searched once more over twice the window (at most
//!    `max_window`) before this check is final (for a partial loop, on
//!    the constrained components only);
//! 5. `reverse_mismatch`: the symmetric match `S_j` vs `I_k`, a climb to
//!    the nearest maximum from the inverse of the forward result, must
//!    agree with it.
//!
//! A candidate of the mission pass that the estimate predicts to overlap
//! almost entirely (`ESCALATE_MIN_PREDICTED_OVERLAP`) but whose match fails
//! check 2 or finds nothing is searched once more over a window
//! `escalate_window_factor` times larger before check 2 is final; the
//! wider match is kept only when it passes checks 2-4.

use super::LoopConfig;
use super::config::{ESCALATE_MIN_PREDICTED_OVERLAP, WINDOW_EDGE_FRACTION};
use super::records::{LoopRecord, RejectReason};
use crate::error::StageError;
use crate::matcher::SearchWindow as Window;
use crate::matcher::symmetric::{Fusion, reverse_match};
use crate::matcher::{
    MatchOutcome, MatchResult, MatcherConfig, Search, SearchWindow, match_scan, match_scan_local,
};
use crate::nodes::NodeData;
use crate::uncertainty::symmetric;
use echofield_graph::Se2;
use nalgebra::{Matrix2, Matrix3, Vector2};

/// Standard deviation (m) of a partial loop's measurement along its
/// unconstrained direction: far beyond any relative uncertainty of two
/// overlapping nodes, so the edge adds no information there (its
/// information along it is 1/100 m⁻², against at least 1/0.35² ≈ 8 m⁻²
/// across), while its covariance stays positive definite for the
/// consistency test and the solver.
pub const PARTIAL_SIGMA_M: f64 = 10.0;

/// A pair to match: `S_to` against `I_from` around `prior = from_from_to`.
#[derive(Clone, Debug)]
pub struct Candidate {
    pub from: usize,
    pub to: usize,
    pub prior: Se2,
    pub prior_covariance: Matrix3<f64>,
    pub predicted_overlap: f64,
    /// `n_sigma` standard deviations per axis, before clamping.
    pub raw_window: SearchWindow,
    /// Searched over `max_window` although its raw window is larger (see
    /// `loops::config::WIDE_SEARCHES_PER_NODE`).
    pub wide: bool,
    /// A densification pair (after the mission, prior from the optimised
    /// estimate): both matches climb to the nearest maximum
    /// ([`match_scan_local`]) instead of searching the whole window.
    pub densify: bool,
}

impl Candidate {
    /// The raw window exceeds `max` on some axis.
    pub fn too_uncertain(&self, max: &Window) -> bool {
        self.raw_window.x_m > max.x_m
            || self.raw_window.y_m > max.y_m
            || self.raw_window.theta_rad > max.theta_rad
    }

    /// The window searched: the raw one clamped to `[min, max]`
    /// (`LoopConfig::validate` keeps `min <= max`; were it not, `max`
    /// wins: `max(lo).min(hi)` never panics, unlike `f64::clamp`).
    pub fn window(&self, config: &LoopConfig) -> SearchWindow {
        let (lo, hi) = (&config.gate.min_window, &config.gate.max_window);
        SearchWindow::new(
            self.raw_window.x_m.max(lo.x_m).min(hi.x_m),
            self.raw_window.y_m.max(lo.y_m).min(hi.y_m),
            self.raw_window
                .theta_rad
                .max(lo.theta_rad)
                .min(hi.theta_rad),
        )
    }

    /// A record of this candidate before matching.
    pub fn record(&self, examined_at: usize, config: &LoopConfig) -> LoopRecord {
        LoopRecord {
            from: self.from as u64,
            to: self.to as u64,
            examined_at: examined_at as u64,
            prior: self.prior,
            prior_covariance: self.prior_covariance,
            predicted_overlap: self.predicted_overlap,
            window: self.window(config),
            matched: None,
            measurement: None,
            score: None,
            quality: None,
            covariance: None,
            reverse: None,
            accepted: false,
            rejected_by: None,
            densified: self.densify,
            unconstrained_direction: None,
            no_match: None,
            robust_weight: None,
            ground_truth: None,
            gt_error_m: None,
            gt_error_deg: None,
            true_positive: None,
            gt_overlap: None,
        }
    }
}

/// Matches `candidate` and runs the individual checks; the record says
/// whether it passed (`rejected_by == None`).
pub fn examine(
    candidate: &Candidate,
    examined_at: usize,
    nodes: &[NodeData],
    matcher: &MatcherConfig,
    config: &LoopConfig,
) -> Result<LoopRecord, StageError> {
    let mut record = candidate.record(examined_at, config);
    let (old, new) = (&nodes[candidate.from], &nodes[candidate.to]);
    if let Some(reason) = unmatchable(old, new) {
        record.rejected_by = Some(reason);
        return Ok(record);
    }
    let stage = || format!("loop match {} -> {}", candidate.from, candidate.to);
    let old_image = old.image.image().map_err(|e| StageError::new(stage(), e))?;
    let matcher_fn = if candidate.densify {
        match_scan_local
    } else {
        match_scan
    };
    let search = |window: &SearchWindow| {
        matcher_fn(
            &new.scan.points,
            &old_image,
            &candidate.prior,
            window,
            matcher,
        )
        .map_err(|e| StageError::new(stage(), e))
    };
    let outcome = search_with_retries(candidate, &mut record.window, &search, config)?;
    let m = match outcome {
        MatchOutcome::Match(m) => m,
        MatchOutcome::NoMatch { reason } => {
            record.rejected_by = Some(RejectReason::NoMatch);
            record.no_match = Some(reason.to_string());
            return Ok(record);
        }
    };
    record.matched = Some(m.image_from_scan);
    record.measurement = Some(m.image_from_scan);
    record.score = Some(m.score);
    record.quality = Some(m.quality.clone());
    record.covariance = Some(m.covariance);
    record.rejected_by = individual_checks(&m, candidate, &record.window, config);
    if record.rejected_by.is_some() {
        return Ok(record);
    }
    let pair = Pair {
        candidate,
        old,
        new,
    };
    confirm(&mut record, &m, &pair, matcher, config)?;
    Ok(record)
}

/// Why the pair of `old` and `new` cannot be matched at all, if it cannot:
/// a node without a scan or an image, or in a DVL gap.
fn unmatchable(old: &NodeData, new: &NodeData) -> Option<RejectReason> {
    if !new.has_scan() || !old.has_scan() || old.image.is_empty() || new.image.is_empty() {
        return Some(RejectReason::NoData);
    }
    if new.in_dvl_gap || old.in_dvl_gap {
        return Some(RejectReason::DvlGap);
    }
    None
}

/// A candidate with its two nodes (`old` = `from`, `new` = `to`).
struct Pair<'a> {
    candidate: &'a Candidate,
    old: &'a NodeData,
    new: &'a NodeData,
}

/// The checks after the individual ones, on a match `m` that passed them:
/// the symmetric check (S_j on I_k, climbing from the inverse of the
/// result; see `symmetric` for why a climb and not a search), whose fused
/// result becomes the measurement, then, when the match leaves a direction
/// unconstrained, the partial measurement along it. Errors: an image that
/// cannot be rebuilt, a reverse match that fails.
fn confirm(
    record: &mut LoopRecord,
    m: &MatchResult,
    pair: &Pair,
    matcher: &MatcherConfig,
    config: &LoopConfig,
) -> Result<(), StageError> {
    let candidate = pair.candidate;
    let stage = || format!("loop match {} -> {}", candidate.from, candidate.to);
    let tolerance = config.gate.reverse_tolerance();
    let new_image = pair
        .new
        .image
        .image()
        .map_err(|e| StageError::new(stage(), e))?;
    let (reverse, measurement) = reverse_match(
        m,
        &pair.old.scan.points,
        &new_image,
        &tolerance,
        matcher,
        Search::Local,
        Fusion::Midpoint,
    )
    .map_err(|e| StageError::new(format!("reverse {}", stage()), e))?;
    record.reverse = Some(reverse);
    match measurement {
        Some(z) => record.measurement = Some(z),
        None => record.rejected_by = Some(RejectReason::ReverseMismatch),
    }
    if record.rejected_by.is_none()
        && let Some(u) = unconstrained(&m.covariance, candidate, config)
        && let Some(z) = record.measurement
    {
        let (z, covariance) = partial_measurement(&z, &m.covariance, &candidate.prior, &u);
        record.measurement = Some(z);
        record.covariance = Some(covariance);
        record.unconstrained_direction = Some([u.x, u.y]);
    }
    Ok(())
}

/// The match of `candidate` by `search` over `window`, searched again
/// where the first result says the window was wrong: over twice the
/// window when its maximum lies at the window's edge (the prior was further
/// off than its covariance allowed), and over `escalate_window_factor`
/// times it when [`escalates`] (kept only when it passes the individual
/// checks). `window` becomes the window of the result kept; both wider
/// windows stay within `gate.max_window`.
fn search_with_retries(
    candidate: &Candidate,
    window: &mut SearchWindow,
    search: &dyn Fn(&SearchWindow) -> Result<MatchOutcome, StageError>,
    config: &LoopConfig,
) -> Result<MatchOutcome, StageError> {
    let mut outcome = search(window)?;
    if let MatchOutcome::Match(m) = &outcome
        && individual_checks(m, candidate, window, config) == Some(RejectReason::WindowEdge)
    {
        let wider = scaled_window(window, 2.0, &config.gate.max_window);
        if wider != *window {
            *window = wider;
            outcome = search(&wider)?;
        }
    }
    if escalates(&outcome, candidate, window, config) {
        let wider = scaled_window(
            window,
            config.escalate_window_factor,
            &config.gate.max_window,
        );
        if wider != *window {
            let again = search(&wider)?;
            if let MatchOutcome::Match(m) = &again
                && individual_checks(m, candidate, &wider, config).is_none()
            {
                *window = wider;
                outcome = again;
            }
        }
    }
    Ok(outcome)
}

/// Whether `outcome` of `candidate` is searched again over a larger window
/// (`LoopConfig::escalate_window_factor`).
fn escalates(
    outcome: &MatchOutcome,
    candidate: &Candidate,
    window: &SearchWindow,
    config: &LoopConfig,
) -> bool {
    if config.escalate_window_factor <= 1.0
        || candidate.densify
        || candidate.wide
        || candidate.predicted_overlap < ESCALATE_MIN_PREDICTED_OVERLAP
    {
        return false;
    }
    match outcome {
        MatchOutcome::Match(m) => {
            individual_checks(m, candidate, window, config) == Some(RejectReason::Quality)
        }
        MatchOutcome::NoMatch { .. } => true,
    }
}

/// `window` with every half-width multiplied by `factor`, at most `max`'s
/// (and never below `window`'s).
fn scaled_window(window: &SearchWindow, factor: f64, max: &Window) -> SearchWindow {
    SearchWindow::new(
        (factor * window.x_m).min(max.x_m.max(window.x_m)),
        (factor * window.y_m).min(max.y_m.max(window.y_m)),
        (factor * window.theta_rad).min(max.theta_rad.max(window.theta_rad)),
    )
}

/// The unit direction (in `from`'s frame) along which a densification
/// match is unconstrained, when `densify_partial` is on and the match
/// fails `densify_max_sigma` along that direction only: the largest axis
/// of its xy covariance exceeds the tighter of the x and y limits while
/// the smallest axis and θ are within them. `None` for every other match
/// (which then passes or fails the covariance check as a whole).
pub fn unconstrained(
    covariance: &Matrix3<f64>,
    candidate: &Candidate,
    config: &LoopConfig,
) -> Option<Vector2<f64>> {
    if !(candidate.densify && config.densify_partial) {
        return None;
    }
    let max_sigma = &config.densify_max_sigma;
    let cov = symmetric(*covariance);
    if cov.cholesky().is_none() || max_sigma.bounds_sigma(&cov) {
        return None;
    }
    let xy: Matrix2<f64> = cov.fixed_view::<2, 2>(0, 0).into_owned();
    let eigen = xy.symmetric_eigen();
    let (small, large) = if eigen.eigenvalues[0] <= eigen.eigenvalues[1] {
        (0, 1)
    } else {
        (1, 0)
    };
    let limit = max_sigma.x_m.min(max_sigma.y_m);
    let constrained = eigen.eigenvalues[small].sqrt() <= limit
        && cov[(2, 2)].sqrt() <= max_sigma.theta_rad
        && eigen.eigenvalues[large].sqrt() > limit;
    constrained.then(|| eigen.eigenvectors.column(large).normalize())
}

/// A partial loop's measurement and covariance from the match `z` (with
/// covariance `covariance`), the prior and the unconstrained direction
/// `u`: along `u` the translation is the prior's; across it and in θ it
/// is the match's, with the match's marginal covariance of those two;
/// along `u` the standard deviation is [`PARTIAL_SIGMA_M`], uncorrelated.
pub fn partial_measurement(
    z: &Se2,
    covariance: &Matrix3<f64>,
    prior: &Se2,
    u: &Vector2<f64>,
) -> (Se2, Matrix3<f64>) {
    let (zt, pt) = (z.translation(), prior.translation());
    let t = zt + u * u.dot(&(pt - zt));
    // Rows: the coordinates along u, across u (v) and θ.
    let basis = Matrix3::new(u.x, u.y, 0.0, -u.y, u.x, 0.0, 0.0, 0.0, 1.0);
    let mut q = basis * symmetric(*covariance) * basis.transpose();
    for i in 1..3 {
        q[(0, i)] = 0.0;
        q[(i, 0)] = 0.0;
    }
    q[(0, 0)] = PARTIAL_SIGMA_M * PARTIAL_SIGMA_M;
    let cov = symmetric(basis.transpose() * q * basis);
    (Se2::new(t.x, t.y, z.theta()), cov)
}

/// Checks 2-4 of the module doc.
fn individual_checks(
    m: &MatchResult,
    candidate: &Candidate,
    window: &SearchWindow,
    config: &LoopConfig,
) -> Option<RejectReason> {
    let q = &m.quality;
    if q.mean_intensity < config.gate.min_mean_intensity
        || q.inside_fraction < config.min_inside_fraction
    {
        return Some(RejectReason::Quality);
    }
    let cov = symmetric(m.covariance);
    let max_sigma = if candidate.densify {
        &config.densify_max_sigma
    } else {
        &config.max_sigma
    };
    let partial = unconstrained(&m.covariance, candidate, config);
    if partial.is_none() && (cov.cholesky().is_none() || !max_sigma.bounds_sigma(&cov)) {
        return Some(RejectReason::Covariance);
    }
    let mut d = m.image_from_scan.to_vector() - candidate.prior.to_vector();
    // Along a partial loop's unconstrained direction the peak may lie
    // anywhere, the window's edge included; that component is not used.
    if let Some(u) = partial {
        let along = u.dot(&d.xy());
        d.x -= along * u.x;
        d.y -= along * u.y;
    }
    let dtheta = echofield_graph::wrap_angle(d.z);
    let margin = 1.0 - WINDOW_EDGE_FRACTION;
    let at_edge = |offset: f64, half: f64| offset.abs() >= margin * half;
    if at_edge(d.x, window.x_m) || at_edge(d.y, window.y_m) || at_edge(dtheta, window.theta_rad) {
        return Some(RejectReason::WindowEdge);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn candidate(raw: SearchWindow) -> Candidate {
        Candidate {
            from: 0,
            to: 12,
            prior: Se2::identity(),
            prior_covariance: Matrix3::identity(),
            predicted_overlap: 0.8,
            raw_window: raw,
            wide: false,
            densify: false,
        }
    }

    /// A match at `prior` with standard deviations `sigma_xy` (m) and 1°,
    /// good quality otherwise.
    fn match_with_sigma(sigma_xy: f64) -> MatchResult {
        MatchResult {
            image_from_scan: Se2::identity(),
            searched_peak: Se2::identity(),
            score: 50.0,
            quality: crate::matcher::MatchQuality {
                mean_intensity: 0.6,
                inside_fraction: 1.0,
                points: 100,
                surface_fit_residual: 0.05,
            },
            covariance: Matrix3::from_diagonal(&nalgebra::Vector3::new(
                sigma_xy * sigma_xy,
                sigma_xy * sigma_xy,
                1.0_f64.to_radians().powi(2),
            )),
            coarse: Se2::identity(),
            stats: crate::matcher::MatchStats {
                angle_step_rad: 0.01,
                search_nodes: 1,
            },
        }
    }

    #[test]
    fn densification_pairs_are_held_to_their_own_sigma_limit() {
        let config = LoopConfig::default();
        let window = SearchWindow::new(1.0, 1.0, 0.1);
        let sigma = 0.5 * (config.max_sigma.x_m + config.densify_max_sigma.x_m);
        assert!(config.densify_max_sigma.x_m < sigma && sigma < config.max_sigma.x_m);
        let mut c = candidate(SearchWindow::new(0.3, 0.3, 0.02));
        assert_eq!(
            individual_checks(&match_with_sigma(sigma), &c, &window, &config),
            None
        );
        c.densify = true;
        assert_eq!(
            individual_checks(&match_with_sigma(sigma), &c, &window, &config),
            Some(RejectReason::Covariance)
        );
        let tight = 0.9 * config.densify_max_sigma.x_m;
        assert_eq!(
            individual_checks(&match_with_sigma(tight), &c, &window, &config),
            None
        );
    }

    #[test]
    fn a_strongly_overlapping_candidate_that_finds_nothing_is_searched_wider() {
        let config = LoopConfig::default();
        let window = SearchWindow::new(0.6, 0.9, 0.06);
        let mut c = candidate(SearchWindow::new(0.2, 0.3, 0.02));
        c.predicted_overlap = 0.9;
        let mut weak = match_with_sigma(0.1);
        weak.quality.mean_intensity = 0.5 * config.gate.min_mean_intensity;
        let failed = MatchOutcome::Match(Box::new(weak));
        let nothing = MatchOutcome::NoMatch {
            reason: crate::matcher::NoMatchReason::NoOverlap,
        };
        assert!(escalates(&failed, &c, &window, &config));
        assert!(escalates(&nothing, &c, &window, &config));
        // Not a match that passes, nor one failing another check.
        let good = MatchOutcome::Match(Box::new(match_with_sigma(0.1)));
        assert!(!escalates(&good, &c, &window, &config));
        let unsure = MatchOutcome::Match(Box::new(match_with_sigma(2.0)));
        assert!(!escalates(&unsure, &c, &window, &config));
        // Not a candidate the estimate predicts to overlap less, a wide
        // search, a densification climb, or with the factor at 1.
        let mut low = c.clone();
        low.predicted_overlap = 0.7;
        let mut wide = c.clone();
        wide.wide = true;
        let mut dense = c.clone();
        dense.densify = true;
        for other in [&low, &wide, &dense] {
            assert!(!escalates(&failed, other, &window, &config));
        }
        let off = LoopConfig {
            escalate_window_factor: 1.0,
            ..LoopConfig::default()
        };
        assert!(!escalates(&failed, &c, &window, &off));
        // Three times wider, capped at max_window on each axis.
        let wider = scaled_window(&window, 3.0, &Window::new(10.0, 2.0, 0.5));
        let want = [1.8, 2.0, 0.18];
        for (got, want) in [wider.x_m, wider.y_m, wider.theta_rad]
            .into_iter()
            .zip(want)
        {
            assert!((got - want).abs() < 1e-12, "{wider:?}");
        }
        // A window already beyond the cap stays as it is.
        let big = SearchWindow::new(12.0, 1.0, 0.1);
        assert_eq!(
            scaled_window(&big, 3.0, &Window::new(10.0, 10.0, 1.0)).x_m,
            12.0
        );
    }

    #[test]
    fn windows_are_clamped_and_large_ones_flagged() {
        let config = LoopConfig::default();
        let small = candidate(SearchWindow::new(0.1, 2.0, 0.01));
        let w = small.window(&config);
        assert_eq!((w.x_m, w.y_m), (config.gate.min_window.x_m, 2.0));
        assert_eq!(w.theta_rad, config.gate.min_window.theta_rad);
        assert!(!small.too_uncertain(&config.gate.max_window));
        let large = candidate(SearchWindow::new(25.0, 1.0, 0.05));
        assert!(large.too_uncertain(&config.gate.max_window));
        assert_eq!(large.window(&config).x_m, config.gate.max_window.x_m);
        let record = large.record(12, &config);
        assert_eq!((record.from, record.to, record.examined_at), (0, 12, 12));
        assert!(record.matched.is_none() && !record.accepted);
    }

    /// A match whose xy covariance has standard deviations `along` (m) at
    /// `angle` (rad) and `across` (m) perpendicular to it, and 1° in θ.
    fn match_along(along: f64, across: f64, angle: f64) -> MatchResult {
        let (s, c) = angle.sin_cos();
        let r = Matrix2::new(c, -s, s, c);
        let xy = r * Matrix2::new(along * along, 0.0, 0.0, across * across) * r.transpose();
        let mut m = match_with_sigma(0.1);
        m.covariance.fixed_view_mut::<2, 2>(0, 0).copy_from(&xy);
        m
    }

    #[test]
    fn a_densified_match_blind_along_one_direction_is_a_partial_loop() {
        let config = LoopConfig::default();
        let window = SearchWindow::new(0.5, 0.5, 0.05);
        let angle = 30.0_f64.to_radians();
        let m = match_along(0.8, 0.1, angle);
        let mut c = candidate(SearchWindow::new(0.3, 0.3, 0.02));
        // While the mission runs, such a match is rejected ...
        assert_eq!(unconstrained(&m.covariance, &c, &config), None);
        assert_eq!(
            individual_checks(&m, &c, &window, &config),
            Some(RejectReason::Covariance)
        );
        // ... in the densification pass it passes, blind along 30°.
        c.densify = true;
        let u = unconstrained(&m.covariance, &c, &config).unwrap();
        assert!((u.x * angle.sin() - u.y * angle.cos()).abs() < 1e-9, "{u}");
        assert!((u.norm() - 1.0).abs() < 1e-12);
        assert_eq!(individual_checks(&m, &c, &window, &config), None);
        // A peak at the window's edge along the blind direction is no
        // reason to reject it; across it, it is.
        let mut at_edge = m.clone();
        at_edge.image_from_scan = Se2::new(0.49 * angle.cos(), 0.49 * angle.sin(), 0.0);
        assert_eq!(individual_checks(&at_edge, &c, &window, &config), None);
        // (y = 0.56·cos 30° = 0.485, beyond 95% of the 0.5 m half-width.)
        at_edge.image_from_scan = Se2::new(-0.56 * angle.sin(), 0.56 * angle.cos(), 0.0);
        assert_eq!(
            individual_checks(&at_edge, &c, &window, &config),
            Some(RejectReason::WindowEdge)
        );
        // Not when switched off, nor when the match is also unsure across
        // the direction or in heading.
        let off = LoopConfig {
            densify_partial: false,
            ..LoopConfig::default()
        };
        assert_eq!(unconstrained(&m.covariance, &c, &off), None);
        assert_eq!(
            individual_checks(&m, &c, &window, &off),
            Some(RejectReason::Covariance)
        );
        let wide = match_along(0.8, 0.4, angle);
        assert_eq!(unconstrained(&wide.covariance, &c, &config), None);
        let mut turning = m.clone();
        turning.covariance[(2, 2)] = 4.0_f64.to_radians().powi(2);
        assert_eq!(unconstrained(&turning.covariance, &c, &config), None);
        // A match within the limits on every axis is a full loop.
        assert_eq!(
            unconstrained(&match_with_sigma(0.2).covariance, &c, &config),
            None
        );
    }

    #[test]
    fn a_partial_measurement_takes_only_the_blind_component_from_the_prior() {
        let angle = 30.0_f64.to_radians();
        let mut m = match_along(0.8, 0.1, angle);
        m.covariance[(0, 2)] = 0.0002;
        m.covariance[(2, 0)] = 0.0002;
        m.covariance[(1, 2)] = -0.0001;
        m.covariance[(2, 1)] = -0.0001;
        assert!(m.covariance.cholesky().is_some());
        let u = Vector2::new(angle.cos(), angle.sin());
        let v = Vector2::new(-u.y, u.x);
        let z = Se2::new(1.0, 2.0, 0.1);
        let prior = Se2::new(1.6, 1.3, 0.04);
        let (p, cov) = partial_measurement(&z, &m.covariance, &prior, &u);
        // Along u the prior's, across u and in θ the match's.
        assert!(u.dot(&(p.translation() - prior.translation())).abs() < 1e-12);
        assert!(v.dot(&(p.translation() - z.translation())).abs() < 1e-12);
        assert!((p.theta() - z.theta()).abs() < 1e-12);
        // The marginal of (across, θ) is the match's; nothing along u.
        let w = |a: [f64; 3], b: [f64; 3], c: &Matrix3<f64>| {
            (nalgebra::Vector3::from(a).transpose() * c * nalgebra::Vector3::from(b))[(0, 0)]
        };
        let (uu, vv, tt) = ([u.x, u.y, 0.0], [v.x, v.y, 0.0], [0.0, 0.0, 1.0]);
        assert!((w(uu, uu, &cov) - PARTIAL_SIGMA_M.powi(2)).abs() < 1e-9);
        assert!(w(uu, vv, &cov).abs() < 1e-12 && w(uu, tt, &cov).abs() < 1e-12);
        for (a, b) in [(vv, vv), (vv, tt), (tt, tt)] {
            assert!((w(a, b, &cov) - w(a, b, &m.covariance)).abs() < 1e-12);
        }
        assert!(cov.cholesky().is_some());
    }
}
