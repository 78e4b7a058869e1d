//! `_DGPS.log`: DGPS fixes at 1 Hz, the ground truth of the mission.
//!
//! 10 data columns (11 with a filled `[idSensor]`): time, latitude and
//! longitude in NMEA `ddmm.mmmm` (north and east are assumed: the log has no
//! hemisphere column), status (GGA fix quality; 0 = no fix), altitude (m),
//! geoid altitude (m), true course, magnetic course (deg), speed (kn), speed
//! (km/h). Fixes with status 0 are skipped and counted.

use super::local_frame::{LocalTangentPlane, nmea_to_degrees};
use super::text::{Layout, SkipReason, SkippedLine, TextLog};
use crate::error::DatasetError;
use serde::{Deserialize, Serialize};

const LAYOUT: Layout = Layout {
    columns: 10,
    optional_id: true,
    time: "time",
};

/// One DGPS fix as read, plus its position in the mission's local frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DgpsFix {
    pub stamp_s: f64,
    pub latitude_deg: f64,
    pub longitude_deg: f64,
    /// GGA fix quality as logged (1 = GPS, 2 = DGPS).
    pub status: i64,
    pub altitude_m: f64,
    /// Position in the local frame about the first fix (x east, y north), m.
    pub east_m: f64,
    pub north_m: f64,
}

pub(crate) struct DgpsLog {
    pub fixes: Vec<DgpsFix>,
    pub frame: Option<LocalTangentPlane>,
    pub skipped: Vec<SkippedLine>,
}

pub(crate) fn parse_dgps(log: &TextLog) -> Result<DgpsLog, DatasetError> {
    let mut out = DgpsLog {
        fixes: Vec::new(),
        frame: None,
        skipped: Vec::new(),
    };
    out.skipped = log.for_each_record(&LAYOUT, |record| {
        let (line, shift, stamp_s) = (record.line, record.shift, record.stamp_s);
        let status = log.integer(line, 3 + shift, "status")?;
        if status <= 0 {
            return Ok(Some(SkipReason::NoGpsFix { status }));
        }
        let latitude_deg = angle(log, line, 1 + shift, "latitude", 90.0)?;
        let longitude_deg = angle(log, line, 2 + shift, "longitude", 180.0)?;
        let altitude_m = log.float(line, 4 + shift, "altitude")?;
        let frame = *out
            .frame
            .get_or_insert_with(|| LocalTangentPlane::new(latitude_deg, longitude_deg));
        let (east_m, north_m) = frame.east_north_m(latitude_deg, longitude_deg);
        out.fixes.push(DgpsFix {
            stamp_s,
            latitude_deg,
            longitude_deg,
            status,
            altitude_m,
            east_m,
            north_m,
        });
        Ok(None)
    })?;
    Ok(out)
}

fn angle(
    log: &TextLog,
    line: &super::text::DataLine<'_>,
    index: usize,
    name: &str,
    limit_deg: f64,
) -> Result<f64, DatasetError> {
    let ddmm = log.float(line, index, name)?;
    match nmea_to_degrees(ddmm) {
        Some(deg) if deg <= limit_deg => Ok(deg),
        _ => Err(log.error(
            line.line,
            &format!("column {} ({name})", index + 1),
            format!("{ddmm} is not an NMEA ddmm.mmmm angle within ±{limit_deg} deg"),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_fix_is_the_origin_and_north_is_positive_y() {
        let text = b"% x\xba\r\n1093455407.9 4212.225 306.2832 1 -2.1 51.8 23.6 24 0.1 0.1\r\n\
1093455408.9 4212.226 306.2832 1 -2.1 51.8 23.6 24 0.1 0.1\r\n\
1093455409.9 4212.226 306.2832 0 -2.1 51.8 23.6 24 0.1 0.1";
        let dgps = parse_dgps(&TextLog::from_bytes("g.log", text)).unwrap();
        assert_eq!(dgps.fixes.len(), 2);
        assert_eq!((dgps.fixes[0].east_m, dgps.fixes[0].north_m), (0.0, 0.0));
        // 0.001 minute of latitude = 1.852 m.
        assert!((dgps.fixes[1].north_m - 1.852).abs() < 0.01);
        assert!(dgps.fixes[1].east_m.abs() < 1e-9);
        assert_eq!(dgps.skipped.len(), 1);
        assert_eq!(dgps.skipped[0].reason, SkipReason::NoGpsFix { status: 0 });
    }

    #[test]
    fn bad_minutes_are_an_error() {
        let text = b"1093455407.9 4275.0 306.2832 1 -2.1 51.8 23.6 24 0.1 0.1\n";
        let err = parse_dgps(&TextLog::from_bytes("g.log", text))
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains("line 1") && err.contains("latitude"), "{err}");
    }
}
