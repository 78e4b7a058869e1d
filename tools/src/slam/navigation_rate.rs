//! The optimised trajectory at the navigation's rate, and its error.
//!
//! [`trajectory`] spreads the optimised node poses over the dense dead
//! reckoning ([`SlamOutput::dead_reckoning`](crate::slam::SlamOutput)) by
//! [`echofield_graph::corrected::corrected_trajectory`]: exact at the
//! nodes, continuous between them, with the dead reckoning's short-term
//! motion. [`evaluate`] measures it against every ground-truth sample
//! between the first and the last node (the trajectory interpolated at the
//! sample's stamp), SE(2)-aligned like the node ATE: `report.json` →
//! `ate_navigation_rate`.

use super::{NodeRecord, Report};
use crate::eval::{Alignment, ate};
use echofield_frontend::sensors::GroundTruthPose;
use echofield_graph::Se2;
use echofield_graph::corrected::{Anchor, blend, corrected_trajectory};
use echofield_graph::io::TrajectoryPose;

/// The optimised trajectory at the rate of `dead_reckoning`
/// (`(stamp_s, world_from_vehicle)` in time order), the node poses merged
/// in at their stamps.
pub fn trajectory(nodes: &[NodeRecord], dead_reckoning: &[(f64, Se2)]) -> Vec<(f64, Se2)> {
    let anchors: Vec<Anchor> = nodes
        .iter()
        .map(|n| Anchor {
            stamp_s: n.stamp_s,
            dead_reckoning: n.dead_reckoning,
            optimised: n.optimised,
        })
        .collect();
    corrected_trajectory(&anchors, dead_reckoning)
}

/// Sets `report.ate_navigation_rate`: the ATE of `trajectory` over the
/// ground-truth samples between the first and the last node stamp; left
/// `None` with fewer than two such samples.
pub fn evaluate(
    ground_truth: &[GroundTruthPose],
    nodes: &[NodeRecord],
    trajectory: &[(f64, Se2)],
    report: &mut Report,
) {
    let (Some(first), Some(last)) = (nodes.first(), nodes.last()) else {
        return;
    };
    let (mut estimate, mut reference) = (Vec::new(), Vec::new());
    for g in ground_truth
        .iter()
        .filter(|g| g.stamp_s >= first.stamp_s && g.stamp_s <= last.stamp_s)
    {
        if let Some(pose) = interpolate(trajectory, g.stamp_s) {
            estimate.push(TrajectoryPose {
                stamp_s: g.stamp_s,
                pose,
            });
            reference.push(TrajectoryPose {
                stamp_s: g.stamp_s,
                pose: g.world_from_vehicle,
            });
        }
    }
    if reference.len() >= 2 {
        // Estimate and reference share their stamps exactly.
        report.ate_navigation_rate = ate(&estimate, &reference, Alignment::Se2, 1e-6).ok();
    }
}

/// The pose of `trajectory` at `stamp_s`, linear between the samples
/// around it (heading along the shorter arc); `None` outside its span.
fn interpolate(trajectory: &[(f64, Se2)], stamp_s: f64) -> Option<Se2> {
    let after = trajectory.partition_point(|(t, _)| *t < stamp_s);
    let (t1, p1) = *trajectory.get(after)?;
    if t1 == stamp_s {
        return Some(p1);
    }
    let (t0, p0) = *trajectory.get(after.checked_sub(1)?)?;
    Some(blend(&p0, &p1, (stamp_s - t0) / (t1 - t0)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use echofield_graph::wrap_angle;

    #[test]
    fn interpolates_between_samples_and_not_beyond() {
        let traj = [
            (1.0, Se2::new(0.0, 0.0, 3.0)),
            (2.0, Se2::new(2.0, 4.0, -3.0)),
        ];
        let mid = interpolate(&traj, 1.25).unwrap();
        assert!((mid.x() - 0.5).abs() < 1e-12 && (mid.y() - 1.0).abs() < 1e-12);
        // 3.0 rad to -3.0 rad: the shorter arc goes through π.
        let expected = wrap_angle(3.0 + 0.25 * wrap_angle(-6.0));
        assert!((mid.theta() - expected).abs() < 1e-12);
        assert_eq!(interpolate(&traj, 2.0), Some(traj[1].1));
        assert_eq!(interpolate(&traj, 1.0), Some(traj[0].1));
        assert!(interpolate(&traj, 0.5).is_none());
        assert!(interpolate(&traj, 2.5).is_none());
    }
}
