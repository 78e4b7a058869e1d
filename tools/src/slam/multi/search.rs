//! The coarse global search of a placement probe, by branch and bound over
//! a max-pooled pyramid of the map's coarse likelihood field.
//!
//! The coarse score of a probe at a pose is the mean over its points of
//! the field value of the cell each point falls in, 0 outside the map's
//! coverage (eq. 5 with nearest-cell lookup and an unknown value of 0).
//! The poses searched are every cell centre of the coarse field that lies
//! in the coverage (and, with a region, within it), at headings on a
//! regular step. Level `h` of the pyramid holds, at cell `(ix, iy)`, the
//! maximum of the field over the `2^h x 2^h` cells from `(ix, iy)` up; the
//! score of any pose whose cell lies in such a block is therefore at most
//! the score computed on level `h` at the block's corner, and a block
//! whose bound does not beat the best pose found so far is skipped whole.
//! The result is exactly the best pose of the exhaustive search, at a
//! fraction of its cost. Several *separated* peaks are found one after the
//! other: each later search skips the poses within a given distance of
//! the peaks already found.
//!
//! Written here rather than taken from a crate: no maintained Rust crate
//! offers a correlative scan-matching branch and bound over a caller's
//! grid (the method is that of Olson's multi-resolution correlative
//! matching and Cartographer's global localisation, both papers).

use echofield_frontend::localization::LikelihoodField;
use echofield_graph::Se2;
use echofield_graph::se2::wrap_angle;
use nalgebra::Point2;

/// Blocks of the top level are `2^LEVELS` cells wide.
const LEVELS: usize = 5;

/// The max-pooled pyramid of a coarse field (see the module doc).
pub struct CoarseIndex {
    width: i64,
    height: i64,
    /// Levels are stored for `ix, iy` in `-pad..width`, `-pad..height`.
    pad: i64,
    origin_m: (f64, f64),
    cell_m: f64,
    /// Level `h`: the maximum of the covered field values (0 outside the
    /// coverage) over the block of `2^h` cells from each cell up.
    values: Vec<Vec<f32>>,
    /// Level `h`: whether any cell of that block is covered.
    covered: Vec<Vec<bool>>,
}

/// Where the search looks: every covered cell (`None`) or those within
/// `radius_m` of `(x, y)`; headings `centre_rad + k * step_rad` for `|k| <=
/// steps`.
#[derive(Clone, Copy, Debug)]
pub struct Region {
    pub disc: Option<(f64, f64, f64)>,
    pub centre_rad: f64,
    pub step_rad: f64,
    pub steps: i64,
}

/// The outcome of a search: the peaks (best first) and the number of
/// bound or score evaluations it took.
pub struct Peaks {
    pub poses: Vec<(f64, Se2)>,
    pub evaluations: usize,
}

impl CoarseIndex {
    /// The pyramid of `field`.
    pub fn new(field: &LikelihoodField) -> Self {
        let grid = field.grid();
        let (width, height) = (grid.width() as i64, grid.height() as i64);
        let pad = (1i64 << LEVELS) - 1;
        let (sw, sh) = (width + pad, height + pad);
        let index = |ix: i64, iy: i64| ((iy + pad) * sw + ix + pad) as usize;
        let mut base = vec![0.0f32; (sw * sh) as usize];
        let mut base_covered = vec![false; (sw * sh) as usize];
        for iy in 0..height {
            for ix in 0..width {
                if field.is_covered_cell(ix, iy) {
                    base[index(ix, iy)] = grid.values()[(iy * width + ix) as usize];
                    base_covered[index(ix, iy)] = true;
                }
            }
        }
        let mut values = vec![base];
        let mut covered = vec![base_covered];
        for h in 1..=LEVELS {
            let s = 1i64 << (h - 1);
            let (prev, prev_covered) = (&values[h - 1], &covered[h - 1]);
            let at = |v: &Vec<f32>, ix: i64, iy: i64| {
                if ix >= width || iy >= height {
                    0.0
                } else {
                    v[index(ix, iy)]
                }
            };
            let at_covered =
                |v: &Vec<bool>, ix: i64, iy: i64| ix < width && iy < height && v[index(ix, iy)];
            let mut next = vec![0.0f32; (sw * sh) as usize];
            let mut next_covered = vec![false; (sw * sh) as usize];
            for iy in -pad..height {
                for ix in -pad..width {
                    let k = index(ix, iy);
                    next[k] = at(prev, ix, iy)
                        .max(at(prev, ix + s, iy))
                        .max(at(prev, ix, iy + s))
                        .max(at(prev, ix + s, iy + s));
                    next_covered[k] = at_covered(prev_covered, ix, iy)
                        || at_covered(prev_covered, ix + s, iy)
                        || at_covered(prev_covered, ix, iy + s)
                        || at_covered(prev_covered, ix + s, iy + s);
                }
            }
            values.push(next);
            covered.push(next_covered);
        }
        Self {
            width,
            height,
            pad,
            origin_m: grid.origin_m(),
            cell_m: grid.cell_size_m(),
            values,
            covered,
        }
    }

    /// Cell size, m.
    pub fn cell_m(&self) -> f64 {
        self.cell_m
    }

    fn slot(&self, ix: i64, iy: i64) -> Option<usize> {
        (ix >= -self.pad && iy >= -self.pad && ix < self.width && iy < self.height)
            .then(|| ((iy + self.pad) * (self.width + self.pad) + ix + self.pad) as usize)
    }

    fn centre_m(&self, ix: i64, iy: i64) -> (f64, f64) {
        (
            self.origin_m.0 + (ix as f64 + 0.5) * self.cell_m,
            self.origin_m.1 + (iy as f64 + 0.5) * self.cell_m,
        )
    }

    /// The coarse score (level 0) or its bound (level `h`) of the block
    /// at `(ix, iy)` with the points' cell `offsets`.
    fn bound(&self, h: usize, ix: i64, iy: i64, offsets: &[(i64, i64)]) -> f64 {
        let level = &self.values[h];
        let sum: f64 = offsets
            .iter()
            .map(|&(dx, dy)| {
                self.slot(ix + dx, iy + dy)
                    .map_or(0.0, |k| f64::from(level[k]))
            })
            .sum();
        sum / offsets.len().max(1) as f64
    }

    /// Up to `count` peaks of `points` (the probe, in its middle node's
    /// frame) over `region`, each at least `separation_m` from the ones
    /// before it (see the module doc).
    pub fn peaks(
        &self,
        points: &[Point2<f64>],
        region: &Region,
        count: usize,
        separation_m: f64,
    ) -> Peaks {
        let headings = self.heading_offsets(points, region);
        let cells = self.cells_of(region);
        let mut search = Search {
            index: self,
            region,
            separation_m,
            found: Vec::new(),
            evaluations: 0,
        };
        for _ in 0..count {
            let roots = search.roots(&headings, cells);
            let mut best: Option<(f64, usize, i64, i64)> = None;
            for &(b, a, ix, iy) in &roots {
                if best.is_some_and(|(s, ..)| b <= s) {
                    break;
                }
                search.descend(LEVELS, a, ix, iy, &headings[a].1, &mut best);
            }
            let Some((score, a, ix, iy)) = best else {
                break;
            };
            let (x, y) = self.centre_m(ix, iy);
            search.found.push((score, Se2::new(x, y, headings[a].0)));
        }
        Peaks {
            evaluations: search.evaluations,
            poses: search.found,
        }
    }

    /// For every heading of `region`: the heading and each point's cell
    /// offset from the pose's cell. With the pose at a cell centre, a
    /// point at `R p` from it falls in the cell `floor(0.5 + (R p) / cell)`
    /// away.
    fn heading_offsets(&self, points: &[Point2<f64>], region: &Region) -> Vec<HeadingOffsets> {
        (-region.steps..=region.steps)
            .map(|k| {
                let theta = wrap_angle(region.centre_rad + k as f64 * region.step_rad);
                let (s, c) = theta.sin_cos();
                let offsets = points
                    .iter()
                    .map(|p| {
                        let (x, y) = (c * p.x - s * p.y, s * p.x + c * p.y);
                        (
                            (0.5 + x / self.cell_m).floor() as i64,
                            (0.5 + y / self.cell_m).floor() as i64,
                        )
                    })
                    .collect();
                (theta, offsets)
            })
            .collect()
    }

    /// The cells `(x0, y0, x1, y1)`, inclusive, a pose of `region` may
    /// take: the whole index, cut to the region's disc when it has one.
    fn cells_of(&self, region: &Region) -> (i64, i64, i64, i64) {
        let (mut x0, mut y0, mut x1, mut y1) = (0, 0, self.width - 1, self.height - 1);
        if let Some((cx, cy, r)) = region.disc {
            let to_cell = |x: f64, o: f64| ((x - o) / self.cell_m).floor() as i64;
            x0 = x0.max(to_cell(cx - r, self.origin_m.0));
            y0 = y0.max(to_cell(cy - r, self.origin_m.1));
            x1 = x1.min(to_cell(cx + r, self.origin_m.0));
            y1 = y1.min(to_cell(cy + r, self.origin_m.1));
        }
        (x0, y0, x1, y1)
    }
}

/// A heading (radians) and every point's cell offset at it.
type HeadingOffsets = (f64, Vec<(i64, i64)>);

/// The state of one [`CoarseIndex::peaks`] call.
struct Search<'a> {
    index: &'a CoarseIndex,
    region: &'a Region,
    separation_m: f64,
    found: Vec<(f64, Se2)>,
    evaluations: usize,
}

impl Search<'_> {
    /// The top-level nodes of the search over `cells` at every heading
    /// that no peak found so far excludes, with their bounds, best first
    /// (ties by heading, then row, then column).
    fn roots(
        &mut self,
        headings: &[HeadingOffsets],
        (x0, y0, x1, y1): (i64, i64, i64, i64),
    ) -> Vec<(f64, usize, i64, i64)> {
        let top = 1i64 << LEVELS;
        let mut roots: Vec<(f64, usize, i64, i64)> = Vec::new();
        for (a, (_, offsets)) in headings.iter().enumerate() {
            let mut iy = y0;
            while iy <= y1 {
                let mut ix = x0;
                while ix <= x1 {
                    if self.admissible(LEVELS, ix, iy) {
                        self.evaluations += 1;
                        roots.push((self.index.bound(LEVELS, ix, iy, offsets), a, ix, iy));
                    }
                    ix += top;
                }
                iy += top;
            }
        }
        roots.sort_by(|p, q| {
            q.0.total_cmp(&p.0)
                .then(p.1.cmp(&q.1))
                .then(p.3.cmp(&q.3))
                .then(p.2.cmp(&q.2))
        });
        roots
    }

    /// Whether the block of level `h` at `(ix, iy)` may hold a pose to
    /// score: a covered cell, inside the region, not wholly within the
    /// separation of a peak already found.
    fn admissible(&self, h: usize, ix: i64, iy: i64) -> bool {
        let Some(k) = self.index.slot(ix, iy) else {
            return false;
        };
        if !self.index.covered[h][k] {
            return false;
        }
        let n = (1i64 << h) - 1;
        let (ax, ay) = self.index.centre_m(ix, iy);
        let (bx, by) = self.index.centre_m(ix + n, iy + n);
        if let Some((cx, cy, r)) = self.region.disc {
            // The block's nearest leaf centre to the disc's centre.
            let (nx, ny) = (cx.clamp(ax, bx), cy.clamp(ay, by));
            if (nx - cx).hypot(ny - cy) > r {
                return false;
            }
        }
        !self.found.iter().any(|(_, p)| {
            // The block's farthest leaf centre from the peak.
            let fx = (p.x() - ax).abs().max((p.x() - bx).abs());
            let fy = (p.y() - ay).abs().max((p.y() - by).abs());
            fx.hypot(fy) < self.separation_m
        })
    }

    /// Whether the pose at cell `(ix, iy)` may be a peak (inside the region,
    /// separated from the peaks found).
    fn leaf_allowed(&self, ix: i64, iy: i64) -> bool {
        let (x, y) = self.index.centre_m(ix, iy);
        if let Some((cx, cy, r)) = self.region.disc
            && (x - cx).hypot(y - cy) > r
        {
            return false;
        }
        self.found
            .iter()
            .all(|(_, p)| (p.x() - x).hypot(p.y() - y) >= self.separation_m)
    }

    fn descend(
        &mut self,
        h: usize,
        a: usize,
        ix: i64,
        iy: i64,
        offsets: &[(i64, i64)],
        best: &mut Option<(f64, usize, i64, i64)>,
    ) {
        if h == 0 {
            if !self.leaf_allowed(ix, iy) {
                return;
            }
            self.evaluations += 1;
            let score = self.index.bound(0, ix, iy, offsets);
            if best.is_none_or(|(s, ..)| score > s) {
                *best = Some((score, a, ix, iy));
            }
            return;
        }
        let s = 1i64 << (h - 1);
        let mut children: Vec<(f64, i64, i64)> =
            [(ix, iy), (ix + s, iy), (ix, iy + s), (ix + s, iy + s)]
                .into_iter()
                .filter(|&(cx, cy)| cx < self.index.width && cy < self.index.height)
                .filter(|&(cx, cy)| self.admissible(h - 1, cx, cy))
                .map(|(cx, cy)| (self.index.bound(h - 1, cx, cy, offsets), cx, cy))
                .collect();
        self.evaluations += children.len();
        children.sort_by(|p, q| q.0.total_cmp(&p.0).then(p.2.cmp(&q.2)).then(p.1.cmp(&q.1)));
        for (b, cx, cy) in children {
            if best.is_some_and(|(s, ..)| b <= s) {
                break;
            }
            self.descend(h - 1, a, cx, cy, offsets, best);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use echofield_frontend::image::Grid;

    /// A field with a few bright walls, and a probe of points on them:
    /// the branch and bound finds the exhaustive search's best pose.
    #[test]
    fn branch_and_bound_finds_the_exhaustive_best() {
        let (w, h) = (120usize, 90usize);
        let mut grid = Grid::zeros(-10.0, -5.0, 0.5, w, h);
        {
            let values = grid.values_mut();
            for ix in 10..100 {
                values[20 * w + ix] = 1.0;
            }
            for iy in 20..80 {
                values[iy * w + 30] = 1.0;
                values[iy * w + 95] = 0.7;
            }
            for ix in 60..90 {
                values[60 * w + ix] = 0.8;
            }
        }
        let footprints = [(Se2::new(20.0, 20.0, 0.0), 40.0)];
        let field = LikelihoodField::new(grid, &footprints, 0.5).unwrap();
        let index = CoarseIndex::new(&field);
        // Points on the walls seen from a vehicle at (12, 15), heading 0.1.
        let truth = Se2::new(12.25, 15.25, 0.1);
        let world: Vec<Point2<f64>> = (0..40)
            .map(|i| Point2::new(-4.75 + 0.5 * i as f64, 5.25))
            .chain((0..30).map(|i| Point2::new(5.25, 5.25 + 0.5 * i as f64)))
            .collect();
        let points: Vec<Point2<f64>> = world
            .iter()
            .map(|p| truth.inverse().transform_point(p))
            .collect();
        let region = Region {
            disc: None,
            centre_rad: 0.0,
            step_rad: 0.05,
            steps: 4,
        };
        let peaks = index.peaks(&points, &region, 3, 4.0);
        // The exhaustive search over the same poses.
        let mut exhaustive: Vec<(f64, Se2)> = Vec::new();
        for iy in 0..h as i64 {
            for ix in 0..w as i64 {
                if !field.is_covered_cell(ix, iy) {
                    continue;
                }
                for k in -4..=4 {
                    let theta = k as f64 * 0.05;
                    let (s, c) = theta.sin_cos();
                    let offsets: Vec<(i64, i64)> = points
                        .iter()
                        .map(|p| {
                            let (x, y) = (c * p.x - s * p.y, s * p.x + c * p.y);
                            (
                                (0.5 + x / 0.5).floor() as i64,
                                (0.5 + y / 0.5).floor() as i64,
                            )
                        })
                        .collect();
                    let (x, y) = index.centre_m(ix, iy);
                    exhaustive.push((index.bound(0, ix, iy, &offsets), Se2::new(x, y, theta)));
                }
            }
        }
        let best = exhaustive.iter().map(|(s, _)| *s).fold(f64::MIN, f64::max);
        assert_eq!(peaks.poses[0].0, best);
        assert!(
            (peaks.poses[0].1.translation() - truth.translation()).norm() < 0.6,
            "{:?}",
            peaks.poses[0]
        );
        assert!(
            peaks.evaluations < exhaustive.len() / 2,
            "{}",
            peaks.evaluations
        );
        // The later peaks keep their distance from the earlier ones.
        for (i, (_, p)) in peaks.poses.iter().enumerate() {
            for (_, q) in &peaks.poses[..i] {
                assert!((p.translation() - q.translation()).norm() >= 4.0);
            }
        }
        // A region around a wrong place never returns the true pose.
        let far = Region {
            disc: Some((40.0, 30.0, 3.0)),
            ..region
        };
        for (_, p) in index.peaks(&points, &far, 2, 4.0).poses {
            assert!((p.x() - 40.0).hypot(p.y() - 30.0) <= 3.0 + 1e-9);
        }
    }
}
