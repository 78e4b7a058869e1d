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
//! - `sensor_msgs`, `geometry_msgs`, `nav_msgs`, `tf2_msgs`: the common
//!   interfaces of ROS 2 (ROS 1 adds `uint32 seq` to the header).
//!
//! | type | stream | fields used, conventions |
//! |------|--------|--------------------------|
//! | `echofield_msgs/SonarBeam` | sonar | all (`tools/ros/echofield_msgs`) |
//! | `ping360_sonar_msgs/SonarEcho` | sonar | `angle` (rad, the head's own direction of rotation), `range` (m, `uint8`): bin size `range / number_of_samples`, bins from 0; `intensities` (`number_of_samples` of them) |
//! | `marine_acoustic_msgs/RawSonarImage` | sonar | one beam per `rx_angles[i]` (rad, about the head's z axis); bin size `sound_speed / (2·sample_rate)`, first bin at `sample0` bins; `image.data` row-major by beam, `dtype` uint8 (or uint16, scaled by 1/256); beam stamp `header.stamp + tx_delays[i]` when given |
//! | `sensor_msgs/LaserScan` | sonar | a sweep: ray `i` at `angle_min + i·angle_increment`, stamped `header.stamp + i·time_increment`, becomes a scan-only beam with one bin (255) at its range (`range_max/500` m bins; no bin outside `[range_min, range_max]`); with `angle_increment = 0` and more than one intensity (the Girona underwater caves data set's `*_ros` topics: one beam per message) the message is one beam at `angle_min` whose bins are `intensities` over `[0, range_max]` |
//! | `marine_acoustic_msgs/Dvl` | DVL | `velocity` in the DVL frame of the message (x forward, z along the beams: down), turned to z up (y and z negated); `velocity_covar` (−1: unknown); valid in bottom-track mode |
//! | `dvl_msgs/DVL`, `waterlinked_a50_ros_driver/DVL` | DVL | `velocity` in the A50's frame (x forward, y starboard, z down), turned to z up; `velocity_valid`; `covariance` (ROS 2, 9 values or none) |
//! | `geometry_msgs/TwistWithCovarianceStamped` | DVL | `twist.twist.linear`; the 3x3 linear block of `twist.covariance` |
//! | `nav_msgs/Odometry` | ground truth, or DVL when chosen with `--topic dvl=` | `pose.pose` (x, y, yaw); as DVL `twist.twist.linear` (the `child_frame_id` frame) |
//! | `geometry_msgs/PoseStamped` | ground truth | `pose` (x, y, yaw) |
//! | `sensor_msgs/Imu` | heading | `orientation` → roll, pitch, yaw (ZYX); `angular_velocity.z` → yaw rate |
//! | `geometry_msgs/QuaternionStamped` | heading | `quaternion` → roll, pitch, yaw |
//! | `tf2_msgs/TFMessage` on `/tf_static` | sonar mounting | see [`super::tf`] |
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

use super::wire::{Header, WireReader};
use crate::mcap::validate::{self, FieldError};
use echofield_frontend::sensors::{Attitude, DvlVelocity, GroundTruthPose, SonarBeam};
use echofield_graph::Se2;
use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};

/// How far a quaternion's norm may be from 1 before it is rejected rather
/// than normalised (drivers write 6-7 significant digits).
const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;

/// Bins of the beam rebuilt from one LaserScan ray: `range_max` is cut
/// into this many.
const LASER_SCAN_BINS: f64 = 500.0;

/// The sensor streams of a mission, in `Mission` field order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Stream {
    Beam,
    Dvl,
    Attitude,
    GroundTruth,
}

/// The ROS message types echofield reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MessageType {
    EchofieldSonarBeam,
    Ping360SonarEcho,
    RawSonarImage,
    LaserScan,
    MarineDvl,
    WaterLinkedDvl,
    WaterLinkedDvlRos1,
    TwistWithCovarianceStamped,
    Odometry,
    PoseStamped,
    Imu,
    QuaternionStamped,
    TfMessage,
}

impl MessageType {
    pub const ALL: [MessageType; 13] = [
        MessageType::EchofieldSonarBeam,
        MessageType::Ping360SonarEcho,
        MessageType::RawSonarImage,
        MessageType::LaserScan,
        MessageType::MarineDvl,
        MessageType::WaterLinkedDvl,
        MessageType::WaterLinkedDvlRos1,
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
            MessageType::RawSonarImage => "marine_acoustic_msgs/msg/RawSonarImage",
            MessageType::LaserScan => "sensor_msgs/msg/LaserScan",
            MessageType::MarineDvl => "marine_acoustic_msgs/msg/Dvl",
            MessageType::WaterLinkedDvl => "dvl_msgs/msg/DVL",
            MessageType::WaterLinkedDvlRos1 => "waterlinked_a50_ros_driver/msg/DVL",
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
            | MessageType::RawSonarImage
            | MessageType::LaserScan => Some(Stream::Beam),
            MessageType::MarineDvl
            | MessageType::WaterLinkedDvl
            | MessageType::WaterLinkedDvlRos1
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

/// One static transform of a `tf2_msgs/TFMessage`: `parent_from_child`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Transform {
    pub parent: String,
    pub child: String,
    pub translation: Vector3<f64>,
    pub rotation: UnitQuaternion<f64>,
}

/// The records of one decoded message.
#[derive(Debug)]
pub(crate) enum Decoded {
    Beams(Vec<SonarBeam>),
    Dvl(DvlVelocity),
    Attitude(Attitude),
    GroundTruth(GroundTruthPose),
    /// Its pose (ground truth) and its twist (as DVL), used by role.
    Odometry(GroundTruthPose, DvlVelocity),
    Transforms(Vec<Transform>),
}

/// Decodes one message of type `ty`; returns its records and its
/// `header.frame_id` (empty for transforms). `log_time_ns` replaces a
/// zero header stamp.
pub(crate) fn decode<R: WireReader>(
    ty: MessageType,
    r: &mut R,
    log_time_ns: u64,
) -> Result<(Decoded, String), FieldError> {
    if ty == MessageType::TfMessage {
        return transforms(r).map(|t| (Decoded::Transforms(t), String::new()));
    }
    let header = r.header("header")?;
    let stamp_s = stamp_s(&header, log_time_ns)?;
    let decoded = match ty {
        MessageType::EchofieldSonarBeam => {
            echofield_beam(r, stamp_s).map(|b| Decoded::Beams(vec![b]))
        }
        MessageType::Ping360SonarEcho => ping360_echo(r, stamp_s).map(|b| Decoded::Beams(vec![b])),
        MessageType::RawSonarImage => raw_sonar_image(r, stamp_s).map(Decoded::Beams),
        MessageType::LaserScan => laser_scan(r, stamp_s).map(Decoded::Beams),
        MessageType::MarineDvl => marine_dvl(r, stamp_s).map(Decoded::Dvl),
        MessageType::WaterLinkedDvl => water_linked_dvl(r, stamp_s, true).map(Decoded::Dvl),
        MessageType::WaterLinkedDvlRos1 => water_linked_dvl(r, stamp_s, false).map(Decoded::Dvl),
        MessageType::TwistWithCovarianceStamped => twist(r, stamp_s, "twist").map(Decoded::Dvl),
        MessageType::Odometry => {
            r.string("child_frame_id")?;
            let gt = pose(r, stamp_s, "pose.pose")?;
            r.f64_array::<36>("pose.covariance")?;
            let dvl = twist(r, stamp_s, "twist")?;
            Ok(Decoded::Odometry(gt, dvl))
        }
        MessageType::PoseStamped => pose(r, stamp_s, "pose").map(Decoded::GroundTruth),
        MessageType::Imu => imu(r, stamp_s).map(Decoded::Attitude),
        MessageType::QuaternionStamped => {
            let (roll_rad, pitch_rad, yaw_rad) = orientation(r, "quaternion")?;
            let att = Attitude {
                stamp_s,
                roll_rad,
                pitch_rad,
                yaw_rad,
                yaw_rate_radps: None,
            };
            validate::attitude(&att)?;
            Ok(Decoded::Attitude(att))
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

fn finite(field: &str, v: f64) -> Result<f64, FieldError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(FieldError::new(field, format!("value {v} is not finite")))
    }
}

fn positive(field: &str, v: f64) -> Result<f64, FieldError> {
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

fn vector3<R: WireReader>(r: &mut R, prefix: &str) -> Result<Vector3<f64>, FieldError> {
    let mut v = Vector3::zeros();
    for (i, axis) in ["x", "y", "z"].iter().enumerate() {
        let field = format!("{prefix}.{axis}");
        v[i] = finite(&field, r.f64(&field)?)?;
    }
    Ok(v)
}

/// Reads a `geometry_msgs/Quaternion` as a unit quaternion.
fn quaternion<R: WireReader>(r: &mut R, prefix: &str) -> Result<UnitQuaternion<f64>, FieldError> {
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
fn orientation<R: WireReader>(r: &mut R, prefix: &str) -> Result<(f64, f64, f64), FieldError> {
    Ok(quaternion(r, prefix)?.euler_angles())
}

fn echofield_beam<R: WireReader>(r: &mut R, stamp_s: f64) -> Result<SonarBeam, FieldError> {
    let beam = SonarBeam {
        stamp_s,
        angle_rad: r.f64("angle_rad")?,
        bin_size_m: r.f64("bin_size_m")?,
        first_bin_range_m: r.f64("first_bin_range_m")?,
        intensities: r.byte_seq("intensities")?,
    };
    validate::beam(&beam)?;
    Ok(beam)
}

fn ping360_echo<R: WireReader>(r: &mut R, stamp_s: f64) -> Result<SonarBeam, FieldError> {
    let angle_rad = finite("angle", f64::from(r.f32("angle")?))?;
    r.u8("gain")?;
    let samples = r.u16("number_of_samples")?;
    r.u16("transmit_frequency")?;
    r.u16("speed_of_sound")?;
    let range_m = positive("range", f64::from(r.u8("range")?))?;
    let intensities = r.byte_seq("intensities")?;
    if intensities.is_empty() || intensities.len() != usize::from(samples) {
        return Err(FieldError::new(
            "intensities",
            format!(
                "{} intensities, but number_of_samples is {samples}",
                intensities.len()
            ),
        ));
    }
    let beam = SonarBeam {
        stamp_s,
        angle_rad,
        bin_size_m: range_m / f64::from(samples),
        first_bin_range_m: 0.0,
        intensities,
    };
    validate::beam(&beam)?;
    Ok(beam)
}

/// `SonarImageData.dtype` values read.
const DTYPE_UINT8: u32 = 0;
const DTYPE_UINT16: u32 = 2;

fn raw_sonar_image<R: WireReader>(r: &mut R, stamp_s: f64) -> Result<Vec<SonarBeam>, FieldError> {
    r.f32("ping_info.frequency")?;
    let sound_speed = positive(
        "ping_info.sound_speed",
        f64::from(r.f32("ping_info.sound_speed")?),
    )?;
    r.f32_seq("ping_info.tx_beamwidths")?;
    r.f32_seq("ping_info.rx_beamwidths")?;
    let sample_rate = positive("sample_rate", f64::from(r.f32("sample_rate")?))?;
    let samples = r.u32("samples_per_beam")? as usize;
    let sample0 = r.u32("sample0")?;
    let tx_delays = r.f32_seq("tx_delays")?;
    r.f32_seq("tx_angles")?;
    let rx_angles = r.f32_seq("rx_angles")?;
    let big_endian = r.bool("image.is_bigendian")?;
    let dtype = r.u32("image.dtype")?;
    let beam_count = r.u32("image.beam_count")? as usize;
    let data = r.byte_seq("image.data")?;
    let bytes = match dtype {
        DTYPE_UINT8 => 1,
        DTYPE_UINT16 => 2,
        other => {
            return Err(FieldError::new(
                "image.dtype",
                format!("dtype {other} is not read (uint8 = 0, uint16 = 2)"),
            ));
        }
    };
    if samples == 0 || beam_count == 0 {
        return Err(FieldError::new(
            "samples_per_beam",
            format!("{samples} samples per beam in {beam_count} beams: no bins"),
        ));
    }
    if rx_angles.len() != beam_count {
        return Err(FieldError::new(
            "rx_angles",
            format!("{} angles for {beam_count} beams", rx_angles.len()),
        ));
    }
    if data.len() != beam_count * samples * bytes {
        return Err(FieldError::new(
            "image.data",
            format!(
                "{} bytes, but {beam_count} beams x {samples} samples x {bytes} bytes = {}",
                data.len(),
                beam_count * samples * bytes
            ),
        ));
    }
    let bin_size_m = sound_speed / (2.0 * sample_rate);
    let mut beams = Vec::with_capacity(beam_count);
    for (i, row) in data.chunks_exact(samples * bytes).enumerate() {
        let angle_rad = finite(&format!("rx_angles[{i}]"), f64::from(rx_angles[i]))?;
        let delay_s = match tx_delays.get(i) {
            Some(&d) if tx_delays.len() == beam_count => {
                finite(&format!("tx_delays[{i}]"), f64::from(d))?
            }
            _ => 0.0,
        };
        let intensities = match bytes {
            1 => row.to_vec(),
            _ => row
                .chunks_exact(2)
                .map(|b| {
                    let v = if big_endian {
                        u16::from_be_bytes([b[0], b[1]])
                    } else {
                        u16::from_le_bytes([b[0], b[1]])
                    };
                    (v >> 8) as u8
                })
                .collect(),
        };
        let beam = SonarBeam {
            stamp_s: stamp_s + delay_s,
            angle_rad,
            bin_size_m,
            first_bin_range_m: f64::from(sample0) * bin_size_m,
            intensities,
        };
        validate::beam(&beam)?;
        beams.push(beam);
    }
    Ok(beams)
}

fn laser_scan<R: WireReader>(r: &mut R, stamp_s: f64) -> Result<Vec<SonarBeam>, FieldError> {
    let angle_min = finite("angle_min", f64::from(r.f32("angle_min")?))?;
    finite("angle_max", f64::from(r.f32("angle_max")?))?;
    let increment = finite("angle_increment", f64::from(r.f32("angle_increment")?))?;
    let time_increment = finite("time_increment", f64::from(r.f32("time_increment")?))?;
    r.f32("scan_time")?;
    let range_min = finite("range_min", f64::from(r.f32("range_min")?))?;
    let range_max = positive("range_max", f64::from(r.f32("range_max")?))?;
    let ranges = r.f32_seq("ranges")?;
    let intensities = r.f32_seq("intensities")?;
    if increment == 0.0 && intensities.len() > 1 {
        // One beam whose bins are the intensities (Girona caves layout).
        let bins = intensities
            .iter()
            .enumerate()
            .map(|(i, &v)| {
                let v = finite(&format!("intensities[{i}]"), f64::from(v))?;
                if !(0.0..=255.0).contains(&v) {
                    return Err(FieldError::new(
                        format!("intensities[{i}]"),
                        format!("{v} is outside 0-255 (an intensity per bin in a one-beam scan)"),
                    ));
                }
                Ok(v.round() as u8)
            })
            .collect::<Result<Vec<u8>, _>>()?;
        let beam = SonarBeam {
            stamp_s,
            angle_rad: angle_min,
            bin_size_m: range_max / bins.len() as f64,
            first_bin_range_m: 0.0,
            intensities: bins,
        };
        validate::beam(&beam)?;
        return Ok(vec![beam]);
    }
    if ranges.is_empty() {
        return Err(FieldError::new(
            "ranges",
            "no range (and no one-beam intensities)",
        ));
    }
    if !intensities.is_empty() && intensities.len() != ranges.len() {
        return Err(FieldError::new(
            "intensities",
            format!(
                "{} intensities for {} ranges",
                intensities.len(),
                ranges.len()
            ),
        ));
    }
    let bin_size_m = range_max / LASER_SCAN_BINS;
    let n_bins = LASER_SCAN_BINS as usize + 1;
    let mut beams = Vec::with_capacity(ranges.len());
    for (i, &range) in ranges.iter().enumerate() {
        let range = f64::from(range);
        let mut bins = vec![0u8; n_bins];
        // NaN, ±inf and out-of-limit values are "no return" (REP-117).
        if range.is_finite() && range > 0.0 && range >= range_min && range <= range_max {
            let bin = ((range / bin_size_m) as usize).min(n_bins - 1);
            bins[bin] = 255;
        }
        let beam = SonarBeam {
            stamp_s: stamp_s + i as f64 * time_increment,
            angle_rad: angle_min + i as f64 * increment,
            bin_size_m,
            first_bin_range_m: 0.0,
            intensities: bins,
        };
        validate::beam(&beam).map_err(|e| FieldError::new(format!("ranges[{i}]"), e.message))?;
        beams.push(beam);
    }
    Ok(beams)
}

/// A DVL velocity in a frame with z down (y starboard) turned to
/// echofield's z up (y port), with its covariance.
fn z_down_to_up(
    v: Vector3<f64>,
    cov: Option<Matrix3<f64>>,
) -> (Vector3<f64>, Option<Matrix3<f64>>) {
    let s = Vector3::new(1.0, -1.0, -1.0);
    (
        v.component_mul(&s),
        cov.map(|c| Matrix3::from_fn(|i, j| s[i] * s[j] * c[(i, j)])),
    )
}

/// A row-major 3x3 covariance: `None` when unknown (−1 first, all zero).
fn covariance3(values: &[f64], field: &str) -> Result<Option<Matrix3<f64>>, FieldError> {
    if values.first() == Some(&-1.0) || values.iter().all(|&c| c == 0.0) {
        return Ok(None);
    }
    for (i, &c) in values.iter().enumerate() {
        finite(&format!("{field}[{i}]"), c)?;
    }
    Ok(Some(Matrix3::from_fn(|i, j| values[3 * i + j])))
}

fn checked_dvl(dvl: DvlVelocity) -> Result<DvlVelocity, FieldError> {
    validate::dvl(&dvl)?;
    Ok(dvl)
}

/// `DVL_MODE_BOTTOM` of `marine_acoustic_msgs/Dvl`.
const DVL_MODE_BOTTOM: u8 = 1;

fn marine_dvl<R: WireReader>(r: &mut R, stamp_s: f64) -> Result<DvlVelocity, FieldError> {
    let mode = r.u8("velocity_mode")?;
    r.u8("dvl_type")?;
    let velocity = vector3(r, "velocity")?;
    let cov = r.f64_array::<9>("velocity_covar")?;
    let (velocity_mps, covariance) = z_down_to_up(velocity, covariance3(&cov, "velocity_covar")?);
    checked_dvl(DvlVelocity {
        stamp_s,
        velocity_mps,
        // Water-track velocities are not over the ground.
        valid: mode == DVL_MODE_BOTTOM,
        covariance,
    })
}

fn water_linked_dvl<R: WireReader>(
    r: &mut R,
    stamp_s: f64,
    with_covariance: bool,
) -> Result<DvlVelocity, FieldError> {
    r.f64("time")?;
    let velocity = vector3(r, "velocity")?;
    r.f64("fom")?;
    let cov = if with_covariance {
        let n = r.seq_len("covariance", 8)?;
        let values = (0..n)
            .map(|i| r.f64(&format!("covariance[{i}]")))
            .collect::<Result<Vec<_>, _>>()?;
        match n {
            0 => None,
            9 => covariance3(&values, "covariance")?,
            _ => {
                return Err(FieldError::new(
                    "covariance",
                    format!("{n} values (a 3x3 covariance has 9, or none)"),
                ));
            }
        }
    } else {
        None
    };
    r.f64("altitude")?;
    // DVLBeam: int64 id, float64 velocity, distance, rssi, nsd, bool valid.
    let beams = r.seq_len("beams", 41)?;
    for i in 0..beams {
        r.i64(&format!("beams[{i}].id"))?;
        for f in ["velocity", "distance", "rssi", "nsd"] {
            r.f64(&format!("beams[{i}].{f}"))?;
        }
        r.bool(&format!("beams[{i}].valid"))?;
    }
    let valid = r.bool("velocity_valid")?;
    let (velocity_mps, covariance) = z_down_to_up(velocity, cov);
    checked_dvl(DvlVelocity {
        stamp_s,
        velocity_mps,
        valid,
        covariance,
    })
}

/// A `geometry_msgs/TwistWithCovariance` named `prefix`.
fn twist<R: WireReader>(r: &mut R, stamp_s: f64, prefix: &str) -> Result<DvlVelocity, FieldError> {
    let linear = vector3(r, &format!("{prefix}.twist.linear"))?;
    vector3(r, &format!("{prefix}.twist.angular"))?;
    let cov_field = format!("{prefix}.covariance");
    let cov = r.f64_array::<36>(&cov_field)?;
    let valid = cov[0] != -1.0;
    let covariance = if !valid || cov.iter().all(|&c| c == 0.0) {
        None
    } else {
        // Rows and columns 0-2 of the row-major 6x6 are (vx, vy, vz).
        Some(Matrix3::from_fn(|i, j| cov[6 * i + j]))
    };
    let dvl = DvlVelocity {
        stamp_s,
        velocity_mps: linear,
        valid,
        covariance,
    };
    validate::dvl(&dvl).map_err(|e| match e.field.strip_prefix("covariance") {
        Some(rc) => FieldError::new(format!("{cov_field}{rc}"), e.message),
        None => e,
    })?;
    Ok(dvl)
}

fn pose<R: WireReader>(
    r: &mut R,
    stamp_s: f64,
    prefix: &str,
) -> Result<GroundTruthPose, FieldError> {
    let position = vector3(r, &format!("{prefix}.position"))?;
    let (_, _, yaw_rad) = orientation(r, &format!("{prefix}.orientation"))?;
    Ok(GroundTruthPose {
        stamp_s,
        world_from_vehicle: Se2::new(position.x, position.y, yaw_rad),
    })
}

fn imu<R: WireReader>(r: &mut R, stamp_s: f64) -> Result<Attitude, FieldError> {
    let (roll_rad, pitch_rad, yaw_rad) = orientation(r, "orientation")?;
    let orientation_cov = r.f64_array::<9>("orientation_covariance")?;
    if orientation_cov[0] == -1.0 {
        return Err(FieldError::new(
            "orientation_covariance[0]",
            "-1 marks an Imu message without orientation, which gives no attitude",
        ));
    }
    let angular_velocity = vector3(r, "angular_velocity")?;
    let angular_velocity_cov = r.f64_array::<9>("angular_velocity_covariance")?;
    // Body z rate; equal to the yaw rate when the vehicle is level (an AUV's
    // roll and pitch are small).
    let yaw_rate_radps = (angular_velocity_cov[0] != -1.0).then_some(angular_velocity.z);
    let att = Attitude {
        stamp_s,
        roll_rad,
        pitch_rad,
        yaw_rad,
        yaw_rate_radps,
    };
    validate::attitude(&att)?;
    Ok(att)
}

/// `tf2_msgs/TFMessage`: `geometry_msgs/TransformStamped[] transforms`.
fn transforms<R: WireReader>(r: &mut R) -> Result<Vec<Transform>, FieldError> {
    let n = r.seq_len("transforms", 8)?;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let prefix = format!("transforms[{i}]");
        let header = r.header(&format!("{prefix}.header"))?;
        let child = r.string(&format!("{prefix}.child_frame_id"))?;
        let translation = vector3(r, &format!("{prefix}.transform.translation"))?;
        let rotation = quaternion(r, &format!("{prefix}.transform.rotation"))?;
        out.push(Transform {
            parent: header.frame_id,
            child,
            translation,
            rotation,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcap::cdr::{CdrReader, CdrWriter};

    fn header(w: &mut CdrWriter, sec: i32, nanosec: u32) {
        w.i32(sec);
        w.u32(nanosec);
        w.string("base_link");
    }

    fn cdr_decode(ty: MessageType, bytes: &[u8], log_time_ns: u64) -> Result<Decoded, FieldError> {
        decode(ty, &mut CdrReader::new(bytes)?, log_time_ns).map(|(d, _)| d)
    }

    #[test]
    fn type_names_round_trip() {
        for ty in MessageType::ALL {
            assert_eq!(MessageType::from_type_name(ty.type_name()), Some(ty));
        }
        assert_eq!(
            MessageType::from_type_name("sensor_msgs/LaserScan"),
            Some(MessageType::LaserScan)
        );
        assert_eq!(MessageType::from_type_name("sensor_msgs/msg/Image"), None);
    }

    #[test]
    fn pose_stamped_quarter_turn() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let mut w = CdrWriter::new();
        header(&mut w, 100, 500_000_000);
        w.f64_array(&[3.0, -4.0, 0.0, 0.0, 0.0, h, h]);
        let Decoded::GroundTruth(gt) =
            cdr_decode(MessageType::PoseStamped, &w.into_bytes(), 0).unwrap()
        else {
            panic!("wrong stream");
        };
        assert_eq!(gt.stamp_s, 100.5);
        assert_eq!(
            (gt.world_from_vehicle.x(), gt.world_from_vehicle.y()),
            (3.0, -4.0)
        );
        assert!((gt.world_from_vehicle.theta() - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
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

    #[test]
    fn bad_quaternion_names_the_field() {
        let mut w = CdrWriter::new();
        header(&mut w, 1, 0);
        w.f64_array(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let err = cdr_decode(MessageType::PoseStamped, &w.into_bytes(), 0).unwrap_err();
        assert_eq!(err.field, "pose.orientation");
    }

    #[test]
    fn truncated_twist_names_the_field() {
        let mut w = CdrWriter::new();
        header(&mut w, 1, 0);
        w.f64_array(&[0.1, 0.2]);
        let err =
            cdr_decode(MessageType::TwistWithCovarianceStamped, &w.into_bytes(), 0).unwrap_err();
        assert_eq!(err.field, "twist.twist.linear.z");
    }

    /// A LaserScan sweep in ROS 1 serialisation: 3 rays, the middle one
    /// without a return.
    #[test]
    fn laser_scan_sweep_in_ros1() {
        let mut d = Vec::new();
        d.extend_from_slice(&0u32.to_le_bytes()); // seq
        d.extend_from_slice(&10u32.to_le_bytes());
        d.extend_from_slice(&0u32.to_le_bytes());
        d.extend_from_slice(&5u32.to_le_bytes());
        d.extend_from_slice(b"sonar");
        for v in [0.0f32, 0.2, 0.1, 0.01, 1.0, 0.5, 10.0] {
            d.extend_from_slice(&v.to_le_bytes());
        }
        d.extend_from_slice(&3u32.to_le_bytes());
        for v in [4.0f32, f32::INFINITY, 9.99] {
            d.extend_from_slice(&v.to_le_bytes());
        }
        d.extend_from_slice(&0u32.to_le_bytes()); // no intensities
        let mut r = super::super::wire::Ros1Reader::new(&d);
        let (Decoded::Beams(beams), frame) = decode(MessageType::LaserScan, &mut r, 0).unwrap()
        else {
            panic!("wrong stream");
        };
        assert_eq!(frame, "sonar");
        assert_eq!(beams.len(), 3);
        assert!((beams[2].angle_rad - 0.2).abs() < 1e-6);
        assert!((beams[2].stamp_s - 10.02).abs() < 1e-6);
        let lit = |b: &SonarBeam| b.intensities.iter().position(|&v| v == 255);
        // 4 m in 0.02 m bins: bin 200.
        assert_eq!(lit(&beams[0]), Some(200));
        assert_eq!(lit(&beams[1]), None);
        assert_eq!(lit(&beams[2]), Some(499));
    }

    #[test]
    fn ping360_bin_count_mismatch_names_the_field() {
        let mut w = CdrWriter::new();
        header(&mut w, 1, 0);
        w.f32(0.5);
        w.u8(3);
        w.u16(4); // number_of_samples
        w.u16(750);
        w.u16(1500);
        w.u8(10);
        w.bytes(&[1, 2, 3]);
        let err = cdr_decode(MessageType::Ping360SonarEcho, &w.into_bytes(), 0).unwrap_err();
        assert_eq!(err.field, "intensities");
    }

    #[test]
    fn raw_sonar_image_data_length_mismatch_names_the_field() {
        let mut w = CdrWriter::new();
        header(&mut w, 1, 0);
        // ping_info: frequency, sound_speed, no beam widths.
        w.f32(700e3);
        w.f32(1500.0);
        w.u32(0);
        w.u32(0);
        w.f32(7500.0); // sample_rate
        w.u32(4); // samples_per_beam
        w.u32(0); // sample0
        w.u32(0); // tx_delays
        w.u32(0); // tx_angles
        w.u32(1); // rx_angles
        w.f32(0.5);
        w.u8(0); // is_bigendian
        w.u32(0); // dtype uint8
        w.u32(1); // beam_count
        w.bytes(&[1, 2, 3]); // 3 bytes for 4 samples
        let err = cdr_decode(MessageType::RawSonarImage, &w.into_bytes(), 0).unwrap_err();
        assert_eq!(err.field, "image.data");
    }
}
