//! The symmetric match: after `S_k` vs `I_j` gave `j_from_k`, `S_j` is
//! matched against `I_k` around its inverse. The two disagree by a few
//! decimetres even when both are right: the strongest echo of a wall seen
//! from two places does not come from the same spot (beam width, grazing
//! incidence), and that bias changes sign with the direction of the match.
//! So a large disagreement flags a wrong match, and the mean of the forward
//! match and the inverse of the reverse one is a better measurement than
//! either (measured: EXPERIMENTS.md § Symmetric match).
//!
//! Loop closures run the reverse match as a climb to the nearest maximum
//! ([`Search::Local`]), sequential matches as a search of the window
//! ([`Search::Global`]). For loops the climb accepts nearly the same loops as a
//! search, at the same ATE, for a third of the search's cost; for the
//! sequential matches, which the reverse check guards against distorted scans,
//! it cost accuracy (measured: EXPERIMENTS.md § Symmetric match).
//!
//! How the two are combined is a [`Fusion`]: loops take the midpoint,
//! sequential matches the information-weighted mean (see [`Fusion`] for
//! why and the measured figures).

use crate::FrontendError;
use crate::image::AcousticImage;
use crate::loops::records::ReverseCheck;
use crate::matcher::{
    CovarianceModel, MatchOptions, MatchResult, MatcherConfig, QualityModel, Search, SearchWindow,
    match_scan_with,
};
use crate::uncertainty::invert;
use echofield_graph::{Se2, wrap_angle};
use nalgebra::{Matrix3, Point2};

/// How the forward match and the inverse of the reverse match are combined
/// into one measurement.
///
/// Loops take the midpoint, sequential matches the information-weighted mean;
/// weighting the loops too made the marina worse (measured: EXPERIMENTS.md §
/// Symmetric match).
/// Our reading, not measured separately: a loop's two matches look at the
/// walls from far-apart places, their viewpoint biases differ in sign and
/// the midpoint cancels them, while the weights lean on one side; the two
/// rotations of a sequential match, a few metres apart, see the walls from
/// nearly the same place and share most of that bias, so weighting by
/// precision loses little there.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fusion {
    /// [`mean_pose`]: the midpoint.
    Midpoint,
    /// [`weighted_mean_pose`] with the two matches' covariances.
    InformationWeighted,
}

/// Tolerances of the symmetric check.
#[derive(Clone, Copy, Debug)]
pub struct Tolerance {
    pub window: SearchWindow,
    pub max_translation_m: f64,
    pub max_rotation_rad: f64,
}

/// Matches `old_scan` (frame `j`) against `new_image` (frame `k`) around
/// the inverse of the `forward` match and compares. Returns the check and,
/// when both agree within the tolerance, the measurement of `j_from_k`
/// combined by `fusion`. `search` is the reverse match's coarse search.
pub fn reverse_match(
    forward: &MatchResult,
    old_scan: &[Point2<f64>],
    new_image: &AcousticImage,
    tolerance: &Tolerance,
    matcher: &MatcherConfig,
    search: Search,
    fusion: Fusion,
) -> Result<(ReverseCheck, Option<Se2>), FrontendError> {
    let (forward_cov, forward) = (&forward.covariance, &forward.image_from_scan);
    // Only the pose of the reverse match is compared: its quality, which
    // no gate reads, is taken on the raster, and its covariance is fitted
    // over the small lattice unless the fusion weighs by it.
    let options = MatchOptions {
        search,
        quality: QualityModel::Raster,
        covariance: match fusion {
            Fusion::Midpoint => CovarianceModel::Inner,
            Fusion::InformationWeighted => CovarianceModel::Surface,
        },
    };
    let outcome = match_scan_with(
        old_scan,
        new_image,
        &forward.inverse(),
        &tolerance.window,
        matcher,
        options,
    )?;
    let Some(r) = outcome.matched() else {
        let check = ReverseCheck {
            matched: None,
            quality: None,
            translation_diff_m: None,
            rotation_diff_rad: None,
        };
        return Ok((check, None));
    };
    let cycle = forward.compose(&r.image_from_scan);
    let check = ReverseCheck {
        matched: Some(r.image_from_scan),
        quality: Some(r.quality.clone()),
        translation_diff_m: Some(cycle.translation().norm()),
        rotation_diff_rad: Some(cycle.theta().abs()),
    };
    let agrees = cycle.translation().norm() <= tolerance.max_translation_m
        && cycle.theta().abs() <= tolerance.max_rotation_rad;
    let measurement = agrees.then(|| {
        let (reverse_inverse, reverse_inverse_cov) = invert(&r.image_from_scan, &r.covariance);
        match fusion {
            Fusion::Midpoint => mean_pose(forward, &reverse_inverse),
            Fusion::InformationWeighted => {
                weighted_mean_pose(forward, forward_cov, &reverse_inverse, &reverse_inverse_cov)
            }
        }
    });
    Ok((check, measurement))
}

/// The information-weighted mean of two nearby pose estimates in vector
/// form, `a + (Ω_a + Ω_b)⁻¹ Ω_b (b - a)` with `Ω = Σ⁻¹` (the angle
/// difference along the shorter arc): the best linear combination of two
/// independent Gaussian estimates. The midpoint when a covariance is not
/// invertible.
pub fn weighted_mean_pose(a: &Se2, cov_a: &Matrix3<f64>, b: &Se2, cov_b: &Matrix3<f64>) -> Se2 {
    let weighted = (|| {
        let (info_a, info_b) = (cov_a.try_inverse()?, cov_b.try_inverse()?);
        let total = (info_a + info_b).try_inverse()?;
        let mut d = b.to_vector() - a.to_vector();
        d.z = wrap_angle(d.z);
        let v = a.to_vector() + total * (info_b * d);
        v.iter()
            .all(|c| c.is_finite())
            .then(|| Se2::new(v.x, v.y, v.z))
    })();
    weighted.unwrap_or_else(|| mean_pose(a, b))
}

/// The midpoint of two nearby poses (vector forms averaged, the angle
/// along the shorter arc).
pub fn mean_pose(a: &Se2, b: &Se2) -> Se2 {
    let d = b.to_vector() - a.to_vector();
    Se2::new(
        a.x() + 0.5 * d.x,
        a.y() + 0.5 * d.y,
        a.theta() + 0.5 * wrap_angle(d.z),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weighted_mean_leans_on_the_better_estimate() {
        let (a, b) = (Se2::new(1.0, 2.0, 0.1), Se2::new(1.4, 1.0, 0.2));
        let same = Matrix3::from_diagonal(&nalgebra::Vector3::new(0.04, 0.09, 0.001));
        let m = weighted_mean_pose(&a, &same, &b, &same);
        let mid = mean_pose(&a, &b);
        assert!((m.to_vector() - mid.to_vector()).norm() < 1e-12);
        // b four times as precise in x only: x moves 4/5 of the way to b.
        let tight_x = Matrix3::from_diagonal(&nalgebra::Vector3::new(0.01, 0.09, 0.001));
        let m = weighted_mean_pose(&a, &same, &b, &tight_x);
        assert!((m.x() - (1.0 + 0.8 * 0.4)).abs() < 1e-12, "{m:?}");
        assert!((m.y() - 1.5).abs() < 1e-12 && (m.theta() - 0.15).abs() < 1e-12);
        // Across ±π the angle takes the short arc.
        let (c, d) = (Se2::new(0.0, 0.0, 3.1), Se2::new(0.0, 0.0, -3.1));
        let m = weighted_mean_pose(&c, &same, &d, &same);
        assert!((m.theta().abs() - std::f64::consts::PI).abs() < 1e-9);
        // A singular covariance falls back to the midpoint.
        let m = weighted_mean_pose(&a, &Matrix3::zeros(), &b, &same);
        assert!((m.to_vector() - mid.to_vector()).norm() < 1e-12);
    }

    #[test]
    fn mean_pose_takes_the_short_arc() {
        let a = Se2::new(1.0, 0.0, 3.1);
        let b = Se2::new(2.0, 1.0, -3.1);
        let m = mean_pose(&a, &b);
        assert!((m.x() - 1.5).abs() < 1e-12 && (m.y() - 0.5).abs() < 1e-12);
        assert!((m.theta().abs() - std::f64::consts::PI).abs() < 1e-9);
    }
}
