//! Solver configuration.

use crate::robust::RobustKernel;
use echofield_graph::EdgeKind;
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// The iteration used to minimise the cost.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Algorithm {
    /// Undamped Gauss-Newton: every step is taken; a step that raises the
    /// cost is undone and ends the solve ([`Termination::CostIncreased`]).
    ///
    /// [`Termination::CostIncreased`]: crate::Termination::CostIncreased
    #[serde(alias = "gn")]
    GaussNewton,
    /// Levenberg-Marquardt with Marquardt's diagonal scaling and Nielsen's
    /// damping update: steps that raise the cost are rejected and the
    /// damping increased.
    #[serde(alias = "lm")]
    LevenbergMarquardt,
}

/// Where the iterations start.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Initialisation {
    /// Chordal relaxation: orientations first, then positions, both by
    /// linear least squares (see the crate documentation). Ignores the
    /// current poses except for the gauge.
    Chordal,
    /// Start from the poses currently in the graph (e.g. the previous
    /// solution when re-optimising a growing graph during a mission).
    Current,
}

/// A robust kernel per edge kind.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RobustConfig {
    /// Dead-reckoning edges.
    pub odometry: RobustKernel,
    /// Scan matches between consecutive nodes.
    pub sequential: RobustKernel,
    /// Loop closures (scan matches between non-consecutive nodes; in g2o
    /// files every edge between non-consecutive ids).
    #[serde(rename = "loop")]
    pub loop_closure: RobustKernel,
    /// Absolute-pose priors.
    pub prior: RobustKernel,
}

impl Default for RobustConfig {
    /// Plain least squares everywhere.
    fn default() -> Self {
        Self {
            odometry: RobustKernel::None,
            sequential: RobustKernel::None,
            loop_closure: RobustKernel::None,
            prior: RobustKernel::None,
        }
    }
}

impl RobustConfig {
    /// `kernel` on loop closures, least squares elsewhere: the usual
    /// protection against false loop closures.
    pub fn loops_only(kernel: RobustKernel) -> Self {
        Self {
            loop_closure: kernel,
            ..Self::default()
        }
    }

    /// The kernel for edges of `kind`.
    pub fn kernel(&self, kind: EdgeKind) -> RobustKernel {
        match kind {
            EdgeKind::Odometry => self.odometry,
            EdgeKind::Sequential => self.sequential,
            EdgeKind::Loop => self.loop_closure,
            EdgeKind::Prior => self.prior,
        }
    }
}

/// Configuration of [`optimize`](crate::optimize) and [`Solver`](crate::Solver).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SolverConfig {
    /// Gauss-Newton or Levenberg-Marquardt. Default: Levenberg-Marquardt.
    pub algorithm: Algorithm,
    /// Starting poses. Default: chordal initialisation.
    pub initialisation: Initialisation,
    /// Robust kernel per edge kind. Default: none.
    pub robust: RobustConfig,
    /// Upper bound on linearisations (accepted plus rejected steps).
    /// Default: 100.
    pub max_iterations: usize,
    /// Converged when an accepted step lowers the cost by less than this
    /// fraction of the cost (dimensionless). Default: 1e-10.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): a numerical convergence threshold, not a property of a mission.
    #[serde(skip)]
    pub relative_cost_tolerance: f64,
    /// Converged when the step norm `‖δ‖` (metres and radians mixed, as in
    /// g2o and Ceres) is below `step_tolerance · (‖x‖ + step_tolerance)`.
    /// Default: 1e-10.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): a numerical convergence threshold, not a property of a mission.
    #[serde(skip)]
    pub step_tolerance: f64,
    /// First Levenberg-Marquardt damping λ, relative to the diagonal of the
    /// normal equations (dimensionless). Default: 1e-10, i.e. start with
    /// (almost) Gauss-Newton steps; λ grows only when a step fails.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): Levenberg-Marquardt adapts λ from its first failed step.
    #[serde(skip)]
    pub initial_lambda: f64,
    /// Threads of the sparse factorisation: 1 runs sequentially, more uses
    /// faer's rayon parallelism. Default: 1.
    pub threads: usize,
}

impl Default for SolverConfig {
    fn default() -> Self {
        Self {
            algorithm: Algorithm::LevenbergMarquardt,
            initialisation: Initialisation::Chordal,
            robust: RobustConfig::default(),
            max_iterations: 100,
            relative_cost_tolerance: 1e-10,
            step_tolerance: 1e-10,
            initial_lambda: 1e-10,
            threads: 1,
        }
    }
}

/// An invalid [`SolverConfig`] value.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum ConfigError {
    #[error("solver config: `{field}` = {value} must be {expected}")]
    OutOfRange {
        field: &'static str,
        value: String,
        expected: &'static str,
    },
}

impl SolverConfig {
    /// Checks every field; never changes a value.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let out = |field, value: String, expected| ConfigError::OutOfRange {
            field,
            value,
            expected,
        };
        if self.max_iterations == 0 {
            return Err(out("max_iterations", "0".into(), "at least 1"));
        }
        let tolerances = [
            ("relative_cost_tolerance", self.relative_cost_tolerance),
            ("step_tolerance", self.step_tolerance),
        ];
        for (field, value) in tolerances {
            if !(value.is_finite() && value >= 0.0) {
                return Err(out(field, value.to_string(), "finite and >= 0"));
            }
        }
        if !(self.initial_lambda.is_finite() && self.initial_lambda > 0.0) {
            let value = self.initial_lambda.to_string();
            return Err(out("initial_lambda", value, "finite and > 0"));
        }
        if self.threads == 0 {
            return Err(out("threads", "0".into(), "at least 1"));
        }
        for kind in EdgeKind::ALL {
            let kernel = self.robust.kernel(kind);
            if !kernel.is_valid() {
                let field = match kind {
                    EdgeKind::Odometry => "robust.odometry",
                    EdgeKind::Sequential => "robust.sequential",
                    EdgeKind::Loop => "robust.loop",
                    EdgeKind::Prior => "robust.prior",
                };
                return Err(out(
                    field,
                    format!("{kernel:?}"),
                    "a finite, positive parameter",
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_validate_and_round_trip() {
        let config = SolverConfig::default();
        config.validate().unwrap();
        let json = serde_json::to_string(&config).unwrap();
        let back: SolverConfig = serde_json::from_str(&json).unwrap();
        assert_eq!(back, config);
        let partial: SolverConfig = serde_json::from_str(
            r#"{"algorithm":"gn","robust":{"loop":{"kind":"cauchy","c":1.0}}}"#,
        )
        .unwrap();
        assert_eq!(partial.algorithm, Algorithm::GaussNewton);
        assert_eq!(
            partial.robust.kernel(EdgeKind::Loop),
            RobustKernel::Cauchy { c: 1.0 }
        );
        assert_eq!(partial.max_iterations, 100);
        assert!(serde_json::from_str::<SolverConfig>(r#"{"iterations":3}"#).is_err());
    }

    #[test]
    fn rejects_bad_values() {
        let bad = SolverConfig {
            threads: 0,
            ..SolverConfig::default()
        };
        assert!(matches!(
            bad.validate(),
            Err(ConfigError::OutOfRange {
                field: "threads",
                ..
            })
        ));
        let bad = SolverConfig {
            robust: RobustConfig::loops_only(RobustKernel::Huber { delta: -1.0 }),
            ..SolverConfig::default()
        };
        assert!(matches!(
            bad.validate(),
            Err(ConfigError::OutOfRange {
                field: "robust.loop",
                ..
            })
        ));
        let bad = SolverConfig {
            relative_cost_tolerance: f64::NAN,
            ..SolverConfig::default()
        };
        assert!(bad.validate().is_err());
    }
}
