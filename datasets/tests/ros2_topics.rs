//! Choosing topics in ROS 2 recordings (`--topic ROLE=/name`), the summary
//! of what became of each channel, and rosbag2 folders with MCAP storage.

use echofield_datasets::mcap::fixture::random_mission;
use echofield_datasets::mcap::{
    Ros2GroundTruth, TopicChoice, read_mission, read_mission_with, write_mission_ros2,
};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A ROS 2 recording of a random mission with its odometry ground truth
/// also on `/odometry/filtered` (as a navigation filter would publish it)
/// and a topic of a type echofield does not read (`/camera/info`).
fn recording_with_two_odometry_topics(dir: &Path) -> PathBuf {
    let plain = dir.join("plain.mcap");
    write_mission_ros2(
        &plain,
        &random_mission(200, 40, 5),
        Ros2GroundTruth::Odometry,
    )
    .unwrap();
    let bytes = std::fs::read(&plain).unwrap();
    let path = dir.join("two.mcap");
    let mut out = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(&path).unwrap(),
    ))
    .unwrap();
    // Ids of their own: the writer keeps the ids it is given.
    let camera = Arc::new(mcap::Channel {
        id: 101,
        topic: "/camera/info".into(),
        schema: Some(Arc::new(mcap::Schema {
            id: 100,
            name: "sensor_msgs/msg/CameraInfo".into(),
            encoding: "ros2msg".into(),
            data: std::borrow::Cow::Borrowed(b"uint32 height\n"),
        })),
        message_encoding: "cdr".into(),
        metadata: Default::default(),
    });
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        out.write(&message).unwrap();
        if message.channel.topic == "/ground_truth/odom" {
            let mut channel = (*message.channel).clone();
            channel.topic = "/odometry/filtered".into();
            channel.id = 100;
            let copy = mcap::Message {
                channel: Arc::new(channel),
                ..message.clone()
            };
            out.write(&copy).unwrap();
            let info = mcap::Message {
                channel: camera.clone(),
                data: std::borrow::Cow::Borrowed(&[0, 1, 0, 0, 7, 0, 0, 0]),
                ..message
            };
            out.write(&info).unwrap();
        }
    }
    out.finish().unwrap();
    path
}

fn choice(assignments: &[&str]) -> TopicChoice {
    let mut choice = TopicChoice::default();
    for a in assignments {
        choice.assign(a).unwrap();
    }
    choice
}

#[test]
fn two_topics_of_one_type_need_a_choice_and_the_choice_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let path = recording_with_two_odometry_topics(dir.path());
    let e = read_mission(&path).unwrap_err().to_string();
    assert!(
        e.contains("/ground_truth/odom") && e.contains("/odometry/filtered"),
        "{e}"
    );
    assert!(e.contains("--topic ground_truth=/name"), "{e}");

    let (mission, uses) =
        read_mission_with(&path, &choice(&["ground_truth=/ground_truth/odom"])).unwrap();
    let reference = read_mission(&dir.path().join("plain.mcap")).unwrap();
    assert_eq!(mission.ground_truth.len(), reference.ground_truth.len());
    assert_eq!(mission.beams.len(), reference.beams.len());
    let find = |topic: &str| uses.iter().find(|u| u.topic == topic).unwrap();
    assert_eq!(find("/ground_truth/odom").role, Some("ground_truth"));
    assert!(
        find("/ground_truth/odom")
            .reason
            .contains("--topic ground_truth")
    );
    let filtered = find("/odometry/filtered");
    assert_eq!(filtered.role, None);
    assert!(
        filtered.reason.contains("/ground_truth/odom"),
        "{}",
        filtered.reason
    );
    assert_eq!(filtered.messages, reference.ground_truth.len() as u64);
    let camera = find("/camera/info");
    assert_eq!(camera.role, None);
    assert!(camera.reason.contains("sensor_msgs/msg/CameraInfo"));
    assert_eq!(find("/sonar/beam").role, Some("sonar"));
    assert_eq!(find("/sonar/beam").reason, "the only topic of its type");
}

#[test]
fn a_wrong_choice_names_the_topics_and_types() {
    let dir = tempfile::tempdir().unwrap();
    let path = recording_with_two_odometry_topics(dir.path());
    let missing = read_mission_with(&path, &choice(&["ground_truth=/gps"]))
        .unwrap_err()
        .to_string();
    assert!(
        missing.contains("--topic ground_truth=/gps: no such topic"),
        "{missing}"
    );
    assert!(
        missing.contains("/odometry/filtered (nav_msgs/msg/Odometry)"),
        "{missing}"
    );
    let wrong = read_mission_with(&path, &choice(&["sonar=/camera/info"]))
        .unwrap_err()
        .to_string();
    assert!(wrong.contains("sensor_msgs/msg/CameraInfo"), "{wrong}");
    assert!(wrong.contains("echofield_msgs/msg/SonarBeam"), "{wrong}");
    let mut c = TopicChoice::default();
    assert!(c.assign("camera=/x").unwrap_err().contains("unknown role"));
    assert!(c.assign("sonar").unwrap_err().contains("ROLE=/topic"));
    assert!(c.assign("dvl=").unwrap_err().contains("empty"));
    c.assign("ground-truth=/gt").unwrap();
    assert_eq!(c.topics[3].as_deref(), Some("/gt"));
}

#[test]
fn a_rosbag2_folder_with_mcap_storage_reads_like_its_file() {
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("bag");
    std::fs::create_dir(&bag).unwrap();
    let mission = random_mission(200, 40, 9);
    write_mission_ros2(
        &bag.join("bag_0.mcap"),
        &mission,
        Ros2GroundTruth::PoseStamped,
    )
    .unwrap();
    std::fs::write(
        bag.join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  version: 8\n  storage_identifier: mcap\n  \
         compression_format: ''\n  compression_mode: ''\n  relative_file_paths:\n  - bag_0.mcap\n",
    )
    .unwrap();
    let (from_folder, _) = read_mission_with(&bag, &TopicChoice::default()).unwrap();
    let from_file = read_mission(&bag.join("bag_0.mcap")).unwrap();
    assert_eq!(from_folder.beams, from_file.beams);
    assert_eq!(from_folder.dvl, from_file.dvl);
    assert_eq!(from_folder.attitude, from_file.attitude);
    assert_eq!(from_folder.ground_truth, from_file.ground_truth);
}
