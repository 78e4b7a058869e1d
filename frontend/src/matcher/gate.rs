//! The search window and the acceptance gate of one scan match, shared by
//! the sequential matches (`[sequential.gate]`) and the loop closures
//! (`[loops.gate]`): one type, each section with its own defaults.
//!
//! A match of `S_k` against `I_j` with prior `j_from_k` of covariance `Σ`
//! searches `n_sigma` standard deviations of `Σ` per axis, clamped to
//! `[min_window, max_window]` ([`MatchGate::window`]). It is used only when
//! its mean image intensity under the points reaches `min_mean_intensity`;
//! its edge covariance is the score surface's, inflated to at least
//! `min_sigma` per axis; and with the symmetric check, the reverse match
//! (`S_j` against `I_k`, searched within [`MatchGate::reverse_window`] of
//! the inverse of the forward match) must agree with it to within
//! `reverse_max_translation_m` and [`REVERSE_MAX_ROTATION_RAD`].
//!
//! Windows are `[x_m, y_m, theta_rad]` in the reference node's frame
//! (metres, metres, radians; one config key each, see
//! [`window_key`](super::window_key)).

use super::SearchWindow;
use super::symmetric::Tolerance;
use crate::config_check::{check_positive_window, check_range, check_window, check_window_order};
use crate::error::FrontendError;
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

/// Largest rotation between the forward match and the inverse of the
/// reverse one, rad: 2°, for sequential and loop matches alike. Not a
/// config key: the heading of a right match is fixed to well under a
/// degree by the walls of both scans, so two right matches of one pair
/// agree in heading far more closely than in position (where the strongest
/// echo of a wall seen from two places is not the same spot), and the
/// translation tolerance, which does differ between the two uses, is the
/// one a user tunes.
pub const REVERSE_MAX_ROTATION_RAD: f64 = 2.0_f64.to_radians();

/// How one match is searched and accepted (module doc). Each section that
/// matches scans holds one: `SequentialConfig::gate`, `LoopConfig::gate`.
///
/// No `Default`: the two uses have different defaults
/// ([`MatchGate::sequential`], [`MatchGate::loops`]), which their sections'
/// defaults supply. Deserialised alone, a gate needs every key; a config
/// file laid over the defaults (the tools crate's `config_file`) may set
/// any of them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MatchGate {
    /// Search half-width in standard deviations of the prior's covariance
    /// (the dead-reckoning motion for sequential matches, the relative
    /// uncertainty of the two nodes in the current graph for loops).
    pub n_sigma: f64,
    /// Smallest search half-widths `[x_m, y_m, theta_rad]`; also the
    /// window of the reverse match around the inverse of the forward one.
    #[serde(with = "super::window_key")]
    pub min_window: SearchWindow,
    /// Largest search half-widths `[x_m, y_m, theta_rad]`.
    #[serde(with = "super::window_key")]
    pub max_window: SearchWindow,
    /// A match whose mean image intensity under the points
    /// (`MatchQuality::mean_intensity`, 0-1) is below this is not used.
    pub min_mean_intensity: f64,
    /// Smallest standard deviations `[x_m, y_m, theta_rad]` of the edge: the
    /// match covariance is inflated to at least these (the score surface's
    /// covariance does not hold the errors of motion compensation, which
    /// grow with the dead-reckoning error inside a rotation).
    #[serde(with = "super::window_key")]
    pub min_sigma: SearchWindow,
    /// Largest disagreement of the forward match and the inverse of the
    /// reverse one, m (symmetric check).
    pub reverse_max_translation_m: f64,
}

impl MatchGate {
    /// The gate of sequential matches (`[sequential.gate]`): windows 0.5 m,
    /// 0.5 m, 3° to 3 m, 3 m, 15°; intensity 0.15; σ at least 0.1 m, 0.1 m,
    /// 0.75°; reverse agreement 0.75 m.
    pub fn sequential() -> Self {
        Self {
            n_sigma: 3.0,
            min_window: SearchWindow::new(0.5, 0.5, 3.0_f64.to_radians()),
            max_window: SearchWindow::new(3.0, 3.0, 15.0_f64.to_radians()),
            min_mean_intensity: 0.15,
            min_sigma: SearchWindow::new(0.1, 0.1, 0.75_f64.to_radians()),
            reverse_max_translation_m: 0.75,
        }
    }

    /// The gate of loop closures (`[loops.gate]`): windows 0.5 m, 0.5 m, 3°
    /// to 10 m, 10 m, 10° (a candidate beyond `max_window` is deferred);
    /// intensity 0.30, set with the images' off-axis suppression, which
    /// lowers the intensity around the walls that a slightly distorted scan
    /// lands on; σ at least 0.05 m, 0.05 m, 0.5°; reverse agreement 0.6 m
    /// (two right matches of one pair often disagree by just over 0.5 m).
    pub fn loops() -> Self {
        Self {
            n_sigma: 3.0,
            min_window: SearchWindow::new(0.5, 0.5, 3.0_f64.to_radians()),
            max_window: SearchWindow::new(10.0, 10.0, 10.0_f64.to_radians()),
            min_mean_intensity: 0.30,
            min_sigma: SearchWindow::new(0.05, 0.05, 0.5_f64.to_radians()),
            reverse_max_translation_m: 0.6,
        }
    }

    /// The searched window for a prior of covariance `prior_covariance`
    /// (x m², y m², θ rad²): `n_sigma` standard deviations per axis clamped
    /// to `[min_window, max_window]` (an infinite variance gives
    /// `max_window`).
    pub fn window(&self, prior_covariance: &Matrix3<f64>) -> SearchWindow {
        SearchWindow::from_covariance(
            prior_covariance,
            self.n_sigma,
            &self.min_window,
            &self.max_window,
        )
    }

    /// The window of the reverse match around the inverse of the forward
    /// one: `min_window`. Derived rather than a key: the forward match has
    /// already placed the pair to within the search's own resolution, so
    /// the reverse match needs no more room than the smallest forward
    /// search gets.
    pub fn reverse_window(&self) -> SearchWindow {
        self.min_window
    }

    /// The tolerance of the symmetric check.
    pub fn reverse_tolerance(&self) -> Tolerance {
        Tolerance {
            window: self.reverse_window(),
            max_translation_m: self.reverse_max_translation_m,
            max_rotation_rad: REVERSE_MAX_ROTATION_RAD,
        }
    }

    /// Checks every key; errors name it as `{section}.gate.{key}`
    /// (`loops.gate.min_window[2] (theta_rad)`).
    pub fn validate(&self, section: &str) -> Result<(), FrontendError> {
        let key = |name: &str| format!("{section}.gate.{name}");
        check_range(&key("n_sigma"), self.n_sigma, 0.1, 100.0)?;
        check_window(&key("min_window"), &self.min_window)?;
        check_window(&key("max_window"), &self.max_window)?;
        check_positive_window(&key("max_window"), &self.max_window)?;
        check_window_order(
            &key("min_window"),
            &self.min_window,
            &key("max_window"),
            &self.max_window,
        )?;
        check_range(
            &key("min_mean_intensity"),
            self.min_mean_intensity,
            0.0,
            1.0,
        )?;
        check_window(&key("min_sigma"), &self.min_sigma)?;
        check_range(
            &key("reverse_max_translation_m"),
            self.reverse_max_translation_m,
            0.0,
            100.0,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_window_is_n_sigma_clamped_to_the_gate() {
        let gate = MatchGate::sequential();
        let small = Matrix3::from_diagonal(&nalgebra::Vector3::new(0.01, 0.25, 1.0));
        let w = gate.window(&small);
        // 3 · 0.1 = 0.3 < 0.5 → 0.5; 3 · 0.5 = 1.5; 3 · 1 rad > 15° → 15°.
        assert_eq!(w.x_m, 0.5);
        assert!((w.y_m - 1.5).abs() < 1e-12);
        assert_eq!(w.theta_rad, gate.max_window.theta_rad);
        let unknown = Matrix3::from_diagonal_element(f64::INFINITY);
        assert_eq!(gate.window(&unknown), gate.max_window);
    }

    #[test]
    fn the_reverse_check_searches_the_smallest_window() {
        let gate = MatchGate::loops();
        let t = gate.reverse_tolerance();
        assert_eq!(t.window, gate.min_window);
        assert_eq!(t.max_translation_m, 0.6);
        assert!((t.max_rotation_rad.to_degrees() - 2.0).abs() < 1e-12);
    }

    #[test]
    fn a_bad_key_is_named_with_its_section() {
        let gate = MatchGate {
            min_window: SearchWindow::new(0.5, 0.5, 0.3),
            ..MatchGate::loops()
        };
        let e = gate.validate("loops").unwrap_err().to_string();
        assert!(e.contains("loops.gate.min_window[2] (theta_rad)"), "{e}");
        let gate = MatchGate {
            n_sigma: f64::NAN,
            ..MatchGate::sequential()
        };
        let e = gate.validate("sequential").unwrap_err().to_string();
        assert!(e.contains("sequential.gate.n_sigma"), "{e}");
    }
}
