//! Monte Carlo localisation on a prior acoustic map: the seed paper's
//! closing remark ("the proposed score function could be directly used to
//! evaluate particles in Monte Carlo Localization") made into a particle
//! filter over SE(2).
//!
//! - [`field`]: the map as one likelihood field `I(x)` in the map's world
//!   frame (the acoustic images of the map's nodes placed at their
//!   optimised poses), with the area the map's sonar covered.
//! - [`particles`]: weighted poses, the weighted mean and spread, and
//!   KLD-sampling resampling (Fox 2003) that adapts the particle count to
//!   how spread the belief is.
//! - [`filter`]: [`MonteCarloLocalizer`]: per rotation, the particles move
//!   by the relative motion since the previous rotation sampled from its
//!   covariance (the dead reckoning's, fused by the CLI with the sonar's own
//!   sequential match: `echofield::localize::odometry`),
//!   are weighted by the score of eq. (5), `s(x) = Σ_i I(x ⊕ p_i)`, of the
//!   rotation's scan `S_k`, and are resampled; a state machine says whether
//!   the vehicle is localised, searching, coasting on dead reckoning or
//!   lost (kidnapped), and re-seeds the particles over the whole map when
//!   the scans stop fitting.
//!
//! The filter is deterministic: one ChaCha stream seeded by
//! [`LocalizationConfig::seed`], consumed in a fixed order on one thread.

pub mod field;
pub mod filter;
pub mod particles;
pub mod refine;

pub use field::LikelihoodField;
pub use filter::{LocalizationState, LocalizationStep, MonteCarloLocalizer};
pub use particles::Particle;

use crate::config_check::check_positive;
use crate::error::FrontendError;
use serde::{Deserialize, Serialize};

/// Configuration of the particle filter (`[localize]` of
/// `tools/configs/localize.toml`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LocalizationConfig {
    /// Seed of the filter's random stream (sampling, resampling).
    pub seed: u64,
    /// Fewest particles kept when the belief is concentrated.
    pub min_particles: usize,
    /// Most particles; also the number spread over the whole map at a
    /// global start and after a kidnapping is detected.
    pub max_particles: usize,
    /// KLD sampling: bound on the Kullback-Leibler distance between the
    /// particle approximation and the belief (smaller: more particles).
    pub kld_epsilon: f64,
    /// KLD sampling: upper standard-normal quantile of the bound's
    /// confidence (2.326 for 99%).
    pub kld_z: f64,
    /// KLD sampling: side of a histogram bin in position, m.
    pub kld_bin_m: f64,
    /// KLD sampling: side of a histogram bin in heading, rad.
    pub kld_bin_rad: f64,
    /// Standard deviation of the particles' heading around the compass
    /// heading at a global start, rad (the map and the mission share the
    /// compass's frame up to the heading units' biases); π or more spreads
    /// the heading uniformly.
    pub global_heading_sigma_rad: f64,
    /// Log-likelihood of a scan per unit of mean field value: a particle
    /// whose scan points meet a mean `I` larger by `d` gets `exp(gain · d)`
    /// times the weight. Larger: a sharper, more confident filter.
    pub score_gain: f64,
    /// Scan points scored per particle (every n-th point of `S_k`, evenly
    /// over the rotation).
    pub max_scan_points: usize,
    /// Side of a cell of the likelihood field, m.
    pub field_cell_m: f64,
    /// Gaussian smoothing of the likelihood field, m (widens the basin of
    /// the score against the particles' spacing and the map's errors).
    pub field_smoothing_m: f64,
    /// How the map's node images combine where they overlap in the field
    /// the particles are weighed on and the scans' fit is judged on
    /// (`min_fit`, the state).
    pub field_blend: FieldBlend,
    /// How they combine in the field the estimate is refined on
    /// (`estimate = "refined"`); when it equals `field_blend`, one field
    /// serves both.
    pub refine_blend: FieldBlend,
    /// Field value of a scan point that falls where the map's sonar never
    /// looked (neither evidence for nor against a pose), 0-1.
    pub unknown_value: f64,
    /// Factor on the dead reckoning's relative covariance between
    /// rotations when the particles are moved.
    pub motion_noise_scale: f64,
    /// Smallest standard deviation of a particle's motion per rotation
    /// along x and y, m (keeps the cloud from collapsing).
    pub motion_noise_floor_m: f64,
    /// Smallest standard deviation of a particle's heading change per
    /// rotation, rad.
    pub motion_noise_floor_rad: f64,
    /// The belief counts as converged when the weighted position spread
    /// (square root of the covariance's trace) is below this, m.
    pub converged_spread_m: f64,
    /// Mean field value of the scan points (those inside the map's
    /// coverage) at the estimate below which the scan does not fit the map.
    pub min_fit: f64,
    /// Fraction of the scan points inside the map's coverage below which
    /// the sonar sees too little of the map to judge the fit: the filter
    /// coasts on dead reckoning.
    pub min_coverage: f64,
    /// Consecutive rotations whose scan does not fit a converged belief
    /// after which the vehicle counts as lost (kidnapped) and the particles
    /// are spread over the whole map again.
    pub lost_after_rotations: usize,
    /// What the per-rotation estimate is: the particles' weighted mean, or
    /// that mean refined to the nearest peak of the scan's score on the
    /// map ([`refine`]) when the scan sees the map.
    pub estimate: Estimate,
    /// Largest distance of the refined estimate from the weighted mean, m.
    pub refine_max_shift_m: f64,
}

/// [`LocalizationConfig::field_blend`] and [`LocalizationConfig::refine_blend`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FieldBlend {
    /// The strongest echo any node saw in the cell.
    Max,
    /// The mean over the nodes that saw an echo in the cell.
    Mean,
}

/// [`LocalizationConfig::estimate`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Estimate {
    /// The particles' weighted mean (the posterior mean).
    Mean,
    /// The particle of the largest weight.
    BestParticle,
    /// The weighted mean moved to the nearest peak of the scan's score on
    /// the map (plus the compass term), within `refine_max_shift_m`; the
    /// mean itself when the scan sees too little of the map.
    Refined,
}

impl Default for LocalizationConfig {
    fn default() -> Self {
        Self {
            seed: 1,
            min_particles: 1000,
            max_particles: 20_000,
            kld_epsilon: 0.05,
            kld_z: 2.326,
            kld_bin_m: 0.5,
            kld_bin_rad: 0.1745,
            global_heading_sigma_rad: 0.26,
            score_gain: 300.0,
            max_scan_points: 1000,
            field_cell_m: 0.25,
            field_smoothing_m: 0.15,
            field_blend: FieldBlend::Max,
            refine_blend: FieldBlend::Mean,
            unknown_value: 0.1,
            motion_noise_scale: 1.0,
            motion_noise_floor_m: 0.03,
            motion_noise_floor_rad: 0.005,
            converged_spread_m: 1.5,
            min_fit: 0.65,
            min_coverage: 0.3,
            lost_after_rotations: 3,
            estimate: Estimate::Refined,
            refine_max_shift_m: 1.0,
        }
    }
}

impl LocalizationConfig {
    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), FrontendError> {
        let unit = |field: &str, v: f64| {
            if (0.0..=1.0).contains(&v) {
                Ok(())
            } else {
                Err(FrontendError::config(
                    field,
                    format!("must be within [0, 1], got {v}"),
                ))
            }
        };
        if self.min_particles < 10 || self.min_particles > self.max_particles {
            return Err(FrontendError::config(
                "min_particles",
                format!(
                    "must be at least 10 and at most max_particles ({}), got {}",
                    self.max_particles, self.min_particles
                ),
            ));
        }
        if self.max_particles > 10_000_000 {
            return Err(FrontendError::config(
                "max_particles",
                format!("must be at most 10000000, got {}", self.max_particles),
            ));
        }
        check_positive("kld_epsilon", self.kld_epsilon)?;
        check_positive("kld_z", self.kld_z)?;
        check_positive("kld_bin_m", self.kld_bin_m)?;
        check_positive("kld_bin_rad", self.kld_bin_rad)?;
        check_positive("global_heading_sigma_rad", self.global_heading_sigma_rad)?;
        check_positive("score_gain", self.score_gain)?;
        if self.max_scan_points == 0 {
            return Err(FrontendError::config("max_scan_points", "must be > 0"));
        }
        check_positive("field_cell_m", self.field_cell_m)?;
        if !(self.field_smoothing_m.is_finite() && self.field_smoothing_m >= 0.0) {
            return Err(FrontendError::config(
                "field_smoothing_m",
                format!("must be finite and >= 0, got {}", self.field_smoothing_m),
            ));
        }
        unit("unknown_value", self.unknown_value)?;
        check_positive("motion_noise_scale", self.motion_noise_scale)?;
        check_positive("motion_noise_floor_m", self.motion_noise_floor_m)?;
        check_positive("motion_noise_floor_rad", self.motion_noise_floor_rad)?;
        check_positive("converged_spread_m", self.converged_spread_m)?;
        unit("min_fit", self.min_fit)?;
        unit("min_coverage", self.min_coverage)?;
        if self.lost_after_rotations == 0 {
            return Err(FrontendError::config("lost_after_rotations", "must be > 0"));
        }
        check_positive("refine_max_shift_m", self.refine_max_shift_m)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_are_valid_and_bad_values_are_named() {
        LocalizationConfig::default().validate().unwrap();
        let bad = LocalizationConfig {
            min_particles: 50_000,
            ..LocalizationConfig::default()
        };
        let err = bad.validate().unwrap_err().to_string();
        assert!(err.contains("min_particles"), "{err}");
        let bad = LocalizationConfig {
            min_fit: 1.5,
            ..LocalizationConfig::default()
        };
        let err = bad.validate().unwrap_err().to_string();
        assert!(err.contains("min_fit"), "{err}");
    }
}
