//! Off-axis echo suppression: dropping what a beam hears from a target
//! that lies on its neighbour's axis.
//!
//! A beam of horizontal width `β` hears a strong target while its axis is
//! still up to about `β` away from it. Each beam's echoes are placed on the
//! beam's own axis, so a post, a wall's end or a pontoon corner is drawn
//! as an arc, about `2β·r` long at range `r`, in the scan and in the image
//! alike. The arc is longer the farther the target, so the same corner
//! seen from two rotations at different ranges does not line up, and the
//! matches come out biased.
//!
//! A bias of one sign does not average out in the pose graph: it shrinks and
//! bends the map. On a simulated mission with exact navigation the suppression
//! removes most of the matches' shortening along the displacement, which a
//! narrow beam does not have (measured: EXPERIMENTS.md § Off-axis suppression).
//!
//! The rule: an echo of beam `j` at range `r` and (smoothed) intensity
//! `z` is dropped when a beam within `max_angle_rad` of `j` holds an echo
//! within `max_range_difference_m` of `r` whose intensity exceeds `z` by
//! more than `margin`. A wall seen by neighbouring beams at about the same
//! range and strength stays; so does a wall at oblique incidence, whose
//! neighbouring echoes lie at other ranges. The margin is in the 0-255
//! units of the beams: heads that map decibels linearly onto counts (a
//! Tritech Miniking maps about 80 dB onto 0-255, ~3.2 counts per dB; the
//! simulator does the same) drop what is 5-8 dB weaker than the
//! neighbour's echo. A target on the neighbour's axis is 4.3 dB weaker one
//! 1.8° step off it with a 3° two-way beam, and 17 dB weaker two steps
//! off, so the suppression removes the arc beyond the nearest beams.
//!
//! The scan ([`crate::scan::build_scan`]) compares its returns
//! ([`keep_returns`]); the image ([`crate::image`]) compares every bin of
//! the smoothed beams before its background is subtracted
//! ([`suppress_bins`]), with a larger margin so that the returns the scan
//! keeps also stay in the image.
//!
//! **The image's margin and the heading bias.** The image's off-axis echoes
//! leave the matches a small heading bias; a smaller image margin removes it,
//! but also removes echoes that the scans keep, so the mean intensity under a
//! loop's points drops and the loop gate `loops.gate.min_mean_intensity` rejects
//! right loops. The searched image therefore keeps the larger margin, and the
//! matcher's last step reads a second raster with a smaller one and no range
//! smoothing ([`crate::image::PoseFitRaster`]): the pose gains the smaller bias
//! while the search and the gates keep the image they were set for. Part of the
//! bias is not explained by the arcs. Measured: EXPERIMENTS.md § Off-axis
//! suppression.

use crate::error::FrontendError;
use crate::sensors::SonarBeam;
use echofield_graph::wrap_angle;
use serde::{Deserialize, Serialize};

/// Parameters of the off-axis echo suppression (module doc).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OffAxisSuppression {
    /// Off: every echo stays.
    pub enabled: bool,
    /// How much stronger (0-255 intensity units of the smoothed beams) a
    /// neighbour's echo must be to drop one.
    pub margin: f64,
    /// Beams whose angles differ by at most this are neighbours, radians:
    /// about the horizontal beam width. Default 3°.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): about the horizontal beam width of the sonars echofield reads (3°).
    #[serde(skip)]
    pub max_angle_rad: f64,
    /// Echoes of two neighbours are compared when their ranges differ by at
    /// most this, metres. Default 0.3.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): about the range resolution of the smoothed bins.
    #[serde(skip)]
    pub max_range_difference_m: f64,
}

impl OffAxisSuppression {
    /// The scan's default: margin 15.
    pub fn for_scans() -> Self {
        Self {
            margin: 15.0,
            ..Self::default()
        }
    }

    /// The image's default: margin 25.
    pub fn for_images() -> Self {
        Self {
            margin: 25.0,
            ..Self::default()
        }
    }

    /// No suppression.
    pub fn off() -> Self {
        Self {
            enabled: false,
            ..Self::default()
        }
    }

    /// Errors name the field as `off_axis.<field>`.
    pub fn validate(&self) -> Result<(), FrontendError> {
        let check = |field: &str, value: f64, ok: bool| {
            if ok {
                Ok(())
            } else {
                Err(FrontendError::config(
                    format!("off_axis.{field}"),
                    format!("out of range: {value}"),
                ))
            }
        };
        check(
            "margin",
            self.margin,
            self.margin.is_finite() && (0.0..=255.0).contains(&self.margin),
        )?;
        check(
            "max_angle_rad",
            self.max_angle_rad,
            self.max_angle_rad.is_finite() && self.max_angle_rad > 0.0 && self.max_angle_rad <= 0.5,
        )?;
        check(
            "max_range_difference_m",
            self.max_range_difference_m,
            self.max_range_difference_m.is_finite() && self.max_range_difference_m >= 0.0,
        )
    }
}

impl Default for OffAxisSuppression {
    /// Enabled, margin 20, neighbours within 3° and 0.3 m.
    fn default() -> Self {
        Self {
            enabled: true,
            margin: 20.0,
            max_angle_rad: 3f64.to_radians(),
            max_range_difference_m: 0.3,
        }
    }
}

/// One echo of a scan: its beam (index into the rotation's beams, echoes
/// in ascending beam order), range and intensity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Echo {
    pub beam: usize,
    pub range_m: f64,
    pub intensity: f64,
}

/// Which of `echoes` (sorted by beam) to keep under `config`; `angles[b]`
/// is beam `b`'s transducer angle. All are kept when it is disabled.
pub fn keep_returns(echoes: &[Echo], angles: &[f64], config: &OffAxisSuppression) -> Vec<bool> {
    let n = echoes.len();
    if !config.enabled {
        return vec![true; n];
    }
    let near = |a: usize, b: usize| {
        wrap_angle(angles[echoes[a].beam] - angles[echoes[b].beam]).abs() <= config.max_angle_rad
    };
    let louder = |i: usize, k: usize| {
        echoes[k].beam != echoes[i].beam
            && (echoes[k].range_m - echoes[i].range_m).abs() <= config.max_range_difference_m
            && echoes[k].intensity > echoes[i].intensity + config.margin
    };
    (0..n)
        .map(|i| {
            // Neighbours are the echoes of the nearby beams on either side,
            // up to the first beam that is too far in angle.
            let before = (0..i)
                .rev()
                .take_while(|&k| echoes[k].beam == echoes[i].beam || near(k, i))
                .any(|k| louder(i, k));
            let after = (i + 1..n)
                .take_while(|&k| echoes[k].beam == echoes[i].beam || near(k, i))
                .any(|k| louder(i, k));
            !(before || after)
        })
        .collect()
}

/// Sets to 0 every bin of the flat `values` (beam `j`'s bins are
/// `values[offsets[j]..offsets[j + 1]]`, bin `i` at the same range in every
/// beam) that a neighbouring beam within `config.max_angle_rad` exceeds by
/// more than `config.margin` within `config.max_range_difference_m`
/// (`bin_size_m` per bin). Comparisons use the values before any is set
/// to 0. Nothing changes when it is disabled.
pub fn suppress_bins(
    values: &mut [u8],
    offsets: &[usize],
    beams: &[SonarBeam],
    bin_size_m: f64,
    config: &OffAxisSuppression,
) {
    if !config.enabled || beams.len() < 2 || bin_size_m.is_nan() || bin_size_m <= 0.0 {
        return;
    }
    let reach = (config.max_range_difference_m / bin_size_m).round() as usize;
    // Each beam's maximum over ±reach bins.
    let mut dilated = vec![0u8; values.len()];
    for j in 0..beams.len() {
        let (start, end) = (offsets[j], offsets[j + 1]);
        window_max(&values[start..end], reach, &mut dilated[start..end]);
    }
    let margin = config.margin.round().clamp(0.0, 255.0) as u8;
    // In place: a bin cleared by one neighbour compares as 0 with the
    // next, which can only clear it again, and the neighbours' maxima were
    // taken before anything was cleared.
    for j in 0..beams.len() {
        let neighbours = |step: isize| {
            (1..)
                .map(move |d| j as isize + step * d)
                .take_while(|&k| k >= 0 && (k as usize) < beams.len())
                .map(|k| k as usize)
                .take_while(|&k| {
                    wrap_angle(beams[k].angle_rad - beams[j].angle_rad).abs()
                        <= config.max_angle_rad
                })
        };
        for k in neighbours(-1).chain(neighbours(1)) {
            let n = (offsets[j + 1] - offsets[j]).min(offsets[k + 1] - offsets[k]);
            let theirs = &dilated[offsets[k]..offsets[k] + n];
            for (v, &t) in values[offsets[j]..offsets[j] + n].iter_mut().zip(theirs) {
                // t > v + margin, without overflow; branch-free so that
                // the loop vectorises.
                *v = if t.saturating_sub(margin) > *v { 0 } else { *v };
            }
        }
    }
}

/// `out[i] = max(values[i - reach ..= i + reach])` (clipped at the ends),
/// one shifted pass per offset so that the loops vectorise.
fn window_max(values: &[u8], reach: usize, out: &mut [u8]) {
    let n = values.len();
    out.copy_from_slice(values);
    for s in 1..=reach.min(n.saturating_sub(1)) {
        for (o, &v) in out[..n - s].iter_mut().zip(&values[s..]) {
            *o = (*o).max(v);
        }
        for (o, &v) in out[s..].iter_mut().zip(&values[..n - s]) {
            *o = (*o).max(v);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn echo(beam: usize, range_m: f64, intensity: f64) -> Echo {
        Echo {
            beam,
            range_m,
            intensity,
        }
    }

    /// Beams every 1.8°.
    fn angles(n: usize) -> Vec<f64> {
        (0..n).map(|j| (1.8 * j as f64).to_radians()).collect()
    }

    #[test]
    fn an_arc_around_a_target_shrinks_to_its_beams() {
        // A target on beam 5's axis at 20 m: 150 there, 4 dB (13 counts)
        // weaker one step off, 17 dB (54 counts) weaker two steps off; a
        // wall at 30 m seen evenly by every beam.
        let mut echoes = Vec::new();
        for (beam, intensity) in [(3, 96.0), (4, 137.0), (5, 150.0), (6, 137.0), (7, 96.0)] {
            echoes.push(echo(beam, 20.05, intensity));
        }
        for beam in 0..10 {
            echoes.push(echo(beam, 30.0, 120.0 + (beam % 3) as f64));
        }
        echoes.sort_by_key(|e| e.beam);
        let keep = keep_returns(&echoes, &angles(10), &OffAxisSuppression::for_scans());
        let kept: Vec<(usize, f64)> = echoes
            .iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(e, _)| (e.beam, e.range_m))
            .collect();
        // Beams 3 and 7 at 20 m go (54 counts below beam 5, two steps and
        // 3.6° away, but 41 below beams 4 and 6, one step away); 4 and 6
        // stay (13 below, within the margin); every wall echo stays.
        let arc: Vec<usize> = kept.iter().filter(|k| k.1 < 25.0).map(|k| k.0).collect();
        assert_eq!(arc, vec![4, 5, 6]);
        assert_eq!(kept.iter().filter(|k| k.1 > 25.0).count(), 10);
        // Disabled: everything stays.
        assert!(
            keep_returns(&echoes, &angles(10), &OffAxisSuppression::off())
                .iter()
                .all(|&k| k)
        );
    }

    #[test]
    fn echoes_at_other_ranges_or_angles_are_not_compared() {
        let config = OffAxisSuppression::for_scans();
        // 0.5 m apart in range: an oblique wall, not an arc.
        let echoes = [echo(0, 20.0, 60.0), echo(1, 20.5, 200.0)];
        assert_eq!(keep_returns(&echoes, &angles(2), &config), vec![true, true]);
        // 5.4° apart: beyond the beam width.
        let echoes = [echo(0, 20.0, 60.0), echo(3, 20.0, 200.0)];
        assert_eq!(keep_returns(&echoes, &angles(4), &config), vec![true, true]);
        // Two echoes of one beam are never compared with each other.
        let echoes = [echo(0, 20.0, 60.0), echo(0, 20.1, 200.0)];
        assert_eq!(keep_returns(&echoes, &angles(1), &config), vec![true, true]);
    }

    fn beam(angle_deg: f64, intensities: Vec<u8>) -> SonarBeam {
        SonarBeam {
            stamp_s: 0.0,
            angle_rad: angle_deg.to_radians(),
            bin_size_m: 0.1,
            first_bin_range_m: 0.0,
            intensities,
        }
    }

    #[test]
    fn bins_far_below_a_neighbour_nearby_are_cleared() {
        let beams = [
            beam(0.0, vec![0; 10]),
            beam(1.8, vec![0; 10]),
            beam(3.6, vec![0; 10]),
        ];
        // Beam 1 holds a strong echo at bin 5; beam 0 its off-axis copy two
        // bins further (within 0.3 m) and 60 counts weaker, beam 2 a copy 10
        // counts weaker, and a weak echo at bin 0 that nothing exceeds.
        #[rustfmt::skip]
        let mut values: Vec<u8> = vec![
            0, 0, 0, 0, 0, 0, 0, 100, 0, 0,
            0, 0, 0, 0, 0, 160, 0, 0, 0, 0,
            40, 0, 0, 0, 0, 150, 0, 0, 0, 0,
        ];
        let offsets = [0, 10, 20, 30];
        let config = OffAxisSuppression::for_images();
        suppress_bins(&mut values, &offsets, &beams, 0.1, &config);
        assert_eq!(values[7], 0, "off-axis copy");
        assert_eq!(values[15], 160);
        assert_eq!(values[25], 150, "within the margin");
        assert_eq!(values[20], 40, "nothing louder near it");
        // 0.5 m away the copy is another echo and stays.
        let mut far = vec![0u8; 30];
        far[0] = 100;
        far[15] = 160;
        suppress_bins(&mut far, &offsets, &beams, 0.1, &config);
        assert_eq!(far[0], 100);
    }

    #[test]
    fn invalid_parameters_are_named() {
        let bad = OffAxisSuppression {
            margin: f64::NAN,
            ..OffAxisSuppression::default()
        };
        assert!(
            bad.validate()
                .unwrap_err()
                .to_string()
                .contains("off_axis.margin")
        );
        let bad = OffAxisSuppression {
            max_angle_rad: 0.0,
            ..OffAxisSuppression::default()
        };
        assert!(
            bad.validate()
                .unwrap_err()
                .to_string()
                .contains("off_axis.max_angle_rad")
        );
        assert!(OffAxisSuppression::for_scans().validate().is_ok());
    }
}
