//! Physically implausible sensor values: what no vehicle that carries these
//! sensors can report, however bad its day.
//!
//! The values are finite (non-finite ones are errors wherever they are
//! read), but a DVL velocity of 1e3 m/s or a heading of 1e306 rad is a
//! corrupt record: fed to the filter it turns every covariance infinite
//! (the dead-reckoning smoother then never ends), or places the beams of
//! one rotation kilometres apart. [`screen`] drops such samples from a
//! mission with a [`WarningKind::ImplausibleValues`] warning that counts
//! them and names the first; a stream left with no usable sample is an
//! error naming the first record and field. The dead reckoning and the
//! rotation assembly reject the same values themselves
//! (`dead_reckoning::run`, `rotation::assemble_rotations`), so a caller
//! that does not screen gets an error naming the record, never a hang.

use crate::error::FrontendError;
use crate::sensors::Mission;
use crate::warnings::{Warning, WarningKind, Warnings};
use std::borrow::Cow;

/// The largest horizontal speed of a DVL sample, m/s. DVLs measure up to
/// about 10 m/s and the vehicles that carry them move at a few m/s; twice
/// the instruments' range leaves room for noise and still rejects every
/// corrupt record.
pub const MAX_DVL_SPEED_MPS: f64 = 20.0;

/// The largest magnitude of an angle in a record (beam angle, attitude
/// yaw), rad: unwrapped angles grow by 2π per turn, and 10⁶ rad is 160 000
/// turns; beyond it an `f64` angle has lost its sub-microradian precision
/// and is a corrupt value, not an angle.
pub const MAX_ANGLE_RAD: f64 = 1e6;

/// The largest yaw rate of an attitude sample, rad/s: 2000°/s, the range
/// of the fastest MEMS gyros.
pub const MAX_YAW_RATE_RADPS: f64 = 35.0;

/// Why a DVL sample's velocity is implausible, if it is (valid samples
/// only; invalid ones carry no velocity).
pub fn implausible_dvl_speed(velocity_mps: &nalgebra::Vector3<f64>) -> Option<String> {
    let speed = velocity_mps.xy().norm();
    (speed > MAX_DVL_SPEED_MPS).then(|| {
        format!("horizontal speed {speed:e} m/s exceeds {MAX_DVL_SPEED_MPS} m/s, more than any DVL measures")
    })
}

/// Why an angle of a record is implausible, if it is.
pub fn implausible_angle(angle_rad: f64) -> Option<String> {
    (angle_rad.abs() > MAX_ANGLE_RAD)
        .then(|| format!("{angle_rad:e} rad is beyond ±{MAX_ANGLE_RAD:e} rad: not an angle"))
}

/// Why a yaw rate is implausible, if it is.
pub fn implausible_yaw_rate(rate_radps: f64) -> Option<String> {
    (rate_radps.abs() > MAX_YAW_RATE_RADPS)
        .then(|| format!("{rate_radps:e} rad/s exceeds ±{MAX_YAW_RATE_RADPS} rad/s"))
}

/// `mission` without its implausible samples (see the module doc), and a
/// warning per stream that lost some. Borrowed when nothing is dropped.
///
/// Errors: a stream whose every sample (every valid one, for the DVL) is
/// implausible; the error names the first such record and its field.
/// Non-finite values are left for the stages that read them to reject.
pub fn screen(mission: &Mission) -> Result<(Cow<'_, Mission>, Warnings), FrontendError> {
    let bad = Implausible::find(mission);
    let mut warnings = Warnings::new();
    if bad.dvl.is_empty() && bad.attitude.is_empty() && bad.beams.is_empty() {
        return Ok((Cow::Borrowed(mission), warnings));
    }
    let valid_dvl = mission.dvl.iter().filter(|s| s.valid).count();
    let streams = [
        (
            &bad.dvl,
            valid_dvl,
            "DVL sample",
            format!("valid sample ({valid_dvl})"),
            "valid DVL samples",
        ),
        (
            &bad.attitude,
            mission.attitude.len(),
            "attitude sample",
            "attitude sample".to_string(),
            "attitude samples",
        ),
        (
            &bad.beams,
            mission.beams.len(),
            "beam",
            "beam".to_string(),
            "sonar beams",
        ),
    ];
    for (bad, total, record, every_other, samples) in streams {
        let text = StreamText {
            record,
            every_other,
            samples,
        };
        warnings.extend(stream_warning(bad, total, &text)?);
    }
    Ok((Cow::Owned(bad.removed_from(mission)), warnings))
}

/// One implausible sample: its index in its stream, the field and why.
type Bad = (usize, &'static str, String);

/// The implausible samples of each stream, in stream order.
struct Implausible {
    /// Valid DVL samples only (invalid ones carry no velocity).
    dvl: Vec<Bad>,
    attitude: Vec<Bad>,
    beams: Vec<Bad>,
}

impl Implausible {
    fn find(mission: &Mission) -> Self {
        let dvl = mission
            .dvl
            .iter()
            .enumerate()
            .filter(|(_, s)| s.valid)
            .filter_map(|(i, s)| {
                implausible_dvl_speed(&s.velocity_mps).map(|why| (i, "velocity_mps", why))
            })
            .collect();
        let attitude = mission
            .attitude
            .iter()
            .enumerate()
            .filter_map(|(i, a)| {
                implausible_angle(a.yaw_rad)
                    .map(|why| (i, "yaw_rad", why))
                    .or_else(|| {
                        a.yaw_rate_radps
                            .and_then(implausible_yaw_rate)
                            .map(|why| (i, "yaw_rate_radps", why))
                    })
            })
            .collect();
        let beams = mission
            .beams
            .iter()
            .enumerate()
            .filter_map(|(i, b)| implausible_angle(b.angle_rad).map(|why| (i, "angle_rad", why)))
            .collect();
        Self {
            dvl,
            attitude,
            beams,
        }
    }

    /// `mission` with the implausible DVL samples marked invalid and the
    /// implausible attitude samples and beams removed.
    fn removed_from(&self, mission: &Mission) -> Mission {
        let mut out = mission.clone();
        for &(i, _, _) in &self.dvl {
            out.dvl[i].valid = false;
        }
        let keep = |n: usize, bad: &[Bad]| {
            let mut keep = vec![true; n];
            bad.iter().for_each(|b| keep[b.0] = false);
            keep
        };
        let keep_attitude = keep(out.attitude.len(), &self.attitude);
        let mut k = keep_attitude.iter();
        out.attitude.retain(|_| *k.next().unwrap_or(&true));
        let keep_beams = keep(out.beams.len(), &self.beams);
        let mut k = keep_beams.iter();
        out.beams.retain(|_| *k.next().unwrap_or(&true));
        out
    }
}

/// How a stream's records are named in the messages.
struct StreamText {
    /// One record, before its index ("DVL sample").
    record: &'static str,
    /// "every other ..." when all are implausible.
    every_other: String,
    /// The records, in the count of those dropped ("valid DVL samples").
    samples: &'static str,
}

/// The warning for a stream that lost the `bad` of its `total` samples
/// (`None` when it lost none). Errors when it lost every one, naming the
/// first record and field.
fn stream_warning(
    bad: &[Bad],
    total: usize,
    text: &StreamText,
) -> Result<Option<Warning>, FrontendError> {
    let Some((i, field, why)) = bad.first() else {
        return Ok(None);
    };
    let record = format!("{} {i}", text.record);
    if bad.len() == total {
        return Err(FrontendError::input(
            record,
            *field,
            format!("{why}; and so does every other {}", text.every_other),
        ));
    }
    let message = format!(
        "{} of {total} {} were dropped as implausible (first: {record}, {field}: {why})",
        bad.len(),
        text.samples
    );
    Ok(Some(
        Warning::new(WarningKind::ImplausibleValues, bad.len(), message).at(record),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensors::{Attitude, DvlVelocity, SonarBeam};
    use nalgebra::Vector3;

    fn mission(speeds: &[f64], yaws: &[f64], angles: &[f64]) -> Mission {
        Mission {
            dvl: speeds
                .iter()
                .enumerate()
                .map(|(i, &v)| DvlVelocity {
                    stamp_s: i as f64,
                    velocity_mps: Vector3::new(v, 0.0, 0.0),
                    valid: true,
                    covariance: None,
                })
                .collect(),
            attitude: yaws
                .iter()
                .enumerate()
                .map(|(i, &y)| Attitude {
                    stamp_s: i as f64,
                    roll_rad: 0.0,
                    pitch_rad: 0.0,
                    yaw_rad: y,
                    yaw_rate_radps: None,
                })
                .collect(),
            beams: angles
                .iter()
                .enumerate()
                .map(|(i, &a)| SonarBeam {
                    stamp_s: i as f64,
                    angle_rad: a,
                    bin_size_m: 0.1,
                    first_bin_range_m: 0.0,
                    intensities: vec![0; 4],
                })
                .collect(),
            ..Mission::default()
        }
    }

    #[test]
    fn plausible_missions_are_borrowed_unchanged() {
        let m = mission(&[0.5, 19.9], &[0.0, 3.0], &[0.0, 1e5]);
        let (out, warnings) = screen(&m).unwrap();
        assert!(matches!(out, Cow::Borrowed(_)));
        assert!(warnings.is_empty());
    }

    #[test]
    fn implausible_samples_are_dropped_counted_and_the_first_named() {
        let m = mission(
            &[0.5, 1e20, 1e3, 0.4],
            &[0.0, 1.7e306, 0.1],
            &[0.0, 1e300, 0.1],
        );
        let (out, warnings) = screen(&m).unwrap();
        assert_eq!(out.dvl.iter().filter(|s| s.valid).count(), 2);
        assert!(!out.dvl[1].valid && !out.dvl[2].valid);
        assert_eq!(out.attitude.len(), 2);
        assert_eq!(out.attitude[1].yaw_rad, 0.1);
        assert_eq!(out.beams.len(), 2);
        assert_eq!(out.beams[1].angle_rad, 0.1);
        // One entry for the kind, counting all four samples.
        assert_eq!(warnings.len(), 1);
        let w = warnings.of(WarningKind::ImplausibleValues).unwrap();
        assert_eq!(w.count, 4);
        assert_eq!(w.first_record.as_deref(), Some("DVL sample 1"));
        assert!(w.message.contains("velocity_mps"), "{}", w.message);
    }

    #[test]
    fn a_stream_with_nothing_plausible_is_an_error_naming_record_and_field() {
        for (m, record, field) in [
            (
                mission(&[1e20, 1e20], &[0.0], &[0.0]),
                "DVL sample 0",
                "velocity_mps",
            ),
            (
                mission(&[1.0], &[1e308], &[0.0]),
                "attitude sample 0",
                "yaw_rad",
            ),
            (
                mission(&[1.0], &[0.0], &[1e300, -1e300]),
                "beam 0",
                "angle_rad",
            ),
        ] {
            let message = screen(&m).unwrap_err().to_string();
            assert!(
                message.contains(record) && message.contains(field),
                "{message}"
            );
        }
    }
}
