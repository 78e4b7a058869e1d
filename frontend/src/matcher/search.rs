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
//!
//! The search is best-first: it always expands the open node with the
//! highest bound and stops when that node is a leaf, so it expands only
//! nodes whose bound exceeds the best score (a depth-first search expands
//! every node whose bound beats the best leaf found *so far*, 2.5 times
//! as many on a ±5 m, ±20° window). The roots are one node per angle and
//! top-level block; points whose cells stay inside the grid for every
//! offset of the window are kept as flat indices, so a node costs one
//! byte load per point. An expanded node's four children are bounded in
//! one pass over the points (one 3 x 3 patch per point for four leaves
//! instead of four 2 x 2 ones), with the same sums in the same order as
//! one at a time, so results are unchanged bit for bit (timings: EXPERIMENTS.md
//! § Speed notes).
//!
//! [`SearchProblem::local_max`] is the alternative for a prior already
//! close to the answer: hill-climbing on the leaves from the prior. The
//! per-angle cell tables are built on first use, so a climb that visits a
//! few angles pays only for those.

use crate::image::AcousticImage;
use crate::image::grid::floor;
use echofield_graph::Se2;
use nalgebra::Point2;
use std::cell::OnceCell;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

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

/// A local climb scores a 3 x 3 layer of leaves in one pass when at least
/// this many of them are new ([`SearchProblem::local_max`]).
const NINE_LEAVES_MIN_NEW: usize = 3;

/// The leaf scores a local climb has evaluated, by (angle, x, y) index
/// over the whole window (NaN: not yet).
struct ClimbMemo {
    scores: Vec<f32>,
    nx: usize,
    ny: usize,
    angle_steps: i32,
    cells_x: i32,
    cells_y: i32,
}

impl ClimbMemo {
    fn new(d: &Discretisation) -> Self {
        let (nx, ny) = ((2 * d.cells_x + 1) as usize, (2 * d.cells_y + 1) as usize);
        let n_angles = (2 * d.angle_steps + 1) as usize;
        Self {
            scores: vec![f32::NAN; n_angles * nx * ny],
            nx,
            ny,
            angle_steps: d.angle_steps,
            cells_x: d.cells_x,
            cells_y: d.cells_y,
        }
    }

    fn index(&self, angle: i32, dx: i32, dy: i32) -> usize {
        ((angle + self.angle_steps) as usize * self.nx + (dx + self.cells_x) as usize) * self.ny
            + (dy + self.cells_y) as usize
    }

    /// The leaf's score, evaluated on first use.
    fn score(
        &mut self,
        problem: &SearchProblem,
        stats: &mut SearchStats,
        angle: i32,
        dx: i32,
        dy: i32,
    ) -> f32 {
        let k = self.index(angle, dx, dy);
        if self.scores[k].is_nan() {
            stats.nodes += 1;
            self.scores[k] = problem.bound(0, angle, dx, dy);
        }
        self.scores[k]
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
    points: &'a [Point2<f64>],
    prior: Se2,
    /// Per angle index `a` (angle `a - K`), built on first use: the global
    /// search reads every angle, a local climb only a few.
    tables: Vec<OnceCell<AngleTable>>,
    top_level: usize,
}

/// The scan's cells at one angle.
struct AngleTable {
    /// The points whose cells stay inside the grid for every offset of the
    /// window: the row-major index of point `i`'s cell (the integer part
    /// of its cell-centre coordinates) and the fractional rest. Their
    /// lookups need no clipping.
    inside: Vec<(u32, f32, f32)>,
    /// The same points' cell coordinates, for the pyramid levels stored at
    /// a coarser stride than the raster.
    inside_cells: Vec<(i32, i32)>,
    /// The other points: integer cell coordinates and the fractional rest.
    edge: Vec<(i32, i32, f32, f32)>,
}

impl<'a> SearchProblem<'a> {
    pub fn new(
        points: &'a [Point2<f64>],
        image: &'a AcousticImage,
        prior: &Se2,
        disc: &'a Discretisation,
    ) -> Self {
        let n_angles = (2 * disc.angle_steps + 1) as usize;
        let span = (2 * disc.cells_x.max(disc.cells_y) + 1) as u32;
        let needed = (u32::BITS - (span - 1).leading_zeros()) as usize; // ceil(log2(span))
        let top_level = needed.min(image.pyramid().len());
        Self {
            image,
            disc,
            points,
            prior: *prior,
            tables: (0..n_angles).map(|_| OnceCell::new()).collect(),
            top_level,
        }
    }

    /// The cells of angle index `a`.
    fn table(&self, a: usize) -> &AngleTable {
        self.tables[a].get_or_init(|| self.build_table(a))
    }

    fn build_table(&self, a: usize) -> AngleTable {
        let (disc, prior) = (self.disc, &self.prior);
        let grid = self.image.grid();
        let (ox, oy) = grid.origin_m();
        let inv = 1.0 / grid.cell_size_m();
        let (width, height) = (grid.width() as i64, grid.height() as i64);
        // A leaf at offset d reads cells c + d and c + d + 1, a node of a
        // higher level cell c + d0, for |d| ≤ cells.
        let (mx, my) = (i64::from(disc.cells_x), i64::from(disc.cells_y));
        let theta = prior.theta() + f64::from(a as i32 - disc.angle_steps) * disc.angle_step_rad;
        let (s, c) = theta.sin_cos();
        let mut inside = Vec::with_capacity(self.points.len());
        let mut inside_cells = Vec::with_capacity(self.points.len());
        let mut edge = Vec::new();
        for p in self.points {
            // Cell-centre coordinates: cell (i, j)'s centre is (i, j).
            let x = (c * p.x - s * p.y + prior.x() - ox) * inv - 0.5;
            let y = (s * p.x + c * p.y + prior.y() - oy) * inv - 0.5;
            // Clamp so far-away points stay far away without overflow.
            let (fx, fy) = (floor(x), floor(y));
            let (cx, cy) = (fx.clamp(-1e8, 1e8) as i64, fy.clamp(-1e8, 1e8) as i64);
            let rest = ((x - fx) as f32, (y - fy) as f32);
            if cx - mx >= 0 && cx + mx + 1 < width && cy - my >= 0 && cy + my + 1 < height {
                inside.push(((cy * width + cx) as u32, rest.0, rest.1));
                inside_cells.push((cx as i32, cy as i32));
            } else {
                edge.push((cx as i32, cy as i32, rest.0, rest.1));
            }
        }
        AngleTable {
            inside,
            inside_cells,
            edge,
        }
    }

    /// The bound of node `(angle, dx0, dy0)` at `level`; at level 0 the
    /// exact score of eq. (5) (bilinear).
    fn bound(&self, level: usize, angle: i32, dx0: i32, dy0: i32) -> f32 {
        let table = self.table((angle + self.disc.angle_steps) as usize);
        let (inside, edge) = (&table.inside[..], &table.edge[..]);
        if level == 0 {
            return self.leaf_score(inside, edge, dx0, dy0);
        }
        let pyramid = self.image.pyramid();
        let l = pyramid.level(level);
        let values = l.values();
        let mut sum = 0u32;
        if l.stride() == 1 {
            let offset = dy0 as isize * l.stored_width() as isize + dx0 as isize;
            for &(k, _, _) in inside {
                sum += u32::from(values[(k as isize + offset) as usize]);
            }
        } else {
            let (shift, sw) = (l.stride().trailing_zeros(), l.stored_width());
            for &(cx, cy) in &table.inside_cells {
                // Inside points stay in the grid for every offset of the window.
                let (x, y) = ((cx + dx0) as usize, (cy + dy0) as usize);
                sum += u32::from(values[(y >> shift) * sw + (x >> shift)]);
            }
        }
        for &(cx, cy, _, _) in edge {
            sum += u32::from(l.get(i64::from(cx + dx0), i64::from(cy + dy0)));
        }
        sum as f32 / pyramid.scale()
    }

    /// The bounds of the four nodes `(dx0 + a·2^level, dy0 + b·2^level)`,
    /// `a, b ∈ {0, 1}` (the children of a node at `level + 1`), in the
    /// order `(0, 0), (1, 0), (0, 1), (1, 1)`: each equal to
    /// [`SearchProblem::bound`] of that node (the same sums in the same
    /// order), with the table read once and, for leaves, one 3 × 3 patch
    /// of cells per point instead of four 2 × 2 ones. All four must lie in
    /// the window.
    fn child_bounds(&self, level: usize, angle: i32, dx0: i32, dy0: i32) -> [f32; 4] {
        let table = self.table((angle + self.disc.angle_steps) as usize);
        let (inside, edge) = (&table.inside[..], &table.edge[..]);
        let step = 1i32 << level;
        let children = [(0, 0), (step, 0), (0, step), (step, step)];
        if level == 0 {
            let grid = self.image.grid();
            let (values, width) = (grid.values(), grid.width());
            let offset = dy0 as isize * width as isize + dx0 as isize;
            let mut sums = [0.0_f32; 4];
            for &(k, fx, fy) in inside {
                let k = (k as isize + offset) as usize;
                let r0 = &values[k..k + 3];
                let r1 = &values[k + width..k + width + 3];
                let r2 = &values[k + 2 * width..k + 2 * width + 3];
                sums[0] += bilinear([r0[0], r0[1], r1[0], r1[1]], fx, fy);
                sums[1] += bilinear([r0[1], r0[2], r1[1], r1[2]], fx, fy);
                sums[2] += bilinear([r1[0], r1[1], r2[0], r2[1]], fx, fy);
                sums[3] += bilinear([r1[1], r1[2], r2[1], r2[2]], fx, fy);
            }
            for (sum, (ox, oy)) in sums.iter_mut().zip(children) {
                *sum = add_edge_leaf_score(*sum, grid, edge, dx0 + ox, dy0 + oy);
            }
            return sums;
        }
        let pyramid = self.image.pyramid();
        let l = pyramid.level(level);
        let values = l.values();
        let mut sums = [0u32; 4];
        if l.stride() == 1 {
            let width = l.stored_width() as isize;
            let base = dy0 as isize * width + dx0 as isize;
            let s = step as isize;
            let offsets = [base, base + s, base + s * width, base + s * width + s];
            for &(k, _, _) in inside {
                let k = k as isize;
                for (sum, o) in sums.iter_mut().zip(offsets) {
                    *sum += u32::from(values[(k + o) as usize]);
                }
            }
        } else {
            let (shift, sw) = (l.stride().trailing_zeros(), l.stored_width());
            for &(cx, cy) in &table.inside_cells {
                let (x0, y0) = ((cx + dx0) as usize, (cy + dy0) as usize);
                let (x1, y1) = (x0 + step as usize, y0 + step as usize);
                let (r0, r1) = ((y0 >> shift) * sw, (y1 >> shift) * sw);
                let (c0, c1) = (x0 >> shift, x1 >> shift);
                sums[0] += u32::from(values[r0 + c0]);
                sums[1] += u32::from(values[r0 + c1]);
                sums[2] += u32::from(values[r1 + c0]);
                sums[3] += u32::from(values[r1 + c1]);
            }
        }
        for &(cx, cy, _, _) in edge {
            for (sum, (ox, oy)) in sums.iter_mut().zip(children) {
                *sum += u32::from(l.get(i64::from(cx + dx0 + ox), i64::from(cy + dy0 + oy)));
            }
        }
        sums.map(|sum| sum as f32 / pyramid.scale())
    }

    /// The scores of the 3 × 3 leaves `(dx0 + i, dy0 + j)`, `i, j ∈ 0..3`,
    /// at `angle`, at index `3j + i`: each equal to
    /// [`SearchProblem::bound`] of that leaf (the same sums in the same
    /// order), with the table read once and one 4 × 4 patch of cells per
    /// point instead of nine 2 × 2 ones. All nine must lie in the window.
    fn nine_leaf_scores(&self, angle: i32, dx0: i32, dy0: i32) -> [f32; 9] {
        let table = self.table((angle + self.disc.angle_steps) as usize);
        let grid = self.image.grid();
        let (values, width) = (grid.values(), grid.width());
        let offset = dy0 as isize * width as isize + dx0 as isize;
        let mut sums = [0.0_f32; 9];
        for &(k, fx, fy) in &table.inside {
            let k = (k as isize + offset) as usize;
            let rows: [&[f32]; 4] =
                std::array::from_fn(|r| &values[k + r * width..k + r * width + 4]);
            for j in 0..3 {
                let (below, above) = (rows[j], rows[j + 1]);
                for i in 0..3 {
                    sums[3 * j + i] +=
                        bilinear([below[i], below[i + 1], above[i], above[i + 1]], fx, fy);
                }
            }
        }
        for (n, sum) in sums.iter_mut().enumerate() {
            let (i, j) = ((n % 3) as i32, (n / 3) as i32);
            *sum = add_edge_leaf_score(*sum, grid, &table.edge, dx0 + i, dy0 + j);
        }
        sums
    }

    /// `Σ_i I(c_i + d + f_i)`: bilinear, cells outside the grid are 0.
    fn leaf_score(
        &self,
        inside: &[(u32, f32, f32)],
        edge: &[(i32, i32, f32, f32)],
        dx: i32,
        dy: i32,
    ) -> f32 {
        let grid = self.image.grid();
        let (values, width) = (grid.values(), grid.width());
        let offset = dy as isize * width as isize + dx as isize;
        let mut sum = 0.0_f32;
        for &(k, fx, fy) in inside {
            let k = (k as isize + offset) as usize;
            let below = &values[k..k + 2];
            let above = &values[k + width..k + width + 2];
            sum += bilinear([below[0], below[1], above[0], above[1]], fx, fy);
        }
        add_edge_leaf_score(sum, grid, edge, dx, dy)
    }

    /// Branch-and-bound for the best leaf; `None` when no leaf scores
    /// above 0.
    ///
    /// Best-first: the open node with the highest bound is expanded next,
    /// and the search ends when that node is a leaf, whose exact score then
    /// beats every bound left. Only nodes whose bound exceeds the best
    /// score are expanded, the fewest any search with these bounds can.
    pub fn best_leaf(&self, stats: &mut SearchStats) -> Option<Leaf> {
        let mut open = self.roots(stats);
        self.run(&mut open, stats)
    }

    /// Hill-climbing on the leaves from the prior (leaf `(0, 0, 0)`): moves
    /// to the best of the up to 26 neighbours (one step in angle and
    /// cells) while it scores higher, and returns the local maximum;
    /// `None` when it scores 0. Each move strictly raises the score, so it
    /// ends; leaves are evaluated at most once. For a prior already close
    /// to the answer this costs tens of leaves where the global search
    /// evaluates about as many nodes as the window has leaves (the bounds
    /// of a smooth image prune little in a window of a few cells). The
    /// new leaves around each leaf are scored nine at a time where they
    /// can be (`SearchProblem::nine_leaf_scores`; the saving is in
    /// EXPERIMENTS.md § Speed notes).
    pub fn local_max(&self, stats: &mut SearchStats) -> Option<Leaf> {
        let mut memo = ClimbMemo::new(self.disc);
        let mut current = Leaf {
            angle: 0,
            dx: 0,
            dy: 0,
            score: memo.score(self, stats, 0, 0, 0),
        };
        loop {
            self.score_layers_around(&current, &mut memo, stats);
            let best = self.best_neighbour(&current, &mut memo, stats);
            if best == current {
                break;
            }
            current = best;
        }
        (current.score > 0.0).then_some(current)
    }

    /// The neighbourhood's leaves not scored yet: a 3 x 3 layer per angle
    /// in one pass over the points where the layer lies in the window and
    /// most of it is new.
    fn score_layers_around(&self, at: &Leaf, memo: &mut ClimbMemo, stats: &mut SearchStats) {
        let d = self.disc;
        let (x0, y0) = (at.dx - 1, at.dy - 1);
        let layer_fits =
            x0 >= -d.cells_x && x0 + 2 <= d.cells_x && y0 >= -d.cells_y && y0 + 2 <= d.cells_y;
        if !layer_fits {
            return;
        }
        for a in at.angle - 1..=at.angle + 1 {
            if a.abs() > d.angle_steps {
                continue;
            }
            let cells: [usize; 9] =
                std::array::from_fn(|n| memo.index(a, x0 + (n % 3) as i32, y0 + (n / 3) as i32));
            let new = cells.iter().filter(|&&k| memo.scores[k].is_nan()).count();
            if new < NINE_LEAVES_MIN_NEW {
                continue;
            }
            for (k, s) in cells.into_iter().zip(self.nine_leaf_scores(a, x0, y0)) {
                let slot = &mut memo.scores[k];
                if slot.is_nan() {
                    stats.nodes += 1;
                    *slot = s;
                }
            }
        }
    }

    /// The best of `at` and its 26 neighbours inside the window (`at` on
    /// ties).
    fn best_neighbour(&self, at: &Leaf, memo: &mut ClimbMemo, stats: &mut SearchStats) -> Leaf {
        let d = self.disc;
        let mut best = *at;
        for da in -1..=1 {
            for ex in -1..=1 {
                for ey in -1..=1 {
                    let (a, x, y) = (at.angle + da, at.dx + ex, at.dy + ey);
                    if a.abs() > d.angle_steps || x.abs() > d.cells_x || y.abs() > d.cells_y {
                        continue;
                    }
                    let s = memo.score(self, stats, a, x, y);
                    if s > best.score {
                        best = Leaf {
                            angle: a,
                            dx: x,
                            dy: y,
                            score: s,
                        };
                    }
                }
            }
        }
        best
    }

    /// The nodes of the top level that cover the window.
    fn roots(&self, stats: &mut SearchStats) -> BinaryHeap<Open> {
        let d = self.disc;
        let top = self.top_level;
        let size = 1i32 << top;
        let mut open = BinaryHeap::new();
        for angle in -d.angle_steps..=d.angle_steps {
            let mut dx0 = -d.cells_x;
            while dx0 <= d.cells_x {
                let mut dy0 = -d.cells_y;
                while dy0 <= d.cells_y {
                    self.push(top, angle, dx0, dy0, stats, &mut open);
                    dy0 += size;
                }
                dx0 += size;
            }
        }
        open
    }

    /// Best-first expansion of `open` until a leaf comes out on top.
    fn run(&self, open: &mut BinaryHeap<Open>, stats: &mut SearchStats) -> Option<Leaf> {
        let d = self.disc;
        while let Some(Open { node, level }) = open.pop() {
            if level == 0 {
                return Some(node); // beats every bound still open
            }
            let child = level - 1;
            let half = 1i32 << child;
            let blocks = [(0, 0), (half, 0), (0, half), (half, half)]
                .map(|(ox, oy)| (node.dx + ox, node.dy + oy));
            let open_child = |&(dx0, dy0): &(i32, i32)| dx0 <= d.cells_x && dy0 <= d.cells_y;
            if blocks.iter().all(open_child) {
                // The usual case: all four bounds in one pass over the points.
                let bounds = self.child_bounds(child, node.angle, node.dx, node.dy);
                stats.nodes += 4;
                for (&(dx, dy), score) in blocks.iter().zip(bounds) {
                    let node = Leaf {
                        angle: node.angle,
                        dx,
                        dy,
                        score,
                    };
                    if score > 0.0 {
                        open.push(Open { node, level: child });
                    }
                }
            } else {
                for &(dx0, dy0) in &blocks {
                    if dx0 <= d.cells_x && dy0 <= d.cells_y {
                        self.push(child, node.angle, dx0, dy0, stats, open);
                    }
                }
            }
        }
        None
    }

    /// Evaluates a node and opens it when its bound is above 0.
    fn push(
        &self,
        level: usize,
        angle: i32,
        dx0: i32,
        dy0: i32,
        stats: &mut SearchStats,
        open: &mut BinaryHeap<Open>,
    ) {
        stats.nodes += 1;
        let node = Leaf {
            angle,
            dx: dx0,
            dy: dy0,
            score: self.bound(level, angle, dx0, dy0),
        };
        if node.score > 0.0 {
            open.push(Open { node, level });
        }
    }
}

/// Bilinear interpolation between the cells `[v00, v10, v01, v11]` at the
/// fraction `(fx, fy)`.
#[inline]
fn bilinear([v00, v10, v01, v11]: [f32; 4], fx: f32, fy: f32) -> f32 {
    let bottom = v00 + fx * (v10 - v00);
    let top = v01 + fx * (v11 - v01);
    bottom + fy * (top - bottom)
}

/// `sum` plus the edge points' part of a leaf's score, added point by
/// point (cells outside the grid are 0).
fn add_edge_leaf_score(
    mut sum: f32,
    grid: &crate::image::Grid,
    edge: &[(i32, i32, f32, f32)],
    dx: i32,
    dy: i32,
) -> f32 {
    for &(cx, cy, fx, fy) in edge {
        let (x, y) = (i64::from(cx + dx), i64::from(cy + dy));
        let at = |x: i64, y: i64| grid.cell(x, y);
        sum += bilinear(
            [at(x, y), at(x + 1, y), at(x, y + 1), at(x + 1, y + 1)],
            fx,
            fy,
        );
    }
    sum
}

/// An open node of the best-first search, ordered by its bound; among
/// equal bounds leaves come first (they end the search), then the
/// lexicographically smallest `(angle, dx, dy)`, so the result is
/// deterministic.
struct Open {
    node: Leaf,
    level: usize,
}

impl Open {
    fn key(&self) -> (f32, std::cmp::Reverse<(usize, i32, i32, i32)>) {
        let n = &self.node;
        (
            n.score,
            std::cmp::Reverse((self.level, n.angle, n.dx, n.dy)),
        )
    }
}

impl PartialEq for Open {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Open {}

impl PartialOrd for Open {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Open {
    fn cmp(&self, other: &Self) -> Ordering {
        let (a, b) = (self.key(), other.key());
        a.0.total_cmp(&b.0).then_with(|| a.1.cmp(&b.1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::Grid;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A 40 x 40 image of 0.2 m cells, each an echo of random strength
    /// with probability `density`, and 25 random scan points within 3 m.
    fn random_image_and_scan(
        rng: &mut ChaCha8Rng,
        density: f64,
    ) -> (AcousticImage, Vec<Point2<f64>>) {
        let mut grid = Grid::zeros(-4.0, -4.0, 0.2, 40, 40);
        for v in grid.values_mut() {
            *v = if rng.random_bool(density) {
                rng.random()
            } else {
                0.0
            };
        }
        let image = AcousticImage::from_grid(grid, 4);
        let points = (0..25)
            .map(|_| Point2::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0)))
            .collect();
        (image, points)
    }

    /// The climb ends at a leaf no neighbour beats, never below the
    /// prior's leaf, evaluating each leaf at most once.
    #[test]
    fn the_local_climb_ends_at_a_local_maximum() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let disc = Discretisation {
            angle_step_rad: 0.03,
            angle_steps: 3,
            cells_x: 7,
            cells_y: 5,
        };
        let leaves = 7 * 15 * 11;
        for trial in 0..10 {
            let (image, points) = random_image_and_scan(&mut rng, 0.3);
            let prior = Se2::new(rng.random_range(-0.5..0.5), 0.0, 0.3);
            let problem = SearchProblem::new(&points, &image, &prior, &disc);
            let mut stats = SearchStats::default();
            let top = problem.local_max(&mut stats).unwrap();
            assert!(top.score >= problem.bound(0, 0, 0, 0), "trial {trial}");
            assert_eq!(top.score, problem.bound(0, top.angle, top.dx, top.dy));
            assert!(
                stats.nodes <= leaves,
                "trial {trial}: {} nodes",
                stats.nodes
            );
            for da in -1..=1 {
                for dx in -1..=1 {
                    for dy in -1..=1 {
                        let (a, x, y) = (top.angle + da, top.dx + dx, top.dy + dy);
                        if a.abs() <= 3 && x.abs() <= 7 && y.abs() <= 5 {
                            assert!(problem.bound(0, a, x, y) <= top.score, "trial {trial}");
                        }
                    }
                }
            }
        }
    }

    /// Four search problems over random images (seeded by `seed`), each
    /// with scan points inside the grid and at its edge at angle index
    /// `angle_index`, passed to `check` with the trial number.
    fn with_edge_problems(
        seed: u64,
        disc: &Discretisation,
        angle_index: usize,
        mut check: impl FnMut(usize, &SearchProblem),
    ) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for trial in 0..4 {
            let (image, points) = random_image_and_scan(&mut rng, 0.4);
            let prior = Se2::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                0.2,
            );
            let problem = SearchProblem::new(&points, &image, &prior, disc);
            let table = problem.table(angle_index);
            assert!(
                !table.inside.is_empty() && !table.edge.is_empty(),
                "trial {trial}: both kinds of points"
            );
            check(trial, &problem);
        }
    }

    /// The four children's bounds read in one pass equal the bounds read
    /// one by one, bit for bit, at every level and for points inside the
    /// grid as well as at its edge.
    #[test]
    fn child_bounds_equal_the_single_bounds() {
        let disc = Discretisation {
            angle_step_rad: 0.03,
            angle_steps: 2,
            cells_x: 12,
            cells_y: 9,
        };
        with_edge_problems(6, &disc, 3, |trial, problem| {
            for level in 0..problem.top_level {
                let step = 1i32 << level;
                for angle in -2..=2 {
                    for dx0 in -disc.cells_x..=disc.cells_x - step {
                        for dy0 in -disc.cells_y..=disc.cells_y - step {
                            let four = problem.child_bounds(level, angle, dx0, dy0);
                            let one = [(0, 0), (step, 0), (0, step), (step, step)]
                                .map(|(ox, oy)| problem.bound(level, angle, dx0 + ox, dy0 + oy));
                            assert_eq!(
                                four.map(f32::to_bits),
                                one.map(f32::to_bits),
                                "trial {trial}, level {level}, ({angle}, {dx0}, {dy0})"
                            );
                        }
                    }
                }
            }
        });
    }

    /// The nine leaves scored in one pass equal the leaves scored one by
    /// one, bit for bit, for points inside the grid as well as at its edge.
    #[test]
    fn nine_leaf_scores_equal_the_single_scores() {
        let disc = Discretisation {
            angle_step_rad: 0.03,
            angle_steps: 2,
            cells_x: 6,
            cells_y: 5,
        };
        with_edge_problems(7, &disc, 2, |trial, problem| {
            for angle in -2..=2 {
                for dx0 in -disc.cells_x..=disc.cells_x - 2 {
                    for dy0 in -disc.cells_y..=disc.cells_y - 2 {
                        let nine = problem.nine_leaf_scores(angle, dx0, dy0);
                        let one: [f32; 9] = std::array::from_fn(|n| {
                            let (i, j) = ((n % 3) as i32, (n / 3) as i32);
                            problem.bound(0, angle, dx0 + i, dy0 + j)
                        });
                        assert_eq!(
                            nine.map(f32::to_bits),
                            one.map(f32::to_bits),
                            "trial {trial}, ({angle}, {dx0}, {dy0})"
                        );
                    }
                }
            }
        });
    }

    /// A random sparse image, a random scan and a window: branch-and-bound
    /// must return the leaf that exhaustive evaluation finds best.
    #[test]
    fn branch_and_bound_finds_the_exhaustive_best() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        for trial in 0..6 {
            let (image, points) = random_image_and_scan(&mut rng, 0.15);
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
            let found = problem.best_leaf(&mut stats).unwrap();
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
        }
    }
}
