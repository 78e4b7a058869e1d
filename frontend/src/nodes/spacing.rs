//! Which rotations become nodes: every one, or on a slow or hovering
//! vehicle only those that moved far enough from the last node
//! (`[rotation] node_spacing_m`, keyframe selection).
//!
//! A rotation's dead-reckoning pose at its central time is compared with
//! that of the last rotation kept. It becomes a node when
//!
//! ```text
//! |Δt| + (R / 2) · |Δθ| ≥ node_spacing_m
//! ```
//!
//! `Δt` (m) and `Δθ` (rad) the relative pose, `R` the farthest range the
//! beams reach (m): under a turn of `Δθ` a wall at half the image's reach
//! moves by `(R / 2)·|Δθ|`, so a turn on the spot counts like a translation
//! that moves the scene as much (the replay's slow stretches are turns,
//! whose rotations carry the heading: EXPERIMENTS.md § Long missions). A
//! vehicle that the dead reckoning sees standing still still gets a node at
//! least every [`MAX_THINNED_IN_A_ROW`]` + 1` rotations, so that the sonar
//! keeps correcting a dead reckoning that may be wrong about it.
//!
//! The rule is causal (the pose of each rotation and the past ones only),
//! the same online and in batch. A node spacing of 0 keeps every rotation
//! (the default is `RotationConfig::node_spacing_m`'s).
//! Thinned rotations are counted in the report, not listed: their beams are
//! dropped.

use echofield_graph::Se2;
use echofield_graph::se2::wrap_angle;

/// Rotations thinned in a row before the next one is a node whatever its
/// motion: it bounds, in rotations, how long the sonar leaves a dead
/// reckoning that sees the vehicle standing still uncorrected.
pub const MAX_THINNED_IN_A_ROW: usize = 4;

/// The keyframe rule of the module doc, fed one rotation at a time.
#[derive(Clone, Debug)]
pub struct NodeSpacing {
    spacing_m: f64,
    /// Dead-reckoning `world_from_vehicle` of the last rotation kept.
    last: Option<Se2>,
    in_a_row: usize,
    thinned: usize,
}

impl NodeSpacing {
    /// The rule for `spacing_m` (≥ 0, finite: `RotationConfig::validate`).
    pub fn new(spacing_m: f64) -> Self {
        Self {
            spacing_m,
            last: None,
            in_a_row: 0,
            thinned: 0,
        }
    }

    /// Whether the rotation whose dead-reckoning pose at its central time
    /// is `world_from_vehicle` becomes a node; `reach_m` is the farthest
    /// range of the beams so far. The first rotation always does.
    pub fn keep(&mut self, world_from_vehicle: &Se2, reach_m: f64) -> bool {
        let keep = match &self.last {
            None => true,
            Some(last) => {
                let moved = last.inverse().compose(world_from_vehicle);
                let scene_m = moved.translation().norm()
                    + 0.5 * reach_m.max(0.0) * wrap_angle(moved.theta()).abs();
                scene_m >= self.spacing_m || self.in_a_row >= MAX_THINNED_IN_A_ROW
            }
        };
        if keep {
            self.last = Some(*world_from_vehicle);
            self.in_a_row = 0;
        } else {
            self.in_a_row += 1;
            self.thinned += 1;
        }
        keep
    }

    /// Rotations not kept so far.
    pub fn thinned(&self) -> usize {
        self.thinned
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The beams' reach of these tests, metres.
    const REACH_M: f64 = 40.0;

    /// `keep` over poses `(x, y, θ)` with beams reaching [`REACH_M`].
    fn kept(spacing_m: f64, poses: &[(f64, f64, f64)]) -> Vec<bool> {
        let mut rule = NodeSpacing::new(spacing_m);
        poses
            .iter()
            .map(|&(x, y, t)| rule.keep(&Se2::new(x, y, t), REACH_M))
            .collect()
    }

    #[test]
    fn zero_spacing_keeps_every_rotation() {
        let still = [(0.0, 0.0, 0.0); 6];
        assert_eq!(kept(0.0, &still), [true; 6]);
    }

    #[test]
    fn a_rotation_is_a_node_once_it_moved_the_spacing_from_the_last_node() {
        // 0.7 m per rotation along x, 2 m spacing: kept at 0, 2.1, 4.2 m
        // (measured from the last node kept, not from the previous rotation).
        let poses: Vec<_> = (0..7).map(|k| (0.7 * k as f64, 0.0, 0.0)).collect();
        assert_eq!(
            kept(2.0, &poses),
            [true, false, false, true, false, false, true]
        );
    }

    #[test]
    fn a_turn_on_the_spot_counts_by_how_far_it_moves_a_wall_at_half_the_reach() {
        // Reach 40 m: a wall at 20 m moves 2 m under a turn of 0.1 rad.
        let poses = [(0.0, 0.0, 0.0), (0.0, 0.0, 0.09), (0.0, 0.0, 0.101)];
        assert_eq!(kept(2.0, &poses), [true, false, true]);
        // Across the ±π wrap the turn is the short one (0.02 rad).
        let across = [(0.0, 0.0, 3.13), (0.0, 0.0, -3.133)];
        assert_eq!(kept(2.0, &across), [true, false]);
    }

    #[test]
    fn a_vehicle_standing_still_still_gets_a_node_every_few_rotations() {
        let still = [(1.0, 2.0, 0.3); 11];
        let k = kept(2.0, &still);
        let nodes: Vec<usize> = (0..k.len()).filter(|&i| k[i]).collect();
        let step = MAX_THINNED_IN_A_ROW + 1;
        assert_eq!(nodes, [0, step, 2 * step]);
        let mut rule = NodeSpacing::new(2.0);
        for _ in 0..11 {
            rule.keep(&Se2::new(1.0, 2.0, 0.3), REACH_M);
        }
        assert_eq!(rule.thinned(), 11 - 3);
    }
}
