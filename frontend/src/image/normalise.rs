//! Intensity normalisation of a rotation's beams to `[0, 1]`.
//!
//! For bin `i` of beam `j` with raw intensity `z_j(i)` (0-255):
//! 0. `z` is the centred moving average over `range_smoothing_bins` bins
//!    (fewer at the beam's ends; the segmentation's, see
//!    `segmentation::smooth`), rounded, when that is more than 1;
//! 1. `z = 0` where the bin's far end is inside the blind zone; bins beyond
//!    `max_range_m` are dropped; `z = 0` too where a neighbouring beam
//!    hears much louder at about the same range (`off_axis`, see
//!    [`crate::off_axis`]);
//! 2. `d = max(0, z - b(i))` with `b(i)` the `background_quantile` of
//!    `z_·(i)` over the rotation's beams (0 when that quantile is 0):
//!    echoes that sit at the same range in most beams (ringing, the noise
//!    floor's range profile) vanish, echoes of structures stay;
//! 3. `v = min(1, d / q)` with `q` the `normalisation_quantile` of all `d`
//!    of the rotation (the maximum when that quantile is 0), so a rotation's
//!    strong echoes are near 1 whatever the gain, and a few outlier bins do
//!    not squash the rest.
//!
//! Everything stays in integer histograms (intensities are `u8`), so the
//! quantiles cost one pass.

use super::ImageConfig;
use super::grid::floor;
use crate::off_axis::suppress_bins;
use crate::segmentation::smooth;
use crate::sensors::SonarBeam;

/// Normalised intensities of every beam, stored flat; `V = [f32; 2]`
/// holds two versions of every bin side by side ([`Profiles::paired`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Profiles<V = f32> {
    offsets: Vec<usize>,
    values: Vec<V>,
}

impl Profiles {
    /// Each bin of `self` next to the same bin of `other`, or `None` when
    /// their beams do not have the same numbers of bins.
    pub fn paired(&self, other: &Profiles) -> Option<Profiles<[f32; 2]>> {
        (self.offsets == other.offsets).then(|| Profiles {
            offsets: self.offsets.clone(),
            values: self
                .values
                .iter()
                .zip(&other.values)
                .map(|(&a, &b)| [a, b])
                .collect(),
        })
    }
}

impl<V> Profiles<V> {
    /// The values of every bin, flat (beam after beam): to reuse their
    /// buffer.
    pub fn into_values(self) -> Vec<V> {
        self.values
    }

    /// The normalised bins of beam `j` (possibly fewer than the raw beam's
    /// when `max_range_m` cut it).
    pub fn beam(&self, j: usize) -> &[V] {
        &self.values[self.offsets[j]..self.offsets[j + 1]]
    }

    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Number of bins of `beam` whose far end lies within `max_range_m`.
pub fn kept_bins(beam: &SonarBeam, max_range_m: Option<f64>) -> usize {
    let n = beam.intensities.len();
    match max_range_m {
        None => n,
        Some(r) => {
            let k = floor((r - beam.first_bin_range_m) / beam.bin_size_m);
            if k <= 0.0 { 0 } else { (k as usize).min(n) }
        }
    }
}

/// First bin whose far end is at or beyond the blind zone.
fn first_unmasked_bin(beam: &SonarBeam, blind_zone_m: f64) -> usize {
    let k = ((blind_zone_m - beam.first_bin_range_m) / beam.bin_size_m - 1.0).ceil();
    if k <= 0.0 { 0 } else { k as usize }
}

/// Normalised intensities one byte per bin: bin `i` of beam `j` is
/// `value(beam(j)[i])`. Every normalised value is a function of a `u8`
/// difference to the background (step 2 of the module doc), so the byte
/// and a 256-entry table hold it exactly, in a quarter of the memory of
/// [`Profiles`] of `f32`: the form an image keeps for the whole mission
/// ([`super::PolarSamples`]).
#[derive(Clone, Debug, PartialEq)]
pub struct CodedProfiles {
    codes: Profiles<u8>,
    table: Box<[f32; 256]>,
}

impl CodedProfiles {
    /// The codes of beam `j`'s bins.
    pub fn beam(&self, j: usize) -> &[u8] {
        self.codes.beam(j)
    }

    /// The normalised value of `code`.
    #[inline]
    pub fn value(&self, code: u8) -> f32 {
        self.table[usize::from(code)]
    }

    /// Bytes on the heap: codes, beam offsets and the table.
    pub fn heap_bytes(&self) -> usize {
        self.codes.values.capacity()
            + self.codes.offsets.capacity() * std::mem::size_of::<usize>()
            + std::mem::size_of::<[f32; 256]>()
    }

    /// Each bin's value next to the same bin's value in `other`, or `None`
    /// when their beams do not have the same numbers of bins: the
    /// [`Profiles::paired`] of both [`Self::decoded`], without the two
    /// `f32` copies.
    pub fn paired(&self, other: &CodedProfiles) -> Option<Profiles<[f32; 2]>> {
        self.paired_in(other, Vec::new())
    }

    /// [`Self::paired`], its values written into `buffer` (cleared first),
    /// whose allocation it reuses ([`Profiles::into_values`] gives it
    /// back). `buffer` is dropped when the beams differ.
    pub fn paired_in(
        &self,
        other: &CodedProfiles,
        mut buffer: Vec<[f32; 2]>,
    ) -> Option<Profiles<[f32; 2]>> {
        if self.codes.offsets != other.codes.offsets {
            return None;
        }
        buffer.clear();
        buffer.extend(
            self.codes
                .values
                .iter()
                .zip(&other.codes.values)
                .map(|(&a, &b)| [self.value(a), other.value(b)]),
        );
        Some(Profiles {
            offsets: self.codes.offsets.clone(),
            values: buffer,
        })
    }

    /// The values as `f32` profiles.
    pub fn decoded(&self) -> Profiles {
        Profiles {
            offsets: self.codes.offsets.clone(),
            values: self.codes.values.iter().map(|&c| self.value(c)).collect(),
        }
    }
}

/// Applies steps 1-3 of the module doc to every beam.
pub fn normalise_beams(beams: &[SonarBeam], config: &ImageConfig) -> Profiles {
    normalise_beams_coded(beams, config).decoded()
}

/// [`normalise_beams`], one byte per bin ([`CodedProfiles`]).
pub fn normalise_beams_coded(beams: &[SonarBeam], config: &ImageConfig) -> CodedProfiles {
    let (mut raw, offsets) = masked_raw(beams, config);
    // Step 1b: echoes a neighbouring beam hears much louder go.
    if let Some(first) = beams.first() {
        suppress_bins(
            &mut raw,
            &offsets,
            beams,
            first.bin_size_m,
            &config.off_axis,
        );
    }
    let lengths: Vec<usize> = offsets.windows(2).map(|w| w[1] - w[0]).collect();
    let background = background_per_bin(&raw, &offsets, &lengths, config.background_quantile);
    // Step 2 in place: the raw values become their difference to the
    // background.
    let mut hist = [0u32; 256];
    for (&start, &n) in offsets.iter().zip(&lengths) {
        for (d, &b) in raw[start..start + n].iter_mut().zip(&background) {
            *d = d.saturating_sub(b);
            hist[usize::from(*d)] += 1;
        }
    }
    let diffs = raw;
    CodedProfiles {
        table: normalisation_table(&hist, diffs.len() as u32, config),
        codes: Profiles {
            offsets,
            values: diffs,
        },
    }
}

/// Steps 0-1: the smoothed, masked raw values of every kept bin of every
/// beam, flat, and the offset of each beam's first bin (one more offset
/// than beams: the end).
fn masked_raw(beams: &[SonarBeam], config: &ImageConfig) -> (Vec<u8>, Vec<usize>) {
    let mut offsets = Vec::with_capacity(beams.len() + 1);
    offsets.push(0);
    let total: usize = beams.iter().map(|b| kept_bins(b, config.max_range_m)).sum();
    let mut raw: Vec<u8> = Vec::with_capacity(total);
    let mut smoothed = Vec::new();
    for beam in beams {
        let n = kept_bins(beam, config.max_range_m);
        let start = raw.len();
        if config.range_smoothing_bins > 1 {
            // The whole beam is smoothed: bins past `n` still enter the
            // last averages.
            smooth(
                &beam.intensities,
                config.range_smoothing_bins,
                &mut smoothed,
            );
            raw.extend(smoothed[..n].iter().map(|&v| (v + 0.5) as u8));
        } else {
            raw.extend_from_slice(&beam.intensities[..n]);
        }
        let masked = first_unmasked_bin(beam, config.blind_zone_m).min(n);
        raw[start..start + masked].fill(0);
        offsets.push(raw.len());
    }
    (raw, offsets)
}

/// The background of every range bin: the `quantile` of that bin over
/// the beams that reach it (0 everywhere for a quantile <= 0).
fn background_per_bin(raw: &[u8], offsets: &[usize], lengths: &[usize], quantile: f64) -> Vec<u8> {
    let max_bins = lengths.iter().copied().max().unwrap_or(0);
    if quantile <= 0.0 {
        return vec![0; max_bins];
    }
    let mut hist = [0u32; 256];
    (0..max_bins)
        .map(|i| {
            hist.fill(0);
            let mut count = 0u32;
            for (&start, &n) in offsets.iter().zip(lengths) {
                if n > i {
                    hist[usize::from(raw[start + i])] += 1;
                    count += 1;
                }
            }
            histogram_quantile(&hist, count, quantile)
        })
        .collect()
}

/// The value of each difference code 0-255 (step 3): divided by the
/// `normalisation_quantile` of the differences (`hist` over `total`
/// bins; their largest when that quantile is 0), clamped to 1 and raised
/// to `intensity_exponent`. All zero when every difference is 0.
fn normalisation_table(hist: &[u32; 256], total: u32, config: &ImageConfig) -> Box<[f32; 256]> {
    let mut scale = histogram_quantile(hist, total, config.normalisation_quantile);
    if scale == 0 {
        scale = hist.iter().rposition(|&c| c > 0).unwrap_or(0) as u8;
    }
    let mut table = Box::new([0.0_f32; 256]);
    if scale > 0 {
        let inv = 1.0 / f64::from(scale);
        let gamma = config.intensity_exponent;
        for (d, v) in table.iter_mut().enumerate() {
            *v = (d as f64 * inv).min(1.0).powf(gamma) as f32;
        }
    }
    table
}

/// The moving average of the segmentation, rounded to u8 as the image
/// uses it.
#[cfg(test)]
fn moving_average(values: &[u8], width: usize) -> Vec<u8> {
    let mut smoothed = Vec::new();
    smooth(values, width, &mut smoothed);
    smoothed.iter().map(|&v| (v + 0.5) as u8).collect()
}

/// The value of rank `floor(q·(count-1))` (0-based, ascending) in a
/// histogram of `count` samples; 0 for an empty histogram.
fn histogram_quantile(hist: &[u32; 256], count: u32, q: f64) -> u8 {
    if count == 0 {
        return 0;
    }
    let rank = (q * f64::from(count - 1)).floor() as u32;
    let mut seen = 0u32;
    for (value, &c) in hist.iter().enumerate() {
        seen += c;
        if seen > rank {
            return value as u8;
        }
    }
    255
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::off_axis::OffAxisSuppression;

    fn beam(intensities: Vec<u8>) -> SonarBeam {
        SonarBeam {
            stamp_s: 0.0,
            angle_rad: 0.0,
            bin_size_m: 0.5,
            first_bin_range_m: 0.0,
            intensities,
        }
    }

    #[test]
    fn quantile_of_a_histogram() {
        let mut hist = [0u32; 256];
        for v in [3u8, 1, 4, 1, 5, 9, 2, 6, 5] {
            hist[usize::from(v)] += 1;
        }
        // Sorted: 1 1 2 3 4 5 5 6 9.
        assert_eq!(histogram_quantile(&hist, 9, 0.0), 1);
        assert_eq!(histogram_quantile(&hist, 9, 0.5), 4);
        assert_eq!(histogram_quantile(&hist, 9, 1.0), 9);
        assert_eq!(histogram_quantile(&[0; 256], 0, 0.5), 0);
    }

    #[test]
    fn blind_zone_background_and_scale() {
        // Bin far ends at 0.5, 1.0, 1.5, 2.0, 2.5 m.
        let beams = vec![
            beam(vec![200, 40, 10, 100, 10]),
            beam(vec![200, 40, 10, 10, 10]),
            beam(vec![200, 40, 50, 10, 10]),
        ];
        let config = ImageConfig {
            range_smoothing_bins: 1,
            blind_zone_m: 0.9, // masks bin 0 (far end 0.5 m), keeps bin 1 (1.0 m)
            background_quantile: 0.5,
            normalisation_quantile: 1.0,
            max_range_m: Some(2.0), // keeps bins 0-3
            // The three beams share one angle (neighbours by the rule).
            off_axis: OffAxisSuppression::off(),
            ..ImageConfig::default()
        };
        let p = normalise_beams(&beams, &config);
        assert_eq!(p.len(), 3);
        // Background per bin: 0, 40, 10, 10. Differences: beam 0 bin 3 = 90,
        // beam 2 bin 2 = 40; everything else 0. Scale = max = 90.
        assert_eq!(p.beam(0), &[0.0, 0.0, 0.0, 1.0]);
        assert_eq!(p.beam(1), &[0.0, 0.0, 0.0, 0.0]);
        let b2 = p.beam(2);
        assert!((b2[2] - 40.0 / 90.0).abs() < 1e-6 && b2[3] == 0.0);
    }

    #[test]
    fn quantile_scale_clamps_outliers() {
        let mut values = vec![0u8; 100];
        values[10] = 50;
        values[20] = 50;
        values[30] = 250; // one outlier
        let beams = vec![beam(values)];
        let config = ImageConfig {
            range_smoothing_bins: 1,
            blind_zone_m: 0.0,
            background_quantile: 0.0,
            normalisation_quantile: 0.98, // rank 97 of 100 sorted -> 50
            ..ImageConfig::default()
        };
        let p = normalise_beams(&beams, &config);
        assert_eq!(p.beam(0)[10], 1.0);
        assert_eq!(p.beam(0)[30], 1.0);
        assert_eq!(p.beam(0)[0], 0.0);
    }

    #[test]
    fn moving_average_is_centred_and_clipped_at_the_ends() {
        // Width 3: one bin before, one after; the ends average two bins.
        assert_eq!(
            moving_average(&[0, 30, 60, 0, 3], 3),
            vec![15, 30, 30, 21, 2]
        );
        // Width 4: two before, one after.
        assert_eq!(moving_average(&[4, 8, 12, 16], 4), vec![6, 8, 10, 12]);
        assert_eq!(moving_average(&[7], 5), vec![7]);
        // The smoothed peak of an echo with a tail lies where a range
        // extractor smoothing the same way finds it: bin 2, not bin 1.
        let echo = [0u8, 180, 170, 40, 0];
        let s = moving_average(&echo, 3);
        assert_eq!((0..5).max_by_key(|&i| s[i]).unwrap(), 2);
    }

    #[test]
    fn kept_bins_respects_first_bin_range() {
        let mut b = beam(vec![0; 10]);
        assert_eq!(kept_bins(&b, None), 10);
        assert_eq!(kept_bins(&b, Some(2.0)), 4);
        b.first_bin_range_m = 1.0;
        assert_eq!(kept_bins(&b, Some(2.0)), 2);
        assert_eq!(kept_bins(&b, Some(0.5)), 0);
        assert_eq!(first_unmasked_bin(&b, 0.0), 0);
        assert_eq!(first_unmasked_bin(&b, 2.0), 1);
    }
}
