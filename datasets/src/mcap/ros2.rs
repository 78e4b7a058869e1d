//! ROS 2 recordings written by echofield ([`write_mission_ros2`]): the
//! message types below, in MCAP files with `cdr` message encoding and
//! `ros2msg` schemas. Reading them, and every other standard message
//! echofield reads, is [`crate::ros::messages`].
//!
//! | schema                                          | stream        | fields used |
//! |-------------------------------------------------|---------------|-------------|
//! | `sensor_msgs/msg/Imu`                           | attitude      | `orientation` → roll, pitch, yaw (ZYX); `angular_velocity.z` → yaw rate |
//! | `geometry_msgs/msg/TwistWithCovarianceStamped`  | DVL           | `twist.twist.linear`; `twist.covariance` (6x6) → its 3x3 linear block |
//! | `nav_msgs/msg/Odometry`                         | ground truth  | `pose.pose.position.{x,y}`, yaw of `pose.pose.orientation` |
//! | `geometry_msgs/msg/PoseStamped`                 | ground truth  | `pose.position.{x,y}`, yaw of `pose.orientation` |
//! | `echofield_msgs/msg/SonarBeam`                  | sonar beams   | all ([`SONAR_BEAM_MSG`]) |
//!
//! Stamps come from `header.stamp` (`sec + nanosec / 10⁹`); a stamp of exactly
//! zero (unset by the driver) falls back to the message's log time. ROS uses
//! REP-103 (x forward, y left, z up; world ENU; yaw counter-clockwise), the
//! same as echofield's vehicle and world frames, so no axis is flipped.
//!
//! ROS conventions for missing data are honoured: `orientation_covariance[0]
//! = -1` (no orientation) makes an Imu message an error (it cannot give an
//! attitude), `angular_velocity_covariance[0] = -1` gives no yaw rate, a twist
//! covariance with element 0 = -1 marks the DVL sample invalid, and an
//! all-zero covariance means "unknown" (no covariance).

mod write;

pub use write::{Ros2GroundTruth, write_mission_ros2};

/// Message encoding of ROS 2 channels.
pub const MESSAGE_ENCODING: &str = "cdr";
/// Schema encoding of ROS 2 channels.
pub const SCHEMA_ENCODING: &str = "ros2msg";

/// The ROS 2 message types echofield reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ros2Kind {
    Imu,
    TwistWithCovarianceStamped,
    Odometry,
    PoseStamped,
    SonarBeam,
}

impl Ros2Kind {
    pub const ALL: [Ros2Kind; 5] = [
        Ros2Kind::Imu,
        Ros2Kind::TwistWithCovarianceStamped,
        Ros2Kind::Odometry,
        Ros2Kind::PoseStamped,
        Ros2Kind::SonarBeam,
    ];

    /// The full ROS 2 type name, as in an MCAP schema record.
    pub fn schema_name(self) -> &'static str {
        match self {
            Ros2Kind::Imu => "sensor_msgs/msg/Imu",
            Ros2Kind::TwistWithCovarianceStamped => "geometry_msgs/msg/TwistWithCovarianceStamped",
            Ros2Kind::Odometry => "nav_msgs/msg/Odometry",
            Ros2Kind::PoseStamped => "geometry_msgs/msg/PoseStamped",
            Ros2Kind::SonarBeam => "echofield_msgs/msg/SonarBeam",
        }
    }

    /// Recognises a schema name, with or without the `/msg/` part
    /// (`sensor_msgs/Imu` is the ROS 1 spelling some tools keep).
    pub fn from_schema_name(name: &str) -> Option<Self> {
        let normalised = match name.split('/').collect::<Vec<_>>()[..] {
            [package, ty] => format!("{package}/msg/{ty}"),
            _ => name.to_string(),
        };
        Self::ALL
            .into_iter()
            .find(|k| k.schema_name() == normalised)
    }

    /// The `ros2msg` schema text: the message definition followed by every
    /// type it uses, each after a `====` separator and a `MSG: ` line.
    pub fn schema_text(self) -> String {
        let (main, deps): (&str, &[&str]) = match self {
            Ros2Kind::Imu => (IMU_MSG, &[HEADER, TIME, QUATERNION, VECTOR3]),
            Ros2Kind::TwistWithCovarianceStamped => (
                TWIST_WITH_COVARIANCE_STAMPED_MSG,
                &[HEADER, TIME, TWIST_WITH_COVARIANCE, TWIST, VECTOR3],
            ),
            Ros2Kind::Odometry => (
                ODOMETRY_MSG,
                &[
                    HEADER,
                    TIME,
                    POSE_WITH_COVARIANCE,
                    POSE,
                    POINT,
                    QUATERNION,
                    TWIST_WITH_COVARIANCE,
                    TWIST,
                    VECTOR3,
                ],
            ),
            Ros2Kind::PoseStamped => (POSE_STAMPED_MSG, &[HEADER, TIME, POSE, POINT, QUATERNION]),
            Ros2Kind::SonarBeam => (SONAR_BEAM_MSG, &[HEADER, TIME]),
        };
        let mut text = main.to_string();
        for dep in deps {
            text.push_str("================================================================================\n");
            text.push_str(dep);
        }
        text
    }
}

/// The definition of `echofield_msgs/msg/SonarBeam`, echofield's sonar beam
/// message for ROS 2 (the file `echofield_msgs/msg/SonarBeam.msg`).
pub const SONAR_BEAM_MSG: &str = "\
# One beam of a mechanically scanned imaging sonar (MSIS).
# header.stamp: time the beam was received. header.frame_id: the sonar head
# frame (x along the transducer at angle 0, z up).
std_msgs/Header header
# Transducer angle in the head frame, rad, counter-clockwise from the head's
# x axis seen from above; not necessarily wrapped.
float64 angle_rad
# Range length of one bin, m (> 0).
float64 bin_size_m
# Range of the start of bin 0, m (>= 0). Bin i covers
# [first_bin_range_m + i*bin_size_m, first_bin_range_m + (i+1)*bin_size_m).
float64 first_bin_range_m
# Echo intensities 0-255, one per bin, nearest bin first (at least one).
uint8[] intensities
";

const IMU_MSG: &str = "\
std_msgs/Header header
geometry_msgs/Quaternion orientation
float64[9] orientation_covariance
geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance
geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance
";

const TWIST_WITH_COVARIANCE_STAMPED_MSG: &str = "\
std_msgs/Header header
geometry_msgs/TwistWithCovariance twist
";

const ODOMETRY_MSG: &str = "\
std_msgs/Header header
string child_frame_id
geometry_msgs/PoseWithCovariance pose
geometry_msgs/TwistWithCovariance twist
";

const POSE_STAMPED_MSG: &str = "\
std_msgs/Header header
geometry_msgs/Pose pose
";

const HEADER: &str = "\
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
";

const TIME: &str = "\
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
";

const QUATERNION: &str = "\
MSG: geometry_msgs/Quaternion
float64 x 0
float64 y 0
float64 z 0
float64 w 1
";

const VECTOR3: &str = "\
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
";

const POINT: &str = "\
MSG: geometry_msgs/Point
float64 x
float64 y
float64 z
";

const POSE: &str = "\
MSG: geometry_msgs/Pose
geometry_msgs/Point position
geometry_msgs/Quaternion orientation
";

const POSE_WITH_COVARIANCE: &str = "\
MSG: geometry_msgs/PoseWithCovariance
geometry_msgs/Pose pose
float64[36] covariance
";

const TWIST: &str = "\
MSG: geometry_msgs/Twist
geometry_msgs/Vector3 linear
geometry_msgs/Vector3 angular
";

const TWIST_WITH_COVARIANCE: &str = "\
MSG: geometry_msgs/TwistWithCovariance
geometry_msgs/Twist twist
float64[36] covariance
";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schema_names_round_trip() {
        for kind in Ros2Kind::ALL {
            assert_eq!(Ros2Kind::from_schema_name(kind.schema_name()), Some(kind));
        }
        assert_eq!(
            Ros2Kind::from_schema_name("sensor_msgs/Imu"),
            Some(Ros2Kind::Imu)
        );
        assert_eq!(Ros2Kind::from_schema_name("sensor_msgs/msg/Image"), None);
    }

    #[test]
    fn schema_text_lists_every_dependency_once() {
        let text = Ros2Kind::Odometry.schema_text();
        for dep in [
            "std_msgs/Header",
            "builtin_interfaces/Time",
            "geometry_msgs/PoseWithCovariance",
            "geometry_msgs/Pose",
            "geometry_msgs/Point",
            "geometry_msgs/Quaternion",
            "geometry_msgs/TwistWithCovariance",
            "geometry_msgs/Twist",
            "geometry_msgs/Vector3",
        ] {
            assert_eq!(text.matches(&format!("MSG: {dep}\n")).count(), 1, "{dep}");
        }
    }
}
