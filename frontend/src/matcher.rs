//! The acoustic-image measurement model (paper section 5).
//!
//! A scan `S_k = {p_i}` (points in the scan's reference frame) is placed on
//! the acoustic image `I_j` by the pose `x = image_from_scan` that maximises
//!
//! `s(x) = Σ_i I_j(x ⊕ p_i)`  (eq. 5),   `x* = argmax_x s(x)`  (eq. 6).
//!
//! [`match_scan`] searches the window that the prior allows in three steps:
//! 1. [`search`]: branch-and-bound over a discretised window (cells in x and
//!    y, an angle step that moves a point at the scan's RMS range by one
//!    cell, the step of the covariance fit too), exact for
//!    the score on the raster, with the max-pooled image pyramid as bounds;
//!    [`match_scan_local`] climbs from the prior to the nearest lattice
//!    maximum instead, for priors already close to the answer; then
//!    [`rim`] refines that lattice pose away from the rim of the image's
//!    reach, where the sum of eq. (5) pulls a match along a wall that runs
//!    out of the image towards a shorter displacement (a climb of a few
//!    lattice steps on the mean over the points inside the rim; the fits
//!    of steps 2 and 3 then use the points that stay inside it; off with
//!    [`MatcherConfig::refine_inside_reach`], and for images without a
//!    known reach);
//! 2. [`covariance`]: a quadratic fit of the raster score around the best
//!    lattice pose and a Laplace approximation give the covariance, and the
//!    fitted quadratic's peak (a Newton step of at most one lattice step)
//!    is the sub-cell estimate `x*`;
//! 3. the pose fit: the same quadratic fit, on the image's pose-fit raster
//!    ([`AcousticImage::pose_fit_grid`], built with a smaller off-axis
//!    margin and no range smoothing, see
//!    [`PoseFitRaster`](crate::image::PoseFitRaster)) around the estimate,
//!    moves it to that raster's peak, by at most half a lattice step and
//!    only along the directions the raster constrains. The score, the
//!    quality and the covariance stay those of the searched image at its
//!    peak ([`MatchResult::searched_peak`]), which the gates are set for.
//!
//! Bad input (NaN points or prior, invalid window or config) is an `Err`;
//! data that cannot be matched gives [`MatchOutcome::NoMatch`] with a
//! [`NoMatchReason`]: too few points, an image without echoes, or no pose
//! in the window that puts any point on an echo (e.g. a prior far outside
//! the image).

pub mod config;
pub mod covariance;
pub mod gate;
pub mod outcome;
pub mod rim;
pub mod search;
pub mod symmetric;
pub mod window;
pub mod window_key;

pub use config::MatcherConfig;
pub use gate::MatchGate;
pub use outcome::{MatchOutcome, MatchQuality, MatchResult, MatchStats, NoMatchReason};
pub use window::SearchWindow;

use crate::error::FrontendError;
use crate::image::AcousticImage;
use echofield_graph::Se2;
use nalgebra::{Point2, Vector3};

/// `s(x)` of eq. (5): the sum of the image under the transformed points,
/// with `I` interpolated from the samples ([`AcousticImage::fine_value_at`]).
pub fn score(points: &[Point2<f64>], image: &AcousticImage, image_from_scan: &Se2) -> f64 {
    let (s, c) = image_from_scan.rotation().angle().sin_cos();
    let (tx, ty) = (image_from_scan.x(), image_from_scan.y());
    points
        .iter()
        .map(|p| image.fine_value_at(c * p.x - s * p.y + tx, s * p.x + c * p.y + ty))
        .sum()
}

/// `s(x)` on the raster (bilinear lookup, [`AcousticImage::value_at`]):
/// what the coarse search maximises, and what the covariance is fitted to.
pub fn raster_score(points: &[Point2<f64>], image: &AcousticImage, image_from_scan: &Se2) -> f64 {
    let (s, c) = image_from_scan.rotation().angle().sin_cos();
    let (tx, ty) = (image_from_scan.x(), image_from_scan.y());
    points
        .iter()
        .map(|p| image.value_at(c * p.x - s * p.y + tx, s * p.x + c * p.y + ty))
        .sum()
}

/// `s(x) / N`, 0 for an empty scan.
pub fn mean_score(points: &[Point2<f64>], image: &AcousticImage, image_from_scan: &Se2) -> f64 {
    if points.is_empty() {
        0.0
    } else {
        score(points, image, image_from_scan) / points.len() as f64
    }
}

/// Matches scan `points` (scan frame) against `image`, searching `window`
/// around `prior` (`image_from_scan`). See the module doc for the method
/// and the failure modes.
pub fn match_scan(
    points: &[Point2<f64>],
    image: &AcousticImage,
    prior: &Se2,
    window: &SearchWindow,
    config: &MatcherConfig,
) -> Result<MatchOutcome, FrontendError> {
    match_with(
        points,
        image,
        prior,
        window,
        config,
        MatchOptions::edge(Search::Global),
    )
}

/// [`match_scan`] with a local coarse search: hill-climbing on the same
/// lattice from the prior ([`search::SearchProblem::local_max`]) instead of
/// the global branch-and-bound, then the same sub-cell fit, covariance and
/// quality. It finds the maximum of eq. (6) nearest the prior, not the
/// best in the window: for verifying a pair whose prior is already close
/// (loop densification), at a fraction of the cost; the window bounds the
/// climb.
pub fn match_scan_local(
    points: &[Point2<f64>],
    image: &AcousticImage,
    prior: &Se2,
    window: &SearchWindow,
    config: &MatcherConfig,
) -> Result<MatchOutcome, FrontendError> {
    match_with(
        points,
        image,
        prior,
        window,
        config,
        MatchOptions::edge(Search::Local),
    )
}

/// The coarse search of a match.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Search {
    /// Branch-and-bound over the whole window ([`match_scan`]).
    Global,
    /// Hill-climbing from the prior ([`match_scan_local`]).
    Local,
}

/// How [`MatchQuality::mean_intensity`] (and so the score) of a match is
/// evaluated at the estimate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QualityModel {
    /// `I` interpolated from the beam samples
    /// ([`AcousticImage::fine_value_at`]): the quality the acceptance
    /// gates read. A few hundred nanoseconds per point.
    Samples,
    /// `I` looked up bilinearly on the raster ([`raster_score`]), some
    /// twenty times cheaper and a little lower where echoes are sharper
    /// than a cell: for matches whose quality no gate reads, such as the
    /// reverse match of the symmetric check, which only compares poses.
    Raster,
}

/// Which lattice the covariance of a match is fitted over
/// ([`covariance::fit_surface`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CovarianceModel {
    /// The 5 x 5 x 5 lattice around the estimate: the covariance an edge
    /// of the pose graph carries.
    Surface,
    /// Only its inner 3 x 3 x 3 nodes, for matches whose covariance no one
    /// reads (the reverse match of a loop's symmetric check, which only
    /// compares poses): a third of the cost and the same pose, because the
    /// sub-cell peak is taken from the inner nodes either way and their
    /// scores do not depend on the lattice's size. The covariance is
    /// smaller (a fifth to two fifths of the variances on a synthetic
    /// scene): the inner nodes see only the peak's sharpest curvature.
    Inner,
}

/// How a match is searched and what it evaluates beyond its pose.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MatchOptions {
    pub search: Search,
    pub quality: QualityModel,
    pub covariance: CovarianceModel,
}

impl MatchOptions {
    /// A match whose quality the gates read and whose covariance an edge
    /// carries ([`match_scan`], [`match_scan_local`]).
    pub fn edge(search: Search) -> Self {
        Self {
            search,
            quality: QualityModel::Samples,
            covariance: CovarianceModel::Surface,
        }
    }
}

/// [`match_scan`] or [`match_scan_local`] with other [`MatchOptions`]
/// (those two use [`MatchOptions::edge`]).
pub fn match_scan_with(
    points: &[Point2<f64>],
    image: &AcousticImage,
    prior: &Se2,
    window: &SearchWindow,
    config: &MatcherConfig,
    options: MatchOptions,
) -> Result<MatchOutcome, FrontendError> {
    match_with(points, image, prior, window, config, options)
}

fn match_with(
    points: &[Point2<f64>],
    image: &AcousticImage,
    prior: &Se2,
    window: &SearchWindow,
    config: &MatcherConfig,
    options: MatchOptions,
) -> Result<MatchOutcome, FrontendError> {
    validate_inputs(points, prior, window, config)?;
    if let Some(reason) = unmatchable(points, image, config) {
        return Ok(MatchOutcome::NoMatch { reason });
    }
    let points = thin(points, config.max_points);
    let lattice = Lattice::new(&points, image.cell_size_m(), window, config);
    let problem = search::SearchProblem::new(&points, image, prior, &lattice.disc);
    let mut stats = search::SearchStats::default();
    let found = match options.search {
        Search::Local => problem.local_max(&mut stats),
        Search::Global => problem.best_leaf(&mut stats),
    };
    let Some(best) = found else {
        return Ok(MatchOutcome::NoMatch {
            reason: NoMatchReason::NoOverlap,
        });
    };
    let coarse = best.pose(prior, &lattice.disc, lattice.cell_m);
    // Step 2: away from the rim of the image's reach (see `rim`).
    let reach = image.reach().filter(|_| config.refine_inside_reach);
    let refined = reach.and_then(|reach| {
        rim::refine_inside_reach(
            &points,
            image,
            reach,
            &coarse,
            &best,
            &lattice.disc,
            config.min_points,
        )
    });
    let (coarse, fit_points) = match &refined {
        Some(r) => (r.pose, r.points.as_slice()),
        None => (coarse, points.as_slice()),
    };
    let start = Start {
        pose: coarse,
        fit_points,
    };
    let mut result = refine(&points, image, &start, window, &lattice, config, options);
    result.stats.search_nodes = stats.nodes;
    Ok(MatchOutcome::Match(Box::new(result)))
}

/// Errors for input that no match can use: an invalid config or window,
/// a non-finite prior or scan point (named by its index).
fn validate_inputs(
    points: &[Point2<f64>],
    prior: &Se2,
    window: &SearchWindow,
    config: &MatcherConfig,
) -> Result<(), FrontendError> {
    config.validate()?;
    window.validate()?;
    if !prior.is_finite() {
        return Err(FrontendError::input("match", "prior", "pose is not finite"));
    }
    match points
        .iter()
        .position(|p| !(p.x.is_finite() && p.y.is_finite()))
    {
        Some(i) => Err(FrontendError::input(
            format!("scan point {i}"),
            "x/y",
            "not finite",
        )),
        None => Ok(()),
    }
}

/// Why valid input cannot be matched before any search: too few points,
/// or an image without echoes.
fn unmatchable(
    points: &[Point2<f64>],
    image: &AcousticImage,
    config: &MatcherConfig,
) -> Option<NoMatchReason> {
    if points.len() < config.min_points {
        Some(NoMatchReason::TooFewPoints {
            points: points.len(),
            required: config.min_points,
        })
    } else if image.is_empty() {
        Some(NoMatchReason::EmptyImage)
    } else {
        None
    }
}

/// The search lattice of a match: cells of the image in x and y, and an
/// angle step that moves a point at the scan's RMS range `rho_m` by one
/// cell (unless the config sets one).
struct Lattice {
    disc: search::Discretisation,
    cell_m: f64,
    rho_m: f64,
}

impl Lattice {
    fn new(
        points: &[Point2<f64>],
        cell_m: f64,
        window: &SearchWindow,
        config: &MatcherConfig,
    ) -> Self {
        let mean_square =
            points.iter().map(|p| p.coords.norm_squared()).sum::<f64>() / points.len() as f64;
        let rho_m = mean_square.sqrt().max(cell_m);
        let angle_step_rad = config.angle_step_rad.unwrap_or(cell_m / rho_m);
        Self {
            disc: search::Discretisation {
                angle_step_rad,
                angle_steps: steps_within(window.theta_rad, angle_step_rad),
                cells_x: steps_within(window.x_m, cell_m),
                cells_y: steps_within(window.y_m, cell_m),
            },
            cell_m,
            rho_m,
        }
    }

    /// One lattice step along x, y and θ: the covariance fit's step (its
    /// angle step is always the one-cell-at-RMS-range one).
    fn steps(&self) -> Vector3<f64> {
        Vector3::new(self.cell_m, self.cell_m, self.cell_m / self.rho_m)
    }
}

/// Where the fits of a match start: the lattice pose (the search's, or
/// the rim refinement's) and the points the covariance and pose fits use
/// (all of them, or those the rim refinement kept).
struct Start<'a> {
    pose: Se2,
    fit_points: &'a [Point2<f64>],
}

/// Steps 2 and 3 of the module doc from the coarse lattice pose: the
/// covariance fit and its sub-cell peak, the quality at that peak, then
/// the pose fit. `stats.search_nodes` is left 0 for the caller.
fn refine(
    points: &[Point2<f64>],
    image: &AcousticImage,
    start: &Start,
    window: &SearchWindow,
    lattice: &Lattice,
    config: &MatcherConfig,
    options: MatchOptions,
) -> MatchResult {
    let (coarse, fit_points) = (&start.pose, start.fit_points);
    let steps = lattice.steps();
    let lattice_radius = match options.covariance {
        CovarianceModel::Surface => 2,
        CovarianceModel::Inner => 1,
    };
    let fit = covariance::fit_surface(
        fit_points,
        image.grid(),
        coarse,
        steps.z,
        lattice_radius,
        &window.as_vector().sup(&steps),
        config.covariance_scale,
    );
    // The peak of the fitted quadratic gives the sub-cell pose (the
    // lattice pose is quantised to the cells).
    let searched_peak = Se2::from_vector(&(coarse.to_vector() + fit.peak_offset));
    // The quality is read where the searched image peaks, before the pose
    // fit's correction: the gates are set for that image's intensities.
    let mean = match options.quality {
        QualityModel::Samples => mean_score(points, image, &searched_peak),
        QualityModel::Raster => raster_score(points, image, &searched_peak) / points.len() as f64,
    };
    MatchResult {
        image_from_scan: pose_fit(
            fit_points,
            image,
            &searched_peak,
            &steps,
            config.covariance_scale,
        ),
        searched_peak,
        score: mean * points.len() as f64,
        quality: MatchQuality {
            mean_intensity: mean,
            inside_fraction: inside_fraction(points, image, &searched_peak),
            points: points.len(),
            surface_fit_residual: fit.relative_fit_residual,
        },
        covariance: fit.covariance,
        coarse: *coarse,
        stats: MatchStats {
            angle_step_rad: lattice.disc.angle_step_rad,
            search_nodes: 0,
        },
    }
}

/// The share of `points` that `pose` puts inside the image's raster.
fn inside_fraction(points: &[Point2<f64>], image: &AcousticImage, pose: &Se2) -> f64 {
    let inside = points
        .iter()
        .filter(|p| {
            let q = pose.transform_point(p);
            image.grid().contains(q.x, q.y)
        })
        .count();
    inside as f64 / points.len() as f64
}

/// Half-width of the pose fit's lattice window, in lattice steps: the
/// directions along which the pose-fit raster's score peaks within about
/// this many steps are refined, the flatter ones left as they are.
const POSE_FIT_WINDOW_STEPS: f64 = 3.0;

/// Largest move of the pose fit, in lattice steps (the largest axis). The
/// bias it removes is a small fraction of a cell; the raster it reads is
/// not smoothed in range, and on real echoes its peak can sit a whole cell
/// away. 0.5 recovers the known offsets of the real MiniKing log better than 1,
/// and on the simulated missions keeps more of the fit's gain than 0.25
/// (measured: EXPERIMENTS.md § Matcher).
const POSE_FIT_MAX_STEPS: f64 = 0.5;

/// The last step of a match: the peak of a quadratic fitted to the score
/// on the image's pose-fit raster ([`AcousticImage::pose_fit_grid`]) around
/// `pose`, at most [`POSE_FIT_MAX_STEPS`] lattice steps (`steps`) away. That raster
/// is built with a smaller off-axis margin than the one searched: it
/// lacks the arcs that bias the heading, and the echoes it lacks are weak
/// ones the search needs but the peak's position does not. Images without
/// such a raster keep `pose`.
fn pose_fit(
    points: &[Point2<f64>],
    image: &AcousticImage,
    pose: &Se2,
    steps: &Vector3<f64>,
    tau: f64,
) -> Se2 {
    let Some(grid) = image.pose_fit_grid() else {
        return *pose;
    };
    let fit = covariance::fit_surface(
        points,
        grid,
        pose,
        steps.z,
        1,
        &(steps * POSE_FIT_WINDOW_STEPS),
        tau,
    );
    let mut offset = fit.peak_offset;
    let reach = offset.component_div(steps).amax();
    if reach > POSE_FIT_MAX_STEPS {
        offset *= POSE_FIT_MAX_STEPS / reach;
    }
    Se2::from_vector(&(pose.to_vector() + offset))
}

/// Number of whole steps within a half-width (0 for a zero half-width).
fn steps_within(half_width: f64, step: f64) -> i32 {
    (half_width / step).ceil().min(f64::from(1 << 20)) as i32
}

/// Every k-th point so at most `max` remain (all when already fewer).
fn thin(points: &[Point2<f64>], max: usize) -> Vec<Point2<f64>> {
    if points.len() <= max {
        return points.to_vec();
    }
    let stride = points.len().div_ceil(max);
    points.iter().step_by(stride).copied().collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::synthetic::{
        RotationPath, SceneConfig, SyntheticRotation, Wall, simulate_rotation, static_rotation,
    };
    use crate::image::{Grid, ImageConfig};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn image_of(rotation: &SyntheticRotation) -> AcousticImage {
        AcousticImage::build(
            &rotation.beams,
            &rotation.reference_from_beams,
            &ImageConfig::default(),
        )
        .unwrap()
    }

    /// A rotation of `scene` from a random pose within 2.5 m, 2 m and
    /// 0.25 rad of the origin, and its true pose relative to `a`.
    fn offset_rotation(
        scene: &SceneConfig,
        a: &SyntheticRotation,
        rng: &mut ChaCha8Rng,
        seed: u64,
    ) -> (SyntheticRotation, Se2) {
        let world_from_b = Se2::new(
            rng.random_range(-2.5..2.5),
            rng.random_range(-2.0..2.0),
            rng.random_range(-0.25..0.25),
        );
        let b = simulate_rotation(scene, &RotationPath::fixed(world_from_b), seed);
        let truth = a.world_from_reference.between(&b.world_from_reference);
        (b, truth)
    }

    fn pose_error(a: &Se2, b: &Se2) -> (f64, f64) {
        let d = a.between(b);
        (d.translation().norm(), d.theta().abs())
    }

    /// `grid` moved by `(dx, dy)` metres: the same values at a shifted
    /// origin.
    fn shifted(grid: &Grid, dx: f64, dy: f64) -> Grid {
        let (ox, oy) = grid.origin_m();
        let mut moved = Grid::zeros(
            ox + dx,
            oy + dy,
            grid.cell_size_m(),
            grid.width(),
            grid.height(),
        );
        moved.values_mut().copy_from_slice(grid.values());
        moved
    }

    #[test]
    fn the_last_step_moves_the_pose_to_the_peak_of_the_pose_fit_raster() {
        // The scan of a rotation against its own image, whose pose-fit
        // raster is the image moved by less than a cell: the search and the
        // quality read the image, the pose follows the moved raster.
        let rotation = static_rotation(&SceneConfig::default(), 3);
        let config = ImageConfig {
            pose_fit: crate::image::PoseFitRaster {
                enabled: false,
                ..Default::default()
            },
            ..ImageConfig::default()
        };
        let image =
            AcousticImage::build(&rotation.beams, &rotation.reference_from_beams, &config).unwrap();
        assert!(image.pose_fit_grid().is_none());
        let scan = &rotation.wall_points;
        let window = SearchWindow::new(0.5, 0.5, 0.05);
        let matcher = MatcherConfig::default();
        let plain = match_scan(scan, &image, &Se2::identity(), &window, &matcher).unwrap();
        let plain = plain.matched().unwrap().clone();
        let (dx, dy) = (0.4 * image.cell_size_m(), -0.3 * image.cell_size_m());
        let moved = shifted(image.grid(), dx, dy);
        let image = image.with_pose_fit_grid(moved);
        let fitted = match_scan(scan, &image, &Se2::identity(), &window, &matcher).unwrap();
        let fitted = fitted.matched().unwrap();
        // Moving the raster by (dx, dy) moves its score surface, and so the
        // peak, by as much in the image frame.
        let p = &plain.image_from_scan;
        let want = Se2::new(p.x() + dx, p.y() + dy, p.theta());
        let got = &fitted.image_from_scan;
        assert!(
            (got.x() - want.x()).abs() < 0.1 * image.cell_size_m()
                && (got.y() - want.y()).abs() < 0.1 * image.cell_size_m()
                && (got.theta() - want.theta()).abs() < 0.002,
            "{got:?} against {want:?} (without the raster {:?})",
            plain.image_from_scan
        );
        // The quality and the covariance are those of the searched image,
        // read at its peak.
        assert_eq!(fitted.searched_peak, plain.image_from_scan);
        assert_eq!(fitted.quality, plain.quality);
        assert_eq!(fitted.covariance, plain.covariance);
    }

    #[test]
    fn scan_and_image_of_the_same_rotation_match_at_identity() {
        // The paper's experiment (section 6) on a static and a moving sonar.
        let scene = SceneConfig::default();
        let moving = RotationPath {
            world_from_start: Se2::new(-2.0, 1.0, 0.3),
            velocity_mps: (0.45, 0.05),
            yaw_rate_radps: 0.02,
        };
        for rotation in [
            static_rotation(&scene, 4),
            simulate_rotation(&scene, &moving, 5),
        ] {
            let image = image_of(&rotation);
            let window = SearchWindow::new(1.0, 1.0, 10.0_f64.to_radians());
            let outcome = match_scan(
                &rotation.wall_points,
                &image,
                &Se2::new(0.3, -0.4, 0.05),
                &window,
                &MatcherConfig::default(),
            )
            .unwrap();
            let m = outcome.matched().expect("a match");
            let (dt, dtheta) = pose_error(&m.image_from_scan, &Se2::identity());
            assert!(dt < 0.05, "translation error {dt} m");
            assert!(dtheta < 0.5_f64.to_radians(), "angle error {dtheta} rad");
            assert!(m.quality.mean_intensity > 0.3, "{:?}", m.quality);
            assert!(m.quality.inside_fraction > 0.99);
        }
    }

    #[test]
    fn known_offsets_between_two_rotations_are_recovered() {
        let scene = SceneConfig::default();
        let a = static_rotation(&scene, 11);
        let image = image_of(&a);
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        for trial in 0..8 {
            let (b, truth) = offset_rotation(&scene, &a, &mut rng, 100 + trial);
            let prior = truth.compose(&Se2::new(
                rng.random_range(-1.5..1.5),
                rng.random_range(-1.5..1.5),
                rng.random_range(-0.15..0.15),
            ));
            let window = SearchWindow::new(2.0, 2.0, 0.2);
            let outcome = match_scan(
                &b.wall_points,
                &image,
                &prior,
                &window,
                &MatcherConfig::default(),
            )
            .unwrap();
            let m = outcome.matched().expect("a match");
            let (dt, dtheta) = pose_error(&m.image_from_scan, &truth);
            assert!(
                dt < 0.1 && dtheta < 1.0_f64.to_radians(),
                "trial {trial}: {dt} m, {dtheta} rad"
            );
            // The covariance is positive definite and says centimetres.
            let eig = m.covariance.symmetric_eigen().eigenvalues;
            assert!(eig.min() > 0.0, "{}", m.covariance);
            assert!(m.covariance[(0, 0)].sqrt() < 0.2 && m.covariance[(1, 1)].sqrt() < 0.2);
        }
    }

    /// From a prior within a few cells of the truth, the local climb
    /// reaches the same lattice pose as the global search, evaluating
    /// fewer leaves.
    #[test]
    fn the_local_climb_recovers_offsets_from_a_close_prior() {
        let scene = SceneConfig::default();
        let a = static_rotation(&scene, 11);
        let image = image_of(&a);
        let config = MatcherConfig::default();
        let mut rng = ChaCha8Rng::seed_from_u64(22);
        for trial in 0..8 {
            let (b, truth) = offset_rotation(&scene, &a, &mut rng, 200 + trial);
            let prior = truth.compose(&Se2::new(
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.03..0.03),
            ));
            let window = SearchWindow::new(0.5, 0.5, 3.0_f64.to_radians());
            let local = match_scan_local(&b.wall_points, &image, &prior, &window, &config).unwrap();
            let global = match_scan(&b.wall_points, &image, &prior, &window, &config).unwrap();
            let (l, g) = (local.matched().unwrap(), global.matched().unwrap());
            let (dt, dtheta) = pose_error(&l.image_from_scan, &truth);
            assert!(
                dt < 0.1 && dtheta < 1.0_f64.to_radians(),
                "trial {trial}: {dt} m, {dtheta} rad"
            );
            assert_eq!(l.coarse, g.coarse, "trial {trial}");
            assert!(
                l.stats.search_nodes < g.stats.search_nodes,
                "trial {trial}: {} vs {} nodes",
                l.stats.search_nodes,
                g.stats.search_nodes
            );
        }
    }

    /// Matches four random offsets of a static scene, by the global and the
    /// local search, each with the options `first` and `second` make from
    /// [`MatchOptions::edge`], and hands both results to `check` (with the
    /// trial, the scan's points and the image). `seed` picks the offsets,
    /// `first_rotation_seed` the first trial's simulation seed.
    fn compare_options(
        seed: u64,
        first_rotation_seed: u64,
        first: impl Fn(MatchOptions) -> MatchOptions,
        second: impl Fn(MatchOptions) -> MatchOptions,
        check: impl Fn(u64, &[Point2<f64>], &AcousticImage, MatchResult, MatchResult),
    ) {
        let scene = SceneConfig::default();
        let a = static_rotation(&scene, 12);
        let image = image_of(&a);
        let config = MatcherConfig::default();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for trial in 0..4 {
            let (b, truth) = offset_rotation(&scene, &a, &mut rng, first_rotation_seed + trial);
            let window = SearchWindow::new(0.5, 0.5, 3.0_f64.to_radians());
            for search in [Search::Global, Search::Local] {
                let run = |options| {
                    match_scan_with(&b.wall_points, &image, &truth, &window, &config, options)
                        .unwrap()
                        .matched()
                        .unwrap()
                        .clone()
                };
                let edge = MatchOptions::edge(search);
                let (x, y) = (run(first(edge)), run(second(edge)));
                check(trial, &b.wall_points, &image, x, y);
            }
        }
    }

    #[test]
    fn the_inner_covariance_lattice_changes_only_the_covariance() {
        let with = |covariance| {
            move |options| MatchOptions {
                covariance,
                ..options
            }
        };
        compare_options(
            29,
            400,
            with(CovarianceModel::Surface),
            with(CovarianceModel::Inner),
            |trial, _, _, surface, inner| {
                // The same pose to the bit, and the same quality.
                assert_eq!(surface.image_from_scan, inner.image_from_scan);
                assert_eq!(surface.searched_peak, inner.searched_peak);
                assert_eq!(surface.quality.mean_intensity, inner.quality.mean_intensity);
                // A covariance all the same: positive definite, and smaller
                // than the surface lattice's (measured 0.18-0.39 of its
                // variances: the inner nodes see the peak's sharper
                // curvature), which is why edges do not use it.
                let (cs, ci) = (surface.covariance, inner.covariance);
                assert!(ci.cholesky().is_some(), "trial {trial}: {ci}");
                for k in 0..3 {
                    let ratio = ci[(k, k)] / cs[(k, k)];
                    assert!(
                        (0.1..1.0).contains(&ratio),
                        "trial {trial} axis {k}: {ci} vs {cs}"
                    );
                }
            },
        );
    }

    #[test]
    fn raster_quality_changes_only_the_quality() {
        let with = |quality| move |options| MatchOptions { quality, ..options };
        compare_options(
            23,
            300,
            with(QualityModel::Samples),
            with(QualityModel::Raster),
            |trial, points, image, samples, raster| {
                assert_eq!(samples.image_from_scan, raster.image_from_scan);
                assert_eq!(samples.covariance, raster.covariance);
                let n = points.len() as f64;
                let expected = raster_score(points, image, &raster.searched_peak) / n;
                assert!((raster.quality.mean_intensity - expected).abs() < 1e-12);
                let fine = mean_score(points, image, &samples.searched_peak);
                assert!((samples.quality.mean_intensity - fine).abs() < 1e-12);
                // On a right match both models see the wall under the points.
                assert!(samples.quality.mean_intensity > 0.3, "trial {trial}");
                assert!(
                    raster.quality.mean_intensity > 0.5 * samples.quality.mean_intensity,
                    "trial {trial}: {} vs {}",
                    raster.quality.mean_intensity,
                    samples.quality.mean_intensity
                );
            },
        );
    }

    #[test]
    fn a_single_wall_leaves_the_along_wall_direction_uncertain() {
        let scene = SceneConfig {
            walls: vec![Wall::new(-30.0, 6.0, 30.0, 6.0, 1.0)],
            ..SceneConfig::default()
        };
        let rotation = static_rotation(&scene, 2);
        let image = image_of(&rotation);
        let window = SearchWindow::new(2.0, 2.0, 0.1);
        let outcome = match_scan(
            &rotation.wall_points,
            &image,
            &Se2::identity(),
            &window,
            &MatcherConfig::default(),
        )
        .unwrap();
        let m = outcome.matched().unwrap();
        // Across the wall (y) it is sharp, along it (x) it is not.
        assert!((m.image_from_scan.y()).abs() < 0.05);
        let (sx, sy) = (m.covariance[(0, 0)].sqrt(), m.covariance[(1, 1)].sqrt());
        assert!(sx > 5.0 * sy, "σx {sx}, σy {sy}");
    }

    #[test]
    fn unmatchable_input_gives_no_match_or_errors() {
        let rotation = static_rotation(&SceneConfig::default(), 3);
        let image = image_of(&rotation);
        let window = SearchWindow::new(1.0, 1.0, 0.1);
        let cfg = MatcherConfig::default();
        let few = &rotation.wall_points[..5];
        let out = match_scan(few, &image, &Se2::identity(), &window, &cfg).unwrap();
        assert_eq!(
            out,
            MatchOutcome::NoMatch {
                reason: NoMatchReason::TooFewPoints {
                    points: 5,
                    required: 10
                }
            }
        );
        // Prior 500 m away: nothing in the window overlaps.
        let far = Se2::new(500.0, 0.0, 0.0);
        let out = match_scan(&rotation.wall_points, &image, &far, &window, &cfg).unwrap();
        assert_eq!(
            out,
            MatchOutcome::NoMatch {
                reason: NoMatchReason::NoOverlap
            }
        );
        // An image without echoes.
        let empty = AcousticImage::from_grid(Grid::zeros(0.0, 0.0, 0.2, 10, 10), 3);
        let out = match_scan(
            &rotation.wall_points,
            &empty,
            &Se2::identity(),
            &window,
            &cfg,
        )
        .unwrap();
        assert_eq!(
            out,
            MatchOutcome::NoMatch {
                reason: NoMatchReason::EmptyImage
            }
        );
        // NaN in the scan, the prior or the window: errors naming it.
        let mut points = rotation.wall_points.clone();
        points[17].x = f64::NAN;
        let err = match_scan(&points, &image, &Se2::identity(), &window, &cfg).unwrap_err();
        assert!(err.to_string().contains("scan point 17"), "{err}");
        let err = match_scan(
            &rotation.wall_points,
            &image,
            &Se2::new(f64::NAN, 0.0, 0.0),
            &window,
            &cfg,
        )
        .unwrap_err();
        assert!(err.to_string().contains("prior"), "{err}");
        let bad_window = SearchWindow::new(1.0, f64::INFINITY, 0.1);
        assert!(
            match_scan(
                &rotation.wall_points,
                &image,
                &Se2::identity(),
                &bad_window,
                &cfg
            )
            .is_err()
        );
        let bad_cfg = MatcherConfig {
            covariance_scale: 0.0,
            ..MatcherConfig::default()
        };
        let err = match_scan(
            &rotation.wall_points,
            &image,
            &Se2::identity(),
            &window,
            &bad_cfg,
        )
        .unwrap_err();
        assert!(err.to_string().contains("covariance_scale"), "{err}");
    }

    #[test]
    fn score_is_eq_5() {
        let mut grid = Grid::zeros(0.0, 0.0, 1.0, 4, 4);
        grid.values_mut()[4 + 2] = 1.0; // cell (2, 1), centre (2.5, 1.5)
        let image = AcousticImage::from_grid(grid, 2);
        let points = [Point2::new(0.5, 0.0), Point2::new(0.0, 0.0)];
        // x ⊕ p: rotate by 90° then translate (2.5, 1.0): p0 -> (2.5, 1.5).
        let x = Se2::new(2.5, 1.0, std::f64::consts::FRAC_PI_2);
        assert!((score(&points, &image, &x) - 1.5).abs() < 1e-9);
        assert!((mean_score(&points, &image, &x) - 0.75).abs() < 1e-9);
    }
}
