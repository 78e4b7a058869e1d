//! The optimised trajectory at the navigation's rate.
//!
//! A pose graph holds one pose per sonar rotation; other sensors
//! (cameras, multibeam, side-scan) need the vehicle's pose at their own
//! times. [`corrected_trajectory`] spreads the optimised node poses over a
//! dense dead-reckoning trajectory:
//!
//! - each node `k` gives a correction `C_k = opt_k ∘ dr_k⁻¹` (world frame)
//!   that takes its dead-reckoning pose `dr_k` to its optimised pose;
//! - a dead-reckoning pose `dr(t)` with `t_k ≤ t ≤ t_{k+1}` becomes the
//!   blend, with weight `s = (t - t_k) / (t_{k+1} - t_k)`, of
//!   `C_k ∘ dr(t)` and `C_{k+1} ∘ dr(t)`: positions linearly, headings
//!   along the shorter arc. Both terms are close to each other (they
//!   differ by the change of correction between two nodes), so the blend
//!   is well defined;
//! - before the first node and after the last, the nearest node's
//!   correction applies unchanged.
//!
//! At `t_k` the result is `opt_k` exactly, and it is continuous in `t`: no
//! jumps at nodes. Between nodes it keeps the dead reckoning's
//! short-term motion. The node poses themselves are part of the output.

use crate::{Se2, wrap_angle};

/// A node of the optimised trajectory.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Anchor {
    /// Time of the node, seconds (the dead reckoning's time base).
    pub stamp_s: f64,
    /// `world_from_vehicle` of the dead reckoning at `stamp_s`.
    pub dead_reckoning: Se2,
    /// `world_from_vehicle` after optimisation.
    pub optimised: Se2,
}

/// The dead-reckoning samples `(stamp_s, world_from_vehicle)` corrected by
/// the `anchors`, with the anchors' own poses merged in at their stamps,
/// in time order (see the module doc). Preconditions: both inputs in
/// non-decreasing time order; an empty `anchors` gives an empty result
/// (there is nothing to correct with).
pub fn corrected_trajectory(anchors: &[Anchor], dead_reckoning: &[(f64, Se2)]) -> Vec<(f64, Se2)> {
    if anchors.is_empty() {
        return Vec::new();
    }
    let corrections: Vec<Se2> = anchors
        .iter()
        .map(|a| a.optimised.compose(&a.dead_reckoning.inverse()))
        .collect();
    let mut out = Vec::with_capacity(dead_reckoning.len() + anchors.len());
    let mut next_anchor = 0;
    for &(t, dr) in dead_reckoning {
        while next_anchor < anchors.len() && anchors[next_anchor].stamp_s <= t {
            let a = &anchors[next_anchor];
            out.push((a.stamp_s, a.optimised));
            next_anchor += 1;
        }
        // `next_anchor` is the first anchor after t.
        let pose = match next_anchor {
            0 => corrections[0].compose(&dr),
            k if k == anchors.len() => corrections[k - 1].compose(&dr),
            k => {
                let (a, b) = (&anchors[k - 1], &anchors[k]);
                let s = (t - a.stamp_s) / (b.stamp_s - a.stamp_s);
                blend(
                    &corrections[k - 1].compose(&dr),
                    &corrections[k].compose(&dr),
                    s,
                )
            }
        };
        if out.last().is_none_or(|&(last, _)| last < t) {
            out.push((t, pose));
        }
    }
    for a in &anchors[next_anchor..] {
        out.push((a.stamp_s, a.optimised));
    }
    out
}

/// `(1 - s) a + s b` in position, and along the shorter arc in heading
/// (`s` in [0, 1] interpolates; the poses should be close for the result to
/// mean anything).
pub fn blend(a: &Se2, b: &Se2, s: f64) -> Se2 {
    let d_theta = wrap_angle(b.theta() - a.theta());
    Se2::new(
        a.x() + s * (b.x() - a.x()),
        a.y() + s * (b.y() - a.y()),
        wrap_angle(a.theta() + s * d_theta),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &Se2, b: &Se2, tol: f64) -> bool {
        (a.x() - b.x()).abs() < tol
            && (a.y() - b.y()).abs() < tol
            && wrap_angle(a.theta() - b.theta()).abs() < tol
    }

    /// Dead reckoning of a vehicle turning at a constant rate, every 0.1 s.
    fn arc(duration_s: f64) -> Vec<(f64, Se2)> {
        (0..=(duration_s * 10.0) as usize)
            .map(|k| {
                let t = k as f64 * 0.1;
                (
                    t,
                    Se2::new(
                        10.0 * (0.05 * t).sin(),
                        10.0 * (1.0 - (0.05 * t).cos()),
                        0.05 * t,
                    ),
                )
            })
            .collect()
    }

    fn dr_at(dr: &[(f64, Se2)], t: f64) -> Se2 {
        dr.iter().find(|(s, _)| (s - t).abs() < 1e-9).unwrap().1
    }

    #[test]
    fn passes_through_the_nodes_without_jumps() {
        let dr = arc(40.0);
        // Corrections that grow along the mission (a drift removed).
        let anchors: Vec<Anchor> = [3.05f64, 15.02, 27.33, 38.01]
            .iter()
            .enumerate()
            .map(|(k, &t)| {
                let d = Se2::new(
                    (0.05 * t).sin() * 10.0,
                    10.0 * (1.0 - (0.05 * t).cos()),
                    0.05 * t,
                );
                let fix = Se2::new(0.3 * k as f64, -0.2 * k as f64, 0.02 * k as f64);
                Anchor {
                    stamp_s: t,
                    dead_reckoning: d,
                    optimised: fix.compose(&d),
                }
            })
            .collect();
        let out = corrected_trajectory(&anchors, &dr);
        assert_eq!(out.len(), dr.len() + anchors.len());
        assert!(out.windows(2).all(|w| w[0].0 < w[1].0));
        for a in &anchors {
            let (_, p) = out.iter().find(|(t, _)| *t == a.stamp_s).unwrap();
            assert_eq!(*p, a.optimised);
        }
        // Continuity: a sample 0.05 s from a node lies within the motion
        // of 0.05 s (0.025 m at 0.5 m/s, plus the blend's share of the
        // correction change) of the node.
        for w in out.windows(2) {
            let step = (w[1].1.translation() - w[0].1.translation()).norm();
            assert!(step < 0.15, "jump of {step} m at t = {}", w[1].0);
        }
        // Before the first node and after the last: that node's correction.
        let c0 = anchors[0]
            .optimised
            .compose(&anchors[0].dead_reckoning.inverse());
        assert!(close(&out[0].1, &c0.compose(&dr_at(&dr, 0.0)), 1e-12));
        let c3 = anchors[3]
            .optimised
            .compose(&anchors[3].dead_reckoning.inverse());
        assert!(close(
            &out.last().unwrap().1,
            &c3.compose(&dr_at(&dr, 40.0)),
            1e-12
        ));
    }

    #[test]
    fn one_correction_everywhere_is_applied_exactly() {
        let dr = arc(20.0);
        let fix = Se2::new(5.0, -3.0, 0.4);
        let anchors: Vec<Anchor> = [2.0, 9.0, 17.0]
            .iter()
            .map(|&t| {
                let d = dr_at(&dr, t);
                Anchor {
                    stamp_s: t,
                    dead_reckoning: d,
                    optimised: fix.compose(&d),
                }
            })
            .collect();
        let out = corrected_trajectory(&anchors, &dr);
        // Anchors fall on samples: the sample is kept once.
        assert_eq!(out.len(), dr.len());
        for ((t, p), (s, d)) in out.iter().zip(&dr) {
            assert_eq!(t, s);
            assert!(close(p, &fix.compose(d), 1e-12));
        }
    }

    #[test]
    fn headings_blend_along_the_shorter_arc() {
        let a = Se2::new(0.0, 0.0, 3.1);
        let b = Se2::new(1.0, 0.0, -3.1);
        let mid = blend(&a, &b, 0.5);
        assert!((mid.theta().abs() - std::f64::consts::PI).abs() < 1e-9);
        assert!((mid.x() - 0.5).abs() < 1e-12);
    }

    #[test]
    fn no_anchor_gives_nothing() {
        assert!(corrected_trajectory(&[], &arc(1.0)).is_empty());
    }
}
