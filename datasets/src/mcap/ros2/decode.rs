//! Decoding of the ROS 2 messages into echofield's sensor records.

use super::Ros2Kind;
use crate::mcap::cdr::CdrReader;
use crate::mcap::reader::Decoded;
use crate::mcap::validate::{self, FieldError};
use echofield_frontend::sensors::{Attitude, DvlVelocity, GroundTruthPose, SonarBeam};
use echofield_graph::Se2;
use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};

/// How far a quaternion's norm may be from 1 before it is rejected rather
/// than normalised (drivers write 6-7 significant digits).
const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;

/// Decodes one CDR payload of `kind`. `log_time_ns` replaces a zero header
/// stamp.
pub(crate) fn decode(
    kind: Ros2Kind,
    payload: &[u8],
    log_time_ns: u64,
) -> Result<Decoded, FieldError> {
    let mut r = CdrReader::new(payload)?;
    let stamp_s = header(&mut r, log_time_ns)?;
    match kind {
        Ros2Kind::Imu => imu(&mut r, stamp_s).map(Decoded::Attitude),
        Ros2Kind::TwistWithCovarianceStamped => twist(&mut r, stamp_s).map(Decoded::Dvl),
        Ros2Kind::Odometry => {
            r.string("child_frame_id")?;
            pose(&mut r, stamp_s, "pose.pose").map(Decoded::GroundTruth)
        }
        Ros2Kind::PoseStamped => pose(&mut r, stamp_s, "pose").map(Decoded::GroundTruth),
        Ros2Kind::SonarBeam => sonar_beam(&mut r, stamp_s).map(Decoded::Beam),
    }
}

/// `std_msgs/Header`: returns the stamp in seconds.
fn header(r: &mut CdrReader, log_time_ns: u64) -> Result<f64, FieldError> {
    let sec = r.i32("header.stamp.sec")?;
    let nanosec = r.u32("header.stamp.nanosec")?;
    if nanosec >= 1_000_000_000 {
        return Err(FieldError::new(
            "header.stamp.nanosec",
            format!("{nanosec} is not below 10^9"),
        ));
    }
    r.string("header.frame_id")?;
    let stamp_s = if sec == 0 && nanosec == 0 {
        log_time_ns as f64 / 1e9
    } else {
        f64::from(sec) + f64::from(nanosec) / 1e9
    };
    validate::stamp(stamp_s).map_err(|e| FieldError::new("header.stamp", e.message))?;
    Ok(stamp_s)
}

fn vector3(r: &mut CdrReader, prefix: &str) -> Result<Vector3<f64>, FieldError> {
    let x = r.f64(&format!("{prefix}.x"))?;
    let y = r.f64(&format!("{prefix}.y"))?;
    let z = r.f64(&format!("{prefix}.z"))?;
    for (axis, v) in [("x", x), ("y", y), ("z", z)] {
        if !v.is_finite() {
            return Err(FieldError::new(
                format!("{prefix}.{axis}"),
                format!("value {v} is not finite"),
            ));
        }
    }
    Ok(Vector3::new(x, y, z))
}

/// Reads a `geometry_msgs/Quaternion` and returns (roll, pitch, yaw) of the
/// rotation R = Rz(yaw)·Ry(pitch)·Rx(roll), as ROS's tf does.
fn orientation(r: &mut CdrReader, prefix: &str) -> Result<(f64, f64, f64), FieldError> {
    let xyz = vector3(r, prefix)?;
    let w = r.f64(&format!("{prefix}.w"))?;
    if !w.is_finite() {
        return Err(FieldError::new(
            format!("{prefix}.w"),
            format!("value {w} is not finite"),
        ));
    }
    let q = Quaternion::new(w, xyz.x, xyz.y, xyz.z);
    let norm = q.norm();
    if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
        return Err(FieldError::new(
            prefix,
            format!("quaternion norm {norm} is not 1 (tolerance {QUATERNION_NORM_TOLERANCE})"),
        ));
    }
    Ok(UnitQuaternion::from_quaternion(q).euler_angles())
}

fn imu(r: &mut CdrReader, stamp_s: f64) -> Result<Attitude, FieldError> {
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

fn twist(r: &mut CdrReader, stamp_s: f64) -> Result<DvlVelocity, FieldError> {
    let linear = vector3(r, "twist.twist.linear")?;
    vector3(r, "twist.twist.angular")?;
    let cov = r.f64_array::<36>("twist.covariance")?;
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
        Some(rc) => FieldError::new(format!("twist.covariance{rc}"), e.message),
        None => e,
    })?;
    Ok(dvl)
}

fn pose(r: &mut CdrReader, stamp_s: f64, prefix: &str) -> Result<GroundTruthPose, FieldError> {
    let position = vector3(r, &format!("{prefix}.position"))?;
    let (_, _, yaw_rad) = orientation(r, &format!("{prefix}.orientation"))?;
    Ok(GroundTruthPose {
        stamp_s,
        world_from_vehicle: Se2::new(position.x, position.y, yaw_rad),
    })
}

fn sonar_beam(r: &mut CdrReader, stamp_s: f64) -> Result<SonarBeam, FieldError> {
    let angle_rad = r.f64("angle_rad")?;
    let bin_size_m = r.f64("bin_size_m")?;
    let first_bin_range_m = r.f64("first_bin_range_m")?;
    let intensities = r.bytes("intensities")?.to_vec();
    let beam = SonarBeam {
        stamp_s,
        angle_rad,
        bin_size_m,
        first_bin_range_m,
        intensities,
    };
    validate::beam(&beam)?;
    Ok(beam)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcap::cdr::CdrWriter;

    fn header(w: &mut CdrWriter, sec: i32, nanosec: u32) {
        w.i32(sec);
        w.u32(nanosec);
        w.string("base_link");
    }

    #[test]
    fn pose_stamped_quarter_turn() {
        // A quarter turn about z is the quaternion (0, 0, sin 45°, cos 45°).
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let mut w = CdrWriter::new();
        header(&mut w, 100, 500_000_000);
        w.f64_array(&[3.0, -4.0, 0.0, 0.0, 0.0, h, h]);
        let Decoded::GroundTruth(gt) = decode(Ros2Kind::PoseStamped, &w.into_bytes(), 0).unwrap()
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
            decode(Ros2Kind::PoseStamped, &w.into_bytes(), 7_250_000_000).unwrap()
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
        let err = decode(Ros2Kind::PoseStamped, &w.into_bytes(), 0).unwrap_err();
        assert_eq!(err.field, "pose.orientation");
    }

    #[test]
    fn truncated_twist_names_the_field() {
        let mut w = CdrWriter::new();
        header(&mut w, 1, 0);
        w.f64_array(&[0.1, 0.2]);
        let err = decode(Ros2Kind::TwistWithCovarianceStamped, &w.into_bytes(), 0).unwrap_err();
        assert_eq!(err.field, "twist.twist.linear.z");
    }
}
