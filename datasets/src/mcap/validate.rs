//! Value checks shared by the writers and the readers, so a file echofield
//! writes is always one it can read back.

use crate::DatasetError;
use echofield_frontend::sensors::{
    Attitude, DvlVelocity, GroundTruthPose, Mission, PositionFix, SensorMounting, SonarBeam,
};
use std::path::Path;

/// A bad field of one record: which field, and what is wrong with it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct FieldError {
    pub field: String,
    pub message: String,
}

impl FieldError {
    pub fn new(field: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            field: field.into(),
            message: message.into(),
        }
    }

    /// Attaches the file and record to make a [`DatasetError::Parse`].
    pub fn at(self, path: &Path, record: impl Into<String>) -> DatasetError {
        DatasetError::parse(path, record, self.field, self.message)
    }
}

/// The largest stamp whose nanosecond count fits the `u64` log time of MCAP
/// (about the year 2554).
const MAX_STAMP_S: f64 = 1.8e10;

fn finite(field: &str, value: f64) -> Result<(), FieldError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(FieldError::new(
            field,
            format!("value {value} is not finite"),
        ))
    }
}

/// A stamp must be finite, non-negative and fit the MCAP log time.
pub(crate) fn stamp(stamp_s: f64) -> Result<(), FieldError> {
    finite("stamp_s", stamp_s)?;
    if !(0.0..=MAX_STAMP_S).contains(&stamp_s) {
        return Err(FieldError::new(
            "stamp_s",
            format!("stamp {stamp_s} s is outside [0, {MAX_STAMP_S}] s"),
        ));
    }
    Ok(())
}

/// MCAP log time in nanoseconds for a stamp already checked by [`stamp`].
pub(crate) fn log_time_ns(stamp_s: f64) -> u64 {
    (stamp_s * 1e9).round() as u64
}

pub(crate) fn beam(beam: &SonarBeam) -> Result<(), FieldError> {
    stamp(beam.stamp_s)?;
    finite("angle_rad", beam.angle_rad)?;
    finite("bin_size_m", beam.bin_size_m)?;
    if beam.bin_size_m <= 0.0 {
        return Err(FieldError::new(
            "bin_size_m",
            format!("bin size {} m must be positive", beam.bin_size_m),
        ));
    }
    finite("first_bin_range_m", beam.first_bin_range_m)?;
    if beam.first_bin_range_m < 0.0 {
        return Err(FieldError::new(
            "first_bin_range_m",
            format!("first bin range {} m is negative", beam.first_bin_range_m),
        ));
    }
    if beam.intensities.is_empty() {
        return Err(FieldError::new("intensities", "beam has no bins"));
    }
    Ok(())
}

pub(crate) fn dvl(dvl: &DvlVelocity) -> Result<(), FieldError> {
    stamp(dvl.stamp_s)?;
    for (axis, v) in ["x", "y", "z"].iter().zip(dvl.velocity_mps.iter()) {
        finite(&format!("velocity_mps.{axis}"), *v)?;
    }
    if let Some(cov) = &dvl.covariance {
        for r in 0..3 {
            for c in 0..3 {
                finite(&format!("covariance[{r}][{c}]"), cov[(r, c)])?;
            }
        }
    }
    Ok(())
}

pub(crate) fn attitude(att: &Attitude) -> Result<(), FieldError> {
    stamp(att.stamp_s)?;
    finite("roll_rad", att.roll_rad)?;
    finite("pitch_rad", att.pitch_rad)?;
    finite("yaw_rad", att.yaw_rad)?;
    if let Some(rate) = att.yaw_rate_radps {
        finite("yaw_rate_radps", rate)?;
    }
    Ok(())
}

pub(crate) fn ground_truth(gt: &GroundTruthPose) -> Result<(), FieldError> {
    stamp(gt.stamp_s)?;
    finite("x_m", gt.world_from_vehicle.x())?;
    finite("y_m", gt.world_from_vehicle.y())?;
    finite("yaw_rad", gt.world_from_vehicle.theta())?;
    Ok(())
}

/// The largest coordinate of a position fix, m: a UTM northing is below
/// 10⁷ m; beyond twice that the value is not a position on Earth's surface
/// in any projected plane.
pub(crate) const MAX_FIX_COORDINATE_M: f64 = 2.0e7;
/// The largest standard deviation of a position fix, m: a fix less certain
/// than this says nothing a merge could use, and is more likely a unit
/// mix-up (centimetres, a variance) than a measurement.
pub(crate) const MAX_FIX_STD_M: f64 = 1.0e4;

/// A fix: finite coordinates within [`MAX_FIX_COORDINATE_M`], a standard
/// deviation in `(0, MAX_FIX_STD_M]`.
pub(crate) fn position_fix(fix: &PositionFix) -> Result<(), FieldError> {
    stamp(fix.stamp_s)?;
    for (field, v) in [("x_m", fix.x_m), ("y_m", fix.y_m)] {
        finite(field, v)?;
        if v.abs() > MAX_FIX_COORDINATE_M {
            return Err(FieldError::new(
                field,
                format!("{v} m is beyond ±{MAX_FIX_COORDINATE_M} m of the plane's origin"),
            ));
        }
    }
    finite("std_m", fix.std_m)?;
    if fix.std_m <= 0.0 || fix.std_m > MAX_FIX_STD_M {
        return Err(FieldError::new(
            "std_m",
            format!(
                "standard deviation {} m is outside (0, {MAX_FIX_STD_M}] m",
                fix.std_m
            ),
        ));
    }
    Ok(())
}

/// The mounting must serialise without `null`: serde_json writes NaN and
/// infinities as `null`, so this catches a non-finite value in any field,
/// present or future, and names it.
pub(crate) fn mounting(mounting: &SensorMounting) -> Result<(), FieldError> {
    fn find_null(value: &serde_json::Value, path: &str) -> Option<String> {
        match value {
            serde_json::Value::Null => Some(path.to_string()),
            serde_json::Value::Array(items) => items
                .iter()
                .enumerate()
                .find_map(|(i, v)| find_null(v, &format!("{path}[{i}]"))),
            serde_json::Value::Object(fields) => fields
                .iter()
                .find_map(|(k, v)| find_null(v, &format!("{path}.{k}"))),
            _ => None,
        }
    }
    let value =
        serde_json::to_value(mounting).map_err(|e| FieldError::new("mounting", e.to_string()))?;
    match find_null(&value, "mounting") {
        Some(field) => Err(FieldError::new(field, "value is not finite")),
        None => Ok(()),
    }
}

/// Checks every record of a mission before anything is written; the record is
/// named by stream and index (`beam 12`).
pub(crate) fn mission(path: &Path, mission: &Mission) -> Result<(), DatasetError> {
    mounting(&mission.mounting).map_err(|e| e.at(path, "mission"))?;
    check_all(path, "beam", &mission.beams, beam)?;
    check_all(path, "dvl", &mission.dvl, dvl)?;
    check_all(path, "attitude", &mission.attitude, attitude)?;
    check_all(path, "ground_truth", &mission.ground_truth, ground_truth)?;
    check_all(path, "position_fix", &mission.position_fixes, position_fix)
}

fn check_all<T>(
    path: &Path,
    stream: &str,
    records: &[T],
    check: fn(&T) -> Result<(), FieldError>,
) -> Result<(), DatasetError> {
    for (i, record) in records.iter().enumerate() {
        check(record).map_err(|e| e.at(path, format!("{stream} {i}")))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_time_rounds_to_nearest_ns() {
        assert_eq!(log_time_ns(1.5), 1_500_000_000);
        assert_eq!(log_time_ns(0.0), 0);
        // 1.7e9 s has a resolution of ~0.24 µs in f64; rounding, not truncation.
        assert_eq!(log_time_ns(2.0e-9 - 1e-12), 2);
    }

    #[test]
    fn stamp_limits() {
        assert!(stamp(0.0).is_ok());
        assert!(stamp(1.7e9).is_ok());
        assert_eq!(stamp(-1.0).unwrap_err().field, "stamp_s");
        assert_eq!(stamp(f64::NAN).unwrap_err().field, "stamp_s");
        assert!(stamp(1.0e11).is_err());
    }

    #[test]
    fn non_finite_mounting_is_named() {
        let mut m = SensorMounting::default();
        assert!(mounting(&m).is_ok());
        m.vehicle_from_dvl = echofield_graph::Se2::new(0.0, f64::INFINITY, 0.0);
        assert_eq!(
            mounting(&m).unwrap_err().field,
            "mounting.vehicle_from_dvl[1]"
        );
    }
}
