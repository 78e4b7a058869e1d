//! Sliding-window maxima of an image for branch-and-bound (the
//! "precomputation grids" of Cartographer's fast correlative scan matcher,
//! widened by one cell for the bilinear lookup).
//!
//! The maxima of level `h ≥ 1` are, per raster cell, `L_h(x, y)`: the
//! maximum of the raster over the `(2^h + 1) × (2^h + 1)` cells
//! `[x, x + 2^h] × [y, y + 2^h]` (cells outside the grid count as 0). A
//! point at raster cell `c` read with bilinear interpolation at any of
//! the `2^h × 2^h` translations `d0 + [0, 2^h)` only touches cells in
//! `c + d0 + [0, 2^h]`, so `Σ_i L_h(c_i + d0)` bounds the score of the
//! whole block from above, and no more loosely than the block requires.
//! For a block starting left of (or below) the grid, the window of cell 0
//! contains every cell the block can read inside the grid, so
//! `L_h(max(x, 0))` still bounds it; blocks wholly outside the grid read 0.
//!
//! Levels 1 and 2 store `L_h` for every cell. Level `h > 2` stores one
//! value per block of `s × s` cells, `s = 2^(h-2)` ([`stride`]): the
//! maximum of `L_h` over the block, read for every cell of it. That bounds
//! the window widened to whole strides (`2^h + s` cells per axis instead
//! of `2^h + 1`), a looser bound only where the search starts, over wide
//! windows, and a quarter of the bytes per level up. An image then holds
//! about 8.3 bytes per cell instead of 11 (`f32` raster, `u16` pose-fit
//! raster, levels 1-5: 1 + 1 + 1/4 + 1/16 + 1/64), with the same
//! matches, bit for bit (memory and time measured: EXPERIMENTS.md § Speed
//! notes).
//!
//! Values are stored as `u8`, rounded up on a scale that maps the raster's
//! largest value to 255, so the bound stays an upper bound (to within the
//! scale's rounding, which is upwards). `L_h` is the maximum of `L_(h-1)`
//! at two cells `2^(h-1)` apart per axis; level 1 is built from the raster
//! with three cells, level 2 from level 1 at full resolution, and each
//! pooled level from the pooled values of the one below, without going
//! back to full resolution (`PyramidLevel::coarsened`: the same values,
//! for one pass over the level below, a quarter of the raster or less from
//! level 4 on, instead of two passes over the whole raster).
//!
//! Levels up to [`EAGER_LEVELS`] are built with the pyramid; the higher
//! ones, which only searches over windows wider than `2^EAGER_LEVELS`
//! cells use (first contacts with a place seen long ago), on first use.
//! On the St Pere replay 13 of 217 images need level 6.

use super::grid::{Grid, max_value};
use std::sync::OnceLock;

/// Levels built with the pyramid; the rest are built when first read.
/// Five levels bound blocks of 32 × 32 translations: windows up to ±15
/// cells (±3 m at 0.2 m cells, the sequential matches' largest) start
/// their search there.
pub const EAGER_LEVELS: usize = 5;

#[derive(Clone, Debug, PartialEq)]
pub struct PyramidLevel {
    /// The raster's cells per row and column.
    width: usize,
    height: usize,
    /// `2^h`: the window spans `block + 1` cells per axis.
    block: usize,
    /// Cells per stored value and axis ([`stride`]).
    stride: usize,
    /// Stored values per row: `ceil(width / stride)`.
    stored_width: usize,
    /// Row-major, one value per `stride × stride` raster cells.
    values: Vec<u8>,
}

/// Raster cells per stored value and axis at level `h`: 1 for levels 1
/// and 2, `2^(h-2)` above (see the module doc).
pub fn stride(h: usize) -> usize {
    1 << h.saturating_sub(2)
}

impl PyramidLevel {
    /// Row-major quantised maxima, one per `stride × stride` raster cells
    /// (see [`Pyramid::scale`]).
    pub fn values(&self) -> &[u8] {
        &self.values
    }

    /// Stored values per row (the raster's width for a level of stride 1).
    pub fn stored_width(&self) -> usize {
        self.stored_width
    }

    /// Raster cells per stored value and axis.
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// Cells per row of the raster.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Cells per column of the raster.
    pub fn height(&self) -> usize {
        self.height
    }

    /// `2^h`: translations per axis of the blocks this level bounds.
    pub fn block(&self) -> usize {
        self.block
    }

    /// The quantised bound of the block of translations starting at raster
    /// cell `(x, y)` (see the module doc); 0 when the block cannot reach
    /// the grid.
    #[inline]
    pub fn get(&self, x: i64, y: i64) -> u8 {
        let block = self.block as i64;
        if x >= self.width as i64 || y >= self.height as i64 || x < -block || y < -block {
            return 0;
        }
        let shift = self.stride.trailing_zeros();
        let (i, j) = ((x.max(0) as usize) >> shift, (y.max(0) as usize) >> shift);
        self.values[j * self.stored_width + i]
    }
}

#[derive(Clone, Debug, Default)]
pub struct Pyramid {
    /// `levels[h - 1]` is level `h`; the ones above `EAGER_LEVELS` are
    /// filled on first use.
    levels: Vec<OnceLock<PyramidLevel>>,
    /// Quantisation: a stored value `q` stands for at most `q / scale`.
    scale: f32,
    /// The largest value of the raster (0 for an empty one).
    max_value: f32,
}

impl Pyramid {
    /// Levels `1..=levels` of `grid`.
    pub fn build(grid: &Grid, levels: usize) -> Self {
        let (width, height) = (grid.width(), grid.height());
        let max = max_value(grid.values());
        // A hair below 255 / max, so that 255 / scale ≥ max survives f32
        // rounding and the largest value's bound stays an upper bound.
        let scale = if max > 0.0 {
            255.0 / (max * (1.0 + 4.0 * f32::EPSILON))
        } else {
            1.0
        };
        if levels == 0 || width == 0 || height == 0 {
            return Self {
                levels: Vec::new(),
                scale,
                max_value: max,
            };
        }
        let quantised: Vec<u8> = grid.values().iter().map(|&v| quantise(v, scale)).collect();
        let levels: Vec<OnceLock<PyramidLevel>> = (0..levels).map(|_| OnceLock::new()).collect();
        // Level 1: windows of 3 cells, as two overlapping windows of 2.
        let pairs = dilate(&quantised, width, height, 1);
        let first = PyramidLevel::full(width, height, 1, dilate(&pairs, width, height, 1));
        levels[0].set(first).expect("a new cell is empty");
        let pyramid = Self {
            levels,
            scale,
            max_value: max,
        };
        // Level 2 from level 1 at full resolution; the pooled levels each
        // from the one below.
        for h in 2..=pyramid.len().min(EAGER_LEVELS) {
            let level = pyramid.next_level(h);
            pyramid.levels[h - 1]
                .set(level)
                .expect("eager levels are built once");
        }
        pyramid
    }

    /// Level `h ≥ 2` from level `h - 1`.
    fn next_level(&self, h: usize) -> PyramidLevel {
        let below = self.level(h - 1);
        if stride(h) == 1 {
            let (width, height) = (below.width, below.height);
            PyramidLevel::full(
                width,
                height,
                h,
                dilate(&below.values, width, height, 1 << (h - 1)),
            )
        } else {
            below.coarsened()
        }
    }

    /// Number of levels above the raster (the raster itself is level 0).
    pub fn len(&self) -> usize {
        self.levels.len()
    }

    pub fn is_empty(&self) -> bool {
        self.levels.is_empty()
    }

    /// Level `h` (`1 ≤ h ≤ len()`), built on first use from level `h - 1`.
    pub fn level(&self, h: usize) -> &PyramidLevel {
        self.levels[h - 1].get_or_init(|| self.next_level(h))
    }

    /// Bytes of the levels built so far on the heap.
    pub fn heap_bytes(&self) -> usize {
        self.levels
            .iter()
            .filter_map(|l| l.get())
            .map(|l| l.values.capacity())
            .sum()
    }

    /// Levels built so far (eager ones and those read since).
    pub fn built_levels(&self) -> usize {
        self.levels.iter().filter(|l| l.get().is_some()).count()
    }

    /// The largest value of the raster the pyramid was built from (0 for
    /// an empty raster).
    pub fn max_value(&self) -> f32 {
        self.max_value
    }

    /// Stored values are in units of `1 / scale`: a sum of stored values
    /// divided by `scale` bounds the sum of the raster values.
    pub fn scale(&self) -> f32 {
        self.scale
    }
}

/// Pyramids are equal when every level is: levels not built yet are
/// built to compare them.
impl PartialEq for Pyramid {
    fn eq(&self, other: &Self) -> bool {
        self.scale == other.scale
            && self.max_value == other.max_value
            && self.len() == other.len()
            && (1..=self.len()).all(|h| self.level(h) == other.level(h))
    }
}

impl PyramidLevel {
    /// A level stored at full resolution.
    fn full(width: usize, height: usize, h: usize, values: Vec<u8>) -> Self {
        Self {
            width,
            height,
            block: 1 << h,
            stride: 1,
            stored_width: width,
            values,
        }
    }

    /// The next level up (`h + 1 ≥ 3`, stored at twice this stride), from
    /// this one (level `h`) alone. With `s` the new stride, the new stored
    /// value of block `b` (per axis) is the maximum of `L_(h+1)` over cells
    /// `[b·s, (b+1)·s)`, that is of `L_h` over those cells and over the
    /// same cells shifted by `2^h = 4·(s/2)`: four of this level's blocks
    /// of `s/2` cells, `2b, 2b + 1, 2b + 4, 2b + 5` (0 beyond the grid). Maxima of the
    /// same quantised cells as `PyramidLevel::pooled` (test only) of the
    /// full-resolution `L_(h+1)`, so the values are the same, for a pass
    /// over this level instead of two over the raster.
    fn coarsened(&self) -> Self {
        let h = self.block.trailing_zeros() as usize + 1;
        let s = stride(h);
        debug_assert!(s == 2 * self.stride && h >= 3);
        let (pw, ph) = (self.stored_width, self.values.len() / self.stored_width);
        let (sw, sh) = (self.width.div_ceil(s), self.height.div_ceil(s));
        // Along x into `rows` (sw × ph), then along y.
        let mut rows = vec![0u8; sw * ph];
        for (src, dst) in self.values.chunks_exact(pw).zip(rows.chunks_exact_mut(sw)) {
            for (b, d) in dst.iter_mut().enumerate() {
                *d = four_max(src, 2 * b);
            }
        }
        let mut values = vec![0u8; sw * sh];
        for (b, dst) in values.chunks_exact_mut(sw).enumerate() {
            for r in [2 * b, 2 * b + 1, 2 * b + 4, 2 * b + 5] {
                if r < ph {
                    let src = &rows[r * sw..(r + 1) * sw];
                    for (d, &v) in dst.iter_mut().zip(src) {
                        *d = (*d).max(v);
                    }
                }
            }
        }
        Self {
            width: self.width,
            height: self.height,
            block: 2 * self.block,
            stride: s,
            stored_width: sw,
            values,
        }
    }

    /// Level `h` from its full-resolution maxima `full` (one per raster
    /// cell), keeping the maximum of each `stride(h)`² block of them.
    #[cfg(test)]
    fn pooled(width: usize, height: usize, h: usize, full: &[u8]) -> Self {
        let s = stride(h);
        let (sw, sh) = (width.div_ceil(s), height.div_ceil(s));
        let mut values = vec![0u8; sw * sh];
        for (y, row) in full.chunks_exact(width).enumerate() {
            let out = &mut values[(y / s) * sw..(y / s + 1) * sw];
            for (o, cells) in out.iter_mut().zip(row.chunks(s)) {
                *o = cells.iter().fold(*o, |m, &c| m.max(c));
            }
        }
        Self {
            width,
            height,
            block: 1 << h,
            stride: s,
            stored_width: sw,
            values,
        }
    }
}

/// `max(v[i], v[i + 1], v[i + 4], v[i + 5])`, entries beyond `v` 0.
#[inline]
fn four_max(v: &[u8], i: usize) -> u8 {
    if i + 5 < v.len() {
        v[i].max(v[i + 1]).max(v[i + 4]).max(v[i + 5])
    } else {
        [i, i + 1, i + 4, i + 5]
            .iter()
            .filter_map(|&k| v.get(k))
            .fold(0, |m, &x| m.max(x))
    }
}

/// The smallest `q` with `q / scale ≥ v` (0 for `v ≤ 0` and NaN, 255 at
/// most). Branch-free, so that the loop over a grid vectorises.
#[inline]
fn quantise(v: f32, scale: f32) -> u8 {
    // `t > 0` is false for NaN and non-positive values; i32 and `&`
    // rather than u32 and `&&` keep the loop free of branches.
    let t = v * scale;
    let t = if t > 0.0 { t.min(255.0) } else { 0.0 };
    // Ceiling without a libm call: truncate (t ≥ 0), then step up when
    // that fell short of the product ...
    let mut q = t as i32;
    q += i32::from((q as f32) < t);
    // ... or when rounding of the product left `q / scale` short of `v`
    // (false for NaN and v ≤ 0, where q = 0).
    q += i32::from(((q as f32) / scale < v) & (q < 255));
    q.min(255) as u8
}

/// `out(x, y) = max(in(x, y), in(x + s, y), in(x, y + s), in(x + s, y + s))`
/// (cells beyond the grid count as 0): windows `[x, x + s]` per axis when
/// `in` holds single cells, and in general the union of two windows `s`
/// apart.
fn dilate(values: &[u8], width: usize, height: usize, s: usize) -> Vec<u8> {
    let mut out = vec![0u8; values.len()];
    for (src, dst) in values.chunks_exact(width).zip(out.chunks_exact_mut(width)) {
        let split = width.saturating_sub(s);
        // `s` may exceed the width (high levels of a narrow image).
        max_of(&mut dst[..split], &src[..split], &src[s.min(width)..]);
        dst[split..].copy_from_slice(&src[split..]);
    }
    // In place, top down: row y + s is still the row pass's when row y
    // reads it.
    for y in 0..height.saturating_sub(s) {
        let (head, tail) = out.split_at_mut((y + s) * width);
        let row = &mut head[y * width..(y + 1) * width];
        let below = &tail[..width];
        for (d, b) in row.chunks_mut(LANES).zip(below.chunks(LANES)) {
            for (d, b) in d.iter_mut().zip(b) {
                *d = (*d).max(*b);
            }
        }
    }
    out
}

/// Bytes per step of the max loops: fixed-size chunks let the compiler
/// emit vector maxima without aliasing or length checks inside.
const LANES: usize = 32;

/// `dst[i] = max(a[i], b[i])` over `dst.len()` bytes (`a`, `b` at least as
/// long).
fn max_of(dst: &mut [u8], a: &[u8], b: &[u8]) {
    let n = dst.len();
    let (a, b) = (&a[..n], &b[..n]);
    let mut d_chunks = dst.chunks_exact_mut(LANES);
    let mut a_chunks = a.chunks_exact(LANES);
    let mut b_chunks = b.chunks_exact(LANES);
    for ((d, a), b) in (&mut d_chunks).zip(&mut a_chunks).zip(&mut b_chunks) {
        let (a, b): (&[u8; LANES], &[u8; LANES]) =
            (a.try_into().expect("chunk"), b.try_into().expect("chunk"));
        for k in 0..LANES {
            d[k] = a[k].max(b[k]);
        }
    }
    let tail = d_chunks.into_remainder();
    for ((d, a), b) in tail
        .iter_mut()
        .zip(a_chunks.remainder())
        .zip(b_chunks.remainder())
    {
        *d = (*a).max(*b);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn every_level_bounds_its_blocks_exactly() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut grid = Grid::zeros(0.0, 0.0, 1.0, 37, 23);
        for v in grid.values_mut() {
            *v = if rng.random_bool(0.1) {
                rng.random::<f32>() * 0.8
            } else {
                0.0
            };
        }
        // Levels 6 and 7 are built on first use, from the eager ones.
        let pyramid = Pyramid::build(&grid, 7);
        assert_eq!(pyramid.len(), 7);
        assert_eq!(pyramid.built_levels(), EAGER_LEVELS);
        let scale = pyramid.scale();
        for h in 1..=7usize {
            let level = pyramid.level(h);
            let block = 1i64 << h;
            assert_eq!(level.block() as i64, block);
            for _ in 0..400 {
                let cx = rng.random_range(-2 * block..37 + block);
                let cy = rng.random_range(-2 * block..23 + block);
                let bound = f32::from(level.get(cx, cy)) / scale;
                // The true maximum over the cells a bilinear lookup can read
                // for the block of translations (one more cell per axis).
                let mut max = 0.0_f32;
                for dx in 0..=block {
                    for dy in 0..=block {
                        max = max.max(grid.cell(cx + dx, cy + dy));
                    }
                }
                assert!(bound >= max, "h {h} at ({cx}, {cy}): {bound} < {max}");
                // Tight: one quantisation step above the maximum over the
                // window widened to whole strides (`stride - 1` more cells
                // per axis), except for blocks that start outside the
                // grid, which are bounded by the window at the grid's edge.
                if cx >= 0 && cy >= 0 {
                    let s = level.stride() as i64;
                    assert_eq!(s, 1 << (h as i64 - 2).max(0));
                    let (x0, y0) = (cx / s * s, cy / s * s);
                    let mut widened = 0.0_f32;
                    for x in x0..x0 + s + block {
                        for y in y0..y0 + s + block {
                            widened = widened.max(grid.cell(x, y));
                        }
                    }
                    assert!(
                        bound <= widened + 1.0 / scale,
                        "h {h} at ({cx}, {cy}): {bound} vs {widened}"
                    );
                }
            }
        }
        assert_eq!(pyramid.built_levels(), 7);
    }

    #[test]
    fn coarsened_levels_equal_the_pooled_full_resolution_maxima() {
        // The reference: each level's full-resolution maxima by dilation
        // of the one below, pooled over its stride.
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        for (width, height) in [(37, 23), (64, 64), (5, 70), (130, 9), (1, 1)] {
            let mut grid = Grid::zeros(0.0, 0.0, 1.0, width, height);
            for v in grid.values_mut() {
                *v = if rng.random_bool(0.2) {
                    rng.random::<f32>()
                } else {
                    0.0
                };
            }
            let pyramid = Pyramid::build(&grid, 9);
            let mut full = pyramid.level(2).values().to_vec();
            for h in 3..=9 {
                full = dilate(&full, width, height, 1 << (h - 1));
                let reference = PyramidLevel::pooled(width, height, h, &full);
                assert_eq!(
                    pyramid.level(h),
                    &reference,
                    "{width} x {height}, level {h}"
                );
            }
        }
    }

    #[test]
    fn quantisation_rounds_up() {
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        for _ in 0..10_000 {
            let max = rng.random_range(1e-3_f32..10.0);
            let scale = 255.0 / max;
            let v = rng.random_range(0.0..=max);
            let q = quantise(v, scale);
            assert!(f32::from(q) / scale >= v, "{v} -> {q}");
            assert!(f32::from(q) / scale <= v + 1.0 / scale * 1.001 + 1e-6);
        }
        assert_eq!(quantise(-1.0, 2.0), 0);
        assert_eq!(quantise(f32::NAN, 2.0), 0);
        assert_eq!(quantise(1.0, 255.0), 255);
    }
}
