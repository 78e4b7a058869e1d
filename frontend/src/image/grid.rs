//! A regular grid of intensities with bilinear lookup.
//!
//! Cell `(ix, iy)` covers `[origin + ix·c, origin + (ix+1)·c) × [...)` and its
//! value sits at the cell centre. Row-major: `values[iy * width + ix]`.
//!
//! A [`Grid`] holds `f32` values and is what rasters are painted, smoothed
//! and blended in. An acoustic image lives for the whole mission (every
//! older image is a loop-closure target), so the raster it reads least,
//! the pose fit's, is kept as a [`QuantisedGrid`]: `u16` cells in steps of
//! `max / 65535`, half the memory of `f32` and a rounding error of at most
//! `max / 131070` (7.6·10⁻⁶ of the largest value), far below the
//! intensities' own resolution (8-bit echoes). Both read the same way
//! ([`Grid::bilinear`] and the rest are defined once for any
//! [`CellValue`]): a stored value `q` stands for `q · step`, and since
//! every lookup is linear in the cell values, the step multiplies the
//! interpolated result.

use nalgebra::Vector2;

/// Largest radius of [`Grid::add_bilinear_shifts`], in cells.
pub const MAX_SHIFT_RADIUS: usize = 3;

/// `x.floor()` without the library call `f64::floor` compiles to on the
/// x86-64 baseline (no SSE4.1 `roundsd`), which showed up in profiles of a
/// pipeline run (EXPERIMENTS.md § Speed notes): truncate, then step down for
/// negative non-integers.
/// Equal to `f64::floor` for every input, up to the sign of a zero result
/// (`-0.5` gives `-1`, `-0.0` gives `0.0`); NaN and infinities pass
/// through.
#[inline]
pub fn floor(x: f64) -> f64 {
    // From 2^52 on every f64 is an integer (and may not fit an i64).
    const INTEGRAL: f64 = 4_503_599_627_370_496.0;
    if x.abs() < INTEGRAL {
        let t = x as i64 as f64;
        if t > x { t - 1.0 } else { t }
    } else {
        x
    }
}

/// The storage of one cell of a [`Grid`].
pub trait CellValue: Copy + PartialEq + std::fmt::Debug + Send + Sync + 'static {
    /// The stored value as a number of steps ([`Grid::step`]).
    fn to_f32(self) -> f32;
}

impl CellValue for f32 {
    #[inline]
    fn to_f32(self) -> f32 {
        self
    }
}

impl CellValue for u16 {
    #[inline]
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
}

/// A grid of `u16` cells: the compact form of a finished raster
/// ([`Grid::quantised`]).
pub type QuantisedGrid = Grid<u16>;

#[derive(Clone, Debug, PartialEq)]
pub struct Grid<T: CellValue = f32> {
    origin_x_m: f64,
    origin_y_m: f64,
    cell_size_m: f64,
    width: usize,
    height: usize,
    values: Vec<T>,
    /// The value one stored unit stands for (1 for `f32` grids).
    step: f32,
}

impl Grid {
    /// A grid of zeros whose lower-left corner is `(origin_x_m, origin_y_m)`.
    pub fn zeros(
        origin_x_m: f64,
        origin_y_m: f64,
        cell_size_m: f64,
        width: usize,
        height: usize,
    ) -> Self {
        let values = vec![0.0; width * height];
        Self::from_values(origin_x_m, origin_y_m, cell_size_m, width, height, values)
    }

    /// A grid of the given cells (row-major, `width · height` of them),
    /// for rasters whose every cell is computed anyway: no zero-filling
    /// first.
    pub(crate) fn from_values(
        origin_x_m: f64,
        origin_y_m: f64,
        cell_size_m: f64,
        width: usize,
        height: usize,
        values: Vec<f32>,
    ) -> Self {
        assert_eq!(values.len(), width * height, "one value per cell");
        Self {
            origin_x_m,
            origin_y_m,
            cell_size_m,
            width,
            height,
            values,
            step: 1.0,
        }
    }

    pub fn values_mut(&mut self) -> &mut [f32] {
        &mut self.values
    }

    /// This grid with every cell rounded to the nearest multiple of
    /// `max / 65535`, `max` its largest value (see the module doc).
    /// Intensities are not negative: negative and NaN cells become 0.
    pub fn quantised(&self) -> QuantisedGrid {
        let max = max_value(&self.values);
        let (step, inverse) = if max > 0.0 && max.is_finite() {
            (max / f32::from(u16::MAX), f32::from(u16::MAX) / max)
        } else {
            (0.0, 0.0)
        };
        let values = self
            .values
            .iter()
            .map(|&v| {
                // `t > 0` is false for NaN and v ≤ 0.
                let t = v * inverse;
                let t = if t > 0.0 { t.min(65_535.0) } else { 0.0 };
                // Adding 2^23 rounds t to the nearest integer, which is then
                // the low bits of the mantissa (t < 2^16): a rounding
                // conversion without the checks of `as`, so the loop
                // vectorises.
                (t + 8_388_608.0).to_bits() as u16
            })
            .collect();
        Grid {
            origin_x_m: self.origin_x_m,
            origin_y_m: self.origin_y_m,
            cell_size_m: self.cell_size_m,
            width: self.width,
            height: self.height,
            values,
            step,
        }
    }
}

impl<T: CellValue> Grid<T> {
    pub fn origin_m(&self) -> (f64, f64) {
        (self.origin_x_m, self.origin_y_m)
    }

    pub fn cell_size_m(&self) -> f64 {
        self.cell_size_m
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// The stored cells, row-major; cell `k` holds the value
    /// `values()[k].to_f32() * step()`.
    pub fn values(&self) -> &[T] {
        &self.values
    }

    /// The value one stored unit stands for: 1 for a [`Grid`] of `f32`,
    /// `max / 65535` for a [`QuantisedGrid`].
    pub fn step(&self) -> f32 {
        self.step
    }

    /// Bytes of the cells on the heap.
    pub fn heap_bytes(&self) -> usize {
        self.values.capacity() * std::mem::size_of::<T>()
    }

    /// The value of cell `k` (row-major index).
    #[inline]
    pub fn value(&self, k: usize) -> f32 {
        self.values[k].to_f32() * self.step
    }

    /// The largest value (0 for an empty grid or one without positive
    /// values).
    pub fn max_value(&self) -> f32 {
        max_value(&self.values) * self.step
    }

    /// The value of cell `(ix, iy)`, 0 outside the grid.
    #[inline]
    pub fn cell(&self, ix: i64, iy: i64) -> f32 {
        self.stored(ix, iy) * self.step
    }

    /// The stored value of cell `(ix, iy)` in steps, 0 outside the grid.
    #[inline]
    fn stored(&self, ix: i64, iy: i64) -> f32 {
        if ix < 0 || iy < 0 || ix >= self.width as i64 || iy >= self.height as i64 {
            0.0
        } else {
            self.values[iy as usize * self.width + ix as usize].to_f32()
        }
    }

    /// The cell containing `(x, y)` (may lie outside the grid).
    #[inline]
    pub fn cell_of(&self, x_m: f64, y_m: f64) -> (i64, i64) {
        (
            floor((x_m - self.origin_x_m) / self.cell_size_m) as i64,
            floor((y_m - self.origin_y_m) / self.cell_size_m) as i64,
        )
    }

    /// The centre of cell `(ix, iy)`.
    pub fn cell_centre_m(&self, ix: i64, iy: i64) -> (f64, f64) {
        (
            self.origin_x_m + (ix as f64 + 0.5) * self.cell_size_m,
            self.origin_y_m + (iy as f64 + 0.5) * self.cell_size_m,
        )
    }

    /// True when `(x, y)` lies inside the grid's extent.
    pub fn contains(&self, x_m: f64, y_m: f64) -> bool {
        let (ix, iy) = self.cell_of(x_m, y_m);
        ix >= 0 && iy >= 0 && ix < self.width as i64 && iy < self.height as i64
    }

    /// Position in "cell-centre" coordinates: the integer lattice point
    /// `(i, j)` is the centre of cell `(i, j)`.
    #[inline]
    fn lattice(&self, x_m: f64, y_m: f64) -> (f64, f64) {
        (
            (x_m - self.origin_x_m) / self.cell_size_m - 0.5,
            (y_m - self.origin_y_m) / self.cell_size_m - 0.5,
        )
    }

    /// The four neighbouring stored values (in steps) and the fractional
    /// position.
    #[inline]
    fn corners(&self, x_m: f64, y_m: f64) -> Option<([f32; 4], f64, f64)> {
        let (gx, gy) = self.lattice(x_m, y_m);
        if !(gx > -1.0 && gy > -1.0 && gx < self.width as f64 && gy < self.height as f64) {
            return None; // also catches NaN
        }
        // gx, gy > -1 here, so truncating gx + 1 is floor(gx) + 1 (cheaper
        // than `floor`, which is a libm call on baseline x86-64).
        let (ix, iy) = ((gx + 1.0) as i64 - 1, (gy + 1.0) as i64 - 1);
        let (fx0, fy0) = (ix as f64, iy as f64);
        let interior =
            ix >= 0 && iy >= 0 && ix + 1 < self.width as i64 && iy + 1 < self.height as i64;
        let v = if interior {
            let k = iy as usize * self.width + ix as usize;
            [
                self.values[k].to_f32(),
                self.values[k + 1].to_f32(),
                self.values[k + self.width].to_f32(),
                self.values[k + self.width + 1].to_f32(),
            ]
        } else {
            [
                self.stored(ix, iy),
                self.stored(ix + 1, iy),
                self.stored(ix, iy + 1),
                self.stored(ix + 1, iy + 1),
            ]
        };
        Some((v, gx - fx0, gy - fy0))
    }

    /// Bilinear interpolation between cell centres; cells outside the grid
    /// count as 0, so the value fades to 0 over the last half cell.
    #[inline]
    pub fn bilinear(&self, x_m: f64, y_m: f64) -> f64 {
        match self.corners(x_m, y_m) {
            None => 0.0,
            Some(([v00, v10, v01, v11], fx, fy)) => {
                let bottom = f64::from(v00) + fx * f64::from(v10 - v00);
                let top = f64::from(v01) + fx * f64::from(v11 - v01);
                (bottom + fy * (top - bottom)) * f64::from(self.step)
            }
        }
    }

    /// Adds to `sums` the bilinear value ([`Grid::bilinear`]) at every
    /// point `(x + a·cell, y + b·cell)`, `a, b ∈ -r..=r`, in row-major order
    /// of `(b, a)` (`sums.len() == (2r + 1)²`). The shifts are whole cells,
    /// so all of them share the fractional position and read one
    /// `(2r + 2)²` patch of cells: far cheaper than `(2r + 1)²` separate
    /// lookups. `r` is at most [`MAX_SHIFT_RADIUS`].
    pub fn add_bilinear_shifts(&self, x_m: f64, y_m: f64, r: usize, sums: &mut [f64]) {
        assert_eq!(sums.len(), (2 * r + 1).pow(2), "one sum per shift");
        // A constant radius lets the compiler unroll the short loops.
        match r {
            0 => self.add_shifts::<0>(x_m, y_m, sums),
            1 => self.add_shifts::<1>(x_m, y_m, sums),
            2 => self.add_shifts::<2>(x_m, y_m, sums),
            3 => self.add_shifts::<3>(x_m, y_m, sums),
            _ => panic!("shift radius {r} > {MAX_SHIFT_RADIUS}"),
        }
    }

    fn add_shifts<const R: usize>(&self, x_m: f64, y_m: f64, sums: &mut [f64]) {
        let n = 2 * R + 1;
        let side = n + 1;
        let (gx, gy) = self.lattice(x_m, y_m);
        if !(gx.is_finite() && gy.is_finite()) {
            return;
        }
        let (fx0, fy0) = (floor(gx), floor(gy));
        let (fx, fy) = (gx - fx0, gy - fy0);
        let (ix, iy) = (fx0 as i64 - R as i64, fy0 as i64 - R as i64);
        let (w, h) = (self.width as i64, self.height as i64);
        if ix >= w || iy >= h || ix + side as i64 <= 0 || iy + side as i64 <= 0 {
            return;
        }
        // Interpolate along x first: `rows[dy][a]` is the value at the
        // fractional x of shift `a` on cell row `iy + dy`. Each of these
        // serves two shifts in y: 2n + 1 lerps per column of shifts
        // instead of 3n, each the same operation as in a lookup of one
        // shift, so the sums do not change.
        let interior = ix >= 0 && iy >= 0 && ix + side as i64 <= w && iy + side as i64 <= h;
        let mut rows = [0.0_f64; (MAX_SHIFT_RADIUS * 2 + 2) * (MAX_SHIFT_RADIUS * 2 + 1)];
        let mut row = [0.0_f64; MAX_SHIFT_RADIUS * 2 + 2];
        for dy in 0..side {
            if interior {
                let start = (iy as usize + dy) * self.width + ix as usize;
                for (v, &c) in row[..side]
                    .iter_mut()
                    .zip(&self.values[start..start + side])
                {
                    *v = f64::from(c.to_f32());
                }
            } else {
                for (dx, v) in row[..side].iter_mut().enumerate() {
                    *v = f64::from(self.stored(ix + dx as i64, iy + dy as i64));
                }
            }
            for a in 0..n {
                let (v0, v1) = (row[a], row[a + 1]);
                rows[dy * n + a] = v0 + fx * (v1 - v0);
            }
        }
        let step = f64::from(self.step);
        for (k, sum) in sums[..n * n].iter_mut().enumerate() {
            let (bottom, top) = (rows[k], rows[k + n]);
            *sum += (bottom + fy * (top - bottom)) * step;
        }
    }

    /// Bilinear value and its gradient in 1/m.
    #[inline]
    pub fn bilinear_with_gradient(&self, x_m: f64, y_m: f64) -> (f64, Vector2<f64>) {
        match self.corners(x_m, y_m) {
            None => (0.0, Vector2::zeros()),
            Some(([v00, v10, v01, v11], fx, fy)) => {
                let (v00, v10, v01, v11) = (
                    f64::from(v00),
                    f64::from(v10),
                    f64::from(v01),
                    f64::from(v11),
                );
                let bottom = v00 + fx * (v10 - v00);
                let top = v01 + fx * (v11 - v01);
                let step = f64::from(self.step);
                let value = (bottom + fy * (top - bottom)) * step;
                let d_dx = ((1.0 - fy) * (v10 - v00) + fy * (v11 - v01)) * step / self.cell_size_m;
                let d_dy = (top - bottom) * step / self.cell_size_m;
                (value, Vector2::new(d_dx, d_dy))
            }
        }
    }
}

/// Above this many binomial passes (`σ` = 4 cells), [`Grid::smooth_gaussian`]
/// uses three box filters instead, whose cost does not depend on `σ` (and
/// which approximate the Gaussian less well for small `σ`).
const MAX_BINOMIAL_PASSES: f64 = 32.0;

impl Grid {
    /// Smoothing that approximates a Gaussian of standard deviation
    /// `sigma_cells`. Up to `σ` = 4 cells: `n = round(2σ²)` (at least 1)
    /// separable passes of the binomial filter `[1 2 1] / 4`, whose
    /// variance is 1/2 cell² per pass. Beyond: three separable box filters
    /// of odd widths chosen so that their variances add up to `σ²` (the
    /// sum of three boxes is close to a Gaussian, and each box costs two
    /// additions per cell whatever its width), so the cost is bounded by
    /// 32 binomial passes for any `σ` (issue 35: 2σ² passes made
    /// `image.smoothing_sigma_m = 100` run for minutes). Cells outside the
    /// grid count as 0. A NaN or non-positive `σ` leaves the grid as is.
    pub fn smooth_gaussian(&mut self, sigma_cells: f64) {
        if sigma_cells.is_nan() || sigma_cells <= 0.0 || self.values.is_empty() {
            return;
        }
        let variance = sigma_cells * sigma_cells;
        if 2.0 * variance > MAX_BINOMIAL_PASSES {
            for radius in box_radii(variance) {
                self.box_filter(radius);
            }
            return;
        }
        let passes = ((2.0 * variance).round() as usize).max(1);
        let (w, h) = (self.width, self.height);
        let mut tmp = vec![0.0_f32; w * h];
        for _ in 0..passes {
            // Along x, row by row.
            for (src, dst) in self.values.chunks_exact(w).zip(tmp.chunks_exact_mut(w)) {
                binomial_row(src, dst);
            }
            // Along y: whole rows at a time, so the inner loops vectorise.
            for y in 0..h {
                let dst = &mut self.values[y * w..(y + 1) * w];
                let centre = &tmp[y * w..(y + 1) * w];
                for (d, c) in dst.iter_mut().zip(centre) {
                    *d = 0.5 * c;
                }
                for ny in [y.wrapping_sub(1), y + 1] {
                    if ny < h {
                        let side = &tmp[ny * w..(ny + 1) * w];
                        for (d, s) in dst.iter_mut().zip(side) {
                            *d += 0.25 * s;
                        }
                    }
                }
            }
        }
    }
}

impl Grid {
    /// A separable box filter of width `2·radius + 1` cells (zero outside
    /// the grid), by running sums in `f64` along x and then y.
    fn box_filter(&mut self, radius: usize) {
        let (w, h) = (self.width, self.height);
        let norm = 1.0 / (2.0 * radius as f64 + 1.0);
        let mut prefix = vec![0.0_f64; w.max(h) + 1];
        for row in self.values.chunks_exact_mut(w) {
            for (x, v) in row.iter().enumerate() {
                prefix[x + 1] = prefix[x] + f64::from(*v);
            }
            for (x, v) in row.iter_mut().enumerate() {
                let (lo, hi) = (
                    x.saturating_sub(radius),
                    (x.saturating_add(radius) + 1).min(w),
                );
                *v = ((prefix[hi] - prefix[lo]) * norm) as f32;
            }
        }
        // Along y: prefix sums of whole rows.
        let mut rows = vec![0.0_f64; (h + 1) * w];
        for y in 0..h {
            let (done, next) = rows.split_at_mut((y + 1) * w);
            let previous = &done[y * w..];
            for ((p, q), v) in next[..w]
                .iter_mut()
                .zip(previous)
                .zip(&self.values[y * w..(y + 1) * w])
            {
                *p = q + f64::from(*v);
            }
        }
        for y in 0..h {
            let (lo, hi) = (
                y.saturating_sub(radius),
                (y.saturating_add(radius) + 1).min(h),
            );
            let (top, bottom) = (&rows[hi * w..(hi + 1) * w], &rows[lo * w..(lo + 1) * w]);
            for ((v, t), b) in self.values[y * w..(y + 1) * w]
                .iter_mut()
                .zip(top)
                .zip(bottom)
            {
                *v = ((t - b) * norm) as f32;
            }
        }
    }
}

/// The radii of three box filters whose variances `((2r + 1)² − 1) / 12`
/// add up to about `variance` (cells²): `m` boxes of the largest odd width
/// `wl` at most the ideal one and `3 − m` of width `wl + 2`, `m` chosen to
/// match the variance (the widths of Kovesi, "Fast almost-Gaussian
/// filtering", 2010).
fn box_radii(variance: f64) -> [usize; 3] {
    let ideal = (4.0 * variance + 1.0).sqrt();
    let mut lower = ideal.floor();
    if lower % 2.0 == 0.0 {
        lower -= 1.0;
    }
    let lower = lower.max(1.0);
    let m = ((12.0 * variance - 3.0 * lower * lower - 12.0 * lower - 9.0) / (-4.0 * lower - 4.0))
        .round()
        .clamp(0.0, 3.0) as usize;
    let radius = |width: f64| ((width - 1.0) / 2.0) as usize;
    std::array::from_fn(|i| {
        if i < m {
            radius(lower)
        } else {
            radius(lower + 2.0)
        }
    })
}

/// The largest of `values` as `f32`, at least 0 (NaN is ignored). Eight
/// lanes of running maxima, so the loop vectorises (`f32::max` over one
/// accumulator is a serial chain).
pub fn max_value<T: CellValue>(values: &[T]) -> f32 {
    let mut lanes = [0.0_f32; 8];
    let chunks = values.chunks_exact(8);
    let rest = chunks.remainder();
    for chunk in chunks {
        for (m, &v) in lanes.iter_mut().zip(chunk) {
            // `v > m` is false for NaN: NaN never enters.
            let v = v.to_f32();
            *m = if v > *m { v } else { *m };
        }
    }
    let mut max = rest.iter().fold(0.0_f32, |m, &v| {
        let v = v.to_f32();
        if v > m { v } else { m }
    });
    for m in lanes {
        max = if m > max { m } else { max };
    }
    max
}

/// `dst[x] = (src[x-1] + 2·src[x] + src[x+1]) / 4`, zero outside.
fn binomial_row(src: &[f32], dst: &mut [f32]) {
    let n = src.len();
    if n == 1 {
        dst[0] = 0.5 * src[0];
        return;
    }
    dst[0] = 0.5 * src[0] + 0.25 * src[1];
    dst[n - 1] = 0.5 * src[n - 1] + 0.25 * src[n - 2];
    for (((d, l), c), r) in dst[1..n - 1]
        .iter_mut()
        .zip(&src[..n - 2])
        .zip(&src[1..n - 1])
        .zip(&src[2..])
    {
        *d = 0.25 * (l + r) + 0.5 * c;
    }
}

#[cfg(test)]
mod tests {

    #[test]
    fn floor_equals_the_library_floor() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut values = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            1.0 - 1e-16,
            -1.0 + 1e-16,
            2.5e15,
            -2.5e15,
            4_503_599_627_370_495.5,
            -4_503_599_627_370_495.5,
            9.1e18,
            -9.3e18,
            1e300,
            -1e300,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        values.extend((0..10_000).map(|_| rng.random_range(-1e4..1e4)));
        values.extend((0..1_000).map(|_| f64::from(rng.random_range(-50..50)) * 0.2));
        for x in values {
            assert_eq!(floor(x), x.floor(), "{x}");
        }
        assert!(floor(f64::NAN).is_nan());
    }

    use super::*;

    #[test]
    fn bilinear_shifts_equal_separate_lookups_inside_and_at_the_edges() {
        let g = ramp();
        let cell = g.cell_size_m();
        // Points inside, near every edge, beyond the grid and NaN.
        let points = [
            (0.3, 3.1),
            (-0.9, 2.05),
            (1.9, 4.4),
            (-2.2, 1.0),
            (4.0, 6.5),
            (0.71, 2.6),
            (f64::NAN, 3.0),
        ];
        for r in 1..=MAX_SHIFT_RADIUS {
            let n = 2 * r + 1;
            for &(x, y) in &points {
                let mut sums = vec![0.5; n * n];
                g.add_bilinear_shifts(x, y, r, &mut sums);
                for b in 0..n {
                    for a in 0..n {
                        let (dx, dy) = ((a as f64 - r as f64) * cell, (b as f64 - r as f64) * cell);
                        let expected = 0.5 + g.bilinear(x + dx, y + dy);
                        let got = sums[b * n + a];
                        assert!(
                            (got - expected).abs() < 1e-9,
                            "r {r} at ({x}, {y}) shift ({a}, {b}): {got} vs {expected}"
                        );
                    }
                }
            }
        }
    }

    fn ramp() -> Grid {
        // v = 2·ix + 3·iy at cell centres.
        let mut g = Grid::zeros(-1.0, 2.0, 0.5, 6, 5);
        for iy in 0..5 {
            for ix in 0..6 {
                g.values_mut()[iy * 6 + ix] = (2 * ix + 3 * iy) as f32;
            }
        }
        g
    }

    #[test]
    fn bilinear_reproduces_a_linear_field_inside() {
        let g = ramp();
        // Cell (2, 1) centre: (-1 + 2.5·0.5, 2 + 1.5·0.5) = (0.25, 2.75), value 7.
        assert!((g.bilinear(0.25, 2.75) - 7.0).abs() < 1e-6);
        // A quarter cell to the right: +0.5 (2 per cell).
        assert!((g.bilinear(0.375, 2.75) - 7.5).abs() < 1e-6);
        let (v, grad) = g.bilinear_with_gradient(0.4, 3.1);
        assert!((v - g.bilinear(0.4, 3.1)).abs() < 1e-12);
        // 2 per cell of 0.5 m = 4 /m in x, 6 /m in y.
        assert!((grad.x - 4.0).abs() < 1e-6 && (grad.y - 6.0).abs() < 1e-6);
    }

    #[test]
    fn outside_is_zero_and_nan_is_zero() {
        let g = ramp();
        assert_eq!(g.bilinear(-5.0, 3.0), 0.0);
        assert_eq!(g.bilinear(0.0, 100.0), 0.0);
        assert_eq!(g.bilinear(f64::NAN, 3.0), 0.0);
        assert_eq!(g.bilinear_with_gradient(f64::INFINITY, 3.0).0, 0.0);
        assert!(!g.contains(-1.01, 2.1));
        assert!(g.contains(-0.99, 2.01));
    }

    #[test]
    fn gradient_matches_central_differences_off_cell_edges() {
        let mut g = Grid::zeros(0.0, 0.0, 0.2, 8, 8);
        for (k, v) in g.values_mut().iter_mut().enumerate() {
            *v = ((k * 37) % 11) as f32 / 11.0;
        }
        for &(x, y) in &[(0.33, 0.47), (1.01, 0.71), (0.55, 1.29)] {
            let (_, grad) = g.bilinear_with_gradient(x, y);
            let h = 1e-6;
            let dx = (g.bilinear(x + h, y) - g.bilinear(x - h, y)) / (2.0 * h);
            let dy = (g.bilinear(x, y + h) - g.bilinear(x, y - h)) / (2.0 * h);
            assert!((grad.x - dx).abs() < 1e-6, "{} vs {dx}", grad.x);
            assert!((grad.y - dy).abs() < 1e-6, "{} vs {dy}", grad.y);
        }
    }

    #[test]
    fn a_quantised_grid_reads_like_its_source_within_half_a_step() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut g = Grid::zeros(-1.0, 2.0, 0.2, 40, 30);
        for v in g.values_mut() {
            *v = rng.random_range(0.0..0.9);
        }
        g.values_mut()[17] = 0.9;
        let q = g.quantised();
        assert_eq!((q.width(), q.height(), q.origin_m()), (40, 30, (-1.0, 2.0)));
        assert!((q.max_value() - 0.9).abs() < 1e-6);
        // Half a step, and the f32 rounding of a value near the maximum.
        let half_step = 0.5 * f64::from(q.step()) + 0.9 * f64::from(f32::EPSILON);
        assert!(q.step() < 0.9 / 65_000.0);
        for k in 0..g.values().len() {
            assert!((f64::from(q.value(k)) - f64::from(g.value(k))).abs() <= half_step);
        }
        for _ in 0..500 {
            let (x, y) = (rng.random_range(-2.0..8.0), rng.random_range(1.0..9.0));
            // Bilinear weights sum to at most 1: the error stays within half a step.
            assert!((q.bilinear(x, y) - g.bilinear(x, y)).abs() <= half_step);
            let (_, gq) = q.bilinear_with_gradient(x, y);
            let (_, gg) = g.bilinear_with_gradient(x, y);
            // Differences of two cells over one cell size.
            assert!((gq - gg).amax() <= 2.0 * half_step / 0.2);
            let (mut a, mut b) = (vec![0.0; 25], vec![0.0; 25]);
            q.add_bilinear_shifts(x, y, 2, &mut a);
            g.add_bilinear_shifts(x, y, 2, &mut b);
            for (a, b) in a.iter().zip(&b) {
                assert!((a - b).abs() <= half_step);
            }
        }
    }

    #[test]
    fn quantising_keeps_zeros_and_drops_what_is_not_an_intensity() {
        let mut g = Grid::zeros(0.0, 0.0, 1.0, 4, 1);
        g.values_mut().copy_from_slice(&[-1.0, f32::NAN, 0.0, 2.0]);
        let q = g.quantised();
        assert_eq!(q.values(), &[0, 0, 0, u16::MAX]);
        assert_eq!(q.value(3), 2.0);
        let empty = Grid::zeros(0.0, 0.0, 1.0, 3, 3).quantised();
        assert_eq!((empty.step(), empty.max_value()), (0.0, 0.0));
        assert_eq!(empty.bilinear(1.2, 1.7), 0.0);
    }

    #[test]
    fn wide_smoothing_is_three_boxes_of_the_gaussians_variance() {
        for sigma in [4.1_f64, 7.3, 15.0] {
            let n = 201;
            let mut g = Grid::zeros(0.0, 0.0, 1.0, n, n);
            let c = (n / 2) as i64;
            g.values_mut()[(c as usize) * n + c as usize] = 1.0;
            g.smooth_gaussian(sigma);
            let sum: f64 = g.values().iter().map(|v| f64::from(*v)).sum();
            assert!((sum - 1.0).abs() < 1e-4, "σ {sigma}: mass {sum}");
            assert!((g.cell(c - 3, c) - g.cell(c + 3, c)).abs() < 1e-7);
            assert!((g.cell(c, c - 2) - g.cell(c - 2, c)).abs() < 1e-7);
            let var: f64 = (0..n as i64)
                .map(|x| {
                    let col: f64 = (0..n as i64).map(|y| f64::from(g.cell(x, y))).sum();
                    col * ((x - c) * (x - c)) as f64
                })
                .sum();
            // Kovesi's widths match σ² to within a few percent.
            assert!(
                (var - sigma * sigma).abs() < 0.08 * sigma * sigma,
                "σ {sigma}: variance {var}"
            );
            // Near the Gaussian's peak 1 / (2πσ²): three boxes have a
            // flatter top, about 6% lower per axis.
            let peak = 1.0 / (2.0 * std::f64::consts::PI * sigma * sigma);
            let got = f64::from(g.cell(c, c));
            assert!(
                (got - peak).abs() < 0.2 * peak,
                "σ {sigma}: {got} vs {peak}"
            );
        }
        // A σ far beyond the grid spreads the mass thinly and ends.
        let mut g = Grid::zeros(0.0, 0.0, 1.0, 9, 9);
        g.values_mut()[40] = 1.0;
        g.smooth_gaussian(1e9);
        assert!(
            g.values()
                .iter()
                .all(|v| v.is_finite() && *v >= 0.0 && *v < 1e-8)
        );
    }

    #[test]
    fn smoothing_keeps_mass_and_spreads_a_spike_like_a_gaussian() {
        let mut g = Grid::zeros(0.0, 0.0, 1.0, 31, 31);
        g.values_mut()[15 * 31 + 15] = 1.0;
        // σ = 1.5 cells: 2σ² = 4.5 rounds to 5 passes (variance 2.5 cells²
        // per axis).
        g.smooth_gaussian(1.5);
        let sum: f32 = g.values().iter().sum();
        assert!((sum - 1.0).abs() < 1e-5);
        assert!((g.cell(14, 15) - g.cell(16, 15)).abs() < 1e-7);
        assert!((g.cell(15, 13) - g.cell(13, 15)).abs() < 1e-7);
        // Per axis the result is the binomial C(10, 5 + k) / 2^10.
        let b = |k: i64| {
            let n = 10u64;
            let r = (5 + k) as u64;
            let mut c = 1u64;
            for i in 0..r {
                c = c * (n - i) / (i + 1);
            }
            c as f32 / 1024.0
        };
        for (dx, dy) in [(0, 0), (1, 0), (2, 1), (3, 3)] {
            let expected = b(dx) * b(dy);
            let got = g.cell(15 + dx, 15 + dy);
            assert!(
                (got - expected).abs() < 1e-6,
                "({dx}, {dy}): {got} vs {expected}"
            );
        }
        // Variance per axis 2.5 cells², close to σ² = 2.25.
        let var: f32 = (0..31)
            .map(|x| {
                let col: f32 = (0..31).map(|y| g.cell(x, y)).sum();
                col * ((x - 15) * (x - 15)) as f32
            })
            .sum();
        assert!((var - 2.5).abs() < 1e-4, "{var}");
    }
}
