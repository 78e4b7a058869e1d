//! Ground-truth poses: `geometry_msgs/PoseStamped`, `nav_msgs/Odometry`
//! (whose twist can also feed the DVL).

use super::dvl::twist;
use super::{Decoded, orientation, vector3};
use crate::mcap::validate::FieldError;
use crate::ros::wire::WireReader;
use echofield_frontend::sensors::GroundTruthPose;
use echofield_graph::Se2;

/// A `geometry_msgs/Pose` named `prefix`: x, y (m) and yaw (rad) of
/// `world_from_vehicle`.
pub(super) fn pose<R: WireReader>(
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

/// `nav_msgs/Odometry` after its header: the pose (ground truth) and the
/// twist (a DVL when chosen), with `child_frame_id`, the frame of the
/// twist.
pub(super) fn odometry<R: WireReader>(
    r: &mut R,
    stamp_s: f64,
) -> Result<(Decoded, String), FieldError> {
    let child_frame = r.string("child_frame_id")?;
    let gt = pose(r, stamp_s, "pose.pose")?;
    r.f64_array::<36>("pose.covariance")?;
    let dvl = twist(r, stamp_s, "twist")?;
    Ok((Decoded::Odometry(gt, dvl), child_frame))
}

#[cfg(test)]
mod tests {
    use super::super::test_support::{cdr_decode, header};
    use super::super::{Decoded, MessageType};
    use crate::mcap::cdr::CdrWriter;

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
    fn bad_quaternion_names_the_field() {
        let mut w = CdrWriter::new();
        header(&mut w, 1, 0);
        w.f64_array(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let err = cdr_decode(MessageType::PoseStamped, &w.into_bytes(), 0).unwrap_err();
        assert_eq!(err.field, "pose.orientation");
    }
}
