//! The standard ROS messages, read from recordings written by the
//! independent Python `rosbags` package (`datasets/ros-fixtures/`, made by
//! its `make_fixtures.py`; every expected value below is a value that
//! script writes): ROS 2 in MCAP and sqlite3 storage, ROS 1 bags with lz4
//! and bz2 chunks, the mounting from `/tf_static`, and a bad message.

use echofield_datasets::mcap::{ChannelUse, TopicChoice, read_mission_with};
use echofield_frontend::sensors::{AngleDirection, Mission, MountingSource};
use std::path::PathBuf;

const T0: f64 = 1_700_000_000.0;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("ros-fixtures")
        .join(name)
}

fn read(name: &str, assignments: &[&str]) -> (Mission, Vec<ChannelUse>) {
    let mut choice = TopicChoice::default();
    for a in assignments {
        choice.assign(a).unwrap();
    }
    read_mission_with(&fixture(name), &choice).unwrap()
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

fn use_of<'a>(uses: &'a [ChannelUse], topic: &str) -> &'a ChannelUse {
    uses.iter().find(|u| u.topic == topic).unwrap()
}

/// Ping360 echoes, marine_acoustic_msgs/Dvl, Imu, Odometry, and the
/// mounting from /tf_static.
fn check_ping360_marine_dvl_imu(name: &str) {
    let (m, uses) = read(
        name,
        &[
            "sonar=/ping360/echo",
            "dvl=/dvl/marine",
            "heading=/imu/data",
            "ground_truth=/odometry",
        ],
    );
    assert_eq!(m.beams.len(), 3, "{name}");
    for (k, b) in m.beams.iter().enumerate() {
        assert!(close(b.angle_rad, 0.1 * k as f64, 1e-6), "{name}: {b:?}");
        assert!(close(b.stamp_s, T0 + 0.1 * (k + 1) as f64, 1e-6), "{name}");
        assert_eq!(b.bin_size_m, 2.0);
        assert_eq!(b.first_bin_range_m, 0.0);
        assert_eq!(b.intensities, [k as u8, 1, 2, 3, 4]);
    }
    assert_eq!(m.dvl.len(), 2);
    let d = &m.dvl[0];
    // (0.5, 0.1, 0.05) with z down -> z up.
    assert!(d.valid);
    assert!(close(d.velocity_mps.x, 0.5, 1e-12) && close(d.velocity_mps.y, -0.1, 1e-12));
    assert!(close(d.velocity_mps.z, -0.05, 1e-12));
    assert_eq!(d.covariance.unwrap()[(1, 1)], 0.01);
    assert_eq!(m.attitude.len(), 2);
    assert!(close(m.attitude[0].yaw_rad, 0.2, 1e-12));
    assert_eq!(m.attitude[0].yaw_rate_radps, Some(0.05));
    assert_eq!(m.ground_truth.len(), 2);
    let gt = m.ground_truth[0].world_from_vehicle;
    assert!(
        close(gt.x(), 1.0, 1e-12) && close(gt.y(), 2.0, 1e-12) && close(gt.theta(), 0.3, 1e-12)
    );
    // base_link -> mast (0.5, -0.1, yaw 0.1) -> sonar_link (0.2, 0).
    let s = m.mounting.vehicle_from_sonar;
    assert!(close(s.x(), 0.5 + 0.2 * 0.1f64.cos(), 1e-9), "{s:?}");
    assert!(close(s.y(), -0.1 + 0.2 * 0.1f64.sin(), 1e-9), "{s:?}");
    assert!(close(s.theta(), 0.1, 1e-9));
    assert_eq!(m.mounting.sonar_angle, AngleDirection::CounterClockwise);
    assert_eq!(m.mounting.source, MountingSource::Recorded);
    let tf = use_of(&uses, "/tf_static");
    assert_eq!(tf.role, Some("mounting"));
    assert!(
        tf.reason.contains("base_link -> sonar_link"),
        "{}",
        tf.reason
    );
    assert!(use_of(&uses, "/tf").reason.contains("dynamic"));
    assert_eq!(use_of(&uses, "/ping360/echo").role, Some("sonar"));
    assert_eq!(use_of(&uses, "/sonar/raw").role, None);
    assert!(use_of(&uses, "/sonar/raw").reason.contains("/ping360/echo"));
}

/// RawSonarImage, Water Linked DVL, QuaternionStamped.
fn check_raw_image_water_linked(name: &str, ros1: bool) {
    let (m, _) = read(
        name,
        &[
            "sonar=/sonar/raw",
            "dvl=/dvl/data",
            "heading=/heading",
            "ground_truth=/odometry",
        ],
    );
    assert_eq!(m.beams.len(), 2, "{name}");
    for (k, b) in m.beams.iter().enumerate() {
        assert!(close(b.angle_rad, 0.5 + k as f64, 1e-6));
        // header stamp + tx delay 0.01 s.
        assert!(
            close(b.stamp_s, T0 + 0.15 + 0.1 * k as f64 + 0.01, 1e-6),
            "{b:?}"
        );
        assert!(close(b.bin_size_m, 0.1, 1e-12));
        assert!(close(b.first_bin_range_m, 0.2, 1e-12));
        assert_eq!(b.intensities, [10, 20, 30, 40 + k as u8]);
    }
    assert_eq!(m.dvl.len(), 2);
    // (0.3, -0.2, 0.1) with y starboard, z down -> y port, z up.
    let d = &m.dvl[0];
    assert!(close(d.velocity_mps.y, 0.2, 1e-12) && close(d.velocity_mps.z, -0.1, 1e-12));
    assert_eq!((m.dvl[0].valid, m.dvl[1].valid), (true, false));
    if ros1 {
        assert!(d.covariance.is_none());
    } else {
        assert_eq!(d.covariance.unwrap()[(2, 2)], 0.0004);
    }
    assert!(close(m.attitude[0].yaw_rad, -0.4, 1e-12));
    assert_eq!(m.attitude[0].yaw_rate_radps, None);
}

/// A LaserScan sweep; an Odometry's twist as DVL (the other Odometry is
/// then the ground truth by default); TwistWithCovarianceStamped.
fn check_laser_scan_odometry_twist(name: &str) {
    let (m, uses) = read(
        name,
        &[
            "sonar=/sonar/scan",
            "dvl=/odometry/filtered",
            "heading=/imu/data",
        ],
    );
    assert_eq!(m.beams.len(), 3);
    let lit: Vec<Option<usize>> = m
        .beams
        .iter()
        .map(|b| b.intensities.iter().position(|&v| v == 255))
        .collect();
    // 4 m, no return, 8 m in 10/500 m bins.
    assert_eq!(lit, [Some(200), None, Some(400)]);
    for (i, b) in m.beams.iter().enumerate() {
        assert!(close(b.angle_rad, -0.5 + 0.25 * i as f64, 1e-6));
        assert!(close(b.stamp_s, T0 + 0.2 + 0.01 * i as f64, 1e-6));
    }
    assert_eq!(m.dvl.len(), 2);
    assert!(close(m.dvl[0].velocity_mps.x, 0.4, 1e-12));
    assert_eq!(use_of(&uses, "/odometry/filtered").role, Some("dvl"));
    assert_eq!(use_of(&uses, "/odometry").role, Some("ground_truth"));
    assert_eq!(m.ground_truth.len(), 2);

    let (m, _) = read(
        name,
        &[
            "sonar=/ping360/echo",
            "dvl=/dvl/twist",
            "heading=/imu/data",
            "ground_truth=/odometry",
        ],
    );
    assert!(close(m.dvl[0].velocity_mps.x, 0.25, 1e-12));
    assert!(m.dvl[0].covariance.is_none() && m.dvl[0].valid);
}

#[test]
fn ros2_mcap_storage() {
    check_ping360_marine_dvl_imu("ros2_mcap");
    check_raw_image_water_linked("ros2_mcap", false);
    check_laser_scan_odometry_twist("ros2_mcap");
}

#[test]
fn ros2_sqlite3_storage() {
    check_ping360_marine_dvl_imu("ros2_sqlite3");
    check_raw_image_water_linked("ros2_sqlite3", false);
    check_laser_scan_odometry_twist("ros2_sqlite3");
    let choice = [
        "sonar=/sonar/raw",
        "dvl=/dvl/data",
        "heading=/heading",
        "ground_truth=/odometry",
    ];
    let (mut from_sqlite, _) = read("ros2_sqlite3", &choice);
    from_sqlite.name = "ros2_mcap".into();
    assert_eq!(from_sqlite, read("ros2_mcap", &choice).0);
}

#[test]
fn ros1_bags_with_lz4_and_bz2_chunks() {
    for name in ["ros1_lz4.bag", "ros1_bz2.bag"] {
        check_ping360_marine_dvl_imu(name);
        check_raw_image_water_linked(name, true);
        check_laser_scan_odometry_twist(name);
        // The Girona underwater caves layout: one beam per LaserScan.
        let (m, _) = read(
            name,
            &[
                "sonar=/sonar_micron_ros",
                "dvl=/dvl/data",
                "heading=/imu/data",
                "ground_truth=/odometry",
            ],
        );
        assert_eq!(m.beams.len(), 2);
        for (k, b) in m.beams.iter().enumerate() {
            assert!(close(b.angle_rad, 0.2 * k as f64, 1e-6));
            assert_eq!(b.intensities, [0, 50, 191, 7]);
            assert_eq!(b.bin_size_m, 5.0);
        }
        // Its frame `micron` has no static transform.
        assert_eq!(m.mounting.source, MountingSource::Assumed);
    }
}

#[test]
fn ambiguous_topics_are_named() {
    let e = read_mission_with(&fixture("ros2_mcap"), &TopicChoice::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("/ping360/echo") && e.contains("/sonar/raw") && e.contains("--topic sonar"),
        "{e}"
    );
}

#[test]
fn bad_message_names_topic_index_and_field() {
    let e = read_mission_with(&fixture("bad_ping360"), &TopicChoice::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("message 1") && e.contains("/ping360/echo") && e.contains("`angle`"),
        "{e}"
    );
    assert!(e.contains("bad_ping360.mcap"), "{e}");
}

/// `[mounting]` in a config overrides the /tf_static mounting key by key.
#[test]
fn mounting_config_overrides_tf_static() {
    let (m, _) = read(
        "ros2_mcap",
        &[
            "sonar=/ping360/echo",
            "dvl=/dvl/marine",
            "heading=/imu/data",
            "ground_truth=/odometry",
        ],
    );
    let config = echofield_frontend::mounting::MountingConfig {
        sonar_yaw_deg: Some(90.0),
        ..Default::default()
    };
    let out = config.apply(&m).unwrap();
    let s = out.mounting.vehicle_from_sonar;
    assert!(close(s.theta(), std::f64::consts::FRAC_PI_2, 1e-12));
    assert!(close(s.x(), 0.5 + 0.2 * 0.1f64.cos(), 1e-9), "{s:?}");
    assert_eq!(out.mounting.source, MountingSource::Config);
}

/// The Girona underwater caves data set's own messages
/// (`cirs_girona_cala_viuda/RangeImageBeam`, `LinkquestDvl`) beside their
/// standard twins, in a ROS 1 bag: the sonar topic must be chosen, both
/// sonar topics give the same beams, the LinkQuest DVL and the `_ros` Imu
/// are taken by type, the custom Imu and depth are named as skipped, and
/// the mountings come from the `/tf` pairs that never change.
#[test]
fn girona_caves_messages() {
    let e = read_mission_with(&fixture("girona_caves.bag"), &TopicChoice::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("/sonar_micron") && e.contains("/sonar_micron_ros"),
        "{e}"
    );
    let (m, uses) = read("girona_caves.bag", &["sonar=/sonar_micron"]);
    assert_eq!(m.beams.len(), 2);
    for (k, b) in m.beams.iter().enumerate() {
        assert!(close(b.angle_rad, 0.2 * k as f64, 1e-12), "{b:?}");
        assert!(close(b.stamp_s, T0 + 0.12 + 0.1 * k as f64, 1e-6));
        assert_eq!((b.bin_size_m, b.first_bin_range_m), (5.0, 0.0));
        assert_eq!(b.intensities, [0, 50, 191, 7 + k as u8]);
    }
    let (twin, _) = read("girona_caves.bag", &["sonar=/sonar_micron_ros"]);
    for (a, b) in m.beams.iter().zip(&twin.beams) {
        // The LaserScan carries the angle as float32.
        assert!(close(a.angle_rad, b.angle_rad, 1e-6));
        assert_eq!(
            (a.bin_size_m, &a.intensities),
            (b.bin_size_m, &b.intensities)
        );
    }
    assert_eq!(m.dvl.len(), 2);
    // velocityInst (0.3, 0.05, 0.01), z down -> z up; flag 1, then 0.
    let v = m.dvl[0].velocity_mps;
    assert!(close(v.x, 0.3, 1e-12) && close(v.y, -0.05, 1e-12) && close(v.z, -0.01, 1e-12));
    assert!(m.dvl[0].valid && !m.dvl[1].valid);
    assert_eq!(use_of(&uses, "/dvl_linkquest").role, Some("dvl"));
    assert_eq!(use_of(&uses, "/imu_adis_ros").role, Some("heading"));
    assert_eq!(m.attitude.len(), 2);
    // The mountings from the /tf pairs that never change (the moving
    // world -> sparus is not one).
    let s = m.mounting.vehicle_from_sonar;
    assert!(
        close(s.x(), 0.55, 1e-9) && close(s.y(), 0.0, 1e-9) && close(s.theta(), 3.0, 1e-9),
        "{s:?}"
    );
    assert_eq!(m.mounting.source, MountingSource::Recorded);
    let d = m.mounting.vehicle_from_dvl;
    let quarter = std::f64::consts::FRAC_PI_4;
    assert!(
        close(d.x(), -0.4, 1e-9) && close(d.y(), 0.05, 1e-9) && close(d.theta(), quarter, 1e-9),
        "{d:?}"
    );
    let tf = use_of(&uses, "/tf");
    assert_eq!(tf.role, Some("mounting"));
    assert!(
        tf.reason.contains("2 of its 3 frame pairs never change")
            && tf.reason.contains("sparus -> micron")
            && tf.reason.contains("DVL mounting sparus -> dvl"),
        "{tf:?}"
    );
    for skipped in ["/imu_adis", "/depth_sensor"] {
        let u = use_of(&uses, skipped);
        assert_eq!(u.role, None);
        assert!(u.reason.contains("not one echofield reads"), "{u:?}");
    }
}

/// The Ping360's ROS 1 driver writes the angle in gradians.
#[test]
fn ros1_ping360_driver() {
    let (m, uses) = read("ping360_ros1.bag", &[]);
    assert_eq!(
        use_of(&uses, "/ping360_node/sonar/data").role,
        Some("sonar")
    );
    assert_eq!(m.beams.len(), 3);
    for (k, b) in m.beams.iter().enumerate() {
        let expected = k as f64 * std::f64::consts::FRAC_PI_2;
        assert!(close(b.angle_rad, expected, 1e-12), "{b:?}");
        assert_eq!(b.bin_size_m, 2.0);
        assert_eq!(b.intensities, [k as u8, 1, 2, 3, 4]);
    }
}

/// A DVL 1.1 m off the vehicle origin (yawed 0.3 rad) while the vehicle
/// turns at 0.2 rad/s: `/tf_static` gives its mounting, the dead reckoning
/// then removes the lever arm; without the mounting it drifts by metres.
#[test]
fn dvl_lever_arm_from_tf_static() {
    use echofield_frontend::dead_reckoning::{DeadReckoningConfig, run};
    let (m, uses) = read("dvl_lever_arm", &[]);
    let d = m.mounting.vehicle_from_dvl;
    assert!(
        close(d.x(), 1.0, 1e-9) && close(d.y(), -0.5, 1e-9) && close(d.theta(), 0.3, 1e-9),
        "{d:?}"
    );
    let u = use_of(&uses, "/dvl/twist");
    assert!(
        u.reason.contains("DVL mounting base_link -> dvl_link"),
        "{u:?}"
    );
    assert_eq!(use_of(&uses, "/tf_static").role, Some("mounting"));

    // Motion between 1 s and 16 s (half a turn, where a lever arm left in
    // the body-frame velocity displaces the track most: 2·|ω×r|/ω), dead
    // reckoning against the ground truth.
    let motion_error = |mission: &Mission| {
        let nav = run(mission, &DeadReckoningConfig::default()).unwrap();
        let dr = |t: f64| nav.pose_at(T0 + t).unwrap();
        let gt = |i: usize| m.ground_truth[i].world_from_vehicle;
        let rel_dr = dr(1.0).between(&dr(16.0));
        let rel_gt = gt(1).between(&gt(16));
        (rel_dr.translation() - rel_gt.translation()).norm()
    };
    let with_arm = motion_error(&m);
    assert!(with_arm < 0.02, "{with_arm} m");
    let mut without = m.clone();
    // The DVL's yaw kept, its position (the lever arm) dropped.
    without.mounting.vehicle_from_dvl = echofield_graph::Se2::new(0.0, 0.0, d.theta());
    let without_arm = motion_error(&without);
    eprintln!("lever arm: {with_arm} m with the tf_static DVL mounting, {without_arm} m without");
    assert!(without_arm > 1.0, "{without_arm} m");

    // `[mounting]` keys override it.
    let config = echofield_frontend::mounting::MountingConfig {
        dvl_x_m: Some(0.2),
        ..Default::default()
    };
    let out = config.apply(&m).unwrap();
    assert!(close(out.mounting.vehicle_from_dvl.x(), 0.2, 1e-12));
    assert!(close(out.mounting.vehicle_from_dvl.y(), -0.5, 1e-9));
}
