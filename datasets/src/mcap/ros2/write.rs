//! Writing a mission as a ROS 2 style MCAP, the way a ROS 2 recorder would
//! store it. echofield itself writes its JSON format; this writer exists to
//! make fixtures and to check interoperability with ROS 2 tools.

use super::{MESSAGE_ENCODING, Ros2Kind, SCHEMA_ENCODING};
use crate::DatasetError;
use crate::mcap::cdr::CdrWriter;
use crate::mcap::validate;
use crate::mcap::writer::McapFile;
use echofield_frontend::sensors::{Attitude, DvlVelocity, GroundTruthPose, Mission, SonarBeam};
use nalgebra::UnitQuaternion;
use std::path::Path;

/// Which message carries the ground truth in a ROS 2 file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ros2GroundTruth {
    /// `nav_msgs/msg/Odometry` on `/ground_truth/odom`.
    Odometry,
    /// `geometry_msgs/msg/PoseStamped` on `/ground_truth/pose`.
    PoseStamped,
}

/// Topics of [`write_mission_ros2`].
const TOPIC_BEAM: &str = "/sonar/beam";
const TOPIC_DVL: &str = "/dvl/twist";
const TOPIC_IMU: &str = "/imu/data";

/// Writes `mission` atomically as ROS 2 messages: beams as
/// `echofield_msgs/msg/SonarBeam` on `/sonar/beam`, DVL as
/// `geometry_msgs/msg/TwistWithCovarianceStamped` on `/dvl/twist`, attitude
/// as `sensor_msgs/msg/Imu` on `/imu/data`, ground truth as chosen.
///
/// What does not survive the trip (documented ROS conventions): the mission
/// name and mounting (no ROS message; read back as the file stem and the
/// identity mounting), the covariance of an invalid DVL sample (element 0 is
/// set to -1 to mark it invalid) and an all-zero covariance (read as none).
/// Stamps go through `sec`/`nanosec`, and attitude and poses through
/// quaternions, so they round-trip to about 1e-9 s and 1e-15 rad.
pub fn write_mission_ros2(
    path: &Path,
    mission: &Mission,
    ground_truth: Ros2GroundTruth,
) -> Result<(), DatasetError> {
    validate::mission(path, mission)?;
    let mut file = McapFile::create(path)?;
    let gt_kind = match ground_truth {
        Ros2GroundTruth::Odometry => (Ros2Kind::Odometry, "/ground_truth/odom"),
        Ros2GroundTruth::PoseStamped => (Ros2Kind::PoseStamped, "/ground_truth/pose"),
    };
    for (stamp_s, stream, i) in time_order(mission) {
        let record = format!(
            "{} {i}",
            ["beam", "dvl", "attitude", "ground_truth"][stream]
        );
        let mut w = CdrWriter::new();
        header(&mut w, stamp_s, FRAMES[stream])
            .map_err(|message| DatasetError::parse(path, &record, "stamp_s", message))?;
        let (kind, topic) = message_body(&mut w, mission, stream, i, gt_kind);
        file.channel(
            topic,
            kind.schema_name(),
            SCHEMA_ENCODING,
            || kind.schema_text(),
            MESSAGE_ENCODING,
        )?;
        file.write(topic, validate::log_time_ns(stamp_s), &w.into_bytes())?;
    }
    file.finish()
}

/// Every record of the mission as `(stamp_s, stream, index)`, streams
/// numbered beam, DVL, attitude, ground truth, sorted by stamp (stable:
/// equal stamps keep the stream order).
fn time_order(mission: &Mission) -> Vec<(f64, usize, usize)> {
    let stamps = [
        mission.beams.iter().map(|r| r.stamp_s).collect::<Vec<_>>(),
        mission.dvl.iter().map(|r| r.stamp_s).collect(),
        mission.attitude.iter().map(|r| r.stamp_s).collect(),
        mission.ground_truth.iter().map(|r| r.stamp_s).collect(),
    ];
    let mut messages: Vec<(f64, usize, usize)> = stamps
        .iter()
        .enumerate()
        .flat_map(|(stream, s)| s.iter().enumerate().map(move |(i, &t)| (t, stream, i)))
        .collect();
    messages.sort_by(|a, b| a.0.total_cmp(&b.0));
    messages
}

/// Writes the body of record `i` of `stream` (after its header) and
/// returns its message kind and topic; ground truth as `gt_kind`.
fn message_body(
    w: &mut CdrWriter,
    mission: &Mission,
    stream: usize,
    i: usize,
    gt_kind: (Ros2Kind, &'static str),
) -> (Ros2Kind, &'static str) {
    match stream {
        0 => {
            sonar_beam(w, &mission.beams[i]);
            (Ros2Kind::SonarBeam, TOPIC_BEAM)
        }
        1 => {
            twist(w, &mission.dvl[i]);
            (Ros2Kind::TwistWithCovarianceStamped, TOPIC_DVL)
        }
        2 => {
            imu(w, &mission.attitude[i]);
            (Ros2Kind::Imu, TOPIC_IMU)
        }
        _ => {
            pose(w, &mission.ground_truth[i], gt_kind.0);
            gt_kind
        }
    }
}

/// `header.frame_id` of each stream.
const FRAMES: [&str; 4] = ["sonar", "dvl", "base_link", "world"];

/// `std_msgs/Header` with the stamp split into whole seconds and nanoseconds.
fn header(w: &mut CdrWriter, stamp_s: f64, frame_id: &str) -> Result<(), String> {
    let mut sec = stamp_s.floor();
    let mut nanosec = ((stamp_s - sec) * 1e9).round();
    if nanosec >= 1e9 {
        sec += 1.0;
        nanosec -= 1e9;
    }
    if sec > f64::from(i32::MAX) {
        return Err(format!(
            "stamp {stamp_s} s does not fit a ROS 2 int32 second count"
        ));
    }
    w.i32(sec as i32);
    w.u32(nanosec as u32);
    w.string(frame_id);
    Ok(())
}

fn quaternion(w: &mut CdrWriter, roll: f64, pitch: f64, yaw: f64) {
    let q = UnitQuaternion::from_euler_angles(roll, pitch, yaw);
    w.f64_array(&[q.i, q.j, q.k, q.w]);
}

fn sonar_beam(w: &mut CdrWriter, beam: &SonarBeam) {
    w.f64(beam.angle_rad);
    w.f64(beam.bin_size_m);
    w.f64(beam.first_bin_range_m);
    w.bytes(&beam.intensities);
}

fn twist(w: &mut CdrWriter, dvl: &DvlVelocity) {
    let v = &dvl.velocity_mps;
    w.f64_array(&[v.x, v.y, v.z, 0.0, 0.0, 0.0]);
    let mut cov = [0.0; 36];
    match (&dvl.covariance, dvl.valid) {
        (_, false) => cov[0] = -1.0,
        (Some(c), true) => {
            for i in 0..3 {
                for j in 0..3 {
                    cov[6 * i + j] = c[(i, j)];
                }
            }
        }
        (None, true) => {}
    }
    w.f64_array(&cov);
}

fn imu(w: &mut CdrWriter, att: &Attitude) {
    quaternion(w, att.roll_rad, att.pitch_rad, att.yaw_rad);
    w.f64_array(&[0.0; 9]); // orientation covariance unknown
    w.f64_array(&[0.0, 0.0, att.yaw_rate_radps.unwrap_or(0.0)]);
    let mut rate_cov = [0.0; 9];
    if att.yaw_rate_radps.is_none() {
        rate_cov[0] = -1.0;
    }
    w.f64_array(&rate_cov);
    w.f64_array(&[0.0; 3]);
    let mut accel_cov = [0.0; 9];
    accel_cov[0] = -1.0; // no linear acceleration
    w.f64_array(&accel_cov);
}

fn pose(w: &mut CdrWriter, gt: &GroundTruthPose, kind: Ros2Kind) {
    let p = &gt.world_from_vehicle;
    if kind == Ros2Kind::Odometry {
        w.string("base_link");
    }
    w.f64_array(&[p.x(), p.y(), 0.0]);
    quaternion(w, 0.0, 0.0, p.theta());
    if kind == Ros2Kind::Odometry {
        w.f64_array(&[0.0; 36]); // pose covariance unknown
        w.f64_array(&[0.0; 6]); // twist
        w.f64_array(&[0.0; 36]);
    }
}
