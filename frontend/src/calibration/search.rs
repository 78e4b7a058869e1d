//! Minimising the objective over the head's continuous unknowns: a coarse
//! grid over the full circle of the yaw, a fine grid and Brent's method on
//! the yaw alone, and Nelder-Mead on the yaw and the lever arm (Brent and
//! Nelder-Mead from argmin).
//!
//! The objective is continuous but only piecewise smooth, and has local
//! minima away from the right yaw (a wall of one rotation can fall on
//! another wall of the next), hence the grid before any local method; and
//! it ripples a little at the scale of a cell, hence the fine grid before
//! Brent, whose bracket would otherwise settle in the nearest ripple.
//! Nelder-Mead only compares values, which suits a function whose
//! gradient jumps at every cell edge; it is restarted at full size from
//! its best point until a run gains nothing, for the same ripples. Its
//! parameters are `(ρ·ψ, x, y)` with `ρ` the median range of the returns,
//! so that a unit step in any of them moves the returns by about the same
//! distance.

use super::objective::{HeadCandidate, Objective};
use argmin::core::{CostFunction, Error, Executor, State};
use argmin::solver::brent::BrentOpt;
use argmin::solver::neldermead::NelderMead;
use echofield_graph::wrap_angle;
use nalgebra::Vector3;

/// Brent stops when the yaw bracket is this narrow, radians (0.001°):
/// far below any uncertainty the data can give.
const YAW_TOLERANCE_RAD: f64 = 1.7e-5;

/// Iteration caps: each is several times what the runs took, so that a
/// pathological objective ends instead of looping.
const MAX_BRENT_ITERATIONS: u64 = 100;
const MAX_SIMPLEX_ITERATIONS: u64 = 400;

/// Nelder-Mead stops when the standard deviation of its simplex's costs
/// is below this, bits: far below any difference between placements that
/// matters, so that a run ends only once the simplex has collapsed.
const SIMPLEX_SD_TOLERANCE_BITS: f64 = 1e-6;

/// A head found by a search, with its objective.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Found {
    pub head: HeadCandidate,
    pub mean_entropy_bits: f64,
}

/// The best yaw of a grid of `step_rad` over the full circle, the rest of
/// `head` fixed. Ties go to the first grid point (from −π).
pub fn coarse_yaw(
    objective: &Objective,
    head: &HeadCandidate,
    selection: &[usize],
    step_rad: f64,
) -> Found {
    let n = (std::f64::consts::TAU / step_rad).round().max(1.0) as usize;
    let mut best = Found {
        head: *head,
        mean_entropy_bits: f64::INFINITY,
    };
    for k in 0..n {
        let candidate = HeadCandidate {
            yaw_rad: wrap_angle(
                -std::f64::consts::PI + k as f64 * std::f64::consts::TAU / n as f64,
            ),
            ..*head
        };
        let cost = objective.mean_entropy(&candidate, selection);
        if cost < best.mean_entropy_bits {
            best = Found {
                head: candidate,
                mean_entropy_bits: cost,
            };
        }
    }
    best
}

/// The yaw as an argmin problem, the rest of the head fixed.
struct YawCost<'a> {
    objective: &'a Objective,
    head: HeadCandidate,
    selection: &'a [usize],
}

impl CostFunction for YawCost<'_> {
    type Param = f64;
    type Output = f64;

    fn cost(&self, yaw_rad: &f64) -> Result<f64, Error> {
        let head = HeadCandidate {
            yaw_rad: *yaw_rad,
            ..self.head
        };
        Ok(self.objective.mean_entropy(&head, self.selection))
    }
}

/// Points of the fine grid on either side of the start in [`refine_yaw`].
const FINE_POINTS_PER_SIDE: usize = 8;

/// The best yaw within `start.yaw ± half_width_rad`: first a fine grid of
/// `half_width_rad / 8` (the objective ripples as returns cross cell edges,
/// and a bracketing method alone settles in the nearest ripple), then
/// Brent's method within one fine step either side of the best grid point.
/// The better of `start` and what was found (the yaw wrapped to (−π, π]).
pub fn refine_yaw(
    objective: &Objective,
    start: &Found,
    selection: &[usize],
    half_width_rad: f64,
) -> Found {
    let fine_rad = half_width_rad / FINE_POINTS_PER_SIDE as f64;
    let n = FINE_POINTS_PER_SIDE as i64;
    let mut best = *start;
    for k in (-n..=n).filter(|&k| k != 0) {
        let head = HeadCandidate {
            yaw_rad: start.head.yaw_rad + k as f64 * fine_rad,
            ..start.head
        };
        let cost = objective.mean_entropy(&head, selection);
        if cost < best.mean_entropy_bits {
            best = Found {
                head,
                mean_entropy_bits: cost,
            };
        }
    }
    let brent = brent_yaw(objective, &best, selection, fine_rad);
    Found {
        head: HeadCandidate {
            yaw_rad: wrap_angle(brent.head.yaw_rad),
            ..brent.head
        },
        ..brent
    }
}

/// Brent's method on the yaw in `start.yaw ± half_width_rad`; the better
/// of `start` and Brent's best.
fn brent_yaw(
    objective: &Objective,
    start: &Found,
    selection: &[usize],
    half_width_rad: f64,
) -> Found {
    let yaw = start.head.yaw_rad;
    let problem = YawCost {
        objective,
        head: start.head,
        selection,
    };
    let solver = BrentOpt::new(yaw - half_width_rad, yaw + half_width_rad)
        .set_tolerance(f64::EPSILON.sqrt(), YAW_TOLERANCE_RAD);
    let run = Executor::new(problem, solver)
        .configure(|state| state.max_iters(MAX_BRENT_ITERATIONS))
        .run();
    let best = run.ok().and_then(|r| {
        let state = r.state();
        Some((*state.get_best_param()?, state.get_best_cost()))
    });
    match best {
        Some((yaw_rad, cost)) if cost < start.mean_entropy_bits => Found {
            head: HeadCandidate {
                yaw_rad,
                ..start.head
            },
            mean_entropy_bits: cost,
        },
        _ => *start,
    }
}

/// The yaw and lever arm as an argmin problem in scaled parameters
/// `(ρ·ψ, x, y)`, the lever arm confined to a box around its start.
#[derive(Clone)]
struct HeadCost<'a> {
    objective: &'a Objective,
    sonar_angle: crate::sensors::AngleDirection,
    selection: &'a [usize],
    rho_m: f64,
    lever_centre: [f64; 2],
    lever_half_width_m: f64,
}

impl HeadCost<'_> {
    fn head(&self, p: &Vector3<f64>) -> HeadCandidate {
        HeadCandidate {
            sonar_angle: self.sonar_angle,
            yaw_rad: p.x / self.rho_m,
            x_m: p.y,
            y_m: p.z,
        }
    }
}

impl CostFunction for HeadCost<'_> {
    type Param = Vector3<f64>;
    type Output = f64;

    fn cost(&self, p: &Vector3<f64>) -> Result<f64, Error> {
        // Outside the box: worse than the start and growing with the
        // distance, so the simplex comes back.
        let outside = ((p.y - self.lever_centre[0]).abs() - self.lever_half_width_m).max(0.0)
            + ((p.z - self.lever_centre[1]).abs() - self.lever_half_width_m).max(0.0);
        if outside > 0.0 {
            return Ok(1e3 * (1.0 + outside));
        }
        Ok(self.objective.mean_entropy(&self.head(p), self.selection))
    }
}

/// Nelder-Mead on `(ψ, x, y)` from `start`, its initial simplex `step_m`
/// along each scaled axis, the lever arm kept within
/// `lever_half_width_m` of `lever_centre`. The simplex shrinks into the
/// nearest ripple of the objective, so it is started again from its best
/// point, at full size, until a run gains less than 1e-4 bits (at most
/// four times). Returns the better of `start` and the best found.
#[allow(clippy::too_many_arguments)]
pub fn refine_head(
    objective: &Objective,
    start: &Found,
    selection: &[usize],
    rho_m: f64,
    step_m: f64,
    lever_centre: [f64; 2],
    lever_half_width_m: f64,
) -> Found {
    let problem = HeadCost {
        objective,
        sonar_angle: start.head.sonar_angle,
        selection,
        rho_m,
        lever_centre,
        lever_half_width_m,
    };
    let mut best = *start;
    for _ in 0..=MAX_RESTARTS {
        let found = simplex_run(&problem, &best, step_m);
        let gain = best.mean_entropy_bits - found.mean_entropy_bits;
        best = found;
        if gain < RESTART_GAIN_BITS {
            break;
        }
    }
    best
}

/// A Nelder-Mead run gaining less than this (bits) ends the restarts of
/// [`refine_head`].
const RESTART_GAIN_BITS: f64 = 1e-4;

/// Restarts of the simplex in [`refine_head`] at most.
const MAX_RESTARTS: usize = 4;

/// One Nelder-Mead run of `problem` from `start`; the better of `start`
/// and the simplex's best.
fn simplex_run(problem: &HeadCost<'_>, start: &Found, step_m: f64) -> Found {
    let h = start.head;
    let x0 = Vector3::new(h.yaw_rad * problem.rho_m, h.x_m, h.y_m);
    let simplex = vec![
        x0,
        x0 + Vector3::new(step_m, 0.0, 0.0),
        x0 + Vector3::new(0.0, step_m, 0.0),
        x0 + Vector3::new(0.0, 0.0, step_m),
    ];
    let Ok(solver) = NelderMead::new(simplex).with_sd_tolerance(SIMPLEX_SD_TOLERANCE_BITS) else {
        return *start;
    };
    let run = Executor::new(problem.clone(), solver)
        .configure(|state| state.max_iters(MAX_SIMPLEX_ITERATIONS))
        .run();
    let best = run.ok().and_then(|r| {
        let state = r.state();
        Some((problem.head(state.get_best_param()?), state.get_best_cost()))
    });
    match best {
        Some((head, cost)) if cost < start.mean_entropy_bits => Found {
            head: HeadCandidate {
                yaw_rad: wrap_angle(head.yaw_rad),
                ..head
            },
            mean_entropy_bits: cost,
        },
        _ => *start,
    }
}
