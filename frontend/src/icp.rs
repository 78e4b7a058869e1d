//! Point-to-point ICP between two range scans: the baseline the
//! acoustic-image matcher is compared against (the paper's section 1 names
//! ICP-style matching as the usual range-based measurement model).
//!
//! Each iteration pairs every source point, moved by the current estimate,
//! with its nearest target point ([`kdtree`]) within a correspondence gate,
//! and solves the rigid alignment of the pairs in closed form: with centred
//! pairs `(a_i, b_i)`, `θ = atan2(Σ a_i × b_i, Σ a_i · b_i)` and
//! `t = μ_b - R(θ) μ_a`. The gate shrinks geometrically from
//! `initial_max_distance_m` to `final_max_distance_m` so that a far initial
//! guess can still pull in and the final fit ignores outliers. It stops when
//! an update moves less than the convergence thresholds at the final gate,
//! or after `max_iterations`.

pub mod kdtree;

use crate::config_check::check_positive;
use crate::error::FrontendError;
use echofield_graph::Se2;
use kdtree::KdTree;
use nalgebra::{Point2, Vector2};
use serde::{Deserialize, Serialize};

/// Configuration of the ICP baseline.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IcpConfig {
    pub max_iterations: usize,
    /// Correspondence gate of the first iteration, metres.
    pub initial_max_distance_m: f64,
    /// Smallest correspondence gate, metres.
    pub final_max_distance_m: f64,
    /// Factor applied to the gate after each iteration (0-1).
    pub gate_decay: f64,
    /// Convergence: translation (metres) and rotation (radians) of one update.
    pub convergence_m: f64,
    pub convergence_rad: f64,
    /// Fewer pairs than this is a failure.
    pub min_correspondences: usize,
}

impl Default for IcpConfig {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            initial_max_distance_m: 5.0,
            final_max_distance_m: 0.5,
            gate_decay: 0.85,
            convergence_m: 1e-4,
            convergence_rad: 1e-5,
            min_correspondences: 6,
        }
    }
}

impl IcpConfig {
    pub fn validate(&self) -> Result<(), FrontendError> {
        check_positive("initial_max_distance_m", self.initial_max_distance_m)?;
        check_positive("final_max_distance_m", self.final_max_distance_m)?;
        check_positive("convergence_m", self.convergence_m)?;
        check_positive("convergence_rad", self.convergence_rad)?;
        if !(self.gate_decay > 0.0 && self.gate_decay <= 1.0) {
            return Err(FrontendError::config(
                "gate_decay",
                format!("must lie in (0, 1], got {}", self.gate_decay),
            ));
        }
        if self.min_correspondences < 2 {
            return Err(FrontendError::config(
                "min_correspondences",
                "must be at least 2",
            ));
        }
        Ok(())
    }
}

/// The result of an ICP run.
#[derive(Clone, Debug, PartialEq)]
pub struct IcpResult {
    /// Pose of the source scan's frame in the target scan's frame.
    pub target_from_source: Se2,
    /// RMS distance of the final pairs, metres.
    pub rms_m: f64,
    /// Fraction of source points paired in the final iteration.
    pub inlier_fraction: f64,
    pub iterations: usize,
    pub converged: bool,
}

/// Aligns `source` to `target` starting from `initial` (`target_from_source`).
///
/// Errors: invalid config, non-finite input, or fewer than
/// `min_correspondences` pairs at some iteration (no overlap).
pub fn icp(
    source: &[Point2<f64>],
    target: &[Point2<f64>],
    initial: &Se2,
    config: &IcpConfig,
) -> Result<IcpResult, FrontendError> {
    config.validate()?;
    check_input(source, target, initial)?;
    let tree = KdTree::new(target);
    let mut estimate = *initial;
    let mut gate = config.initial_max_distance_m;
    let mut pairs: Vec<(Point2<f64>, Point2<f64>)> = Vec::with_capacity(source.len());
    let mut last_sq = 0.0;
    for iteration in 1..=config.max_iterations {
        last_sq = pair_nearest(source, target, &tree, &estimate, gate, &mut pairs);
        if pairs.len() < config.min_correspondences {
            return Err(FrontendError::insufficient(
                "ICP",
                format!(
                    "{} correspondences within {gate:.2} m at iteration {iteration}, at least {} needed",
                    pairs.len(),
                    config.min_correspondences
                ),
            ));
        }
        let aligned = align(&pairs);
        let update = estimate.between(&aligned);
        estimate = aligned;
        let at_final_gate = gate <= config.final_max_distance_m;
        if at_final_gate
            && update.translation().norm() < config.convergence_m
            && update.theta().abs() < config.convergence_rad
        {
            return Ok(result(
                estimate,
                &pairs,
                last_sq,
                source.len(),
                iteration,
                true,
            ));
        }
        gate = (gate * config.gate_decay).max(config.final_max_distance_m);
    }
    Ok(result(
        estimate,
        &pairs,
        last_sq,
        source.len(),
        config.max_iterations,
        false,
    ))
}

/// Every point finite and the initial pose finite; errors name the point.
fn check_input(
    source: &[Point2<f64>],
    target: &[Point2<f64>],
    initial: &Se2,
) -> Result<(), FrontendError> {
    for (name, points) in [("source", source), ("target", target)] {
        if let Some(i) = points
            .iter()
            .position(|p| !(p.x.is_finite() && p.y.is_finite()))
        {
            return Err(FrontendError::input(
                format!("ICP {name} point {i}"),
                "x/y",
                "not finite",
            ));
        }
    }
    if !initial.is_finite() {
        return Err(FrontendError::input("ICP", "initial", "pose is not finite"));
    }
    Ok(())
}

/// Replaces `pairs` with each source point (source frame) and its nearest
/// target point within `gate` metres of it placed by `estimate`; returns
/// the sum of the squared distances, m².
fn pair_nearest(
    source: &[Point2<f64>],
    target: &[Point2<f64>],
    tree: &KdTree,
    estimate: &Se2,
    gate: f64,
    pairs: &mut Vec<(Point2<f64>, Point2<f64>)>,
) -> f64 {
    pairs.clear();
    let mut sum_sq = 0.0;
    for p in source {
        let q = estimate.transform_point(p);
        if let Some((j, d2)) = tree.nearest(&q, gate) {
            pairs.push((*p, target[j]));
            sum_sq += d2;
        }
    }
    sum_sq
}

fn result(
    estimate: Se2,
    pairs: &[(Point2<f64>, Point2<f64>)],
    sum_sq: f64,
    n_source: usize,
    iterations: usize,
    converged: bool,
) -> IcpResult {
    IcpResult {
        target_from_source: estimate,
        rms_m: (sum_sq / pairs.len().max(1) as f64).sqrt(),
        inlier_fraction: pairs.len() as f64 / n_source.max(1) as f64,
        iterations,
        converged,
    }
}

/// The rigid transform `T` minimising `Σ |T a_i - b_i|²` (closed form).
fn align(pairs: &[(Point2<f64>, Point2<f64>)]) -> Se2 {
    let n = pairs.len() as f64;
    let (mut ma, mut mb) = (Vector2::zeros(), Vector2::zeros());
    for (a, b) in pairs {
        ma += a.coords;
        mb += b.coords;
    }
    ma /= n;
    mb /= n;
    let (mut dot, mut cross) = (0.0, 0.0);
    for (a, b) in pairs {
        let (da, db) = (a.coords - ma, b.coords - mb);
        dot += da.dot(&db);
        cross += da.x * db.y - da.y * db.x;
    }
    let theta = cross.atan2(dot);
    let (s, c) = theta.sin_cos();
    let rotated = Vector2::new(c * ma.x - s * ma.y, s * ma.x + c * ma.y);
    let t = mb - rotated;
    Se2::new(t.x, t.y, theta)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::synthetic::{RotationPath, SceneConfig, simulate_rotation, static_rotation};

    #[test]
    fn closed_form_alignment_is_exact_for_noise_free_pairs() {
        let truth = Se2::new(1.5, -0.7, 0.4);
        let pairs: Vec<_> = [(0.0, 1.0), (3.0, -2.0), (-1.0, 4.0), (2.5, 2.5)]
            .iter()
            .map(|&(x, y)| {
                let a = Point2::new(x, y);
                (a, truth.transform_point(&a))
            })
            .collect();
        let est = align(&pairs);
        assert!((est.to_vector() - truth.to_vector()).norm() < 1e-12);
    }

    #[test]
    fn icp_aligns_two_rotations_from_a_nearby_guess() {
        let scene = SceneConfig::default();
        let a = static_rotation(&scene, 1);
        let b = simulate_rotation(&scene, &RotationPath::fixed(Se2::new(0.8, -0.5, 0.1)), 2);
        let truth = a.world_from_reference.between(&b.world_from_reference);
        let initial = truth.compose(&Se2::new(0.4, 0.3, -0.05));
        let r = icp(
            &b.wall_points,
            &a.wall_points,
            &initial,
            &IcpConfig::default(),
        )
        .unwrap();
        let err = truth.between(&r.target_from_source);
        // Point-to-point ICP between two samplings of the same walls is
        // limited by the beam spacing (points do not correspond exactly).
        assert!(err.translation().norm() < 0.15, "{err:?}");
        assert!(err.theta().abs() < 1.0_f64.to_radians(), "{err:?}");
        assert!(r.converged && r.inlier_fraction > 0.8);
    }

    #[test]
    fn no_overlap_and_bad_input_are_errors() {
        let scene = SceneConfig::default();
        let a = static_rotation(&scene, 1);
        let far = Se2::new(1000.0, 0.0, 0.0);
        let err = icp(&a.wall_points, &a.wall_points, &far, &IcpConfig::default()).unwrap_err();
        assert!(err.to_string().contains("correspondences"), "{err}");
        let mut bad = a.wall_points.clone();
        bad[3].y = f64::NAN;
        let err = icp(
            &bad,
            &a.wall_points,
            &Se2::identity(),
            &IcpConfig::default(),
        )
        .unwrap_err();
        assert!(err.to_string().contains("source point 3"), "{err}");
        let cfg = IcpConfig {
            gate_decay: 1.5,
            ..IcpConfig::default()
        };
        assert!(icp(&a.wall_points, &a.wall_points, &Se2::identity(), &cfg).is_err());
    }
}
