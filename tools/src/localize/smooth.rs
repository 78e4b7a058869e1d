//! The offline smoothed trajectory of a localised mission: the causal
//! filter's per-rotation fixes and the dead reckoning between rotations
//! combined in one small pose graph over the whole mission, solved by the
//! backend (sparse Levenberg-Marquardt). The filter's own output (causal,
//! what the vehicle knew at the time) is left as it is; this is what a user
//! post-processing a recorded mission gets in addition
//! (`trajectory_smoothed_tum.txt`).
//!
//! The graph, one node per rotation (map frame):
//!
//! - **Odometry** `k-1 -> k`: the forward dead reckoning's relative motion
//!   between the two rotations' central times and its covariance
//!   ([`echofield_frontend::dead_reckoning`]'s `relative`), plus the
//!   filter's own motion-noise floors (`motion_noise_floor_m`,
//!   `motion_noise_floor_rad`, which also keep it definite).
//! - **A fix** (a prior) on every rotation whose state is `localised` and
//!   whose scan fits the map (`fit >= min_fit`): the filter's estimate, with
//!   the covariance of what that rotation's scan told the filter
//!   (`LocalizationStep::scan_information`, the weighed cloud's
//!   information minus the predicted one's: the particles' spread is a
//!   posterior that holds the motion the odometry edges hold again), plus
//!   [`FLAT_SIGMA_M`] and [`FLAT_SIGMA_RAD`] as the least information in
//!   any direction, plus the floors [`FIX_FLOOR_M`]² and [`FIX_FLOOR_RAD`]².
//!   Where the step has none (after a seeding), an isotropic position
//!   covariance of the particles' spread (`spread_m² / 2` per axis) and
//!   their heading spread squared, plus the same floors.
//!   Coasting, searching and lost rotations get none: the dead reckoning
//!   carries them between fixes. Each fix has a Cauchy kernel, so that a
//!   fix far from what the odometry and the other fixes say loses its
//!   weight instead of bending the path.
//!
//! The chain is cut after every rotation at which the filter re-seeded (it
//! judged itself lost: the dead reckoning missed a motion, e.g. a
//! kidnapping), and where a rotation has no motion (the first). Each piece
//! is solved on its own; a piece without any fix keeps the filter's
//! estimates. The solve starts from the fixes, with the rotations between
//! them placed by the dead reckoning from the previous fix (before a
//! piece's first fix: back from it).
//!
//! Failure: a solve that fails (non-finite input, a degenerate system)
//! makes [`smooth_trajectory`] an error naming the rotation; the caller
//! reports it and keeps the filtered trajectory.

use super::replay::LocalizedRotation;
use anyhow::{Context, Result};
use echofield_backend::{Initialisation, RobustConfig, RobustKernel, SolverConfig, optimize};
use echofield_frontend::localization::{LocalizationConfig, LocalizationState, LocalizationStep};
use echofield_frontend::uncertainty::information;
use echofield_graph::{Edge, EdgeKind, Node, PoseGraph, Se2};
use nalgebra::{Matrix3, Vector3};

/// Smallest standard deviation of a fix's position per axis, m: the
/// particles' spread can collapse to their resampling noise while the
/// map's own error (its nodes' placement) remains.
pub const FIX_FLOOR_M: f64 = 0.1;

/// Smallest standard deviation of a fix's heading, rad.
pub const FIX_FLOOR_RAD: f64 = 0.01;

/// Standard deviation of a fix's position along a direction its scan does
/// not see (a quay's length), m: large against the odometry's, so the
/// motion carries that direction, and finite, so the fix's covariance
/// exists.
pub const FLAT_SIGMA_M: f64 = 10.0;

/// The same for the heading, rad.
pub const FLAT_SIGMA_RAD: f64 = 1.0;

/// Cauchy kernel parameter on the fixes, standard deviations.
const FIX_KERNEL: RobustKernel = RobustKernel::CAUCHY_DEFAULT;

/// One rotation as the smoother sees it.
#[derive(Clone, Debug, PartialEq)]
pub struct SmoothingRotation {
    /// The filter's estimate (map frame): the fix when `fix` is set, and the
    /// result for a piece without fixes.
    pub estimate: Se2,
    /// Covariance of the estimate as a fix in `(x, y, θ)`, when it is one.
    pub fix: Option<Matrix3<f64>>,
    /// Dead reckoning's `previous_from_current` since the previous rotation
    /// and its covariance (`None`: the chain is cut before this rotation).
    pub motion: Option<(Se2, Matrix3<f64>)>,
}

/// The smoothed pose of every rotation (see the module doc), in the order
/// given. Errors name the piece of rotations (indices in the input) whose
/// solve failed.
pub fn smooth_trajectory(rotations: &[SmoothingRotation]) -> Result<Vec<Se2>> {
    let mut out = Vec::with_capacity(rotations.len());
    let mut start = 0;
    while start < rotations.len() {
        let end = (start + 1..rotations.len())
            .find(|&k| rotations[k].motion.is_none())
            .unwrap_or(rotations.len());
        let piece = smooth_piece(&rotations[start..end], start)
            .with_context(|| format!("smoothing rotations {start}-{}", end - 1))?;
        out.extend(piece);
        start = end;
    }
    Ok(out)
}

/// The smoother's rotations from the filter's (see the module doc): the
/// fixes and their covariances, the motions with the filter's motion model
/// (`motion_noise_scale` times the dead reckoning's covariance plus the
/// floors squared), cut after every re-seeding.
pub fn smoothing_rotations(
    rotations: &[LocalizedRotation],
    config: &LocalizationConfig,
) -> Vec<SmoothingRotation> {
    let floor = Matrix3::from_diagonal(&Vector3::new(
        config.motion_noise_floor_m.powi(2),
        config.motion_noise_floor_m.powi(2),
        config.motion_noise_floor_rad.powi(2),
    ));
    rotations
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let step = &r.step;
            let is_fix = step.state == LocalizationState::Localised && step.fit >= config.min_fit;
            // Re-seeded after the previous rotation (judged lost; at the
            // first rotation the seeding comes before it): the dead
            // reckoning missed a motion, so the chain is cut.
            let cut = k >= 2 && rotations[k - 1].step.reseeded;
            SmoothingRotation {
                estimate: step.estimate,
                fix: is_fix.then(|| fix_covariance(step)),
                motion: r
                    .motion
                    .filter(|_| !cut)
                    .map(|(m, cov)| (m, cov * config.motion_noise_scale + floor)),
            }
        })
        .collect()
}

/// A fix's covariance from the filter's step (see the module doc).
fn fix_covariance(step: &LocalizationStep) -> Matrix3<f64> {
    let floor = Matrix3::from_diagonal(&Vector3::new(
        FIX_FLOOR_M.powi(2),
        FIX_FLOOR_M.powi(2),
        FIX_FLOOR_RAD.powi(2),
    ));
    let least = Matrix3::from_diagonal(&Vector3::new(
        FLAT_SIGMA_M.powi(-2),
        FLAT_SIGMA_M.powi(-2),
        FLAT_SIGMA_RAD.powi(-2),
    ));
    let from_scan = step
        .scan_information
        .and_then(|information| (information + least).try_inverse());
    let spread = || {
        let position_var = 0.5 * step.spread_m.powi(2);
        Matrix3::from_diagonal(&Vector3::new(
            position_var,
            position_var,
            step.heading_spread_rad.powi(2),
        ))
    };
    from_scan.unwrap_or_else(spread) + floor
}

/// One uncut piece, its first rotation the `first`-th of the mission's
/// (for the node ids and messages); its first rotation's motion is
/// ignored.
fn smooth_piece(piece: &[SmoothingRotation], first: usize) -> Result<Vec<Se2>> {
    let Some(initial) = initial_poses(piece) else {
        return Ok(piece.iter().map(|r| r.estimate).collect());
    };
    let mut graph = PoseGraph::new();
    let id = |k: usize| (first + k) as u64;
    for (k, pose) in initial.iter().enumerate() {
        graph.add_node(Node {
            id: id(k),
            pose: *pose,
            stamp_s: None,
        })?;
    }
    for (k, r) in piece.iter().enumerate() {
        if let Some(cov) = r.fix {
            let information = information(&cov).with_context(|| {
                format!(
                    "rotation {}: the fix's covariance is not positive definite",
                    id(k)
                )
            })?;
            graph.add_edge(Edge::new(
                EdgeKind::Prior,
                id(k),
                id(k),
                r.estimate,
                information,
            ))?;
        }
        if let (Some((motion, cov)), true) = (&r.motion, k > 0) {
            let information = information(cov).with_context(|| {
                format!(
                    "rotation {}: the motion's covariance is not positive definite",
                    id(k)
                )
            })?;
            graph.add_edge(Edge::new(
                EdgeKind::Odometry,
                id(k - 1),
                id(k),
                *motion,
                information,
            ))?;
        }
    }
    let config = SolverConfig {
        initialisation: Initialisation::Current,
        robust: RobustConfig {
            prior: FIX_KERNEL,
            ..RobustConfig::default()
        },
        ..SolverConfig::default()
    };
    optimize(&mut graph, &config)?;
    Ok(graph.poses())
}

/// Where the solve starts: the fixes, the rotations between them placed by
/// the dead reckoning from the previous fix, those before the first fix
/// back from it; `None` without any fix.
fn initial_poses(piece: &[SmoothingRotation]) -> Option<Vec<Se2>> {
    let first = piece.iter().position(|r| r.fix.is_some())?;
    let mut poses = vec![piece[first].estimate; piece.len()];
    let motion = |k: usize| piece[k].motion.as_ref().map_or(Se2::identity(), |m| m.0);
    for k in (0..first).rev() {
        poses[k] = poses[k + 1].compose(&motion(k + 1).inverse());
    }
    for k in first + 1..piece.len() {
        poses[k] = if piece[k].fix.is_some() {
            piece[k].estimate
        } else {
            poses[k - 1].compose(&motion(k))
        };
    }
    Some(poses)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    fn step(scan_information: Option<Matrix3<f64>>) -> LocalizationStep {
        LocalizationStep {
            state: LocalizationState::Localised,
            estimate: Se2::identity(),
            mean: Se2::identity(),
            spread_m: 0.2,
            heading_spread_rad: 0.02,
            particles: 1000,
            fit: 0.9,
            coverage: 1.0,
            scan_points: 500,
            reseeded: false,
            scan_information,
        }
    }

    #[test]
    fn a_fix_is_what_the_scan_saw_and_the_spread_only_without_it() {
        // The scan saw x (σ 0.05 m) and the heading (σ 0.01 rad), not y:
        // variances 0.05² + 0.1², 1 / (0 + 10⁻²) + 0.1², ... plus the
        // least information of a flat direction, which leaves x and θ
        // nearly as they are.
        let information = Matrix3::from_diagonal(&Vector3::new(400.0, 0.0, 1e4));
        let c = fix_covariance(&step(Some(information)));
        let expected = [
            1.0 / (400.0 + 0.01) + 0.01,
            100.0 + 0.01,
            1.0 / (1e4 + 1.0) + 1e-4,
        ];
        for (i, e) in expected.iter().enumerate() {
            assert!((c[(i, i)] - e).abs() < 1e-9 * e.max(1.0), "{c}");
        }
        assert!(c[(0, 1)].abs() < 1e-12 && c[(0, 2)].abs() < 1e-12);
        // Without it (after a seeding): the particles' spread, isotropic.
        let c = fix_covariance(&step(None));
        let position = 0.5 * 0.2f64.powi(2) + 0.01;
        let heading = 0.02f64.powi(2) + 1e-4;
        assert!((c[(0, 0)] - position).abs() < 1e-12 && (c[(1, 1)] - position).abs() < 1e-12);
        assert!((c[(2, 2)] - heading).abs() < 1e-12, "{c}");
    }

    /// A lawnmower-like path of `n` rotations, 5 m apart, turning by
    /// 0.05 rad per rotation.
    fn truth(n: usize) -> Vec<Se2> {
        let step = Se2::new(5.0, 0.0, 0.05);
        let mut poses = vec![Se2::new(3.0, -2.0, 0.4)];
        for _ in 1..n {
            let last = *poses.last().unwrap();
            poses.push(last.compose(&step));
        }
        poses
    }

    fn rms_position_error(a: &[Se2], b: &[Se2]) -> f64 {
        let sum: f64 = a
            .iter()
            .zip(b)
            .map(|(p, q)| (p.translation() - q.translation()).norm_squared())
            .sum();
        (sum / a.len() as f64).sqrt()
    }

    /// The chain with exact odometry (covariance `odometry_sigma`² per
    /// axis) and fixes scattered by `fix_sigma` (seeded), every fix's
    /// covariance the scatter's.
    fn chain(
        truth: &[Se2],
        fix_sigma: f64,
        odometry_sigma: f64,
        seed: u64,
    ) -> Vec<SmoothingRotation> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut normal = || rng.sample::<f64, _>(StandardNormal);
        let fix_cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(
            fix_sigma.powi(2),
            fix_sigma.powi(2),
            0.01f64.powi(2),
        ));
        let odometry_cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(
            odometry_sigma.powi(2),
            odometry_sigma.powi(2),
            0.001f64.powi(2),
        ));
        truth
            .iter()
            .enumerate()
            .map(|(k, t)| SmoothingRotation {
                estimate: Se2::new(
                    t.x() + fix_sigma * normal(),
                    t.y() + fix_sigma * normal(),
                    t.theta() + 0.01 * normal(),
                ),
                fix: Some(fix_cov),
                motion: (k > 0).then(|| (truth[k - 1].between(t), odometry_cov)),
            })
            .collect()
    }

    #[test]
    fn noisy_fixes_with_exact_odometry_are_smoothed_towards_the_truth() {
        let truth = truth(60);
        for seed in 0..5 {
            let rotations = chain(&truth, 0.3, 0.01, seed);
            let fixes: Vec<Se2> = rotations.iter().map(|r| r.estimate).collect();
            let smoothed = smooth_trajectory(&rotations).unwrap();
            let before = rms_position_error(&fixes, &truth);
            let after = rms_position_error(&smoothed, &truth);
            // 60 independent fixes of 0.3 m per axis on one rigid chain: the
            // chain's pose is known to about 0.3 / sqrt(60) per axis, its
            // heading to a similar share; well under a third of the fixes'
            // scatter.
            assert!(
                after < before / 3.0,
                "seed {seed}: {before:.3} m -> {after:.3} m"
            );
        }
    }

    #[test]
    fn a_wrong_fix_is_outweighed_and_rotations_without_a_fix_follow_the_odometry() {
        let truth = truth(40);
        let mut rotations = chain(&truth, 0.1, 0.02, 11);
        // A fix 5 m off, and ten rotations (coasting) without any.
        rotations[20].estimate = Se2::new(truth[20].x() + 5.0, truth[20].y(), truth[20].theta());
        for r in &mut rotations[25..35] {
            r.fix = None;
            r.estimate = Se2::identity();
        }
        let smoothed = smooth_trajectory(&rotations).unwrap();
        for (k, (s, t)) in smoothed.iter().zip(&truth).enumerate() {
            let error = (s.translation() - t.translation()).norm();
            assert!(error < 0.25, "rotation {k}: {error:.3} m");
        }
    }

    #[test]
    fn a_piece_without_fixes_keeps_the_estimates_and_a_cut_separates_pieces() {
        let truth = truth(20);
        let mut rotations = chain(&truth, 0.2, 0.01, 3);
        for r in &mut rotations[..8] {
            r.fix = None;
        }
        // Cut before rotation 8: the first piece has no fix.
        rotations[8].motion = None;
        let smoothed = smooth_trajectory(&rotations).unwrap();
        assert_eq!(smoothed.len(), 20);
        for k in 0..8 {
            assert_eq!(smoothed[k], rotations[k].estimate);
        }
        let after = rms_position_error(&smoothed[8..], &truth[8..]);
        let before = rms_position_error(
            &rotations[8..]
                .iter()
                .map(|r| r.estimate)
                .collect::<Vec<_>>(),
            &truth[8..],
        );
        assert!(after < before, "{before:.3} -> {after:.3}");
    }
}
