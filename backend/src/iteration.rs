//! The Gauss-Newton / Levenberg-Marquardt iteration on a prepared system.
//!
//! Each iteration solves `(H + λD) δ = −g` with `H = Σ Jᵀ w Ω J`,
//! `g = Σ Jᵀ w Ω e` (w the robust weight), `D = diag(H)` clamped to
//! [1e-6, 1e32] (Marquardt's scaling, bounded as in Ceres so that a pose
//! whose diagonal vanishes is still damped), and λ = 0 for Gauss-Newton.
//! Levenberg-Marquardt accepts a step when the robust cost drops and updates
//! λ with Nielsen's rule: on success `λ ← λ · max(1/3, 1 − (2ρ − 1)³)` with
//! ρ the ratio of actual to predicted decrease, on failure `λ ← λ·ν`,
//! `ν ← 2ν`. The first λ is tiny (1e-10 by default): the chordal start is
//! good enough for full Gauss-Newton steps, and a larger λ holds back the
//! long, soft deformations some benchmarks need (M3500 took 12 iterations
//! with λ₀ = 1e-4, 4 with 1e-10).

use crate::config::{Algorithm, SolverConfig};
use crate::error::SolveError;
use crate::linear::{BlockSystem, LinearError};
use crate::linearize::{Cost, EdgeSlots, apply_step, evaluate, linearise};
use crate::problem::Problem;
use crate::robust::RobustKernel;
use crate::summary::{IterationLog, SolveSummary, Termination};
use echofield_graph::Se2;
use std::time::Instant;

/// Bounds of the diagonal scaling.
const MIN_DIAGONAL: f64 = 1e-6;
const MAX_DIAGONAL: f64 = 1e32;
/// Beyond this damping no step can lower the cost: we are at a minimum.
const MAX_LAMBDA: f64 = 1e32;
/// Below this the damping is lost in rounding anyway.
const MIN_LAMBDA: f64 = 1e-15;

/// λ and ν of Levenberg-Marquardt; always 0 for Gauss-Newton.
struct Damping {
    lambda: f64,
    nu: f64,
    gauss_newton: bool,
}

impl Damping {
    fn new(config: &SolverConfig) -> Self {
        let gauss_newton = config.algorithm == Algorithm::GaussNewton;
        Self {
            lambda: if gauss_newton {
                0.0
            } else {
                config.initial_lambda
            },
            nu: 2.0,
            gauss_newton,
        }
    }

    /// `λ D` for the diagonal `diagonal` of H.
    fn values(&self, diagonal: &[f64]) -> Vec<f64> {
        diagonal
            .iter()
            .map(|d| self.lambda * d.clamp(MIN_DIAGONAL, MAX_DIAGONAL))
            .collect()
    }

    /// After an accepted step with gain ratio `rho`.
    fn accepted(&mut self, rho: f64) {
        if !self.gauss_newton {
            let factor = (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
            self.lambda = (self.lambda * factor).max(MIN_LAMBDA);
            self.nu = 2.0;
        }
    }

    /// After a rejected (or, `singular`, unfactorisable) step: why the
    /// iteration ends, or `None` to retry with more damping. Gauss-Newton
    /// cannot retry; a tiny step that was solved ends it; so does λ past
    /// its limit.
    fn stop_after_rejection(&mut self, tiny_step: bool, singular: bool) -> Option<Termination> {
        if self.gauss_newton {
            return Some(if tiny_step {
                Termination::StepTolerance
            } else {
                Termination::CostIncreased
            });
        }
        if tiny_step && !singular {
            return Some(Termination::StepTolerance);
        }
        if !self.rejected() {
            return Some(Termination::DampingLimit);
        }
        None
    }

    /// After a rejected step; false once λ passes its limit.
    fn rejected(&mut self) -> bool {
        self.lambda *= self.nu;
        self.nu *= 2.0;
        self.lambda <= MAX_LAMBDA
    }
}

/// One run of the iteration over borrowed, prepared state.
pub(crate) struct Iteration<'a> {
    pub problem: &'a Problem,
    pub kernels: &'a [RobustKernel],
    pub slots: &'a [EdgeSlots],
    pub system: &'a mut BlockSystem<3>,
    pub config: &'a SolverConfig,
    pub start: Instant,
}

/// Work vectors of the iteration.
struct Buffers {
    gradient: Vec<f64>,
    delta: Vec<f64>,
    candidate: Vec<Se2>,
}

/// What one linear step did.
enum Outcome {
    Accepted {
        relative_decrease: f64,
        rho: f64,
    },
    Rejected,
    /// LM only: the damped matrix could not be factorised; more damping.
    Singular,
}

impl Iteration<'_> {
    /// Iterates from `poses` (updated in place) and fills the cost,
    /// iteration and termination fields of `summary`.
    pub fn run(
        &mut self,
        poses: &mut Vec<Se2>,
        summary: &mut SolveSummary,
    ) -> Result<(), SolveError> {
        let n = self.system.dim();
        let mut buffers = Buffers {
            gradient: vec![0.0; n],
            delta: vec![0.0; n],
            candidate: poses.clone(),
        };
        let mut cost = self.linearise(poses, &mut buffers.gradient);
        summary.initial_cost = cost.robust;
        if !cost.is_finite() {
            return Err(SolveError::NonFiniteCost { iteration: 0 });
        }
        let mut damping = Damping::new(self.config);
        let mut termination = Termination::MaxIterations;
        for it in 1..=self.config.max_iterations {
            if cost.robust == 0.0 {
                termination = Termination::ZeroCost;
                break;
            }
            summary.iterations = it;
            let lambda_used = damping.lambda;
            let outcome = self.step(it, poses, &mut buffers, &damping, cost)?;
            let step_norm = norm(&buffers.delta);
            let tol = self.config.step_tolerance;
            let tiny_step = step_norm <= tol * (pose_norm(poses) + tol);
            match outcome {
                Outcome::Accepted {
                    relative_decrease,
                    rho,
                } => {
                    std::mem::swap(poses, &mut buffers.candidate);
                    cost = self.linearise(poses, &mut buffers.gradient);
                    self.log(summary, it, cost, lambda_used, step_norm, true);
                    if let Some(reason) = self.converged(relative_decrease, tiny_step) {
                        termination = reason;
                        break;
                    }
                    damping.accepted(rho);
                }
                Outcome::Rejected | Outcome::Singular => {
                    let singular = matches!(outcome, Outcome::Singular);
                    let norm = if singular { f64::NAN } else { step_norm };
                    self.log(summary, it, cost, lambda_used, norm, false);
                    if let Some(reason) = damping.stop_after_rejection(tiny_step, singular) {
                        termination = reason;
                        break;
                    }
                }
            }
        }
        summary.termination = termination;
        summary.final_cost = cost.robust;
        summary.final_chi2 = cost.chi2;
        Ok(())
    }

    /// Whether an accepted step ends the iteration: its relative cost
    /// decrease is below the tolerance, or the step is tiny (below
    /// `step_tolerance` relative to the poses).
    fn converged(&self, relative_decrease: f64, tiny_step: bool) -> Option<Termination> {
        if relative_decrease < self.config.relative_cost_tolerance {
            Some(Termination::CostTolerance)
        } else if tiny_step {
            Some(Termination::StepTolerance)
        } else {
            None
        }
    }

    /// Solves for the step `delta` and evaluates `candidate = poses ⊞ delta`.
    fn step(
        &mut self,
        iteration: usize,
        poses: &[Se2],
        buffers: &mut Buffers,
        damping: &Damping,
        cost: Cost,
    ) -> Result<Outcome, SolveError> {
        let Buffers {
            gradient,
            delta,
            candidate,
        } = buffers;
        let lambda_d = damping.values(&self.system.diagonal());
        match self.system.factorise(&lambda_d) {
            Ok(()) => {}
            Err(LinearError::NotPositiveDefinite { .. }) if !damping.gauss_newton => {
                delta.fill(0.0);
                return Ok(Outcome::Singular);
            }
            Err(LinearError::NotPositiveDefinite { block }) => {
                let node = self.problem.node_ids[self.problem.node_of_variable[block]];
                return Err(SolveError::SystemNotPositiveDefinite { node });
            }
            Err(e) => return Err(SolveError::Linear(e.to_string())),
        }
        for (d, g) in delta.iter_mut().zip(gradient.iter()) {
            *d = -g;
        }
        self.system.solve(delta);
        apply_step(self.problem, poses, delta, candidate);
        let new_cost = evaluate(self.problem, self.kernels, candidate);
        if !new_cost.is_finite() {
            if damping.gauss_newton {
                return Err(SolveError::NonFiniteCost { iteration });
            }
            return Ok(Outcome::Rejected);
        }
        let actual = cost.robust - new_cost.robust;
        if actual <= 0.0 {
            return Ok(Outcome::Rejected);
        }
        // Decrease predicted by the quadratic model: δᵀ(λDδ − g).
        let predicted: f64 = delta
            .iter()
            .zip(gradient.iter())
            .zip(&lambda_d)
            .map(|((d, g), l)| d * (l * d - g))
            .sum();
        Ok(Outcome::Accepted {
            relative_decrease: actual / cost.robust,
            rho: actual / predicted,
        })
    }

    fn linearise(&mut self, poses: &[Se2], gradient: &mut [f64]) -> Cost {
        linearise(
            self.problem,
            self.kernels,
            self.slots,
            poses,
            self.system,
            gradient,
        )
    }

    fn log(
        &self,
        summary: &mut SolveSummary,
        iteration: usize,
        cost: Cost,
        lambda: f64,
        step_norm: f64,
        accepted: bool,
    ) {
        summary.log.push(IterationLog {
            iteration,
            chi2: cost.chi2,
            cost: cost.robust,
            lambda,
            step_norm,
            accepted,
            time_s: self.start.elapsed().as_secs_f64(),
        });
    }
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// ‖x‖ of the stacked vector forms of all poses.
fn pose_norm(poses: &[Se2]) -> f64 {
    poses
        .iter()
        .map(|p| p.to_vector().norm_squared())
        .sum::<f64>()
        .sqrt()
}
