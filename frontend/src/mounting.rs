//! `[mounting]`: the sensor mounting of a mission, overridden from a
//! configuration (a user's, or the file `echofield calibrate` writes).
//!
//! Every key is optional; a key left out keeps the mission's value. The
//! frames are those of [`SensorMounting`]: vehicle x forward, y port, z up;
//! the sonar head at `(sonar_x_m, sonar_y_m)` with its angle zero at
//! `sonar_yaw_deg` counter-clockwise from the vehicle's x axis, its angle
//! counting `sonar_angle` (counter-clockwise, or clockwise for an inverted
//! head):
//!
//! ```text
//!        y (port)
//!        ▲            beam at head angle θ:
//!        │   ╲θ        counter_clockwise: yaw + θ
//!        │    ●──▶ zero of the head's angle, at sonar_yaw_deg
//!        │   (sonar_x_m, sonar_y_m)           clockwise: yaw − θ
//!        └─────────────▶ x (forward)
//! ```
//!
//! ```toml
//! [mounting]
//! sonar_x_m = 0.33
//! sonar_y_m = 0.0
//! sonar_yaw_deg = -114.0
//! sonar_angle = "clockwise"
//! sweep = "angle_decreasing"
//! heading_offset_deg = 19.4
//! ```
//!
//! `sweep` matters only for missions whose beam stamps were reconstructed
//! from point sets ([`SweepTiming`]): changing it between
//! `angle_increasing` and `angle_decreasing` gives each rotation's beams
//! the stamps of the other assumption ([`restamp_sweep`]). A mission whose
//! beams carry their logged stamps cannot take another sweep.

use crate::error::FrontendError;
use crate::sensors::{
    AngleDirection, Mission, MountingSource, SensorMounting, SonarBeam, SweepTiming,
};
use echofield_graph::{Se2, wrap_angle};
use serde::{Deserialize, Serialize};
use std::borrow::Cow;

/// Overrides of a mission's [`SensorMounting`]; `None` keeps its value.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MountingConfig {
    /// The sonar head's position forward of the vehicle origin, metres.
    pub sonar_x_m: Option<f64>,
    /// The sonar head's position to port of the vehicle origin, metres.
    pub sonar_y_m: Option<f64>,
    /// Direction of the head's angle zero, degrees counter-clockwise from
    /// the vehicle's x axis.
    pub sonar_yaw_deg: Option<f64>,
    /// `"counter_clockwise"` or `"clockwise"` (inverted head).
    pub sonar_angle: Option<AngleDirection>,
    /// `"logged"`, `"angle_increasing"` or `"angle_decreasing"` (see the
    /// module doc).
    pub sweep: Option<SweepTiming>,
    /// The DVL's position forward of the vehicle origin, metres.
    pub dvl_x_m: Option<f64>,
    /// The DVL's position to port, metres.
    pub dvl_y_m: Option<f64>,
    /// The DVL's yaw on the vehicle, degrees counter-clockwise.
    pub dvl_yaw_deg: Option<f64>,
    /// Added to every heading sample (compass misalignment and magnetic
    /// declination), degrees counter-clockwise.
    pub heading_offset_deg: Option<f64>,
}

/// The largest lever arm accepted, metres: larger values are typing errors.
const MAX_LEVER_ARM_M: f64 = 100.0;

impl MountingConfig {
    /// True when no key is set.
    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }

    /// Checks every value (finite, lever arms within 100 m, angles within
    /// ±360°); never changes one.
    pub fn validate(&self) -> Result<(), FrontendError> {
        let lengths = [
            ("sonar_x_m", self.sonar_x_m),
            ("sonar_y_m", self.sonar_y_m),
            ("dvl_x_m", self.dvl_x_m),
            ("dvl_y_m", self.dvl_y_m),
        ];
        for (field, value) in lengths {
            if let Some(v) = value
                && !(v.is_finite() && v.abs() <= MAX_LEVER_ARM_M)
            {
                return Err(FrontendError::config(
                    field,
                    format!("must be finite and within ±{MAX_LEVER_ARM_M} m, got {v}"),
                ));
            }
        }
        let angles = [
            ("sonar_yaw_deg", self.sonar_yaw_deg),
            ("dvl_yaw_deg", self.dvl_yaw_deg),
            ("heading_offset_deg", self.heading_offset_deg),
        ];
        for (field, value) in angles {
            if let Some(v) = value
                && !(v.is_finite() && v.abs() <= 360.0)
            {
                return Err(FrontendError::config(
                    field,
                    format!("must be finite and within ±360 degrees, got {v}"),
                ));
            }
        }
        Ok(())
    }

    /// The mounting `mission` has under these overrides. Its source
    /// becomes [`MountingSource::Config`] when a key of the sonar head is
    /// set (the keys that decide where the scans land).
    pub fn mounting_over(&self, mission: &SensorMounting) -> SensorMounting {
        let mut m = mission.clone();
        let s = m.vehicle_from_sonar;
        m.vehicle_from_sonar = Se2::new(
            self.sonar_x_m.unwrap_or(s.x()),
            self.sonar_y_m.unwrap_or(s.y()),
            self.sonar_yaw_deg
                .map_or(s.theta(), |d| wrap_angle(d.to_radians())),
        );
        let d = m.vehicle_from_dvl;
        m.vehicle_from_dvl = Se2::new(
            self.dvl_x_m.unwrap_or(d.x()),
            self.dvl_y_m.unwrap_or(d.y()),
            self.dvl_yaw_deg
                .map_or(d.theta(), |v| wrap_angle(v.to_radians())),
        );
        if let Some(a) = self.sonar_angle {
            m.sonar_angle = a;
        }
        if let Some(sweep) = self.sweep {
            m.sweep = sweep;
        }
        if let Some(h) = self.heading_offset_deg {
            m.heading_offset_rad = wrap_angle(h.to_radians());
        }
        let sets_sonar = self.sonar_x_m.is_some()
            || self.sonar_y_m.is_some()
            || self.sonar_yaw_deg.is_some()
            || self.sonar_angle.is_some();
        if sets_sonar {
            m.source = MountingSource::Config;
        }
        m
    }

    /// `mission` with these overrides applied: its mounting replaced, and
    /// its beams re-stamped when the sweep assumption changes. Borrowed
    /// when nothing changes.
    ///
    /// Errors: an invalid value; a sweep for a mission whose stamps are
    /// logged (or `logged` for one whose stamps were reconstructed); beams
    /// that cannot be re-stamped ([`restamp_sweep`]).
    pub fn apply<'m>(&self, mission: &'m Mission) -> Result<Cow<'m, Mission>, FrontendError> {
        self.validate()?;
        if self.is_empty() {
            return Ok(Cow::Borrowed(mission));
        }
        let mounting = self.mounting_over(&mission.mounting);
        let from = mission.mounting.sweep;
        let restamp = match (from, mounting.sweep) {
            (a, b) if a == b => false,
            (SweepTiming::Logged, _) => {
                return Err(FrontendError::config(
                    "sweep",
                    "the mission's beams carry their logged stamps; only missions rebuilt \
                     from point sets take an assumed sweep",
                ));
            }
            (_, SweepTiming::Logged) => {
                return Err(FrontendError::config(
                    "sweep",
                    "the mission's beam stamps were reconstructed from point sets; \
                     choose angle_increasing or angle_decreasing",
                ));
            }
            _ => true,
        };
        let mut out = Mission {
            mounting,
            ..mission.clone()
        };
        if restamp {
            restamp_sweep(&mut out.beams)?;
        }
        Ok(Cow::Owned(out))
    }
}

/// Gives the beams of every reconstructed rotation the stamps of the
/// opposite sweep assumption.
///
/// A rotation is a run of beams from one at angle 0 to the next such beam
/// (the reconstruction starts every rotation there). Under one assumption
/// the `j`-th stamp of a rotation of `n` beams belongs to the beam `j`
/// steps into it; under the other, the beam `j` steps in is the one `n − j`
/// steps the other way, so it takes stamp `(n − j) mod n`. The beams are
/// left in time order.
///
/// Errors: beams before the first beam at angle 0, or a rotation whose
/// angles do not step evenly round a whole turn (not a reconstruction).
pub fn restamp_sweep(beams: &mut [SonarBeam]) -> Result<(), FrontendError> {
    if beams.len() < 2 {
        return Ok(());
    }
    let step = wrap_angle(beams[1].angle_rad - beams[0].angle_rad).abs();
    if step.is_nan() || step <= 1e-6 {
        return Err(FrontendError::input("beam 1", "angle_rad", "no angle step"));
    }
    let at_zero = |b: &SonarBeam| wrap_angle(b.angle_rad).abs() < 0.5 * step;
    if !at_zero(&beams[0]) {
        return Err(FrontendError::input(
            "beam 0",
            "angle_rad",
            "a reconstructed rotation starts at angle 0",
        ));
    }
    let starts: Vec<usize> = (0..beams.len()).filter(|&i| at_zero(&beams[i])).collect();
    for (k, &start) in starts.iter().enumerate() {
        let end = starts.get(k + 1).copied().unwrap_or(beams.len());
        let n = end - start;
        let turns = n as f64 * step / std::f64::consts::TAU;
        if (turns - 1.0).abs() > 0.5 / n as f64 {
            return Err(FrontendError::input(
                format!("beam {start}"),
                "angle_rad",
                format!(
                    "the rotation from here holds {n} beams of {step:.5} rad, not one turn: \
                     not a reconstructed rotation"
                ),
            ));
        }
        let run = &mut beams[start..end];
        let stamps: Vec<f64> = run.iter().map(|b| b.stamp_s).collect();
        for (j, beam) in run.iter_mut().enumerate() {
            beam.stamp_s = stamps[(n - j) % n];
        }
        run.sort_by(|a, b| a.stamp_s.total_cmp(&b.stamp_s));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_2, PI, TAU};

    fn rotation(start_s: f64, n: usize, direction: f64) -> Vec<SonarBeam> {
        (0..n)
            .map(|j| SonarBeam {
                stamp_s: start_s + j as f64,
                angle_rad: wrap_angle(direction * j as f64 * TAU / n as f64),
                bin_size_m: 0.1,
                first_bin_range_m: 0.0,
                intensities: vec![j as u8],
            })
            .collect()
    }

    #[test]
    fn restamping_twice_is_the_identity_and_once_reverses_the_sweep() {
        let mut beams = [rotation(0.0, 8, 1.0), rotation(8.0, 8, 1.0)].concat();
        let original = beams.clone();
        restamp_sweep(&mut beams).unwrap();
        // The beam at angle 0 keeps its stamp; then the angle runs the other way.
        assert_eq!(beams[0].stamp_s, 0.0);
        assert_eq!(beams[0].intensities, vec![0]);
        assert_eq!(beams[1].stamp_s, 1.0);
        assert_eq!(beams[1].intensities, vec![7]);
        assert!((beams[1].angle_rad - (-TAU / 8.0)).abs() < 1e-12);
        assert_eq!(beams[8].intensities, vec![0]);
        assert_eq!(beams[8].stamp_s, 8.0);
        restamp_sweep(&mut beams).unwrap();
        assert_eq!(beams, original);
    }

    #[test]
    fn partial_rotations_are_refused() {
        let mut beams = rotation(0.0, 8, 1.0);
        beams.truncate(5);
        let err = restamp_sweep(&mut beams).unwrap_err().to_string();
        assert!(err.contains("not one turn"), "{err}");
    }

    #[test]
    fn overrides_replace_only_the_keys_given() {
        let mission = SensorMounting {
            vehicle_from_sonar: Se2::new(0.33, 0.1, PI),
            heading_offset_rad: 0.3,
            ..SensorMounting::assumed_identity()
        };
        let config = MountingConfig {
            sonar_yaw_deg: Some(90.0),
            sonar_angle: Some(AngleDirection::Clockwise),
            ..MountingConfig::default()
        };
        let m = config.mounting_over(&mission);
        assert_eq!(
            (m.vehicle_from_sonar.x(), m.vehicle_from_sonar.y()),
            (0.33, 0.1)
        );
        assert!((m.vehicle_from_sonar.theta() - FRAC_PI_2).abs() < 1e-12);
        assert_eq!(m.sonar_angle, AngleDirection::Clockwise);
        assert_eq!(m.heading_offset_rad, 0.3);
        assert_eq!(m.source, MountingSource::Config);
        // A clockwise head's beam at +90° points along yaw − 90° = 0.
        assert!(m.vehicle_from_beam(FRAC_PI_2).theta().abs() < 1e-12);
    }

    #[test]
    fn a_sweep_for_logged_stamps_is_an_error() {
        let mission = Mission {
            beams: rotation(0.0, 8, 1.0),
            ..Mission::default()
        };
        let config = MountingConfig {
            sweep: Some(SweepTiming::AngleDecreasing),
            ..MountingConfig::default()
        };
        let err = config.apply(&mission).unwrap_err().to_string();
        assert!(err.contains("sweep") && err.contains("logged"), "{err}");
        let bad = MountingConfig {
            sonar_x_m: Some(f64::NAN),
            ..MountingConfig::default()
        };
        assert!(
            bad.apply(&mission)
                .unwrap_err()
                .to_string()
                .contains("sonar_x_m")
        );
    }

    #[test]
    fn an_assumed_sweep_is_restamped() {
        let mut mission = Mission {
            beams: rotation(0.0, 8, 1.0),
            ..Mission::default()
        };
        mission.mounting.sweep = SweepTiming::AngleIncreasing;
        let config = MountingConfig {
            sweep: Some(SweepTiming::AngleDecreasing),
            ..MountingConfig::default()
        };
        let out = config.apply(&mission).unwrap();
        assert_eq!(out.mounting.sweep, SweepTiming::AngleDecreasing);
        assert_eq!(out.beams[1].intensities, vec![7]);
    }
}
