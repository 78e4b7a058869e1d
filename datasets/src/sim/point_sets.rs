//! Graded beams turned into what a thresholded point-set log keeps.
//!
//! The published St Pere sonar data (`datasets/stpere-marina-sonar`) are
//! not beams but the bins that passed a threshold, made per beam by the
//! data set's MATLAB scripts: the first 10 bins dropped, the profile
//! smoothed along range, a linear ramp from 0 at the first bin to 30 at the
//! last subtracted, and every bin still above 45 kept as a point. Rebuilt
//! as beams (`stpere::keyframes`), a kept bin has one intensity and every
//! other bin 0. [`to_point_sets`] applies the same recipe to simulated (or
//! real graded) beams, so that the handling of binary intensities can be
//! measured against a simulator's ground truth as well as on the real
//! data. The scripts' smoothing window is not documented; a centred moving
//! average of [`SMOOTHING_BINS`] bins stands in for it.

use echofield_frontend::sensors::SonarBeam;

/// Bins dropped at the start of every beam.
pub const DROPPED_BINS: usize = 10;
/// Width of the centred moving average along range, bins.
pub const SMOOTHING_BINS: usize = 5;
/// The ramp subtracted rises linearly from 0 to this over the beam.
pub const RAMP_END: f64 = 30.0;
/// A bin is kept when its smoothed, ramp-corrected value exceeds this.
pub const KEEP_ABOVE: f64 = 45.0;
/// The intensity of a kept bin (what the keyframe reader writes).
pub const KEPT_INTENSITY: u8 = 255;

/// Applies the point-set recipe of the module doc to every beam, in place.
pub fn to_point_sets(beams: &mut [SonarBeam]) {
    for beam in beams {
        beam.intensities = thresholded(&beam.intensities);
    }
}

fn thresholded(bins: &[u8]) -> Vec<u8> {
    let n = bins.len();
    let half = SMOOTHING_BINS / 2;
    (0..n)
        .map(|i| {
            if i < DROPPED_BINS {
                return 0;
            }
            let (lo, hi) = (
                i.saturating_sub(half).max(DROPPED_BINS),
                (i + half).min(n - 1),
            );
            let sum: f64 = bins[lo..=hi].iter().map(|&v| f64::from(v)).sum();
            let smoothed = sum / (hi - lo + 1) as f64;
            let ramp = if n > 1 {
                RAMP_END * i as f64 / (n - 1) as f64
            } else {
                0.0
            };
            if smoothed - ramp > KEEP_ABOVE {
                KEPT_INTENSITY
            } else {
                0
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_echo_becomes_a_band_and_the_floor_and_near_bins_vanish() {
        let mut bins = vec![20u8; 100];
        bins[..10].fill(250); // ringing in the dropped bins
        bins[40..44].fill(200);
        let out = thresholded(&bins);
        assert!(out[..10].iter().all(|&v| v == 0));
        // The 5-bin average of a 4-bin echo of 200 over a floor of 20 stays
        // above 45 + ramp from bin 39 to bin 44.
        let kept: Vec<usize> = (0..100).filter(|&i| out[i] > 0).collect();
        assert_eq!(kept, (39..=44).collect::<Vec<_>>());
        assert!(out.iter().all(|&v| v == 0 || v == KEPT_INTENSITY));
    }
}
