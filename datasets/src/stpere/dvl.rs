//! `_DVL.log`: SonTek Argonaut DVL records.
//!
//! 32 data columns (the header's `[idSensor]` column is empty in the data; a
//! file that does fill it, 33 columns, is accepted and the id ignored):
//! time, year, month, day, hour, minute, second, water velocity x, y, z,
//! status, bottom velocity x, y, z, status, 3 bottom ranges, 3 amplitudes,
//! percent good, heading, pitch, roll, temperature, pressure, power level,
//! slosv, elosv, distance travelled x, y. Velocities in cm/s; 32767 marks an
//! invalid value.
//!
//! Frame: the header says `CoordSystem: 1 {BEAM, XYZ, ENU}`, velocities in the
//! instrument XYZ frame. Dead reckoning against DGPS (see the module doc of
//! [`crate::stpere`]) shows x forward and y to port, so with a right-handed z
//! (up) the instrument frame already is echofield's vehicle-frame convention
//! and the components are kept as they are, only scaled to m/s.

use super::mti::compass_to_yaw_rad;
use super::text::{Layout, SkippedLine, TextLog};
use crate::error::DatasetError;
use echofield_frontend::sensors::{Attitude, DvlVelocity};
use nalgebra::Vector3;

/// Value the Argonaut writes for a velocity it could not measure, cm/s.
pub const DVL_INVALID_CMPS: f64 = 32767.0;
const LAYOUT: Layout = Layout {
    columns: 32,
    optional_id: true,
    time: "time",
};
const BOTTOM_VX: usize = 11;
const BOTTOM_STATUS: usize = 14;
const HEADING: usize = 22;
const PITCH: usize = 23;
const ROLL: usize = 24;

/// DVL samples plus the instrument's own compass (kept for checks).
pub(crate) struct DvlLog {
    pub samples: Vec<DvlVelocity>,
    /// The DVL compass heading converted like the MTi's (see
    /// [`super::mti::compass_to_yaw_rad`]); roll and pitch as written (degrees
    /// to radians, sign convention not verified).
    pub compass: Vec<Attitude>,
    pub skipped: Vec<SkippedLine>,
}

pub(crate) fn parse_dvl(log: &TextLog) -> Result<DvlLog, DatasetError> {
    let mut out = DvlLog {
        samples: Vec::new(),
        compass: Vec::new(),
        skipped: Vec::new(),
    };
    out.skipped = log.for_each_record(&LAYOUT, |record| {
        let (line, shift, stamp_s) = (record.line, record.shift, record.stamp_s);
        let names = ["bottomVelX", "bottomVelY", "bottomVelZ"];
        let mut velocity_cmps = [0.0; 3];
        for (k, name) in names.iter().enumerate() {
            velocity_cmps[k] = log.float(line, BOTTOM_VX + shift + k, name)?;
        }
        let status = log.integer(line, BOTTOM_STATUS + shift, "bottomVelStatus")?;
        let heading_deg = log.float(line, HEADING + shift, "heading")?;
        let pitch_deg = log.float(line, PITCH + shift, "pitch")?;
        let roll_deg = log.float(line, ROLL + shift, "roll")?;
        let flagged = velocity_cmps.iter().any(|v| v.abs() >= DVL_INVALID_CMPS);
        let valid = status == 1 && !flagged;
        // Beyond the invalid marker a velocity is a corrupt value (issue
        // 35: 1e20 m/s hung the dead reckoning).
        if let Some(k) = (0..3).find(|&k| velocity_cmps[k].abs() > DVL_INVALID_CMPS) {
            return Err(log.error(
                line.line,
                &format!("column {} ({})", BOTTOM_VX + shift + k + 1, names[k]),
                format!(
                    "{:e} cm/s is beyond the Argonaut's invalid marker {DVL_INVALID_CMPS} cm/s: a corrupt value",
                    velocity_cmps[k]
                ),
            ));
        }
        let velocity_mps = if valid {
            Vector3::from(velocity_cmps) / 100.0
        } else {
            Vector3::zeros()
        };
        out.samples.push(DvlVelocity {
            stamp_s,
            velocity_mps,
            valid,
            covariance: None,
        });
        out.compass.push(Attitude {
            stamp_s,
            roll_rad: roll_deg.to_radians(),
            pitch_rad: pitch_deg.to_radians(),
            yaw_rad: compass_to_yaw_rad(heading_deg),
            yaw_rate_radps: None,
        });
        Ok(None)
    })?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "1093455407.147 2007 3 16 13 0 56 38.20 -47.00 1.80 1 6.10 -4.90 2.80 1 1.84 1.88 1.86 143.00 142.00 149.00 100 207.70 -0.50 1.60 14.27 1488.00 12.80 0.50 1.50 0.08 -0.25";
    const INVALID: &str = "1093455669.508 2007 3 16 13 5 19 -19.60 21.10 -4.60 1 32767.00 32767.00 32767.00 0 1.95 0.00 1.96 126.00 101.00 115.00 0 106.40 -0.40 1.70 14.05 1488.00 12.80 0.50 4.10 15.57 30.23";

    #[test]
    fn converts_cm_per_s_and_flags_32767() {
        let text = format!("% header\r\n\r\n{GOOD}\r\n{INVALID}\r\n");
        let dvl = parse_dvl(&TextLog::from_bytes("d.log", text.as_bytes())).unwrap();
        assert_eq!(dvl.samples.len(), 2);
        let s = &dvl.samples[0];
        assert!(s.valid);
        assert!((s.velocity_mps - Vector3::new(0.061, -0.049, 0.028)).norm() < 1e-12);
        assert!(!dvl.samples[1].valid);
        // Heading 207.7 deg clockwise from north = -117.7 deg from east, CCW.
        assert!((dvl.compass[0].yaw_rad - (-117.7f64).to_radians()).abs() < 1e-12);
    }

    #[test]
    fn filled_id_column_is_accepted() {
        let with_id = GOOD.replacen(' ', " 7 ", 1);
        let dvl = parse_dvl(&TextLog::from_bytes("d.log", with_id.as_bytes())).unwrap();
        assert!((dvl.samples[0].velocity_mps.x - 0.061).abs() < 1e-12);
    }

    #[test]
    fn short_line_in_the_middle_is_an_error() {
        let text = format!("{GOOD}\n1093455408 2007 3\n{INVALID}\n");
        let err = parse_dvl(&TextLog::from_bytes("d.log", text.as_bytes()))
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains("d.log") && err.contains("line 2") && err.contains("3 columns"),
            "{err}"
        );
    }

    #[test]
    fn truncated_last_line_is_skipped_and_counted() {
        let text = format!("{GOOD}\r\n1093455408 2007 3 16");
        let dvl = parse_dvl(&TextLog::from_bytes("d.log", text.as_bytes())).unwrap();
        assert_eq!(dvl.samples.len(), 1);
        assert_eq!(dvl.skipped.len(), 1);
        assert_eq!(dvl.skipped[0].line, 2);
    }
}
