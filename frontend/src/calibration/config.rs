//! `[calibration]`: the few settings of the mounting calibration, and the
//! one value derived from the data (the cell size).

use crate::error::FrontendError;
use serde::{Deserialize, Serialize};

/// Settings of [`super::calibrate`]. Every key has a default that suits a
/// mechanically scanned head of any range; the cell size is derived from
/// the data unless given.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CalibrationConfig {
    /// Consecutive rotations placed together in one window of the
    /// objective (the module doc of [`super`]). Longer windows see each
    /// wall from more places (a sharper minimum) but carry more of the dead
    /// reckoning's drift, which blurs every candidate alike. Default 6
    /// (about 80 s of a head that turns once in 14 s). At least 2.
    pub window_rotations: usize,
    /// Side of the cells the returns are splatted on, metres. `None` (the
    /// default) derives it from the data ([`derive_cell_size_m`]: half the
    /// beam spacing at the median range of the returns).
    pub cell_size_m: Option<f64>,
    /// Step of the coarse grid of the head's yaw over the full circle,
    /// degrees; each combination's best grid point is then refined. It must
    /// be finer than the basin of the objective's minimum (a few cells at
    /// the median range). Default 5.
    pub coarse_yaw_step_deg: f64,
    /// Blocks of consecutive windows in the block jackknife that gives the
    /// uncertainties and the discrete choices' votes. Default 10; at least
    /// 6 (the fewest with which a vote can be significant). A mission with
    /// fewer windows uses one block per window.
    pub jackknife_blocks: usize,
}

impl Default for CalibrationConfig {
    fn default() -> Self {
        Self {
            window_rotations: 6,
            cell_size_m: None,
            coarse_yaw_step_deg: 5.0,
            jackknife_blocks: 10,
        }
    }
}

/// The fewest blocks (and so windows) the calibration accepts: with fewer,
/// no block vote can be significant (`uncertainty::signed_rank_p_value`).
pub const MIN_BLOCKS: usize = 6;

impl CalibrationConfig {
    /// Checks every value; never changes one.
    pub fn validate(&self) -> Result<(), FrontendError> {
        if self.window_rotations < 2 {
            return Err(FrontendError::config(
                "window_rotations",
                format!(
                    "must be at least 2 (one rotation alone says nothing about the mounting), got {}",
                    self.window_rotations
                ),
            ));
        }
        if let Some(cell) = self.cell_size_m
            && !(cell.is_finite() && cell > 0.0 && cell <= 10.0)
        {
            return Err(FrontendError::config(
                "cell_size_m",
                format!("must be in (0, 10] m, got {cell}"),
            ));
        }
        let step = self.coarse_yaw_step_deg;
        if !(step.is_finite() && step > 0.0 && step <= 45.0) {
            return Err(FrontendError::config(
                "coarse_yaw_step_deg",
                format!("must be in (0, 45] degrees, got {step}"),
            ));
        }
        if self.jackknife_blocks < MIN_BLOCKS {
            return Err(FrontendError::config(
                "jackknife_blocks",
                format!(
                    "must be at least {MIN_BLOCKS}, got {}",
                    self.jackknife_blocks
                ),
            ));
        }
        Ok(())
    }
}

/// The derived cell size: half the arc between neighbouring beams at the
/// median range of the returns, `r_med · Δθ / 2`, and never below two
/// range bins.
///
/// Why: the entropy of a splat pulls a placement towards putting its
/// walls along the lattice's rows of cells, a pull that grows with the
/// cell (the two offset lattices of [`super::objective`] cancel most of
/// it, not all); far below the beam spacing, on the other hand, each
/// rotation samples a wall at points farther apart than the cells, and the
/// entropy jumps with where the samples fall. At half the spacing the
/// bilinear splat still spreads the returns of one rotation over touching
/// cells. Two bins is the finest spacing along range the segmentation
/// resolves. `None` when an input is not positive and finite.
pub fn derive_cell_size_m(median_range_m: f64, beam_step_rad: f64, bin_size_m: f64) -> Option<f64> {
    let ok = |v: f64| v.is_finite() && v > 0.0;
    (ok(median_range_m) && ok(beam_step_rad) && ok(bin_size_m))
        .then(|| (0.5 * median_range_m * beam_step_rad).max(2.0 * bin_size_m))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_bad_values_name_their_key() {
        CalibrationConfig::default().validate().unwrap();
        let bad = [
            CalibrationConfig {
                window_rotations: 1,
                ..Default::default()
            },
            CalibrationConfig {
                cell_size_m: Some(0.0),
                ..Default::default()
            },
            CalibrationConfig {
                coarse_yaw_step_deg: f64::NAN,
                ..Default::default()
            },
            CalibrationConfig {
                jackknife_blocks: 5,
                ..Default::default()
            },
        ];
        let keys = [
            "window_rotations",
            "cell_size_m",
            "coarse_yaw_step_deg",
            "jackknife_blocks",
        ];
        for (config, key) in bad.iter().zip(keys) {
            let err = config.validate().unwrap_err().to_string();
            assert!(err.contains(key), "{err}");
        }
    }

    #[test]
    fn the_cell_is_half_the_beam_spacing_at_the_median_range_and_at_least_two_bins() {
        let step = std::f64::consts::TAU / 200.0;
        let cell = derive_cell_size_m(20.0, step, 0.1).unwrap();
        assert!((cell - 10.0 * step).abs() < 1e-12);
        assert_eq!(derive_cell_size_m(4.0, step, 0.1), Some(0.2));
        assert_eq!(derive_cell_size_m(f64::NAN, step, 0.1), None);
        assert_eq!(derive_cell_size_m(20.0, 0.0, 0.1), None);
    }
}
