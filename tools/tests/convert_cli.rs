//! `echofield convert` end to end on the committed real logs: the MCAP it
//! writes reads back with every record.

use echofield_datasets::mcap::read_mission;
use echofield_datasets::stpere::read_stpere_dir;
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

/// Converts the committed St Pere logs with `extra` arguments and reads the
/// mission back.
fn convert_stpere(extra: &[&str]) -> echofield_frontend::Mission {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("marina.mcap");
    let input = data("stpere-marina");
    let mut args = vec!["stpere", input.to_str().unwrap()];
    args.extend_from_slice(extra);
    args.extend_from_slice(&["--output", out.to_str().unwrap()]);
    let run = convert(&args);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    read_mission(&out).unwrap()
}

#[test]
fn stpere_folder_to_mcap_keeps_the_heading_calibration_in_the_mounting() {
    let mission = convert_stpere(&[]);
    assert_eq!(mission.name, "040825_1735");
    assert_eq!(
        (
            mission.dvl.len(),
            mission.attitude.len(),
            mission.ground_truth.len()
        ),
        (5045, 33457, 3342)
    );
    // MTi line 7: heading -126.276 deg is yaw -143.724 deg, written as
    // logged; the +19.4 deg calibration is the mounting's heading offset,
    // which dead reckoning adds once.
    assert!((mission.attitude[0].yaw_rad.to_degrees() - (-143.724)).abs() < 1e-6);
    assert!((mission.mounting.heading_offset_rad.to_degrees() - 19.4).abs() < 1e-9);
    // The same mission as the reader gives, calibration included.
    let logs = read_stpere_dir(&data("stpere-marina")).unwrap();
    assert_eq!(mission.mounting, logs.mission.mounting);
}

#[test]
fn stpere_yaw_offset_replaces_the_calibration_instead_of_adding_to_it() {
    // Regression: `--yaw-offset-deg 19.4` used to be added to the attitude
    // on top of the mounting's +19.4 deg, correcting the heading twice.
    for (arg, expected_deg) in [("19.4", 19.4), ("0", 0.0), ("-5.5", -5.5)] {
        let mission = convert_stpere(&["--yaw-offset-deg", arg]);
        assert!((mission.attitude[0].yaw_rad.to_degrees() - (-143.724)).abs() < 1e-6);
        let offset_deg = mission.mounting.heading_offset_rad.to_degrees();
        assert!(
            (offset_deg - expected_deg).abs() < 1e-9,
            "{arg}: {offset_deg}"
        );
    }
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

/// The real sonar point sets become beams beside the navigation: 200 per
/// rotation, stamped under the sweep asked for, with the assumed mounting
/// marked as such.
#[test]
fn stpere_keyframes_become_beams_and_bad_point_sets_name_file_line_and_field() {
    use echofield_datasets::stpere::point_bands::committed_keyframes;
    use echofield_frontend::sensors::{MountingSource, SweepTiming};
    let dir = tempfile::tempdir().unwrap();
    let keyframes = committed_keyframes(dir.path()).unwrap();
    let kf = keyframes.to_str().unwrap();
    let mission = convert_stpere(&["--keyframes", kf, "--sweep", "decreasing"]);
    assert_eq!(mission.beams.len(), 115 * 200);
    assert_eq!(mission.mounting.sweep, SweepTiming::AngleDecreasing);
    assert_eq!(mission.mounting.source, MountingSource::Assumed);

    // A point between two beams of the head's 1.8° grid, on line 12 of
    // rotation 7's file.
    let pcd = keyframes.join("pclKeyFrame7.pcd");
    let text = std::fs::read_to_string(&pcd).unwrap();
    let mut lines: Vec<&str> = text.lines().collect();
    lines[11] = "10.0000 0.1571 0.0000";
    std::fs::write(&pcd, lines.join("\n") + "\n").unwrap();
    let out = dir.path().join("bad.mcap");
    let input = data("stpere-marina");
    let run = convert(&[
        "stpere",
        input.to_str().unwrap(),
        "--keyframes",
        kf,
        "--output",
        out.to_str().unwrap(),
    ]);
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("pclKeyFrame7.pcd")
            && stderr.contains("line 12")
            && stderr.contains("x, y"),
        "{stderr}"
    );
    assert!(!out.exists());
}

/// `convert ros` on the Girona caves layout (a ROS 1 bag written by the
/// `rosbags` package, `datasets/ros-fixtures/girona_caves.bag`): the
/// data set's own RangeImageBeam and LinkquestDvl topics become an
/// echofield MCAP whose metadata keeps the sonar and DVL mountings found
/// on `/tf`; the summary names what fed what and what was skipped.
#[test]
fn convert_ros_girona_caves_bag_keeps_the_mountings() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("caves.mcap");
    let input = data("ros-fixtures/girona_caves.bag");
    let run = convert(&[
        "ros",
        input.to_str().unwrap(),
        "--topic",
        "sonar=/sonar_micron",
        "--output",
        out.to_str().unwrap(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let stdout = String::from_utf8_lossy(&run.stdout);
    for line in [
        "topic /sonar_micron (cirs_girona_cala_viuda/RangeImageBeam, 2 messages): used as sonar",
        "topic /dvl_linkquest (cirs_girona_cala_viuda/LinkquestDvl, 2 messages): used as dvl",
        "topic /imu_adis (cirs_girona_cala_viuda/Imu, 2 messages): skipped",
        "DVL mounting sparus -> dvl",
    ] {
        assert!(stdout.contains(line), "{line}\n{stdout}");
    }
    let m = read_mission(&out).unwrap();
    assert_eq!((m.beams.len(), m.dvl.len(), m.attitude.len()), (2, 2, 2));
    let (s, d) = (m.mounting.vehicle_from_sonar, m.mounting.vehicle_from_dvl);
    assert!(
        (s.x() - 0.55).abs() < 1e-9 && (s.theta() - 3.0).abs() < 1e-9,
        "{s:?}"
    );
    assert!(
        (d.x() + 0.4).abs() < 1e-9 && (d.y() - 0.05).abs() < 1e-9,
        "{d:?}"
    );
}
