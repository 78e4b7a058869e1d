//! The standard ROS messages echofield reads, and how each one's fields
//! become echofield records. Written once for both serialisations: every
//! decoder reads through [`WireReader`] (CDR for ROS 2, the ROS 1 wire
//! format for bags).
//!
//! Definitions were read from the packages' own repositories:
//! - `ping360_sonar_msgs/SonarEcho`: CentraleNantesRobotics/ping360_sonar,
//!   `ping360_sonar_msgs/msg/SonarEcho.msg` at fa53b8f (ROS 2 driver; its
//!   `ping360_node.cpp` fills `angle` from gradians as radians and
//!   `sonar_interface.h` puts sample `i` at `(i+1)·range/number_of_samples`).
//! - `marine_acoustic_msgs/RawSonarImage`, `PingInfo`, `SonarImageData`,
//!   `Dvl`: apl-ocean-engineering/marine_msgs, `marine_acoustic_msgs/msg/`
//!   (Dvl.msg at 139b5d4; RawSonarImage as generated for
//!   `marine_acoustic_msgs`, PingInfo without the older `acoustic_msgs`
//!   array-geometry fields).
//! - `dvl_msgs/DVL` (Water Linked A50 ROS 2 driver, paagutie/dvl_msgs) and
//!   `waterlinked_a50_ros_driver/DVL` (ROS 1, waterlinked/dvl-a50-ros-driver
//!   `msg/DVL.msg`, `msg/DVLBeam.msg` at 15ad219): the ROS 2 one adds
//!   `float64[] covariance` after `fom`.
//! - `ping360_sonar/SonarEcho` (ROS 1 driver): the same repository,
//!   `msg/SonarEcho.msg` at 4ecc256; its `src/ping360_sonar/node.py`
//!   (0957c01) fills `angle` with the head angle in gradians (0-400) although
//!   the message comment says rad.
//! - `cirs_girona_cala_viuda/RangeImageBeam`, `LinkquestDvl` (the Girona
//!   underwater caves data set, Mallios et al., IJRR 2017): the ROS 2 port
//!   of the data set's package, PickNikRobotics/cirs_girona_cala_viuda,
//!   `msg/` at 18ec011, whose field types the ROS 1 bag's data keep (the
//!   port lower-cases the ROS 1 field names, e.g. `velocityInst`).
//! - `sensor_msgs`, `geometry_msgs`, `nav_msgs`, `tf2_msgs`: the common
//!   interfaces of ROS 2 (ROS 1 adds `uint32 seq` to the header).
//!
//! | type | stream | fields used, conventions |
//! |------|--------|--------------------------|
//! | `echofield_msgs/SonarBeam` | sonar | all (`tools/ros/echofield_msgs`) |
//! | `ping360_sonar_msgs/SonarEcho` | sonar | `angle` (rad, the head's own direction of rotation), `range` (m, `uint8`): bin size `range / number_of_samples`, bins from 0; `intensities` (`number_of_samples` of them) |
//! | `ping360_sonar/SonarEcho` (ROS 1) | sonar | as the ROS 2 message, but `angle` in gradians (400 per turn) |
//! | `cirs_girona_cala_viuda/RangeImageBeam` | sonar | `angle_rad`; bins `beam_data` (0-255) over `[0, max_range]` m (`max_range / nbins` m bins), as the data set's `*_ros` LaserScan twin of the same beam; `angle_grad` not read |
//! | `marine_acoustic_msgs/RawSonarImage` | sonar | one beam per `rx_angles[i]` (rad, about the head's z axis); bin size `sound_speed / (2·sample_rate)`, first bin at `sample0` bins; `image.data` row-major by beam, `dtype` uint8 (or uint16, scaled by 1/256); beam stamp `header.stamp + tx_delays[i]` when given |
//! | `sensor_msgs/LaserScan` | sonar | a sweep: ray `i` at `angle_min + i·angle_increment`, stamped `header.stamp + i·time_increment`, becomes a scan-only beam with one bin (255) at its range (`range_max/500` m bins; no bin outside `[range_min, range_max]`); with `angle_increment = 0` and more than one intensity (the Girona underwater caves data set's `*_ros` topics: one beam per message) the message is one beam at `angle_min` whose bins are `intensities` over `[0, range_max]` |
//! | `marine_acoustic_msgs/Dvl` | DVL | `velocity` in the DVL frame of the message (x forward, z along the beams: down), turned to z up (y and z negated); `velocity_covar` (−1: unknown); valid in bottom-track mode |
//! | `dvl_msgs/DVL`, `waterlinked_a50_ros_driver/DVL` | DVL | `velocity` in the A50's frame (x forward, y starboard, z down), turned to z up; `velocity_valid`; `covariance` (ROS 2, 9 values or none) |
//! | `cirs_girona_cala_viuda/LinkquestDvl` | DVL | `velocityInst` (m/s, the NavQuest's instrument frame: x forward, z down), turned to z up; valid when `velocityInstFlag` is 1; no covariance |
//! | `geometry_msgs/TwistWithCovarianceStamped` | DVL | `twist.twist.linear`; the 3x3 linear block of `twist.covariance` |
//! | `nav_msgs/Odometry` | ground truth, or DVL when chosen with `--topic dvl=` | `pose.pose` (x, y, yaw); as DVL `twist.twist.linear` (the `child_frame_id` frame) |
//! | `geometry_msgs/PoseStamped` | ground truth | `pose` (x, y, yaw) |
//! | `sensor_msgs/Imu` | heading | `orientation` → roll, pitch, yaw (ZYX); `angular_velocity.z` → yaw rate |
//! | `geometry_msgs/QuaternionStamped` | heading | `quaternion` → roll, pitch, yaw |
//! | `tf2_msgs/TFMessage` on `/tf_static` | sonar and DVL mountings | see [`super::tf`] |
//!
//! A DVL's velocity is that of its own frame (`header.frame_id`; an
//! Odometry's twist: `child_frame_id`); when `/tf_static` places that
//! frame on the vehicle, its position and yaw become the mission's
//! `vehicle_from_dvl` ([`super::tf`]), with which the dead reckoning
//! rotates the velocity and removes the lever arm.
//!
//! Stamps come from `header.stamp`; a stamp of exactly zero (unset by the
//! driver) falls back to the message's log time. ROS uses REP-103 (x
//! forward, y left, z up; yaw counter-clockwise), echofield's convention.
//! ROS conventions for missing data are honoured: `orientation_covariance[0]
//! = −1` makes an Imu message an error (no attitude), `angular_velocity_covariance[0]
//! = −1` gives no yaw rate, a twist covariance with element 0 = −1 marks the
//! DVL sample invalid, an all-zero covariance means "unknown".
//!
//! A message whose fields make no sense (a NaN angle, a bin count that does
//! not match the data, a non-positive range or sound speed) is an error
//! naming the field; the reader adds the file, topic and message index.

mod attitude;
mod dvl;
mod pose;
mod sonar;
mod transforms;

pub(crate) use transforms::Transform;

use super::wire::{Header, WireReader};
use crate::mcap::validate::{self, FieldError};
use echofield_frontend::sensors::{Attitude, DvlVelocity, GroundTruthPose, PositionFix, SonarBeam};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// How far a quaternion's norm may be from 1 before it is rejected rather
/// than normalised (drivers write 6-7 significant digits).
const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;

/// The sensor streams of a mission, in `Mission` field order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Stream {
    Beam,
    Dvl,
    Attitude,
    GroundTruth,
    /// Position fixes: echofield's own channel only (no ROS type feeds it).
    PositionFix,
}

/// The ROS message types echofield reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MessageType {
    EchofieldSonarBeam,
    Ping360SonarEcho,
    Ping360SonarEchoRos1,
    GironaRangeImageBeam,
    RawSonarImage,
    LaserScan,
    MarineDvl,
    WaterLinkedDvl,
    WaterLinkedDvlRos1,
    LinkquestDvl,
    TwistWithCovarianceStamped,
    Odometry,
    PoseStamped,
    Imu,
    QuaternionStamped,
    TfMessage,
}

impl MessageType {
    pub const ALL: [MessageType; 16] = [
        MessageType::EchofieldSonarBeam,
        MessageType::Ping360SonarEcho,
        MessageType::Ping360SonarEchoRos1,
        MessageType::GironaRangeImageBeam,
        MessageType::RawSonarImage,
        MessageType::LaserScan,
        MessageType::MarineDvl,
        MessageType::WaterLinkedDvl,
        MessageType::WaterLinkedDvlRos1,
        MessageType::LinkquestDvl,
        MessageType::TwistWithCovarianceStamped,
        MessageType::Odometry,
        MessageType::PoseStamped,
        MessageType::Imu,
        MessageType::QuaternionStamped,
        MessageType::TfMessage,
    ];

    /// The type name as ROS 2 spells it (`package/msg/Type`).
    pub fn type_name(self) -> &'static str {
        match self {
            MessageType::EchofieldSonarBeam => "echofield_msgs/msg/SonarBeam",
            MessageType::Ping360SonarEcho => "ping360_sonar_msgs/msg/SonarEcho",
            MessageType::Ping360SonarEchoRos1 => "ping360_sonar/msg/SonarEcho",
            MessageType::GironaRangeImageBeam => "cirs_girona_cala_viuda/msg/RangeImageBeam",
            MessageType::RawSonarImage => "marine_acoustic_msgs/msg/RawSonarImage",
            MessageType::LaserScan => "sensor_msgs/msg/LaserScan",
            MessageType::MarineDvl => "marine_acoustic_msgs/msg/Dvl",
            MessageType::WaterLinkedDvl => "dvl_msgs/msg/DVL",
            MessageType::WaterLinkedDvlRos1 => "waterlinked_a50_ros_driver/msg/DVL",
            MessageType::LinkquestDvl => "cirs_girona_cala_viuda/msg/LinkquestDvl",
            MessageType::TwistWithCovarianceStamped => {
                "geometry_msgs/msg/TwistWithCovarianceStamped"
            }
            MessageType::Odometry => "nav_msgs/msg/Odometry",
            MessageType::PoseStamped => "geometry_msgs/msg/PoseStamped",
            MessageType::Imu => "sensor_msgs/msg/Imu",
            MessageType::QuaternionStamped => "geometry_msgs/msg/QuaternionStamped",
            MessageType::TfMessage => "tf2_msgs/msg/TFMessage",
        }
    }

    /// Recognises a type name with or without the `/msg/` part
    /// (`sensor_msgs/Imu` is the ROS 1 spelling).
    pub fn from_type_name(name: &str) -> Option<Self> {
        let normalised = match name.split('/').collect::<Vec<_>>()[..] {
            [package, ty] => format!("{package}/msg/{ty}"),
            _ => name.to_string(),
        };
        Self::ALL.into_iter().find(|k| k.type_name() == normalised)
    }

    /// The stream a topic of this type feeds when chosen by type alone
    /// (`None`: transforms, read for the mounting).
    pub(crate) fn stream(self) -> Option<Stream> {
        match self {
            MessageType::EchofieldSonarBeam
            | MessageType::Ping360SonarEcho
            | MessageType::Ping360SonarEchoRos1
            | MessageType::GironaRangeImageBeam
            | MessageType::RawSonarImage
            | MessageType::LaserScan => Some(Stream::Beam),
            MessageType::MarineDvl
            | MessageType::WaterLinkedDvl
            | MessageType::WaterLinkedDvlRos1
            | MessageType::LinkquestDvl
            | MessageType::TwistWithCovarianceStamped => Some(Stream::Dvl),
            MessageType::Odometry | MessageType::PoseStamped => Some(Stream::GroundTruth),
            MessageType::Imu | MessageType::QuaternionStamped => Some(Stream::Attitude),
            MessageType::TfMessage => None,
        }
    }

    /// Whether a topic of this type can feed `stream` when the user
    /// chooses it (`--topic`): its own stream, or the DVL for an Odometry
    /// (its twist).
    pub(crate) fn can_feed(self, stream: Stream) -> bool {
        self.stream() == Some(stream) || (self == MessageType::Odometry && stream == Stream::Dvl)
    }
}

/// The records of one decoded message.
#[derive(Debug)]
pub(crate) enum Decoded {
    Beams(Vec<SonarBeam>),
    Dvl(DvlVelocity),
    Attitude(Attitude),
    GroundTruth(GroundTruthPose),
    PositionFix(PositionFix),
    /// Its pose (ground truth) and its twist (as DVL), used by role.
    Odometry(GroundTruthPose, DvlVelocity),
    Transforms(Vec<Transform>),
}

/// Decodes one message of type `ty`; returns its records and the frame
/// its measurement is in: `header.frame_id`, `child_frame_id` for an
/// Odometry (its twist), empty for transforms. `log_time_ns` replaces a
/// zero header stamp.
pub(crate) fn decode<R: WireReader>(
    ty: MessageType,
    r: &mut R,
    log_time_ns: u64,
) -> Result<(Decoded, String), FieldError> {
    if ty == MessageType::TfMessage {
        return transforms::transforms(r).map(|t| (Decoded::Transforms(t), String::new()));
    }
    let header = r.header("header")?;
    let stamp_s = stamp_s(&header, log_time_ns)?;
    let one = |b: SonarBeam| Decoded::Beams(vec![b]);
    let decoded = match ty {
        MessageType::EchofieldSonarBeam => sonar::echofield_beam(r, stamp_s).map(one),
        MessageType::Ping360SonarEcho => {
            sonar::ping360_echo(r, stamp_s, sonar::AngleUnit::Radians).map(one)
        }
        MessageType::Ping360SonarEchoRos1 => {
            sonar::ping360_echo(r, stamp_s, sonar::AngleUnit::Gradians).map(one)
        }
        MessageType::GironaRangeImageBeam => sonar::range_image_beam(r, stamp_s).map(one),
        MessageType::RawSonarImage => sonar::raw_sonar_image(r, stamp_s).map(Decoded::Beams),
        MessageType::LaserScan => sonar::laser_scan(r, stamp_s).map(Decoded::Beams),
        MessageType::MarineDvl => dvl::marine_dvl(r, stamp_s).map(Decoded::Dvl),
        MessageType::WaterLinkedDvl => dvl::water_linked_dvl(r, stamp_s, true).map(Decoded::Dvl),
        MessageType::WaterLinkedDvlRos1 => {
            dvl::water_linked_dvl(r, stamp_s, false).map(Decoded::Dvl)
        }
        MessageType::LinkquestDvl => dvl::linkquest_dvl(r, stamp_s).map(Decoded::Dvl),
        MessageType::TwistWithCovarianceStamped => {
            dvl::twist(r, stamp_s, "twist").map(Decoded::Dvl)
        }
        MessageType::Odometry => {
            let (decoded, child_frame) = pose::odometry(r, stamp_s)?;
            return Ok((decoded, child_frame));
        }
        MessageType::PoseStamped => pose::pose(r, stamp_s, "pose").map(Decoded::GroundTruth),
        MessageType::Imu => attitude::imu(r, stamp_s).map(Decoded::Attitude),
        MessageType::QuaternionStamped => {
            attitude::quaternion_stamped(r, stamp_s).map(Decoded::Attitude)
        }
        // Read without a header, above.
        MessageType::TfMessage => Err(FieldError::new("(type)", "TFMessage has no header")),
    }?;
    Ok((decoded, header.frame_id))
}

fn stamp_s(header: &Header, log_time_ns: u64) -> Result<f64, FieldError> {
    let stamp_s = if header.sec == 0 && header.nanosec == 0 {
        log_time_ns as f64 / 1e9
    } else {
        header.sec as f64 + f64::from(header.nanosec) / 1e9
    };
    validate::stamp(stamp_s).map_err(|e| FieldError::new("header.stamp", e.message))?;
    Ok(stamp_s)
}

pub(super) fn finite(field: &str, v: f64) -> Result<f64, FieldError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(FieldError::new(field, format!("value {v} is not finite")))
    }
}

pub(super) fn positive(field: &str, v: f64) -> Result<f64, FieldError> {
    finite(field, v)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(FieldError::new(
            field,
            format!("value {v} must be positive"),
        ))
    }
}

pub(super) fn vector3<R: WireReader>(r: &mut R, prefix: &str) -> Result<Vector3<f64>, FieldError> {
    let mut v = Vector3::zeros();
    for (i, axis) in ["x", "y", "z"].iter().enumerate() {
        let field = format!("{prefix}.{axis}");
        v[i] = finite(&field, r.f64(&field)?)?;
    }
    Ok(v)
}

/// Reads a `geometry_msgs/Quaternion` as a unit quaternion.
pub(super) fn quaternion<R: WireReader>(
    r: &mut R,
    prefix: &str,
) -> Result<UnitQuaternion<f64>, FieldError> {
    let xyz = vector3(r, prefix)?;
    let field = format!("{prefix}.w");
    let w = finite(&field, r.f64(&field)?)?;
    let q = Quaternion::new(w, xyz.x, xyz.y, xyz.z);
    let norm = q.norm();
    if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
        return Err(FieldError::new(
            prefix,
            format!("quaternion norm {norm} is not 1 (tolerance {QUATERNION_NORM_TOLERANCE})"),
        ));
    }
    Ok(UnitQuaternion::from_quaternion(q))
}

/// (roll, pitch, yaw) of R = Rz(yaw)·Ry(pitch)·Rx(roll), as ROS's tf.
pub(super) fn orientation<R: WireReader>(
    r: &mut R,
    prefix: &str,
) -> Result<(f64, f64, f64), FieldError> {
    Ok(quaternion(r, prefix)?.euler_angles())
}
/// Helpers for the decoders' tests: CDR messages built field by field.
#[cfg(test)]
pub(crate) mod test_support {
    use super::{Decoded, MessageType, decode};
    use crate::mcap::cdr::{CdrReader, CdrWriter};
    use crate::mcap::validate::FieldError;

    /// A ROS 2 `std_msgs/Header` with frame `base_link`.
    pub fn header(w: &mut CdrWriter, sec: i32, nanosec: u32) {
        w.i32(sec);
        w.u32(nanosec);
        w.string("base_link");
    }

    pub fn cdr_decode(
        ty: MessageType,
        bytes: &[u8],
        log_time_ns: u64,
    ) -> Result<Decoded, FieldError> {
        decode(ty, &mut CdrReader::new(bytes)?, log_time_ns).map(|(d, _)| d)
    }

    /// A ROS 1 `std_msgs/Header` (seq 0) with stamp `sec` s and `frame`.
    pub fn ros1_header(d: &mut Vec<u8>, sec: u32, frame: &str) {
        d.extend_from_slice(&0u32.to_le_bytes());
        d.extend_from_slice(&sec.to_le_bytes());
        d.extend_from_slice(&0u32.to_le_bytes());
        d.extend_from_slice(&(frame.len() as u32).to_le_bytes());
        d.extend_from_slice(frame.as_bytes());
    }
}

#[cfg(test)]
mod tests {
    use super::test_support::{cdr_decode, header};
    use super::*;
    use crate::mcap::cdr::CdrWriter;

    #[test]
    fn type_names_round_trip() {
        for ty in MessageType::ALL {
            assert_eq!(MessageType::from_type_name(ty.type_name()), Some(ty));
        }
        assert_eq!(
            MessageType::from_type_name("sensor_msgs/LaserScan"),
            Some(MessageType::LaserScan)
        );
        assert_eq!(
            MessageType::from_type_name("cirs_girona_cala_viuda/RangeImageBeam"),
            Some(MessageType::GironaRangeImageBeam)
        );
        assert_eq!(MessageType::from_type_name("sensor_msgs/msg/Image"), None);
    }

    #[test]
    fn zero_stamp_falls_back_to_log_time() {
        let mut w = CdrWriter::new();
        header(&mut w, 0, 0);
        w.f64_array(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
        let Decoded::GroundTruth(gt) =
            cdr_decode(MessageType::PoseStamped, &w.into_bytes(), 7_250_000_000).unwrap()
        else {
            panic!("wrong stream");
        };
        assert_eq!(gt.stamp_s, 7.25);
    }
}
