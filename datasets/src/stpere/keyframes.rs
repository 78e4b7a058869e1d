//! Thresholded sonar point sets, one per rotation, turned back into beams.
//!
//! Published copies of the St Pere sonar data keep each 360° rotation as
//! an ASCII PCD file of points (`pclKeyFrameK.pcd`, fields `x y z`, z = 0)
//! and the rotations' time spans (`keyFrameTimeStamps.csv`:
//! `keyFrame,keyFrameBeginning,keyFrameEnd`, Unix seconds). Every point
//! was one bin above a threshold: `x = r cos θ, y = r sin θ` with the raw
//! transducer angle `θ` and the far end `r` of its bin, in the head's frame,
//! not motion-compensated. So each point gives back its beam's angle (an
//! integer multiple of the setup's step) and its bin exactly.
//!
//! [`read_keyframes`] rebuilds the beams of every rotation listed in the
//! CSV:
//! - the rotation's `N = 2π / step` beam stamps are the `N` rows of
//!   `_IS_timestamps.log` from the one at `keyFrameBeginning`;
//! - the rotation starts at the beam whose angle is 0; the `j`-th stamp
//!   goes to the beam at angle `+j · step` or `−j · step`, as the caller's
//!   [`SweepTiming`] assumes (the files do not say which way the head
//!   turned: `echofield calibrate` finds out from the data);
//! - a bin that holds a point gets intensity [`POINT_INTENSITY`], every
//!   other bin 0, and a beam without points is kept as an empty beam, so
//!   the mission has all `N` beams of every rotation and the image of a
//!   rotation knows where the head looked and saw nothing.
//!
//! The intensities are therefore binary; the frontend detects that and
//! builds its scans and images for it (`echofield_frontend::intensity`).
//!
//! # Bad input
//! Errors name the file, the line and the field: a PCD whose fields are not
//! `x y z`, a binary PCD, a header or point count that disagrees with the
//! data, a point off the angle or range grid, a rotation that does not span
//! `N` beam stamps or does not start on one, rotations out of order or
//! overlapping, a missing PCD file.

mod pcd;

use super::sonar::{BeamStamp, SonarSetup};
use crate::error::DatasetError;
use echofield_frontend::sensors::{SonarBeam, SweepTiming};
use echofield_graph::wrap_angle;
use pcd::{Point, read_pcd};
use std::path::Path;

/// Intensity (0-255) given to a bin that holds a point.
pub const POINT_INTENSITY: u8 = 255;

/// A point may sit this far from the angle grid, in steps, and from the
/// range grid, in bins (the files round to 0.1 mm).
const GRID_TOLERANCE: f64 = 0.1;

/// The CSV file that lists the rotations.
pub const KEYFRAME_CSV: &str = "keyFrameTimeStamps.csv";

/// One rotation as listed in the CSV.
#[derive(Clone, Debug, PartialEq)]
pub struct KeyframeRotation {
    /// The `keyFrame` number `K` (file `pclKeyFrameK.pcd`).
    pub keyframe: u64,
    pub begin_s: f64,
    pub end_s: f64,
    /// Points read from its PCD file.
    pub points: usize,
    /// Beams of the rotation that hold at least one point.
    pub beams_with_points: usize,
}

/// The beams rebuilt from a keyframe folder.
#[derive(Clone, Debug)]
pub struct KeyframeBeams {
    /// `N` beams per rotation, in time order.
    pub beams: Vec<SonarBeam>,
    pub rotations: Vec<KeyframeRotation>,
    /// The convention the stamps were assigned under.
    pub sweep: SweepTiming,
}

/// Reads `dir/keyFrameTimeStamps.csv` and every `pclKeyFrameK.pcd` it
/// lists (see the module doc). `sweep` must be
/// [`SweepTiming::AngleIncreasing`] or [`SweepTiming::AngleDecreasing`].
pub fn read_keyframes(
    dir: &Path,
    setup: &SonarSetup,
    stamps: &[BeamStamp],
    sweep: SweepTiming,
) -> Result<KeyframeBeams, DatasetError> {
    let direction = sweep_direction(sweep, dir)?;
    let steps = steps_per_turn(setup, dir)?;
    let csv_path = dir.join(KEYFRAME_CSV);
    let spans = read_spans(&csv_path)?;
    if spans.is_empty() {
        return Err(DatasetError::Missing {
            path: csv_path,
            what: "a rotation (the file lists none)".into(),
        });
    }
    let mut beams = Vec::with_capacity(spans.len() * steps);
    let mut rotations = Vec::with_capacity(spans.len());
    for span in &spans {
        let first = first_stamp(&csv_path, span, stamps, steps)?;
        let pcd_path = dir.join(format!("pclKeyFrame{}.pcd", span.keyframe));
        let points = read_pcd(&pcd_path)?;
        let mut rotation_beams = empty_beams(setup, &stamps[first..first + steps], direction);
        for point in &points {
            let (angle_index, bin) = grid_cell(&pcd_path, point, setup, steps)?;
            // Time index of the beam at `angle_index · step` under `direction`.
            let j = (direction * angle_index as i64).rem_euclid(steps as i64) as usize;
            rotation_beams[j].intensities[bin] = POINT_INTENSITY;
        }
        rotations.push(KeyframeRotation {
            keyframe: span.keyframe,
            begin_s: span.begin_s,
            end_s: span.end_s,
            points: points.len(),
            beams_with_points: rotation_beams
                .iter()
                .filter(|b| b.intensities.iter().any(|&v| v > 0))
                .count(),
        });
        beams.extend(rotation_beams);
    }
    Ok(KeyframeBeams {
        beams,
        rotations,
        sweep,
    })
}

/// +1 when the angle increases with time, -1 when it decreases; an error
/// for [`SweepTiming::Logged`] (point sets carry no beam times).
fn sweep_direction(sweep: SweepTiming, dir: &Path) -> Result<i64, DatasetError> {
    match sweep {
        SweepTiming::AngleIncreasing => Ok(1),
        SweepTiming::AngleDecreasing => Ok(-1),
        SweepTiming::Logged => Err(DatasetError::Format {
            path: dir.to_path_buf(),
            message: "point sets carry no beam times: the sweep must be assumed \
                      (angle_increasing or angle_decreasing)"
                .into(),
        }),
    }
}

/// One beam per stamp of `stamps` (one turn of `N = stamps.len()` steps),
/// without echoes; beam `j` at angle index `direction · j` mod `N`.
fn empty_beams(setup: &SonarSetup, stamps: &[BeamStamp], direction: i64) -> Vec<SonarBeam> {
    let steps = stamps.len();
    stamps
        .iter()
        .enumerate()
        .map(|(j, stamp)| {
            let angle_index = (direction * j as i64).rem_euclid(steps as i64);
            SonarBeam {
                stamp_s: stamp.stamp_s,
                // One turn in `steps` equal steps: the setup's step is
                // 2π/N rounded to 7 digits.
                angle_rad: wrap_angle(angle_index as f64 * std::f64::consts::TAU / steps as f64),
                bin_size_m: setup.bin_size_m,
                first_bin_range_m: 0.0,
                intensities: vec![0; setup.bins()],
            }
        })
        .collect()
}

/// `N = 2π / step`, which must be a whole number of steps.
fn steps_per_turn(setup: &SonarSetup, dir: &Path) -> Result<usize, DatasetError> {
    let steps = std::f64::consts::TAU / setup.step_rad;
    if !(steps.is_finite() && (steps - steps.round()).abs() < 0.01 && steps.round() >= 4.0) {
        return Err(DatasetError::Format {
            path: dir.to_path_buf(),
            message: format!(
                "the setup's step {} rad is not a whole fraction of a turn ({steps:.3} steps)",
                setup.step_rad
            ),
        });
    }
    Ok(steps.round() as usize)
}

/// One CSV row, with its line for errors.
struct Span {
    line: u64,
    keyframe: u64,
    begin_s: f64,
    end_s: f64,
}

/// How far a rotation may begin before the previous one ends, s:
/// consecutive rotations share their boundary stamp, and the slack
/// accepts an overlap from rounding it.
const OVERLAP_SLACK_S: f64 = 0.01;

/// The CSV's columns, in order.
const COLUMNS: [&str; 3] = ["keyFrame", "keyFrameBeginning", "keyFrameEnd"];

/// Reads the rotations of `keyFrameTimeStamps.csv`. Errors name the line
/// and column: a header other than [`COLUMNS`], a value that is not a
/// rotation number or a time, a rotation that ends before it begins, does
/// not follow the one before or begins more than [`OVERLAP_SLACK_S`]
/// before it ends.
fn read_spans(path: &Path) -> Result<Vec<Span>, DatasetError> {
    let file = std::fs::File::open(path).map_err(|e| DatasetError::io(path, e))?;
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(file);
    let header = reader
        .headers()
        .map_err(|e| csv_error(path, &e))?
        .iter()
        .map(str::to_string)
        .collect::<Vec<_>>();
    if header != COLUMNS {
        return Err(DatasetError::parse(
            path,
            "line 1",
            "header",
            format!("{header:?}, expected {COLUMNS:?}"),
        ));
    }
    let mut spans: Vec<Span> = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| csv_error(path, &e))?;
        let span = parse_span(path, &record, spans.last())?;
        spans.push(span);
    }
    Ok(spans)
}

/// One CSV row, checked against the row before it (`prev`).
fn parse_span(
    path: &Path,
    record: &csv::StringRecord,
    prev: Option<&Span>,
) -> Result<Span, DatasetError> {
    let line = record.position().map_or(0, |p| p.line());
    let field = |i: usize| -> Result<&str, DatasetError> {
        record
            .get(i)
            .ok_or_else(|| DatasetError::parse(path, format!("line {line}"), COLUMNS[i], "missing"))
    };
    let bad = |i: usize, message: String| {
        DatasetError::parse(path, format!("line {line}"), COLUMNS[i], message)
    };
    let keyframe: u64 = field(0)?.parse().map_err(|_| {
        bad(
            0,
            format!("`{}` is not a rotation number", field(0).unwrap_or("")),
        )
    })?;
    let time = |i: usize| -> Result<f64, DatasetError> {
        let text = field(i)?;
        match text.parse::<f64>() {
            Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
            _ => Err(bad(i, format!("`{text}` is not a time in seconds"))),
        }
    };
    let (begin_s, end_s) = (time(1)?, time(2)?);
    if end_s <= begin_s {
        return Err(bad(
            2,
            format!("{end_s} is not after the beginning {begin_s}"),
        ));
    }
    if let Some(prev) = prev {
        if keyframe <= prev.keyframe {
            return Err(bad(
                0,
                format!("{keyframe} does not follow {}", prev.keyframe),
            ));
        }
        if begin_s < prev.end_s - OVERLAP_SLACK_S {
            return Err(bad(
                1,
                format!(
                    "rotation {keyframe} begins before rotation {} ends",
                    prev.keyframe
                ),
            ));
        }
    }
    Ok(Span {
        line,
        keyframe,
        begin_s,
        end_s,
    })
}

fn csv_error(path: &Path, e: &csv::Error) -> DatasetError {
    let record = e
        .position()
        .map_or_else(|| "file".to_string(), |p| format!("line {}", p.line()));
    DatasetError::parse(path, record, "row", e.to_string())
}

/// Index in `stamps` of the rotation's first beam, after checking that
/// the rotation begins on a stamp and spans exactly `steps` of them.
fn first_stamp(
    csv_path: &Path,
    span: &Span,
    stamps: &[BeamStamp],
    steps: usize,
) -> Result<usize, DatasetError> {
    let record = format!("line {}", span.line);
    // Half the shortest plausible beam interval: the files agree to 1 ms.
    const MATCH_S: f64 = 0.02;
    let first = stamps.partition_point(|s| s.stamp_s < span.begin_s - MATCH_S);
    if first == stamps.len() || (stamps[first].stamp_s - span.begin_s).abs() > MATCH_S {
        return Err(DatasetError::parse(
            csv_path,
            record,
            "keyFrameBeginning",
            format!(
                "{:.3} s is not the time of a beam in _IS_timestamps.log",
                span.begin_s
            ),
        ));
    }
    let spanned = stamps[first..].partition_point(|s| s.stamp_s < span.end_s - MATCH_S);
    if spanned != steps {
        return Err(DatasetError::parse(
            csv_path,
            record,
            "keyFrameEnd",
            format!(
                "rotation {} spans {spanned} beam stamps of _IS_timestamps.log, \
                 expected {steps} (one per step of a turn)",
                span.keyframe
            ),
        ));
    }
    Ok(first)
}

/// `(angle index 0..steps, bin)` of a point; an error names the point's
/// line when it is off either grid.
fn grid_cell(
    path: &Path,
    point: &Point,
    setup: &SonarSetup,
    steps: usize,
) -> Result<(usize, usize), DatasetError> {
    let record = format!("line {}", point.line);
    let angle_steps = point.y.atan2(point.x) / setup.step_rad;
    let range_bins = point.x.hypot(point.y) / setup.bin_size_m;
    if (angle_steps - angle_steps.round()).abs() > GRID_TOLERANCE {
        return Err(DatasetError::parse(
            path,
            record,
            "x, y",
            format!(
                "the angle {:.5} rad is {angle_steps:.3} steps of {} rad: not on the head's angle grid",
                point.y.atan2(point.x),
                setup.step_rad
            ),
        ));
    }
    let bin_end = range_bins.round();
    if (range_bins - bin_end).abs() > GRID_TOLERANCE
        || bin_end < 1.0
        || bin_end > setup.bins() as f64
    {
        return Err(DatasetError::parse(
            path,
            record,
            "x, y",
            format!(
                "the range {:.4} m is not the far end of one of the {} bins of {} m",
                point.x.hypot(point.y),
                setup.bins(),
                setup.bin_size_m
            ),
        ));
    }
    let angle_index = (angle_steps.round() as i64).rem_euclid(steps as i64) as usize;
    Ok((angle_index, bin_end as usize - 1))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup() -> SonarSetup {
        SonarSetup {
            range_m: 2.0,
            bin_size_m: 0.1,
            step_rad: std::f64::consts::TAU / 8.0,
        }
    }

    fn stamps(n: usize) -> Vec<BeamStamp> {
        (0..n)
            .map(|i| BeamStamp {
                stamp_s: 100.0 + 0.5 * i as f64,
                sensor_clock_ms: 500 * i as i64,
            })
            .collect()
    }

    fn pcd(points: &[(f64, f64)]) -> String {
        let mut s = format!(
            "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n\
             WIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA ascii\n",
            n = points.len()
        );
        for (x, y) in points {
            s.push_str(&format!("{x:.4} {y:.4} 0.0000\n"));
        }
        s
    }

    /// A folder with two rotations of 8 beams: a point at 1.0 m on angle
    /// index 1 (45°) in the first, at 0.5 m on angle index 0 in the second.
    fn folder() -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join(KEYFRAME_CSV),
            "keyFrame,keyFrameBeginning,keyFrameEnd\n1,100.0,104.0\n2,104.0,108.0\n",
        )
        .unwrap();
        let h = std::f64::consts::FRAC_1_SQRT_2;
        std::fs::write(dir.path().join("pclKeyFrame1.pcd"), pcd(&[(h, h)])).unwrap();
        std::fs::write(dir.path().join("pclKeyFrame2.pcd"), pcd(&[(0.5, 0.0)])).unwrap();
        dir
    }

    #[test]
    fn points_go_back_to_their_beam_bin_and_time() {
        let dir = folder();
        for (sweep, j) in [
            (SweepTiming::AngleIncreasing, 1),
            (SweepTiming::AngleDecreasing, 7),
        ] {
            let kf = read_keyframes(dir.path(), &setup(), &stamps(20), sweep).unwrap();
            assert_eq!(kf.beams.len(), 16);
            assert_eq!(kf.rotations[0].points, 1);
            assert_eq!(kf.rotations[0].beams_with_points, 1);
            let beam = &kf.beams[j];
            assert_eq!(beam.stamp_s, 100.0 + 0.5 * j as f64);
            assert!((beam.angle_rad - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
            // Bin 9 ends at 1.0 m.
            assert_eq!(beam.intensities[9], POINT_INTENSITY);
            assert_eq!(beam.intensities.iter().filter(|&&v| v > 0).count(), 1);
            // Second rotation: angle 0 is its first beam whichever the sweep.
            assert_eq!(kf.beams[8].stamp_s, 104.0);
            assert_eq!(kf.beams[8].intensities[4], POINT_INTENSITY);
            // Stamps run forward.
            assert!(kf.beams.windows(2).all(|w| w[1].stamp_s > w[0].stamp_s));
        }
    }

    #[test]
    fn logged_sweep_is_refused() {
        let dir = folder();
        let err = read_keyframes(dir.path(), &setup(), &stamps(20), SweepTiming::Logged)
            .unwrap_err()
            .to_string();
        assert!(err.contains("sweep"), "{err}");
    }

    fn error_of(file: &str, text: &str) -> String {
        let dir = folder();
        std::fs::write(dir.path().join(file), text).unwrap();
        read_keyframes(
            dir.path(),
            &setup(),
            &stamps(20),
            SweepTiming::AngleIncreasing,
        )
        .unwrap_err()
        .to_string()
    }

    #[test]
    fn bad_pcd_files_name_line_and_field() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let good = pcd(&[(h, h)]);
        let cases = [
            (
                good.replace("FIELDS x y z", "FIELDS x y z intensity"),
                "line 3",
                "FIELDS",
            ),
            (good.replace("DATA ascii", "DATA binary"), "line 11", "DATA"),
            (
                good.replace("0.7071 0.7071", "0.7071 nan"),
                "line 12",
                "`y`",
            ),
            (
                good.replace("0.7071 0.7071 0.0000", "0.7071 0.7071"),
                "line 12",
                "x y z",
            ),
            // 30° is off the 45° grid.
            (
                good.replace("0.7071 0.7071", "0.8660 0.5000"),
                "line 12",
                "angle grid",
            ),
            // 1.05 m is between two bin ends.
            (
                good.replace("0.7071 0.7071", "0.7425 0.7425"),
                "line 12",
                "far end",
            ),
            (
                good.replace("POINTS 1", "POINTS 2"),
                "pclKeyFrame1.pcd",
                "truncated",
            ),
        ];
        for (text, record, field) in cases {
            let err = error_of("pclKeyFrame1.pcd", &text);
            assert!(err.contains("pclKeyFrame1.pcd"), "{err}");
            assert!(err.contains(record) && err.contains(field), "{err}");
        }
    }

    // Issue 35: a POINTS count of u64::MAX made the reader reserve memory
    // for that many points (a capacity-overflow panic); invalid UTF-8 gave
    // no byte offset; a byte-order mark hid the first header key.
    #[test]
    fn a_huge_point_count_invalid_utf8_and_a_bom() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let good = pcd(&[(h, h)]);
        let huge = good.replace("POINTS 1", "POINTS 18446744073709551615");
        let err = error_of("pclKeyFrame1.pcd", &huge);
        assert!(
            err.contains("declares") && err.contains("truncated"),
            "{err}"
        );
        let mut latin1 = good.clone().into_bytes();
        let at = good.find("0.7071").unwrap();
        latin1[at] = 0xB0;
        let dir = folder();
        std::fs::write(dir.path().join("pclKeyFrame1.pcd"), latin1).unwrap();
        let err = read_keyframes(
            dir.path(),
            &setup(),
            &stamps(20),
            SweepTiming::AngleIncreasing,
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("line 12") && err.contains(&format!("byte {at}")),
            "{err}"
        );
        let dir = folder();
        let bom = format!("\u{feff}{}", good.replace("# .PCD v0.7\n", ""));
        std::fs::write(dir.path().join("pclKeyFrame1.pcd"), bom).unwrap();
        let bad_fields = format!(
            "\u{feff}{}",
            good.replace("# .PCD v0.7\nVERSION 0.7\n", "")
                .replace("FIELDS x y z", "FIELDS x y")
        );
        read_keyframes(
            dir.path(),
            &setup(),
            &stamps(20),
            SweepTiming::AngleIncreasing,
        )
        .unwrap();
        let err = error_of("pclKeyFrame1.pcd", &bad_fields);
        assert!(err.contains("FIELDS"), "{err}");
    }

    #[test]
    fn bad_rotation_lists_are_errors() {
        let header = "keyFrame,keyFrameBeginning,keyFrameEnd\n";
        let cases = [
            // Ends after 7 stamps, not 8.
            (
                format!("{header}1,100.0,103.5\n"),
                "line 2",
                "spans 7 beam stamps",
            ),
            (
                format!("{header}1,100.2,104.2\n"),
                "line 2",
                "keyFrameBeginning",
            ),
            (format!("{header}1,100.0,abc\n"), "line 2", "keyFrameEnd"),
            (
                format!("{header}2,100.0,104.0\n1,104.0,108.0\n"),
                "line 3",
                "does not follow",
            ),
            (
                "frame,begin,end\n1,100,104\n".to_string(),
                "line 1",
                "header",
            ),
        ];
        for (text, record, what) in cases {
            let err = error_of(KEYFRAME_CSV, &text);
            assert!(err.contains(KEYFRAME_CSV), "{err}");
            assert!(err.contains(record) && err.contains(what), "{err}");
        }
        // A listed rotation without its file.
        let err = error_of(
            KEYFRAME_CSV,
            &format!("{header}1,100.0,104.0\n3,104.0,108.0\n"),
        );
        assert!(err.contains("pclKeyFrame3.pcd"), "{err}");
        // Fewer stamps than the rotations need.
        let dir = folder();
        let err = read_keyframes(
            dir.path(),
            &setup(),
            &stamps(12),
            SweepTiming::AngleIncreasing,
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("spans 4 beam stamps"), "{err}");
    }
}
