//! ROS 2 style MCAP (CDR messages, ros2msg schemas): round trips through
//! `write_mission_ros2` and hand-made messages with known values.

use echofield_datasets::DatasetError;
use echofield_datasets::mcap::fixture::random_mission;
use echofield_datasets::mcap::ros2::{Ros2Kind, SONAR_BEAM_MSG};
use echofield_datasets::mcap::{Ros2GroundTruth, read_mission, write_mission_ros2};
use echofield_frontend::sensors::{Mission, SensorMounting};
use echofield_graph::wrap_angle;
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

fn assert_close(a: f64, b: f64, tol: f64, what: &str) {
    assert!((a - b).abs() <= tol, "{what}: {a} vs {b}");
}

/// Stamps pass through int32 seconds + uint32 nanoseconds.
const STAMP_TOL_S: f64 = 1e-6;
/// Angles pass through a quaternion.
const ANGLE_TOL_RAD: f64 = 1e-12;

fn check_round_trip(written: &Mission, read: &Mission) {
    // No metadata: the identity mounting, marked as assumed.
    assert_eq!(read.mounting, SensorMounting::assumed_identity());
    assert_eq!(read.beams.len(), written.beams.len());
    let mut beams = written.beams.clone();
    beams.sort_by(|a, b| a.stamp_s.total_cmp(&b.stamp_s));
    for (r, w) in read.beams.iter().zip(&beams) {
        assert_close(r.stamp_s, w.stamp_s, STAMP_TOL_S, "beam stamp");
        assert_eq!(r.angle_rad, w.angle_rad);
        assert_eq!(r.bin_size_m, w.bin_size_m);
        assert_eq!(r.first_bin_range_m, w.first_bin_range_m);
        assert_eq!(r.intensities, w.intensities);
    }
    assert_eq!(read.dvl.len(), written.dvl.len());
    for (r, w) in read.dvl.iter().zip(&written.dvl) {
        assert_close(r.stamp_s, w.stamp_s, STAMP_TOL_S, "dvl stamp");
        assert_eq!(r.velocity_mps, w.velocity_mps);
        assert_eq!(r.valid, w.valid);
        // ROS cannot carry the covariance of an invalid sample (element 0 = -1).
        let expected_cov = if w.valid { w.covariance } else { None };
        assert_eq!(r.covariance, expected_cov);
    }
    assert_eq!(read.attitude.len(), written.attitude.len());
    for (r, w) in read.attitude.iter().zip(&written.attitude) {
        assert_close(r.stamp_s, w.stamp_s, STAMP_TOL_S, "attitude stamp");
        assert_close(r.roll_rad, w.roll_rad, ANGLE_TOL_RAD, "roll");
        assert_close(r.pitch_rad, w.pitch_rad, ANGLE_TOL_RAD, "pitch");
        assert_close(wrap_angle(r.yaw_rad - w.yaw_rad), 0.0, ANGLE_TOL_RAD, "yaw");
        assert_eq!(r.yaw_rate_radps, w.yaw_rate_radps);
    }
    assert_eq!(read.ground_truth.len(), written.ground_truth.len());
    for (r, w) in read.ground_truth.iter().zip(&written.ground_truth) {
        assert_close(r.stamp_s, w.stamp_s, STAMP_TOL_S, "gt stamp");
        let (rp, wp) = (&r.world_from_vehicle, &w.world_from_vehicle);
        assert_eq!((rp.x(), rp.y()), (wp.x(), wp.y()));
        assert_close(
            wrap_angle(rp.theta() - wp.theta()),
            0.0,
            ANGLE_TOL_RAD,
            "gt yaw",
        );
    }
}

#[test]
fn ros2_round_trip_with_odometry_and_with_pose_stamped() {
    let dir = tempfile::tempdir().unwrap();
    let mission = random_mission(400, 60, 21);
    for (gt, file) in [
        (Ros2GroundTruth::Odometry, "odom_bag.mcap"),
        (Ros2GroundTruth::PoseStamped, "pose_bag.mcap"),
    ] {
        let path = dir.path().join(file);
        write_mission_ros2(&path, &mission, gt).unwrap();
        let read = read_mission(&path).unwrap();
        assert_eq!(read.name, file.trim_end_matches(".mcap"));
        check_round_trip(&mission, &read);
    }
}

#[test]
fn ros2_file_layout() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bag.mcap");
    write_mission_ros2(&path, &random_mission(50, 10, 2), Ros2GroundTruth::Odometry).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let mut seen = BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m.channel.schema.as_ref().unwrap();
        assert_eq!(m.channel.message_encoding, "cdr");
        assert_eq!(schema.encoding, "ros2msg");
        // Little-endian plain CDR encapsulation.
        assert_eq!(&m.data[..4], &[0, 1, 0, 0]);
        seen.insert(
            m.channel.topic.clone(),
            (schema.name.clone(), schema.data.to_vec()),
        );
    }
    assert_eq!(seen["/imu/data"].0, "sensor_msgs/msg/Imu");
    assert_eq!(
        seen["/dvl/twist"].0,
        "geometry_msgs/msg/TwistWithCovarianceStamped"
    );
    assert_eq!(seen["/ground_truth/odom"].0, "nav_msgs/msg/Odometry");
    let (beam_schema, beam_text) = &seen["/sonar/beam"];
    assert_eq!(beam_schema, "echofield_msgs/msg/SonarBeam");
    let text = String::from_utf8(beam_text.clone()).unwrap();
    assert!(text.starts_with(SONAR_BEAM_MSG));
    assert!(text.contains("uint8[] intensities"));
}

/// Little-endian CDR built by hand, independent of echofield's writer.
struct Cdr(Vec<u8>);

impl Cdr {
    fn new() -> Self {
        Cdr(vec![0, 1, 0, 0])
    }
    fn pad(&mut self, n: usize) {
        while !(self.0.len() - 4).is_multiple_of(n) {
            self.0.push(0);
        }
    }
    fn i32(&mut self, v: i32) -> &mut Self {
        self.pad(4);
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn u32(&mut self, v: u32) -> &mut Self {
        self.pad(4);
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn string(&mut self, s: &str) -> &mut Self {
        self.u32(s.len() as u32 + 1);
        self.0.extend_from_slice(s.as_bytes());
        self.0.push(0);
        self
    }
    fn f64s(&mut self, vs: &[f64]) -> &mut Self {
        for v in vs {
            self.pad(8);
            self.0.extend_from_slice(&v.to_le_bytes());
        }
        self
    }
}

fn write_ros2(path: &Path, messages: &[(&str, Ros2Kind, u64, Vec<u8>)]) {
    let mut writer = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(path).unwrap(),
    ))
    .unwrap();
    let mut ids = BTreeMap::new();
    for (topic, kind, log_time, data) in messages {
        let next = ids.len() as u16 + 1;
        let id = *ids.entry(topic.to_string()).or_insert(next);
        let channel = Arc::new(mcap::Channel {
            id,
            topic: topic.to_string(),
            schema: Some(Arc::new(mcap::Schema {
                id,
                name: kind.schema_name().into(),
                encoding: "ros2msg".into(),
                data: Cow::Owned(kind.schema_text().into_bytes()),
            })),
            message_encoding: "cdr".into(),
            metadata: BTreeMap::new(),
        });
        writer
            .write(&mcap::Message {
                channel,
                sequence: 0,
                log_time: *log_time,
                publish_time: *log_time,
                data: Cow::Borrowed(data),
            })
            .unwrap();
    }
    writer.finish().unwrap();
}

fn imu_payload(sec: i32, quaternion_xyzw: [f64; 4], yaw_rate: Option<f64>) -> Vec<u8> {
    let mut c = Cdr::new();
    c.i32(sec).u32(250_000_000).string("imu_link");
    c.f64s(&quaternion_xyzw).f64s(&[0.0; 9]);
    c.f64s(&[0.01, -0.02, yaw_rate.unwrap_or(0.0)]);
    let mut rate_cov = [0.0; 9];
    if yaw_rate.is_none() {
        rate_cov[0] = -1.0;
    }
    c.f64s(&rate_cov).f64s(&[0.0, 0.0, 9.81]).f64s(&[0.0; 9]);
    c.0
}

#[test]
fn hand_made_imu_twist_and_pose_give_known_values() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("hand.mcap");
    let s = std::f64::consts::FRAC_1_SQRT_2;
    // Yaw +90° (counter-clockwise, REP-103), then a pure 60° roll.
    let yaw90 = imu_payload(10, [0.0, 0.0, s, s], Some(0.05));
    let half = std::f64::consts::PI / 6.0;
    let roll60 = imu_payload(11, [half.sin(), 0.0, 0.0, half.cos()], None);
    let mut twist = Cdr::new();
    twist
        .i32(12)
        .u32(0)
        .string("dvl_link")
        .f64s(&[0.3, -0.1, 0.02, 0.0, 0.0, 0.0]);
    let mut cov = [0.0; 36];
    cov[0] = 0.04; // vx
    cov[7] = 0.05; // vy
    cov[14] = 0.06; // vz
    cov[1] = 0.001; // vx-vy
    cov[6] = 0.001;
    cov[21] = 9.0; // an angular term, dropped
    twist.f64s(&cov);
    let mut pose = Cdr::new();
    pose.i32(13)
        .u32(0)
        .string("map")
        .f64s(&[5.0, -7.0, 1.0, 0.0, 0.0, -s, s]);
    write_ros2(
        &path,
        &[
            ("/imu", Ros2Kind::Imu, 10, yaw90),
            ("/imu", Ros2Kind::Imu, 11, roll60),
            ("/dvl", Ros2Kind::TwistWithCovarianceStamped, 12, twist.0),
            ("/gps/pose", Ros2Kind::PoseStamped, 13, pose.0),
        ],
    );
    let m = read_mission(&path).unwrap();
    assert_eq!(m.attitude.len(), 2);
    assert_eq!(m.attitude[0].stamp_s, 10.25);
    assert_close(
        m.attitude[0].yaw_rad,
        std::f64::consts::FRAC_PI_2,
        1e-12,
        "yaw",
    );
    assert_close(m.attitude[0].roll_rad, 0.0, 1e-12, "roll");
    assert_eq!(m.attitude[0].yaw_rate_radps, Some(0.05));
    assert_close(
        m.attitude[1].roll_rad,
        std::f64::consts::FRAC_PI_3,
        1e-12,
        "roll",
    );
    assert_close(m.attitude[1].yaw_rad, 0.0, 1e-12, "yaw");
    assert_eq!(m.attitude[1].yaw_rate_radps, None);

    let d = &m.dvl[0];
    assert_eq!(
        (d.velocity_mps.x, d.velocity_mps.y, d.velocity_mps.z),
        (0.3, -0.1, 0.02)
    );
    assert!(d.valid);
    let c = d.covariance.unwrap();
    assert_eq!(
        (c[(0, 0)], c[(1, 1)], c[(2, 2)], c[(0, 1)], c[(1, 0)]),
        (0.04, 0.05, 0.06, 0.001, 0.001)
    );

    let g = &m.ground_truth[0].world_from_vehicle;
    assert_eq!((g.x(), g.y()), (5.0, -7.0));
    assert_close(g.theta(), -std::f64::consts::FRAC_PI_2, 1e-12, "gt yaw");
}

#[test]
fn nan_and_truncated_cdr_name_message_topic_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad_cdr.mcap");
    let mut good = Cdr::new();
    good.i32(1)
        .u32(0)
        .string("map")
        .f64s(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    let mut nan = Cdr::new();
    nan.i32(2)
        .u32(0)
        .string("map")
        .f64s(&[f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    write_ros2(
        &path,
        &[
            ("/gt", Ros2Kind::PoseStamped, 1, good.0.clone()),
            ("/gt", Ros2Kind::PoseStamped, 2, nan.0),
        ],
    );
    match read_mission(&path).unwrap_err() {
        DatasetError::Parse { record, field, .. } => {
            assert_eq!(record, "message 1 (topic `/gt`)");
            assert_eq!(field, "pose.position.x");
        }
        other => panic!("{other}"),
    }

    let truncated = good.0[..good.0.len() - 4].to_vec();
    write_ros2(&path, &[("/gt", Ros2Kind::PoseStamped, 1, truncated)]);
    match read_mission(&path).unwrap_err() {
        DatasetError::Parse {
            record,
            field,
            message,
            ..
        } => {
            assert_eq!(record, "message 0 (topic `/gt`)");
            assert_eq!(field, "pose.orientation.w");
            assert!(message.contains("truncated"), "{message}");
        }
        other => panic!("{other}"),
    }

    // An Imu without orientation (raw IMU) cannot give an attitude.
    let mut raw = Cdr::new();
    raw.i32(1).u32(0).string("imu").f64s(&[0.0, 0.0, 0.0, 1.0]);
    let mut ocov = [0.0; 9];
    ocov[0] = -1.0;
    raw.f64s(&ocov)
        .f64s(&[0.0; 3])
        .f64s(&[0.0; 9])
        .f64s(&[0.0; 3])
        .f64s(&[0.0; 9]);
    write_ros2(&path, &[("/imu/data_raw", Ros2Kind::Imu, 1, raw.0)]);
    match read_mission(&path).unwrap_err() {
        DatasetError::Parse { field, .. } => assert_eq!(field, "orientation_covariance[0]"),
        other => panic!("{other}"),
    }
}

#[test]
fn out_of_order_ros2_messages_are_sorted() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("unordered.mcap");
    let beam = |sec: i32, angle: f64| {
        let mut c = Cdr::new();
        c.i32(sec).u32(0).string("sonar").f64s(&[angle, 0.05, 0.2]);
        c.u32(3);
        c.0.extend_from_slice(&[9, 8, 7]);
        c.0
    };
    write_ros2(
        &path,
        &[
            ("/sonar", Ros2Kind::SonarBeam, 3, beam(3, 0.3)),
            ("/sonar", Ros2Kind::SonarBeam, 1, beam(1, 0.1)),
            ("/sonar", Ros2Kind::SonarBeam, 2, beam(2, 0.2)),
        ],
    );
    let m = read_mission(&path).unwrap();
    let got: Vec<(f64, f64)> = m.beams.iter().map(|b| (b.stamp_s, b.angle_rad)).collect();
    assert_eq!(got, vec![(1.0, 0.1), (2.0, 0.2), (3.0, 0.3)]);
    assert_eq!(m.beams[0].intensities, vec![9, 8, 7]);
    assert_eq!(
        (m.beams[0].bin_size_m, m.beams[0].first_bin_range_m),
        (0.05, 0.2)
    );
}
