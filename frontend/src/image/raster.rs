//! Rasterisation of a rotation's motion-compensated beams (paper section 4).
//!
//! The fan between two consecutive beams `j` and `j+1` (a *wedge*) is swept
//! by lines at parameters `u = m / M` (`m = 0..M`): origin and bearing are
//! interpolated between the two beams' frames (both already in the reference
//! frame, eq. 3-4), and each line is sampled at the bins' far ends (eq. 3),
//! with sub-samples when bins are longer than the cells. `M = 2^L` is chosen
//! so that neighbouring lines are at most `cell/√2` apart at the far end;
//! line `m` starts only at the range where the coarser lines (multiples of
//! `2^(tz(m)+1)`) become too sparse, so the near field is not oversampled.
//! The sample spacing (≤ `cell/√2` both ways) puts at least one sample in
//! every cell the wedge covers.
//!
//! Values along a line follow the [`Interpolation`]:
//! - `Nearest`: the bin of the angularly nearer beam; a cell keeps the
//!   sample closest to its centre (≈ the closest bin sample, Fig. 4-b);
//! - `AngularWindow`: the triangular-weighted mean over the beams within the
//!   window of the line's bearing; a cell holds the mean of its samples.
//!
//! Wedges wider than `max_wedge_rad`, or between beams with different bin
//! geometry, are not filled; each beam's own line is always drawn.

use super::grid::Grid;
use super::grid::floor;
use super::normalise::Profiles;
use super::{ImageConfig, Interpolation};
use crate::error::FrontendError;
use crate::sensors::SonarBeam;
use echofield_graph::{Se2, wrap_angle};
use std::cell::RefCell;
use std::f64::consts::SQRT_2;

thread_local! {
    /// The accumulators' per-cell buffers, kept per thread between images:
    /// a fresh multi-megabyte buffer per image comes from `mmap` and costs
    /// a page fault per 4 KiB (two when it is zero-filled lazily), which
    /// on the St Pere replay took longer than filling the cells.
    static CLOSEST: RefCell<Vec<u64>> = const { RefCell::new(Vec::new()) };
    static MEAN: RefCell<Vec<[f32; 2]>> = const { RefCell::new(Vec::new()) };
    static SECOND_SUM: RefCell<Vec<f32>> = const { RefCell::new(Vec::new()) };
    static SECOND_CLOSEST: RefCell<Vec<u64>> = const { RefCell::new(Vec::new()) };
}

/// A value painted into the raster: one intensity, or two painted at once
/// ([`rasterise_pair`]).
trait Sample: Copy + Default {
    /// `self += w · v`.
    fn add_scaled(&mut self, w: f32, v: Self);
    /// `w · v`.
    fn scaled(w: f32, v: Self) -> Self;
}

impl Sample for f32 {
    #[inline]
    fn add_scaled(&mut self, w: f32, v: Self) {
        *self += w * v;
    }

    #[inline]
    fn scaled(w: f32, v: Self) -> Self {
        w * v
    }
}

impl Sample for [f32; 2] {
    #[inline]
    fn add_scaled(&mut self, w: f32, v: Self) {
        self[0] += w * v[0];
        self[1] += w * v[1];
    }

    #[inline]
    fn scaled(w: f32, v: Self) -> Self {
        [w * v[0], w * v[1]]
    }
}

/// Largest image accepted, in cells (256 MB of `f32`).
pub const MAX_CELLS: usize = 1 << 26;

/// At most this many beams on each side enter an angular window.
const MAX_WINDOW_NEIGHBOURS: usize = 32;

/// Geometry of one beam in the reference frame.
#[derive(Clone, Copy, Debug)]
struct BeamLine {
    origin_x_m: f64,
    origin_y_m: f64,
    /// Bearing, unwrapped along the acquisition order.
    bearing_rad: f64,
    first_bin_range_m: f64,
    bin_size_m: f64,
    bins: usize,
}

impl BeamLine {
    fn far_range_m(&self) -> f64 {
        self.first_bin_range_m + self.bins as f64 * self.bin_size_m
    }

    fn same_bins(&self, other: &BeamLine) -> bool {
        self.bin_size_m == other.bin_size_m && self.first_bin_range_m == other.first_bin_range_m
    }
}

fn beam_lines<V>(beams: &[SonarBeam], poses: &[Se2], profiles: &Profiles<V>) -> Vec<BeamLine> {
    let mut lines = Vec::with_capacity(beams.len());
    let mut bearing = 0.0;
    for (j, (beam, pose)) in beams.iter().zip(poses).enumerate() {
        bearing = if j == 0 {
            pose.theta()
        } else {
            bearing + wrap_angle(pose.theta() - poses[j - 1].theta())
        };
        lines.push(BeamLine {
            origin_x_m: pose.x(),
            origin_y_m: pose.y(),
            bearing_rad: bearing,
            first_bin_range_m: beam.first_bin_range_m,
            bin_size_m: beam.bin_size_m,
            bins: profiles.beam(j).len(),
        });
    }
    lines
}

/// Where a raster lies: its lower-left corner, cell size and cells per row
/// and column.
#[derive(Clone, Copy, Debug)]
struct Frame {
    origin_x_m: f64,
    origin_y_m: f64,
    cell_m: f64,
    width: usize,
    height: usize,
}

impl Frame {
    fn cells(&self) -> usize {
        self.width * self.height
    }

    /// The grid of this frame holding `values` (one per cell, row-major).
    fn grid(&self, values: Vec<f32>) -> Grid {
        Grid::from_values(
            self.origin_x_m,
            self.origin_y_m,
            self.cell_m,
            self.width,
            self.height,
            values,
        )
    }
}

/// The frame covering every bin of every beam, plus one cell of margin,
/// with its origin on a multiple of the cell size.
fn covering_frame(lines: &[BeamLine], cell_m: f64) -> Result<Frame, FrontendError> {
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for l in lines {
        let r = l.far_range_m();
        let (s, c) = l.bearing_rad.sin_cos();
        for (x, y) in [
            (l.origin_x_m, l.origin_y_m),
            (l.origin_x_m + r * c, l.origin_y_m + r * s),
        ] {
            x0 = x0.min(x);
            y0 = y0.min(y);
            x1 = x1.max(x);
            y1 = y1.max(y);
        }
    }
    let ox = (x0 / cell_m).floor() * cell_m - cell_m;
    let oy = (y0 / cell_m).floor() * cell_m - cell_m;
    let width = ((x1 - ox) / cell_m).ceil() as usize + 2;
    let height = ((y1 - oy) / cell_m).ceil() as usize + 2;
    if width.saturating_mul(height) > MAX_CELLS {
        // Beams whose origins lie farther apart than their own reach were
        // placed there by the motion compensation: the navigation is to
        // blame, not the cell size (issue 35: a DVL at 1e3 m/s).
        let spread_m = lines
            .iter()
            .map(|l| l.origin_x_m.hypot(l.origin_y_m))
            .fold(0.0, f64::max);
        let reach_m = lines.iter().map(BeamLine::far_range_m).fold(0.0, f64::max);
        if spread_m > reach_m {
            return Err(FrontendError::input(
                "beams of the rotation",
                "pose",
                format!(
                    "the navigation places beams {spread_m:.3e} m from the rotation's central \
                     pose, beyond their {reach_m:.1} m reach: the vehicle cannot have moved so \
                     far within one rotation; check the DVL and heading records of this time"
                ),
            ));
        }
        return Err(FrontendError::config(
            "cell_size_m",
            format!(
                "the image would have {width} x {height} cells (more than {MAX_CELLS}); \
                 use larger cells or a smaller max_range_m"
            ),
        ));
    }
    Ok(Frame {
        origin_x_m: ox,
        origin_y_m: oy,
        cell_m,
        width,
        height,
    })
}

/// How samples falling into one cell are combined.
trait Accumulator<V> {
    /// A sample of value `v` in cell `idx`, at the fractional position
    /// `(fx, fy) / 2³²` within it.
    fn put(&mut self, idx: usize, fx: u32, fy: u32, v: V);
}

/// Keeps the sample closest to the cell centre. The squared distance (in
/// units of 2⁻³² cells², integer arithmetic on the fixed-point fractions)
/// and the value are packed into one `u64` key (non-negative `f32` bits
/// order like the numbers), so keeping the closest is a branch-free `min`.
struct ClosestSample<'a> {
    best: &'a mut [u64],
}

/// The distance part of a [`ClosestSample`] key: the squared distance of
/// the fixed-point position `(fx, fy) / 2³²` from the cell centre, shifted
/// into the key's top 32 bits.
#[inline]
fn distance_key(fx: u32, fy: u32) -> u64 {
    // Offsets from the centre on 31-bit fractions, |d| ≤ 2³⁰: the sum of
    // squares is at most 2⁶¹ (no overflow), and its top bits order the
    // distances.
    let dx = i64::from(fx >> 1) - HALF_CELL;
    let dy = i64::from(fy >> 1) - HALF_CELL;
    (((dx * dx + dy * dy) >> 30) as u64) << 32
}

impl Accumulator<f32> for ClosestSample<'_> {
    #[inline]
    fn put(&mut self, idx: usize, fx: u32, fy: u32, v: f32) {
        let key = distance_key(fx, fy) | u64::from(v.to_bits());
        let slot = &mut self.best[idx];
        *slot = (*slot).min(key);
    }
}

/// [`ClosestSample`] of two values at once, each in a buffer of its own
/// (a tie in distance keeps the smaller value in each, as for one).
struct ClosestPair<'a> {
    best: &'a mut [u64],
    second: &'a mut [u64],
}

impl Accumulator<[f32; 2]> for ClosestPair<'_> {
    #[inline]
    fn put(&mut self, idx: usize, fx: u32, fy: u32, v: [f32; 2]) {
        let d = distance_key(fx, fy);
        let slot = &mut self.best[idx];
        *slot = (*slot).min(d | u64::from(v[0].to_bits()));
        let slot = &mut self.second[idx];
        *slot = (*slot).min(d | u64::from(v[1].to_bits()));
    }
}

/// The value of a [`ClosestSample`] key (0 where no sample fell).
#[inline]
fn closest_value(key: u64) -> f32 {
    if key == u64::MAX {
        0.0
    } else {
        f32::from_bits(key as u32)
    }
}

/// Averages the samples of a cell: `(sum, count)` side by side, so one
/// sample touches one cache line.
struct MeanSample<'a> {
    sum_count: &'a mut [[f32; 2]],
}

impl Accumulator<f32> for MeanSample<'_> {
    #[inline]
    fn put(&mut self, idx: usize, _fx: u32, _fy: u32, v: f32) {
        let slot = &mut self.sum_count[idx];
        slot[0] += v;
        slot[1] += 1.0;
    }
}

/// [`MeanSample`] of two values at once, the first with the count and the
/// second's sum in a buffer of its own (faster than three values side by side:
/// EXPERIMENTS.md § Speed notes).
struct MeanPair<'a> {
    sum_count: &'a mut [[f32; 2]],
    second_sum: &'a mut [f32],
}

impl Accumulator<[f32; 2]> for MeanPair<'_> {
    #[inline]
    fn put(&mut self, idx: usize, _fx: u32, _fy: u32, v: [f32; 2]) {
        let slot = &mut self.sum_count[idx];
        slot[0] += v[0];
        slot[1] += 1.0;
        self.second_sum[idx] += v[1];
    }
}

/// Rasterises the normalised beams into a grid (see the module doc).
pub fn rasterise(
    beams: &[SonarBeam],
    poses: &[Se2],
    profiles: &Profiles,
    cell_m: f64,
    config: &ImageConfig,
) -> Result<Grid, FrontendError> {
    let lines = beam_lines(beams, poses, profiles);
    let frame = covering_frame(&lines, cell_m)?;
    let n = frame.cells();
    let mut painter = Painter::<f32>::new(&frame, config);
    let values = match config.interpolation {
        Interpolation::Nearest => CLOSEST.with_borrow_mut(|buffer| {
            buffer.clear();
            buffer.resize(n, u64::MAX);
            let mut acc = ClosestSample { best: buffer };
            painter.paint(&lines, profiles, &mut acc);
            acc.best.iter().map(|&key| closest_value(key)).collect()
        }),
        Interpolation::AngularWindow => MEAN.with_borrow_mut(|buffer| {
            buffer.clear();
            buffer.resize(n, [0.0; 2]);
            let mut acc = MeanSample { sum_count: buffer };
            painter.paint(&lines, profiles, &mut acc);
            acc.sum_count
                .iter()
                .map(|&[sum, count]| mean(sum, count))
                .collect()
        }),
    };
    Ok(frame.grid(values))
}

/// Rasterises two versions of the same beams (`a` and `b`, the same bins
/// with other values) into two grids, sweeping the wedges once: what
/// [`rasterise`] gives for each, for less than the cost of two (profiles
/// whose beams differ in length are rasterised one after the other).
pub fn rasterise_pair(
    beams: &[SonarBeam],
    poses: &[Se2],
    a: &Profiles,
    b: &Profiles,
    cell_m: f64,
    config: &ImageConfig,
) -> Result<(Grid, Grid), FrontendError> {
    let Some(paired) = a.paired(b) else {
        return Ok((
            rasterise(beams, poses, a, cell_m, config)?,
            rasterise(beams, poses, b, cell_m, config)?,
        ));
    };
    rasterise_paired(beams, poses, &paired, cell_m, config)
}

/// [`rasterise_pair`] of the two versions paired bin by bin
/// ([`Profiles::paired`]): the grid of the first values and the grid of
/// the second.
pub fn rasterise_paired(
    beams: &[SonarBeam],
    poses: &[Se2],
    paired: &Profiles<[f32; 2]>,
    cell_m: f64,
    config: &ImageConfig,
) -> Result<(Grid, Grid), FrontendError> {
    let lines = beam_lines(beams, poses, paired);
    let frame = covering_frame(&lines, cell_m)?;
    let n = frame.cells();
    let mut painter = Painter::<[f32; 2]>::new(&frame, config);
    // Each grid is collected in a pass of its own over the accumulators:
    // an exact-size `map` + `collect` compiles to a vector loop, where one
    // loop pushing into both grids stayed scalar (4.5% of a St Pere run,
    // `perf`).
    if config.interpolation == Interpolation::Nearest {
        return Ok(CLOSEST.with_borrow_mut(|best| {
            SECOND_CLOSEST.with_borrow_mut(|second| {
                for buffer in [&mut *best, &mut *second] {
                    buffer.clear();
                    buffer.resize(n, u64::MAX);
                }
                let mut acc = ClosestPair { best, second };
                painter.paint(&lines, paired, &mut acc);
                let values = |keys: &[u64]| keys.iter().map(|&key| closest_value(key)).collect();
                (frame.grid(values(acc.best)), frame.grid(values(acc.second)))
            })
        }));
    }
    Ok(MEAN.with_borrow_mut(|sum_count| {
        SECOND_SUM.with_borrow_mut(|second_sum| {
            sum_count.clear();
            sum_count.resize(n, [0.0; 2]);
            second_sum.clear();
            second_sum.resize(n, 0.0);
            let mut acc = MeanPair {
                sum_count,
                second_sum,
            };
            painter.paint(&lines, paired, &mut acc);
            let values_a = acc.sum_count.iter().map(|&[sum, count]| mean(sum, count));
            let values_b = (acc.second_sum.iter().zip(acc.sum_count.iter()))
                .map(|(&sum, &[_, count])| mean(sum, count));
            (
                frame.grid(values_a.collect()),
                frame.grid(values_b.collect()),
            )
        })
    }))
}

/// The mean of a cell's samples from their sum and count (0 where none fell).
#[inline]
fn mean(sum: f32, count: f32) -> f32 {
    if count > 0.0 { sum / count } else { 0.0 }
}

/// Sweeps the wedges and feeds samples to an [`Accumulator`].
struct Painter<V> {
    origin_x_m: f64,
    origin_y_m: f64,
    inv_cell: f64,
    width: usize,
    height: usize,
    /// Largest spacing between samples, metres.
    spacing_m: f64,
    interpolation: Interpolation,
    half_width_rad: f64,
    max_wedge_rad: f64,
    /// Scratch: combined profile of one line, and window weights.
    combined: Vec<V>,
    weights: Vec<(usize, f32)>,
    jobs: Vec<LineJob>,
}

impl<V: Sample> Painter<V> {
    fn new(frame: &Frame, config: &ImageConfig) -> Self {
        Self {
            origin_x_m: frame.origin_x_m,
            origin_y_m: frame.origin_y_m,
            inv_cell: 1.0 / frame.cell_m,
            width: frame.width,
            height: frame.height,
            spacing_m: frame.cell_m / SQRT_2,
            interpolation: config.interpolation,
            half_width_rad: config.angular_half_width_rad,
            max_wedge_rad: config.max_wedge_rad,
            combined: Vec::new(),
            weights: Vec::new(),
            jobs: Vec::new(),
        }
    }

    fn paint<A: Accumulator<V>>(
        &mut self,
        lines: &[BeamLine],
        profiles: &Profiles<V>,
        acc: &mut A,
    ) {
        for j in 0..lines.len() {
            let a = &lines[j];
            let next = lines
                .get(j + 1)
                .filter(|b| b.same_bins(a))
                .filter(|b| (b.bearing_rad - a.bearing_rad).abs() <= self.max_wedge_rad);
            let (delta, shift_m) = match next {
                Some(b) => (
                    b.bearing_rad - a.bearing_rad,
                    (b.origin_x_m - a.origin_x_m).hypot(b.origin_y_m - a.origin_y_m),
                ),
                None => (0.0, 0.0),
            };
            // Lateral spread of the wedge at its far end decides M = 2^L.
            let spread_m = a.far_range_m() * delta.abs() + shift_m;
            let levels = if next.is_some() && spread_m > self.spacing_m {
                ((spread_m / self.spacing_m).log2().ceil() as u32).min(16)
            } else {
                0
            };
            let lines_in_wedge = 1usize << levels;
            for m in 0..lines_in_wedge {
                let u = m as f64 / lines_in_wedge as f64;
                // Line m is needed where lines at multiples of 2^(tz+1) are
                // more than `spacing` apart.
                let start_range_m = if m == 0 {
                    0.0
                } else {
                    let coarse =
                        (1usize << (m.trailing_zeros() + 1)) as f64 / lines_in_wedge as f64;
                    if delta == 0.0 {
                        0.0
                    } else {
                        ((self.spacing_m / coarse - shift_m) / delta.abs()).max(0.0)
                    }
                };
                let b = next.unwrap_or(a);
                let line = SweepLine {
                    origin_x_m: a.origin_x_m + u * (b.origin_x_m - a.origin_x_m),
                    origin_y_m: a.origin_y_m + u * (b.origin_y_m - a.origin_y_m),
                    bearing_rad: a.bearing_rad + u * delta,
                    start_range_m,
                };
                let bins = a.bins.min(b.bins);
                let start_bin = a.bin_at_or_after(start_range_m).min(bins);
                let values = match self.interpolation {
                    Interpolation::Nearest => {
                        let k = if u < 0.5 { j } else { j + 1 };
                        ValueSource::Beam(k)
                    }
                    Interpolation::AngularWindow => {
                        let at = self.combined.len();
                        self.window_profile(lines, profiles, j, delta, &line, start_bin, bins);
                        ValueSource::Combined(at)
                    }
                };
                self.jobs.push(self.job(a, &line, start_bin, bins, values));
            }
            self.draw_jobs(profiles, acc);
        }
    }

    /// Sampling plan of one line: grid position of its first sample and the
    /// step between samples, in cells.
    fn job(
        &self,
        beam: &BeamLine,
        line: &SweepLine,
        start_bin: usize,
        bins: usize,
        values: ValueSource,
    ) -> LineJob {
        let (s, c) = line.bearing_rad.sin_cos();
        let sub = (beam.bin_size_m / self.spacing_m).ceil().max(1.0) as usize;
        let step_m = beam.bin_size_m / sub as f64;
        // Sample q of bin i sits at far(i) + ((q + 0.5)/sub - 0.5)·bin.
        let first_m = beam.first_bin_range_m
            + (start_bin + 1) as f64 * beam.bin_size_m
            + (0.5 / sub as f64 - 0.5) * beam.bin_size_m;
        let skip = if line.start_range_m > first_m {
            ((line.start_range_m - first_m) / step_m).ceil() as usize
        } else {
            0
        };
        LineJob {
            gx: (line.origin_x_m + first_m * c - self.origin_x_m) * self.inv_cell,
            gy: (line.origin_y_m + first_m * s - self.origin_y_m) * self.inv_cell,
            sx: step_m * c * self.inv_cell,
            sy: step_m * s * self.inv_cell,
            sub,
            first_sample: skip,
            start_bin,
            end_bin: bins,
            values,
        }
    }

    /// Draws the queued lines of one wedge band by band in range, so the
    /// cells a band touches stay in cache while all its lines visit them.
    fn draw_jobs<A: Accumulator<V>>(&mut self, profiles: &Profiles<V>, acc: &mut A) {
        const BAND_SAMPLES: usize = 48;
        let total = self
            .jobs
            .iter()
            .map(|j| (j.end_bin - j.start_bin) * j.sub)
            .max()
            .unwrap_or(0);
        let (w, h) = (self.width as u64, self.height as u64);
        let mut band = 0;
        while band < total {
            for job in &self.jobs {
                let values: &[V] = match job.values {
                    ValueSource::Beam(k) => &profiles.beam(k)[job.start_bin..job.end_bin],
                    ValueSource::Combined(at) => {
                        &self.combined[at..at + job.end_bin - job.start_bin]
                    }
                };
                let lo = band.max(job.first_sample);
                let hi = (band + BAND_SAMPLES).min(values.len() * job.sub);
                if lo >= hi {
                    continue;
                }
                // Positions in 32.32 fixed point: integer steps, and the
                // cell index is a shift (float-to-int casts saturate and
                // cost a dozen instructions each).
                let mut x = to_fixed(job.gx + lo as f64 * job.sx);
                let mut y = to_fixed(job.gy + lo as f64 * job.sy);
                let (sx, sy) = (to_fixed(job.sx), to_fixed(job.sy));
                let value = |t: usize| {
                    if job.sub == 1 {
                        values[t]
                    } else {
                        values[t / job.sub]
                    }
                };
                // A run whose first and last samples are in the grid lies
                // in it (the grid is convex): no test per sample. That is
                // nearly every run, as the grid covers the lines.
                let steps = (hi - lo - 1) as i64;
                if run_inside(x, sx, steps, w) && run_inside(y, sy, steps, h) {
                    let mut put = |v: V| {
                        let idx = (y >> 32) as usize * self.width + (x >> 32) as usize;
                        acc.put(idx, x as u32, y as u32, v);
                        x += sx;
                        y += sy;
                    };
                    if job.sub == 1 {
                        values[lo..hi].iter().for_each(|&v| put(v));
                    } else {
                        (lo..hi).for_each(|t| put(value(t)));
                    }
                    continue;
                }
                for t in lo..hi {
                    // Negative positions become huge and fail the test.
                    let (ix, iy) = ((x >> 32) as u64, (y >> 32) as u64);
                    if ix < w && iy < h {
                        let idx = iy as usize * self.width + ix as usize;
                        acc.put(idx, x as u32, y as u32, value(t));
                    }
                    x = x.wrapping_add(sx);
                    y = y.wrapping_add(sy);
                }
            }
            band += BAND_SAMPLES;
        }
        self.jobs.clear();
        self.combined.clear();
    }

    /// Fills `self.combined` with the angular-window mean along `line`.
    #[allow(clippy::too_many_arguments)]
    fn window_profile(
        &mut self,
        lines: &[BeamLine],
        profiles: &Profiles<V>,
        j: usize,
        delta: f64,
        line: &SweepLine,
        start_bin: usize,
        bins: usize,
    ) {
        let w = self.half_width_rad.max(delta.abs());
        self.weights.clear();
        let mut consider = |k: usize| -> bool {
            let l = &lines[k];
            if !l.same_bins(&lines[j]) {
                return false;
            }
            let d = (l.bearing_rad - line.bearing_rad).abs();
            if d < w {
                self.weights.push((k, (1.0 - d / w) as f32));
            }
            // Keep walking while the bearing is within reach of the window.
            d < w + delta.abs() + 1e-12
        };
        for k in (j.saturating_sub(MAX_WINDOW_NEIGHBOURS)..=j).rev() {
            if !consider(k) && k != j {
                break;
            }
        }
        for k in j + 1..lines.len().min(j + 1 + MAX_WINDOW_NEIGHBOURS) {
            if !consider(k) {
                break;
            }
        }
        let (at, len) = (self.combined.len(), bins - start_bin);
        let total: f32 = self.weights.iter().map(|(_, w)| w).sum();
        // The sum over the window of each beam's weighted values, in the
        // weights' order, from 0 (bins that no beam reaches stay 0). The
        // first beam's terms are written rather than added to zeros: the
        // values and weights are not negative, so `0 + w·v` is `w·v` bit
        // for bit, and the buffer is not zero-filled first.
        let mut first = true;
        if total > 0.0 {
            for &(k, wk) in &self.weights {
                let wk = wk / total;
                let profile = profiles.beam(k);
                let end = profile.len().min(bins);
                if end <= start_bin {
                    continue;
                }
                let values = &profile[start_bin..end];
                if first {
                    self.combined
                        .extend(values.iter().map(|&v| V::scaled(wk, v)));
                    self.combined.resize(at + len, V::default());
                    first = false;
                } else {
                    for (c, v) in self.combined[at..].iter_mut().zip(values) {
                        c.add_scaled(wk, *v);
                    }
                }
            }
        }
        if first {
            self.combined.resize(at + len, V::default());
        }
    }
}

/// Scale of the 32.32 fixed-point sample positions.
const FIXED_ONE: f64 = 4_294_967_296.0;
/// Half a cell in 31-bit fractions.
const HALF_CELL: i64 = 1 << 30;

/// A position in cells as 32.32 fixed point (positions far outside any
/// grid saturate, which keeps them outside).
#[inline]
fn to_fixed(cells: f64) -> i64 {
    (cells * FIXED_ONE) as i64
}

/// The fixed-point coordinates `p0` and `p0 + steps·step` both lie in
/// cells `0..cells` (`0 ≤ p < cells·2³²`).
#[inline]
fn run_inside(p0: i64, step: i64, steps: i64, cells: u64) -> bool {
    let max = (i128::from(cells) << 32) - 1;
    let last = i128::from(p0) + i128::from(steps) * i128::from(step);
    (0..=max).contains(&i128::from(p0)) && (0..=max).contains(&last)
}

/// Where the values of a line come from.
#[derive(Clone, Copy, Debug)]
enum ValueSource {
    /// A beam's normalised profile.
    Beam(usize),
    /// The combined (angular-window) profile at this offset of the scratch.
    Combined(usize),
}

/// The sampling plan of one line; sample `t` lies at `(gx + t·sx, gy + t·sy)`
/// in cell units and takes value `t / sub` of the line's bins.
#[derive(Clone, Copy, Debug)]
struct LineJob {
    gx: f64,
    gy: f64,
    sx: f64,
    sy: f64,
    sub: usize,
    first_sample: usize,
    start_bin: usize,
    end_bin: usize,
    values: ValueSource,
}

/// One line of a wedge sweep.
struct SweepLine {
    origin_x_m: f64,
    origin_y_m: f64,
    bearing_rad: f64,
    start_range_m: f64,
}

impl BeamLine {
    /// First bin whose (sub-sampled) far end may lie at or beyond `range_m`.
    fn bin_at_or_after(&self, range_m: f64) -> usize {
        let k = floor((range_m - self.first_bin_range_m) / self.bin_size_m - 1.5);
        if k <= 0.0 { 0 } else { k as usize }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::normalise::normalise_beams;

    /// A static sonar at the origin, beams every `step` degrees, each with a
    /// single bright bin at `range` (far end) and zeros elsewhere.
    fn ring(step_deg: f64, bright_bin: usize) -> (Vec<SonarBeam>, Vec<Se2>) {
        let n = (360.0 / step_deg).round() as usize;
        let mut beams = Vec::new();
        let mut poses = Vec::new();
        for k in 0..n {
            let angle = (k as f64 * step_deg).to_radians();
            let mut intensities = vec![0u8; 100];
            intensities[bright_bin] = 200;
            beams.push(SonarBeam {
                stamp_s: k as f64,
                angle_rad: angle,
                bin_size_m: 0.1,
                first_bin_range_m: 0.0,
                intensities,
            });
            poses.push(Se2::new(0.0, 0.0, angle));
        }
        (beams, poses)
    }

    fn config(interpolation: Interpolation) -> ImageConfig {
        ImageConfig {
            interpolation,
            range_smoothing_bins: 1,
            blind_zone_m: 0.0,
            background_quantile: 0.0,
            normalisation_quantile: 1.0,
            smoothing_sigma_m: 0.0,
            ..ImageConfig::default()
        }
    }

    #[test]
    fn a_pair_rasterised_at_once_equals_each_rasterised_alone() {
        // A moving sonar (so the wedges are swept with several lines) over
        // a synthetic basin; the second version of the profiles has the
        // pose-fit raster's margin and smoothing.
        let rotation = crate::image::synthetic::simulate_rotation(
            &crate::image::synthetic::SceneConfig::default(),
            &crate::image::synthetic::RotationPath {
                world_from_start: Se2::identity(),
                velocity_mps: (0.4, 0.1),
                yaw_rate_radps: 0.02,
            },
            7,
        );
        let (beams, poses) = (&rotation.beams, &rotation.reference_from_beams);
        for interpolation in [Interpolation::AngularWindow, Interpolation::Nearest] {
            let cfg = ImageConfig {
                interpolation,
                ..ImageConfig::default()
            };
            let a = normalise_beams(beams, &cfg);
            let b = normalise_beams(beams, &cfg.pose_fit.image_config(&cfg));
            assert_ne!(a, b);
            let cell = cfg.cell_size_for(beams);
            let (pair_a, pair_b) = rasterise_pair(beams, poses, &a, &b, cell, &cfg).unwrap();
            // Bit for bit: the same samples are summed in the same order.
            assert_eq!(pair_a, rasterise(beams, poses, &a, cell, &cfg).unwrap());
            assert_eq!(pair_b, rasterise(beams, poses, &b, cell, &cfg).unwrap());
            assert_ne!(pair_a, pair_b);
        }
    }

    #[test]
    fn a_ring_echo_becomes_a_closed_ring_at_its_range() {
        // Bin 49: far end at 5.0 m.
        let (beams, poses) = ring(1.8, 49);
        for interpolation in [Interpolation::Nearest, Interpolation::AngularWindow] {
            let cfg = ImageConfig {
                cell_size_m: Some(0.1),
                ..config(interpolation)
            };
            let profiles = normalise_beams(&beams, &cfg);
            let grid =
                rasterise(&beams, &poses, &profiles, cfg.cell_size_for(&beams), &cfg).unwrap();
            // Every direction (not only beam directions) finds the ring at 5 m.
            for k in 0..720 {
                let a = (k as f64 * 0.5 + 0.25).to_radians();
                // A nearest-sample ring is the digital circle of cells whose
                // centres lie within half a bin of 5 m: one cell thick, its
                // cells may touch only at corners, so look at the 3x3 cells
                // around the point.
                let (ix, iy) = grid.cell_of(5.0 * a.cos(), 5.0 * a.sin());
                let mut on: f64 = 0.0;
                for dx in -1..=1 {
                    for dy in -1..=1 {
                        on = on.max(f64::from(grid.cell(ix + dx, iy + dy)));
                    }
                }
                assert!(on > 0.3, "{interpolation:?}: hole at {a} rad: {on}");
                let (x, y) = (4.5 * a.cos(), 4.5 * a.sin());
                let (ix, iy) = grid.cell_of(x, y);
                assert_eq!(grid.cell(ix, iy), 0.0, "{interpolation:?} at 4.5 m");
                let (x, y) = (5.5 * a.cos(), 5.5 * a.sin());
                let (ix, iy) = grid.cell_of(x, y);
                assert_eq!(grid.cell(ix, iy), 0.0, "{interpolation:?} at 5.5 m");
            }
        }
    }

    #[test]
    fn closest_sample_keys_handle_the_cell_corners() {
        // Regression: at a fraction of 0 on both axes the squared offset
        // sum is 2^63, which overflowed an i64.
        let mut best = [u64::MAX];
        let mut acc = ClosestSample { best: &mut best };
        acc.put(0, 0, 0, 0.25); // a corner: the farthest a sample can be
        acc.put(0, u32::MAX, u32::MAX, 0.5); // the opposite corner
        assert_eq!(f32::from_bits(acc.best[0] as u32), 0.5);
        acc.put(0, 1 << 31, 1 << 31, 0.75); // the centre wins
        assert_eq!(f32::from_bits(acc.best[0] as u32), 0.75);
    }

    #[test]
    fn nearest_sample_takes_the_nearer_beam() {
        // Two beams 4 degrees apart; the first bright at bin 29 (3.0 m), the
        // second at bin 39 (4.0 m).
        let mk = |angle_deg: f64, bin: usize| {
            let mut intensities = vec![0u8; 60];
            intensities[bin] = 100;
            SonarBeam {
                stamp_s: 0.0,
                angle_rad: angle_deg.to_radians(),
                bin_size_m: 0.1,
                first_bin_range_m: 0.0,
                intensities,
            }
        };
        let beams = vec![mk(0.0, 29), mk(4.0, 39)];
        let poses: Vec<Se2> = beams
            .iter()
            .map(|b| Se2::new(0.0, 0.0, b.angle_rad))
            .collect();
        let cfg = ImageConfig {
            cell_size_m: Some(0.05),
            ..config(Interpolation::Nearest)
        };
        let profiles = normalise_beams(&beams, &cfg);
        let grid = rasterise(&beams, &poses, &profiles, cfg.cell_size_for(&beams), &cfg).unwrap();
        let at = |r: f64, deg: f64| {
            let a = deg.to_radians();
            let (ix, iy) = grid.cell_of(r * a.cos(), r * a.sin());
            grid.cell(ix, iy)
        };
        assert_eq!(at(3.0, 1.0), 1.0); // nearer to beam 0, which is bright at 3 m
        assert_eq!(at(3.0, 3.0), 0.0); // nearer to beam 1, dark at 3 m
        assert_eq!(at(4.0, 3.0), 1.0);
        assert_eq!(at(4.0, 1.0), 0.0);
        assert_eq!(at(3.0, 6.0), 0.0); // outside the wedge
    }

    #[test]
    fn angular_window_blends_with_triangular_weights() {
        let mk = |angle_deg: f64, value: u8| SonarBeam {
            stamp_s: 0.0,
            angle_rad: angle_deg.to_radians(),
            bin_size_m: 0.1,
            first_bin_range_m: 0.0,
            intensities: vec![value; 80],
        };
        let beams = vec![mk(0.0, 200), mk(2.0, 0)];
        let poses: Vec<Se2> = beams
            .iter()
            .map(|b| Se2::new(0.0, 0.0, b.angle_rad))
            .collect();
        let cfg = ImageConfig {
            cell_size_m: Some(0.05),
            angular_half_width_rad: 2.0_f64.to_radians(),
            ..config(Interpolation::AngularWindow)
        };
        let profiles = normalise_beams(&beams, &cfg);
        let grid = rasterise(&beams, &poses, &profiles, cfg.cell_size_for(&beams), &cfg).unwrap();
        // At bearing β (deg) the weights are 1 - β/2 and β/2, so the value is
        // 1 - β/2; a cell averages the lines through it, i.e. about the value
        // at the bearing of its centre; lines are 0.25 deg apart, so a cell's
        // mean may be off by half a line spacing times the slope (0.06).
        for deg in [0.3, 0.5, 1.0, 1.5, 1.8] {
            let a = f64::to_radians(deg);
            let (ix, iy) = grid.cell_of(7.0 * a.cos(), 7.0 * a.sin());
            let (cx, cy) = grid.cell_centre_m(ix, iy);
            let expected = 1.0 - cy.atan2(cx).to_degrees() / 2.0;
            let got = f64::from(grid.cell(ix, iy));
            assert!(
                (got - expected).abs() < 0.07,
                "{deg} deg: {got} vs {expected}"
            );
        }
    }

    #[test]
    fn gaps_wider_than_the_wedge_limit_stay_empty_and_moving_origins_are_used() {
        // Two beams 20 degrees apart: the wedge is not filled.
        let mk = |angle_deg: f64| SonarBeam {
            stamp_s: 0.0,
            angle_rad: angle_deg.to_radians(),
            bin_size_m: 0.1,
            first_bin_range_m: 0.0,
            intensities: vec![100; 50],
        };
        let beams = vec![mk(0.0), mk(20.0)];
        // The second beam's transducer was 1 m further along y.
        let poses = vec![
            Se2::new(0.0, 0.0, 0.0),
            Se2::new(0.0, 1.0, 20.0_f64.to_radians()),
        ];
        let cfg = config(Interpolation::AngularWindow);
        let profiles = normalise_beams(&beams, &cfg);
        let grid = rasterise(&beams, &poses, &profiles, cfg.cell_size_for(&beams), &cfg).unwrap();
        let a = 10.0_f64.to_radians();
        let (ix, iy) = grid.cell_of(4.0 * a.cos(), 4.0 * a.sin());
        assert_eq!(grid.cell(ix, iy), 0.0);
        let b = 20.0_f64.to_radians();
        let (ix, iy) = grid.cell_of(4.0 * b.cos(), 1.0 + 4.0 * b.sin());
        assert!(grid.cell(ix, iy) > 0.9);
    }

    /// `run_inside` holds exactly when every sample of the run passes the
    /// per-sample cell test, also for runs that start outside the grid,
    /// leave it, never enter it or stand still.
    #[test]
    fn a_run_is_inside_when_every_sample_is() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let one = FIXED_ONE as i64;
        let (mut inside, mut outside) = (0, 0);
        for case in 0..20_000 {
            let cells = rng.random_range(1..40_u64);
            let p0 = rng.random_range(-10 * one..50 * one);
            let step = match case % 3 {
                0 => 0,
                1 => rng.random_range(-one / 4..=one / 4),
                _ => rng.random_range(-one..=one),
            };
            let steps = rng.random_range(0..100_i64);
            let every = (0..=steps).all(|k| (((p0 + k * step) >> 32) as u64) < cells);
            assert_eq!(
                run_inside(p0, step, steps, cells),
                every,
                "p0 {p0}, step {step}, steps {steps}, cells {cells}"
            );
            if every { inside += 1 } else { outside += 1 }
        }
        assert!(inside > 1000 && outside > 1000, "{inside} / {outside}");
    }

    #[test]
    fn huge_images_are_refused() {
        let beams = vec![SonarBeam {
            stamp_s: 0.0,
            angle_rad: 0.0,
            bin_size_m: 1000.0,
            first_bin_range_m: 0.0,
            intensities: vec![1; 100],
        }];
        let poses = vec![Se2::new(0.0, 0.0, 0.7)];
        let cfg = config(Interpolation::Nearest);
        let profiles = normalise_beams(&beams, &cfg);
        let err =
            rasterise(&beams, &poses, &profiles, cfg.cell_size_for(&beams), &cfg).unwrap_err();
        assert!(err.to_string().contains("cells"), "{err}");
    }
}
