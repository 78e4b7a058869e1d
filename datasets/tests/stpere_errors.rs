//! Bad St Pere folders give errors naming file, line and column, or are
//! skipped as documented in `echofield_datasets::stpere`; never a panic.

use echofield_datasets::DatasetError;
use echofield_datasets::stpere::{SkipReason, read_stpere_dir};
use std::path::Path;

const DVL: &str = "% time, [idSensor], year, ...\r\n\r\n\
1093455407.147 2007 3 16 13 0 56 38.20 -47.00 1.80 1 6.10 -4.90 2.80 1 1.84 1.88 1.86 143.00 142.00 149.00 100 207.70 -0.50 1.60 14.27 1488.00 12.80 0.50 1.50 0.08 -0.25\r\n\
1093455407.822 2007 3 16 13 0 57 4.80 51.40 18.30 1 -1.90 8.90 -4.70 1 1.83 1.87 1.85 152.00 144.00 144.00 100 207.40 -0.50 1.60 14.27 1488.00 12.80 0.50 1.50 0.07 -0.20\r\n\
1093455408.465 2007 3 16 13 0 58 -63.00 82.40 8.30 1 32767.00 32767.00 32767.00 0 1.84 1.88 1.85 134.00 136.00 142.00 100 207.60 -0.50 1.60 14.27 1488.00 12.80 0.50 1.50 -0.00 -0.17\r\n";
const MTI: &str = "% time, [idSensor], positionX\r\n\r\n\
1093455407.042 0.506328 -2.5422 -126.276 0.0115654 -0.00641596 0.00508943 -0.427074 -0.0795686 -9.77331 \r\n\
1093455407.149 0.537181 -2.56871 -126.325 -0.00123256 -0.00291132 0.000567025 -0.421376 -0.0790028 -9.77091 \r\n\
1093455408.500 0.537181 -2.56871 -126.4 -0.00123256 -0.00291132 0.000567025 -0.421376 -0.0790028 -9.77091 \r\n";
const DGPS: &[u8] = b"% trueCourse(\xba)\r\n\r\n\
1093455407.9 4212.225 306.2832 1 -2.1 51.8 23.6 24 0.1 0.1\r\n\
1093455408.9 4212.2251 306.2833 1 -2.1 51.8 23.6 24 0.1 0.1";
const SETUP: &str = "0.3 0.1 0.0314159";

/// Writes a mission folder; `edit` may replace any file's content.
fn mission(dir: &Path, edit: impl Fn(&str, Vec<u8>) -> Vec<u8>) {
    let files: [(&str, &[u8]); 4] = [
        ("DVL", DVL.as_bytes()),
        ("MTI", MTI.as_bytes()),
        ("DGPS", DGPS),
        ("SETUP", SETUP.as_bytes()),
    ];
    for (kind, content) in files {
        let bytes = edit(kind, content.to_vec());
        std::fs::write(dir.join(format!("_040825_1735_{kind}.log")), bytes).unwrap();
    }
}

fn replace(bytes: Vec<u8>, from: &str, to: &str) -> Vec<u8> {
    let text = String::from_utf8_lossy(&bytes).into_owned();
    assert!(text.contains(from), "fixture lacks {from}");
    text.replacen(from, to, 1).into_bytes()
}

fn read_err(edit: impl Fn(&str, Vec<u8>) -> Vec<u8>) -> String {
    let dir = tempfile::tempdir().unwrap();
    mission(dir.path(), edit);
    read_stpere_dir(dir.path())
        .expect_err("must fail")
        .to_string()
}

#[test]
fn the_small_fixture_reads() {
    let dir = tempfile::tempdir().unwrap();
    mission(dir.path(), |_, b| b);
    let logs = read_stpere_dir(dir.path()).unwrap();
    assert_eq!(logs.mission.name, "040825_1735");
    assert_eq!(logs.mission.dvl.len(), 3);
    assert_eq!(
        logs.mission.dvl.iter().map(|d| d.valid).collect::<Vec<_>>(),
        [true, true, false]
    );
    assert_eq!(logs.mission.attitude.len(), 3);
    assert_eq!(logs.dgps.len(), 2);
    assert!(logs.beam_stamps.is_empty() && logs.mission.beams.is_empty());
    // 0.0001 min north = 0.185 m, 0.0001 min east = 0.137 m at 42.2 deg.
    let p = logs.mission.ground_truth[1].world_from_vehicle;
    assert!(
        (p.y() - 0.1852).abs() < 0.001 && (p.x() - 0.1373).abs() < 0.001,
        "{p:?}"
    );
}

#[test]
fn nan_in_the_mti_names_file_line_and_column() {
    let err = read_err(|k, b| {
        if k == "MTI" {
            replace(b, "-126.325", "NaN")
        } else {
            b
        }
    });
    assert!(
        err.contains("_MTI.log: line 4: field `column 4 (yaw)`"),
        "{err}"
    );
    assert!(err.contains("not finite"), "{err}");
}

#[test]
fn non_numeric_dgps_names_the_column() {
    let err = read_err(|k, b| {
        if k == "DGPS" {
            replace(b, "4212.2251", "42l2.2251")
        } else {
            b
        }
    });
    assert!(
        err.contains("_DGPS.log: line 4: field `column 2 (latitude)`"),
        "{err}"
    );
}

#[test]
fn dvl_time_going_back_is_an_error() {
    let err = read_err(|k, b| {
        if k == "DVL" {
            replace(b, "1093455408.465", "1093455406.0")
        } else {
            b
        }
    });
    assert!(
        err.contains("_DVL.log: line 5: field `column 1 (time)`"),
        "{err}"
    );
    assert!(err.contains("earlier"), "{err}");
}

#[test]
fn wrong_column_count_inside_the_file_is_an_error() {
    let err = read_err(|k, b| {
        if k == "DVL" {
            replace(b, " 0.07 -0.20", "")
        } else {
            b
        }
    });
    assert!(
        err.contains("_DVL.log: line 4: field `columns`: 30 columns, expected 32"),
        "{err}"
    );
}

#[test]
fn repeated_stamp_and_truncated_tail_are_skipped_and_listed() {
    let dir = tempfile::tempdir().unwrap();
    mission(dir.path(), |k, b| match k {
        "MTI" => replace(b, "1093455408.500", "1093455407.149"),
        "DGPS" => {
            let mut b = b;
            b.extend_from_slice(b"\r\n1093455409.9 4212.2251 306.28");
            b
        }
        _ => b,
    });
    let logs = read_stpere_dir(dir.path()).unwrap();
    assert_eq!(logs.mission.attitude.len(), 2);
    assert_eq!(logs.dgps.len(), 2);
    let reasons: Vec<_> = logs
        .skipped
        .iter()
        .map(|s| (s.line, s.reason.clone()))
        .collect();
    assert!(
        reasons.contains(&(5, SkipReason::DuplicateStamp)),
        "{reasons:?}"
    );
    let tail = SkipReason::TruncatedFinalLine {
        columns: 3,
        expected: 10,
    };
    assert!(reasons.contains(&(5, tail)), "{reasons:?}");
}

#[test]
fn missing_mti_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    mission(dir.path(), |_, b| b);
    std::fs::remove_file(dir.path().join("_040825_1735_MTI.log")).unwrap();
    let err = read_stpere_dir(dir.path()).unwrap_err();
    assert!(matches!(err, DatasetError::Missing { .. }), "{err}");
    assert!(err.to_string().contains("_MTI.log"), "{err}");
}

#[test]
fn beams_and_stamps_files_are_read_when_present() {
    let dir = tempfile::tempdir().unwrap();
    mission(dir.path(), |_, b| b);
    let is_log = "% logtime sensortime angle bins\r\n\
1093455407.10 63224578 0.0000 10 20 30\r\n\
1093455407.17 63224646 0.0314 40 50 255\r\n";
    std::fs::write(dir.path().join("_040825_1735_IS.log"), is_log).unwrap();
    let stamps = "1093455407.10 63224578\n1093455407.17 63224646\n";
    std::fs::write(dir.path().join("_040825_1735_IS_timestamps.log"), stamps).unwrap();
    let logs = read_stpere_dir(dir.path()).unwrap();
    let beams = &logs.mission.beams;
    assert_eq!(beams.len(), 2);
    assert_eq!(beams[1].intensities, vec![40, 50, 255]);
    assert_eq!(beams[1].angle_rad, 0.0314);
    assert!((beams[1].bin_size_m - 0.1).abs() < 1e-12);
    assert_eq!(logs.beam_stamps[1].sensor_clock_ms, 63224646);
}

#[test]
fn beams_with_the_wrong_bin_count_name_the_line() {
    let dir = tempfile::tempdir().unwrap();
    mission(dir.path(), |_, b| b);
    let is_log = "1093455407.10 63224578 0.0 10 20 30\n1093455407.17 63224646 0.0314 40 50\n1093455407.24 1 0.06 1 2 3\n";
    std::fs::write(dir.path().join("_040825_1735_IS.log"), is_log).unwrap();
    let err = read_stpere_dir(dir.path()).unwrap_err().to_string();
    assert!(
        err.contains("_IS.log: line 2: field `columns`: 5 columns, expected 6"),
        "{err}"
    );
}

#[test]
fn random_damage_never_panics() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1735);
    let dir = tempfile::tempdir().unwrap();
    for _ in 0..100 {
        let target = ["DVL", "MTI", "DGPS", "SETUP"][rng.random_range(0..4)];
        let edits: Vec<(f64, u8)> = (0..rng.random_range(1..6))
            .map(|_| (rng.random::<f64>(), rng.random_range(0..128u8)))
            .collect();
        let cut: f64 = rng.random_range(0.5..=1.0);
        mission(dir.path(), |kind, mut bytes| {
            if kind == target && !bytes.is_empty() {
                for &(at, value) in &edits {
                    let i = (at * bytes.len() as f64) as usize % bytes.len();
                    bytes[i] = value;
                }
                bytes.truncate((cut * bytes.len() as f64) as usize);
            }
            bytes
        });
        // Either result is fine; a panic fails the test.
        let _ = read_stpere_dir(dir.path());
    }
}
