//! The sonar files: `_SETUP.log`, `_IS_timestamps.log` and `_IS.log`.
//!
//! - `_SETUP.log`: one line `range_m bin_size_m step_rad` (`50 0.1 0.0314159`).
//! - `_IS_timestamps.log`: `time_s sensor_clock_ms`, one line per beam.
//! - `_IS.log` (not in the public logs; for users with the full data set):
//!   `%` header lines, then `logtime_s sensortime transducer_angle_rad bin_0 …
//!   bin_{n−1}` with `n = range_m / bin_size_m` intensities 0-255. The angle is
//!   passed through unchanged (the head's own convention; not verifiable
//!   without the file).

use super::text::{DataLine, Layout, SkippedLine, TextLog};
use crate::error::DatasetError;
use echofield_frontend::sensors::SonarBeam;
use serde::{Deserialize, Serialize};

/// The sonar configuration of the mission.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SonarSetup {
    /// Maximum range, metres.
    pub range_m: f64,
    /// Range length of one bin, metres.
    pub bin_size_m: f64,
    /// Transducer step between consecutive beams, radians.
    pub step_rad: f64,
}

impl SonarSetup {
    /// Bins per beam, `range_m / bin_size_m` rounded.
    pub fn bins(&self) -> usize {
        (self.range_m / self.bin_size_m).round() as usize
    }
}

/// Time of one beam: the logger's Unix time and the sonar's own clock.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BeamStamp {
    pub stamp_s: f64,
    /// The sensor's millisecond counter.
    pub sensor_clock_ms: i64,
}

pub(crate) fn parse_setup(log: &TextLog) -> Result<SonarSetup, DatasetError> {
    let line = log
        .data_lines()
        .next()
        .ok_or_else(|| log.error(1, "line", "no setup line"))?;
    if line.fields.len() != 3 {
        return Err(log.error(
            line.line,
            "columns",
            format!("{} columns, expected 3", line.fields.len()),
        ));
    }
    let setup = SonarSetup {
        range_m: log.float(&line, 0, "range")?,
        bin_size_m: log.float(&line, 1, "bin size")?,
        step_rad: log.float(&line, 2, "step")?,
    };
    let fields = [
        ("range", setup.range_m),
        ("bin size", setup.bin_size_m),
        ("step", setup.step_rad),
    ];
    for (k, (name, value)) in fields.iter().enumerate() {
        if *value <= 0.0 {
            return Err(log.error(
                line.line,
                &format!("column {} ({name})", k + 1),
                "must be positive",
            ));
        }
    }
    // Every beam and every rotation is allocated from these numbers: a
    // corrupted setup must not ask for billions of bins or steps.
    let bins = setup.range_m / setup.bin_size_m;
    if !(bins.round() >= 1.0 && bins <= MAX_SETUP_COUNT) {
        return Err(log.error(
            line.line,
            "column 2 (bin size)",
            format!(
                "range {} m / bin size {} m gives {bins:.0} bins per beam, expected 1 to {MAX_SETUP_COUNT}",
                setup.range_m, setup.bin_size_m
            ),
        ));
    }
    let steps = std::f64::consts::TAU / setup.step_rad;
    if steps > MAX_SETUP_COUNT {
        return Err(log.error(
            line.line,
            "column 3 (step)",
            format!(
                "a step of {} rad gives {steps:.0} beams per turn, more than {MAX_SETUP_COUNT}",
                setup.step_rad
            ),
        ));
    }
    Ok(setup)
}

/// Most bins per beam and beams per turn a setup may give (sonar heads
/// have a few hundred to a few thousand of either).
const MAX_SETUP_COUNT: f64 = 100_000.0;

pub(crate) fn parse_beam_stamps(
    log: &TextLog,
) -> Result<(Vec<BeamStamp>, Vec<SkippedLine>), DatasetError> {
    let mut stamps = Vec::with_capacity(50_000);
    let layout = Layout {
        columns: 2,
        optional_id: false,
        time: "time",
    };
    let skipped = log.for_each_record(&layout, |record| {
        let sensor_clock_ms = log.integer(record.line, 1, "sensor clock")?;
        stamps.push(BeamStamp {
            stamp_s: record.stamp_s,
            sensor_clock_ms,
        });
        Ok(None)
    })?;
    Ok((stamps, skipped))
}

pub(crate) fn parse_beams(
    log: &TextLog,
    setup: &SonarSetup,
) -> Result<(Vec<SonarBeam>, Vec<SkippedLine>), DatasetError> {
    let bins = setup.bins();
    let mut beams = Vec::new();
    let layout = Layout {
        columns: 3 + bins,
        optional_id: false,
        time: "logtime",
    };
    let skipped = log.for_each_record(&layout, |record| {
        let (line, stamp_s) = (record.line, record.stamp_s);
        log.float(line, 1, "sensortime")?;
        let angle_rad = log.float(line, 2, "transducer_angle")?;
        let intensities = (0..bins)
            .map(|i| intensity(log, line, 3 + i))
            .collect::<Result<Vec<u8>, _>>()?;
        beams.push(SonarBeam {
            stamp_s,
            angle_rad,
            bin_size_m: setup.bin_size_m,
            first_bin_range_m: 0.0,
            intensities,
        });
        Ok(None)
    })?;
    Ok((beams, skipped))
}

/// One intensity field: an integer 0-255 (a `.0` tail is accepted).
fn intensity(log: &TextLog, line: &DataLine<'_>, index: usize) -> Result<u8, DatasetError> {
    let raw = line.fields[index];
    // Fast path for the plain digits that make up almost all of the file.
    if raw.len() <= 3 && raw.iter().all(u8::is_ascii_digit) {
        let value = raw
            .iter()
            .fold(0u32, |acc, d| acc * 10 + u32::from(d - b'0'));
        if value <= 255 {
            return Ok(value as u8);
        }
    }
    let name = format!("bin_{}", index - 3);
    let value = log.float(line, index, &name)?;
    if value.fract() != 0.0 || !(0.0..=255.0).contains(&value) {
        let field = format!("column {} ({name})", index + 1);
        return Err(log.error(
            line.line,
            &field,
            format!("{value} is not an intensity 0-255"),
        ));
    }
    Ok(value as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup() -> SonarSetup {
        SonarSetup {
            range_m: 0.4,
            bin_size_m: 0.1,
            step_rad: 0.0314,
        }
    }

    #[test]
    fn setup_line_of_the_mission() {
        let s = parse_setup(&TextLog::from_bytes("s.log", b"50 0.1 0.03141592653590")).unwrap();
        assert_eq!((s.range_m, s.bin_size_m, s.bins()), (50.0, 0.1, 500));
    }

    // Issue 35 (fuzzing): a setup of 50 m in 1e-9 m bins asked the
    // keyframe reader for 5e10 bins per beam (an allocation failure that
    // aborts the process); a step of 1e-300 rad for as many beams per turn.
    #[test]
    fn setups_giving_absurd_bin_or_step_counts_are_errors() {
        for (text, field) in [
            (&b"50 1e-9 0.0314159"[..], "column 2 (bin size)"),
            (b"1e300 0.1 0.0314159", "column 2 (bin size)"),
            (b"0.01 0.1 0.0314159", "column 2 (bin size)"),
            (b"50 0.1 1e-300", "column 3 (step)"),
        ] {
            let err = parse_setup(&TextLog::from_bytes("s.log", text))
                .unwrap_err()
                .to_string();
            assert!(
                err.contains("s.log: line 1") && err.contains(field),
                "{err}"
            );
        }
    }

    #[test]
    fn beams_in_the_documented_format() {
        let text = b"% logtime sensortime angle bins\r\n10.0 100 0.5 0 12 255 7.0\r\n10.07 170 0.53 1 2 3 4\r\n";
        let (beams, skipped) = parse_beams(&TextLog::from_bytes("i.log", text), &setup()).unwrap();
        assert!(skipped.is_empty());
        assert_eq!(beams.len(), 2);
        assert_eq!(beams[0].intensities, vec![0, 12, 255, 7]);
        assert_eq!(beams[1].angle_rad, 0.53);
        assert_eq!(beams[1].bin_size_m, 0.1);
    }

    #[test]
    fn intensity_out_of_range_names_the_bin() {
        let text = b"10.0 100 0.5 0 12 256 7\n";
        let err = parse_beams(&TextLog::from_bytes("i.log", text), &setup())
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains("line 1") && err.contains("bin_2"), "{err}");
    }
}
