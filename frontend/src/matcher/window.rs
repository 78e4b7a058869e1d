//! The one window type of echofield ([`SearchWindow`]): per-axis values
//! `(x_m, y_m, theta_rad)` in the frame of the reference node.

use crate::error::FrontendError;
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Three per-axis values in the frame of the reference node: the
/// half-widths of a searched window around the prior, or standard
/// deviations (`[loops] max_sigma`). The one window type of echofield: the
/// matcher searches it and the config sections spell it (unknown keys are
/// refused).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SearchWindow {
    /// Along the x axis of the reference node's frame, metres.
    pub x_m: f64,
    /// Along its y axis, metres.
    pub y_m: f64,
    /// In heading, radians; at most π (a whole turn).
    pub theta_rad: f64,
}

impl SearchWindow {
    /// The standard deviations of `covariance` (x m, y m, θ rad) are
    /// within these values on every axis.
    pub fn bounds_sigma(&self, covariance: &Matrix3<f64>) -> bool {
        covariance[(0, 0)].sqrt() <= self.x_m
            && covariance[(1, 1)].sqrt() <= self.y_m
            && covariance[(2, 2)].sqrt() <= self.theta_rad
    }

    /// `(key, value)` per axis, in TOML order.
    pub fn axes(&self) -> [(&'static str, f64); 3] {
        [
            ("x_m", self.x_m),
            ("y_m", self.y_m),
            ("theta_rad", self.theta_rad),
        ]
    }

    pub const fn new(x_m: f64, y_m: f64, theta_rad: f64) -> Self {
        Self {
            x_m,
            y_m,
            theta_rad,
        }
    }

    /// `n_sigma` standard deviations of the prior covariance `(x, y, θ)`
    /// per axis, each clamped to `[min, max]` (`max` wins where `min`
    /// exceeds it; never panics).
    pub fn from_covariance(
        covariance: &Matrix3<f64>,
        n_sigma: f64,
        min: &SearchWindow,
        max: &SearchWindow,
    ) -> Self {
        let axis = |k: usize, lo: f64, hi: f64| {
            let variance = covariance[(k, k)];
            if !variance.is_finite() {
                return hi; // unknown uncertainty: search as widely as allowed
            }
            (n_sigma * variance.max(0.0).sqrt()).max(lo).min(hi)
        };
        Self {
            x_m: axis(0, min.x_m, max.x_m),
            y_m: axis(1, min.y_m, max.y_m),
            theta_rad: axis(2, min.theta_rad, max.theta_rad),
        }
    }

    pub fn validate(&self) -> Result<(), FrontendError> {
        let ok = |v: f64| v.is_finite() && v >= 0.0;
        if !(ok(self.x_m) && ok(self.y_m) && ok(self.theta_rad) && self.theta_rad <= PI) {
            return Err(FrontendError::input(
                "search window",
                "x_m/y_m/theta_rad",
                format!("must be finite, >= 0 and theta <= π, got {self:?}"),
            ));
        }
        Ok(())
    }

    /// `(x_m, y_m, theta_rad)`.
    pub fn as_vector(&self) -> Vector3<f64> {
        Vector3::new(self.x_m, self.y_m, self.theta_rad)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_from_covariance_is_clamped_per_axis() {
        let cov = Matrix3::from_diagonal(&Vector3::new(0.01, 4.0, 1e-6));
        let min = SearchWindow::new(0.5, 0.5, 0.05);
        let max = SearchWindow::new(5.0, 5.0, 0.5);
        let w = SearchWindow::from_covariance(&cov, 3.0, &min, &max);
        assert_eq!(w, SearchWindow::new(0.5, 5.0, 0.05));
        let nan = Matrix3::from_diagonal(&Vector3::new(f64::NAN, 1.0, 0.01));
        let w = SearchWindow::from_covariance(&nan, 3.0, &min, &max);
        assert_eq!(w.x_m, 5.0);
        assert!((w.theta_rad - 0.3).abs() < 1e-12);
    }

    #[test]
    fn an_invalid_window_is_named() {
        let err = SearchWindow::new(1.0, 1.0, 4.0).validate().unwrap_err();
        assert!(err.to_string().contains("theta"), "{err}");
    }
}
