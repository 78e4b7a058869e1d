//! Scan-only sonar data: beams whose intensities are binary.
//!
//! Many published MSIS logs keep only the bins above a threshold (the St
//! Pere point sets), or only ranges (a LaserScan). Rebuilt as beams, such
//! data has one intensity where an echo passed the threshold and 0
//! elsewhere, and a wall arrives as a *band* of bins 1-3 m (up to 10 m)
//! thick along range rather than as a peak. Fed as they are, the bands
//! make a poor likelihood field for eq. (5): the image is flat across each
//! band, so `s(x)` has a plateau as wide as the band along every beam and
//! the maximum of eq. (6) is anywhere on it, and the scan's range (the
//! centre of the first plateau) is one point among many equal ones.
//!
//! [`band_profiles`] turns every band into the profile its own
//! correlation would give: the band `[a, b]` (bins, width `w = b − a + 1`)
//! becomes a triangle that peaks at its centre `c = (a + b) / 2` and falls
//! linearly to 0 at `c ± w`,
//!
//! ```text
//! p(i) = max(0, 1 − |i − c| / w)        (band ⊛ box of width w, over w)
//! ```
//!
//! scaled to the beam's intensity scale and combined over bands by their
//! maximum. The segmentation then takes the centre of a band as its range
//! (the profile's single peak), the image peaks at the same range, and a
//! scan point that lies `d` bins off the band's centre scores `1 − d / w`:
//! the score of eq. (5) falls away from the true pose on every beam, the
//! more slowly the thicker (less certain) the band. No parameter: the
//! band's own width sets the spread.
//!
//! The centre rather than the leading edge: a band is where a beam of
//! finite width, spread along range by the pulse and the smoothing before
//! the threshold, saw a surface; its near edge is where the beam's edge
//! first touched it, which moves with the viewpoint, while its centre
//! stays near the axis's range.

use crate::sensors::SonarBeam;
use serde::{Deserialize, Serialize};

/// What a mission's beam intensities are.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum IntensityKind {
    /// Echo intensities on a graded scale (a head's own log).
    Graded,
    /// One non-zero `level` and 0: thresholded data (see the module doc).
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

/// Replaces every band of non-zero bins of `beam` by its triangular
/// profile (module doc), peaking at `level`.
pub fn band_profile(beam: &mut SonarBeam, level: u8) {
    let bins = &beam.intensities;
    let n = bins.len();
    let mut out = vec![0u8; n];
    let mut i = 0;
    while i < n {
        if bins[i] == 0 {
            i += 1;
            continue;
        }
        let start = i;
        while i < n && bins[i] != 0 {
            i += 1;
        }
        let width = (i - start) as f64;
        let centre = 0.5 * (start + i - 1) as f64;
        let lo = (centre - width).ceil().max(0.0) as usize;
        let hi = ((centre + width).floor() as usize).min(n - 1);
        for (k, slot) in out.iter_mut().enumerate().take(hi + 1).skip(lo) {
            let p = 1.0 - (k as f64 - centre).abs() / width;
            let value = (p * f64::from(level)).round() as u8;
            *slot = (*slot).max(value);
        }
    }
    beam.intensities = out;
}

/// [`band_profile`] on every beam.
pub fn band_profiles(beams: &mut [SonarBeam], level: u8) {
    for beam in beams {
        band_profile(beam, level);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
    fn a_band_becomes_a_triangle_peaked_at_its_centre() {
        // Band of 4 bins at 10..=13: centre 11.5, zero at 7.5 and 15.5.
        let mut bins = vec![0u8; 20];
        bins[10..14].fill(255);
        let mut b = beam(bins);
        band_profile(&mut b, 200);
        let p = &b.intensities;
        assert_eq!(p[11], p[12]);
        assert_eq!(p[11], 175); // 1 - 0.5/4 = 0.875 of 200
        assert_eq!(p[10], 125); // 1 - 1.5/4
        assert_eq!(p[9], 75);
        assert_eq!(p[8], 25);
        assert_eq!(p[7], 0);
        assert_eq!(p[16], 0);
        assert!(p[..11].windows(2).all(|w| w[1] >= w[0]));
        assert!(p[12..].windows(2).all(|w| w[1] <= w[0]));
    }

    #[test]
    fn a_single_bin_keeps_its_peak_and_bands_overlap_by_maximum() {
        let mut bins = vec![0u8; 12];
        bins[2] = 9;
        bins[6..9].fill(9);
        let mut b = beam(bins);
        band_profile(&mut b, 90);
        let p = &b.intensities;
        assert_eq!(p[2], 90);
        assert_eq!((p[1], p[3]), (0, 0));
        assert_eq!(p[7], 90);
        assert_eq!(p[5], 30);
        assert_eq!(p[4], 0);
        assert_eq!(p[10], 0);
    }
}
