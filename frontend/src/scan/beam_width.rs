//! The beam-width range correction: where the peak of an echo lies on an
//! oblique surface, and how far to move it back.
//!
//! A beam of horizontal width `β` (two-way −3 dB) does not hit a surface
//! in one point but along a footprint. On a flat wall at incidence `α`
//! (angle between the beam axis and the wall's normal), the ray at angle
//! `φ` off the axis meets the wall at range `r(φ) = d / cos(α + φ)`. The
//! energy that arrives at range `r` is the beam pattern times the
//! backscatter, divided by `dr/dφ = r·tan(α + φ)`: the near side of the
//! footprint packs more energy into each range bin and also faces the
//! sonar more squarely. The echo therefore peaks at a ray `φ* < 0`, nearer
//! than the axis range `r(0)`. With a Gaussian pattern of standard
//! deviation `s = β / √(8 ln 2)` and backscatter `∝ cos^k α` (`k = 2` is
//! Lambert's law), setting the derivative of the log-energy to zero gives
//! to first order `φ* = −s² (cot α + (2 + k) tan α)`, so the peak is short
//! by
//!
//! ```text
//! Δr = r·tan α·|φ*| = r·s²·(1 + (2 + k)·tan² α).
//! ```
//!
//! For a 3° beam (`s² = 4.9e-4`) at 20 m that is 1 cm at normal incidence,
//! 5 cm at 45°, 13 cm at 60° and 56 cm at 75°.
//!
//! Why it matters: the error is different from each viewpoint, so a wall seen
//! obliquely from one rotation and squarely from the next does not line up
//! between their scan and image, and the matches come out short of the true
//! displacements (measured: EXPERIMENTS.md § Beam-width correction).
//!
//! The correction moves each return outward by `Δr`, with `α` taken from
//! the wall through its two neighbouring returns (the chord between the
//! returns of the previous and the next beam). Where the neighbours are
//! missing or the three returns bend by more than `max_bend_rad` (a corner,
//! a different object), `α` is unknown and only the normal-incidence term
//! `r·s²` is applied. Beyond `max_incidence_rad` the correction is that of
//! `max_incidence_rad`: near grazing incidence the first-order formula
//! grows without bound while the echo fades into the noise.
//!
//! The image `I_k` must be moved the same way, or the scan and the image
//! of one rotation no longer agree: [`crate::scan::Scan::image_frames`]
//! shifts each beam frame along its axis by its return's correction.
//!
//! What the first-order correction leaves: a heading error of the matches
//! between rotations that grows with the vehicle's speed and with the beam
//! width. It is the range error left on oblique walls: the head turns one way
//! while the vehicle moves, so the walls on either side are seen from different
//! places at different incidences, and a residual error that depends on
//! incidence turns the scan against the image of another rotation. A stronger
//! incidence term (a larger `backscatter_exponent`) shrinks it, and helps with
//! exact navigation, but not on missions with realistic navigation noise, whose
//! errors distort the scans more. Measured: EXPERIMENTS.md § Beam-width
//! correction.

use crate::error::FrontendError;
use echofield_graph::Se2;
use nalgebra::{Point2, Vector2};
use serde::{Deserialize, Serialize};

/// Parameters of the beam-width range correction (module doc).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BeamWidthCorrection {
    /// Off: returns stay at their peak bins. Default on.
    pub enabled: bool,
    /// Two-way −3 dB full width of the horizontal beam, radians. Default
    /// 3° (Tritech Miniking; a Ping360's is 2°).
    pub beam_width_rad: f64,
    /// Exponent `k` of the backscatter law `cos^k α`; 2 (Lambert) by
    /// default.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): Lambert's law (2), the physical model of the correction.
    #[serde(skip)]
    pub backscatter_exponent: f64,
    /// Incidences above this are corrected as at this angle, radians.
    /// Default 75°.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): a numerical guard of the correction at grazing incidence.
    #[serde(skip)]
    pub max_incidence_rad: f64,
    /// Largest turn between the chords from the previous return to this one
    /// and from this one to the next for the wall direction to be used,
    /// radians. Default 20°.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): a geometric guard of the wall-direction estimate.
    #[serde(skip)]
    pub max_bend_rad: f64,
}

impl Default for BeamWidthCorrection {
    fn default() -> Self {
        Self {
            enabled: true,
            beam_width_rad: 3f64.to_radians(),
            backscatter_exponent: 2.0,
            max_incidence_rad: 75f64.to_radians(),
            max_bend_rad: 20f64.to_radians(),
        }
    }
}

impl BeamWidthCorrection {
    /// The correction switched off.
    pub fn off() -> Self {
        Self {
            enabled: false,
            ..Self::default()
        }
    }

    pub fn validate(&self) -> Result<(), FrontendError> {
        let angle = |field: &str, v: f64, max: f64| {
            if v.is_finite() && v > 0.0 && v < max {
                Ok(())
            } else {
                Err(FrontendError::config(
                    format!("beam_width.{field}"),
                    format!("must lie in (0, {max:.4}) rad, got {v}"),
                ))
            }
        };
        angle("beam_width_rad", self.beam_width_rad, 0.5)?;
        angle(
            "max_incidence_rad",
            self.max_incidence_rad,
            85f64.to_radians(),
        )?;
        angle(
            "max_bend_rad",
            self.max_bend_rad,
            std::f64::consts::FRAC_PI_2,
        )?;
        // Backscatter laws run from Lambert's 2 to about 10 for smooth
        // surfaces; far beyond, the shortfall throws returns kilometres out.
        if !(self.backscatter_exponent.is_finite()
            && (0.0..=20.0).contains(&self.backscatter_exponent))
        {
            return Err(FrontendError::config(
                "beam_width.backscatter_exponent",
                format!("must lie in [0, 20], got {}", self.backscatter_exponent),
            ));
        }
        Ok(())
    }

    /// The variance `s²` of the Gaussian beam pattern, rad².
    fn pattern_variance(&self) -> f64 {
        self.beam_width_rad * self.beam_width_rad / (8.0 * std::f64::consts::LN_2)
    }

    /// `Δr` for a return at `range_m` on a surface at incidence `α` given as
    /// `tan² α` (`None`: unknown, normal-incidence term only).
    pub fn shortfall_m(&self, range_m: f64, tan2_incidence: Option<f64>) -> f64 {
        let tan2_max = self.max_incidence_rad.tan().powi(2);
        let tan2 = tan2_incidence.map_or(0.0, |t| t.min(tan2_max));
        range_m * self.pattern_variance() * (1.0 + (2.0 + self.backscatter_exponent) * tan2)
    }
}

/// The outward correction of every return, metres, for returns `points`
/// (in the reference frame) of beams `beam_indices` (ascending, as
/// `build_scan` emits them) whose frames are `reference_from_beams`.
pub(crate) fn corrections(
    points: &[Point2<f64>],
    beam_indices: &[u32],
    reference_from_beams: &[Se2],
    config: &BeamWidthCorrection,
) -> Vec<f32> {
    if !config.enabled {
        return vec![0.0; points.len()];
    }
    // The returns of beam `b` are `first[b]..first[b + 1]`.
    let beams = reference_from_beams.len();
    let mut first = vec![0usize; beams + 1];
    for &b in beam_indices {
        first[b as usize + 1] += 1;
    }
    for b in 0..beams {
        first[b + 1] += first[b];
    }
    let returns_of = |b: usize| &points[first[b]..first[b + 1]];
    points
        .iter()
        .zip(beam_indices)
        .map(|(p, &b)| {
            let b = b as usize;
            let frame = &reference_from_beams[b];
            let origin = Point2::from(frame.translation());
            let axis = frame.rotation() * Vector2::x();
            let nearest = |beam: usize| nearest_to(returns_of(beam), p);
            let tan2 = match (b.checked_sub(1), b + 1 < beams) {
                (Some(prev), true) => match (nearest(prev), nearest(b + 1)) {
                    (Some(a), Some(c)) => tan2_incidence(&a, p, &c, &axis, config.max_bend_rad),
                    _ => None,
                },
                _ => None,
            };
            config.shortfall_m((p - origin).norm(), tan2) as f32
        })
        .collect()
}

fn nearest_to(candidates: &[Point2<f64>], p: &Point2<f64>) -> Option<Point2<f64>> {
    candidates
        .iter()
        .min_by(|a, b| (*a - p).norm_squared().total_cmp(&(*b - p).norm_squared()))
        .copied()
}

/// `tan² α` of the wall through `prev` and `next` seen along `axis`, or
/// `None` when the three returns do not lie on one wall.
fn tan2_incidence(
    prev: &Point2<f64>,
    p: &Point2<f64>,
    next: &Point2<f64>,
    axis: &Vector2<f64>,
    max_bend_rad: f64,
) -> Option<f64> {
    let (a, c) = (p - prev, next - p);
    let bend = a.perp(&c).atan2(a.dot(&c)).abs();
    let chord = next - prev;
    if bend.is_nan() || bend > max_bend_rad || chord.norm() < 1e-9 {
        return None;
    }
    let along = axis.dot(&chord);
    let across = axis.perp(&chord);
    Some(along * along / (across * across).max(1e-12))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Returns of a fan of beams from the origin on the line `y = x·tan(w) + d`
    /// (a wall whose normal makes angle `w` with the y axis).
    fn wall(
        d: f64,
        wall_angle_rad: f64,
        bearings_deg: std::ops::Range<i32>,
    ) -> (Vec<Point2<f64>>, Vec<Se2>) {
        let normal = Vector2::new(-wall_angle_rad.sin(), wall_angle_rad.cos());
        bearings_deg
            .map(|deg| {
                let bearing = (deg as f64).to_radians();
                let u = Vector2::new(bearing.cos(), bearing.sin());
                let range = d / u.dot(&normal);
                (Point2::from(u * range), Se2::new(0.0, 0.0, bearing))
            })
            .unzip()
    }

    fn indices(n: usize) -> Vec<u32> {
        (0..n as u32).collect()
    }

    #[test]
    fn the_shortfall_follows_the_first_order_formula() {
        let c = BeamWidthCorrection::default();
        let s2 = 3f64.to_radians().powi(2) / (8.0 * 2f64.ln());
        assert!((c.shortfall_m(20.0, None) - 20.0 * s2).abs() < 1e-12);
        let t2 = 60f64.to_radians().tan().powi(2);
        assert!((c.shortfall_m(20.0, Some(t2)) - 20.0 * s2 * (1.0 + 4.0 * t2)).abs() < 1e-12);
        // Clamped at the largest incidence.
        let at_max = c.shortfall_m(20.0, Some(75f64.to_radians().tan().powi(2)));
        assert_eq!(c.shortfall_m(20.0, Some(1e6)), at_max);
        // The doc's figures: 1, 5, 13 and 56 cm at 20 m.
        for (deg, cm) in [(0.0, 1.0), (45.0, 5.0), (60.0, 13.0), (75.0, 56.0)] {
            let t2 = f64::tan(f64::to_radians(deg)).powi(2);
            let got = 100.0 * c.shortfall_m(20.0, Some(t2));
            assert!((got - cm).abs() < 0.6, "{deg} deg: {got} cm");
        }
    }

    #[test]
    fn the_incidence_comes_from_the_neighbouring_returns() {
        let config = BeamWidthCorrection::default();
        // Wall y = 10 (normal along y): incidence = 90° − bearing.
        let (points, frames) = wall(10.0, 0.0, 20..161);
        let got = corrections(&points, &indices(points.len()), &frames, &config);
        for (i, deg) in (20..161).enumerate().skip(1).take(139) {
            let alpha = (90.0 - deg as f64).to_radians();
            let want = config.shortfall_m(points[i].coords.norm(), Some(alpha.tan().powi(2)));
            // The chord of the two neighbours is parallel to a straight wall.
            assert!(
                (got[i] as f64 - want).abs() < 1e-5,
                "bearing {deg}: {} vs {want}",
                got[i]
            );
        }
        // The first and the last return have one neighbour: base term only.
        let r0 = points[0].coords.norm();
        assert!((got[0] as f64 - config.shortfall_m(r0, None)).abs() < 1e-6);
        // A tilted wall gives the same incidences, shifted.
        let tilt = 15f64.to_radians();
        let (points, frames) = wall(10.0, tilt, 60..80);
        let got = corrections(&points, &indices(points.len()), &frames, &config);
        let alpha = (90.0 - 70.0 + 15.0f64).to_radians();
        let want = config.shortfall_m(points[10].coords.norm(), Some(alpha.tan().powi(2)));
        assert!(
            (got[10] as f64 - want).abs() < 1e-5,
            "{} vs {want}",
            got[10]
        );
    }

    #[test]
    fn a_corner_or_a_missing_neighbour_leaves_only_the_normal_term() {
        let config = BeamWidthCorrection::default();
        // Two walls meeting at the corner (10, 10): bearings up to 45° see
        // x = 10, the others y = 10.
        let (mut points, frames): (Vec<_>, Vec<_>) = (30..61)
            .map(|deg| {
                let b = (deg as f64).to_radians();
                let r = 10.0 / b.cos().max(b.sin());
                (Point2::new(r * b.cos(), r * b.sin()), Se2::new(0.0, 0.0, b))
            })
            .unzip();
        let got = corrections(&points, &indices(points.len()), &frames, &config);
        let corner = 15; // bearing 45°
        let base = config.shortfall_m(points[corner].coords.norm(), None);
        assert!((got[corner] as f64 - base).abs() < 1e-6);
        // A beam without a return: its neighbours have one neighbour each.
        let mut beams = indices(points.len());
        points.remove(5);
        beams.remove(5);
        let got = corrections(&points, &beams, &frames, &config);
        for i in [4, 5] {
            let base = config.shortfall_m(points[i].coords.norm(), None);
            assert!((got[i] as f64 - base).abs() < 1e-6, "return {i}");
        }
    }

    #[test]
    fn switched_off_it_corrects_nothing_and_bad_values_are_named() {
        let (points, frames) = wall(10.0, 0.0, 30..60);
        let got = corrections(&points, &indices(30), &frames, &BeamWidthCorrection::off());
        assert!(got.iter().all(|&c| c == 0.0));
        BeamWidthCorrection::default().validate().unwrap();
        for (bad, field) in [
            (
                BeamWidthCorrection {
                    beam_width_rad: 0.0,
                    ..Default::default()
                },
                "beam_width_rad",
            ),
            (
                BeamWidthCorrection {
                    beam_width_rad: f64::NAN,
                    ..Default::default()
                },
                "beam_width_rad",
            ),
            (
                BeamWidthCorrection {
                    max_incidence_rad: 1.5,
                    ..Default::default()
                },
                "max_incidence_rad",
            ),
            (
                BeamWidthCorrection {
                    max_bend_rad: -1.0,
                    ..Default::default()
                },
                "max_bend_rad",
            ),
            (
                BeamWidthCorrection {
                    backscatter_exponent: -1.0,
                    ..Default::default()
                },
                "backscatter_exponent",
            ),
        ] {
            let err = bad.validate().unwrap_err().to_string();
            assert!(err.contains(field), "{err}");
        }
    }
}
