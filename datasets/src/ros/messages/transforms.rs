//! `tf2_msgs/TFMessage`: the transforms of `/tf_static` (the sonar
//! and DVL mountings, [`crate::ros::tf`]).

use super::{quaternion, vector3};
use crate::mcap::validate::FieldError;
use crate::ros::wire::WireReader;
use nalgebra::{UnitQuaternion, Vector3};

/// One static transform of a `tf2_msgs/TFMessage`: `parent_from_child`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Transform {
    pub parent: String,
    pub child: String,
    pub translation: Vector3<f64>,
    pub rotation: UnitQuaternion<f64>,
}

/// `tf2_msgs/TFMessage`: `geometry_msgs/TransformStamped[] transforms`.
pub(super) fn transforms<R: WireReader>(r: &mut R) -> Result<Vec<Transform>, FieldError> {
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
