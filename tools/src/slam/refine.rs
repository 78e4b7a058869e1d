//! Motion compensation from an optimised trajectory (the matching
//! tool's `--navigation slam`; the pipeline's two-pass option that used it
//! made every benchmark worse and was removed, see the README's
//! accuracy section).
//!
//! The first pass builds every rotation's scan and image with the dead
//! reckoning's beam poses (eq. 3-4). Where the dead reckoning is poor
//! (a noisy DVL, sharp turns), those poses are wrong inside the rotation
//! and the scan comes out distorted. After the pass, the optimised node
//! poses are known much better. This module bends the dead reckoning
//! through them. At node `k` the correction is the rigid motion
//! `C_k = T*_k ∘ D_k⁻¹` (optimised pose after the inverse of the
//! dead-reckoning pose). Between two nodes it is interpolated on SE(2):
//! `C(t) = C_k ∘ exp(f · log(C_k⁻¹ ∘ C_{k+1}))`, with `f` the fraction of the
//! interval. Before the first node and after the last it is held. Each
//! dead-reckoning step `D(t)` becomes `C(t) ∘ D(t)`. The result keeps the
//! dead reckoning's shape between nodes and passes through every
//! optimised node pose.

use echofield_frontend::FrontendError;
use echofield_frontend::dead_reckoning::Navigation;
use echofield_graph::Se2;

/// The dead reckoning `navigation` bent through the optimised poses
/// `optimised[k]` of the nodes at `node_stamps_s[k]` (increasing), whose
/// dead-reckoning poses are `dead_reckoning[k]`. It has the steps (one per
/// stamp) and span of `navigation`, and zero covariance: it serves the
/// motion compensation, not the odometry.
pub fn refined_navigation(
    navigation: &Navigation,
    node_stamps_s: &[f64],
    dead_reckoning: &[Se2],
    optimised: &[Se2],
    max_extrapolation_s: f64,
) -> Result<Navigation, FrontendError> {
    let corrections: Vec<Se2> = optimised
        .iter()
        .zip(dead_reckoning)
        .map(|(opt, dr)| opt.compose(&dr.inverse()))
        .collect();
    let correction_at = |t: f64| -> Se2 {
        let next = node_stamps_s.partition_point(|&s| s <= t);
        match (next, corrections.len()) {
            (_, 0) => Se2::identity(),
            (0, _) => corrections[0],
            (k, n) if k >= n => corrections[n - 1],
            (k, _) => {
                let (a, b) = (node_stamps_s[k - 1], node_stamps_s[k]);
                let f = (t - a) / (b - a);
                let step = corrections[k - 1].between(&corrections[k]).log() * f;
                corrections[k - 1].compose(&Se2::exp(&step))
            }
        }
    };
    // The filter may take several steps at one stamp (a DVL and an
    // attitude record at the same time): the last one stands.
    let mut stamps: Vec<f64> = Vec::with_capacity(navigation.steps().len());
    let mut poses: Vec<Se2> = Vec::with_capacity(navigation.steps().len());
    for step in navigation.steps() {
        let pose = correction_at(step.stamp_s).compose(&step.world_from_vehicle);
        if stamps.last() == Some(&step.stamp_s) {
            *poses.last_mut().expect("a pose per stamp") = pose;
        } else {
            stamps.push(step.stamp_s);
            poses.push(pose);
        }
    }
    Navigation::from_poses(&stamps, &poses, max_extrapolation_s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A dead reckoning along a quarter circle, sampled at 10 Hz for 60 s.
    fn arc() -> Navigation {
        let stamps: Vec<f64> = (0..=600).map(|i| 100.0 + f64::from(i) * 0.1).collect();
        let poses: Vec<Se2> = stamps
            .iter()
            .map(|t| {
                let a = (t - 100.0) / 60.0 * std::f64::consts::FRAC_PI_2;
                Se2::new(20.0 * a.sin(), 20.0 * (1.0 - a.cos()), a)
            })
            .collect();
        Navigation::from_poses(&stamps, &poses, 2.0).unwrap()
    }

    fn close(a: &Se2, b: &Se2, tol: f64) -> bool {
        (a.translation() - b.translation()).norm() < tol
            && echofield_graph::wrap_angle(a.theta() - b.theta()).abs() < tol
    }

    #[test]
    fn the_refined_navigation_passes_through_the_optimised_poses() {
        let nav = arc();
        let stamps = [110.0, 124.0, 138.0, 152.0];
        let dr: Vec<Se2> = stamps.iter().map(|&t| nav.pose_at(t).unwrap()).collect();
        // Each node moved by a different rigid correction.
        let optimised: Vec<Se2> = dr
            .iter()
            .enumerate()
            .map(|(k, p)| {
                let k = k as f64;
                Se2::new(0.3 * k, -0.2 * k, 0.01 * k).compose(p)
            })
            .collect();
        let refined = refined_navigation(&nav, &stamps, &dr, &optimised, 2.0).unwrap();
        for (t, opt) in stamps.iter().zip(&optimised) {
            assert!(close(&refined.pose_at(*t).unwrap(), opt, 1e-9), "at {t}");
        }
        assert_eq!(refined.start_s(), nav.start_s());
        assert_eq!(refined.end_s(), nav.end_s());
        // Held beyond the first and the last node.
        let before = Se2::new(0.0, 0.0, 0.0).compose(&nav.pose_at(101.0).unwrap());
        assert!(close(&refined.pose_at(101.0).unwrap(), &before, 1e-9));
        let last = Se2::new(0.9, -0.6, 0.03).compose(&nav.pose_at(159.0).unwrap());
        assert!(close(&refined.pose_at(159.0).unwrap(), &last, 1e-9));
        // Between two nodes the correction lies between theirs: half-way,
        // the heading correction is half-way.
        let mid = refined.pose_at(117.0).unwrap();
        let dr_mid = nav.pose_at(117.0).unwrap();
        let dtheta = echofield_graph::wrap_angle(mid.theta() - dr_mid.theta());
        assert!((dtheta - 0.005).abs() < 1e-9, "{dtheta}");
    }

    #[test]
    fn a_common_correction_moves_the_whole_trajectory_rigidly() {
        let nav = arc();
        let stamps = [105.0, 119.0, 133.0, 147.0];
        let dr: Vec<Se2> = stamps.iter().map(|&t| nav.pose_at(t).unwrap()).collect();
        let shift = Se2::new(5.0, -3.0, 0.4);
        let optimised: Vec<Se2> = dr.iter().map(|p| shift.compose(p)).collect();
        let refined = refined_navigation(&nav, &stamps, &dr, &optimised, 2.0).unwrap();
        for t in [100.0, 111.3, 126.7, 140.0, 160.0] {
            let want = shift.compose(&nav.pose_at(t).unwrap());
            assert!(close(&refined.pose_at(t).unwrap(), &want, 1e-9), "at {t}");
            // Relative motions, which the motion compensation uses, are
            // those of the dead reckoning.
            let a = refined
                .pose_at(t)
                .unwrap()
                .between(&refined.pose_at(t + 0.5).unwrap());
            let b = nav
                .pose_at(t)
                .unwrap()
                .between(&nav.pose_at(t + 0.5).unwrap());
            assert!(close(&a, &b, 1e-9), "relative at {t}");
        }
        // Unchanged poses give the dead reckoning back.
        let same = refined_navigation(&nav, &stamps, &dr, &dr, 2.0).unwrap();
        for t in [100.0, 123.4, 160.0] {
            assert!(close(
                &same.pose_at(t).unwrap(),
                &nav.pose_at(t).unwrap(),
                1e-9
            ));
        }
    }
}
