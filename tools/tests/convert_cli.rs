//! `echofield convert` end to end on the committed real logs: the MCAP it
//! writes reads back with every record.

use echofield_datasets::mcap::read_mission;
use std::path::PathBuf;
use std::process::Command;

fn data(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../datasets")
        .join(rel)
}

fn convert(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_echofield"))
        .arg("convert")
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn stpere_folder_to_mcap_with_the_recommended_offset() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("marina.mcap");
    let input = data("stpere-marina");
    let run = convert(&[
        "stpere",
        input.to_str().unwrap(),
        "--yaw-offset-deg",
        "19.4",
        "--output",
        out.to_str().unwrap(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let mission = read_mission(&out).unwrap();
    assert_eq!(mission.name, "040825_1735");
    assert_eq!(
        (
            mission.dvl.len(),
            mission.attitude.len(),
            mission.ground_truth.len()
        ),
        (5045, 33457, 3342)
    );
    // MTi line 7: heading -126.276 deg is yaw -143.724 deg; +19.4 deg.
    assert!((mission.attitude[0].yaw_rad.to_degrees() - (-143.724 + 19.4)).abs() < 1e-6);
}

#[test]
fn ping360_and_miniking_logs_to_mcap() {
    let dir = tempfile::tempdir().unwrap();
    for (kind, rel, beams) in [
        (
            "ping360",
            "msis-real/ping360/Sensor_Log_02__20210829-003011721.bin",
            356,
        ),
        (
            "miniking",
            "msis-real/miniking/narrow_sonar_scan_2015-05-26-11-41-49.bag",
            566,
        ),
    ] {
        let out = dir.path().join(format!("{kind}.mcap"));
        let input = data(rel);
        let run = convert(&[kind, input.to_str().unwrap(), "-o", out.to_str().unwrap()]);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let stdout = String::from_utf8_lossy(&run.stdout);
        assert!(stdout.contains(&format!("{beams} beams")), "{stdout}");
        assert_eq!(read_mission(&out).unwrap().beams.len(), beams);
    }
}

#[test]
fn unreadable_input_fails_with_one_line_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.mcap");
    let input = dir.path().join("missing.bin");
    let run = convert(&[
        "ping360",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.starts_with("error: cannot read") && stderr.contains("missing.bin"),
        "{stderr}"
    );
    assert!(!out.exists());
}
