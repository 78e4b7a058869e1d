//! Coarse global search of eq. (6): branch-and-bound over a discretised
//! window of poses (in the manner of Cartographer's fast correlative scan
//! matcher), exact for the score on the raster at the lattice poses.
//!
//! Poses are `θ_k = θ_prior + k·δθ` for `|k| ≤ K` and translations
//! `t_prior + (dx, dy)·c` for integer cell offsets within the window. For a
//! fixed angle, point `i` sits at `g_i = c_i + f_i` in cell-centre
//! coordinates (`c_i` integer, `f_i ∈ [0, 1)²`), and a translation by whole
//! cells keeps `f_i`, so the score of leaf `(k, dx, dy)` is the exact eq. (5)
//! `Σ_i I(c_i + (dx, dy) + f_i)`, bilinear between cells `c_i + d` and
//! `c_i + d + 1`. A node at level `h` stands for a `2^h × 2^h` block of
//! offsets; over it each point reads cells `[c_i + d0, c_i + d0 + 2^h]`,
//! exactly the window that level `h` of the sliding-window pyramid stores
//! at cell `c_i + d0` (see [`crate::image::pyramid`]), so
//! `Σ_i L_h[c_i + d0]` bounds every leaf of the node from above.
//! Depth-first search expanding the best children first finds a good leaf
//! early; every node whose bound does not beat it is pruned.
//!
//! The second search for the best *separated* peak excludes nodes lying
//! entirely within `separation` of the best leaf and leaves within it.

use crate::image::AcousticImage;
use echofield_graph::Se2;
use nalgebra::Point2;

/// The discretised search problem.
pub struct Discretisation {
    /// Angular step, radians.
    pub angle_step_rad: f64,
    /// Angles are `θ_prior + k·step` for `k ∈ [-angle_steps, angle_steps]`.
    pub angle_steps: i32,
    /// Translations are whole cells in `[-cells_x, cells_x] × [-cells_y, cells_y]`.
    pub cells_x: i32,
    pub cells_y: i32,
}

/// A node of the search: angle index, cell offsets of its first leaf and
/// its bound (the score of eq. (5) on the raster for a leaf).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Leaf {
    pub angle: i32,
    pub dx: i32,
    pub dy: i32,
    pub score: f32,
}

impl Leaf {
    /// The pose `image_from_scan` of this leaf.
    pub fn pose(&self, prior: &Se2, disc: &Discretisation, cell_m: f64) -> Se2 {
        Se2::new(
            prior.x() + f64::from(self.dx) * cell_m,
            prior.y() + f64::from(self.dy) * cell_m,
            prior.theta() + f64::from(self.angle) * disc.angle_step_rad,
        )
    }
}

/// Which leaves a search may not return.
#[derive(Clone, Copy, Debug)]
pub struct Exclusion {
    pub centre: Leaf,
    /// Half-size of the excluded cylinder: cells and angle steps.
    pub cells: f64,
    pub angle_steps: i32,
}

impl Exclusion {
    fn angle_excluded(&self, angle: i32) -> bool {
        (angle - self.centre.angle).abs() <= self.angle_steps
    }

    /// True when every offset of the block `[dx0, dx0+size) × [dy0, dy0+size)`
    /// lies within the excluded radius.
    fn block_excluded(&self, dx0: i32, dy0: i32, size: i32) -> bool {
        // The block corner farthest from the centre, per axis.
        let far = |lo: i32, centre: i32| {
            f64::from((lo - centre).abs().max((lo + size - 1 - centre).abs()))
        };
        far(dx0, self.centre.dx).hypot(far(dy0, self.centre.dy)) <= self.cells
    }
}

/// Statistics of one search.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SearchStats {
    /// Nodes whose bound was evaluated (all levels).
    pub nodes: usize,
}

/// The scan's cells for every angle, and the image to search.
pub struct SearchProblem<'a> {
    image: &'a AcousticImage,
    disc: &'a Discretisation,
    /// `cells[a * n + i]`: the integer part of point `i`'s cell-centre
    /// coordinates at angle index `a - K`; `fractions` the rest.
    cells: Vec<(i32, i32)>,
    fractions: Vec<(f32, f32)>,
    points: usize,
    top_level: usize,
}

impl<'a> SearchProblem<'a> {
    pub fn new(
        points: &[Point2<f64>],
        image: &'a AcousticImage,
        prior: &Se2,
        disc: &'a Discretisation,
    ) -> Self {
        let grid = image.grid();
        let (ox, oy) = grid.origin_m();
        let inv = 1.0 / grid.cell_size_m();
        let n_angles = (2 * disc.angle_steps + 1) as usize;
        let mut cells = Vec::with_capacity(n_angles * points.len());
        let mut fractions = Vec::with_capacity(n_angles * points.len());
        for a in 0..n_angles {
            let theta =
                prior.theta() + f64::from(a as i32 - disc.angle_steps) * disc.angle_step_rad;
            let (s, c) = theta.sin_cos();
            for p in points {
                // Cell-centre coordinates: cell (i, j)'s centre is (i, j).
                let x = (c * p.x - s * p.y + prior.x() - ox) * inv - 0.5;
                let y = (s * p.x + c * p.y + prior.y() - oy) * inv - 0.5;
                // Clamp so far-away points stay far away without overflow.
                let (fx, fy) = (x.floor(), y.floor());
                cells.push((fx.clamp(-1e8, 1e8) as i32, fy.clamp(-1e8, 1e8) as i32));
                fractions.push(((x - fx) as f32, (y - fy) as f32));
            }
        }
        let span = (2 * disc.cells_x.max(disc.cells_y) + 1) as u32;
        let needed = (u32::BITS - (span - 1).leading_zeros()) as usize; // ceil(log2(span))
        let top_level = needed.min(image.pyramid().len());
        Self {
            image,
            disc,
            cells,
            fractions,
            points: points.len(),
            top_level,
        }
    }

    /// The bound of node `(angle, dx0, dy0)` at `level`; at level 0 the
    /// exact score of eq. (5) (bilinear).
    fn bound(&self, level: usize, angle: i32, dx0: i32, dy0: i32) -> f32 {
        let a = (angle + self.disc.angle_steps) as usize;
        let range = a * self.points..(a + 1) * self.points;
        let cells = &self.cells[range.clone()];
        if level == 0 {
            return self.leaf_score(cells, &self.fractions[range], dx0, dy0);
        }
        let pyramid = self.image.pyramid();
        let l = pyramid.level(level);
        let (values, width) = (l.values(), l.width());
        let (w, h) = (width as u32, l.height() as u32);
        let mut sum = 0u32;
        for &(cx, cy) in cells {
            let (x, y) = (cx + dx0, cy + dy0);
            // Negative indices wrap to huge u32 values: one comparison per
            // axis finds the common case of a block starting inside.
            sum += u32::from(if (x as u32) < w && (y as u32) < h {
                values[y as usize * width + x as usize]
            } else {
                l.get(i64::from(x), i64::from(y))
            });
        }
        sum as f32 / pyramid.scale()
    }

    /// `Σ_i I(c_i + d + f_i)`: bilinear, cells outside the grid are 0.
    fn leaf_score(&self, cells: &[(i32, i32)], fractions: &[(f32, f32)], dx: i32, dy: i32) -> f32 {
        let grid = self.image.grid();
        let (values, width) = (grid.values(), grid.width());
        let (w1, h1) = (width as u32 - 1, grid.height() as u32 - 1);
        let mut sum = 0.0_f32;
        for (&(cx, cy), &(fx, fy)) in cells.iter().zip(fractions) {
            let (x, y) = (cx + dx, cy + dy);
            let [v00, v10, v01, v11] = if (x as u32) < w1 && (y as u32) < h1 {
                let k = y as usize * width + x as usize;
                [
                    values[k],
                    values[k + 1],
                    values[k + width],
                    values[k + width + 1],
                ]
            } else {
                let at = |x: i32, y: i32| grid.cell(i64::from(x), i64::from(y));
                [at(x, y), at(x + 1, y), at(x, y + 1), at(x + 1, y + 1)]
            };
            let bottom = v00 + fx * (v10 - v00);
            let top = v01 + fx * (v11 - v01);
            sum += bottom + fy * (top - bottom);
        }
        sum
    }

    /// Branch-and-bound for the best leaf outside `exclusion`. A `seed`
    /// (a leaf already known, e.g. from an earlier search) sets the score
    /// to beat and is returned when nothing beats it. Every leaf evaluated
    /// is appended to `record` when given. `None` when no leaf scores
    /// above 0.
    pub fn best_leaf(
        &self,
        seed: Option<Leaf>,
        exclusion: Option<&Exclusion>,
        stats: &mut SearchStats,
        record: Option<&mut Vec<Leaf>>,
    ) -> Option<Leaf> {
        let d = self.disc;
        let top = self.top_level;
        let size = 1i32 << top;
        let mut walk = Walk {
            best: seed,
            threshold: seed.map_or(0.0, |l| l.score),
            exclusion,
            stats,
            record,
        };
        let mut roots = Vec::new();
        for angle in -d.angle_steps..=d.angle_steps {
            let mut dx0 = -d.cells_x;
            while dx0 <= d.cells_x {
                let mut dy0 = -d.cells_y;
                while dy0 <= d.cells_y {
                    roots.extend(self.node(top, angle, dx0, dy0, &mut walk));
                    dy0 += size;
                }
                dx0 += size;
            }
        }
        self.descend(top, roots, &mut walk);
        walk.best.filter(|l| l.score > 0.0)
    }

    /// Evaluates a node, or `None` when it is wholly excluded.
    fn node(&self, level: usize, angle: i32, dx0: i32, dy0: i32, walk: &mut Walk) -> Option<Leaf> {
        if let Some(e) = walk.exclusion
            && e.angle_excluded(angle)
            && e.block_excluded(dx0, dy0, 1 << level)
        {
            return None;
        }
        walk.stats.nodes += 1;
        let leaf = Leaf {
            angle,
            dx: dx0,
            dy: dy0,
            score: self.bound(level, angle, dx0, dy0),
        };
        if level == 0
            && let Some(record) = walk.record.as_deref_mut()
        {
            record.push(leaf);
        }
        Some(leaf)
    }

    fn descend(&self, level: usize, mut nodes: Vec<Leaf>, walk: &mut Walk) {
        nodes.sort_by(|a, b| b.score.total_cmp(&a.score));
        for node in nodes {
            if node.score <= walk.threshold {
                break; // sorted: no later node can beat the threshold
            }
            if level == 0 {
                walk.threshold = node.score;
                walk.best = Some(node);
                continue;
            }
            let half = 1i32 << (level - 1);
            let d = self.disc;
            let mut children = Vec::with_capacity(4);
            for (ox, oy) in [(0, 0), (half, 0), (0, half), (half, half)] {
                let (dx0, dy0) = (node.dx + ox, node.dy + oy);
                if dx0 > d.cells_x || dy0 > d.cells_y {
                    continue;
                }
                children.extend(self.node(level - 1, node.angle, dx0, dy0, walk));
            }
            self.descend(level - 1, children, walk);
        }
    }
}

/// State of one branch-and-bound walk.
struct Walk<'e, 's, 'r> {
    best: Option<Leaf>,
    /// Only nodes whose bound exceeds this are expanded.
    threshold: f32,
    exclusion: Option<&'e Exclusion>,
    stats: &'s mut SearchStats,
    record: Option<&'r mut Vec<Leaf>>,
}

impl Exclusion {
    /// True when the leaf lies inside the excluded cylinder.
    pub fn contains(&self, leaf: &Leaf) -> bool {
        self.angle_excluded(leaf.angle) && self.block_excluded(leaf.dx, leaf.dy, 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::Grid;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A random sparse image, a random scan and a window: branch-and-bound
    /// must return the leaf that exhaustive evaluation finds best, and the
    /// best one outside an exclusion zone.
    #[test]
    fn branch_and_bound_finds_the_exhaustive_best() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        for trial in 0..6 {
            let mut grid = Grid::zeros(-4.0, -4.0, 0.2, 40, 40);
            for v in grid.values_mut() {
                *v = if rng.random_bool(0.15) {
                    rng.random()
                } else {
                    0.0
                };
            }
            let image = AcousticImage::from_grid(grid, 4);
            let points: Vec<Point2<f64>> = (0..25)
                .map(|_| Point2::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0)))
                .collect();
            let prior = Se2::new(
                rng.random_range(-0.5..0.5),
                rng.random_range(-0.5..0.5),
                0.3,
            );
            let disc = Discretisation {
                angle_step_rad: 0.03,
                angle_steps: 3,
                cells_x: 7,
                cells_y: 5,
            };
            let problem = SearchProblem::new(&points, &image, &prior, &disc);
            let mut all = Vec::new();
            for angle in -3..=3 {
                for dx in -7..=7 {
                    for dy in -5..=5 {
                        all.push(Leaf {
                            angle,
                            dx,
                            dy,
                            score: problem.bound(0, angle, dx, dy),
                        });
                    }
                }
            }
            let exhaustive = all
                .iter()
                .copied()
                .max_by(|a, b| a.score.total_cmp(&b.score))
                .unwrap();
            let mut stats = SearchStats::default();
            let found = problem.best_leaf(None, None, &mut stats, None).unwrap();
            assert_eq!(found.score, exhaustive.score, "trial {trial}");
            assert!(
                stats.nodes < all.len() * 2,
                "trial {trial}: {} nodes",
                stats.nodes
            );
            // The leaf score is eq. (5) on the raster at the leaf's pose.
            let pose = found.pose(&prior, &disc, 0.2);
            let direct = crate::matcher::raster_score(&points, &image, &pose);
            assert!(
                (f64::from(found.score) - direct).abs() < 1e-4,
                "{} vs {direct}",
                found.score
            );
            // The second search, outside 0.5 m and one angle step of it.
            let exclusion = Exclusion {
                centre: found,
                cells: 2.5,
                angle_steps: 1,
            };
            let second = all
                .iter()
                .filter(|l| !exclusion.contains(l))
                .map(|l| l.score)
                .fold(f32::MIN, f32::max);
            let got = problem
                .best_leaf(None, Some(&exclusion), &mut stats, None)
                .unwrap();
            assert!(!exclusion.contains(&got));
            assert_eq!(got.score, second, "trial {trial}");
        }
    }
}
