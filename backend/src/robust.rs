//! Robust kernels: they replace an edge's squared Mahalanobis error
//! `s = eᵀΩe` by `ρ(s)` so that gross outliers (false loop closures) stop
//! dominating the solution.
//!
//! The solver uses iteratively reweighted least squares: each linearisation
//! scales the edge's information by the weight `w = ρ'(s)` (for DCS the
//! scale `s_ij²` of the paper), and the step acceptance of
//! Levenberg-Marquardt compares the robust cost `Σ ρ(s)`.

use serde::{Deserialize, Serialize};

/// A robust kernel and its parameter.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum RobustKernel {
    /// Plain least squares, `ρ(s) = s`.
    #[default]
    None,
    /// Huber: quadratic up to a Mahalanobis error `delta` (dimensionless,
    /// in standard deviations), linear beyond:
    /// `ρ(s) = s` for `s ≤ δ²`, else `2δ√s − δ²`.
    Huber { delta: f64 },
    /// Cauchy (Lorentzian): `ρ(s) = c² ln(1 + s/c²)`, `c` in standard
    /// deviations; the weight `1/(1 + s/c²)` keeps decaying for outliers.
    Cauchy { c: f64 },
    /// Dynamic Covariance Scaling (Agarwal, Tipaldi, Spinello, Stachniss,
    /// Burgard, ICRA 2013): the error is scaled by
    /// `s_ij = min(1, 2Φ/(Φ + χ²))`, so the normal equations get the weight
    /// `s_ij²`. `phi` (Φ) is a χ² value; the paper recommends Φ = 1. The cost
    /// that goes with this weight (its integral, continuous at Φ) is
    /// `ρ(χ²) = χ²` up to Φ and `3Φ − 4Φ²/(Φ + χ²)` beyond, bounded by 3Φ:
    /// Levenberg-Marquardt compares this cost when it accepts a step.
    /// (Using `s_ij² χ²` instead, as some implementations do, makes the cost
    /// *fall* as an edge's error grows past Φ, which rewards pushing true
    /// loop closures away.)
    Dcs { phi: f64 },
}

impl RobustKernel {
    /// Huber with δ = 2.796, the square root of the 95% quantile of χ²
    /// with 3 degrees of freedom (7.815): an edge whose error is consistent
    /// with its covariance keeps its full weight.
    pub const HUBER_DEFAULT: RobustKernel = RobustKernel::Huber { delta: 2.796 };
    /// Cauchy with c = 2.796, as for Huber.
    pub const CAUCHY_DEFAULT: RobustKernel = RobustKernel::Cauchy { c: 2.796 };
    /// DCS with the paper's Φ = 1.
    pub const DCS_DEFAULT: RobustKernel = RobustKernel::Dcs { phi: 1.0 };

    /// `(ρ(s), w)` for a squared Mahalanobis error `s ≥ 0`: the cost the
    /// edge contributes and the weight its information gets in the normal
    /// equations.
    pub fn evaluate(&self, s: f64) -> (f64, f64) {
        match *self {
            RobustKernel::None => (s, 1.0),
            RobustKernel::Huber { delta } => {
                let d2 = delta * delta;
                if s <= d2 {
                    (s, 1.0)
                } else {
                    let r = s.sqrt();
                    (2.0 * delta * r - d2, delta / r)
                }
            }
            RobustKernel::Cauchy { c } => {
                let c2 = c * c;
                (c2 * (s / c2).ln_1p(), 1.0 / (1.0 + s / c2))
            }
            RobustKernel::Dcs { phi } => {
                if s <= phi {
                    (s, 1.0)
                } else {
                    let scale = 2.0 * phi / (phi + s);
                    (3.0 * phi - 4.0 * phi * phi / (phi + s), scale * scale)
                }
            }
        }
    }

    /// The kernel's parameter must be finite and positive.
    pub fn is_valid(&self) -> bool {
        match *self {
            RobustKernel::None => true,
            RobustKernel::Huber { delta: p }
            | RobustKernel::Cauchy { c: p }
            | RobustKernel::Dcs { phi: p } => p.is_finite() && p > 0.0,
        }
    }

    /// A short name: `none`, `huber`, `cauchy`, `dcs`.
    pub fn name(&self) -> &'static str {
        match self {
            RobustKernel::None => "none",
            RobustKernel::Huber { .. } => "huber",
            RobustKernel::Cauchy { .. } => "cauchy",
            RobustKernel::Dcs { .. } => "dcs",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The weight is the derivative of ρ (central differences); all kernels
    /// are continuous at their threshold.
    #[test]
    fn weights_are_derivatives() {
        for kernel in [
            RobustKernel::HUBER_DEFAULT,
            RobustKernel::CAUCHY_DEFAULT,
            RobustKernel::DCS_DEFAULT,
        ] {
            for s in [0.1, 1.0, 7.0, 9.0, 50.0, 1e4] {
                let h = 1e-6 * s;
                let numeric = (kernel.evaluate(s + h).0 - kernel.evaluate(s - h).0) / (2.0 * h);
                let (_, w) = kernel.evaluate(s);
                assert!(
                    (numeric - w).abs() < 1e-6,
                    "{kernel:?} at {s}: {numeric} vs {w}"
                );
            }
        }
        for kernel in [
            RobustKernel::HUBER_DEFAULT,
            RobustKernel::CAUCHY_DEFAULT,
            RobustKernel::DCS_DEFAULT,
        ] {
            let t = match kernel {
                RobustKernel::Huber { delta } => delta * delta,
                RobustKernel::Cauchy { c } => c * c,
                RobustKernel::Dcs { phi } => phi,
                RobustKernel::None => unreachable!(),
            };
            let below = kernel.evaluate(t * (1.0 - 1e-12)).0;
            let above = kernel.evaluate(t * (1.0 + 1e-12)).0;
            assert!((below - above).abs() < 1e-9 * t);
        }
    }

    #[test]
    fn outliers_are_down_weighted() {
        assert_eq!(RobustKernel::None.evaluate(1e6), (1e6, 1.0));
        // Huber: w = δ/√s.
        let (_, w) = RobustKernel::Huber { delta: 2.0 }.evaluate(400.0);
        assert!((w - 0.1).abs() < 1e-15);
        // Cauchy: w = 1/(1 + s/c²).
        let (_, w) = RobustKernel::Cauchy { c: 1.0 }.evaluate(99.0);
        assert!((w - 0.01).abs() < 1e-15);
        // DCS with Φ = 1 at χ² = 3: s_ij = 2/4, weight 1/4; cost 3 − 4/4.
        let (rho, w) = RobustKernel::Dcs { phi: 1.0 }.evaluate(3.0);
        assert!((w - 0.25).abs() < 1e-15 && (rho - 2.0).abs() < 1e-15);
        // Inliers keep their full weight.
        assert_eq!(RobustKernel::DCS_DEFAULT.evaluate(0.5), (0.5, 1.0));
    }

    #[test]
    fn serde_names() {
        let json = serde_json::to_string(&RobustKernel::Huber { delta: 1.5 }).unwrap();
        assert_eq!(json, r#"{"kind":"huber","delta":1.5}"#);
        let back: RobustKernel = serde_json::from_str(r#"{"kind":"dcs","phi":2.0}"#).unwrap();
        assert_eq!(back, RobustKernel::Dcs { phi: 2.0 });
        assert!(serde_json::from_str::<RobustKernel>(r#"{"kind":"huber","c":1}"#).is_err());
    }
}
