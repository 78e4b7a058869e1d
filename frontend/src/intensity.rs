//! Scan-only sonar data: beams whose intensities are binary.
//!
//! Many published MSIS logs keep only the bins above a threshold (the St
//! Pere point sets), or only one range per beam (a LaserScan). Rebuilt as
//! beams, such data has one intensity where an echo passed the threshold
//! and 0 elsewhere: a wall arrives as a *band* of bins, metres thick along
//! range in the St Pere data, a LaserScan return as a single
//! bin. [`detect`] recognises such data from the beams themselves.
//!
//! # How `S_k` and `I_k` are built from bands
//!
//! A band says that the surface lies somewhere between its ends; the
//! threshold removed whatever would tell where. So:
//!
//! - **`I_k`** keeps the bands as they are: the likelihood of a return is
//!   uniform across a band and 0 outside it (after the image's usual
//!   normalisation every band has value 1). The score of eq. (5) then
//!   counts the scan points that land inside bands, and eq. (6) finds the
//!   pose that puts the most of them there; where several poses tie, the
//!   match's covariance (fitted to the score surface) is wide along the
//!   directions of the tie.
//! - **`S_k`** takes one range per beam: the centre of the beam's
//!   *nearest* band (the first surface the beam met; bands behind it are
//!   reverberation, multipath or what the beam saw over the wall). With
//!   the segmentation's default 3-bin smoothing a band reaches the full
//!   level only when it is at least 3 bins thick, so [`widen_bands`] first
//!   widens every band thinner than `min_band_bins` to that width about
//!   its centre; then the strongest (smoothed) bin is the nearest band's
//!   plateau and the segmentation returns its centre.
//! - Widening also keeps single-bin returns (ranges-only data) resolvable
//!   on the image's raster: the pipeline asks for two raster cells.
//! - Binary data carries no echo strength, so the two stages that compare
//!   intensities do not apply and are switched off by the pipeline
//!   ([`prepare`]): the off-axis suppression (which needs a
//!   neighbour that hears the target louder) and the beam-width
//!   correction (which models how a graded echo's peak falls short of the
//!   beam's axis; a band's centre already lies near the axis range).
//!
//! The alternatives measured before this choice (triangular profiles
//! peaked at each band's centre, bands weighted by their width, every band
//! bin as a scan point, Gaussian-smoothed bands) and their figures on the
//! real St Pere point sets and on simulated missions thresholded the same
//! way are in README.md, section "Real data".

use crate::image::ImageConfig;
use crate::segmentation::SegmentationConfig;
use crate::sensors::SonarBeam;
use serde::{Deserialize, Serialize};

/// What a mission's beam intensities are.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum IntensityKind {
    /// Echo intensities on a graded scale (a head's own log).
    Graded,
    /// One non-zero `level` and 0: thresholded or ranges-only data.
    Binary { level: u8 },
    /// No bin above 0 at all.
    Empty,
}

/// Looks at every bin: [`IntensityKind::Binary`] when all non-zero bins
/// hold one value.
pub fn detect(beams: &[SonarBeam]) -> IntensityKind {
    let mut level: Option<u8> = None;
    for &v in beams.iter().flat_map(|b| &b.intensities) {
        if v == 0 {
            continue;
        }
        match level {
            None => level = Some(v),
            Some(l) if l != v => return IntensityKind::Graded,
            Some(_) => {}
        }
    }
    match level {
        Some(level) => IntensityKind::Binary { level },
        None => IntensityKind::Empty,
    }
}

/// Widens every band (run of non-zero bins) of `beam` thinner than
/// `min_band_bins` to that width about its centre (the extra bin of an
/// odd difference goes on the far side), at the band's own level. Bands
/// that grow into each other merge. Bins beyond the beam's ends are not
/// added.
pub fn widen_bands(beam: &mut SonarBeam, min_band_bins: usize) {
    let n = beam.intensities.len();
    let mut out = beam.intensities.clone();
    let mut i = 0;
    while i < n {
        let level = beam.intensities[i];
        if level == 0 {
            i += 1;
            continue;
        }
        let start = i;
        while i < n && beam.intensities[i] != 0 {
            i += 1;
        }
        let width = i - start;
        if width < min_band_bins {
            let extra = min_band_bins - width;
            let lo = start.saturating_sub(extra / 2);
            let hi = (i + extra - extra / 2).min(n);
            for v in &mut out[lo..hi] {
                *v = (*v).max(level);
            }
        }
    }
    beam.intensities = out;
}

/// [`widen_bands`] on every beam, each to at least `min_band_m` (in its
/// own bins, rounded up) and at least `min_bins`.
pub fn widen_all(beams: &mut [SonarBeam], min_band_m: f64, min_bins: usize) {
    for beam in beams {
        let bins = if beam.bin_size_m > 0.0 && min_band_m.is_finite() {
            (min_band_m / beam.bin_size_m).ceil().max(0.0) as usize
        } else {
            0
        };
        widen_bands(beam, bins.max(min_bins));
    }
}

/// Switches off the stages that compare intensities (module doc): what
/// [`prepare`] changes in the settings of binary data. Returns the
/// settings changed, as `key = value` with TOML paths.
pub fn binary_settings(
    segmentation: &mut SegmentationConfig,
    image: &mut ImageConfig,
) -> [&'static str; 3] {
    segmentation.off_axis.enabled = false;
    image.off_axis.enabled = false;
    segmentation.beam_width.enabled = false;
    [
        "segmentation.off_axis.enabled = false",
        "image.off_axis.enabled = false",
        "segmentation.beam_width.enabled = false",
    ]
}

/// What [`prepare`] found and changed.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Preparation {
    pub kind: IntensityKind,
    /// The settings changed for binary data (`key = value`, TOML paths
    /// under the segmentation and image sections), empty otherwise.
    pub derived: Vec<String>,
}

/// Prepares a mission's beams and the scan and image settings for their
/// intensities, in place (the one place both pipelines call): for binary
/// data, the level is set to 255, every band is widened to at least two raster cells of `image`
/// (for the beams given) and at least the segmentation's smoothing window
/// ([`widen_all`]), and the off-axis suppressions and the beam-width
/// correction are switched off (module doc). Graded and empty data are
/// left as they are.
pub fn prepare(
    beams: &mut [SonarBeam],
    segmentation: &mut SegmentationConfig,
    image: &mut ImageConfig,
) -> Preparation {
    let kind = detect(beams);
    let derived = match kind {
        IntensityKind::Binary { .. } => prepare_binary(beams, segmentation, image),
        IntensityKind::Graded | IntensityKind::Empty => Vec::new(),
    };
    Preparation { kind, derived }
}

/// The binary part of [`prepare`], for a caller that has already
/// [`detect`]ed binary intensities; returns what it derived.
pub fn prepare_binary(
    beams: &mut [SonarBeam],
    segmentation: &mut SegmentationConfig,
    image: &mut ImageConfig,
) -> Vec<String> {
    // One level means "a return": at full scale, so that the thresholds
    // in counts (`segmentation.min_intensity`) treat every band alike.
    for v in beams.iter_mut().flat_map(|b| b.intensities.iter_mut()) {
        if *v > 0 {
            *v = u8::MAX;
        }
    }
    let min_band_m = 2.0 * image.cell_size_for(beams);
    widen_all(beams, min_band_m, segmentation.smoothing_bins);
    binary_settings(segmentation, image)
        .into_iter()
        .map(String::from)
        .chain(std::iter::once(format!(
            "bands thinner than {min_band_m:.2} m widened to it"
        )))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::segmentation::{SegmentationConfig, extract_ranges};

    fn beam(intensities: Vec<u8>) -> SonarBeam {
        SonarBeam {
            stamp_s: 0.0,
            angle_rad: 0.0,
            bin_size_m: 0.1,
            first_bin_range_m: 0.0,
            intensities,
        }
    }

    #[test]
    fn detects_binary_graded_and_empty_beams() {
        let binary = [beam(vec![0, 200, 200, 0]), beam(vec![200, 0, 0, 0])];
        assert_eq!(detect(&binary), IntensityKind::Binary { level: 200 });
        let graded = [beam(vec![0, 200, 201, 0])];
        assert_eq!(detect(&graded), IntensityKind::Graded);
        assert_eq!(detect(&[beam(vec![0; 4])]), IntensityKind::Empty);
    }

    #[test]
    fn thin_bands_widen_about_their_centre_and_thick_ones_stay() {
        let mut bins = vec![0u8; 30];
        bins[5] = 9; // a single bin
        bins[10..12].fill(9); // two bins
        bins[20..26].fill(9); // six bins
        let mut b = beam(bins);
        widen_bands(&mut b, 4);
        let lit: Vec<usize> = (0..30).filter(|&i| b.intensities[i] > 0).collect();
        let expected: Vec<usize> = [4, 5, 6, 7, 9, 10, 11, 12]
            .into_iter()
            .chain(20..26)
            .collect();
        assert_eq!(lit, expected);
        // At the beam's end nothing is added beyond it.
        let mut end = beam(vec![0, 0, 0, 7]);
        widen_bands(&mut end, 4);
        assert_eq!(end.intensities, vec![0, 0, 7, 7]);
    }

    /// The segmentation's range of a binary beam is the centre of its
    /// nearest band, whatever the bands' widths.
    #[test]
    fn the_scan_takes_the_centre_of_the_nearest_band() {
        let config = SegmentationConfig {
            min_sigma_above_mean: 0.0,
            ..SegmentationConfig::default()
        };
        // Bands at bins 40..=41 (thin), 100..=159 (thick), 300.
        let mut bins = vec![0u8; 400];
        bins[40..42].fill(255);
        bins[100..160].fill(255);
        bins[300] = 255;
        let mut b = beam(bins);
        widen_bands(&mut b, 4);
        let ranges = extract_ranges(&b, &config);
        assert_eq!(ranges.len(), 1);
        // Widened to 39..=42: centre 40.5, the plateau centre bin 40 or 41,
        // whose far ends are 4.1 and 4.2 m.
        assert!((ranges[0].range_m - 4.15).abs() < 0.06, "{ranges:?}");
    }
}
