//! The Monte Carlo localiser: one predict-weight-resample step per sonar
//! rotation, on one thread, with one seeded random stream.
//!
//! Per rotation `k` (its scan `S_k` in the vehicle frame at the rotation's
//! reference time, the dead reckoning's motion `Δ_k` since the previous
//! rotation with its covariance `Σ_k`, and the compass heading `θ_k`):
//!
//! 1. **Predict**: every particle moves by `x ⊕ Δ_k ⊕ ε`, `ε ~ N(0,
//!    scale·Σ_k + floor²)` in the frame of the moved pose.
//! 2. **Weight**: `log w += gain · s̄(x) − (θ(x) − θ_k)² / (2σ_θ²)`, where
//!    `s̄(x)` is eq. (5) on the map's likelihood field divided by the number
//!    of points scored ([`LikelihoodField::score`]), and `σ_θ` is
//!    `global_heading_sigma_rad` (the map's frame is the compass's, up to
//!    the heading units' biases).
//! 3. **Judge**: the scan's fit and coverage at the weighted mean and the
//!    cloud's spread set the state ([`LocalizationState`]); the estimate is
//!    the weighted mean, by default refined when localised to the mode of
//!    the posterior near it: the scan's log-weight of step 2 plus the
//!    predicted cloud of step 1 as a Gaussian prior ([`super::refine`], on
//!    the field's refine raster, [`LikelihoodField::refine_score`]).
//! 4. **Resample** by KLD sampling ([`super::particles::kld_resample`]);
//!    when the scans have stopped fitting a converged cloud for
//!    `lost_after_rotations` rotations, the particles are spread over the
//!    whole map again instead (kidnapping recovery).
//!
//! The first step has no motion: the particles start over the whole map
//! ([`MonteCarloLocalizer::step`] seeds them), or at a known pose
//! ([`MonteCarloLocalizer::start_at`]).

use super::field::LikelihoodField;
use super::particles::{
    Belief, KldBounds, Particle, belief, covariance, kld_resample, set_weights,
};
use super::refine::RefineProblem;
use super::{Estimate, LocalizationConfig};
use crate::error::FrontendError;
use echofield_graph::{Se2, wrap_angle};
use nalgebra::{Matrix3, Point2, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

/// Fewest scan points that weigh the particles; a rotation with fewer
/// only moves them.
const MIN_SCAN_POINTS: usize = 10;

/// A localised cloud that spreads (the sonar sees too little of the map to
/// hold it) keeps coasting up to this many times `converged_spread_m`;
/// beyond, the filter no longer claims to know where it is (searching).
const COASTING_SPREAD_FACTOR: f64 = 3.0;

/// Consecutive rotations on which a searching filter must find a
/// concentrated cloud whose scan fits the map before it claims to be
/// localised. One scan after a global start can fit a wrong place about as
/// well as a marginal fit of the right one (a quay like another quay); the
/// next rotation, moved by the dead reckoning, rarely fits the same wrong
/// place again. A filter started at a known pose
/// ([`MonteCarloLocalizer::start_at`]) needs one.
pub const CONFIRM_ROTATIONS: usize = 2;

/// Share of the scan's points inside the map's coverage that a searching
/// filter's fit needs to count towards [`CONFIRM_ROTATIONS`]. Tracking
/// judges fits from `min_coverage` on, but a global fix has no prior
/// behind it: a scan mostly outside the map is judged on its inside part
/// alone, where a straight wall fits a wrong quay as well as the right
/// one. A scan of a mapped place lies nearly all inside (measured:
/// EXPERIMENTS.md § Localisation through DVL gaps).
const CONFIRM_COVERAGE: f64 = 0.75;

/// What the filter believes about itself after a rotation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LocalizationState {
    /// No single pose explains the scans yet (global search, or the cloud
    /// converged where the scans do not fit): not localised.
    Searching,
    /// The cloud is concentrated and the scan fits the map there (from
    /// searching: on `CONFIRM_ROTATIONS` rotations in a row).
    Localised,
    /// Was localised; now the sonar sees too little of the map to check the
    /// fit, or the cloud has spread beyond `converged_spread_m` (up to
    /// three times it): carried by dead reckoning and what the sonar still
    /// sees of the map (the spread says how sure).
    Coasting,
    /// The scans stopped fitting a concentrated cloud (kidnapped): the
    /// particles were spread over the whole map again.
    Lost,
}

impl LocalizationState {
    /// Localised or coasting: the estimate is believed.
    pub fn is_localised(self) -> bool {
        matches!(self, Self::Localised | Self::Coasting)
    }
}

/// One rotation's result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalizationStep {
    pub state: LocalizationState,
    /// The estimate ([`LocalizationConfig::estimate`]),
    /// `world_from_vehicle` in the map's world frame.
    pub estimate: Se2,
    /// Weighted mean of the particles (map frame).
    pub mean: Se2,
    /// Square root of the trace of the particles' position covariance, m.
    pub spread_m: f64,
    /// Circular standard deviation of the particles' heading, rad.
    pub heading_spread_rad: f64,
    /// Particles weighed in this rotation.
    pub particles: usize,
    /// Mean field value of the scan points inside the map's coverage at
    /// the weighted mean (0-1; 0 without a scan): what the state is judged
    /// on.
    pub fit: f64,
    /// Fraction of the scan points inside the map's coverage at the
    /// weighted mean.
    pub coverage: f64,
    /// Scan points scored per particle.
    pub scan_points: usize,
    /// The particles were spread over the whole map after (or, at the
    /// start, before) this rotation.
    pub reseeded: bool,
    /// What this rotation's scan and compass told the filter, as an
    /// information matrix in `(x, y, θ)` (world frame, m⁻² and rad⁻²): the
    /// weighed cloud's information minus the predicted cloud's, negative
    /// eigenvalues set to 0 (a direction the scan does not see, e.g. along
    /// a quay, gets none). `None` without a prediction (the first rotation,
    /// a seeding) or a scan. What the offline smoother takes as a fix, so
    /// that the motion it also holds is not counted twice.
    pub scan_information: Option<Matrix3<f64>>,
}

/// The particle filter (see the module doc).
pub struct MonteCarloLocalizer {
    config: LocalizationConfig,
    field: LikelihoodField,
    particles: Vec<Particle>,
    rng: ChaCha8Rng,
    state: LocalizationState,
    /// Consecutive rotations whose scan did not fit a concentrated cloud.
    poor_fits: usize,
    /// Consecutive rotations, while searching, whose scan fitted a
    /// concentrated cloud ([`CONFIRM_ROTATIONS`]).
    confirmed_fits: usize,
}

impl MonteCarloLocalizer {
    /// A filter on `field`. Errors: an invalid config.
    pub fn new(config: &LocalizationConfig, field: LikelihoodField) -> Result<Self, FrontendError> {
        config.validate()?;
        Ok(Self {
            config: config.clone(),
            field,
            particles: Vec::new(),
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            state: LocalizationState::Searching,
            poor_fits: 0,
            confirmed_fits: 0,
        })
    }

    /// The map's likelihood field.
    pub fn field(&self) -> &LikelihoodField {
        &self.field
    }

    /// The current particles (after the last resampling).
    pub fn particles(&self) -> &[Particle] {
        &self.particles
    }

    /// Starts tracking from a known `world_from_vehicle` with standard
    /// deviations `sigma` (x m, y m, heading rad): `min_particles`
    /// particles drawn around it.
    pub fn start_at(&mut self, pose: Se2, sigma: Vector3<f64>) {
        // A known start is its own confirmation: the first rotation that
        // fits localises.
        self.confirmed_fits = CONFIRM_ROTATIONS - 1;
        let n = self.config.min_particles;
        self.particles = (0..n)
            .map(|_| {
                let e = self.normal3().component_mul(&sigma);
                Particle {
                    pose: pose.compose(&Se2::new(e.x, e.y, e.z)),
                    weight: 1.0 / n as f64,
                }
            })
            .collect();
    }

    /// Spreads `max_particles` particles uniformly over the map's covered
    /// cells, the heading around `heading_rad` (see
    /// [`LocalizationConfig::global_heading_sigma_rad`]).
    fn seed_global(&mut self, heading_rad: f64) {
        let n = self.config.max_particles;
        let cells = self.field.covered_cells();
        let grid = self.field.grid();
        let (width, cell_m) = (grid.width(), grid.cell_size_m());
        let (x0, y0) = grid.origin_m();
        let sigma = self.config.global_heading_sigma_rad;
        let mut particles = Vec::with_capacity(n);
        for _ in 0..n {
            let k = cells[self.rng.random_range(0..cells.len())] as usize;
            let (ix, iy) = ((k % width) as f64, (k / width) as f64);
            let x = x0 + (ix + self.rng.random::<f64>()) * cell_m;
            let y = y0 + (iy + self.rng.random::<f64>()) * cell_m;
            let theta = if sigma >= std::f64::consts::PI {
                self.rng
                    .random_range(-std::f64::consts::PI..std::f64::consts::PI)
            } else {
                heading_rad + sigma * self.rng.sample::<f64, _>(StandardNormal)
            };
            particles.push(Particle {
                pose: Se2::new(x, y, wrap_angle(theta)),
                weight: 1.0 / n as f64,
            });
        }
        self.particles = particles;
    }

    fn normal3(&mut self) -> Vector3<f64> {
        Vector3::new(
            self.rng.sample(StandardNormal),
            self.rng.sample(StandardNormal),
            self.rng.sample(StandardNormal),
        )
    }

    /// Moves every particle by `relative` (`previous_from_current` of the
    /// dead reckoning) with noise of covariance `covariance` (scaled, with
    /// the floors added).
    fn predict(&mut self, relative: &Se2, covariance: &Matrix3<f64>) {
        let c = &self.config;
        let floor = Matrix3::from_diagonal(&Vector3::new(
            c.motion_noise_floor_m.powi(2),
            c.motion_noise_floor_m.powi(2),
            c.motion_noise_floor_rad.powi(2),
        ));
        let sigma = covariance * c.motion_noise_scale + floor;
        // A covariance from the navigation is symmetric positive
        // semi-definite; the floor makes it definite. Should rounding still
        // defeat Cholesky, the diagonal alone is used.
        let factor = match sigma.cholesky() {
            Some(l) => l.l(),
            None => Matrix3::from_diagonal(&sigma.diagonal().map(|v| v.max(0.0).sqrt())),
        };
        for i in 0..self.particles.len() {
            let e = factor * self.normal3();
            let p = &mut self.particles[i];
            p.pose = p.pose.compose(relative).compose(&Se2::new(e.x, e.y, e.z));
        }
    }

    /// One rotation (see the module doc): `motion` is the vehicle's
    /// `previous_from_current` (the dead reckoning's, or its fusion with
    /// the sonar's sequential match) and its covariance since the previous step
    /// (`None` at the first), `heading_rad` the compass heading of the
    /// dead reckoning at this rotation's reference time, `points` the scan
    /// `S_k` in the vehicle frame (may be empty).
    pub fn step(
        &mut self,
        motion: Option<&(Se2, Matrix3<f64>)>,
        heading_rad: f64,
        points: &[Point2<f64>],
    ) -> LocalizationStep {
        let mut reseeded = false;
        let mut prior = None;
        if self.particles.is_empty() {
            self.seed_global(heading_rad);
            reseeded = true;
        } else if let Some((relative, motion_covariance)) = motion {
            self.predict(relative, motion_covariance);
            // The predicted cloud is the refinement's prior (step 3); a
            // degenerate one (every particle on one pose) gives none.
            let mean = belief(&self.particles).mean;
            prior = covariance(&self.particles, &mean)
                .try_inverse()
                .map(|information| (mean, information));
        }
        let stride = points.len().div_ceil(self.config.max_scan_points).max(1);
        let scored = points.len() >= MIN_SCAN_POINTS;
        if scored {
            self.weigh(heading_rad, points, stride);
        }
        let weighed = self.particles.len();
        let b = belief(&self.particles);
        let scan_information = match &prior {
            Some((_, predicted)) if scored => covariance(&self.particles, &b.mean)
                .try_inverse()
                .map(|information| positive_part(&(information - predicted))),
            _ => None,
        };
        let at_mean = self
            .field
            .score(&b.mean, points, stride, self.config.unknown_value);
        let lost = self.judge(&b, scored, at_mean.fit, at_mean.coverage);
        let sees_map = scored && at_mean.coverage >= self.config.min_coverage;
        let estimate = self.estimate(&b, sees_map, heading_rad, points, stride, prior);
        if lost {
            self.seed_global(heading_rad);
            reseeded = true;
        } else if scored {
            let bounds = self.kld_bounds();
            let u0 = self.rng.random::<f64>();
            self.particles = kld_resample(&self.particles, u0, &bounds);
        }
        LocalizationStep {
            state: self.state,
            estimate,
            mean: b.mean,
            spread_m: b.spread_m,
            heading_spread_rad: b.heading_spread_rad,
            particles: weighed,
            fit: if scored { at_mean.fit } else { 0.0 },
            coverage: if scored { at_mean.coverage } else { 0.0 },
            scan_points: if scored {
                points.len().div_ceil(stride)
            } else {
                0
            },
            reseeded,
            scan_information,
        }
    }

    /// Step 2 of the module doc.
    fn weigh(&mut self, heading_rad: f64, points: &[Point2<f64>], stride: usize) {
        let c = &self.config;
        let heading_var = c.global_heading_sigma_rad.powi(2);
        let log_weights: Vec<f64> = self
            .particles
            .iter()
            .map(|p| {
                let s = self.field.score(&p.pose, points, stride, c.unknown_value);
                let dh = wrap_angle(p.pose.theta() - heading_rad);
                c.score_gain * s.mean - dh * dh / (2.0 * heading_var)
            })
            .collect();
        set_weights(&mut self.particles, &log_weights);
    }

    /// The step's estimate ([`LocalizationConfig::estimate`]) from the
    /// weighed particles and their belief `b`: refined only when the
    /// filter believes it is localised and the scan sees the map
    /// (`sees_map`), else the weighted mean.
    fn estimate(
        &self,
        b: &Belief,
        sees_map: bool,
        heading_rad: f64,
        points: &[Point2<f64>],
        stride: usize,
        prior: Option<(Se2, Matrix3<f64>)>,
    ) -> Se2 {
        let c = &self.config;
        match c.estimate {
            Estimate::Mean => b.mean,
            Estimate::BestParticle => self
                .particles
                .iter()
                .max_by(|a, b| a.weight.total_cmp(&b.weight))
                .map_or(b.mean, |p| p.pose),
            Estimate::Refined if sees_map && self.state.is_localised() => RefineProblem {
                field: &self.field,
                points,
                stride,
                unknown: c.unknown_value,
                gain: c.score_gain,
                heading_rad,
                heading_sigma_rad: c.global_heading_sigma_rad,
                max_shift_m: c.refine_max_shift_m,
                prior,
            }
            .refine(&b.mean),
            Estimate::Refined => b.mean,
        }
    }

    /// Step 3: the new state; true when the vehicle is judged lost (the
    /// caller re-seeds).
    fn judge(&mut self, b: &Belief, scored: bool, fit: f64, coverage: f64) -> bool {
        use LocalizationState::*;
        let c = &self.config;
        let was_localised = self.state.is_localised();
        let converged = b.spread_m <= c.converged_spread_m;
        let sees_map = scored && coverage >= c.min_coverage;
        let fits = fit >= c.min_fit;
        if converged && sees_map && !fits {
            self.confirmed_fits = 0;
            self.poor_fits += 1;
            if self.poor_fits >= c.lost_after_rotations {
                self.poor_fits = 0;
                self.state = Lost;
                return true;
            }
            // Not yet judged: the state stays.
            if self.state == Lost {
                self.state = Searching;
            }
            return false;
        }
        self.poor_fits = 0;
        let coasting = b.spread_m <= COASTING_SPREAD_FACTOR * c.converged_spread_m;
        self.state = match (converged, sees_map) {
            (true, true) if was_localised => Localised,
            (true, true) if coverage < CONFIRM_COVERAGE => Searching,
            (true, true) => {
                self.confirmed_fits += 1;
                if self.confirmed_fits >= CONFIRM_ROTATIONS {
                    Localised
                } else {
                    Searching
                }
            }
            _ if was_localised && coasting => Coasting,
            _ => Searching,
        };
        if self.state != Searching || !(converged && sees_map && coverage >= CONFIRM_COVERAGE) {
            self.confirmed_fits = 0;
        }
        false
    }

    fn kld_bounds(&self) -> KldBounds {
        let c = &self.config;
        KldBounds {
            min_particles: c.min_particles,
            max_particles: c.max_particles,
            epsilon: c.kld_epsilon,
            z: c.kld_z,
            bin_m: c.kld_bin_m,
            bin_rad: c.kld_bin_rad,
        }
    }
}

/// `m` (symmetric) with its negative eigenvalues set to 0.
fn positive_part(m: &Matrix3<f64>) -> Matrix3<f64> {
    let mut eigen = m.symmetric_eigen();
    eigen.eigenvalues.iter_mut().for_each(|l| *l = l.max(0.0));
    eigen.recompose()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::Grid;

    /// A 40 m x 40 m map of an L-shaped pair of walls and a post, fully
    /// covered, and a scan of it seen from `world_from_vehicle`.
    fn map_and_scan(world_from_vehicle: &Se2) -> (LikelihoodField, Vec<Point2<f64>>) {
        let cell = 0.25;
        let mut grid = Grid::zeros(-20.0, -20.0, cell, 160, 160);
        let mut world_points = Vec::new();
        for i in 0..120 {
            let t = -15.0 + 0.25 * i as f64;
            world_points.push((t, 12.0)); // wall along y = 12
            world_points.push((-12.0, t)); // wall along x = -12
        }
        for i in 0..12 {
            let a = i as f64 * std::f64::consts::PI / 6.0;
            world_points.push((5.0 + a.cos(), -4.0 + a.sin())); // post
        }
        let w = grid.width();
        for &(x, y) in &world_points {
            let (ix, iy) = grid.cell_of(x, y);
            grid.values_mut()[iy as usize * w + ix as usize] = 1.0;
        }
        let field = LikelihoodField::new(grid, &[(Se2::identity(), 30.0)], 0.5).unwrap();
        let vehicle_from_world = world_from_vehicle.inverse();
        let scan = world_points
            .iter()
            .map(|&(x, y)| {
                let (u, v) = vehicle_from_world.transform_xy(x, y);
                Point2::new(u, v)
            })
            .collect();
        (field, scan)
    }

    fn config() -> LocalizationConfig {
        LocalizationConfig {
            max_particles: 5000,
            ..LocalizationConfig::default()
        }
    }

    #[test]
    fn a_global_start_converges_on_the_true_pose() {
        // The vehicle drives 1 m per rotation straight ahead from (-3, 2),
        // heading 0.3 rad.
        let mut filter =
            MonteCarloLocalizer::new(&config(), map_and_scan(&Se2::identity()).0).unwrap();
        let motion = (
            Se2::new(1.0, 0.0, 0.0),
            Matrix3::from_diagonal_element(1e-4),
        );
        let mut last = None;
        for k in 0..8 {
            let truth = Se2::new(-3.0, 2.0, 0.3).compose(&Se2::new(k as f64, 0.0, 0.0));
            let (_, scan) = map_and_scan(&truth);
            let step = filter.step((k > 0).then_some(&motion), 0.3, &scan);
            // The seeding has no prediction to tell the scan's share from.
            assert_eq!(step.scan_information.is_some(), k > 0, "rotation {k}");
            last = Some((step, truth));
        }
        let (step, truth) = last.unwrap();
        assert_eq!(step.state, LocalizationState::Localised, "{step:?}");
        // Tracking, the scan adds information (positive semi-definite).
        let information = step.scan_information.unwrap();
        let eigenvalues = information.symmetric_eigenvalues();
        assert!(eigenvalues.iter().all(|l| *l >= -1e-9), "{information}");
        assert!(eigenvalues.max() > 0.0, "{information}");
        let error = (step.estimate.translation() - truth.translation()).norm();
        assert!(error < 0.3, "{error} m: {step:?}");
        assert!(step.particles < 5000, "KLD kept {}", step.particles);
    }

    #[test]
    fn a_searching_filter_localises_on_consecutive_fits_only() {
        use LocalizationState::*;
        let (field, _) = map_and_scan(&Se2::identity());
        let mut filter = MonteCarloLocalizer::new(&config(), field).unwrap();
        let concentrated = Belief {
            mean: Se2::identity(),
            spread_m: 0.2,
            heading_spread_rad: 0.01,
        };
        let (good, poor) = (config().min_fit + 0.05, config().min_fit - 0.01);
        // A good fit, a poor one, a good one: a wrong place that fits now
        // and then (seed 3 of the marina on a map of seed 1) never localises.
        for fit in [good, poor, good] {
            assert!(!filter.judge(&concentrated, true, fit, 1.0));
            assert_eq!(filter.state, Searching, "fit {fit}");
        }
        // The second good fit in a row does.
        assert!(!filter.judge(&concentrated, true, good, 1.0));
        assert_eq!(filter.state, Localised);
        // Localised, one poor fit keeps the state and a good one holds it.
        assert!(!filter.judge(&concentrated, true, poor, 1.0));
        assert_eq!(filter.state, Localised);
        assert!(!filter.judge(&concentrated, true, good, 1.0));
        assert_eq!(filter.state, Localised);
        // Good fits of a scan half outside the map do not count, and one
        // breaks a run of confirming fits (a wall fitting a wrong quay).
        let (field, _) = map_and_scan(&Se2::identity());
        let mut edge = MonteCarloLocalizer::new(&config(), field).unwrap();
        for coverage in [0.5, 0.5, 1.0, 0.5, 1.0] {
            assert!(!edge.judge(&concentrated, true, good, coverage));
            assert_eq!(edge.state, Searching, "coverage {coverage}");
        }
        assert!(!edge.judge(&concentrated, true, good, 1.0));
        assert_eq!(edge.state, Localised);
        // Once localised, it tracks on such fits.
        assert!(!edge.judge(&concentrated, true, good, 0.5));
        assert_eq!(edge.state, Localised);
        // A known start needs one fit.
        let (field, _) = map_and_scan(&Se2::identity());
        let mut known = MonteCarloLocalizer::new(&config(), field).unwrap();
        known.start_at(Se2::identity(), Vector3::new(0.1, 0.1, 0.01));
        assert!(!known.judge(&concentrated, true, good, 1.0));
        assert_eq!(known.state, Localised);
    }

    #[test]
    fn the_same_seed_gives_the_same_steps() {
        let run = || {
            let mut filter =
                MonteCarloLocalizer::new(&config(), map_and_scan(&Se2::identity()).0).unwrap();
            let (_, scan) = map_and_scan(&Se2::new(1.0, 1.0, 0.0));
            (0..3)
                .map(|_| filter.step(None, 0.0, &scan))
                .collect::<Vec<_>>()
        };
        assert_eq!(run(), run());
    }

    #[test]
    fn a_scan_that_fits_nowhere_is_never_localised_and_a_kidnapping_is_detected() {
        let (field, _) = map_and_scan(&Se2::identity());
        let mut filter = MonteCarloLocalizer::new(&config(), field).unwrap();
        // Start tracking at the origin, where the scan below does not fit:
        // a ring of points 3 m around the vehicle that no wall explains.
        filter.start_at(Se2::identity(), Vector3::new(0.1, 0.1, 0.01));
        let ring: Vec<Point2<f64>> = (0..60)
            .map(|i| {
                let a = i as f64 * std::f64::consts::TAU / 60.0;
                Point2::new(3.0 * a.cos(), 3.0 * a.sin())
            })
            .collect();
        let motion = (Se2::identity(), Matrix3::from_diagonal_element(1e-4));
        let states: Vec<LocalizationState> = (0..12)
            .map(|_| filter.step(Some(&motion), 0.0, &ring).state)
            .collect();
        assert!(states.contains(&LocalizationState::Lost), "{states:?}");
        assert!(
            !states.contains(&LocalizationState::Localised),
            "{states:?}"
        );
    }
}
