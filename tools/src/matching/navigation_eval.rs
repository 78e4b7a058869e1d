//! How well dead reckoning serves motion compensation and the trajectory,
//! measured against ground truth (`echofield bench-dead-reckoning`).
//!
//! - **Distortion within a rotation** (simulated missions, whose ground
//!   truth is exact): every beam of every rotation is motion-compensated
//!   into the rotation's reference frame (eq. 3-4) once with dead reckoning
//!   and once with the ground truth; the statistic is the distance between
//!   the two positions of the point 5 m along the beam. Also the error of
//!   the dead-reckoning motion from the first to the last beam of each
//!   rotation (translation and heading).
//! - **Scan points on the walls** (built-in scenarios, whose environment is
//!   known): the fraction of the points of every scan `S_k` (default
//!   segmentation, dead-reckoning compensation) within 0.1, 0.3 and 1 m of
//!   the environment, the scan placed in the world with the true pose of
//!   its reference time; beside it the same with exact compensation.
//! - **Trajectory**: at every ground-truth stamp inside the navigation span,
//!   the ATE RMSE after the best SE(2) alignment, and the mean and largest
//!   error after moving the dead-reckoning origin onto the ground truth at
//!   the first compared stamp (no rotation fitted, the heading being
//!   absolute).

use super::ground_truth_at;
use anyhow::{Context, Result, bail};
use echofield_datasets::sim::Environment;
use echofield_frontend::dead_reckoning::Navigation;
use echofield_frontend::motion::reference_from_beams;
use echofield_frontend::rotation::Rotation;
use echofield_frontend::scan::build_scan;
use echofield_frontend::segmentation::SegmentationConfig;
use echofield_frontend::sensors::Mission;
use echofield_graph::Se2;
use echofield_graph::io::TrajectoryPose;
use nalgebra::Vector2;
use serde::Serialize;

/// Median, 90th percentile and largest value of a sample.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Spread {
    pub median: f64,
    pub p90: f64,
    pub max: f64,
}

impl Spread {
    pub fn of(values: &[f64]) -> Option<Self> {
        if values.is_empty() {
            return None;
        }
        let mut sorted = values.to_vec();
        sorted.sort_by(f64::total_cmp);
        let at = |q: f64| sorted[((sorted.len() - 1) as f64 * q).round() as usize];
        Some(Self {
            median: at(0.5),
            p90: at(0.9),
            max: sorted[sorted.len() - 1],
        })
    }
}

/// Distortion of the rotations by dead reckoning.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Distortion {
    pub rotations: usize,
    /// Distance between the dead-reckoning and the exact compensation of
    /// the point 5 m along each beam, m.
    pub point_5m_m: Spread,
    /// Error of the motion from the first to the last beam of each rotation.
    pub rotation_motion_m: Spread,
    pub rotation_motion_deg: Spread,
    /// The [`WORST_ROTATIONS`] rotations whose motion errs most
    /// (translation), worst first: where a motion model fails (a start, a
    /// stop, a turn that slows the vehicle) hides in the median.
    pub worst: Vec<RotationMotionError>,
}

/// How many rotations [`Distortion::worst`] lists.
pub const WORST_ROTATIONS: usize = 3;

/// The error of the dead-reckoning motion over one rotation (first to
/// last beam) against the ground truth's.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RotationMotionError {
    /// [`Rotation::index`].
    pub index: usize,
    /// Stamp of the rotation's first beam after the mission's first beam, s.
    pub start_s: f64,
    /// Translation error, m.
    pub translation_m: f64,
    /// Absolute heading error, degrees.
    pub heading_deg: f64,
}

/// The `n` largest translation errors of `errors`, largest first (ties:
/// the earlier rotation first).
pub fn worst_rotations(errors: &[RotationMotionError], n: usize) -> Vec<RotationMotionError> {
    let mut sorted = errors.to_vec();
    sorted.sort_by(|a, b| {
        b.translation_m
            .total_cmp(&a.translation_m)
            .then(a.index.cmp(&b.index))
    });
    sorted.truncate(n);
    sorted
}

/// Fractions of scan points within 0.1, 0.3 and 1 m of the environment.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct WallFractions {
    pub points: usize,
    pub within_0_1_m: f64,
    pub within_0_3_m: f64,
    pub within_1_m: f64,
}

/// Trajectory errors against ground truth.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrajectoryErrors {
    pub compared: usize,
    pub ate_rmse_se2_m: f64,
    pub origin_mean_m: f64,
    pub origin_max_m: f64,
}

/// A navigation that follows the mission's ground truth exactly.
pub fn ground_truth_navigation(mission: &Mission) -> Result<Navigation> {
    let gt = &mission.ground_truth;
    if gt.len() < 2 {
        bail!("{} has no ground truth", mission.name);
    }
    let stamps: Vec<f64> = gt.iter().map(|g| g.stamp_s).collect();
    let poses: Vec<Se2> = gt.iter().map(|g| g.world_from_vehicle).collect();
    Navigation::from_poses(&stamps, &poses, 1.0).context("navigation from the ground truth")
}

/// The distortion statistics of the module doc (exact ground truth needed).
pub fn distortion(
    mission: &Mission,
    rotations: &[Rotation],
    nav: &Navigation,
    truth: &Navigation,
) -> Result<Distortion> {
    let (mut points, mut motions) = (Vec::new(), Vec::new());
    let first_beam_s = mission.beams.first().map_or(0.0, |b| b.stamp_s);
    for rotation in rotations {
        let beams = &mission.beams[rotation.beams.clone()];
        let t_ref = rotation.reference_stamp_s;
        let (Ok(dr), Ok(exact)) = (
            reference_from_beams(beams, nav, &mission.mounting, t_ref),
            reference_from_beams(beams, truth, &mission.mounting, t_ref),
        ) else {
            continue; // outside the navigation or the ground truth
        };
        for (a, b) in dr.iter().zip(&exact) {
            let (pa, pb) = (a.transform_xy(5.0, 0.0), b.transform_xy(5.0, 0.0));
            points.push((pa.0 - pb.0).hypot(pa.1 - pb.1));
        }
        let (first, last) = (beams[0].stamp_s, beams[beams.len() - 1].stamp_s);
        let (estimate, _) = nav.relative(first, last)?;
        let (reference, _) = truth.relative(first, last)?;
        let e = reference.between(&estimate);
        motions.push(RotationMotionError {
            index: rotation.index,
            start_s: first - first_beam_s,
            translation_m: e.translation().norm(),
            heading_deg: e.theta().abs().to_degrees(),
        });
    }
    let spread = |v: &[f64]| Spread::of(v).context("no rotation inside the navigation span");
    let motion_m: Vec<f64> = motions.iter().map(|m| m.translation_m).collect();
    let motion_deg: Vec<f64> = motions.iter().map(|m| m.heading_deg).collect();
    Ok(Distortion {
        rotations: motions.len(),
        point_5m_m: spread(&points)?,
        rotation_motion_m: spread(&motion_m)?,
        rotation_motion_deg: spread(&motion_deg)?,
        worst: worst_rotations(&motions, WORST_ROTATIONS),
    })
}

/// Scan points near the environment's walls (see the module doc).
pub fn wall_fractions(
    mission: &Mission,
    rotations: &[Rotation],
    nav: &Navigation,
    environment: &Environment,
) -> Result<WallFractions> {
    let config = SegmentationConfig::default();
    let mut distances = Vec::new();
    for rotation in rotations {
        let beams = &mission.beams[rotation.beams.clone()];
        let t_ref = rotation.reference_stamp_s;
        let Some(world_from_reference) = ground_truth_at(&mission.ground_truth, t_ref) else {
            continue;
        };
        let Ok(frames) = reference_from_beams(beams, nav, &mission.mounting, t_ref) else {
            continue;
        };
        let Ok(scan) = build_scan(beams, &frames, t_ref, &config) else {
            continue; // too few ranges
        };
        distances.extend(
            scan.points
                .iter()
                .map(|p| environment.distance_to_nearest(world_from_reference.transform_point(p))),
        );
    }
    if distances.is_empty() {
        bail!("no scan point to compare with the environment");
    }
    let n = distances.len() as f64;
    let within = |limit: f64| distances.iter().filter(|&&d| d < limit).count() as f64 / n;
    Ok(WallFractions {
        points: distances.len(),
        within_0_1_m: within(0.1),
        within_0_3_m: within(0.3),
        within_1_m: within(1.0),
    })
}

/// Trajectory errors of `nav` at the ground-truth stamps in its span.
pub fn trajectory_errors(mission: &Mission, nav: &Navigation) -> Result<TrajectoryErrors> {
    let mut estimate = Vec::new();
    let mut reference = Vec::new();
    for g in &mission.ground_truth {
        if g.stamp_s < nav.start_s() || g.stamp_s > nav.end_s() {
            continue;
        }
        estimate.push(TrajectoryPose {
            stamp_s: g.stamp_s,
            pose: nav.pose_at(g.stamp_s)?,
        });
        reference.push(TrajectoryPose {
            stamp_s: g.stamp_s,
            pose: g.world_from_vehicle,
        });
    }
    if estimate.is_empty() {
        bail!("no ground truth inside the navigation span");
    }
    let ate = crate::eval::ate(&estimate, &reference, crate::eval::Alignment::Se2, 1e-6)?;
    let offset: Vector2<f64> = reference[0].pose.translation() - estimate[0].pose.translation();
    let errors: Vec<f64> = estimate
        .iter()
        .zip(&reference)
        .map(|(e, r)| (e.pose.translation() + offset - r.pose.translation()).norm())
        .collect();
    Ok(TrajectoryErrors {
        compared: errors.len(),
        ate_rmse_se2_m: ate.rmse_m,
        origin_mean_m: errors.iter().sum::<f64>() / errors.len() as f64,
        origin_max_m: errors.iter().copied().fold(0.0, f64::max),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_picks_order_statistics() {
        let values: Vec<f64> = (0..=10).rev().map(f64::from).collect();
        let s = Spread::of(&values).unwrap();
        assert_eq!((s.median, s.p90, s.max), (5.0, 9.0, 10.0));
        assert!(Spread::of(&[]).is_none());
    }

    #[test]
    fn worst_rotations_are_the_largest_translation_errors_first() {
        let error = |index: usize, translation_m: f64| RotationMotionError {
            index,
            start_s: 14.0 * index as f64,
            translation_m,
            heading_deg: 0.1,
        };
        let errors = [
            error(0, 1.5),
            error(1, 0.2),
            error(2, 3.2),
            error(3, 0.2),
            error(4, 1.5),
        ];
        let worst = worst_rotations(&errors, 3);
        let order: Vec<usize> = worst.iter().map(|w| w.index).collect();
        // 3.2 m first; the two 1.5 m rotations in rotation order.
        assert_eq!(order, [2, 0, 4]);
        assert_eq!(worst_rotations(&errors[..2], 3).len(), 2);
        assert!(worst_rotations(&[], 3).is_empty());
    }
}
