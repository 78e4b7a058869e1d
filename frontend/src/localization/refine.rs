//! The estimate refined on the map: from the particles' weighted mean, the
//! pose that maximises the scan's score on the likelihood field (eq. 6,
//! `x* = argmax_x s(x)`, with `s` of eq. 5 on the field), plus the
//! compass term the particles are weighed with and, when given, the
//! predicted cloud as a Gaussian prior: the mode of the filter's own
//! posterior, `argmax_x gain·s̄(x) − ½(θ − θ_c)²/σ_θ² − ½ dᵀ Ω d`, `d` the
//! offset from the prior's mean and `Ω` its information.
//!
//! Why: the weighted mean of a cloud of a thousand particles scatters
//! about the score's peak by the particles' spacing and the noise the
//! motion model adds every rotation; the peak itself is what the paper's
//! matcher reports for a scan against an image. The matcher's own search
//! ([`crate::matcher`]) takes one node's acoustic image and a search
//! window; the map here is one mosaic field, so the peak is found on it
//! directly.
//!
//! Why the prior: along a straight quay the score is flat (every shift
//! along it fits as well), and its peak there is wherever the field's
//! small ripples put it, up to `max_shift_m` away; the motion says where
//! along the quay the vehicle is, as it does for the particles' weights.
//!
//! The search is Nelder-Mead (argmin's) on `(x, y, ρ·θ)`, `ρ` the scan's
//! RMS range, so that a unit step in any parameter moves the points by
//! about the same distance. Nelder-Mead only compares values, which suits
//! a bilinear field whose gradient jumps at every cell edge. The result is
//! kept within `max_shift_m` of the start (beyond it the cost grows, so
//! that a scan that also fits a neighbouring place cannot pull the estimate
//! there); when the search fails or finds nothing better, the start is
//! returned.

use super::field::LikelihoodField;
use super::particles::offset;
use argmin::core::{CostFunction, Error, Executor, State};
use argmin::solver::neldermead::NelderMead;
use echofield_graph::{Se2, wrap_angle};
use nalgebra::{Matrix3, Point2, Vector3};

/// Side of the initial simplex along each scaled axis, m.
const SIMPLEX_STEP_M: f64 = 0.1;

/// The simplex stops when its costs' standard deviation falls below this
/// (cost units: `score_gain` times a mean field value, i.e. log-weights).
const SIMPLEX_SD_TOLERANCE: f64 = 1e-3;

/// Nelder-Mead iterations at most.
const MAX_ITERATIONS: u64 = 200;

/// Shortest `ρ` used for scaling the heading, m (a scan of points all
/// near the vehicle would otherwise make the heading axis degenerate).
const MIN_RHO_M: f64 = 1.0;

/// What is maximised, and where the search may go.
pub struct RefineProblem<'a> {
    pub field: &'a LikelihoodField,
    /// The scan in the vehicle frame.
    pub points: &'a [Point2<f64>],
    /// Every `stride`-th point is scored (at least 1).
    pub stride: usize,
    /// Field value of a point outside the map's coverage, 0-1.
    pub unknown: f64,
    /// Log-likelihood per unit of mean field value (`score_gain`).
    pub gain: f64,
    /// Compass heading and its standard deviation, rad.
    pub heading_rad: f64,
    pub heading_sigma_rad: f64,
    /// Largest distance of the result from the start, m (> 0).
    pub max_shift_m: f64,
    /// The predicted cloud as a Gaussian prior: its mean and information
    /// matrix in `(x, y, θ)` (world frame). With it the result is the
    /// posterior's mode, not the score's peak alone.
    pub prior: Option<(Se2, Matrix3<f64>)>,
}

impl RefineProblem<'_> {
    /// The log-weight a particle at `pose` would get (larger is better),
    /// the scan scored on the field's refine raster
    /// ([`LikelihoodField::refine_score`]; the particles' own field when it
    /// has none).
    pub fn log_weight(&self, pose: &Se2) -> f64 {
        let s = self
            .field
            .refine_score(pose, self.points, self.stride, self.unknown);
        let dh = wrap_angle(pose.theta() - self.heading_rad);
        let prior = self.prior.as_ref().map_or(0.0, |(mean, information)| {
            let d = offset(pose, mean);
            0.5 * d.dot(&(information * d))
        });
        self.gain * s.mean - dh * dh / (2.0 * self.heading_sigma_rad.powi(2)) - prior
    }

    /// The pose near `start` with the largest [`Self::log_weight`] (see
    /// the module doc); `start` itself when nothing better is found.
    pub fn refine(&self, start: &Se2) -> Se2 {
        let rho = rms_range_m(self.points).max(MIN_RHO_M);
        let cost = Cost {
            problem: self,
            start: *start,
            rho,
        };
        let x0 = Vector3::zeros();
        let simplex = vec![
            x0,
            Vector3::new(SIMPLEX_STEP_M, 0.0, 0.0),
            Vector3::new(0.0, SIMPLEX_STEP_M, 0.0),
            Vector3::new(0.0, 0.0, SIMPLEX_STEP_M),
        ];
        let Ok(solver) = NelderMead::new(simplex).with_sd_tolerance(SIMPLEX_SD_TOLERANCE) else {
            return *start;
        };
        let start_cost = -self.log_weight(start);
        let found = Executor::new(cost.clone(), solver)
            .configure(|state| state.max_iters(MAX_ITERATIONS))
            .run()
            .ok()
            .and_then(|r| {
                let state = r.state();
                Some((*state.get_best_param()?, state.get_best_cost()))
            });
        match found {
            Some((p, c)) if c < start_cost && c.is_finite() => cost.pose(&p),
            _ => *start,
        }
    }
}

/// The problem in the scaled offsets `(dx, dy, ρ·dθ)` from the start
/// (world frame), as argmin minimises it.
#[derive(Clone)]
struct Cost<'a> {
    problem: &'a RefineProblem<'a>,
    start: Se2,
    rho: f64,
}

impl Cost<'_> {
    fn pose(&self, p: &Vector3<f64>) -> Se2 {
        Se2::new(
            self.start.x() + p.x,
            self.start.y() + p.y,
            wrap_angle(self.start.theta() + p.z / self.rho),
        )
    }
}

impl CostFunction for Cost<'_> {
    type Param = Vector3<f64>;
    type Output = f64;

    fn cost(&self, p: &Vector3<f64>) -> Result<f64, Error> {
        let pose = self.pose(p);
        let outside = (p.x.hypot(p.y) - self.problem.max_shift_m).max(0.0);
        // Outside the disc: the start's cost plus a slope, so the simplex
        // comes back.
        if outside > 0.0 {
            return Ok(-self.problem.log_weight(&self.start) + 1e3 * (1.0 + outside));
        }
        Ok(-self.problem.log_weight(&pose))
    }
}

/// RMS distance of `points` from the origin, m (0 without points).
fn rms_range_m(points: &[Point2<f64>]) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    (points.iter().map(|p| p.coords.norm_squared()).sum::<f64>() / points.len() as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::Grid;

    /// A field of two crossing walls (x = 2.125 and y = 3.125) and a post,
    /// every point at a cell's centre (where the bilinear field peaks), and
    /// the same points in the vehicle frame of `world_from_vehicle`.
    fn field_and_scan(world_from_vehicle: &Se2) -> (LikelihoodField, Vec<Point2<f64>>) {
        let mut grid = Grid::zeros(-10.0, -10.0, 0.25, 80, 80);
        let mut world = Vec::new();
        for i in 0..60 {
            let t = -7.375 + 0.25 * i as f64;
            world.push((2.125, t));
            world.push((t, 3.125));
        }
        world.push((-3.875, -3.875));
        let w = grid.width();
        for &(x, y) in &world {
            let (ix, iy) = grid.cell_of(x, y);
            grid.values_mut()[iy as usize * w + ix as usize] = 1.0;
        }
        let field = LikelihoodField::new(grid, &[(Se2::identity(), 15.0)], 0.3).unwrap();
        let inverse = world_from_vehicle.inverse();
        let scan = world
            .iter()
            .map(|&(x, y)| {
                let (u, v) = inverse.transform_xy(x, y);
                Point2::new(u, v)
            })
            .collect();
        (field, scan)
    }

    /// The problem of `points` on `field` with a compass heading
    /// `heading_rad` (sigma 0.26 rad) and at most `max_shift_m` of move.
    fn test_problem<'a>(
        field: &'a LikelihoodField,
        points: &'a [Point2<f64>],
        heading_rad: f64,
        max_shift_m: f64,
    ) -> RefineProblem<'a> {
        RefineProblem {
            field,
            points,
            stride: 1,
            unknown: 0.1,
            gain: 300.0,
            heading_rad,
            heading_sigma_rad: 0.26,
            max_shift_m,
            prior: None,
        }
    }

    #[test]
    fn an_estimate_off_by_a_fraction_of_a_metre_moves_onto_the_true_pose() {
        let truth = Se2::new(0.4, -0.7, 0.2);
        let (field, scan) = field_and_scan(&truth);
        let problem = test_problem(&field, scan.as_slice(), 0.2, 1.0);
        let start = Se2::new(0.6, -0.55, 0.23);
        let refined = problem.refine(&start);
        let before = (start.translation() - truth.translation()).norm();
        let after = (refined.translation() - truth.translation()).norm();
        assert!(after < 0.08, "{after} m from the truth (was {before} m)");
        assert!(
            wrap_angle(refined.theta() - truth.theta()).abs() < 0.01,
            "{refined:?}"
        );
        assert!(problem.log_weight(&refined) > problem.log_weight(&start));
    }

    #[test]
    fn the_result_stays_within_the_allowed_shift() {
        let truth = Se2::new(0.0, 0.0, 0.0);
        let (field, scan) = field_and_scan(&truth);
        let problem = test_problem(&field, scan.as_slice(), 0.0, 0.2);
        let start = Se2::new(0.5, 0.0, 0.0);
        let refined = problem.refine(&start);
        let shift = (refined.translation() - start.translation()).norm();
        assert!(shift <= 0.2 + 1e-9, "moved {shift} m");
        // It moved towards the truth.
        assert!(refined.x() < 0.45, "{refined:?}");
    }

    #[test]
    fn the_estimate_is_refined_on_the_refine_raster() {
        // The particles' field has the walls of `field_and_scan`; the refine
        // raster has them 0.25 m further along x (one cell): the refined
        // estimate follows the refine raster.
        let truth = Se2::identity();
        let (field, scan) = field_and_scan(&truth);
        let mut shifted = Grid::zeros(-10.0, -10.0, 0.25, 80, 80);
        let w = shifted.width();
        for (k, v) in field.grid().values().iter().enumerate() {
            if k % w + 1 < w {
                shifted.values_mut()[k + 1] = *v;
            }
        }
        let field = field.with_refine_raster(shifted, 0.0).unwrap();
        let problem = test_problem(&field, scan.as_slice(), 0.0, 1.0);
        let refined = problem.refine(&truth);
        assert!((refined.x() - 0.25).abs() < 0.08, "{refined:?}");
        assert!(refined.y().abs() < 0.08, "{refined:?}");
    }

    #[test]
    fn along_a_wall_the_prior_says_where_and_the_scan_how_far_from_it() {
        // The scan sees only the middle of the wall x = 2.125, so its score
        // is flat along y; the prior at the truth with 0.1 m and 0.01 rad
        // standard deviations holds the estimate there along the wall,
        // while the scan pulls it onto the wall across.
        let truth = Se2::identity();
        let (field, scan) = field_and_scan(&truth);
        let wall: Vec<Point2<f64>> = scan
            .into_iter()
            .filter(|p| (p.x - 2.125).abs() < 1e-9 && p.y.abs() < 2.0)
            .collect();
        assert!(wall.len() > 10);
        let start = Se2::new(0.3, 0.4, 0.0);
        let mut problem = test_problem(&field, wall.as_slice(), 0.0, 1.0);
        let free = problem.refine(&start);
        assert!(free.x().abs() < 0.08, "{free:?}");
        // The score alone, flat along the wall, leaves y near the start.
        assert!(free.y() > 0.2, "{free:?}");
        problem.prior = Some((
            Se2::identity(),
            Matrix3::from_diagonal(&Vector3::new(100.0, 100.0, 1e4)),
        ));
        let held = problem.refine(&start);
        assert!(held.x().abs() < 0.08, "{held:?}");
        assert!(held.y().abs() < 0.1, "{held:?}");
    }

    #[test]
    fn without_points_the_start_is_returned() {
        let (field, _) = field_and_scan(&Se2::identity());
        let problem = test_problem(&field, &[], 0.0, 1.0);
        let start = Se2::new(1.0, 2.0, 0.0);
        assert_eq!(problem.refine(&start), start);
    }
}
