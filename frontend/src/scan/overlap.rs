//! The ground-truth scan overlap shared by every evaluation against ground
//! truth (the pipeline's loop recall in `echofield run`, the matcher's
//! trial pairs in `echofield bench-matcher`): how much of what one rotation
//! saw another one saw too.
//!
//! Definition: with `S_j` rasterised into [`ScanCells`] (cells of side
//! `cell_m` holding a point of `S_j`, each dilated by its eight
//! neighbours), the overlap of `S_k` placed by a pose `j_from_k` is the
//! fraction of the points of `S_k` that land on those cells, i.e. within
//! about one to two cell sides of a point of `S_j`. It is not symmetric in
//! `j` and `k`, and it is meant for truth poses: it says nothing about
//! whether a matcher can register the pair.

use echofield_graph::Se2;
use nalgebra::Point2;

/// The cells of side `cell_m` (metres) holding a point of a scan, dilated by
/// one cell, as a dense bitmap over the scan's bounding box. The memory is
/// one byte per cell of that box: a scan of 50 m reach at 0.5 m cells takes
/// about 40 kB.
#[derive(Clone, Debug)]
pub struct ScanCells {
    cell_m: f64,
    origin: (i64, i64),
    width: i64,
    height: i64,
    occupied: Vec<bool>,
}

impl ScanCells {
    /// The cells of `points` (metres, in the scan's own frame). Precondition:
    /// `cell_m > 0` and finite points (scans are built from validated beams);
    /// an empty scan gives cells that nothing lands on.
    pub fn new(points: &[Point2<f64>], cell_m: f64) -> Self {
        let cell = |v: f64| (v / cell_m).floor() as i64;
        let cells: Vec<(i64, i64)> = points.iter().map(|p| (cell(p.x), cell(p.y))).collect();
        if cells.is_empty() {
            return Self {
                cell_m,
                origin: (0, 0),
                width: 0,
                height: 0,
                occupied: Vec::new(),
            };
        }
        let min_x = cells.iter().map(|c| c.0).min().unwrap_or(0) - 1;
        let min_y = cells.iter().map(|c| c.1).min().unwrap_or(0) - 1;
        let max_x = cells.iter().map(|c| c.0).max().unwrap_or(0) + 1;
        let max_y = cells.iter().map(|c| c.1).max().unwrap_or(0) + 1;
        let (width, height) = (max_x - min_x + 1, max_y - min_y + 1);
        let mut occupied = vec![false; (width * height) as usize];
        for (cx, cy) in cells {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (x, y) = (cx + dx - min_x, cy + dy - min_y);
                    occupied[(y * width + x) as usize] = true;
                }
            }
        }
        Self {
            cell_m,
            origin: (min_x, min_y),
            width,
            height,
            occupied,
        }
    }

    /// Whether the point `(x_m, y_m)` (the scan's frame) lands on a cell.
    pub fn contains(&self, x_m: f64, y_m: f64) -> bool {
        let x = (x_m / self.cell_m).floor() as i64 - self.origin.0;
        let y = (y_m / self.cell_m).floor() as i64 - self.origin.1;
        x >= 0
            && y >= 0
            && x < self.width
            && y < self.height
            && self.occupied[(y * self.width + x) as usize]
    }

    /// The overlap of the module doc: the fraction of `points` (frame `k`)
    /// that land on the cells when placed by `j_from_k`; 0 for an empty
    /// `points` or empty cells.
    pub fn overlap(&self, points: &[Point2<f64>], j_from_k: &Se2) -> f64 {
        if points.is_empty() || self.occupied.is_empty() {
            return 0.0;
        }
        let hits = points
            .iter()
            .filter(|p| {
                let (x, y) = j_from_k.transform_xy(p.x, p.y);
                self.contains(x, y)
            })
            .count();
        hits as f64 / points.len() as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlap_of_a_wall_seen_twice() {
        // A wall along y = 5 from x = 0 to 20 m, one point per 0.1 m.
        let wall: Vec<Point2<f64>> = (0..200).map(|i| Point2::new(i as f64 * 0.1, 5.0)).collect();
        let cells = ScanCells::new(&wall, 0.5);
        // The same wall from the same place: all of it.
        assert_eq!(cells.overlap(&wall, &Se2::identity()), 1.0);
        // From 10 m further along x: half of it lies beyond the end (the
        // dilation adds a cell's worth at the end).
        let half = cells.overlap(&wall, &Se2::new(10.0, 0.0, 0.0));
        assert!((half - 0.5).abs() < 0.03, "{half}");
        // Placed 3 m off the wall: nothing; within the dilation: all.
        assert_eq!(cells.overlap(&wall, &Se2::new(0.0, 3.0, 0.0)), 0.0);
        assert_eq!(cells.overlap(&wall, &Se2::new(0.0, 0.4, 0.0)), 1.0);
        // Turned by 90° about the origin, the wall runs along x = -5: no
        // point of it lands on the original wall's cells.
        let turned = Se2::new(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        assert_eq!(cells.overlap(&wall, &turned), 0.0);
        // An empty scan overlaps nothing and is overlapped by nothing.
        let empty = ScanCells::new(&[], 0.5);
        assert_eq!(empty.overlap(&wall, &Se2::identity()), 0.0);
        assert!(!empty.contains(0.0, 0.0));
        assert_eq!(cells.overlap(&[], &Se2::identity()), 0.0);
    }

    #[test]
    fn a_point_is_inside_up_to_the_dilated_cells() {
        let cells = ScanCells::new(&[Point2::new(0.25, 0.25)], 0.5);
        // Its own cell [0, 0.5)² and the eight around it: [-0.5, 1.0)².
        assert!(cells.contains(0.25, 0.25));
        assert!(cells.contains(-0.49, 0.99));
        assert!(!cells.contains(-0.51, 0.25));
        assert!(!cells.contains(0.25, 1.0));
    }
}
