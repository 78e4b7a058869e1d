//! Issue 35: physically impossible sensor values and repaired input, on the
//! small simulated tank mission. Impossible values are dropped with a
//! counted warning naming the first record, or, when nothing plausible is
//! left, an error naming record and field; never a hang. What a reader or
//! a stage repaired reaches `report.json` → `warnings` with a kind and a
//! count.

use base64::Engine;
use echofield::slam::{NoProgress, SlamConfig, SlamOutput, run_mission};
use echofield_datasets::mcap::{json, read_mission};
use echofield_datasets::sim::{Scenario, simulate_mission};
use echofield_frontend::Mission;
use echofield_frontend::sensors::SensorMounting;
use echofield_frontend::warnings::WarningKind;
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::{Arc, OnceLock, mpsc};
use std::time::Duration;

/// The first 120 s of the simulated tank, seed 3.
fn tank() -> &'static Mission {
    static MISSION: OnceLock<Mission> = OnceLock::new();
    MISSION.get_or_init(|| {
        let mut m = simulate_mission(&Scenario::named("tank").unwrap(), 3).unwrap();
        let end_s = m.beams[0].stamp_s + 120.0;
        m.beams.retain(|b| b.stamp_s < end_s);
        m.dvl.retain(|d| d.stamp_s < end_s + 5.0);
        m.attitude.retain(|a| a.stamp_s < end_s + 5.0);
        m.ground_truth.retain(|g| g.stamp_s < end_s + 5.0);
        m
    })
}

/// Runs `mission` on another thread; `Err` with the message of a failed
/// run; a panic here when it takes longer than a minute (a hang).
fn run(mission: Mission, config: SlamConfig) -> Result<SlamOutput, String> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(run_mission(&mission, &config, &NoProgress).map_err(|e| e.to_string()));
    });
    rx.recv_timeout(Duration::from_secs(60))
        .expect("the run ended (no panic, no hang)")
}

fn default_run(mission: Mission) -> Result<SlamOutput, String> {
    run(mission, SlamConfig::default())
}

#[test]
fn dvl_velocities_of_1e20_mps_are_an_error_naming_the_record_not_a_hang() {
    let mut mission = tank().clone();
    mission.dvl.iter_mut().for_each(|d| d.velocity_mps.x = 1e20);
    let message = default_run(mission).unwrap_err();
    assert!(
        message.contains("DVL sample 0") && message.contains("velocity_mps"),
        "{message}"
    );
}

#[test]
fn dvl_velocities_of_1e3_mps_name_the_dvl_record_not_the_cell_size() {
    let mut mission = tank().clone();
    mission.dvl.iter_mut().for_each(|d| d.velocity_mps.y = 1e3);
    let message = default_run(mission).unwrap_err();
    assert!(
        message.contains("DVL sample 0") && message.contains("velocity_mps"),
        "{message}"
    );
    assert!(!message.contains("cell_size_m"), "{message}");
}

#[test]
fn a_few_impossible_samples_are_dropped_and_counted_in_the_report() {
    let mut mission = tank().clone();
    let k = mission.dvl.len() / 2;
    mission.dvl[k].velocity_mps.x = 1e20;
    mission.dvl[k + 3].velocity_mps.x = -5e2;
    let a = mission.attitude.len() / 3;
    mission.attitude[a].yaw_rad = 1.7e306;
    let b = mission.beams.len() / 4;
    mission.beams[b].angle_rad = 1e300;
    let output = default_run(mission).unwrap();
    let warning = output
        .report
        .warnings
        .of(WarningKind::ImplausibleValues)
        .expect("an implausible-values warning");
    assert_eq!(warning.count, 4, "{warning:?}");
    assert_eq!(
        warning.first_record.as_deref(),
        Some(format!("DVL sample {k}").as_str())
    );
    let json = serde_json::to_value(&output.report).unwrap();
    let entry = json["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .find(|w| w["kind"] == "implausible_values")
        .unwrap();
    assert_eq!(entry["count"], 4);
    assert!(entry["message"].as_str().unwrap().contains("velocity_mps"));
    // The run is the clean run's, near enough: dropping four samples does
    // not move the trajectory.
    let clean = default_run(tank().clone()).unwrap();
    let (ate, ate_clean) = (
        output.report.ate_rmse_m.unwrap(),
        clean.report.ate_rmse_m.unwrap(),
    );
    assert!((ate - ate_clean).abs() < 0.05, "{ate} vs {ate_clean}");
}

#[test]
fn headings_and_beam_angles_beyond_any_angle_are_errors_when_all_are_bad() {
    let mut mission = tank().clone();
    mission
        .attitude
        .iter_mut()
        .for_each(|a| a.yaw_rad = 1.7e306);
    let message = default_run(mission).unwrap_err();
    assert!(
        message.contains("attitude sample 0") && message.contains("yaw_rad"),
        "{message}"
    );
    let mut mission = tank().clone();
    mission.beams.iter_mut().for_each(|b| b.angle_rad = 1e300);
    let message = default_run(mission).unwrap_err();
    assert!(
        message.contains("beam 0") && message.contains("angle_rad"),
        "{message}"
    );
    assert!(!message.contains("no complete rotation"), "{message}");
}

#[test]
fn a_blind_zone_beyond_the_beams_is_an_error_naming_the_key() {
    for (text, key) in [
        (
            "[segmentation]\nblind_zone_m = 1e9\n",
            "segmentation.blind_zone_m",
        ),
        (
            "[segmentation]\nblind_zone_m = 60.0\n",
            "segmentation.blind_zone_m",
        ),
        ("[image]\nblind_zone_m = 60.0\n", "image.blind_zone_m"),
    ] {
        let message = match SlamConfig::from_toml_str(text) {
            Err(e) => e.to_string(),
            Ok(config) => run(tank().clone(), config).unwrap_err(),
        };
        assert!(message.contains(key), "{text}: {message}");
    }
}

#[test]
fn an_assumed_mounting_and_skipped_rotations_are_counted_warnings() {
    let mut mission = tank().clone();
    mission.mounting = SensorMounting::assumed_identity();
    // Navigation from 30 s on: the first rotations get no node.
    let late_s = mission.beams[0].stamp_s + 30.0;
    mission.dvl.retain(|d| d.stamp_s >= late_s);
    mission.attitude.retain(|a| a.stamp_s >= late_s);
    let output = default_run(mission).unwrap();
    let warnings = &output.report.warnings;
    let mounting = warnings.of(WarningKind::MountingAssumed).unwrap();
    assert_eq!(mounting.count, 1);
    assert!(mounting.contains("no verified sensor mounting"));
    let skipped = warnings.of(WarningKind::RotationsSkipped).unwrap();
    assert_eq!(skipped.count, output.report.skipped_rotations.len());
    assert!(skipped.count >= 1);
    assert_eq!(
        skipped.first_record,
        Some(format!(
            "rotation {}",
            output.report.skipped_rotations[0].rotation_index
        ))
    );
}

#[test]
fn beams_cut_out_of_their_rotation_are_a_dropped_rotations_warning() {
    let mut mission = tank().clone();
    // 20 s without beams in the middle of a rotation: the beams before the
    // gap and after it form no whole turn.
    let t0 = mission.beams[0].stamp_s;
    let (from_s, to_s) = (t0 + 50.0, t0 + 70.0);
    mission
        .beams
        .retain(|b| b.stamp_s < from_s || b.stamp_s > to_s);
    let output = default_run(mission.clone()).unwrap();
    let dropped = output
        .report
        .warnings
        .of(WarningKind::RotationsDropped)
        .expect("a dropped-rotations warning");
    assert!(dropped.count >= 1, "{dropped:?}");
    // The first dropped beam follows the last beam of a rotation.
    let first: usize = dropped
        .first_record
        .as_deref()
        .and_then(|r| r.strip_prefix("beam "))
        .and_then(|n| n.parse().ok())
        .unwrap();
    assert!(output.nodes.iter().any(|n| n.beams.end == first), "{first}");
    // The clean mission drops nothing between rotations.
    let clean = default_run(tank().clone()).unwrap();
    assert!(
        clean
            .report
            .warnings
            .of(WarningKind::RotationsDropped)
            .is_none()
    );
}

/// The tank mission as an MCAP without metadata whose DVL messages
/// `swapped` (pairs of indices) are written in each other's place: stamps
/// that go backwards in the file.
fn write_shuffled(path: &Path, mission: &Mission, swapped: &[(usize, usize)]) {
    let mut writer = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(path).unwrap(),
    ))
    .unwrap();
    let channel = |id: u16, topic: &str, schema: &str| {
        Arc::new(mcap::Channel {
            id,
            topic: topic.to_string(),
            schema: Some(Arc::new(mcap::Schema {
                id,
                name: schema.to_string(),
                encoding: json::SCHEMA_ENCODING.to_string(),
                data: Cow::Owned(b"{}".to_vec()),
            })),
            message_encoding: json::MESSAGE_ENCODING.to_string(),
            metadata: BTreeMap::new(),
        })
    };
    let beams = channel(1, "/sonar/beam", json::BEAM_SCHEMA_NAME);
    let dvl = channel(2, "/dvl/velocity", json::DVL_SCHEMA_NAME);
    let attitude = channel(3, "/attitude", json::ATTITUDE_SCHEMA_NAME);
    let mut write = |channel: &Arc<mcap::Channel>, stamp_s: f64, text: String| {
        let log_time = (stamp_s * 1e9) as u64;
        writer
            .write(&mcap::Message {
                channel: channel.clone(),
                sequence: 0,
                log_time,
                publish_time: log_time,
                data: Cow::Owned(text.into_bytes()),
            })
            .unwrap();
    };
    for b in &mission.beams {
        let bins = base64::engine::general_purpose::STANDARD.encode(&b.intensities);
        write(
            &beams,
            b.stamp_s,
            format!(
                r#"{{"stamp_s":{},"angle_rad":{},"bin_size_m":{},"first_bin_range_m":{},"intensities":"{bins}"}}"#,
                b.stamp_s, b.angle_rad, b.bin_size_m, b.first_bin_range_m
            ),
        );
    }
    let mut order: Vec<usize> = (0..mission.dvl.len()).collect();
    for &(i, j) in swapped {
        order.swap(i, j);
    }
    for i in order {
        let d = &mission.dvl[i];
        let v = d.velocity_mps;
        write(
            &dvl,
            d.stamp_s,
            format!(
                r#"{{"stamp_s":{},"velocity_mps":{{"x":{},"y":{},"z":{}}},"valid":{}}}"#,
                d.stamp_s, v.x, v.y, v.z, d.valid
            ),
        );
    }
    for a in &mission.attitude {
        let rate = a
            .yaw_rate_radps
            .map_or(String::new(), |r| format!(r#","yaw_rate_radps":{r}"#));
        write(
            &attitude,
            a.stamp_s,
            format!(
                r#"{{"stamp_s":{},"roll_rad":{},"pitch_rad":{},"yaw_rad":{}{rate}}}"#,
                a.stamp_s, a.roll_rad, a.pitch_rad, a.yaw_rad
            ),
        );
    }
    writer.finish().unwrap();
}

#[test]
fn stamps_that_go_backwards_in_the_file_are_resorted_with_a_counted_warning() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("shuffled.mcap");
    let n = tank().dvl.len();
    // Three records written early: each is older than the one before it.
    write_shuffled(
        &path,
        tank(),
        &[(n / 4, n / 4 + 5), (n / 2, n / 2 + 9), (n - 20, n - 2)],
    );
    let mission = read_mission(&path).unwrap();
    // Re-sorted: the streams are as simulated.
    assert_eq!(mission.dvl, tank().dvl);
    let resorted = mission
        .warnings
        .of(WarningKind::StampsResorted)
        .expect("a re-sort warning");
    // A swap of records i < j leaves the records i+1..=j of the stream
    // behind the later one written at i... counted once each: the
    // records written after a later stamp, j - i per swap.
    assert_eq!(resorted.count, 5 + 9 + 18, "{resorted:?}");
    assert_eq!(
        resorted.first_record.as_deref(),
        Some(format!("DVL record {}", n / 4 + 1).as_str())
    );
    // The run reports it, beside the mounting this file does not record.
    let output = default_run(mission).unwrap();
    let warnings = &output.report.warnings;
    assert_eq!(warnings.of(WarningKind::StampsResorted).unwrap().count, 32);
    assert!(warnings.of(WarningKind::MountingAssumed).is_some());
    // The file in time order gives no such warning.
    let ordered = dir.path().join("ordered.mcap");
    write_shuffled(&ordered, tank(), &[]);
    let mission = read_mission(&ordered).unwrap();
    assert!(mission.warnings.of(WarningKind::StampsResorted).is_none());
}
