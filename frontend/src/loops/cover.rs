//! Loop sparsification: the pairs that a kept loop makes redundant.
//!
//! A loop `(j, k)` measures `j_from_k`. Node `j'` next to `j` and node `k'`
//! next to `k` are tied to them by the sequential chain (odometry and
//! sequential matches), whose uncertainty over a short stretch is small
//! against a loop's own. A loop `(j', k')` then measures nearly the same
//! relative pose as `(j, k)`, through the same images and scans seen from
//! almost the same places, so its errors are strongly correlated with
//! `(j, k)`'s (module doc of [`super`]: the loops at a node share its
//! errors) and it adds almost no information. How many such pairs a
//! revisit holds grows with the square of the rotations per metre of track:
//! a vehicle twice as slow has four times the pairs for the same place.
//!
//! **The rule.** Let `s(i)` be the distance travelled by dead reckoning up
//! to node `i`, metres. A pair `(j, k)` is *covered* when a kept loop
//! `(j', k')` has `|s(j) − s(j')| ≤ spacing` and `|s(k) − s(k')| ≤ spacing`
//! (`LoopConfig::cover_spacing_m`; 0 covers nothing). Covered pairs are
//! neither matched nor kept: the mission pass skips candidates covered by
//! the accepted loops, and takes a node's candidates only where they do not
//! cover each other; densification picks, in pair order, the pairs that no
//! accepted loop and no pair picked before covers, matches them, and picks
//! again among the pairs that only failed picks covered, for at most
//! `COVER_ROUNDS` rounds (the loop closer, tools `slam::loops`). The kept
//! loops then number at most
//! about `(L / spacing)²` times the fraction of pairs that overlap, for a
//! track of length `L`, whatever the number of rotations: the work and the
//! edges per metre of track are bounded, not per rotation. A vehicle that
//! hovers (`s` does not grow) keeps one loop per revisit of the spot.
//!
//! Precondition: `s` is non-decreasing in the node index (a distance
//! travelled), so the nodes within `spacing` of a node are one index range.

use std::collections::BTreeMap;

/// Kept loops indexed for the cover test.
#[derive(Clone, Debug, Default)]
pub struct LoopCover {
    spacing_m: f64,
    /// `from` nodes of the kept loops, by their `to` node.
    by_to: BTreeMap<usize, Vec<usize>>,
}

impl LoopCover {
    /// An empty cover with `spacing_m` (0 or less covers nothing).
    pub fn new(spacing_m: f64) -> Self {
        Self {
            spacing_m,
            by_to: BTreeMap::new(),
        }
    }

    /// Whether the rule is active (`spacing_m > 0`).
    pub fn enabled(&self) -> bool {
        self.spacing_m > 0.0
    }

    /// Forgets every kept loop.
    pub fn clear(&mut self) {
        self.by_to.clear();
    }

    /// Keeps the loop `(from, to)`.
    pub fn insert(&mut self, from: usize, to: usize) {
        if self.enabled() {
            self.by_to.entry(to).or_default().push(from);
        }
    }

    /// Forgets one kept loop `(from, to)` (nothing when none is kept).
    pub fn remove(&mut self, from: usize, to: usize) {
        let Some(froms) = self.by_to.get_mut(&to) else {
            return;
        };
        if let Some(i) = froms.iter().position(|&f| f == from) {
            froms.swap_remove(i);
        }
        if froms.is_empty() {
            self.by_to.remove(&to);
        }
    }

    /// Whether a kept loop covers `(j, k)`; `distance_m[i]` is `s(i)`
    /// (non-decreasing). Nodes past the end of `distance_m` cover and are
    /// covered by nothing.
    pub fn covers(&self, j: usize, k: usize, distance_m: &[f64]) -> bool {
        if !self.enabled() || j >= distance_m.len() || k >= distance_m.len() {
            return false;
        }
        let near = |i: usize, other: usize| {
            other < distance_m.len() && (distance_m[i] - distance_m[other]).abs() <= self.spacing_m
        };
        let (lo, hi) = within(k, self.spacing_m, distance_m);
        self.by_to
            .range(lo..=hi)
            .any(|(_, froms)| froms.iter().any(|&f| near(j, f)))
    }

    /// Whether nodes `a` and `b` lie within the spacing of each other.
    pub fn near(&self, a: usize, b: usize, distance_m: &[f64]) -> bool {
        self.enabled()
            && a < distance_m.len()
            && b < distance_m.len()
            && (distance_m[a] - distance_m[b]).abs() <= self.spacing_m
    }
}

/// The index range of the nodes within `spacing_m` of node `i`, by the
/// non-decreasing `distance_m`.
fn within(i: usize, spacing_m: f64, distance_m: &[f64]) -> (usize, usize) {
    let s = distance_m[i];
    let lo = distance_m.partition_point(|&d| d < s - spacing_m);
    let hi = distance_m.partition_point(|&d| d <= s + spacing_m);
    (lo, hi.saturating_sub(1).max(i))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Nodes 1 m apart along the track, except a hover at nodes 5-7.
    fn track() -> Vec<f64> {
        vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 5.0, 5.0, 6.0, 7.0, 8.0, 9.0]
    }

    #[test]
    fn a_kept_loop_covers_the_pairs_within_the_spacing_at_both_ends() {
        let s = track();
        let mut cover = LoopCover::new(1.5);
        cover.insert(1, 9);
        // Both ends within 1.5 m: covered.
        for (j, k) in [(1, 9), (0, 8), (2, 10), (0, 10), (2, 8)] {
            assert!(cover.covers(j, k, &s), "({j}, {k})");
        }
        // One end 2 m away: kept.
        for (j, k) in [(3, 9), (1, 11), (1, 6)] {
            assert!(!cover.covers(j, k, &s), "({j}, {k})");
        }
    }

    #[test]
    fn a_hover_is_one_place() {
        let s = track();
        let mut cover = LoopCover::new(0.5);
        cover.insert(0, 6);
        assert!(cover.covers(0, 5, &s));
        assert!(cover.covers(0, 7, &s));
        assert!(!cover.covers(0, 8, &s));
        assert!(!cover.covers(1, 6, &s));
        assert!(cover.near(5, 7, &s));
        assert!(!cover.near(4, 5, &s));
    }

    #[test]
    fn zero_spacing_covers_nothing_and_bad_indices_are_not_covered() {
        let s = track();
        let mut cover = LoopCover::new(0.0);
        cover.insert(1, 9);
        assert!(!cover.covers(1, 9, &s));
        let mut cover = LoopCover::new(2.0);
        cover.insert(1, 9);
        assert!(!cover.covers(1, 40, &s));
        assert!(!cover.covers(40, 9, &s));
        cover.clear();
        assert!(!cover.covers(1, 9, &s));
    }

    #[test]
    fn a_removed_loop_no_longer_covers_and_the_others_still_do() {
        let s = track();
        let mut cover = LoopCover::new(1.5);
        cover.insert(1, 9);
        cover.insert(3, 9);
        cover.remove(1, 9);
        // (0, 8) was covered by (1, 9) only; (3, 9) still covers (4, 10).
        assert!(!cover.covers(0, 8, &s));
        assert!(cover.covers(4, 10, &s));
        cover.remove(3, 9);
        cover.remove(3, 9);
        assert!(!cover.covers(4, 10, &s));
        assert!(!cover.covers(3, 9, &s));
    }
}
