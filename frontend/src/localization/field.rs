//! The prior map as one likelihood field `I(x)` over the map's world frame,
//! and the score of eq. (5) of a scan placed on it.
//!
//! The field is a raster of normalised intensities (0-1) in the map's world
//! frame, e.g. the acoustic images `I_j` of the map's nodes placed at their
//! optimised poses and blended by max, smoothed by a Gaussian and divided
//! by a high quantile of its covered cells (clamped to 1), so that the
//! scale of the score does not depend on how bright one map was.
//!
//! It may hold a second raster over the same cells, the field the
//! estimate is *refined* on ([`LikelihoodField::with_refine_raster`]),
//! e.g. the node images blended by their mean where the field the
//! particles are weighed and judged on takes their max: the particles
//! (which place does the scan fit, and does it fit at all?) and the
//! estimate (where exactly in that place?) then come from the blend that
//! suits each. Without it, one raster serves both.
//!
//! Beside the values it keeps the *coverage*: the cells within the
//! footprint of some map node, where the map's sonar looked. A scan point
//! outside the coverage is neither evidence for nor against a pose (the
//! likelihood-field model's "unknown" space) and scores a constant;
//! the share of a scan's points inside the coverage says how much of the
//! map the sonar still sees.

use crate::error::FrontendError;
use crate::image::Grid;
use echofield_graph::Se2;
use nalgebra::Point2;

/// Quantile of the covered cells' positive values that maps to 1.
const NORMALISING_QUANTILE: f64 = 0.99;

/// The score of one scan at one pose on a [`LikelihoodField`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldScore {
    /// Mean over the points of `I(x ⊕ p_i)` inside the coverage and of the
    /// unknown value outside it: eq. (5) divided by the number of points.
    pub mean: f64,
    /// Mean of `I(x ⊕ p_i)` over the points inside the coverage (0 when
    /// none is): how well the part of the scan that sees the map fits it.
    pub fit: f64,
    /// Fraction of the points inside the coverage, 0-1.
    pub coverage: f64,
}

/// The map's likelihood field (see the module doc).
#[derive(Clone, Debug)]
pub struct LikelihoodField {
    /// The field the particles are weighed and the scans' fit judged on
    /// ([`Self::score`]).
    values: Grid,
    /// The field the estimate is refined on ([`Self::refine_score`]), when
    /// it differs from `values`: the same raster geometry, smoothed and
    /// normalised the same way.
    refine: Option<Grid>,
    covered: Vec<bool>,
    /// Indices of the covered cells, row-major, for sampling poses over
    /// the whole map.
    covered_cells: Vec<u32>,
}

impl LikelihoodField {
    /// The field of `map` (intensities 0-1 in the map's world frame)
    /// smoothed by a Gaussian of `smoothing_m`, covered within
    /// `footprints` (`(world_from_node, radius_m)`: the discs the map's
    /// nodes saw).
    ///
    /// Errors: an empty grid, or no cell inside any footprint (a map that
    /// saw nothing cannot localise anything).
    pub fn new(
        mut map: Grid,
        footprints: &[(Se2, f64)],
        smoothing_m: f64,
    ) -> Result<Self, FrontendError> {
        if map.width() == 0 || map.height() == 0 {
            return Err(FrontendError::input(
                "map",
                "acoustic images",
                "the map's likelihood field is empty",
            ));
        }
        if map.width() * map.height() > u32::MAX as usize {
            return Err(FrontendError::input(
                "map",
                "acoustic images",
                "the map's likelihood field has more than 2^32 cells: use a larger cell",
            ));
        }
        map.smooth_gaussian(smoothing_m / map.cell_size_m());
        let covered = coverage(&map, footprints);
        let covered_cells: Vec<u32> = covered
            .iter()
            .enumerate()
            .filter(|(_, c)| **c)
            .map(|(k, _)| k as u32)
            .collect();
        if covered_cells.is_empty() {
            return Err(FrontendError::input(
                "map",
                "node footprints",
                "no cell of the map lies within the footprint of a map node",
            ));
        }
        normalise(&mut map, &covered);
        Ok(Self {
            values: map,
            refine: None,
            covered,
            covered_cells,
        })
    }

    /// The same field with `map` as the raster the estimate is refined on
    /// ([`Self::refine_score`]), smoothed by `smoothing_m` and normalised
    /// over the same coverage as the particles' one.
    ///
    /// Errors: `map` not on the particles' raster (origin, cell size,
    /// width and height).
    pub fn with_refine_raster(
        mut self,
        mut map: Grid,
        smoothing_m: f64,
    ) -> Result<Self, FrontendError> {
        let same_raster = map.origin_m() == self.values.origin_m()
            && map.cell_size_m() == self.values.cell_size_m()
            && map.width() == self.values.width()
            && map.height() == self.values.height();
        if !same_raster {
            return Err(FrontendError::input(
                "map",
                "acoustic images",
                "the refine raster differs from the particles' raster",
            ));
        }
        map.smooth_gaussian(smoothing_m / map.cell_size_m());
        normalise(&mut map, &self.covered);
        self.refine = Some(map);
        Ok(self)
    }

    /// The values the particles are weighed on (0-1), world frame.
    pub fn grid(&self) -> &Grid {
        &self.values
    }

    /// The values the estimate is refined on (0-1, world frame): the
    /// refine raster when there is one, else [`Self::grid`].
    pub fn refine_grid(&self) -> &Grid {
        self.refine.as_ref().unwrap_or(&self.values)
    }

    /// Whether the cell `(ix, iy)` lies in the map's coverage.
    pub fn is_covered_cell(&self, ix: i64, iy: i64) -> bool {
        let (w, h) = (self.values.width() as i64, self.values.height() as i64);
        ix >= 0 && iy >= 0 && ix < w && iy < h && self.covered[(iy * w + ix) as usize]
    }

    /// The covered cells (row-major indices).
    pub fn covered_cells(&self) -> &[u32] {
        &self.covered_cells
    }

    /// Covered area, m².
    pub fn covered_area_m2(&self) -> f64 {
        let c = self.values.cell_size_m();
        self.covered_cells.len() as f64 * c * c
    }

    /// Eq. (5) of `points` (vehicle frame) placed by `world_from_vehicle`
    /// on the particles' field, with `unknown` for the points outside the
    /// coverage. Every `stride`-th point (at least 1).
    pub fn score(
        &self,
        world_from_vehicle: &Se2,
        points: &[Point2<f64>],
        stride: usize,
        unknown: f64,
    ) -> FieldScore {
        self.score_on(&self.values, world_from_vehicle, points, stride, unknown)
    }

    /// [`Self::score`] on the field the estimate is refined on
    /// ([`Self::refine_grid`]).
    pub fn refine_score(
        &self,
        world_from_vehicle: &Se2,
        points: &[Point2<f64>],
        stride: usize,
        unknown: f64,
    ) -> FieldScore {
        let grid = self.refine_grid();
        self.score_on(grid, world_from_vehicle, points, stride, unknown)
    }

    /// Eq. (5) on `grid` (the particles' or the refine raster).
    fn score_on(
        &self,
        grid: &Grid,
        world_from_vehicle: &Se2,
        points: &[Point2<f64>],
        stride: usize,
        unknown: f64,
    ) -> FieldScore {
        let (s, c) = world_from_vehicle.theta().sin_cos();
        let (tx, ty) = (world_from_vehicle.x(), world_from_vehicle.y());
        let (mut inside, mut total, mut sum_inside) = (0usize, 0usize, 0.0);
        for p in points.iter().step_by(stride.max(1)) {
            let x = tx + c * p.x - s * p.y;
            let y = ty + s * p.x + c * p.y;
            total += 1;
            let (ix, iy) = grid.cell_of(x, y);
            if self.is_covered_cell(ix, iy) {
                inside += 1;
                sum_inside += grid.bilinear(x, y);
            }
        }
        if total == 0 {
            return FieldScore {
                mean: unknown,
                fit: 0.0,
                coverage: 0.0,
            };
        }
        let outside = (total - inside) as f64;
        FieldScore {
            mean: (sum_inside + outside * unknown) / total as f64,
            fit: if inside > 0 {
                sum_inside / inside as f64
            } else {
                0.0
            },
            coverage: inside as f64 / total as f64,
        }
    }
}

/// The cells of `grid` whose centre lies within one of `footprints`.
fn coverage(grid: &Grid, footprints: &[(Se2, f64)]) -> Vec<bool> {
    let (w, h) = (grid.width() as i64, grid.height() as i64);
    let mut covered = vec![false; grid.width() * grid.height()];
    for (pose, radius_m) in footprints {
        if !(pose.is_finite() && radius_m.is_finite() && *radius_m > 0.0) {
            continue;
        }
        let (x0, y0) = grid.cell_of(pose.x() - radius_m, pose.y() - radius_m);
        let (x1, y1) = grid.cell_of(pose.x() + radius_m, pose.y() + radius_m);
        let r2 = radius_m * radius_m;
        for iy in y0.max(0)..=y1.min(h - 1) {
            for ix in x0.max(0)..=x1.min(w - 1) {
                let (cx, cy) = grid.cell_centre_m(ix, iy);
                let (dx, dy) = (cx - pose.x(), cy - pose.y());
                if dx * dx + dy * dy <= r2 {
                    covered[(iy * w + ix) as usize] = true;
                }
            }
        }
    }
    covered
}

/// Divides the values by the [`NORMALISING_QUANTILE`] of the covered
/// positive cells and clamps them to 1; a map without any echo is left
/// as it is (all zero).
fn normalise(grid: &mut Grid, covered: &[bool]) {
    let mut positive: Vec<f32> = grid
        .values()
        .iter()
        .zip(covered)
        .filter(|(v, c)| **c && **v > 0.0)
        .map(|(v, _)| *v)
        .collect();
    if positive.is_empty() {
        return;
    }
    let k = ((positive.len() - 1) as f64 * NORMALISING_QUANTILE).round() as usize;
    let (_, scale, _) = positive.select_nth_unstable_by(k, f32::total_cmp);
    let scale = *scale;
    if scale > 0.0 {
        for v in grid.values_mut() {
            *v = (*v / scale).min(1.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 20 m x 20 m field with one bright wall along x = 5 m.
    fn wall_field() -> LikelihoodField {
        let mut grid = Grid::zeros(-10.0, -10.0, 0.25, 80, 80);
        let w = grid.width();
        for iy in 0..80 {
            grid.values_mut()[iy * w + 60] = 1.0; // x in [5, 5.25)
        }
        LikelihoodField::new(grid, &[(Se2::identity(), 8.0)], 0.0).unwrap()
    }

    #[test]
    fn a_scan_on_the_wall_fits_and_a_shifted_one_does_not() {
        let field = wall_field();
        let points: Vec<Point2<f64>> = (-4..=4).map(|i| Point2::new(5.125, f64::from(i))).collect();
        let on = field.score(&Se2::identity(), &points, 1, 0.1);
        assert!((on.fit - 1.0).abs() < 1e-9, "{on:?}");
        assert_eq!(on.coverage, 1.0);
        let off = field.score(&Se2::new(-2.0, 0.0, 0.0), &points, 1, 0.1);
        assert!(off.fit < 1e-9, "{off:?}");
        // Moved 20 m away: outside the coverage, every point is unknown.
        let away = field.score(&Se2::new(0.0, 20.0, 0.0), &points, 1, 0.1);
        assert_eq!(away.coverage, 0.0);
        assert!((away.mean - 0.1).abs() < 1e-12);
    }

    #[test]
    fn coverage_is_the_union_of_the_footprints() {
        let field = wall_field();
        // Radius 8 m disc around the origin in 0.25 m cells: about π·64 m².
        let area = field.covered_area_m2();
        assert!((area - std::f64::consts::PI * 64.0).abs() < 2.0, "{area}");
        assert!(field.is_covered_cell(40, 40));
        assert!(!field.is_covered_cell(0, 0));
    }

    #[test]
    fn the_refine_score_reads_the_refine_raster_and_the_score_the_other() {
        // The particles' field: the wall at x = 5 m; the refine raster: a
        // wall at x = 3 m.
        let mut other = Grid::zeros(-10.0, -10.0, 0.25, 80, 80);
        let w = other.width();
        for iy in 0..80 {
            other.values_mut()[iy * w + 52] = 0.5; // x in [3, 3.25)
        }
        let field = wall_field().with_refine_raster(other, 0.0).unwrap();
        let points: Vec<Point2<f64>> = (-4..=4).map(|i| Point2::new(5.125, f64::from(i))).collect();
        let at_5 = Se2::identity();
        let at_3 = Se2::new(-2.0, 0.0, 0.0);
        assert!((field.score(&at_5, &points, 1, 0.1).fit - 1.0).abs() < 1e-9);
        assert!(field.score(&at_3, &points, 1, 0.1).fit < 1e-9);
        // Normalised over the coverage like the other: 0.5 maps to 1.
        assert!((field.refine_score(&at_3, &points, 1, 0.1).fit - 1.0).abs() < 1e-9);
        assert!(field.refine_score(&at_5, &points, 1, 0.1).fit < 1e-9);
        // Without a refine raster, both scores read the one field.
        let one = wall_field();
        assert_eq!(
            one.refine_score(&at_5, &points, 1, 0.1),
            one.score(&at_5, &points, 1, 0.1)
        );
    }

    #[test]
    fn a_refine_raster_of_another_geometry_is_an_error() {
        let other = Grid::zeros(-10.0, -10.0, 0.25, 79, 80);
        let err = wall_field()
            .with_refine_raster(other, 0.0)
            .unwrap_err()
            .to_string();
        assert!(err.contains("raster"), "{err}");
    }

    #[test]
    fn a_map_without_coverage_is_an_error() {
        let grid = Grid::zeros(0.0, 0.0, 1.0, 4, 4);
        let err = LikelihoodField::new(grid, &[(Se2::new(100.0, 0.0, 0.0), 1.0)], 0.0)
            .unwrap_err()
            .to_string();
        assert!(err.contains("footprint"), "{err}");
    }
}
