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

use crate::dead_reckoning::Navigation;
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

/// `returns` placed in the world along `nav` with `mounting` (module doc).
/// Returns outside the navigation's span are left out.
pub fn place_returns(
    returns: &[BeamReturn],
    nav: &Navigation,
    mounting: &SensorMounting,
) -> Vec<Vector2<f64>> {
    place_with(returns, mounting, |t| nav.pose_at(t).ok())
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

/// A reusable dense grid for [`sharpness`]; keeps its allocation between
/// calls (the calibration evaluates thousands of placements).
#[derive(Clone, Debug, Default)]
pub struct SplatGrid {
    weights: Vec<f32>,
}

impl SplatGrid {
    /// Splats `points` on a grid that covers them (one cell of margin).
    pub fn fill(&mut self, points: &[Vector2<f64>], cell_size_m: f64) -> Result<(), FrontendError> {
        self.weights.clear();
        let Some(first) = points.first() else {
            return Ok(());
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
        let width = ((hi.x - lo.x) / cell_size_m).floor() + 3.0;
        let height = ((hi.y - lo.y) / cell_size_m).floor() + 3.0;
        if width > MAX_CELLS_PER_SIDE || height > MAX_CELLS_PER_SIDE {
            return Err(FrontendError::input(
                "points",
                "x, y",
                format!(
                    "spread over {:.0} m x {:.0} m, more than {MAX_CELLS_PER_SIDE} cells a side",
                    hi.x - lo.x,
                    hi.y - lo.y
                ),
            ));
        }
        let (w, h) = (width as usize, height as usize);
        self.weights.resize(w * h, 0.0);
        for p in points {
            // Cell centre `i` at `lo + (i − 1) · cell`: one cell of margin.
            let u = (p.x - lo.x) / cell_size_m + 1.0;
            let v = (p.y - lo.y) / cell_size_m + 1.0;
            let (i, j) = (u.floor(), v.floor());
            let (fu, fv) = ((u - i) as f32, (v - j) as f32);
            let k = j as usize * w + i as usize;
            self.weights[k] += (1.0 - fu) * (1.0 - fv);
            self.weights[k + 1] += fu * (1.0 - fv);
            self.weights[k + w] += (1.0 - fu) * fv;
            self.weights[k + w + 1] += fu * fv;
        }
        Ok(())
    }

    /// The entropy and occupancy of the last [`fill`](Self::fill).
    pub fn sharpness(&self, points: usize, cell_size_m: f64) -> Sharpness {
        let total: f64 = self.weights.iter().map(|&w| f64::from(w)).sum();
        let mut entropy = 0.0;
        let mut occupied = 0;
        if total > 0.0 {
            for &w in &self.weights {
                if w > 0.0 {
                    occupied += 1;
                    let p = f64::from(w) / total;
                    entropy -= p * p.log2();
                }
            }
        }
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
