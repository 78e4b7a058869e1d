//! Heading: `sensor_msgs/Imu`, `geometry_msgs/QuaternionStamped`.

use super::{orientation, vector3};
use crate::mcap::validate::{self, FieldError};
use crate::ros::wire::WireReader;
use echofield_frontend::sensors::Attitude;

/// `sensor_msgs/Imu` after its header: orientation (ZYX roll, pitch, yaw)
/// and the body z rate as yaw rate.
pub(super) fn imu<R: WireReader>(r: &mut R, stamp_s: f64) -> Result<Attitude, FieldError> {
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

/// `geometry_msgs/QuaternionStamped` after its header: roll, pitch, yaw;
/// no yaw rate.
pub(super) fn quaternion_stamped<R: WireReader>(
    r: &mut R,
    stamp_s: f64,
) -> Result<Attitude, FieldError> {
    let (roll_rad, pitch_rad, yaw_rad) = orientation(r, "quaternion")?;
    let att = Attitude {
        stamp_s,
        roll_rad,
        pitch_rad,
        yaw_rad,
        yaw_rate_radps: None,
    };
    validate::attitude(&att)?;
    Ok(att)
}
