//! The order in which a batch of loop matches reads the node images.
//!
//! A match of the pair `(j, k)` reads the images `I_j` and, for its
//! symmetric check, `I_k` ([`super::checks::examine`]). On a long mission
//! most images are released between reads and built again when read
//! ([`crate::image::ImageResidency`]); how often depends only on the order
//! of the reads, never on the results, since each match reads nothing that
//! another one writes. Pair order (`k`, then `j`) reads the images of a
//! place once per later pass over it: a node of the first pass is read
//! when the second pass comes by and again when the third does, with the
//! rest of the mission in between.
//!
//! **Place order.** Node `x`'s *place* is the first node `i <= x` whose
//! position lies within `radius_m` of `x`'s (the node itself when none
//! does); pairs are matched by the place of their older node, then in pair
//! order. The pairs of one place, from every pass over it, then follow each
//! other, and the places follow the track of the first pass: the images a
//! stretch of track needs are read while it is worked on, then not again.
//! The radius sets how far apart two passes may run and still count as
//! one place; it changes the order of the reads, never a result.
//!
//! **Resident places first.** The places are taken by the share of
//! their images that are held now (most first; ties in track order): the
//! images the work before left in memory (the last places of the
//! previous round, the newest nodes after the mission pass) are read
//! before the reads of other places push them out, instead of being
//! released and built again when their place's turn comes.

use echofield_graph::Se2;
use std::collections::{BTreeMap, BTreeSet};

/// The order in which to match `pairs` (older node, newer node): indices
/// into `pairs`, grouped by the place of the older node (module doc), each
/// group in the pairs' own order, the groups by the share of their
/// pairs' nodes for which `resident` is true (largest first), then in
/// track order. `positions[i]` is node `i`'s pose (any frame common to
/// all nodes; only the translation is used), `radius_m` metres. A pair
/// naming a node past `positions` is its own place, after the others.
/// Runs in `O(n²)` for `n` nodes.
pub fn place_order(
    pairs: &[(usize, usize)],
    positions: &[Se2],
    radius_m: f64,
    resident: impl Fn(usize) -> bool,
) -> Vec<usize> {
    let places = places(positions, radius_m);
    let place_of = |i: usize| places.get(i).copied().unwrap_or(usize::MAX);
    // Per place: its distinct nodes, and how many of them are resident.
    let mut nodes: BTreeMap<usize, BTreeSet<usize>> = BTreeMap::new();
    for &(old, new) in pairs {
        nodes.entry(place_of(old)).or_default().extend([old, new]);
    }
    let share: BTreeMap<usize, (usize, usize)> = nodes
        .into_iter()
        .map(|(place, nodes)| {
            let held = nodes.iter().filter(|&&i| resident(i)).count();
            (place, (held, nodes.len()))
        })
        .collect();
    let mut ranked: Vec<(usize, (usize, usize))> = share.into_iter().collect();
    // Largest share first (held / count compared without division),
    // then track order; stable, so ties keep the place order.
    ranked.sort_by(|(_, (h1, n1)), (_, (h2, n2))| (h2 * n1).cmp(&(h1 * n2)));
    let rank: BTreeMap<usize, usize> = ranked
        .iter()
        .enumerate()
        .map(|(r, &(place, _))| (place, r))
        .collect();
    let mut order: Vec<usize> = (0..pairs.len()).collect();
    // Stable: within a place, the pairs keep their order.
    order.sort_by_key(|&q| rank[&place_of(pairs[q].0)]);
    order
}

/// The place of every node: the first node within `radius_m` of it.
fn places(positions: &[Se2], radius_m: f64) -> Vec<usize> {
    let r2 = radius_m * radius_m;
    (0..positions.len())
        .map(|x| {
            let p = positions[x].translation();
            (0..x)
                .find(|&i| (positions[i].translation() - p).norm_squared() <= r2)
                .unwrap_or(x)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three passes along the x axis, `n` nodes each, 1 m apart, the second
    /// run backwards, each pass 0.25 m beside the previous one.
    fn three_passes(n: usize) -> Vec<Se2> {
        let mut poses = Vec::new();
        for pass in 0..3 {
            for i in 0..n {
                let x = if pass == 1 { n - 1 - i } else { i } as f64;
                poses.push(Se2::new(x, 0.25 * pass as f64, 0.0));
            }
        }
        poses
    }

    #[test]
    fn the_pairs_of_one_place_from_every_pass_follow_each_other() {
        let positions = three_passes(10);
        // Node 13 (second pass, x = 6) and node 26 (third pass, x = 6)
        // lie at node 6's place; nodes 1 m apart are places of their own.
        let places = places(&positions, 0.6);
        assert_eq!((places[5], places[6], places[13], places[26]), (5, 6, 6, 6));
        // Pairs in pair order (newer node, then older).
        let pairs = [(2, 17), (6, 13), (6, 26), (13, 26), (2, 22), (17, 22)];
        let order = place_order(&pairs, &positions, 0.6, |_| false);
        let ordered: Vec<(usize, usize)> = order.iter().map(|&q| pairs[q]).collect();
        assert_eq!(
            ordered,
            [(2, 17), (2, 22), (17, 22), (6, 13), (6, 26), (13, 26)]
        );
        // A radius of zero: every node is its own place, pairs by older node.
        let order = place_order(&pairs, &positions, 0.0, |_| false);
        let ordered: Vec<(usize, usize)> = order.iter().map(|&q| pairs[q]).collect();
        assert_eq!(
            ordered,
            [(2, 17), (2, 22), (6, 13), (6, 26), (13, 26), (17, 22)]
        );
    }

    #[test]
    fn the_places_whose_images_are_held_come_first() {
        let positions = three_passes(10);
        let pairs = [(2, 17), (6, 13), (6, 26), (13, 26), (2, 22), (17, 22)];
        let ordered = |resident: &[usize]| -> Vec<(usize, usize)> {
            place_order(&pairs, &positions, 0.6, |i| resident.contains(&i))
                .iter()
                .map(|&q| pairs[q])
                .collect()
        };
        // Two of the three images of node 6's place are held, none of
        // node 2's: node 6's place first, each place's pairs in order.
        assert_eq!(
            ordered(&[13, 26]),
            [(6, 13), (6, 26), (13, 26), (2, 17), (2, 22), (17, 22)]
        );
        // A larger share wins over a larger count; equal shares keep the
        // track order.
        assert_eq!(ordered(&[2, 17, 22, 6]), ordered(&[]));
        assert_eq!(ordered(&[2, 6]), ordered(&[]));
        assert_eq!(ordered(&[6]), ordered(&[13, 26]));
    }

    #[test]
    fn the_order_is_a_permutation_and_nodes_past_the_positions_come_last() {
        let positions = three_passes(4);
        let pairs = [(20, 30), (1, 9), (5, 10), (3, 8), (1, 10)];
        let order = place_order(&pairs, &positions, 0.6, |_| false);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, [0, 1, 2, 3, 4]);
        // Node 5 (second pass, x = 2) lies at node 2's place, before 3.
        assert_eq!(order, [1, 4, 2, 3, 0]);
        assert_eq!(
            place_order(&pairs, &positions, 0.0, |_| false),
            [1, 4, 3, 2, 0]
        );
    }
}
