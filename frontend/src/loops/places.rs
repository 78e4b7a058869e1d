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
}
