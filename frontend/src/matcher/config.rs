//! Configuration of the matcher.

use crate::config_check::check_positive;
use crate::error::FrontendError;
use serde::{Deserialize, Serialize};

/// Configuration of the scan matcher.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MatcherConfig {
    /// Scans with fewer points give `NoMatch(TooFewPoints)`.
    pub min_points: usize,
    /// Longer scans are thinned to this many points (every k-th point in
    /// scan order), bounding the cost of a match.
    pub max_points: usize,
    /// Angular step of the coarse search, radians; `None` derives it as
    /// cell size / RMS range of the scan's points (a point at that range
    /// moves one cell, the farthest ones more, and the quadratic fit takes
    /// the pose between lattice angles). Stepping by the farthest point
    /// instead was slower for no better accuracy (measured: EXPERIMENTS.md
    /// § Matcher).
    pub angle_step_rad: Option<f64>,
    /// `τ` of the covariance `Σ = τ (-H)⁻¹` (see [`covariance`](crate::matcher::covariance)), in
    /// intensity units; larger is more conservative. Default 1 (its
    /// consistency on simulated missions: EXPERIMENTS.md § Matcher).
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): 1, the Laplace approximation itself; the loop and sequential covariances are floored by the gates' `min_sigma` instead.
    #[serde(skip)]
    pub covariance_scale: f64,
    /// Refine each match away from the rim of the image's reach
    /// ([`rim`](crate::matcher::rim)): from the search's lattice pose, a
    /// climb of at most a few lattice steps on the mean of `I` over the
    /// scan points the pose puts inside the rim, and the covariance and
    /// pose fits on the points that stay inside it. Images without a known
    /// reach (made from a grid) are matched without it.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default,
    /// false, the match on the sum over every point; library callers may
    /// turn it on). Off by default until the localisation tests pass with
    /// it (EXPERIMENTS.md § Long missions, the mean inside the rim).
    #[serde(skip)]
    pub refine_inside_reach: bool,
}

impl Default for MatcherConfig {
    fn default() -> Self {
        Self {
            min_points: 10,
            max_points: 500,
            angle_step_rad: None,
            covariance_scale: 1.0,
            refine_inside_reach: false,
        }
    }
}

impl MatcherConfig {
    pub fn validate(&self) -> Result<(), FrontendError> {
        if self.min_points == 0 {
            return Err(FrontendError::config("min_points", "must be at least 1"));
        }
        if self.max_points < self.min_points {
            return Err(FrontendError::config(
                "max_points",
                format!(
                    "must be >= min_points ({}), got {}",
                    self.min_points, self.max_points
                ),
            ));
        }
        if let Some(step) = self.angle_step_rad {
            check_positive("angle_step_rad", step)?;
        }
        check_positive("covariance_scale", self.covariance_scale)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invalid_configs_and_windows_are_named() {
        MatcherConfig::default().validate().unwrap();
        let bad = MatcherConfig {
            max_points: 5,
            ..MatcherConfig::default()
        };
        assert!(
            bad.validate()
                .unwrap_err()
                .to_string()
                .contains("max_points")
        );
    }
}
