//! The odometry edge and the sequential match between consecutive nodes.
//!
//! - **Odometry** `k-1 -> k`: the dead-reckoning motion between the two
//!   reference times and its covariance ([`Navigation::relative`], the EKF's
//!   relative covariance, with common error cancelled), floored at
//!   [`ODOMETRY_MIN_SIGMA`] so the information stays finite.
//!   Odometry covariance model: it is the EKF's own, so it is only as
//!   honest as the filter's noise model. Two filter features make it so
//!   on real data (`echofield_frontend::dead_reckoning`): the DVL
//!   innovation gate (outliers are not integrated while the covariance
//!   ignores them) and the innovation-based DVL noise adaptation (noisy
//!   stretches get wider covariances). Checked against ground truth, its mean
//!   squared Mahalanobis distance is above the ideal 3 on the St Pere replay
//!   and on the simulated marina (whose DVL has an unmodelled scale error);
//!   inflating the odometry covariance made the marina ATE worse, so none is
//!   applied (measured: EXPERIMENTS.md § Odometry covariance).
//! - **Sequential match** `S_k` vs `I_{k-1}` (eq. 5-6): the prior is the
//!   odometry motion, the window `gate.n_sigma` standard deviations of it
//!   (clamped to `[gate.min_window, gate.max_window]`, [`MatchGate`]). The
//!   match becomes an edge of kind `Sequential` when its mean intensity
//!   reaches `gate.min_mean_intensity`, its covariance is positive
//!   definite, and it agrees with the odometry: the squared Mahalanobis
//!   distance of `prior⁻¹ ⊕ match` under the sum of both covariances is at
//!   most [`SEQUENTIAL_MAX_PRIOR_CHI2`]. Its covariance is the score
//!   surface's plus the `gate.min_sigma` floor.
//! - **Submap** (scan-only data, `seq.submap_rotations` > 0): `I_{k-1}` is
//!   replaced by one image of the beams of rotations `k-1-d … k-1`, each
//!   earlier rotation placed in `k-1`'s frame through the accepted
//!   sequential matches between them (the odometry where one was not
//!   accepted; [`StoredImage::composite`]). Its reverse match still reads
//!   `I_k` alone, which lacks what that rotation dropped, so the two are
//!   compared under their covariances (χ² at most
//!   [`SUBMAP_REVERSE_MAX_CHI2`]) instead of by the fixed tolerance.
//!
//! [`MatchGate`]: echofield_frontend::matcher::MatchGate
//!
//! Sequential matches depend on dead reckoning only, not on the graph;
//! each is computed when its newer node is built.

use super::SlamError;
use super::config::{SEQUENTIAL_MAX_PRIOR_CHI2, SUBMAP_REVERSE_MAX_CHI2, SequentialConfig};
use echofield_frontend::FrontendError;
use echofield_frontend::dead_reckoning::Navigation;
use echofield_frontend::image::AcousticImage;
use echofield_frontend::image::StoredImage;
use echofield_frontend::loops::{RejectReason, ReverseCheck, SequentialRecord};
use echofield_frontend::matcher::symmetric::{Fusion, reverse_match, weighted_mean_pose};
use echofield_frontend::matcher::{
    MatchOutcome, MatchResult, MatcherConfig, Search, SearchWindow, match_scan,
};
use echofield_frontend::nodes::NodeData;
use echofield_frontend::uncertainty::{information, invert, mahalanobis2, symmetric, with_floor};
use echofield_graph::Se2;
use nalgebra::{Matrix3, Point2};
use std::sync::Arc;

/// Floor of the odometry edges' standard deviations: 1 mm, 1 mm, 0.01°.
pub const ODOMETRY_MIN_SIGMA: SearchWindow = SearchWindow::new(1e-3, 1e-3, 1.745_329_251_994_33e-4);

/// The odometry motion `(k-1)_from_k` and its floored covariance.
pub fn odometry(
    navigation: &Navigation,
    prev: &NodeData,
    node: &NodeData,
) -> Result<(Se2, Matrix3<f64>), SlamError> {
    let (motion, cov) = navigation
        .relative(prev.stamp_s, node.stamp_s)
        .map_err(|e| SlamError::frontend("dead-reckoning motion between nodes", e))?;
    Ok((motion, with_floor(&cov, &ODOMETRY_MIN_SIGMA)))
}

/// The sequential match of node `k` (`node`) against its predecessor
/// `prev` (the record `k - 1 -> k`), with the odometry of `navigation` as
/// prior, gated by `seq` and matched with `matcher`. `history` holds the
/// earlier nodes of the submap with their `(k-1)_from_j` (empty: `I_{k-1}`
/// alone; [`submap_history`]). `None` when sequential matching is off.
pub fn match_next(
    prev: &NodeData,
    history: &[(&NodeData, Se2)],
    node: &NodeData,
    k: usize,
    navigation: &Navigation,
    (seq, matcher): (&SequentialConfig, &MatcherConfig),
) -> Result<Option<SequentialRecord>, SlamError> {
    if !seq.enabled {
        return Ok(None);
    }
    match_one(prev, history, node, k, navigation, seq, matcher).map(Some)
}

/// The nodes before `k - 1` that join its image in the submap of node
/// `k`'s match, newest first, each with `(k-1)_from_j`: at most
/// `depth`, chained through the accepted sequential records
/// (`sequential[j]` is node `j + 1` against node `j`) or the odometry,
/// and stopping at the first node without a scan or in a DVL gap (its
/// image is distorted, and so is the placement through it).
pub fn submap_history<'n>(
    nodes: &'n [NodeData],
    sequential: &[SequentialRecord],
    k: usize,
    depth: usize,
    navigation: &Navigation,
) -> Result<Vec<(&'n NodeData, Se2)>, SlamError> {
    let mut history = Vec::new();
    let mut prev_from_j = Se2::identity();
    for j in (k.saturating_sub(1 + depth)..k.saturating_sub(1)).rev() {
        let accepted = sequential.get(j).filter(|r| r.accepted);
        let j_from_next = match accepted.and_then(|r| r.measurement) {
            Some(z) => z,
            None => odometry(navigation, &nodes[j], &nodes[j + 1])?.0,
        };
        prev_from_j = prev_from_j.compose(&j_from_next.inverse());
        if !nodes[j].matchable() {
            break;
        }
        history.push((&nodes[j], prev_from_j));
    }
    Ok(history)
}

fn match_one(
    prev: &NodeData,
    history: &[(&NodeData, Se2)],
    node: &NodeData,
    k: usize,
    navigation: &Navigation,
    seq: &SequentialConfig,
    matcher: &MatcherConfig,
) -> Result<SequentialRecord, SlamError> {
    let (prior, prior_cov) = odometry(navigation, prev, node)?;
    let mut record = unmatched_record(k, prior, prior_cov, seq);
    if !node.has_scan() || prev.image.is_empty() {
        record.rejected_by = Some(RejectReason::NoData);
        return Ok(record);
    }
    if node.in_dvl_gap || prev.in_dvl_gap {
        record.rejected_by = Some(RejectReason::DvlGap);
        return Ok(record);
    }
    let stage = || format!("sequential match {} -> {k}", k - 1);
    let prev_image =
        submap_image(&prev.image, history).map_err(|e| SlamError::frontend(stage(), e))?;
    let outcome = match_scan(
        &node.scan.points,
        &prev_image,
        &prior,
        &record.window,
        matcher,
    )
    .map_err(|e| SlamError::frontend(stage(), e))?;
    let m = match outcome {
        MatchOutcome::Match(m) => m,
        MatchOutcome::NoMatch { reason } => {
            record.rejected_by = Some(RejectReason::NoMatch);
            record.no_match = Some(reason.to_string());
            return Ok(record);
        }
    };
    gate_forward(&mut record, &m, seq);
    if record.rejected_by.is_none() && seq.symmetric && prev.has_scan() {
        let image = node
            .image
            .image()
            .map_err(|e| SlamError::frontend(stage(), e))?;
        let checked = if history.is_empty() {
            check_reverse(&mut record, &m, &prev.scan.points, &image, seq, matcher)
        } else {
            check_reverse_of_submap(&mut record, &m, &prev.scan.points, &image, seq, matcher)
        };
        checked.map_err(|e| {
            SlamError::frontend(format!("reverse sequential match {k} -> {}", k - 1), e)
        })?;
    }
    record.accepted = record.rejected_by.is_none();
    Ok(record)
}

/// The record of node `k` against node `k - 1` before any match: the
/// odometry `prior` (`image_from_scan`) with its covariance and the gate's
/// window for it.
fn unmatched_record(
    k: usize,
    prior: Se2,
    prior_cov: Matrix3<f64>,
    seq: &SequentialConfig,
) -> SequentialRecord {
    SequentialRecord {
        from: (k - 1) as u64,
        to: k as u64,
        prior,
        prior_covariance: prior_cov,
        window: seq.gate.window(&prior_cov),
        matched: None,
        measurement: None,
        quality: None,
        covariance: None,
        reverse: None,
        prior_chi2: None,
        accepted: false,
        rejected_by: None,
        no_match: None,
    }
}

/// Records the forward match `m` and judges it by the gate: its mean
/// intensity, its (floored) covariance, and its agreement with the
/// odometry prior (χ² at most [`SEQUENTIAL_MAX_PRIOR_CHI2`]).
fn gate_forward(record: &mut SequentialRecord, m: &MatchResult, seq: &SequentialConfig) {
    record.matched = Some(m.image_from_scan);
    record.quality = Some(m.quality.clone());
    record.covariance = Some(m.covariance);
    let cov = with_floor(&m.covariance, &seq.gate.min_sigma);
    // Near the identity the vector form of prior⁻¹ ⊕ match is the
    // difference of the two, with covariance about the sum of both.
    let difference = record.prior.inverse().compose(&m.image_from_scan);
    record.prior_chi2 = mahalanobis2(&difference, &symmetric(record.prior_covariance + cov));
    record.rejected_by = if m.quality.mean_intensity < seq.gate.min_mean_intensity {
        Some(RejectReason::Quality)
    } else if information(&cov).is_none() {
        Some(RejectReason::Covariance)
    } else if record
        .prior_chi2
        .is_none_or(|c| c > SEQUENTIAL_MAX_PRIOR_CHI2)
    {
        Some(RejectReason::Prior)
    } else {
        None
    };
    record.measurement = Some(m.image_from_scan);
}

/// The symmetric check of an accepted forward match `m`: `S_{k-1}`
/// (`prev_points`) against `I_k` (`image`) around the inverse of `m`.
/// Agreement within the gate's tolerance makes the record's measurement
/// the fusion of both; disagreement rejects it (`reverse_mismatch`).
fn check_reverse(
    record: &mut SequentialRecord,
    m: &MatchResult,
    prev_points: &[Point2<f64>],
    image: &AcousticImage,
    seq: &SequentialConfig,
    matcher: &MatcherConfig,
) -> Result<(), FrontendError> {
    let (reverse, measurement) = reverse_match(
        m,
        prev_points,
        image,
        &seq.gate.reverse_tolerance(),
        matcher,
        Search::Global,
        Fusion::InformationWeighted,
    )?;
    record.reverse = Some(reverse);
    match measurement {
        Some(z) => record.measurement = Some(z),
        None => record.rejected_by = Some(RejectReason::ReverseMismatch),
    }
    Ok(())
}

/// `I_{k-1}` alone (`history` empty), or the submap of `prev`'s image
/// and `history`'s.
fn submap_image(
    prev: &StoredImage,
    history: &[(&NodeData, Se2)],
) -> Result<Arc<AcousticImage>, FrontendError> {
    if history.is_empty() {
        return prev.image();
    }
    let others: Vec<_> = history.iter().map(|(n, t)| (&n.image, *t)).collect();
    match prev.composite(&others) {
        Some(image) => image.map(Arc::new),
        None => prev.image(),
    }
}

/// The symmetric check of a submap match `m` (module doc): `S_{k-1}`
/// against `I_k` around the inverse of `m`, compared with `m` under both
/// covariances (each floored at `gate.min_sigma`); agreement makes the
/// record's measurement their information-weighted mean, disagreement or
/// no reverse match rejects it (`reverse_mismatch`).
fn check_reverse_of_submap(
    record: &mut SequentialRecord,
    m: &MatchResult,
    prev_points: &[Point2<f64>],
    image: &AcousticImage,
    seq: &SequentialConfig,
    matcher: &MatcherConfig,
) -> Result<(), FrontendError> {
    let window = seq.gate.reverse_tolerance().window;
    let outcome = match_scan(
        prev_points,
        image,
        &m.image_from_scan.inverse(),
        &window,
        matcher,
    )?;
    let MatchOutcome::Match(r) = outcome else {
        record.rejected_by = Some(RejectReason::ReverseMismatch);
        return Ok(());
    };
    let (reverse_inverse, reverse_inverse_cov) = invert(&r.image_from_scan, &r.covariance);
    let cycle = m.image_from_scan.inverse().compose(&reverse_inverse);
    let floor = &seq.gate.min_sigma;
    let both =
        symmetric(with_floor(&m.covariance, floor) + with_floor(&reverse_inverse_cov, floor));
    let cycle_t = cycle.translation().norm();
    record.reverse = Some(ReverseCheck {
        matched: Some(r.image_from_scan),
        quality: Some(r.quality.clone()),
        translation_diff_m: Some(cycle_t),
        rotation_diff_rad: Some(cycle.theta().abs()),
    });
    if mahalanobis2(&cycle, &both).is_some_and(|c| c <= SUBMAP_REVERSE_MAX_CHI2) {
        record.measurement = Some(weighted_mean_pose(
            &m.image_from_scan,
            &m.covariance,
            &reverse_inverse,
            &reverse_inverse_cov,
        ));
    } else {
        record.rejected_by = Some(RejectReason::ReverseMismatch);
    }
    Ok(())
}

/// The covariance of an accepted sequential edge.
pub fn edge_covariance(record: &SequentialRecord, seq: &SequentialConfig) -> Option<Matrix3<f64>> {
    let cov = record.covariance?;
    Some(with_floor(&cov, &seq.gate.min_sigma))
}
