//! The design effect of loops that share a place.
//!
//! Loops that share a node share its errors: a scan built with a wrong
//! motion within its rotation, or seen along a wall, misplaces every loop
//! it takes part in the same way (the intra-class correlation of the loop
//! errors at a node: EXPERIMENTS.md § Loop densification). Densification
//! adds loops mostly where loops already are, so treating them as
//! independent would count the same error many times: a densified loop's
//! covariance is multiplied by the design effect of equicorrelated
//! measurements, `1 + ρ·(m_j + m_k − 2)` (`config::DENSIFY_CORRELATION` =
//! ρ, `m_x` the accepted loops at node `x`, or within `cover_spacing_m` of
//! travel of it, [`super::cover`]).
//!
//! Loops that join the same two places ([`PlacePairs`]) share more: both
//! images and both scans are seen from nearly the same places, so the
//! matches repeat one measurement of one relative pose with its bias
//! (along a quay, the match's shortening: EXPERIMENTS.md § Long missions).
//! How many such loops a revisit holds grows with the square of the
//! rotations per metre of track, so without the place-pair design effect
//! a slow mission would weigh the same biased measurement many times more
//! than a fast one; with it, every place pair weighs about as much as one
//! loop, whatever the speed.

use super::consistency::LoopMeasurement;
use std::collections::HashMap;

/// The loops at each place, for the design effect `1 + ρ·(m_j + m_k − 2)`
/// of a loop `(j, k)`: `m_x` counts the accepted loop ends at node `x`
/// or, with the cover rule on (`spacing_m > 0`), within `spacing_m` of
/// travel of it ([`super::cover`]): loops seen from nearly the same place share
/// its errors as loops at one node do.
pub struct Places<'a> {
    spacing_m: f64,
    distance_m: &'a [f64],
    /// The loop ends: node ids, and their travelled distances, ascending.
    nodes: HashMap<usize, usize>,
    ends_m: Vec<f64>,
}

impl<'a> Places<'a> {
    /// The ends of `loops`, counted at their places: `distance_m[i]` is the
    /// distance travelled up to node `i`, metres (non-decreasing);
    /// `spacing_m` the cover spacing (0 or less: only a node's own loops
    /// count).
    pub fn new<'m>(
        spacing_m: f64,
        distance_m: &'a [f64],
        loops: impl Iterator<Item = &'m LoopMeasurement>,
    ) -> Self {
        let mut nodes: HashMap<usize, usize> = HashMap::new();
        let mut ends_m = Vec::new();
        for m in loops {
            for x in [m.from, m.to] {
                *nodes.entry(x).or_default() += 1;
                if let Some(&d) = distance_m.get(x) {
                    ends_m.push(d);
                }
            }
        }
        ends_m.sort_unstable_by(f64::total_cmp);
        // A loop end past the known distances (none in a run) makes the
        // count fall back to ends at the node itself.
        let spacing_m = if ends_m.len() == nodes.values().sum::<usize>() {
            spacing_m
        } else {
            0.0
        };
        Self {
            spacing_m,
            distance_m,
            nodes,
            ends_m,
        }
    }

    /// `m_x`: the loop ends at node `x` or near it.
    pub fn loops_at(&self, x: usize) -> usize {
        match self.distance_m.get(x) {
            Some(&d) if self.spacing_m > 0.0 => {
                let lo = self.ends_m.partition_point(|&e| e < d - self.spacing_m);
                let hi = self.ends_m.partition_point(|&e| e <= d + self.spacing_m);
                hi - lo
            }
            _ => self.nodes.get(&x).copied().unwrap_or(0),
        }
    }

    /// `1 + ρ·(m_j + m_k − 2)` of the accepted loop `m` (counted in
    /// `m_j` and `m_k` itself).
    pub fn design_effect(&self, m: &LoopMeasurement, rho: f64) -> f64 {
        let others = (self.loops_at(m.from) + self.loops_at(m.to)).saturating_sub(2);
        1.0 + rho * others as f64
    }
}

/// Travel, metres, within which two loop ends count as one place for the
/// place-pair design effect ([`PlacePairs`]): nodes within 2 m of travel
/// of each other see the same walls, at the ranges of tens of metres the
/// matches rely on, from nearly the same place; the spacing that
/// `echofield bench-long` gives the cover rule ([`super::cover`]).
pub const PLACE_PAIR_SPACING_M: f64 = 2.0;

/// `ρ` of the place-pair design effect: 1, the loops joining two places
/// repeat one measurement, so together they count about as much as one loop.
pub const PLACE_PAIR_CORRELATION: f64 = 1.0;

/// The loops joining each pair of places, for the place-pair design effect
/// `1 + ρ·(n − 1)` of a loop `(j, k)`: `n` counts the loops `(j', k')`
/// (itself included) with `|s(j) − s(j')| ≤ spacing` and `|s(k) − s(k')| ≤
/// spacing` (ends taken in the order of `s`), `s` the distance travelled.
pub struct PlacePairs<'a> {
    spacing_m: f64,
    distance_m: &'a [f64],
    /// `(s(earlier end), s(later end))` of every loop with both ends in
    /// `distance_m`, ascending by the first.
    pairs: Vec<(f64, f64)>,
}

impl<'a> PlacePairs<'a> {
    /// The place pairs of `loops`: `distance_m[i]` is the distance travelled
    /// up to node `i`, metres (non-decreasing); `spacing_m` the travel within
    /// which ends count as one place (0 or less: only the same nodes).
    pub fn new<'m>(
        spacing_m: f64,
        distance_m: &'a [f64],
        loops: impl Iterator<Item = &'m LoopMeasurement>,
    ) -> Self {
        let mut pairs: Vec<(f64, f64)> = loops.filter_map(|m| Self::ends(distance_m, m)).collect();
        pairs.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        Self {
            spacing_m: spacing_m.max(0.0),
            distance_m,
            pairs,
        }
    }

    /// The distances travelled at `m`'s ends, the smaller first; `None` when
    /// an end is past `distance_m`.
    fn ends(distance_m: &[f64], m: &LoopMeasurement) -> Option<(f64, f64)> {
        let (a, b) = (*distance_m.get(m.from)?, *distance_m.get(m.to)?);
        Some((a.min(b), a.max(b)))
    }

    /// `n`: the loops joining `m`'s two places, `m` itself included (at
    /// least 1, also for a loop not given to [`Self::new`] or with an end
    /// past the known distances).
    pub fn loops_between(&self, m: &LoopMeasurement) -> usize {
        let Some((a, b)) = Self::ends(self.distance_m, m) else {
            return 1;
        };
        let s = self.spacing_m;
        let lo = self.pairs.partition_point(|p| p.0 < a - s);
        let hi = self.pairs.partition_point(|p| p.0 <= a + s);
        let n = self.pairs[lo..hi]
            .iter()
            .filter(|p| (p.1 - b).abs() <= s)
            .count();
        n.max(1)
    }

    /// `1 + ρ·(n − 1)` of the loop `m` ([`Self::loops_between`]).
    pub fn design_effect(&self, m: &LoopMeasurement, rho: f64) -> f64 {
        1.0 + rho * (self.loops_between(m) - 1) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use echofield_graph::Se2;
    use nalgebra::Matrix3;

    fn measurement(id: usize, from: usize, to: usize) -> LoopMeasurement {
        LoopMeasurement {
            id,
            from,
            to,
            z: Se2::identity(),
            covariance: Matrix3::identity(),
        }
    }

    #[test]
    fn loops_near_a_node_count_in_its_design_effect() {
        let distance_m: Vec<f64> = (0..40).map(f64::from).collect();
        let loops = [
            measurement(0, 2, 30),
            measurement(1, 3, 31),
            measurement(2, 10, 20),
        ];
        // Spacing 1.5 m: nodes 2 and 3 are one place, so are 30 and 31.
        let places = Places::new(1.5, &distance_m, loops.iter());
        assert_eq!(places.loops_at(2), 2);
        assert_eq!(places.loops_at(31), 2);
        assert_eq!(places.loops_at(10), 1);
        assert_eq!(places.design_effect(&loops[0], 1.0), 3.0);
        assert_eq!(places.design_effect(&loops[2], 1.0), 1.0);
        // Without the rule only the node's own loops count.
        let places = Places::new(0.0, &distance_m, loops.iter());
        assert_eq!(places.design_effect(&loops[0], 1.0), 1.0);
    }

    #[test]
    fn densified_loops_are_inflated_by_the_loops_sharing_their_nodes() {
        let primary = [measurement(0, 0, 20), measurement(1, 1, 20)];
        let primary: Vec<&LoopMeasurement> = primary.iter().collect();
        let dense = [
            // Node 0 holds one other loop, node 21 none.
            measurement(2, 0, 21),
            // Nodes 1 and 20 hold one and two other loops.
            measurement(3, 1, 20),
            // Alone at both ends.
            measurement(4, 5, 30),
        ];
        let effects = |rho: f64| {
            let places = Places::new(0.0, &[], primary.iter().copied().chain(&dense));
            dense
                .iter()
                .map(|m| places.design_effect(m, rho))
                .collect::<Vec<f64>>()
        };
        assert_eq!(effects(0.5), vec![1.5, 1.0 + 0.5 * 3.0, 1.0]);
        assert_eq!(effects(0.0), vec![1.0; 3]);
    }

    #[test]
    fn loops_joining_the_same_two_places_count_in_their_place_pair_effect() {
        let distance_m: Vec<f64> = (0..60).map(f64::from).collect();
        let loops = [
            measurement(0, 2, 30),
            // 1 m of travel from loop 0 at both ends, given the other way round.
            measurement(1, 31, 3),
            // Same first place, second place 10 m away: another pair.
            measurement(2, 2, 40),
            // Alone.
            measurement(3, 10, 50),
        ];
        let pairs = PlacePairs::new(1.5, &distance_m, loops.iter());
        assert_eq!(pairs.loops_between(&loops[0]), 2);
        assert_eq!(pairs.loops_between(&loops[1]), 2);
        assert_eq!(pairs.loops_between(&loops[2]), 1);
        assert_eq!(pairs.design_effect(&loops[0], 1.0), 2.0);
        assert_eq!(pairs.design_effect(&loops[3], 1.0), 1.0);
        // Spacing 0: only loops between the same two nodes share a pair.
        let pairs = PlacePairs::new(0.0, &distance_m, loops.iter());
        assert_eq!(pairs.loops_between(&loops[0]), 1);
        // An end past the known distances: no inflation.
        let pairs = PlacePairs::new(1.5, &distance_m[..20], loops.iter());
        assert_eq!(pairs.loops_between(&loops[0]), 1);
        assert_eq!(pairs.design_effect(&loops[0], 1.0), 1.0);
    }
}
