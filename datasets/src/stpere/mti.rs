//! `_MTI.log`: Xsens MTi attitude at 10 Hz.
//!
//! The header of this file is wrong (it lists positions and velocities). The
//! 10 data columns are: time, roll, pitch, yaw (degrees), angular rates x, y,
//! z (rad/s), accelerations x, y, z (m/s²). A filled `[idSensor]` column (11
//! columns) is accepted and ignored.
//!
//! Frames: the MTi reports in a north-east-down convention. The accelerometer
//! z reads −9.8 m/s² when level (z down), the yaw grows when the z rate is
//! positive (turning clockwise seen from above), and the yaw agrees with the
//! DVL's clockwise-from-north compass to within a constant. So the body frame
//! is x forward, y starboard, z down and the yaw is a compass heading. It is
//! converted to echofield's x forward / y port / z up vehicle frame and the
//! east-north world frame: `yaw = π/2 − heading`, `pitch = −pitch_MTi`,
//! `roll = roll_MTi`, yaw rate `= −rate_z`.

use super::text::{Layout, SkippedLine, TextLog};
use crate::error::DatasetError;
use echofield_frontend::sensors::Attitude;
use echofield_graph::wrap_angle;
use std::f64::consts::FRAC_PI_2;

const LAYOUT: Layout = Layout {
    columns: 10,
    optional_id: true,
    time: "time",
};

/// A compass heading (degrees, clockwise from north) as echofield yaw
/// (radians, counter-clockwise from east), wrapped to (−π, π].
pub fn compass_to_yaw_rad(heading_deg: f64) -> f64 {
    wrap_angle(FRAC_PI_2 - heading_deg.to_radians())
}

/// The largest magnitude of a logged heading, degrees.
const MAX_HEADING_DEG: f64 = 720.0;

pub(crate) struct MtiLog {
    pub samples: Vec<Attitude>,
    pub skipped: Vec<SkippedLine>,
}

pub(crate) fn parse_mti(log: &TextLog) -> Result<MtiLog, DatasetError> {
    let mut out = MtiLog {
        samples: Vec::with_capacity(40_000),
        skipped: Vec::new(),
    };
    out.skipped = log.for_each_record(&LAYOUT, |record| {
        let (line, shift, stamp_s) = (record.line, record.shift, record.stamp_s);
        let roll_deg = log.float(line, 1 + shift, "roll")?;
        let pitch_deg = log.float(line, 2 + shift, "pitch")?;
        let heading_deg = log.float(line, 3 + shift, "yaw")?;
        // A compass heading beyond two turns is a corrupt value, not a
        // heading (1e308° once read as a heading silently, issue 35).
        if heading_deg.abs() > MAX_HEADING_DEG {
            return Err(log.error(
                line.line,
                &format!("column {} (yaw)", 4 + shift),
                format!("{heading_deg:e} degrees is not a heading (beyond ±{MAX_HEADING_DEG}°)"),
            ));
        }
        let rate_z_radps = log.float(line, 6 + shift, "rate z")?;
        // The accelerations are parsed only to reject a corrupt line.
        for (k, name) in ["rate x", "rate y", "acc x", "acc y", "acc z"]
            .iter()
            .enumerate()
        {
            let index = [4, 5, 7, 8, 9][k] + shift;
            log.float(line, index, name)?;
        }
        out.samples.push(Attitude {
            stamp_s,
            roll_rad: wrap_angle(roll_deg.to_radians()),
            pitch_rad: wrap_angle(-pitch_deg.to_radians()),
            yaw_rad: compass_to_yaw_rad(heading_deg),
            yaw_rate_radps: Some(-rate_z_radps),
        });
        Ok(None)
    })?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn compass_headings_become_ccw_from_east() {
        assert!((compass_to_yaw_rad(0.0) - FRAC_PI_2).abs() < 1e-12);
        assert!(compass_to_yaw_rad(90.0).abs() < 1e-12);
        assert!((compass_to_yaw_rad(180.0) + FRAC_PI_2).abs() < 1e-12);
        assert!((compass_to_yaw_rad(270.0) - PI).abs() < 1e-12);
        // 90 + 126.276 = 216.276 deg, wrapped to -143.724 deg.
        assert!((compass_to_yaw_rad(-126.276) - (-143.724f64).to_radians()).abs() < 1e-9);
    }

    #[test]
    fn parses_a_real_line_with_trailing_space() {
        let text = b"% time, [idSensor], positionX\r\n\r\n1093455407.042 0.506328 -2.5422 -126.276 0.0115654 -0.00641596 0.00508943 -0.427074 -0.0795686 -9.77331 \r\n";
        let mti = parse_mti(&TextLog::from_bytes("m.log", text)).unwrap();
        let a = &mti.samples[0];
        assert_eq!(a.stamp_s, 1093455407.042);
        assert!((a.roll_rad - 0.506328f64.to_radians()).abs() < 1e-12);
        assert!((a.pitch_rad - 2.5422f64.to_radians()).abs() < 1e-12);
        assert_eq!(a.yaw_rate_radps, Some(-0.00508943));
    }

    #[test]
    fn nan_yaw_is_an_error_naming_the_column() {
        let text = b"1 0 0 nan 0 0 0 0 0 -9.8\n";
        let err = parse_mti(&TextLog::from_bytes("m.log", text))
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains("m.log: line 1: field `column 4 (yaw)`"),
            "{err}"
        );
    }
}
