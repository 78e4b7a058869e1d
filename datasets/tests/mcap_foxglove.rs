//! Foxglove output channels written beside a mission: message content as
//! Foxglove expects it, and the mission reader skipping them.

use base64::Engine as _;
use echofield_datasets::mcap::fixture::random_mission;
use echofield_datasets::mcap::foxglove::ScanPoint;
use echofield_datasets::mcap::{MissionWriter, Ros2GroundTruth, read_mission, write_mission_ros2};
use echofield_frontend::sensors::Mission;
use echofield_graph::Se2;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;

/// A tiny valid PNG (1x1 grey pixel), as an acoustic image would be.
const PNG_1X1: &[u8] = &[
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52,
    0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x01, 0x08, 0x00, 0x00, 0x00, 0x00, 0x3a, 0x7e, 0x9b,
    0x55, 0x00, 0x00, 0x00, 0x0a, 0x49, 0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0x68, 0x00, 0x00, 0x00,
    0x82, 0x00, 0x81, 0x4c, 0x17, 0xd7, 0xdf, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae,
    0x42, 0x60, 0x82,
];

/// Writes a mission plus one message of every Foxglove helper.
fn write_with_outputs(path: &Path, mission: &Mission) {
    let mut w = MissionWriter::create(path, &mission.name, &mission.mounting).unwrap();
    for b in &mission.beams {
        w.write_beam(b).unwrap();
    }
    for d in &mission.dvl {
        w.write_dvl(d).unwrap();
    }
    for a in &mission.attitude {
        w.write_attitude(a).unwrap();
    }
    for g in &mission.ground_truth {
        w.write_ground_truth(g).unwrap();
    }
    let t = mission.beams[0].stamp_s;
    let quarter = Se2::new(1.0, 2.0, std::f64::consts::FRAC_PI_2);
    w.write_pose_in_frame("/slam/pose", t, "world", &quarter)
        .unwrap();
    w.write_poses_in_frame("/slam/trajectory", t, "world", &[Se2::identity(), quarter])
        .unwrap();
    let points = [
        ScanPoint {
            x_m: 1.5,
            y_m: -2.0,
            intensity: 200.0,
        },
        ScanPoint {
            x_m: 3.0,
            y_m: 0.25,
            intensity: 90.0,
        },
    ];
    w.write_point_cloud("/slam/scan", t, "world", &quarter, &points)
        .unwrap();
    w.write_compressed_image("/slam/acoustic_image", t, "rotation_0", "png", PNG_1X1)
        .unwrap();
    w.write_frame_transform(
        "/tf",
        t,
        "vehicle",
        "sonar",
        &mission.mounting.vehicle_from_sonar,
    )
    .unwrap();
    w.finish().unwrap();
}

fn messages_by_topic(path: &Path) -> BTreeMap<String, (String, Value)> {
    let bytes = std::fs::read(path).unwrap();
    let mut out = BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m.channel.schema.as_ref().unwrap();
        if schema.name.starts_with("foxglove.") {
            assert_eq!(schema.encoding, "jsonschema");
            assert_eq!(m.channel.message_encoding, "json");
            let value = serde_json::from_slice(&m.data).unwrap();
            out.insert(m.channel.topic.clone(), (schema.name.clone(), value));
        }
    }
    out
}

#[test]
fn foxglove_messages_carry_the_documented_fields() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.mcap");
    let mission = random_mission(30, 20, 4);
    write_with_outputs(&path, &mission);
    let msgs = messages_by_topic(&path);
    let h = std::f64::consts::FRAC_1_SQRT_2;

    let (name, pose) = &msgs["/slam/pose"];
    assert_eq!(name, "foxglove.PoseInFrame");
    assert_eq!(pose["frame_id"], "world");
    assert_eq!(pose["pose"]["position"]["x"], 1.0);
    assert!((pose["pose"]["orientation"]["z"].as_f64().unwrap() - h).abs() < 1e-15);
    let stamp_ns = (mission.beams[0].stamp_s * 1e9).round() as u64;
    assert_eq!(pose["timestamp"]["sec"], stamp_ns / 1_000_000_000);
    assert_eq!(pose["timestamp"]["nsec"], stamp_ns % 1_000_000_000);

    let (name, traj) = &msgs["/slam/trajectory"];
    assert_eq!(name, "foxglove.PosesInFrame");
    assert_eq!(traj["poses"].as_array().unwrap().len(), 2);
    assert_eq!(traj["poses"][0]["orientation"]["w"], 1.0);

    let (name, cloud) = &msgs["/slam/scan"];
    assert_eq!(name, "foxglove.PointCloud");
    assert_eq!(cloud["point_stride"], 16);
    assert_eq!(cloud["fields"][3]["name"], "intensity");
    assert_eq!(cloud["fields"][3]["type"], 7);
    let data = base64::engine::general_purpose::STANDARD
        .decode(cloud["data"].as_str().unwrap())
        .unwrap();
    let floats: Vec<f32> = data
        .chunks(4)
        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    assert_eq!(floats, vec![1.5, -2.0, 0.0, 200.0, 3.0, 0.25, 0.0, 90.0]);

    let (name, image) = &msgs["/slam/acoustic_image"];
    assert_eq!(name, "foxglove.CompressedImage");
    assert_eq!(image["format"], "png");
    let png = base64::engine::general_purpose::STANDARD
        .decode(image["data"].as_str().unwrap())
        .unwrap();
    assert_eq!(png, PNG_1X1);

    let (name, tf) = &msgs["/tf"];
    assert_eq!(name, "foxglove.FrameTransform");
    assert_eq!(
        (&tf["parent_frame_id"], &tf["child_frame_id"]),
        (&"vehicle".into(), &"sonar".into())
    );
    // The fixture mounts the sonar rotated by π: quaternion (0, 0, 1, ~0).
    assert_eq!(tf["translation"]["x"], 0.6);
    assert!((tf["rotation"]["z"].as_f64().unwrap() - 1.0).abs() < 1e-15);

    // The mission reader ignores the output channels.
    let read = read_mission(&path).unwrap();
    assert_eq!(read.beams, mission.beams);
    assert_eq!(read.dvl, mission.dvl);
}

#[test]
fn helpers_refuse_bad_values_and_sensor_topics() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.mcap");
    let mission = random_mission(5, 5, 4);
    let mut w = MissionWriter::create(&path, "bad", &mission.mounting).unwrap();
    let err = w
        .write_pose_in_frame("/sonar/beam", 1.0, "world", &Se2::identity())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("topic") && err.contains("/sonar/beam"),
        "{err}"
    );
    let err = w
        .write_pose_in_frame("/slam/pose", 1.0, "world", &Se2::new(f64::NAN, 0.0, 0.0))
        .unwrap_err()
        .to_string();
    assert!(err.contains("pose"), "{err}");
    let err = w
        .write_compressed_image("/img", 1.0, "f", "bmp", PNG_1X1)
        .unwrap_err()
        .to_string();
    assert!(err.contains("format"), "{err}");
    // One topic, one schema.
    w.write_pose_in_frame("/slam/pose", 1.0, "world", &Se2::identity())
        .unwrap();
    let err = w
        .write_poses_in_frame("/slam/pose", 2.0, "world", &[])
        .unwrap_err()
        .to_string();
    assert!(err.contains("already carries"), "{err}");
}

/// Writes sample files for `tools/check_mcap.sh` into `$ECHOFIELD_MCAP_SAMPLES`.
#[test]
#[ignore = "writes files for tools/check_mcap.sh"]
fn write_samples_for_python_check() {
    let dir = std::env::var_os("ECHOFIELD_MCAP_SAMPLES").expect("ECHOFIELD_MCAP_SAMPLES");
    let dir = Path::new(&dir);
    let mission = random_mission(2000, 500, 42);
    write_with_outputs(&dir.join("echofield_mission.mcap"), &mission);
    write_mission_ros2(
        &dir.join("ros2_odometry.mcap"),
        &mission,
        Ros2GroundTruth::Odometry,
    )
    .unwrap();
    write_mission_ros2(
        &dir.join("ros2_pose.mcap"),
        &mission,
        Ros2GroundTruth::PoseStamped,
    )
    .unwrap();
}
