//! Map sharpness: how tightly a set of sonar returns placed in the world
//! piles up, a measure of a trajectory and a mounting that needs no ground
//! truth.
//!
//! Every return of every beam is placed in the world at its beam's time,
//!
//! ```text
//! p = world_from_vehicle(t) ⊕ vehicle_from_beam(θ) ⊕ [r, 0]      (eq. 3-4)
//! ```
//!
//! and splatted bilinearly on a grid of `cell_size_m` cells. A wall seen
//! from many poses lands on the same cells when the poses and the mounting
//! are right, and is smeared over more cells when they are not. The
//! sharpness is the Shannon entropy of the normalised cell weights,
//!
//! ```text
//! H = −Σ_c w_c log2 w_c,   w_c = weight of cell c / Σ weights        (bits)
//! ```
//!
//! (lower is sharper), with the number of cells holding weight (the map's
//! area) beside it. Bilinear splatting makes `H` a continuous function of
//! the poses and the mounting, so it can be minimised numerically
//! (`crate::calibration`). Comparisons are meaningful between placements
//! of the same returns only.

use crate::error::FrontendError;
use crate::segmentation::{SegmentationConfig, extract_ranges_into};
use crate::sensors::{SensorMounting, SonarBeam};
use echofield_graph::Se2;
use nalgebra::Vector2;
use serde::Serialize;

/// One return of one beam: what the segmentation found, before any
/// placement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamReturn {
    /// Index of the beam in the slice it came from.
    pub beam: usize,
    pub stamp_s: f64,
    /// The head's logged angle (its own direction convention), radians.
    pub angle_rad: f64,
    pub range_m: f64,
}

/// Every return of `beams` under `config`'s range extraction, in beam order.
pub fn beam_returns(beams: &[SonarBeam], config: &SegmentationConfig) -> Vec<BeamReturn> {
    let mut scratch = Vec::new();
    let mut ranges = Vec::new();
    let mut out = Vec::new();
    for (j, beam) in beams.iter().enumerate() {
        ranges.clear();
        extract_ranges_into(beam, config, &mut scratch, &mut ranges);
        out.extend(ranges.iter().map(|r| BeamReturn {
            beam: j,
            stamp_s: beam.stamp_s,
            angle_rad: beam.angle_rad,
            range_m: r.range_m,
        }));
    }
    out
}

/// `returns` placed with any `world_from_vehicle(t)`; `None` leaves a
/// return out.
pub fn place_with(
    returns: &[BeamReturn],
    mounting: &SensorMounting,
    world_from_vehicle: impl Fn(f64) -> Option<Se2>,
) -> Vec<Vector2<f64>> {
    returns
        .iter()
        .filter_map(|r| {
            let pose = world_from_vehicle(r.stamp_s)?;
            let beam = pose.compose(&mounting.vehicle_from_beam(r.angle_rad));
            let (x, y) = beam.transform_xy(r.range_m, 0.0);
            Some(Vector2::new(x, y))
        })
        .collect()
}

/// The sharpness of one placement (module doc).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Sharpness {
    /// Entropy of the cell weights, bits; lower is sharper.
    pub entropy_bits: f64,
    /// Cells that hold weight.
    pub occupied_cells: usize,
    /// `occupied_cells · cell_size_m²`.
    pub area_m2: f64,
    pub points: usize,
    pub cell_size_m: f64,
}

/// Grids wider than this many cells on a side are refused (a placement
/// gone wrong: NaN-free but kilometres wide).
const MAX_CELLS_PER_SIDE: f64 = 20_000.0;

/// The sharpness of `points` on a grid of `cell_size_m` cells.
///
/// Errors: a cell size that is not positive and finite; a non-finite
/// point; points spread over more than 20 000 cells on a side.
pub fn sharpness(points: &[Vector2<f64>], cell_size_m: f64) -> Result<Sharpness, FrontendError> {
    if !(cell_size_m.is_finite() && cell_size_m > 0.0) {
        return Err(FrontendError::config(
            "cell_size_m",
            format!("must be positive and finite, got {cell_size_m}"),
        ));
    }
    let mut grid = SplatGrid::default();
    grid.fill(points, cell_size_m)?;
    Ok(grid.sharpness(points.len(), cell_size_m))
}

/// How a point's unit weight is spread over the cells near it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// Over the 2 x 2 cells whose centres surround it, bilinearly.
    Bilinear,
    /// Over the 3 x 3 cells about the nearest centre, by the quadratic
    /// B-spline. Smoother: a line of points splits its weight between rows
    /// in nearly the same proportions wherever it lies in a cell (the
    /// entropy of a line changes by 0.06 bits across a cell, against 1 bit
    /// for the bilinear kernel), so the lattice pulls far less on a
    /// placement whose entropy is minimised.
    QuadraticBSpline,
}

/// The lower and upper corners of a set of points.
type Corners = (Vector2<f64>, Vector2<f64>);

/// A reusable dense grid for [`sharpness`]; keeps its allocation between
/// calls (the calibration evaluates thousands of placements). Only the
/// cells that received weight are visited after splatting, so the cost of
/// one placement goes with its points, not with the area they cover.
#[derive(Clone, Debug, Default)]
pub struct SplatGrid {
    /// All zero except at `touched`.
    weights: Vec<f32>,
    /// The cells holding weight, in the order they first received it.
    touched: Vec<usize>,
}

impl SplatGrid {
    /// Splats `points` on a grid that covers them (one cell of margin),
    /// its cells aligned with the lowest corner of their bounding box.
    pub fn fill(&mut self, points: &[Vector2<f64>], cell_size_m: f64) -> Result<(), FrontendError> {
        let Some((lo, hi)) = self.reset(points)? else {
            return Ok(());
        };
        self.splat(points, cell_size_m, lo - Vector2::repeat(cell_size_m), hi)
    }

    /// Splats `points` with `kernel` on the fixed lattice whose cell
    /// centres lie at `offset_m + (i, j) · cell_size_m` for integers `i, j`.
    /// Unlike [`SplatGrid::fill`], the cells do not move with the points,
    /// so the entropy changes only as points move across them.
    pub fn fill_on_lattice(
        &mut self,
        points: &[Vector2<f64>],
        cell_size_m: f64,
        offset_m: Vector2<f64>,
        kernel: Kernel,
    ) -> Result<(), FrontendError> {
        let Some((lo, hi)) = self.reset(points)? else {
            return Ok(());
        };
        let below = ((lo - offset_m) / cell_size_m).map(f64::floor);
        let origin = offset_m + (below - Vector2::repeat(1.0)) * cell_size_m;
        match kernel {
            Kernel::Bilinear => self.splat(points, cell_size_m, origin, hi),
            Kernel::QuadraticBSpline => self.splat_quadratic(points, cell_size_m, origin, hi),
        }
    }

    /// Clears the last fill; the bounding box of `points` (`None` when
    /// there are none). Errors on a non-finite point.
    fn reset(&mut self, points: &[Vector2<f64>]) -> Result<Option<Corners>, FrontendError> {
        for &k in &self.touched {
            self.weights[k] = 0.0;
        }
        self.touched.clear();
        let Some(first) = points.first() else {
            return Ok(None);
        };
        let (mut lo, mut hi) = (*first, *first);
        for (i, p) in points.iter().enumerate() {
            if !(p.x.is_finite() && p.y.is_finite()) {
                return Err(FrontendError::input(
                    format!("point {i}"),
                    "x, y",
                    "not finite",
                ));
            }
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        Ok(Some((lo, hi)))
    }

    /// Splats bilinearly on cells centred at `origin + (i, j) · cell`,
    /// `origin` at least one cell below and left of every point and `hi`
    /// the points' upper corner.
    fn splat(
        &mut self,
        points: &[Vector2<f64>],
        cell_size_m: f64,
        origin: Vector2<f64>,
        hi: Vector2<f64>,
    ) -> Result<(), FrontendError> {
        let (w, _) = self.allocate(cell_size_m, origin, hi, 0.0)?;
        for p in points {
            let u = (p.x - origin.x) / cell_size_m;
            let v = (p.y - origin.y) / cell_size_m;
            // u, v > 0: truncation is the floor, without a call to libm.
            let (i, j) = (u as usize, v as usize);
            let (fu, fv) = ((u - i as f64) as f32, (v - j as f64) as f32);
            let k = j * w + i;
            self.add(k, (1.0 - fu) * (1.0 - fv));
            self.add(k + 1, fu * (1.0 - fv));
            self.add(k + w, (1.0 - fu) * fv);
            self.add(k + w + 1, fu * fv);
        }
        Ok(())
    }

    /// Splats with the quadratic B-spline on cells centred at
    /// `origin + (i, j) · cell`: a point `f` cells from its nearest centre
    /// (`|f| ≤ ½`) gives `(½ − f)²/2, ¾ − f², (½ + f)²/2` to that centre's
    /// row neighbours, and likewise along y. `origin` lies at least one
    /// cell below and left of every point.
    fn splat_quadratic(
        &mut self,
        points: &[Vector2<f64>],
        cell_size_m: f64,
        origin: Vector2<f64>,
        hi: Vector2<f64>,
    ) -> Result<(), FrontendError> {
        let (w, _) = self.allocate(cell_size_m, origin, hi, 0.5)?;
        let weights = |f: f64| {
            let f = f as f32;
            [
                0.5 * (0.5 - f) * (0.5 - f),
                0.75 - f * f,
                0.5 * (0.5 + f) * (0.5 + f),
            ]
        };
        for p in points {
            let u = (p.x - origin.x) / cell_size_m;
            let v = (p.y - origin.y) / cell_size_m;
            // u, v ≥ 1: truncation rounds, without a call to libm.
            let (i, j) = ((u + 0.5) as usize, (v + 0.5) as usize);
            let (wx, wy) = (weights(u - i as f64), weights(v - j as f64));
            let k = (j - 1) * w + i - 1;
            for (row, &wy) in wy.iter().enumerate() {
                for (col, &wx) in wx.iter().enumerate() {
                    self.add(k + row * w + col, wx * wy);
                }
            }
        }
        Ok(())
    }

    /// Sizes the dense grid from `origin` to `hi` with `extra` cells past
    /// the last centre a point rounds to (plus the neighbour a kernel
    /// reaches); errors when it would be wider than the limit.
    fn allocate(
        &mut self,
        cell_size_m: f64,
        origin: Vector2<f64>,
        hi: Vector2<f64>,
        extra: f64,
    ) -> Result<(usize, usize), FrontendError> {
        let width = ((hi.x - origin.x) / cell_size_m + extra).floor() + 2.0;
        let height = ((hi.y - origin.y) / cell_size_m + extra).floor() + 2.0;
        if width > MAX_CELLS_PER_SIDE || height > MAX_CELLS_PER_SIDE {
            return Err(FrontendError::input(
                "points",
                "x, y",
                format!(
                    "spread over {:.0} m x {:.0} m, more than {MAX_CELLS_PER_SIDE} cells a side",
                    hi.x - origin.x - cell_size_m,
                    hi.y - origin.y - cell_size_m
                ),
            ));
        }
        let (w, h) = (width as usize, height as usize);
        if self.weights.len() < w * h {
            self.weights.resize(w * h, 0.0);
        }
        Ok((w, h))
    }

    fn add(&mut self, cell: usize, weight: f32) {
        let before = self.weights[cell];
        self.weights[cell] = before + weight;
        if before == 0.0 && weight > 0.0 {
            self.touched.push(cell);
        }
    }

    /// The entropy and occupancy of the last [`fill`](Self::fill).
    pub fn sharpness(&self, points: usize, cell_size_m: f64) -> Sharpness {
        // H = −Σ (w/T) log2(w/T) = log2 T − (1/T) Σ w log2 w, the logarithms
        // in the weights' own single precision (the calibration evaluates
        // thousands of placements; its errors are far below any difference
        // between two of them that matters).
        let (mut total, mut sum_w_log_w) = (0.0f64, 0.0f64);
        for &k in &self.touched {
            let w = self.weights[k];
            total += f64::from(w);
            sum_w_log_w += f64::from(w * w.log2());
        }
        let entropy = if total > 0.0 {
            (total.log2() - sum_w_log_w / total).max(0.0)
        } else {
            0.0
        };
        let occupied = self.touched.len();
        Sharpness {
            entropy_bits: entropy,
            occupied_cells: occupied,
            area_m2: occupied as f64 * cell_size_m * cell_size_m,
            points,
            cell_size_m,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wall(offset_m: f64, n: usize) -> Vec<Vector2<f64>> {
        (0..n)
            .map(|i| Vector2::new(i as f64 * 0.05, offset_m))
            .collect()
    }

    #[test]
    fn two_copies_of_a_wall_are_sharpest_when_they_coincide() {
        let base = wall(0.0, 400);
        let entropy = |shift: f64| {
            let points = [base.clone(), wall(shift, 400)].concat();
            sharpness(&points, 0.5).unwrap().entropy_bits
        };
        // Rises while the copies share cells, then stays: beyond a cell
        // apart they no longer overlap.
        let rising: Vec<f64> = [0.0, 0.1, 0.25, 0.4].map(entropy).to_vec();
        assert!(rising.windows(2).all(|w| w[1] > w[0]), "{rising:?}");
        assert!(entropy(1.0) >= rising[3]);
        assert!((entropy(2.0) - entropy(1.0)).abs() < 1e-9);
    }

    #[test]
    fn entropy_of_equal_cells_is_their_log() {
        // Points exactly on 8 cell centres (cell 1 m): each lands on one cell.
        let points: Vec<_> = (0..8).map(|i| Vector2::new(i as f64, 0.0)).collect();
        let s = sharpness(&points, 1.0).unwrap();
        assert!((s.entropy_bits - 3.0).abs() < 1e-9, "{}", s.entropy_bits);
        assert_eq!(s.occupied_cells, 8);
        assert_eq!(s.area_m2, 8.0);
    }

    #[test]
    fn lattices_stay_put_and_the_quadratic_kernel_splits_a_point_by_the_spline() {
        let mut grid = SplatGrid::default();
        let entropy = |grid: &mut SplatGrid, points: &[Vector2<f64>], kernel| {
            grid.fill_on_lattice(points, 0.5, Vector2::zeros(), kernel)
                .unwrap();
            grid.sharpness(points.len(), 0.5).entropy_bits
        };
        // A point on a node: (1/8, 3/4, 1/8) along each axis.
        let node = -2.0 * (0.25 * 0.125f64.log2() + 0.75 * 0.75f64.log2());
        let on_node = [Vector2::new(1.0, -2.0)];
        let h = entropy(&mut grid, &on_node, Kernel::QuadraticBSpline);
        assert!((h - node).abs() < 1e-6, "{h}");
        assert_eq!(grid.sharpness(1, 0.5).occupied_cells, 9);
        // Between nodes along x: (1/2, 1/2) there.
        let between = [Vector2::new(1.25, -2.0)];
        let h = entropy(&mut grid, &between, Kernel::QuadraticBSpline);
        assert!((h - (1.0 + 0.5 * node)).abs() < 1e-6, "{h}");
        // Bilinear on the same lattice: a node is one cell, between is two.
        assert!(entropy(&mut grid, &on_node, Kernel::Bilinear).abs() < 1e-6);
        let h = entropy(&mut grid, &between, Kernel::Bilinear);
        assert!((h - 1.0).abs() < 1e-6, "{h}");
    }

    #[test]
    fn bad_points_and_cells_are_errors() {
        assert!(sharpness(&[Vector2::new(f64::NAN, 0.0)], 0.5).is_err());
        assert!(sharpness(&[Vector2::zeros()], 0.0).is_err());
        let far = [Vector2::zeros(), Vector2::new(1e7, 0.0)];
        assert!(
            sharpness(&far, 0.5)
                .unwrap_err()
                .to_string()
                .contains("cells a side")
        );
        assert_eq!(sharpness(&[], 0.5).unwrap().occupied_cells, 0);
    }
}
