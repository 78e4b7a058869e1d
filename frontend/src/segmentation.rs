//! Beam segmentation: range extraction from one echo-intensity profile
//! (paper section 3, "beam segmentation"; the ranges become the scan `S_k`).
//!
//! Per beam:
//! 1. optional smoothing: a centred moving average over `smoothing_bins`
//!    bins (fewer at the beam ends);
//! 2. the search window: bins whose centre lies in `[blind_zone_m,
//!    max_range_m]`, and, with `ringing_below_intensity` set, past the
//!    beam's own ringing (below);
//! 3. the threshold: a return must reach `min_intensity` (0-255) and
//!    exceed `mean + min_sigma_above_mean · std` of the smoothed bins in the
//!    window (the beam's own statistics, which rejects speckle on beams that
//!    see nothing; a flat profile has no return);
//! 4. the returns: the single strongest bin of the window
//!    ([`PeakMode::Strongest`]), or up to `max_peaks` local maxima, strongest
//!    first, each at least `min_peak_separation_m` from those already taken
//!    ([`PeakMode::Multiple`]).
//!
//! **Ringing that changes from ping to ping.** A fixed blind zone has to
//! cover the longest ringing of the log and so hides every echo nearer than
//! that. At high gain a Ping360's ringing and near-field reverberation changes
//! its length from ping to ping (measured: EXPERIMENTS.md § Segmentation). With
//! `ringing_below_intensity` set, each beam's ringing is the run of
//! (smoothed) bins from the first bin outward up to the first bin below
//! that level, then down its falling edge to the first bin that is not
//! lower than the next; the search window, and the statistics of step 3,
//! start after it (or at `blind_zone_m` if that is farther). A beam that
//! never drops below the level gives no return.
//!
//! A return's range is the far end of its bin, `first_bin_range_m + (i + 1) ·
//! bin_size_m`, the same endpoint eq. (3) uses for the acoustic image, so a
//! scan and an image built from the same beams agree exactly.

use crate::error::FrontendError;
use crate::off_axis::OffAxisSuppression;
use crate::scan::beam_width::BeamWidthCorrection;
use crate::sensors::SonarBeam;
use serde::{Deserialize, Serialize};

/// How many returns one beam gives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PeakMode {
    /// The strongest bin above the threshold, if any.
    Strongest,
    /// Up to `max_peaks` separated local maxima above the threshold.
    Multiple,
}

/// Parameters of range extraction (and the minimum scan size of
/// [`crate::scan::build_scan`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SegmentationConfig {
    /// Bins whose centre is nearer than this are ignored (transducer ringing,
    /// the vehicle's own echoes), metres. Default 1.0.
    pub blind_zone_m: f64,
    /// Per-beam ringing suppression (see the module doc): the search window
    /// also starts at the first bin whose smoothed intensity (0-255) is
    /// below this level. `None` (the default) disables it. For a high-gain
    /// Ping360, about 200 (its ringing saturates at 255).
    pub ringing_below_intensity: Option<f64>,
    /// Bins whose centre is farther than this are ignored, metres; `None`
    /// (the default) uses the whole beam.
    pub max_range_m: Option<f64>,
    /// Smallest (smoothed) intensity of a return, on the 0-255 scale.
    /// Default 50.
    pub min_intensity: f64,
    /// A return must also exceed the window's mean by this many standard
    /// deviations (of the smoothed bins in the search window); 0 disables
    /// this test. Default 3.
    pub min_sigma_above_mean: f64,
    /// Strongest peak only, or several. Default `strongest`.
    pub mode: PeakMode,
    /// With `mode = multiple`, the most returns per beam (>= 1). Default 3.
    pub max_peaks: usize,
    /// With `mode = multiple`, the smallest range difference between two
    /// returns of a beam, metres. Default 1.0.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): the separation of returns of `mode = multiple`, about the range resolution of the smoothed bins.
    #[serde(skip)]
    pub min_peak_separation_m: f64,
    /// Width of the centred moving-average window, in bins; 1 means no
    /// smoothing. Default 3.
    pub smoothing_bins: usize,
    /// `build_scan` fails with `FrontendError::TooFewRanges` when a rotation
    /// gives fewer points than this. Default 10.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): the matcher's own `min_points`; a scan with fewer points cannot be matched.
    #[serde(skip)]
    pub min_scan_points: usize,
    /// The correction `build_scan` applies to the ranges for the width of
    /// the beam ([`crate::scan::beam_width`]); on by default.
    pub beam_width: BeamWidthCorrection,
    /// `build_scan` drops the returns that a neighbouring beam hears much
    /// louder at about the same range ([`crate::off_axis`]). Default on,
    /// margin 15.
    pub off_axis: OffAxisSuppression,
}

impl Default for SegmentationConfig {
    fn default() -> Self {
        Self {
            blind_zone_m: 1.0,
            ringing_below_intensity: None,
            max_range_m: None,
            min_intensity: 50.0,
            min_sigma_above_mean: 3.0,
            mode: PeakMode::Strongest,
            max_peaks: 3,
            min_peak_separation_m: 1.0,
            smoothing_bins: 3,
            min_scan_points: 10,
            beam_width: BeamWidthCorrection::default(),
            off_axis: OffAxisSuppression::for_scans(),
        }
    }
}

impl SegmentationConfig {
    pub fn validate(&self) -> Result<(), FrontendError> {
        if !(self.blind_zone_m.is_finite() && self.blind_zone_m >= 0.0) {
            return Err(FrontendError::config(
                "blind_zone_m",
                format!("must be finite and >= 0, got {}", self.blind_zone_m),
            ));
        }
        if let Some(level) = self.ringing_below_intensity
            && !(level > 0.0 && level <= 255.0)
        {
            return Err(FrontendError::config(
                "ringing_below_intensity",
                format!("must be in (0, 255], got {level}"),
            ));
        }
        if let Some(max) = self.max_range_m
            && !(max.is_finite() && max > self.blind_zone_m)
        {
            return Err(FrontendError::config(
                "max_range_m",
                format!("must be finite and > blind_zone_m, got {max}"),
            ));
        }
        if !(0.0..=255.0).contains(&self.min_intensity) {
            return Err(FrontendError::config(
                "min_intensity",
                format!("must be in [0, 255], got {}", self.min_intensity),
            ));
        }
        if !(self.min_sigma_above_mean.is_finite() && self.min_sigma_above_mean >= 0.0) {
            return Err(FrontendError::config(
                "min_sigma_above_mean",
                format!("must be finite and >= 0, got {}", self.min_sigma_above_mean),
            ));
        }
        if self.max_peaks == 0 {
            return Err(FrontendError::config("max_peaks", "must be >= 1"));
        }
        if !(self.min_peak_separation_m.is_finite() && self.min_peak_separation_m >= 0.0) {
            return Err(FrontendError::config(
                "min_peak_separation_m",
                format!(
                    "must be finite and >= 0, got {}",
                    self.min_peak_separation_m
                ),
            ));
        }
        if self.smoothing_bins == 0 {
            return Err(FrontendError::config(
                "smoothing_bins",
                "must be >= 1 (1 = no smoothing)",
            ));
        }
        self.beam_width.validate()?;
        self.off_axis.validate()
    }
}

/// One range extracted from a beam.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RangeReturn {
    /// Far end of the return's bin, metres from the transducer.
    pub range_m: f64,
    /// Smoothed intensity at the return (0-255 scale).
    pub intensity: f32,
    /// Index of the return's bin in the beam.
    pub bin: usize,
}

/// The returns of one beam, nearest first (see the module doc). A beam with
/// no bins, a non-finite or non-positive bin size, or nothing above the
/// threshold gives none. Assumes a valid config (see
/// [`SegmentationConfig::validate`]).
pub fn extract_ranges(beam: &SonarBeam, config: &SegmentationConfig) -> Vec<RangeReturn> {
    let mut scratch = Vec::new();
    let mut out = Vec::new();
    extract_ranges_into(beam, config, &mut scratch, &mut out);
    out
}

/// [`extract_ranges`] appending to `out`, reusing `smoothed` as scratch.
pub(crate) fn extract_ranges_into(
    beam: &SonarBeam,
    config: &SegmentationConfig,
    smoothed: &mut Vec<f32>,
    out: &mut Vec<RangeReturn>,
) {
    let n = beam.intensities.len();
    if n == 0 || !(beam.bin_size_m.is_finite() && beam.bin_size_m > 0.0) {
        return;
    }
    let Some(window) = search_window(beam, config) else {
        return;
    };
    smooth(&beam.intensities, config.smoothing_bins, smoothed);
    let window = match config.ringing_below_intensity {
        None => window,
        Some(level) => match ringing_end(smoothed, level) {
            Some(end) if end < window.end => window.start.max(end)..window.end,
            _ => return,
        },
    };
    let values = &smoothed[window.clone()];
    let threshold = Threshold::new(values, config);
    let start = out.len();
    let ret = |i: usize| RangeReturn {
        range_m: beam.bin_end_range_m(i),
        intensity: smoothed[i],
        bin: i,
    };
    match config.mode {
        PeakMode::Strongest => {
            if let Some(best) = strongest(values, &threshold) {
                out.push(ret(window.start + best));
            }
        }
        PeakMode::Multiple => {
            let mut peaks: Vec<usize> = local_maxima(values, &threshold)
                .into_iter()
                .map(|i| window.start + i)
                .collect();
            peaks.sort_by(|&a, &b| smoothed[b].total_cmp(&smoothed[a]).then(a.cmp(&b)));
            let min_separation_bins = config.min_peak_separation_m / beam.bin_size_m;
            for bin in peaks {
                if out.len() - start == config.max_peaks {
                    break;
                }
                let separated = out[start..]
                    .iter()
                    .all(|r| (r.bin as f64 - bin as f64).abs() >= min_separation_bins - 1e-9);
                if separated {
                    out.push(ret(bin));
                }
            }
            out[start..].sort_by_key(|r| r.bin);
        }
    }
}

/// The first maximum of `values` (the nearest of equal peaks), at the
/// centre of its plateau, when it passes `threshold`; an index in `values`.
fn strongest(values: &[f32], threshold: &Threshold) -> Option<usize> {
    let (best, value) = values
        .iter()
        .enumerate()
        .fold(
            (0, f32::NEG_INFINITY),
            |acc, (i, &v)| {
                if v > acc.1 { (i, v) } else { acc }
            },
        );
    threshold
        .passes(value)
        .then(|| plateau_centre(values, best))
}

/// The local maxima of `values` that pass `threshold`: plateaus higher
/// than both neighbours, each at its centre, in order; indices in `values`.
fn local_maxima(values: &[f32], threshold: &Threshold) -> Vec<usize> {
    let mut peaks = Vec::new();
    let mut i = 0;
    while i < values.len() {
        let v = values[i];
        let end = i + values[i + 1..].iter().take_while(|&&w| w == v).count();
        let rising = i == 0 || values[i - 1] < v;
        let falling = end + 1 == values.len() || values[end + 1] < v;
        if rising && falling && threshold.passes(v) {
            peaks.push((i + end) / 2);
        }
        i = end + 1;
    }
    peaks
}

/// The first bin after the ringing: the first bin below `level`, moved on
/// down the ringing's falling edge while the values keep decreasing (the
/// smoothing and the decay spread the edge over several bins). `None` when
/// no bin is below `level`.
fn ringing_end(smoothed: &[f32], level: f64) -> Option<usize> {
    let mut end = smoothed.iter().position(|&v| f64::from(v) < level)?;
    while end + 1 < smoothed.len() && smoothed[end + 1] < smoothed[end] {
        end += 1;
    }
    Some(end)
}

/// The middle of the run of values equal to `values[i]` that starts at `i`:
/// smoothing turns a one-bin echo into a plateau `smoothing_bins` wide, and
/// its centre is the echo's bin.
fn plateau_centre(values: &[f32], i: usize) -> usize {
    let run = values[i + 1..]
        .iter()
        .take_while(|&&v| v == values[i])
        .count();
    i + run / 2
}

/// Bins whose centre lies in `[blind_zone_m, max_range_m]`.
fn search_window(beam: &SonarBeam, config: &SegmentationConfig) -> Option<std::ops::Range<usize>> {
    let n = beam.intensities.len();
    let bin_at = |range_m: f64| (range_m - beam.first_bin_range_m) / beam.bin_size_m - 0.5;
    let first = bin_at(config.blind_zone_m).ceil().max(0.0);
    let last = config.max_range_m.map_or(n as f64 - 1.0, |max| {
        bin_at(max).floor().min(n as f64 - 1.0)
    });
    (first.is_finite() && last.is_finite() && first <= last)
        .then(|| first as usize..last as usize + 1)
}

/// Centred moving average of width `width` (`width / 2` bins before, the
/// rest after; clipped at the ends) into `out`. The acoustic image smooths
/// its beams with it too, so that scan and image peak at the same ranges.
pub(crate) fn smooth(intensities: &[u8], width: usize, out: &mut Vec<f32>) {
    out.clear();
    let n = intensities.len();
    if width <= 1 || n == 0 {
        out.extend(intensities.iter().map(|&v| v as f32));
        return;
    }
    let before = width / 2;
    let after = width - 1 - before;
    out.resize(n, 0.0);
    // Running sum over [i - before, i + after], clipped to [0, n).
    let mut sum: u32 = intensities[..after.min(n)].iter().map(|&v| v as u32).sum();
    let clipped = |i: usize, sum: &mut u32| {
        if i + after < n {
            *sum += intensities[i + after] as u32;
        }
        if i > before {
            *sum -= intensities[i - before - 1] as u32;
        }
        let count = (i + after + 1).min(n) - i.saturating_sub(before);
        *sum as f32 / count as f32
    };
    let interior = (before + 1)..n.saturating_sub(after);
    if interior.is_empty() {
        for (i, o) in out.iter_mut().enumerate() {
            *o = clipped(i, &mut sum);
        }
        return;
    }
    for (i, o) in out[..interior.start].iter_mut().enumerate() {
        *o = clipped(i, &mut sum);
    }
    // Full windows: no clipping, one add and one subtract per bin.
    let scale = 1.0 / width as f32;
    let adds = &intensities[interior.start + after..];
    let subs = &intensities[interior.start - before - 1..];
    for ((o, &add), &sub) in out[interior.clone()].iter_mut().zip(adds).zip(subs) {
        sum = sum + add as u32 - sub as u32;
        *o = sum as f32 * scale;
    }
    for (i, o) in out.iter_mut().enumerate().skip(interior.end) {
        *o = clipped(i, &mut sum);
    }
}

/// The threshold a return must pass: `v >= absolute && v > statistical`.
struct Threshold {
    absolute: f32,
    statistical: f32,
}

impl Threshold {
    fn new(values: &[f32], config: &SegmentationConfig) -> Self {
        let absolute = config.min_intensity as f32;
        if config.min_sigma_above_mean == 0.0 || values.is_empty() {
            return Self {
                absolute,
                statistical: f32::NEG_INFINITY,
            };
        }
        // One pass, four independent accumulators (the adds would otherwise
        // wait on each other); the values are at most 255.
        let (mut sum, mut sum_sq) = ([0.0f64; 4], [0.0f64; 4]);
        let chunks = values.chunks_exact(4);
        let rest = chunks.remainder();
        for chunk in chunks {
            for k in 0..4 {
                let v = chunk[k] as f64;
                sum[k] += v;
                sum_sq[k] += v * v;
            }
        }
        for (k, &v) in rest.iter().enumerate() {
            sum[k] += v as f64;
            sum_sq[k] += v as f64 * v as f64;
        }
        let (sum, sum_sq): (f64, f64) = (sum.iter().sum(), sum_sq.iter().sum());
        let n = values.len() as f64;
        let mean = sum / n;
        let var = (sum_sq / n - mean * mean).max(0.0);
        Self {
            absolute,
            statistical: (mean + config.min_sigma_above_mean * var.sqrt()) as f32,
        }
    }

    /// Strict above the statistical level, so a flat profile has no return.
    fn passes(&self, v: f32) -> bool {
        v >= self.absolute && v > self.statistical
    }
}

#[cfg(test)]
mod tests;
