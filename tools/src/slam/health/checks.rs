//! The checks of [`super::assess`]: each compares one figure of the
//! evidence with a limit and, when it fails, becomes a reason of a
//! "suspect" verdict. A check whose evidence is too thin (too few pairs,
//! too little motion) is not made.
//!
//! The limits and why they sit where they do:
//!
//! - **Sequential agreement**: the median χ² of the matches against the
//!   odometry is at most [`CHI2_3DOF_Q90`], the 90% quantile of χ² with 3
//!   degrees of freedom. With honest covariances a median above it needs
//!   more than half the matches in the tail that holds a tenth of them
//!   (with [`MIN_PAIRS`] pairs that happens by chance less than once in a
//!   hundred runs).
//! - **Rotation slope** at least [`MIN_ROTATION_SLOPE`], halfway between
//!   agreement (1) and a sonar that sees no turn (0); a mirrored angle
//!   convention gives −1.
//! - **Translation direction** within [`MAX_DIRECTION_DEG`] of the
//!   odometry's: the fit over the pairs is good to a few degrees (its
//!   standard error), and a head turned this much from its mounting spoils
//!   every match.
//! - **Head offset** at most [`MAX_HEAD_OFFSET_M`], and only when it is
//!   three standard errors from zero: a head half a metre from where the
//!   mounting puts it moves a match across a 30° turn by 0.26 m, more than
//!   twice the smallest standard deviation a sequential edge is given
//!   (`sequential.gate.min_sigma`, 0.1 m).
//! - **Sequential acceptance** at least [`MIN_SEQUENTIAL_SHARE`], and
//!   **loop acceptance** at least [`MIN_LOOP_SHARE`] of the loop
//!   candidates matched (with at least [`MIN_LOOP_MATCHES`] of them):
//!   consecutive rotations overlap almost entirely, and the gates reject a
//!   match on its own evidence (quality, agreement with the prior, the
//!   symmetric match), so a run whose sonar agrees with its navigation
//!   accepts nearly all of them; a loop is harder, but a map that closes
//!   accepts a good share of the candidates it matches. No model gives
//!   these two shares: their limits are round figures set between the
//!   runs that agree and the runs with a wrong mounting, with the margins
//!   on both sides in the README. A share fails only when the evidence
//!   puts it below its limit: when the upper end of its Wilson score
//!   interval ([`share_upper_bound`], `z` = [`SHARE_Z`]) lies below the
//!   limit, so that a short mission's few candidates, accepted at a share
//!   just under the limit by chance, are not called suspect for it (as
//!   the head offset counts only three standard errors from zero).
//! - **Map sharpening**: the map of placed scans must not be less sharp
//!   under the optimised trajectory than under dead reckoning, by more than
//!   [`MAX_ENTROPY_INCREASE_BITS`]: the optimisation exists to bring the
//!   scans together. The tolerance (`2^0.1`: the weight spread over 7% more
//!   cells) leaves room for the noise of a map the optimisation has little
//!   to correct, when the navigation is nearly exact.
//! - **Scans**: at least [`MIN_SCAN_SHARE`] of the rotations give a scan.
//!
//! The README ("Run health") gives every figure on the simulated missions
//! and the real St Pere data, good and with wrong mountings, with the
//! command that measures them.

use super::evidence::{LoopEvidence, MapEvidence, SequentialEvidence, TranslationFit};
use super::{Check, HealthReason};

/// The 0.9 quantile of χ² with 3 degrees of freedom.
pub const CHI2_3DOF_Q90: f64 = 6.251;
/// Matched sequential pairs needed for the sequential checks.
pub const MIN_PAIRS: usize = 5;
pub const MIN_ROTATION_SLOPE: f64 = 0.5;
pub const MAX_DIRECTION_DEG: f64 = 30.0;
pub const MAX_HEAD_OFFSET_M: f64 = 0.5;
pub const MIN_SEQUENTIAL_SHARE: f64 = 0.75;
pub const MIN_LOOP_SHARE: f64 = 0.25;
pub const MIN_LOOP_MATCHES: usize = 20;
pub const MIN_SCAN_SHARE: f64 = 0.5;
/// Standard normal quantile of the acceptance shares' one-sided bound
/// (97.7 %): two standard errors.
pub const SHARE_Z: f64 = 2.0;
pub const MAX_ENTROPY_INCREASE_BITS: f64 = 0.1;

fn reason(check: Check, figure: f64, limit: f64, message: String) -> HealthReason {
    HealthReason {
        check,
        figure,
        limit,
        message,
    }
}

/// The share of rotations that gave a scan.
pub fn scans(nodes: usize, with_scan: usize) -> Option<HealthReason> {
    if nodes == 0 {
        return None;
    }
    let share = with_scan as f64 / nodes as f64;
    (share < MIN_SCAN_SHARE).then(|| {
        reason(
            Check::Scans,
            share,
            MIN_SCAN_SHARE,
            format!(
                "only {with_scan} of {nodes} rotations gave a scan ({:.0}%, at least {:.0}% expected)",
                100.0 * share,
                100.0 * MIN_SCAN_SHARE
            ),
        )
    })
}

/// The checks on the sequential matches, in the order of the module doc.
pub fn sequential(evidence: &SequentialEvidence) -> Vec<HealthReason> {
    let mut out = Vec::new();
    if evidence.matched < MIN_PAIRS {
        return out;
    }
    if let Some(chi2) = evidence.median_chi2.filter(|&c| c > CHI2_3DOF_Q90) {
        out.push(reason(
            Check::SequentialAgreement,
            chi2,
            CHI2_3DOF_Q90,
            format!(
                "the sequential matches disagree with the odometry beyond their covariances: \
                 median χ² {chi2:.2} (3 degrees of freedom; at most {CHI2_3DOF_Q90}, the 90% quantile)"
            ),
        ));
    }
    if let Some(slope) = evidence
        .rotation_slope
        .filter(|s| s.value < MIN_ROTATION_SLOPE)
    {
        out.push(reason(
            Check::RotationSlope,
            slope.value,
            MIN_ROTATION_SLOPE,
            format!(
                "the sonar turns {:.2} ± {:.2} times as much as the odometry between rotations \
                 (at least {MIN_ROTATION_SLOPE}; an angle that runs the other way gives −1)",
                slope.value, slope.standard_error
            ),
        ));
    }
    if let Some(fit) = &evidence.translation {
        out.extend(translation(fit));
    }
    out.extend(acceptance(evidence));
    out
}

/// The checks on the translations of the sequential matches against the
/// odometry's: their direction, and the head offset the turns imply.
fn translation(fit: &TranslationFit) -> Vec<HealthReason> {
    let mut out = Vec::new();
    let direction_deg = fit.direction_rad().to_degrees();
    if direction_deg.abs() > MAX_DIRECTION_DEG {
        out.push(reason(
            Check::TranslationDirection,
            direction_deg,
            MAX_DIRECTION_DEG,
            format!(
                "the sonar sees the vehicle move {direction_deg:.0}° away from the odometry's \
                 direction (at most ±{MAX_DIRECTION_DEG}°; a head turned by δ from its mounting shows −δ)"
            ),
        ));
    }
    if let Some((offset_m, error_m)) = fit.head_offset_m()
        && offset_m > MAX_HEAD_OFFSET_M
        && offset_m > 3.0 * error_m
    {
        out.push(reason(
            Check::HeadOffset,
            offset_m,
            MAX_HEAD_OFFSET_M,
            format!(
                "the turns between rotations place the sonar head {offset_m:.2} ± {error_m:.2} m \
                 from where the mounting puts it (at most {MAX_HEAD_OFFSET_M} m)"
            ),
        ));
    }
    out
}

/// The upper end of the Wilson score interval of a binomial share
/// `share` observed over `n` trials, `z` standard errors (one-sided).
/// Preconditions: `share` in [0, 1]; `n > 0` (1 for `n = 0`: no evidence).
pub fn share_upper_bound(share: f64, n: usize, z: f64) -> f64 {
    if n == 0 {
        return 1.0;
    }
    let n = n as f64;
    let z2n = z * z / n;
    let centre = share + 0.5 * z2n;
    let spread = z * (share * (1.0 - share) / n + 0.25 * z2n / n).sqrt();
    ((centre + spread) / (1.0 + z2n)).min(1.0)
}

/// `share` of `n` lies below `limit` beyond its chance ([`SHARE_Z`]).
fn clearly_below(share: f64, n: usize, limit: f64) -> bool {
    share_upper_bound(share, n, SHARE_Z) < limit
}

fn acceptance(evidence: &SequentialEvidence) -> Option<HealthReason> {
    let share = evidence
        .accepted_share
        .filter(|&s| clearly_below(s, evidence.attempted, MIN_SEQUENTIAL_SHARE))?;
    let reasons: Vec<String> = evidence
        .rejected_by
        .iter()
        .map(|(reason, count)| {
            let name = serde_json::to_value(reason)
                .ok()
                .and_then(|v| v.as_str().map(str::to_string))
                .unwrap_or_default();
            format!("{count} {name}")
        })
        .collect();
    Some(reason(
        Check::SequentialAcceptance,
        share,
        MIN_SEQUENTIAL_SHARE,
        format!(
            "only {} of {} sequential matches were accepted ({:.0}%, at least {:.0}% expected; rejected: {})",
            evidence.accepted,
            evidence.attempted,
            100.0 * share,
            100.0 * MIN_SEQUENTIAL_SHARE,
            reasons.join(", ")
        ),
    ))
}

/// The loop acceptance check.
pub fn loops(evidence: &LoopEvidence) -> Option<HealthReason> {
    if evidence.matched < MIN_LOOP_MATCHES {
        return None;
    }
    let share = evidence
        .accepted_share
        .filter(|&s| clearly_below(s, evidence.matched, MIN_LOOP_SHARE))?;
    Some(reason(
        Check::LoopAcceptance,
        share,
        MIN_LOOP_SHARE,
        format!(
            "only {} of {} matched loop candidates were accepted ({:.0}%, at least {:.0}% expected)",
            evidence.accepted,
            evidence.matched,
            100.0 * share,
            100.0 * MIN_LOOP_SHARE
        ),
    ))
}

/// The map sharpening check.
pub fn map(evidence: &MapEvidence) -> Option<HealthReason> {
    let change = evidence
        .entropy_change_bits
        .filter(|&c| c > MAX_ENTROPY_INCREASE_BITS)?;
    Some(reason(
        Check::MapSharpening,
        change,
        MAX_ENTROPY_INCREASE_BITS,
        format!(
            "the map of placed scans is {change:.3} bits less sharp under the optimised trajectory \
             than under dead reckoning (at most {MAX_ENTROPY_INCREASE_BITS}; it should be sharper)"
        ),
    ))
}
