//! The symmetric match: after `S_k` vs `I_j` gave `j_from_k`, `S_j` is
//! matched against `I_k` around its inverse. The two disagree by a few
//! decimetres even when both are right: the strongest echo of a wall seen
//! from two places does not come from the same spot (beam width, grazing
//! incidence), and that bias changes sign with the direction of the match.
//! So a large disagreement flags a wrong match, and the mean of the forward
//! match and the inverse of the reverse one is a better measurement than
//! either (on the simulated marina the error of loop measurements drops
//! from 0.29 m to 0.22 m RMS).
//!
//! Loop closures run the reverse match as a climb to the nearest maximum
//! ([`Search::Local`]), sequential matches as a search of the window
//! ([`Search::Global`]). Over ten simulated missions (marina seeds 1-6, St
//! Pere 1-3, canyon) the climb accepts the same loops to within a few (St Pere
//! seed 1: 473 against 472, 465 true positives either way), moves the ATE
//! by at most 0.017 m in either direction, and costs a third of the
//! search: 4.8% fewer instructions over a St Pere run. For the sequential
//! matches, which the reverse check guards against distorted scans, the
//! climb cost accuracy (marina seed 2: ATE 0.309 -> 0.348 m).

use super::result::ReverseCheck;
use echofield_frontend::FrontendError;
use echofield_frontend::image::AcousticImage;
use echofield_frontend::matcher::{
    MatcherConfig, QualityModel, Search, SearchWindow, match_scan_with,
};
use echofield_graph::{Se2, wrap_angle};
use nalgebra::Point2;

/// Tolerances of the symmetric check.
#[derive(Clone, Copy, Debug)]
pub struct Tolerance {
    pub window: SearchWindow,
    pub max_translation_m: f64,
    pub max_rotation_rad: f64,
}

/// Matches `old_scan` (frame `j`) against `new_image` (frame `k`) around
/// `forward⁻¹` and compares. Returns the check and, when both agree within
/// the tolerance, the combined measurement of `j_from_k`. `local` climbs
/// to the nearest maximum instead of searching the window
/// ([`Search::Local`]).
pub fn reverse_match(
    forward: &Se2,
    old_scan: &[Point2<f64>],
    new_image: &AcousticImage,
    tolerance: &Tolerance,
    matcher: &MatcherConfig,
    local: bool,
) -> Result<(ReverseCheck, Option<Se2>), FrontendError> {
    let search = if local { Search::Local } else { Search::Global };
    // Only the pose of the reverse match is compared: its quality, which
    // no gate reads, is taken on the raster.
    let outcome = match_scan_with(
        old_scan,
        new_image,
        &forward.inverse(),
        &tolerance.window,
        matcher,
        search,
        QualityModel::Raster,
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
    let measurement = agrees.then(|| mean_pose(forward, &r.image_from_scan.inverse()));
    Ok((check, measurement))
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
    fn mean_pose_takes_the_short_arc() {
        let a = Se2::new(1.0, 0.0, 3.1);
        let b = Se2::new(2.0, 1.0, -3.1);
        let m = mean_pose(&a, &b);
        assert!((m.x() - 1.5).abs() < 1e-12 && (m.y() - 0.5).abs() < 1e-12);
        assert!((m.theta().abs() - std::f64::consts::PI).abs() < 1e-9);
    }
}
