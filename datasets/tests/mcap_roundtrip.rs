//! echofield's MCAP format: write-then-read round trips and the file layout
//! standard tools rely on.

use echofield_datasets::mcap::fixture::random_mission;
use echofield_datasets::mcap::{MissionWriter, read_mission, write_mission};
use echofield_frontend::sensors::{Mission, SensorMounting, SonarBeam};
use echofield_graph::Se2;
use std::collections::BTreeMap;
use std::path::Path;

/// Se2 keeps a unit complex number, not the angle: (x, y) and every scalar
/// field round-trip bit for bit, the heading through `theta()` to within the
/// rounding of atan2 (a few 1e-16 rad).
fn assert_same_pose(a: &Se2, b: &Se2, what: &str) {
    assert_eq!(a.x(), b.x(), "{what}: x");
    assert_eq!(a.y(), b.y(), "{what}: y");
    let d = echofield_graph::se2::wrap_angle(a.theta() - b.theta());
    assert!(d.abs() <= 1e-15, "{what}: theta differs by {d}");
}

fn assert_same_mission(read: &Mission, written: &Mission) {
    assert_eq!(read.name, written.name);
    assert_same_pose(
        &read.mounting.vehicle_from_sonar,
        &written.mounting.vehicle_from_sonar,
        "vehicle_from_sonar",
    );
    assert_same_pose(
        &read.mounting.vehicle_from_dvl,
        &written.mounting.vehicle_from_dvl,
        "vehicle_from_dvl",
    );
    assert_eq!(
        read.mounting.heading_offset_rad,
        written.mounting.heading_offset_rad
    );
    assert_eq!(read.beams, written.beams);
    assert_eq!(read.dvl, written.dvl);
    assert_eq!(read.attitude, written.attitude);
    assert_eq!(read.ground_truth.len(), written.ground_truth.len());
    for (k, (r, w)) in read
        .ground_truth
        .iter()
        .zip(&written.ground_truth)
        .enumerate()
    {
        assert_eq!(r.stamp_s, w.stamp_s, "ground truth {k}");
        assert_same_pose(&r.world_from_vehicle, &w.world_from_vehicle, "ground truth");
    }
}

#[test]
fn every_message_type_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mission.mcap");
    let mission = random_mission(600, 120, 7);
    // The fixture exercises every optional field both ways.
    assert!(mission.dvl.iter().any(|d| !d.valid));
    assert!(mission.dvl.iter().any(|d| d.covariance.is_some()));
    assert!(mission.dvl.iter().any(|d| d.covariance.is_none()));
    assert!(mission.attitude.iter().any(|a| a.yaw_rate_radps.is_some()));
    assert!(mission.attitude.iter().any(|a| a.yaw_rate_radps.is_none()));
    write_mission(&path, &mission).unwrap();
    let read = read_mission(&path).unwrap();
    // The fixture's streams are sorted except the jittered beams.
    let mut expected = mission.clone();
    expected
        .beams
        .sort_by(|a, b| a.stamp_s.total_cmp(&b.stamp_s));
    assert_same_mission(&read, &expected);
}

#[test]
fn extreme_values_round_trip_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("extreme.mcap");
    let beam = |stamp_s: f64, angle_rad: f64, bins: Vec<u8>| SonarBeam {
        stamp_s,
        angle_rad,
        bin_size_m: 1e-300,
        first_bin_range_m: 0.1 + 0.2,
        intensities: bins,
    };
    let mission = Mission {
        name: "ünïcode \"quoted\" name\n".into(),
        beams: vec![
            beam(0.0, -0.0, vec![0]),
            beam(1.0 / 3.0, 1e308, (0..=255).collect()),
            beam(1.7e9 + 0.123456789, -std::f64::consts::PI, vec![255; 1000]),
        ],
        ..Mission::default()
    };
    write_mission(&path, &mission).unwrap();
    let read = read_mission(&path).unwrap();
    assert_eq!(read.name, mission.name);
    for (r, w) in read.beams.iter().zip(&mission.beams) {
        assert_eq!(r.stamp_s.to_bits(), w.stamp_s.to_bits());
        assert_eq!(r.angle_rad.to_bits(), w.angle_rad.to_bits());
        assert_eq!(r.bin_size_m.to_bits(), w.bin_size_m.to_bits());
        assert_eq!(r.first_bin_range_m.to_bits(), w.first_bin_range_m.to_bits());
        assert_eq!(r.intensities, w.intensities);
    }
}

#[test]
fn empty_mission_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("empty.mcap");
    let mission = Mission {
        name: "empty".into(),
        ..Mission::default()
    };
    write_mission(&path, &mission).unwrap();
    assert_eq!(read_mission(&path).unwrap(), mission);
}

/// Reads every message with the `mcap` crate alone, as a third-party tool
/// would: (topic, schema name, schema encoding, message encoding, log time, JSON).
fn raw_messages(path: &Path) -> Vec<(String, String, String, String, u64, serde_json::Value)> {
    let bytes = std::fs::read(path).unwrap();
    mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            let schema = m.channel.schema.as_ref().unwrap();
            (
                m.channel.topic.clone(),
                schema.name.clone(),
                schema.encoding.clone(),
                m.channel.message_encoding.clone(),
                m.log_time,
                serde_json::from_slice(&m.data).unwrap(),
            )
        })
        .collect()
}

#[test]
fn layout_is_what_the_readme_documents() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("layout.mcap");
    let mission = random_mission(300, 50, 3);
    write_mission(&path, &mission).unwrap();
    let messages = raw_messages(&path);
    assert_eq!(
        messages.len(),
        mission.beams.len()
            + mission.dvl.len()
            + mission.attitude.len()
            + mission.ground_truth.len()
    );
    let expected_schema = BTreeMap::from([
        ("/sonar/beam", "echofield.SonarBeam"),
        ("/dvl/velocity", "echofield.DvlVelocity"),
        ("/attitude", "echofield.Attitude"),
        ("/ground_truth/pose", "echofield.GroundTruthPose"),
    ]);
    let mut previous_log_time = 0;
    for (topic, schema, schema_encoding, encoding, log_time, json) in &messages {
        assert_eq!(expected_schema[topic.as_str()], schema);
        assert_eq!(schema_encoding, "jsonschema");
        assert_eq!(encoding, "json");
        // log_time is the stamp in ns, and the streams are interleaved by time.
        let stamp_s = json["stamp_s"].as_f64().unwrap();
        assert_eq!(*log_time, (stamp_s * 1e9).round() as u64);
        assert!(*log_time >= previous_log_time);
        previous_log_time = *log_time;
    }
    // The first beam, field by field, as the README shows it.
    let (_, _, _, _, _, first_beam) = messages.iter().find(|m| m.0 == "/sonar/beam").unwrap();
    let b = &mission
        .beams
        .iter()
        .min_by(|a, b| a.stamp_s.total_cmp(&b.stamp_s))
        .unwrap();
    assert_eq!(first_beam["angle_rad"], b.angle_rad);
    assert_eq!(first_beam["bin_size_m"], 0.1);
    let base64 = first_beam["intensities"].as_str().unwrap();
    assert_eq!(base64.len(), 50usize.div_ceil(3) * 4);

    // Chunks are zstd-compressed; the mission metadata is a Metadata record.
    let bytes = std::fs::read(&path).unwrap();
    let mut compressions = Vec::new();
    let mut metadata = None;
    for record in mcap::read::LinearReader::new(&bytes).unwrap() {
        match record.unwrap() {
            mcap::records::Record::Chunk { header, .. } => compressions.push(header.compression),
            mcap::records::Record::Metadata(m) => metadata = Some(m),
            _ => {}
        }
    }
    assert!(!compressions.is_empty());
    assert!(compressions.iter().all(|c| c == "zstd"));
    let metadata = metadata.unwrap();
    assert_eq!(metadata.name, "echofield.mission");
    assert_eq!(metadata.metadata["format"], "echofield-mission");
    assert_eq!(metadata.metadata["format_version"], "1");
    assert_eq!(metadata.metadata["name"], mission.name);
    let mounting: serde_json::Value = serde_json::from_str(&metadata.metadata["mounting"]).unwrap();
    assert_eq!(mounting["vehicle_from_sonar"][0], 0.6);
}

#[test]
fn same_mission_gives_identical_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let mission = random_mission(400, 64, 11);
    let a = dir.path().join("a.mcap");
    let b = dir.path().join("b.mcap");
    write_mission(&a, &mission).unwrap();
    write_mission(&b, &mission).unwrap();
    let (a, b) = (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    let first_difference = a.iter().zip(&b).position(|(x, y)| x != y);
    assert_eq!((first_difference, a.len()), (None, b.len()));
    // Still a valid file after the summary was put in order.
    assert_eq!(
        read_mission(&dir.path().join("a.mcap"))
            .unwrap()
            .beams
            .len(),
        400
    );
}

#[test]
fn streamed_out_of_order_records_are_sorted_and_equal_stamps_kept_in_file_order() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("unordered.mcap");
    let beam = |stamp_s: f64, angle_rad: f64| SonarBeam {
        stamp_s,
        angle_rad,
        bin_size_m: 0.1,
        first_bin_range_m: 0.0,
        intensities: vec![1, 2, 3],
    };
    let mut writer = MissionWriter::create(&path, "unordered", &SensorMounting::default()).unwrap();
    for b in [
        beam(3.0, 0.3),
        beam(1.0, 0.1),
        beam(2.0, 0.2),
        beam(1.0, 0.15),
    ] {
        writer.write_beam(&b).unwrap();
    }
    writer.finish().unwrap();
    let read = read_mission(&path).unwrap();
    let order: Vec<(f64, f64)> = read
        .beams
        .iter()
        .map(|b| (b.stamp_s, b.angle_rad))
        .collect();
    assert_eq!(order, vec![(1.0, 0.1), (1.0, 0.15), (2.0, 0.2), (3.0, 0.3)]);
}

#[test]
fn failed_write_keeps_the_previous_file_and_leaves_no_temporary() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mission.mcap");
    let good = random_mission(50, 10, 1);
    write_mission(&path, &good).unwrap();
    let before = std::fs::read(&path).unwrap();

    let mut bad = good.clone();
    bad.dvl[4].velocity_mps.y = f64::NAN;
    let err = write_mission(&path, &bad).unwrap_err().to_string();
    assert!(
        err.contains("dvl 4") && err.contains("velocity_mps.y"),
        "{err}"
    );

    // A streamed write abandoned half-way (dropped without finish).
    let mut writer = MissionWriter::create(&path, "abandoned", &SensorMounting::default()).unwrap();
    writer.write_beam(&good.beams[0]).unwrap();
    drop(writer);

    assert_eq!(std::fs::read(&path).unwrap(), before);
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("mission.mcap")]);
}

#[test]
fn a_completed_file_replaces_the_old_one_only_when_persisted() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mission.mcap");
    let old = random_mission(20, 8, 2);
    write_mission(&path, &old).unwrap();
    let before = std::fs::read(&path).unwrap();
    let new = random_mission(30, 8, 3);
    let names = || -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    };
    let writer = || {
        let mut writer = MissionWriter::create(&path, "new", &new.mounting).unwrap();
        for beam in &new.beams {
            writer.write_beam(beam).unwrap();
        }
        writer
    };
    let write = || writer().complete().unwrap();

    // Completed but dropped: the old file stays and the temporary goes.
    let completed = write();
    assert_eq!(completed.path(), path);
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert_eq!(names().len(), 2, "{:?}", names());
    drop(completed);
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert_eq!(names(), vec!["mission.mcap".to_string()]);

    // Completed and persisted: the new file, as `finish` writes it.
    write().persist().unwrap();
    assert_eq!(read_mission(&path).unwrap().beams.len(), 30);
    assert_eq!(names(), vec!["mission.mcap".to_string()]);
    let persisted = std::fs::read(&path).unwrap();
    writer().finish().unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), persisted);
}

/// `/position/fix`: fixes written with a mission read back bit for bit, on
/// their own documented channel, and a NaN or a non-positive standard
/// deviation is refused before anything is written, naming the record and
/// the field.
#[test]
fn position_fixes_round_trip_on_their_channel() {
    use echofield_frontend::sensors::PositionFix;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fixes.mcap");
    let mut mission = random_mission(300, 50, 3);
    let t0 = mission.beams[0].stamp_s;
    // UTM-sized coordinates, awkward decimals, one fix per 2 s.
    mission.position_fixes = (0..10)
        .map(|k| PositionFix {
            stamp_s: t0 + 2.0 * k as f64 + 0.1,
            x_m: 482_310.123_456_789 + k as f64 / 3.0,
            y_m: 4_650_120.987_654_321 - k as f64 / 7.0,
            std_m: 1.5 + k as f64 * 0.01,
        })
        .collect();
    write_mission(&path, &mission).unwrap();
    let mut expected = mission.clone();
    expected
        .beams
        .sort_by(|a, b| a.stamp_s.total_cmp(&b.stamp_s));
    let read = read_mission(&path).unwrap();
    assert_same_mission(&read, &expected);
    assert_eq!(read.position_fixes, mission.position_fixes);
    assert!(read.warnings.is_empty(), "{:?}", read.warnings);
    // The channel, its schema and a message as a third-party tool sees them.
    let fixes: Vec<_> = raw_messages(&path)
        .into_iter()
        .filter(|m| m.0 == "/position/fix")
        .collect();
    assert_eq!(fixes.len(), 10);
    let (_, schema, schema_encoding, encoding, log_time, json) = &fixes[3];
    assert_eq!(
        (schema.as_str(), schema_encoding.as_str(), encoding.as_str()),
        ("echofield.PositionFix", "jsonschema", "json")
    );
    assert_eq!(
        *log_time,
        (mission.position_fixes[3].stamp_s * 1e9).round() as u64
    );
    assert_eq!(json["std_m"], 1.53);
    // A mission without fixes has no such channel (files written before
    // the channel existed are unchanged).
    let plain = dir.path().join("plain.mcap");
    write_mission(&plain, &random_mission(50, 10, 3)).unwrap();
    assert!(raw_messages(&plain).iter().all(|m| m.0 != "/position/fix"));

    for (k, field, breaks) in [
        (
            4,
            "x_m",
            Box::new(|f: &mut PositionFix| f.x_m = f64::NAN) as Box<dyn Fn(&mut PositionFix)>,
        ),
        (7, "std_m", Box::new(|f: &mut PositionFix| f.std_m = 0.0)),
        (2, "y_m", Box::new(|f: &mut PositionFix| f.y_m = 1e9)),
    ] {
        let mut bad = mission.clone();
        breaks(&mut bad.position_fixes[k]);
        let out = dir.path().join("bad.mcap");
        match write_mission(&out, &bad).unwrap_err() {
            echofield_datasets::DatasetError::Parse {
                record, field: f, ..
            } => {
                assert_eq!(record, format!("position_fix {k}"));
                assert_eq!(f, field);
            }
            other => panic!("expected a Parse error, got {other}"),
        }
        assert!(!out.exists());
    }
}
