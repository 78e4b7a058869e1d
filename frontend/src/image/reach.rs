//! Where the beams of a rotation reach: the rim of the image.
//!
//! An acoustic image holds echoes only where its beams reached; beyond the
//! far end of the beams `I` is 0 because nothing was measured, not because
//! nothing is there. A scan point carried past that rim by a candidate pose
//! scores 0, so of two poses that both put a long wall on the image's wall,
//! the one that keeps more of the wall inside the rim scores higher: along
//! a wall that runs out of the image, eq. (5) prefers the displacement that
//! is too short. The matcher therefore refines its estimate with the scan
//! points that stay inside the rim for every pose it still considers
//! ([`crate::matcher`], step 2).
//!
//! [`Reach`] describes the rim as a distance from the mean origin of the
//! beams for each bearing, in bins of [`BIN_RAD`]: the far end of every
//! beam (`reference_from_beam ⊕ [max range, 0]`, the ranges limited by
//! [`super::ImageConfig::max_range_m`]) is put in the bin of its bearing,
//! and a bin keeps the farthest end that fell into it (where a turn makes a
//! rotation overlap itself, the union of both is covered). Bins without a
//! beam take the nearer of their neighbours within `max_wedge_rad` (the
//! raster fills wedges up to that angle), and stay 0, not covered, beyond
//! it (the unswept side of a sector scan).
//!
//! [`Reach::margin`] is conservative between bins: the smaller of the two
//! neighbouring bins' distances.

use super::normalise::kept_bins;
use crate::sensors::SonarBeam;
use echofield_graph::Se2;
use nalgebra::Point2;
use std::f64::consts::TAU;

/// Width of a bearing bin, radians (half a degree).
pub const BIN_RAD: f64 = TAU / 720.0;

/// The rim of an image's reach (see the module doc). Frame: the image's
/// reference frame; distances in metres.
#[derive(Clone, Debug, PartialEq)]
pub struct Reach {
    centre: Point2<f64>,
    /// Distance of the rim from `centre` per bearing bin (bin `b` covers
    /// bearings `[b·BIN_RAD, (b+1)·BIN_RAD)` counter-clockwise from x);
    /// 0 where no beam reached.
    rim_m: Vec<f32>,
    /// The smallest of `rim_m`: every point nearer to `centre` than this
    /// is inside the rim whatever its bearing.
    nearest_rim_m: f32,
}

impl Reach {
    /// The reach of `beams` placed by `reference_from_beams` (same length,
    /// validated by the caller), their ranges cut at `max_range_m`. Beams
    /// without a kept bin reach nowhere. `None` when no beam reaches.
    pub fn of_beams(
        beams: &[SonarBeam],
        reference_from_beams: &[Se2],
        max_range_m: Option<f64>,
        max_wedge_rad: f64,
    ) -> Option<Self> {
        let n = beams.len().max(1) as f64;
        let centre = Point2::new(
            reference_from_beams.iter().map(Se2::x).sum::<f64>() / n,
            reference_from_beams.iter().map(Se2::y).sum::<f64>() / n,
        );
        let bins = (TAU / BIN_RAD).round() as usize;
        let mut rim_m = vec![0.0_f32; bins];
        let mut any = false;
        for (beam, pose) in beams.iter().zip(reference_from_beams) {
            let kept = kept_bins(beam, max_range_m);
            if kept == 0 {
                continue;
            }
            let end = pose.transform_point(&Point2::new(beam.bin_end_range_m(kept - 1), 0.0));
            let d = end - centre;
            let b = bin_of(d.y.atan2(d.x), bins);
            rim_m[b] = rim_m[b].max(d.norm() as f32);
            any = true;
        }
        if !any {
            return None;
        }
        fill_gaps(&mut rim_m, (max_wedge_rad / BIN_RAD).ceil() as usize);
        let nearest_rim_m = rim_m.iter().copied().fold(f32::INFINITY, f32::min);
        Some(Self {
            centre,
            rim_m,
            nearest_rim_m,
        })
    }

    /// The reach of a full turn of beams of `range_m` metres from `centre`:
    /// a disc, for images made without beams (rasters built in tests and
    /// benchmarks) whose rim is known.
    pub fn disc(centre: Point2<f64>, range_m: f64) -> Self {
        let bins = (TAU / BIN_RAD).round() as usize;
        Self {
            centre,
            rim_m: vec![range_m as f32; bins],
            nearest_rim_m: range_m as f32,
        }
    }

    /// How far inside the rim `q` (image frame, metres) lies, measured
    /// along its bearing from the centre: negative outside the reach, and
    /// minus the distance from the centre where no beam reached that
    /// bearing. Conservative between bins (see the module doc).
    pub fn margin(&self, q: &Point2<f64>) -> f64 {
        let d = q - self.centre;
        let bins = self.rim_m.len();
        let bearing = d.y.atan2(d.x);
        // The two bins whose centres enclose the bearing.
        let t = bearing.rem_euclid(TAU) / BIN_RAD - 0.5;
        let lo = t.floor().rem_euclid(bins as f64) as usize % bins;
        let hi = (lo + 1) % bins;
        f64::from(self.rim_m[lo].min(self.rim_m[hi])) - d.norm()
    }

    /// `self.margin(q) >= need_m`, the same answer for every `q`, without
    /// the bearing's bin when `q` lies nearer to the centre than the
    /// nearest stretch of the rim by at least `need_m` (most points of a
    /// full turn: the matcher asks this for every point of every pose it
    /// refines).
    pub fn covers(&self, q: &Point2<f64>, need_m: f64) -> bool {
        let d = (q - self.centre).norm();
        // margin(q) = rim of q's bins − d ≥ nearest_rim_m − d.
        f64::from(self.nearest_rim_m) - d >= need_m || self.margin(q) >= need_m
    }

    /// The mean origin of the beams, image frame.
    pub fn centre(&self) -> Point2<f64> {
        self.centre
    }

    pub fn heap_bytes(&self) -> usize {
        self.rim_m.capacity() * std::mem::size_of::<f32>()
    }
}

/// The bin of `bearing` (radians, any value) among `bins` bins.
fn bin_of(bearing: f64, bins: usize) -> usize {
    ((bearing.rem_euclid(TAU) / BIN_RAD) as usize).min(bins - 1)
}

/// Empty bins (0) take the smaller of the nearest non-empty bins on each
/// side when both lie within `max_gap` bins, else stay 0.
fn fill_gaps(rim_m: &mut [f32], max_gap: usize) {
    let bins = rim_m.len();
    let source = rim_m.to_vec();
    let nearest = |b: usize, step: isize| -> Option<f32> {
        (1..=max_gap.min(bins)).find_map(|k| {
            let i = (b as isize + step * k as isize).rem_euclid(bins as isize) as usize;
            (source[i] > 0.0).then_some(source[i])
        })
    };
    for (b, value) in rim_m.iter_mut().enumerate() {
        if source[b] > 0.0 {
            continue;
        }
        if let (Some(left), Some(right)) = (nearest(b, -1), nearest(b, 1)) {
            *value = left.min(right);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn beam(angle_rad: f64, bins: usize) -> SonarBeam {
        SonarBeam {
            stamp_s: 0.0,
            angle_rad,
            bin_size_m: 0.1,
            first_bin_range_m: 0.0,
            intensities: vec![0; bins],
        }
    }

    /// A full turn of `n` beams of 50 m from `origin`, each beam frame at
    /// the beam's bearing.
    fn turn(n: usize, origin: (f64, f64)) -> (Vec<SonarBeam>, Vec<Se2>) {
        (0..n)
            .map(|j| {
                let a = TAU * j as f64 / n as f64;
                (beam(a, 500), Se2::new(origin.0, origin.1, a))
            })
            .unzip()
    }

    #[test]
    fn a_full_turn_reaches_its_range_in_every_direction() {
        let (beams, frames) = turn(200, (0.0, 0.0));
        let reach = Reach::of_beams(&beams, &frames, None, 0.1).unwrap();
        for k in 0..36 {
            let a = f64::from(k) * 10.0_f64.to_radians() + 0.01;
            let at = |r: f64| Point2::new(r * a.cos(), r * a.sin());
            assert!((reach.margin(&at(40.0)) - 10.0).abs() < 1e-3);
            assert!((reach.margin(&at(52.0)) + 2.0).abs() < 1e-3);
        }
    }

    #[test]
    fn a_disc_is_the_reach_of_a_full_turn_from_its_centre() {
        let (beams, frames) = turn(720, (2.0, -1.0));
        let turn = Reach::of_beams(&beams, &frames, None, 0.1).unwrap();
        assert_eq!(Reach::disc(Point2::new(2.0, -1.0), 50.0), turn);
    }

    #[test]
    fn covers_is_the_margin_compared_with_the_need() {
        // A sector scan (a rim at 0 on the unswept side) and a full turn
        // from a moved origin (the nearest rim short of the range).
        let sector: (Vec<_>, Vec<_>) = (0..=90)
            .map(|k| {
                let a = f64::from(k - 45).to_radians();
                (beam(a, 500), Se2::new(0.0, 0.0, a))
            })
            .unzip();
        let moved = turn(360, (3.0, 0.0));
        for (beams, frames) in [sector, moved] {
            let reach = Reach::of_beams(&beams, &frames, None, 0.1).unwrap();
            for k in 0..2000 {
                let a = f64::from(k) * 0.0137;
                let r = f64::from(k % 120) * 0.5;
                let q = Point2::new(r * a.cos(), r * a.sin());
                for need in [-1.0, 0.0, 0.5, 4.0] {
                    assert_eq!(
                        reach.covers(&q, need),
                        reach.margin(&q) >= need,
                        "{q} {need}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_range_limit_of_the_image_config_moves_the_rim() {
        let (beams, frames) = turn(200, (0.0, 0.0));
        let reach = Reach::of_beams(&beams, &frames, Some(30.0), 0.1).unwrap();
        assert!((reach.margin(&Point2::new(0.0, 25.0)) - 5.0).abs() < 1e-3);
    }

    #[test]
    fn the_rim_follows_beams_whose_origins_moved() {
        // Beams from an origin 3 m along x: the rim is a 50 m circle
        // around it, seen from the mean origin (the same point here).
        let (beams, frames) = turn(360, (3.0, 0.0));
        let reach = Reach::of_beams(&beams, &frames, None, 0.1).unwrap();
        assert!((reach.margin(&Point2::new(50.0, 0.0)) - 3.0).abs() < 0.01);
        assert!((reach.margin(&Point2::new(-44.0, 0.0)) - 3.0).abs() < 0.01);
    }

    #[test]
    fn a_sector_scan_does_not_reach_its_unswept_side() {
        // Beams over [-45°, 45°] only.
        let (beams, frames): (Vec<_>, Vec<_>) = (0..=90)
            .map(|k| {
                let a = f64::from(k - 45).to_radians();
                (beam(a, 500), Se2::new(0.0, 0.0, a))
            })
            .unzip();
        let reach = Reach::of_beams(&beams, &frames, None, 0.1).unwrap();
        assert!(reach.margin(&Point2::new(10.0, 0.0)) > 39.0);
        assert!(reach.margin(&Point2::new(-10.0, 0.0)) < -9.9);
        assert!(reach.margin(&Point2::new(0.0, 10.0)) < -9.9);
    }

    #[test]
    fn beams_without_kept_bins_reach_nowhere() {
        let beams = vec![beam(0.0, 0)];
        assert!(Reach::of_beams(&beams, &[Se2::identity()], None, 0.1).is_none());
    }
}
