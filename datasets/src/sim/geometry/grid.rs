//! Uniform grid of segment ids and the ray walk through it (the cell
//! traversal of Amanatides and Woo, "A fast voxel traversal algorithm for ray
//! tracing", 1987).

use super::Segment;
use nalgebra::{Point2, Vector2};

/// Cells per side of the longest extent; cells are square.
const CELLS_ALONG_LONGEST_SIDE: f64 = 256.0;
/// Smallest cell side, metres (keeps tiny tanks from exploding the grid).
const MIN_CELL_M: f64 = 0.25;

/// Segment ids binned by the square cells they cross, stored compactly
/// (cell `c` owns `ids[offsets[c]..offsets[c + 1]]`).
#[derive(Clone, Debug)]
pub(super) struct SegmentGrid {
    origin: Point2<f64>,
    cell_m: f64,
    cols: usize,
    rows: usize,
    offsets: Vec<u32>,
    ids: Vec<u32>,
}

impl SegmentGrid {
    pub(super) fn build(segments: &[Segment]) -> Self {
        let (min, max) = extent(segments);
        let longest = (max.x - min.x).max(max.y - min.y);
        let cell_m = (longest / CELLS_ALONG_LONGEST_SIDE).max(MIN_CELL_M);
        let cols = (((max.x - min.x) / cell_m).ceil() as usize).max(1);
        let rows = (((max.y - min.y) / cell_m).ceil() as usize).max(1);
        let mut grid = Self {
            origin: min,
            cell_m,
            cols,
            rows,
            offsets: Vec::new(),
            ids: Vec::new(),
        };
        let mut per_cell: Vec<Vec<u32>> = vec![Vec::new(); cols * rows];
        for (id, s) in segments.iter().enumerate() {
            let (c0, r0) = grid.cell_of(Point2::new(s.a.x.min(s.b.x), s.a.y.min(s.b.y)));
            let (c1, r1) = grid.cell_of(Point2::new(s.a.x.max(s.b.x), s.a.y.max(s.b.y)));
            for r in r0..=r1 {
                for c in c0..=c1 {
                    if grid.segment_touches_cell(s, c, r) {
                        per_cell[r * cols + c].push(id as u32);
                    }
                }
            }
        }
        grid.offsets.push(0);
        for cell in &per_cell {
            grid.ids.extend_from_slice(cell);
            grid.offsets.push(grid.ids.len() as u32);
        }
        grid
    }

    pub(super) fn bounds(&self) -> (Point2<f64>, Point2<f64>) {
        let size = Vector2::new(self.cols as f64, self.rows as f64) * self.cell_m;
        (self.origin, self.origin + size)
    }

    fn cell_of(&self, p: Point2<f64>) -> (usize, usize) {
        let c = ((p.x - self.origin.x) / self.cell_m).floor();
        let r = ((p.y - self.origin.y) / self.cell_m).floor();
        (
            (c.max(0.0) as usize).min(self.cols - 1),
            (r.max(0.0) as usize).min(self.rows - 1),
        )
    }

    /// Separating-axis test of the segment against the (slightly grown) cell.
    fn segment_touches_cell(&self, s: &Segment, c: usize, r: usize) -> bool {
        let pad = 1e-9 * self.cell_m.max(1.0);
        let lo = self.origin + Vector2::new(c as f64, r as f64) * self.cell_m;
        let centre = lo + Vector2::repeat(0.5 * self.cell_m);
        let half = 0.5 * self.cell_m + pad;
        let e = s.b - s.a;
        let normal = Vector2::new(-e.y, e.x);
        let dist = normal.dot(&(centre - s.a)).abs();
        let reach = half * (normal.x.abs() + normal.y.abs());
        dist <= reach
    }

    /// Walks the cells crossed by `origin + t·dir`, `t` in [0, max_t], in
    /// order. `visit(ids, t_exit)` gets the segment ids of each cell and the
    /// ray parameter where the ray leaves it; returning `true` stops the walk.
    pub(super) fn traverse<F>(
        &self,
        origin: Point2<f64>,
        dir: Vector2<f64>,
        max_t: f64,
        mut visit: F,
    ) where
        F: FnMut(&[u32], f64) -> bool,
    {
        let (lo, hi) = self.bounds();
        let Some((t_enter, t_leave)) = slab(origin, dir, lo, hi) else {
            return;
        };
        let t_start = t_enter.max(0.0);
        let t_end = t_leave.min(max_t);
        if t_start > t_end {
            return;
        }
        let start = origin + dir * t_start;
        let (mut c, mut r) = self.cell_of(start);
        let step_c: isize = if dir.x >= 0.0 { 1 } else { -1 };
        let step_r: isize = if dir.y >= 0.0 { 1 } else { -1 };
        let next_boundary = |index: usize, step: isize, o: f64| {
            let k = if step > 0 { index + 1 } else { index };
            o + k as f64 * self.cell_m
        };
        let param = |boundary: f64, o: f64, d: f64| {
            if d.abs() < 1e-15 {
                f64::INFINITY
            } else {
                (boundary - o) / d
            }
        };
        let mut t_max_c = param(next_boundary(c, step_c, self.origin.x), origin.x, dir.x);
        let mut t_max_r = param(next_boundary(r, step_r, self.origin.y), origin.y, dir.y);
        let t_delta_c = if dir.x.abs() < 1e-15 {
            f64::INFINITY
        } else {
            self.cell_m / dir.x.abs()
        };
        let t_delta_r = if dir.y.abs() < 1e-15 {
            f64::INFINITY
        } else {
            self.cell_m / dir.y.abs()
        };
        loop {
            let t_exit = t_max_c.min(t_max_r);
            let cell = r * self.cols + c;
            let ids = &self.ids[self.offsets[cell] as usize..self.offsets[cell + 1] as usize];
            if visit(ids, t_exit) || t_exit > t_end {
                return;
            }
            if t_max_c < t_max_r {
                let next = c as isize + step_c;
                if next < 0 || next as usize >= self.cols {
                    return;
                }
                c = next as usize;
                t_max_c += t_delta_c;
            } else {
                let next = r as isize + step_r;
                if next < 0 || next as usize >= self.rows {
                    return;
                }
                r = next as usize;
                t_max_r += t_delta_r;
            }
        }
    }
}

/// Bounds of all segment end points, grown by a small margin.
fn extent(segments: &[Segment]) -> (Point2<f64>, Point2<f64>) {
    if segments.is_empty() {
        return (Point2::new(-0.5, -0.5), Point2::new(0.5, 0.5));
    }
    let mut min = Point2::new(f64::INFINITY, f64::INFINITY);
    let mut max = Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
    for p in segments.iter().flat_map(|s| [s.a, s.b]) {
        min = min.inf(&p);
        max = max.sup(&p);
    }
    let margin = Vector2::repeat(0.5);
    (min - margin, max + margin)
}

/// Ray-box slab test: the parameter interval inside the box, if any.
fn slab(
    origin: Point2<f64>,
    dir: Vector2<f64>,
    lo: Point2<f64>,
    hi: Point2<f64>,
) -> Option<(f64, f64)> {
    let mut t0 = f64::NEG_INFINITY;
    let mut t1 = f64::INFINITY;
    for axis in 0..2 {
        let (o, d) = (origin[axis], dir[axis]);
        if d.abs() < 1e-15 {
            if o < lo[axis] || o > hi[axis] {
                return None;
            }
        } else {
            let a = (lo[axis] - o) / d;
            let b = (hi[axis] - o) / d;
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
    }
    (t0 <= t1).then_some((t0, t1))
}
