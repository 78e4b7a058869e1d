//! What a solve did: costs, iterations, why it stopped, how long it took.

use crate::config::{Algorithm, Initialisation};
use serde::Serialize;

/// Why the iterations stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Termination {
    /// An accepted step lowered the cost by less than
    /// `relative_cost_tolerance` of it.
    CostTolerance,
    /// The step norm fell below `step_tolerance`.
    StepTolerance,
    /// The cost is zero: every measurement is met exactly.
    ZeroCost,
    /// `max_iterations` linearisations without convergence.
    MaxIterations,
    /// Levenberg-Marquardt found no decreasing step even with very large
    /// damping: the cost is at a minimum to machine precision.
    DampingLimit,
    /// A Gauss-Newton step raised the cost; it was undone.
    CostIncreased,
    /// Every node is fixed: there is nothing to optimise.
    NothingToOptimise,
}

impl Termination {
    /// True for the reasons that mean "at a minimum".
    pub fn is_converged(&self) -> bool {
        matches!(
            self,
            Termination::CostTolerance
                | Termination::StepTolerance
                | Termination::ZeroCost
                | Termination::DampingLimit
                | Termination::NothingToOptimise
        )
    }
}

/// One linearisation of the iteration.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IterationLog {
    /// 1-based.
    pub iteration: usize,
    /// χ² (Σ eᵀΩe, no kernel) after this iteration.
    pub chi2: f64,
    /// Robust cost Σ ρ(eᵀΩe) after this iteration (equals `chi2` without
    /// robust kernels).
    pub cost: f64,
    /// Damping λ used for the step (0 for Gauss-Newton).
    pub lambda: f64,
    /// ‖δ‖ of the step (metres and radians mixed).
    pub step_norm: f64,
    /// Whether the step was kept.
    pub accepted: bool,
    /// Seconds since the start of the solve.
    pub time_s: f64,
}

/// The record of one solve.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SolveSummary {
    pub algorithm: Algorithm,
    pub initialisation: Initialisation,
    /// χ² at the poses the graph held on entry.
    pub initial_chi2: f64,
    /// χ² after the initialisation, before the first iteration.
    pub initialised_chi2: f64,
    /// χ² at the returned poses.
    pub final_chi2: f64,
    /// Robust cost at the start of the iterations.
    pub initial_cost: f64,
    /// Robust cost at the returned poses.
    pub final_cost: f64,
    /// Linearisations (accepted and rejected steps).
    pub iterations: usize,
    pub termination: Termination,
    /// Wall time of the whole solve, seconds.
    pub time_s: f64,
    /// Of which spent in the initialisation, seconds.
    pub initialisation_time_s: f64,
    /// Whether the symbolic factorisation of an earlier solve was reused.
    pub symbolic_reused: bool,
    /// Free poses (fixed nodes excluded).
    pub free_poses: usize,
    pub edges: usize,
    /// One entry per linearisation.
    pub log: Vec<IterationLog>,
}
