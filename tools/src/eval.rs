//! Trajectory evaluation: absolute trajectory error (ATE) and relative pose
//! error (RPE) between an estimate and a reference, with timestamps
//! associated as the `evo` package does.
//!
//! - Association: the shorter trajectory's stamps are each paired with the
//!   nearest stamp of the other, kept when they differ by less than
//!   `max_time_diff_s` (evo's `--t_max_diff`, default 0.01 s).
//! - Alignment ([`Alignment::Se2`]): the rigid motion of the plane that best
//!   maps estimated positions onto reference positions in the least-squares
//!   sense (closed-form 2D Umeyama/Horn without scale), as `evo_ape -a` does
//!   for planar trajectories.
//! - ATE: statistics of the position error `|p_ref - T p_est|` over
//!   associated pairs (the RMSE is evo's APE "translation part" RMSE).
//! - RPE per distance: for each pose `i` and each distance `d`, the later
//!   pose `j` whose distance along the reference path from `i` is nearest
//!   to `d` (the first such pose on a tie), kept when it is within
//!   `d / 10` of `d` ([`rpe_pairs`]); error of the relative motion
//!   `(⊖ ref_i ⊕ ref_j)⁻¹ (⊖ est_i ⊕ est_j)`, translation RMSE (m and % of
//!   d) and rotation RMSE (deg). These are the pairs of evo's
//!   `evo_rpe tum REF EST --delta d --delta_unit m --all_pairs
//!   --pairs_from_reference` (its default relative tolerance 0.1), and the
//!   errors its translation-part and `-r angle_deg` RMSEs;
//!   `tools/check_evo.sh` compares them.

use anyhow::{Result, bail};
use echofield_graph::io::TrajectoryPose;
use echofield_graph::{Se2, wrap_angle};
use nalgebra::Vector2;
use serde::Serialize;

/// How the estimate is aligned to the reference before computing ATE.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Alignment {
    /// Best rigid motion of the plane (rotation about z and translation).
    Se2,
    /// Compare as given.
    None,
}

/// Index pairs `(estimate, reference)` of associated poses.
pub fn associate(
    estimate: &[TrajectoryPose],
    reference: &[TrajectoryPose],
    max_time_diff_s: f64,
) -> Vec<(usize, usize)> {
    let nearest = |stamps: &[TrajectoryPose], t: f64| -> Option<usize> {
        let i = stamps.partition_point(|p| p.stamp_s < t);
        let candidates = [i.checked_sub(1), (i < stamps.len()).then_some(i)];
        candidates
            .into_iter()
            .flatten()
            .min_by(|&a, &b| {
                (stamps[a].stamp_s - t)
                    .abs()
                    .total_cmp(&(stamps[b].stamp_s - t).abs())
            })
            .filter(|&k| (stamps[k].stamp_s - t).abs() < max_time_diff_s)
    };
    if estimate.len() <= reference.len() {
        (0..estimate.len())
            .filter_map(|i| nearest(reference, estimate[i].stamp_s).map(|j| (i, j)))
            .collect()
    } else {
        (0..reference.len())
            .filter_map(|j| nearest(estimate, reference[j].stamp_s).map(|i| (i, j)))
            .collect()
    }
}

/// The rigid motion `reference_from_estimate` minimising
/// `Σ |q_k - T p_k|²` over point pairs (p from the estimate, q from the
/// reference). Needs at least two distinct points for a unique rotation;
/// with one point only the translation is fitted.
pub fn align_se2(estimate: &[Vector2<f64>], reference: &[Vector2<f64>]) -> Se2 {
    let n = estimate.len().min(reference.len());
    if n == 0 {
        return Se2::identity();
    }
    let mean = |v: &[Vector2<f64>]| v[..n].iter().sum::<Vector2<f64>>() / n as f64;
    let (cp, cq) = (mean(estimate), mean(reference));
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for (p, q) in estimate[..n].iter().zip(&reference[..n]) {
        let (a, b) = (p - cp, q - cq);
        sxx += a.x * b.x + a.y * b.y; // Σ a·b
        sxy += a.x * b.y - a.y * b.x; // Σ a×b
    }
    let theta = sxy.atan2(sxx);
    let rotation = Se2::new(0.0, 0.0, theta);
    let rotated = rotation.transform_point(&cp.into());
    Se2::new(cq.x - rotated.x, cq.y - rotated.y, theta)
}

/// RMSE of the positions of `estimate` against `reference`, pose `k` with
/// pose `k` (same length; extra poses of the longer are ignored), after the
/// SE(2) alignment ([`align_se2`]) that minimises it, metres. For graphs
/// over the same nodes, where [`ate`]'s association by time does not apply.
pub fn aligned_position_rmse(estimate: &[Se2], reference: &[Se2]) -> f64 {
    let p: Vec<Vector2<f64>> = estimate.iter().map(Se2::translation).collect();
    let q: Vec<Vector2<f64>> = reference.iter().map(Se2::translation).collect();
    let n = p.len().min(q.len());
    let t = align_se2(&p[..n], &q[..n]);
    let sum: f64 = p[..n]
        .iter()
        .zip(&q[..n])
        .map(|(p, q)| {
            let (x, y) = t.transform_xy(p.x, p.y);
            (q - Vector2::new(x, y)).norm_squared()
        })
        .sum();
    (sum / n.max(1) as f64).sqrt()
}

/// Absolute trajectory error statistics, metres.
#[derive(Clone, Debug, Serialize)]
pub struct AteStats {
    pub pairs: usize,
    pub rmse_m: f64,
    pub mean_m: f64,
    pub median_m: f64,
    pub max_m: f64,
    /// `reference_from_estimate` applied before measuring.
    pub alignment: Se2,
}

/// ATE of `estimate` against `reference`. Errors: no associated pair, a
/// `max_time_diff_s` that is not a positive number, or statistics that are
/// not finite.
pub fn ate(
    estimate: &[TrajectoryPose],
    reference: &[TrajectoryPose],
    alignment: Alignment,
    max_time_diff_s: f64,
) -> Result<AteStats> {
    if !(max_time_diff_s.is_finite() && max_time_diff_s > 0.0) {
        bail!(
            "the largest time difference must be a positive number of seconds, got {max_time_diff_s}"
        );
    }
    let pairs = associate(estimate, reference, max_time_diff_s);
    if pairs.is_empty() {
        bail!(
            "no pose of the estimate has a reference pose within {max_time_diff_s} s: check the stamps"
        );
    }
    let p: Vec<_> = pairs
        .iter()
        .map(|&(i, _)| estimate[i].pose.translation())
        .collect();
    let q: Vec<_> = pairs
        .iter()
        .map(|&(_, j)| reference[j].pose.translation())
        .collect();
    let transform = match alignment {
        Alignment::Se2 => align_se2(&p, &q),
        Alignment::None => Se2::identity(),
    };
    let errors: Vec<f64> = p
        .iter()
        .zip(&q)
        .map(|(p, q)| {
            let (x, y) = transform.transform_xy(p.x, p.y);
            (q - Vector2::new(x, y)).norm()
        })
        .collect();
    ate_stats(errors, &pairs, transform)
}

/// The statistics of the position `errors` (m, one per associated pair of
/// `pairs`, not empty) after `transform`. Errors when an error or the RMSE
/// is not finite, naming the pair.
fn ate_stats(mut errors: Vec<f64>, pairs: &[(usize, usize)], transform: Se2) -> Result<AteStats> {
    let n = errors.len() as f64;
    let rmse_m = (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
    // Never report NaN or infinity as a result: the readers bound every
    // value, so this only fires on trajectories built in memory.
    if let Some(k) = errors.iter().position(|e| !e.is_finite()) {
        let (i, j) = pairs[k];
        bail!(
            "the position error of estimate pose {i} against reference pose {j} is not finite              (positions too large?)"
        );
    }
    if !rmse_m.is_finite() {
        bail!("the ATE is not finite: the position errors are too large to square");
    }
    let mean_m = errors.iter().sum::<f64>() / n;
    errors.sort_by(f64::total_cmp);
    let median_m = if errors.len() % 2 == 1 {
        errors[errors.len() / 2]
    } else {
        0.5 * (errors[errors.len() / 2 - 1] + errors[errors.len() / 2])
    };
    Ok(AteStats {
        pairs: pairs.len(),
        rmse_m,
        mean_m,
        median_m,
        max_m: *errors.last().unwrap_or(&0.0),
        alignment: transform,
    })
}

/// Relative pose error over one travelled distance.
#[derive(Clone, Debug, Serialize)]
pub struct RpeStats {
    pub distance_m: f64,
    pub pairs: usize,
    pub translation_rmse_m: f64,
    /// Translation RMSE as a percentage of `distance_m`.
    pub translation_rmse_percent: f64,
    pub rotation_rmse_deg: f64,
}

/// RPE for each distance in `distances_m`; distances longer than the path,
/// and distances that are not positive and finite, are left out.
pub fn rpe(
    estimate: &[TrajectoryPose],
    reference: &[TrajectoryPose],
    distances_m: &[f64],
    max_time_diff_s: f64,
) -> Vec<RpeStats> {
    let pairs = associate(estimate, reference, max_time_diff_s);
    let est: Vec<Se2> = pairs.iter().map(|&(i, _)| estimate[i].pose).collect();
    let refs: Vec<Se2> = pairs.iter().map(|&(_, j)| reference[j].pose).collect();
    let travelled = cumulative_distance(&refs);
    let mut out = Vec::new();
    // A distance that is not positive has no relative motion to measure
    // (and would divide by zero in the percentage).
    for &d in distances_m.iter().filter(|d| d.is_finite() && **d > 0.0) {
        let (mut t2, mut r2, mut count) = (0.0, 0.0, 0usize);
        for (i, j) in rpe_pairs(&travelled, d) {
            let rel_ref = refs[i].between(&refs[j]);
            let rel_est = est[i].between(&est[j]);
            let e = rel_ref.between(&rel_est);
            t2 += e.translation().norm_squared();
            r2 += wrap_angle(e.theta()).powi(2);
            count += 1;
        }
        if count == 0 {
            continue;
        }
        let translation_rmse_m = (t2 / count as f64).sqrt();
        out.push(RpeStats {
            distance_m: d,
            pairs: count,
            translation_rmse_m,
            translation_rmse_percent: 100.0 * translation_rmse_m / d,
            rotation_rmse_deg: (r2 / count as f64).sqrt().to_degrees(),
        });
    }
    out
}

/// Relative tolerance of [`rpe_pairs`]: evo's default `--delta_tol`.
pub const RPE_RELATIVE_TOLERANCE: f64 = 0.1;

/// The RPE's pose pairs over distance `d` along a path whose cumulative
/// length at each pose is `travelled` (non-decreasing): for each `i`, the
/// `j > i` whose `travelled[j] - travelled[i]` is nearest to `d`, the
/// first such `j` on a tie, kept when it is within `d ·`
/// [`RPE_RELATIVE_TOLERANCE`] of `d`. This is evo's `all_pairs` rule
/// (`evo.core.filters.filter_pairs_by_path`), found here by binary search
/// instead of a scan of every later pose.
pub fn rpe_pairs(travelled: &[f64], d: f64) -> Vec<(usize, usize)> {
    let tolerance = d * RPE_RELATIVE_TOLERANCE;
    let mut pairs = Vec::new();
    for i in 0..travelled.len().saturating_sub(1) {
        // Lengths from pose i, and their errors, computed as evo does
        // (`(travelled[j] - travelled[i]) - d`), so that near-ties fall the
        // same way.
        let from_here = |s: f64| s - travelled[i];
        let error = |s: f64| (from_here(s) - d).abs();
        let later = &travelled[i + 1..];
        // First later pose at or beyond d, and the first pose of the run
        // of equal lengths just before it (a vehicle standing still
        // repeats its length).
        let above = later.partition_point(|&s| from_here(s) < d);
        let mut best: Option<usize> = None;
        if above > 0 {
            let below_value = later[above - 1];
            best = Some(later.partition_point(|&s| s < below_value));
        }
        if above < later.len() {
            // A tie goes to the earlier pose, which is the one below.
            if best.is_none_or(|k| error(later[above]) < error(later[k])) {
                best = Some(above);
            }
        }
        if let Some(k) = best
            && error(later[k]) <= tolerance
        {
            pairs.push((i, i + 1 + k));
        }
    }
    pairs
}

/// Path length from the first pose to each pose.
pub fn cumulative_distance(poses: &[Se2]) -> Vec<f64> {
    let mut total = 0.0;
    let mut out = Vec::with_capacity(poses.len());
    for (k, p) in poses.iter().enumerate() {
        if k > 0 {
            total += (p.translation() - poses[k - 1].translation()).norm();
        }
        out.push(total);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rigidly moved copy has no error; moving one of four points by
    /// 2 m away from the others' fit gives a known positive RMSE.
    #[test]
    fn aligned_position_rmse_ignores_a_rigid_motion() {
        let reference = [
            Se2::new(0.0, 0.0, 0.0),
            Se2::new(4.0, 0.0, 0.0),
            Se2::new(4.0, 3.0, 0.0),
            Se2::new(0.0, 3.0, 0.0),
        ];
        let motion = Se2::new(10.0, -5.0, 0.7);
        let moved: Vec<Se2> = reference.iter().map(|p| motion.compose(p)).collect();
        assert!(aligned_position_rmse(&moved, &reference) < 1e-12);
        let mut bent = reference;
        bent[0] = Se2::new(0.0, -2.0, 0.0);
        let rmse = aligned_position_rmse(&bent, &reference);
        assert!(rmse > 0.5 && rmse < 1.0, "{rmse}");
    }

    fn traj(poses: &[Se2], t0: f64) -> Vec<TrajectoryPose> {
        poses
            .iter()
            .enumerate()
            .map(|(k, &pose)| TrajectoryPose {
                stamp_s: t0 + k as f64,
                pose,
            })
            .collect()
    }

    fn square_path() -> Vec<Se2> {
        (0..40)
            .map(|k| {
                let s = k as f64;
                Se2::new(s.min(10.0), (s - 10.0).clamp(0.0, 10.0), 0.3 * s)
            })
            .collect()
    }

    #[test]
    fn alignment_recovers_a_rigid_motion() {
        let truth = square_path();
        let motion = Se2::new(3.0, -7.0, 2.5);
        let moved: Vec<_> = truth.iter().map(|p| motion.compose(p)).collect();
        let stats = ate(&traj(&moved, 0.0), &traj(&truth, 0.0), Alignment::Se2, 0.01).unwrap();
        assert!(stats.rmse_m < 1e-9, "{stats:?}");
        let inverse = motion.inverse().to_vector();
        assert!((stats.alignment.to_vector() - inverse).norm() < 1e-9);
        let raw = ate(
            &traj(&moved, 0.0),
            &traj(&truth, 0.0),
            Alignment::None,
            0.01,
        )
        .unwrap();
        assert!(raw.rmse_m > 1.0);
    }

    #[test]
    fn ate_of_a_known_offset() {
        // Every estimated position 0.3 m east of the truth, no alignment:
        // every error is 0.3 m exactly.
        let truth = square_path();
        let shifted: Vec<_> = truth
            .iter()
            .map(|p| Se2::new(p.x() + 0.3, p.y(), p.theta()))
            .collect();
        let stats = ate(
            &traj(&shifted, 0.0),
            &traj(&truth, 0.0),
            Alignment::None,
            0.01,
        )
        .unwrap();
        assert!((stats.rmse_m - 0.3).abs() < 1e-12);
        assert!((stats.max_m - 0.3).abs() < 1e-12);
    }

    #[test]
    fn association_respects_max_time_difference() {
        let truth = traj(&square_path(), 0.0);
        let late = traj(&square_path(), 0.005);
        assert_eq!(associate(&late, &truth, 0.01).len(), truth.len());
        let very_late = traj(&square_path(), 0.5);
        assert!(associate(&very_late, &truth, 0.01).is_empty());
        assert!(ate(&very_late, &truth, Alignment::None, 0.01).is_err());
    }

    /// evo's rule written out as it states it (every later pose examined),
    /// against the binary search.
    fn pairs_by_scan(travelled: &[f64], d: f64) -> Vec<(usize, usize)> {
        let mut pairs = Vec::new();
        for i in 0..travelled.len().saturating_sub(1) {
            let mut best = i + 1;
            for j in i + 1..travelled.len() {
                let e = ((travelled[j] - travelled[i]) - d).abs();
                if e < ((travelled[best] - travelled[i]) - d).abs() {
                    best = j;
                }
            }
            if (travelled[best] - travelled[i] - d).abs() <= 0.1 * d {
                pairs.push((i, best));
            }
        }
        pairs
    }

    #[test]
    fn rpe_pairs_follow_evos_all_pairs_rule() {
        // Steps of 0, 0.4 and 1.3 m, with stops (repeated lengths).
        let steps = [0.0, 0.4, 1.3, 0.0, 0.0, 1.3, 0.4, 0.4, 0.0, 1.3];
        let mut travelled = vec![0.0];
        for k in 0..60 {
            travelled.push(travelled[k] + steps[k % steps.len()]);
        }
        for d in [0.4, 1.0, 2.5, 5.0, 10.0, 40.0] {
            assert_eq!(
                rpe_pairs(&travelled, d),
                pairs_by_scan(&travelled, d),
                "d = {d}"
            );
        }
        // Every pose to the pose 2 m on, when the poses are 1 m apart.
        let even: Vec<f64> = (0..6).map(f64::from).collect();
        assert_eq!(rpe_pairs(&even, 2.0), [(0, 2), (1, 3), (2, 4), (3, 5)]);
        // Beyond the tolerance: 2.5 m on lies 0.5 m from any pose.
        assert!(rpe_pairs(&even, 2.5).is_empty());
    }

    #[test]
    fn rpe_sees_a_heading_drift() {
        // An estimate that turns 1° per metre more than the truth.
        let truth: Vec<_> = (0..50).map(|k| Se2::new(k as f64, 0.0, 0.0)).collect();
        let mut drifting = vec![Se2::identity()];
        for _ in 1..50 {
            let last = *drifting.last().unwrap();
            drifting.push(last.compose(&Se2::new(1.0, 0.0, 1f64.to_radians())));
        }
        let stats = rpe(&traj(&drifting, 0.0), &traj(&truth, 0.0), &[10.0], 0.01);
        assert_eq!(stats.len(), 1);
        // Poses 0-39 pair with the pose 10 m on (10° of drift); pose 40
        // pairs with the last one, 9 m on, within the tolerance d/10 (9°).
        assert_eq!(stats[0].pairs, 41);
        let expected = ((40.0 * 100.0 + 81.0) / 41.0f64).sqrt();
        assert!(
            (stats[0].rotation_rmse_deg - expected).abs() < 1e-9,
            "{stats:?}"
        );
        assert!(stats[0].translation_rmse_m > 0.5);
    }
}
