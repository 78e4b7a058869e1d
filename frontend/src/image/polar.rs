//! `I(x)` interpolated directly from the beam samples, without the raster.
//!
//! The raster quantises positions to its cells: a bilinear lookup peaks on
//! cell centres, so an estimate from it snaps towards them (up to half a
//! cell when many points share a cell offset, as along a straight wall).
//! This model evaluates the interpolation the raster approximates at any
//! point `q`, at the resolution of the samples themselves:
//!
//! - for every beam `j` near `q`, the angle `α_j` of `q` off the beam's axis
//!   (seen from the beam's own, motion-compensated, origin) and the range
//!   `r_j = |q - o_j|`;
//! - along range, linear interpolation between the samples at the bins' far
//!   ends (eq. 3), or the nearest one for [`Interpolation::Nearest`];
//! - across beams, the triangular angular window of
//!   [`Interpolation::AngularWindow`] (`1 - |α_j| / w`, `w` widened to the
//!   angle between the two beams around `q`), or the nearest beam.
//!
//! Beams are grouped into *layers*: runs in acquisition order whose bearing
//! moves one way and spans less than a turn (a rotation is one layer, plus
//! a second where the vehicle's turn makes it overlap itself; each sweep of
//! a sector scan is one). Within a layer the beams around `q` are found by
//! a binary search on the bearing and a short walk that corrects for the
//! origins' parallax; where layers overlap their values are averaged, as
//! the raster averages the samples of overlapping wedges. Gaps wider than
//! `max_wedge_rad` stay empty except within `w` of a beam.

use super::grid::floor;
use super::normalise::CodedProfiles;
use super::{ImageConfig, Interpolation};
use crate::sensors::SonarBeam;
use echofield_graph::{Se2, wrap_angle};
use nalgebra::Vector2;
use std::f64::consts::TAU;

/// Most beams examined on each side of a query.
const MAX_NEIGHBOURS: usize = 16;

#[derive(Clone, Copy, Debug)]
struct Beam {
    origin_x_m: f64,
    origin_y_m: f64,
    cos: f64,
    sin: f64,
    first_bin_range_m: f64,
    bin_size_m: f64,
}

/// Beams `start..end` (acquisition order) whose unwrapped bearings move
/// one way; `sign` is +1 when they increase, -1 when they decrease.
#[derive(Clone, Copy, Debug)]
struct Layer {
    start: usize,
    end: usize,
    sign: f64,
}

/// The samples of a rotation and the geometry to interpolate them.
#[derive(Clone, Debug)]
pub struct PolarSamples {
    beams: Vec<Beam>,
    profiles: CodedProfiles,
    /// Unwrapped bearing of each beam, acquisition order.
    bearings: Vec<f64>,
    layers: Vec<Layer>,
    centre: (f64, f64),
    interpolation: Interpolation,
    half_width_rad: f64,
    max_wedge_rad: f64,
}

/// The beams of one layer visited at a query: the angular window's
/// weighted sum, or the nearest beam's value.
#[derive(Default)]
struct LayerSum {
    weighted: f64,
    weights: f64,
    /// `(α, value)` of the nearest beam so far.
    nearest: Option<(f64, f64)>,
}

impl LayerSum {
    /// Adds beam `j`'s sample at the query when the query lies within
    /// `window` of its axis and in front of it; false otherwise.
    fn visit(&mut self, samples: &PolarSamples, j: usize, x_m: f64, y_m: f64, window: f64) -> bool {
        let (tan_alpha, along) = samples.offset(j, x_m, y_m);
        let alpha = small_atan(tan_alpha.abs());
        if along <= 0.0 || alpha >= window {
            return false;
        }
        let beam = &samples.beams[j];
        let (qx, qy) = (x_m - beam.origin_x_m, y_m - beam.origin_y_m);
        let r = (qx * qx + qy * qy).sqrt();
        match samples.interpolation {
            Interpolation::AngularWindow => {
                let w = 1.0 - alpha / window;
                self.weighted += w * samples.linear_in_range(j, beam, r);
                self.weights += w;
            }
            Interpolation::Nearest => {
                if self.nearest.is_none_or(|(a, _)| alpha < a) {
                    self.nearest = Some((alpha, samples.nearest_in_range(j, beam, r)));
                }
            }
        }
        true
    }

    fn contribution(self, interpolation: Interpolation) -> Contribution {
        match (interpolation, self.nearest) {
            (Interpolation::AngularWindow, _) if self.weights > 0.0 => {
                Contribution::Mean(self.weighted / self.weights)
            }
            (Interpolation::Nearest, Some((alpha, v))) => Contribution::Nearest(v, alpha),
            _ => Contribution::None,
        }
    }
}

/// What one layer contributes at a query.
enum Contribution {
    None,
    /// Weighted mean of the window (angular window).
    Mean(f64),
    /// The nearest beam's value and its angle off the query (nearest).
    Nearest(f64, f64),
}

impl PolarSamples {
    pub fn new(
        beams: &[SonarBeam],
        reference_from_beams: &[Se2],
        profiles: CodedProfiles,
        config: &ImageConfig,
    ) -> Self {
        let geometry: Vec<Beam> = beams
            .iter()
            .zip(reference_from_beams)
            .map(|(b, pose)| {
                let (sin, cos) = pose.theta().sin_cos();
                Beam {
                    origin_x_m: pose.x(),
                    origin_y_m: pose.y(),
                    cos,
                    sin,
                    first_bin_range_m: b.first_bin_range_m,
                    bin_size_m: b.bin_size_m,
                }
            })
            .collect();
        let n = geometry.len().max(1) as f64;
        let centre = (
            geometry.iter().map(|b| b.origin_x_m).sum::<f64>() / n,
            geometry.iter().map(|b| b.origin_y_m).sum::<f64>() / n,
        );
        let mut bearings = Vec::with_capacity(geometry.len());
        for (j, pose) in reference_from_beams.iter().enumerate() {
            bearings.push(match j {
                0 => pose.theta(),
                _ => {
                    bearings[j - 1] + wrap_angle(pose.theta() - reference_from_beams[j - 1].theta())
                }
            });
        }
        Self {
            // A layer must not hold two beams of about the same direction
            // (both ends of a turn): keep its span below a turn minus the
            // widest window.
            layers: layers(
                &bearings,
                TAU - (config.max_wedge_rad + config.angular_half_width_rad),
            ),
            beams: geometry,
            profiles,
            bearings,
            centre,
            interpolation: config.interpolation,
            half_width_rad: config.angular_half_width_rad,
            max_wedge_rad: config.max_wedge_rad,
        }
    }

    /// `I(x, y)` from the samples (0 where no beam reaches).
    pub fn value_at(&self, x_m: f64, y_m: f64) -> f64 {
        if !(x_m.is_finite() && y_m.is_finite()) {
            return 0.0;
        }
        let bearing = (y_m - self.centre.1).atan2(x_m - self.centre.0);
        let (mut sum, mut count) = (0.0, 0usize);
        let mut nearest: Option<(f64, f64)> = None;
        for layer in &self.layers {
            match self.layer_value(layer, bearing, x_m, y_m) {
                Contribution::None => {}
                Contribution::Mean(v) => {
                    sum += v;
                    count += 1;
                }
                Contribution::Nearest(v, alpha) => {
                    if nearest.is_none_or(|(a, _)| alpha < a) {
                        nearest = Some((alpha, v));
                    }
                }
            }
        }
        match self.interpolation {
            Interpolation::AngularWindow if count > 0 => sum / count as f64,
            Interpolation::Nearest => nearest.map_or(0.0, |(_, v)| v),
            _ => 0.0,
        }
    }

    /// The interpolation within one layer.
    fn layer_value(&self, layer: &Layer, bearing: f64, x_m: f64, y_m: f64) -> Contribution {
        let (start, end) = (layer.start, layer.end);
        let (lo, hi, bracketed) = self.bracket(layer, bearing, x_m, y_m);
        let window = self.window_at(lo, hi, bracketed);
        let mut sum = LayerSum::default();
        // Each side stops at its first beam outside the window.
        for j in (start.max(lo.saturating_sub(MAX_NEIGHBOURS))..=lo).rev() {
            if !sum.visit(self, j, x_m, y_m, window) {
                break;
            }
        }
        if hi != lo {
            for j in hi..end.min(hi + MAX_NEIGHBOURS) {
                if !sum.visit(self, j, x_m, y_m, window) {
                    break;
                }
            }
        }
        sum.contribution(self.interpolation)
    }

    /// The beams `(lo, hi)` of `layer` around the query at `(x_m, y_m)`,
    /// bearing `bearing` from the centre: `hi = lo + 1` where the query
    /// lies between two beams, seen from their own origins (a binary
    /// search on the bearing, then a walk that corrects for the origins'
    /// parallax); `lo = hi` at the layer's ends. The flag: the query lies
    /// between `lo` and `hi`.
    fn bracket(&self, layer: &Layer, bearing: f64, x_m: f64, y_m: f64) -> (usize, usize, bool) {
        let (start, end, sign) = (layer.start, layer.end, layer.sign);
        // Position along the layer: bearings times `sign` increase. The
        // query's bearing is moved by whole turns next to the layer's.
        let key = |j: usize| sign * self.bearings[j];
        let (first, last) = (key(start), key(end - 1));
        // Inside the layer's span if a whole turn puts it there, else next
        // to the nearer end.
        let mut b = sign * bearing;
        b -= TAU * floor((b - first) / TAU);
        if b > last && (b - last) > (first + TAU - b) {
            b -= TAU;
        }
        let mut hi = start + self.bearings[start..end].partition_point(|&v| sign * v < b);
        hi = hi
            .clamp(start, end - 1)
            .max(start + usize::from(end - start > 1));
        // Walk so that the query is on the "after" side of beam hi-1 and the
        // "before" side of beam hi, seen from their own origins.
        let side = |j: usize| sign * self.offset(j, x_m, y_m).0;
        for _ in 0..end - start {
            if hi + 1 < end && side(hi) >= 0.0 {
                hi += 1;
            } else if hi > start + 1 && side(hi - 1) < 0.0 {
                hi -= 1;
            } else {
                break;
            }
        }
        let lo = hi.saturating_sub(1).max(start);
        let bracketed = end - start > 1 && side(lo) >= 0.0 && side(hi) < 0.0;
        (lo, hi, bracketed)
    }

    /// The angular window (radians) of a query between beams `lo` and
    /// `hi` (`bracketed`: it lies between them): widened to the gap
    /// between them where they bracket it within `max_wedge_rad`, half the
    /// gap for the nearest beam, else the configured half-width.
    fn window_at(&self, lo: usize, hi: usize, bracketed: bool) -> f64 {
        let gap = (self.bearings[hi] - self.bearings[lo]).abs();
        let in_wedge = bracketed && gap <= self.max_wedge_rad;
        match (self.interpolation, in_wedge) {
            (Interpolation::AngularWindow, true) => self.half_width_rad.max(gap),
            (Interpolation::AngularWindow, false) => self.half_width_rad,
            (Interpolation::Nearest, true) => 0.5 * gap.max(1e-9),
            (Interpolation::Nearest, false) => self.half_width_rad,
        }
    }

    /// `(tan α, along)` of the query seen from beam `j`: `α > 0` when the
    /// query is counter-clockwise of the beam's axis; behind the transducer
    /// (`along <= 0`) `tan α` is ±∞ by side.
    #[inline]
    fn offset(&self, j: usize, x_m: f64, y_m: f64) -> (f64, f64) {
        let beam = &self.beams[j];
        let (qx, qy) = (x_m - beam.origin_x_m, y_m - beam.origin_y_m);
        let along = beam.cos * qx + beam.sin * qy;
        let across = beam.cos * qy - beam.sin * qx;
        if along > 0.0 {
            (across / along, along)
        } else if across >= 0.0 {
            (f64::INFINITY, along)
        } else {
            (f64::NEG_INFINITY, along)
        }
    }

    /// Value and central-difference gradient (step `h_m`).
    pub fn value_and_gradient(&self, x_m: f64, y_m: f64, h_m: f64) -> (f64, Vector2<f64>) {
        let v = self.value_at(x_m, y_m);
        let gx = (self.value_at(x_m + h_m, y_m) - self.value_at(x_m - h_m, y_m)) / (2.0 * h_m);
        let gy = (self.value_at(x_m, y_m + h_m) - self.value_at(x_m, y_m - h_m)) / (2.0 * h_m);
        (v, Vector2::new(gx, gy))
    }

    /// Bytes this holds on the heap: the beams' geometry, bearings and
    /// layers, and the coded samples.
    pub fn heap_bytes(&self) -> usize {
        use std::mem::size_of;
        self.beams.capacity() * size_of::<Beam>()
            + self.bearings.capacity() * size_of::<f64>()
            + self.layers.capacity() * size_of::<Layer>()
            + self.profiles.heap_bytes()
    }

    /// Smallest bin size of the rotation, metres.
    pub fn finest_bin_m(&self) -> f64 {
        self.beams
            .iter()
            .map(|b| b.bin_size_m)
            .fold(f64::INFINITY, f64::min)
    }

    /// Position of range `r` in sample units: sample `i` is at the far end
    /// of bin `i`, `first + (i + 1)·bin`.
    fn sample_position(beam: &Beam, r: f64) -> f64 {
        (r - beam.first_bin_range_m) / beam.bin_size_m - 1.0
    }

    fn linear_in_range(&self, j: usize, beam: &Beam, r: f64) -> f64 {
        let profile = self.profiles.beam(j);
        let t = Self::sample_position(beam, r);
        if !(t > -1.0 && t < profile.len() as f64) {
            return 0.0;
        }
        let i0 = floor(t);
        let f = t - i0;
        let at = |i: f64| -> f64 {
            if i >= 0.0 && (i as usize) < profile.len() {
                f64::from(self.profiles.value(profile[i as usize]))
            } else {
                0.0
            }
        };
        at(i0) * (1.0 - f) + at(i0 + 1.0) * f
    }

    fn nearest_in_range(&self, j: usize, beam: &Beam, r: f64) -> f64 {
        let profile = self.profiles.beam(j);
        let i = Self::sample_position(beam, r).round();
        if i >= 0.0 && (i as usize) < profile.len() {
            f64::from(self.profiles.value(profile[i as usize]))
        } else {
            0.0
        }
    }
}

/// `atan(t)` for `t >= 0`: a series where `t` is small (the angular windows
/// are a few degrees; error below 1e-7 rad for t < 0.1), the library
/// function elsewhere.
#[inline]
fn small_atan(t: f64) -> f64 {
    if t < 0.1 {
        let t2 = t * t;
        t * (1.0 - t2 * (1.0 / 3.0 - t2 * (0.2 - t2 / 7.0)))
    } else {
        t.atan()
    }
}

/// Splits unwrapped bearings into monotone runs spanning at most
/// `max_span_rad`; consecutive layers share their boundary beam so no wedge
/// is lost.
fn layers(bearings: &[f64], max_span_rad: f64) -> Vec<Layer> {
    let mut out = Vec::new();
    if bearings.is_empty() {
        return out;
    }
    let mut start = 0;
    let mut sign = 0.0_f64;
    for j in 1..bearings.len() {
        let step = bearings[j] - bearings[j - 1];
        let step_sign = if step > 0.0 {
            1.0
        } else if step < 0.0 {
            -1.0
        } else {
            0.0
        };
        let reverses = sign != 0.0 && step_sign != 0.0 && step_sign != sign;
        let full_turn = (bearings[j] - bearings[start]).abs() > max_span_rad;
        if reverses || full_turn {
            out.push(Layer {
                start,
                end: j,
                sign: if sign == 0.0 { 1.0 } else { sign },
            });
            start = j - 1;
            sign = step_sign;
        } else if sign == 0.0 {
            sign = step_sign;
        }
    }
    out.push(Layer {
        start,
        end: bearings.len(),
        sign: if sign == 0.0 { 1.0 } else { sign },
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::normalise::normalise_beams_coded;

    fn config(interpolation: Interpolation) -> ImageConfig {
        ImageConfig {
            interpolation,
            range_smoothing_bins: 1,
            blind_zone_m: 0.0,
            background_quantile: 0.0,
            normalisation_quantile: 1.0,
            angular_half_width_rad: 1.0_f64.to_radians(),
            ..ImageConfig::default()
        }
    }

    /// Beams every 2 degrees from -10 to 10, bin size 0.1 m, each with a
    /// ramp `v(i) = i` (so the value is linear in range) times a per-beam
    /// gain `k + 1`.
    fn fan(origin_y: f64) -> (Vec<SonarBeam>, Vec<Se2>) {
        let mut beams = Vec::new();
        let mut poses = Vec::new();
        for k in 0..11 {
            let angle = f64::from(-10 + 2 * k).to_radians();
            beams.push(SonarBeam {
                stamp_s: f64::from(k),
                angle_rad: angle,
                bin_size_m: 0.1,
                first_bin_range_m: 0.0,
                intensities: (0..100).map(|i| (i * (k as usize + 1) / 5) as u8).collect(),
            });
            poses.push(Se2::new(0.0, origin_y * f64::from(k), angle));
        }
        (beams, poses)
    }

    #[test]
    fn on_a_beam_the_value_is_its_sample_and_between_samples_linear() {
        for interpolation in [Interpolation::AngularWindow, Interpolation::Nearest] {
            let (beams, poses) = fan(0.0);
            let cfg = config(interpolation);
            let profiles = normalise_beams_coded(&beams, &cfg);
            let expected = |k: usize, i: usize| f64::from(profiles.value(profiles.beam(k)[i]));
            let polar = PolarSamples::new(&beams, &poses, profiles.clone(), &cfg);
            // Beam 5 points along +x: sample 39 sits at 4.0 m.
            assert!((polar.value_at(4.0, 0.0) - expected(5, 39)).abs() < 1e-6);
            if interpolation == Interpolation::AngularWindow {
                // Halfway between samples 39 and 40 along the beam.
                let mid = 0.5 * (expected(5, 39) + expected(5, 40));
                assert!((polar.value_at(4.05, 0.0) - mid).abs() < 1e-6);
                // Halfway in angle between beams 5 (0 deg) and 6 (2 deg), at the
                // range of sample 39: the mean of the two.
                let a = 1.0_f64.to_radians();
                let v = polar.value_at(4.0 * a.cos(), 4.0 * a.sin());
                let m = 0.5 * (expected(5, 39) + expected(6, 39));
                assert!((v - m).abs() < 1e-6, "{v} vs {m}");
            } else {
                // Nearest: 0.7 deg off beam 5 is beam 5's sample.
                let a = 0.7_f64.to_radians();
                let v = polar.value_at(4.02 * a.cos(), 4.02 * a.sin());
                assert!((v - expected(5, 39)).abs() < 1e-6);
            }
            // Outside the fan: nothing.
            assert_eq!(polar.value_at(-4.0, 0.0), 0.0);
            assert_eq!(polar.value_at(f64::NAN, 0.0), 0.0);
        }
    }

    /// The same interpolation (angular window), visiting every beam of
    /// every layer: the reference the fast search must agree with.
    fn brute_force(polar: &PolarSamples, x: f64, y: f64) -> f64 {
        let (mut sum, mut count) = (0.0, 0);
        for layer in &polar.layers {
            let side = |j: usize| layer.sign * polar.offset(j, x, y).0;
            let bracket = (layer.start..layer.end.saturating_sub(1))
                .find(|&j| side(j) >= 0.0 && side(j + 1) < 0.0);
            let window = match bracket {
                Some(j) => {
                    let gap = (polar.bearings[j + 1] - polar.bearings[j]).abs();
                    if gap <= polar.max_wedge_rad {
                        polar.half_width_rad.max(gap)
                    } else {
                        polar.half_width_rad
                    }
                }
                None => polar.half_width_rad,
            };
            let (mut wsum, mut vsum) = (0.0, 0.0);
            for j in layer.start..layer.end {
                let (t, along) = polar.offset(j, x, y);
                let alpha = small_atan(t.abs());
                if along <= 0.0 || alpha >= window {
                    continue;
                }
                let beam = &polar.beams[j];
                let r = (x - beam.origin_x_m).hypot(y - beam.origin_y_m);
                let w = 1.0 - alpha / window;
                wsum += w;
                vsum += w * polar.linear_in_range(j, beam, r);
            }
            if wsum > 0.0 {
                sum += vsum / wsum;
                count += 1;
            }
        }
        if count > 0 {
            sum / f64::from(count)
        } else {
            0.0
        }
    }

    #[test]
    fn small_atan_matches_atan() {
        for k in 0..400 {
            let t = f64::from(k) * 0.001;
            assert!((small_atan(t) - t.atan()).abs() < 1e-7, "{t}");
        }
    }

    #[test]
    fn layers_split_at_reversals_and_after_a_turn() {
        let deg = |v: &[f64]| v.iter().map(|d| d.to_radians()).collect::<Vec<f64>>();
        let l = layers(&deg(&[0.0, 10.0, 20.0, 15.0, 5.0, 6.0]), TAU);
        let spans: Vec<(usize, usize, f64)> = l.iter().map(|l| (l.start, l.end, l.sign)).collect();
        assert_eq!(spans, vec![(0, 3, 1.0), (2, 5, -1.0), (4, 6, 1.0)]);
        let turn: Vec<f64> = (0..40).map(|k| f64::from(k) * 10.0).collect();
        let l = layers(&deg(&turn), 345.0_f64.to_radians());
        // 0..=340 degrees is one layer; 350 starts the next (sharing 340).
        assert_eq!((l[0].start, l[0].end), (0, 35));
        assert_eq!((l[1].start, l[1].end), (34, 40));
    }

    #[test]
    fn the_beam_search_agrees_with_visiting_every_beam() {
        use crate::image::synthetic::{RotationPath, SceneConfig, simulate_rotation};
        use rand::{Rng, SeedableRng};
        let path = RotationPath {
            world_from_start: Se2::new(1.0, -2.0, 0.4),
            velocity_mps: (0.5, 0.1),
            yaw_rate_radps: 0.03,
        };
        let rotation = simulate_rotation(&SceneConfig::default(), &path, 3);
        let cfg = ImageConfig {
            range_smoothing_bins: 1,
            ..ImageConfig::default()
        };
        let profiles = normalise_beams_coded(&rotation.beams, &cfg);
        let polar = PolarSamples::new(
            &rotation.beams,
            &rotation.reference_from_beams,
            profiles,
            &cfg,
        );
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
        let (mut compared, mut nonzero, mut ambiguous) = (0, 0, 0);
        for _ in 0..3000 {
            let (x, y) = (rng.random_range(-20.0..20.0), rng.random_range(-15.0..15.0));
            // Where the turn's two ends meet (the seam, here 24 degrees wide
            // as the vehicle turned), or where a layer holds the point in two
            // wedges (the parallax of a transducer that moved metres during
            // the turn reorders the beams near its path), the fast search
            // uses the wedge found from the centre's bearing and the brute
            // force mixes both: not comparable. Everywhere else they agree.
            let bearing = (y - polar.centre.1).atan2(x - polar.centre.0);
            let seam = polar.bearings[0];
            let near_seam = wrap_angle(bearing - seam).abs() < 40.0_f64.to_radians();
            // The transducer moved 3.5 m: within 5 m of the centre the
            // parallax exceeds the beam spacing everywhere.
            let near_path = (x - polar.centre.0).hypot(y - polar.centre.1) < 5.0;
            let twice = polar.layers.iter().any(|layer| {
                let side = |j: usize| layer.sign * polar.offset(j, x, y).0;
                (layer.start..layer.end.saturating_sub(1))
                    .filter(|&j| side(j) >= 0.0 && side(j + 1) < 0.0)
                    .count()
                    > 1
            });
            if near_seam || near_path || twice {
                ambiguous += 1;
                continue;
            }
            let fast = polar.value_at(x, y);
            let slow = brute_force(&polar, x, y);
            assert!(
                (fast - slow).abs() < 1e-9,
                "at ({x}, {y}): {fast} vs {slow}"
            );
            compared += 1;
            nonzero += usize::from(slow > 0.0);
        }
        assert!(compared > 2000, "{compared} compared, {ambiguous} skipped");
        assert!(nonzero > 300, "{nonzero}");
    }

    #[test]
    fn moving_origins_are_used() {
        // Every beam's transducer 0.5 m further along y than the previous.
        let (beams, poses) = fan(0.5);
        let cfg = config(Interpolation::AngularWindow);
        let profiles = normalise_beams_coded(&beams, &cfg);
        let on_beam_3 = poses[3].transform_xy(6.0, 0.0);
        let expected = f64::from(profiles.value(profiles.beam(3)[59]));
        let polar = PolarSamples::new(&beams, &poses, profiles, &cfg);
        assert!((polar.value_at(on_beam_3.0, on_beam_3.1) - expected).abs() < 1e-6);
        let (v, g) = polar.value_and_gradient(on_beam_3.0 + 0.03, on_beam_3.1, 1e-3);
        assert!(v > 0.0 && g.x.is_finite() && g.y.is_finite());
    }
}
