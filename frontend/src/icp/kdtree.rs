//! A static 2D k-d tree for nearest-neighbour queries.
//!
//! The tree is implicit: points are reordered so that, for the range
//! `[lo, hi)` split on axis `depth % 2`, the median `mid = (lo + hi) / 2`
//! holds the splitting point, `[lo, mid)` lies on its low side and
//! `(mid, hi)` on its high side.

use nalgebra::Point2;

pub struct KdTree {
    /// Points in tree order, with their index in the input.
    nodes: Vec<(Point2<f64>, usize)>,
}

impl KdTree {
    pub fn new(points: &[Point2<f64>]) -> Self {
        let mut nodes: Vec<(Point2<f64>, usize)> = points
            .iter()
            .copied()
            .enumerate()
            .map(|(i, p)| (p, i))
            .collect();
        build(&mut nodes, 0);
        Self { nodes }
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The nearest point within `max_distance` of `query`: its index in the
    /// input and its squared distance.
    pub fn nearest(&self, query: &Point2<f64>, max_distance: f64) -> Option<(usize, f64)> {
        let mut best = (usize::MAX, max_distance * max_distance);
        self.search(query, 0, self.nodes.len(), 0, &mut best);
        (best.0 != usize::MAX).then_some(best)
    }

    /// Indices (in the input) of every point within `radius` of `query`,
    /// in no particular order.
    pub fn within(&self, query: &Point2<f64>, radius: f64) -> Vec<usize> {
        let mut found = Vec::new();
        self.collect(query, radius * radius, 0, self.nodes.len(), 0, &mut found);
        found
    }

    fn collect(
        &self,
        q: &Point2<f64>,
        r2: f64,
        lo: usize,
        hi: usize,
        depth: usize,
        found: &mut Vec<usize>,
    ) {
        if lo >= hi {
            return;
        }
        let mid = (lo + hi) / 2;
        let (p, index) = self.nodes[mid];
        if (p - q).norm_squared() <= r2 {
            found.push(index);
        }
        let axis = depth % 2;
        let diff = q[axis] - p[axis];
        // The low side holds coordinates <= the split, the high side >=.
        if diff <= 0.0 || diff * diff <= r2 {
            self.collect(q, r2, lo, mid, depth + 1, found);
        }
        if diff >= 0.0 || diff * diff <= r2 {
            self.collect(q, r2, mid + 1, hi, depth + 1, found);
        }
    }

    fn search(&self, q: &Point2<f64>, lo: usize, hi: usize, depth: usize, best: &mut (usize, f64)) {
        if lo >= hi {
            return;
        }
        let mid = (lo + hi) / 2;
        let (p, index) = self.nodes[mid];
        let d2 = (p - q).norm_squared();
        if d2 < best.1 {
            *best = (index, d2);
        }
        let axis = depth % 2;
        let diff = q[axis] - p[axis];
        let (near, far) = if diff < 0.0 {
            ((lo, mid), (mid + 1, hi))
        } else {
            ((mid + 1, hi), (lo, mid))
        };
        self.search(q, near.0, near.1, depth + 1, best);
        if diff * diff < best.1 {
            self.search(q, far.0, far.1, depth + 1, best);
        }
    }
}

fn build(nodes: &mut [(Point2<f64>, usize)], depth: usize) {
    if nodes.len() <= 1 {
        return;
    }
    let axis = depth % 2;
    let mid = nodes.len() / 2;
    nodes.select_nth_unstable_by(mid, |a, b| a.0[axis].total_cmp(&b.0[axis]));
    let (low, rest) = nodes.split_at_mut(mid);
    build(low, depth + 1);
    build(&mut rest[1..], depth + 1);
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn nearest_agrees_with_brute_force() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let points: Vec<Point2<f64>> = (0..300)
            .map(|_| Point2::new(rng.random_range(-10.0..10.0), rng.random_range(-5.0..5.0)))
            .collect();
        let tree = KdTree::new(&points);
        assert_eq!(tree.len(), 300);
        for _ in 0..500 {
            let q = Point2::new(rng.random_range(-12.0..12.0), rng.random_range(-7.0..7.0));
            let brute = points
                .iter()
                .enumerate()
                .map(|(i, p)| (i, (p - q).norm_squared()))
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap();
            let found = tree.nearest(&q, f64::INFINITY).unwrap();
            assert_eq!(found.1, brute.1);
            // The distance gate hides points beyond it.
            let gated = tree.nearest(&q, 0.5 * brute.1.sqrt());
            assert!(gated.is_none());
        }
        assert!(KdTree::new(&[]).nearest(&Point2::origin(), 1.0).is_none());
    }

    #[test]
    fn within_agrees_with_brute_force() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        // Repeated coordinates test the split ties.
        let points: Vec<Point2<f64>> = (0..400)
            .map(|_| {
                Point2::new(
                    f64::from(rng.random_range(-20..20)) * 0.25,
                    rng.random_range(-3.0..3.0),
                )
            })
            .collect();
        let tree = KdTree::new(&points);
        for _ in 0..300 {
            let q = Point2::new(rng.random_range(-6.0..6.0), rng.random_range(-4.0..4.0));
            let r = rng.random_range(0.0..2.0);
            let mut found = tree.within(&q, r);
            found.sort_unstable();
            let brute: Vec<usize> = (0..points.len())
                .filter(|&i| (points[i] - q).norm() <= r)
                .collect();
            assert_eq!(found, brute);
        }
        assert!(KdTree::new(&[]).within(&Point2::origin(), 1.0).is_empty());
    }
}
