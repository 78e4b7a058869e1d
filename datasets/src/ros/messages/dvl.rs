//! DVL velocities: `marine_acoustic_msgs/Dvl`, the Water Linked A50's
//! `DVL` (ROS 2 and ROS 1), the Girona caves data set's `LinkquestDvl`,
//! `geometry_msgs/TwistWithCovarianceStamped` (and an Odometry's twist).
//! Each velocity is in the frame of its message, turned to z up; that
//! frame's place on the vehicle comes from `/tf_static` ([`crate::ros::tf`]).

use super::{finite, vector3};
use crate::mcap::validate::{self, FieldError};
use crate::ros::wire::WireReader;
use echofield_frontend::sensors::DvlVelocity;
use nalgebra::{Matrix3, Vector3};

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

pub(super) fn marine_dvl<R: WireReader>(
    r: &mut R,
    stamp_s: f64,
) -> Result<DvlVelocity, FieldError> {
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

pub(super) fn water_linked_dvl<R: WireReader>(
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
pub(super) fn twist<R: WireReader>(
    r: &mut R,
    stamp_s: f64,
    prefix: &str,
) -> Result<DvlVelocity, FieldError> {
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

/// `velocityInstFlag` of a good instrument-frame velocity (COLA2's
/// simulated NavQuest writes 1 with every velocity it publishes).
const LINKQUEST_FLAG_GOOD: i32 = 1;

/// `cirs_girona_cala_viuda/LinkquestDvl` after its header (LinkQuest
/// NavQuest 600): `velocityInst` (m/s, the instrument frame, z down along
/// the beams) turned to z up, valid when `velocityInstFlag` is 1. The
/// fields after the flag (earth-frame and water-track velocities, attitude,
/// environment, the raw sentence) are not read.
pub(super) fn linkquest_dvl<R: WireReader>(
    r: &mut R,
    stamp_s: f64,
) -> Result<DvlVelocity, FieldError> {
    r.string("errcode")?;
    for i in 0..4 {
        r.i32(&format!("datagood[{i}]"))?;
    }
    for field in [
        "altitudebeam",
        "bottomvelocitybeam",
        "watervelocitybeam",
        "watervelocitycredit",
    ] {
        r.f64_array::<4>(field)?;
    }
    let velocity = vector3_array(r, "velocityinst")?;
    let flag = r.i32("velocityinstflag")?;
    let (velocity_mps, _) = z_down_to_up(velocity, None);
    checked_dvl(DvlVelocity {
        stamp_s,
        velocity_mps,
        valid: flag == LINKQUEST_FLAG_GOOD,
        covariance: None,
    })
}

/// A `float64[3]` as a vector; a non-finite value is an error naming it.
fn vector3_array<R: WireReader>(r: &mut R, field: &str) -> Result<Vector3<f64>, FieldError> {
    let v = r.f64_array::<3>(field)?;
    for (i, x) in v.iter().enumerate() {
        finite(&format!("{field}[{i}]"), *x)?;
    }
    Ok(Vector3::from(v))
}

#[cfg(test)]
mod tests {
    use super::super::test_support::{cdr_decode, header, ros1_header};
    use super::super::{Decoded, MessageType, decode};
    use crate::mcap::cdr::CdrWriter;
    use crate::ros::wire::Ros1Reader;

    #[test]
    fn truncated_twist_names_the_field() {
        let mut w = CdrWriter::new();
        header(&mut w, 1, 0);
        w.f64_array(&[0.1, 0.2]);
        let err =
            cdr_decode(MessageType::TwistWithCovarianceStamped, &w.into_bytes(), 0).unwrap_err();
        assert_eq!(err.field, "twist.twist.linear.z");
    }

    /// A LinkquestDvl in ROS 1 serialisation, up to and past the fields read.
    fn linkquest_ros1(velocity: [f64; 3], flag: i32) -> Vec<u8> {
        let mut d = Vec::new();
        ros1_header(&mut d, 9, "dvl");
        d.extend_from_slice(&2u32.to_le_bytes());
        d.extend_from_slice(b"ok");
        for _ in 0..4 {
            d.extend_from_slice(&1i32.to_le_bytes());
        }
        for _ in 0..16 {
            d.extend_from_slice(&0.5f64.to_le_bytes());
        }
        for v in velocity {
            d.extend_from_slice(&v.to_le_bytes());
        }
        d.extend_from_slice(&flag.to_le_bytes());
        // velocityEarth and its flag, then the rest (not read).
        d.extend_from_slice(&[0u8; 28]);
        d
    }

    #[test]
    fn linkquest_velocity_turned_to_z_up() {
        let d = linkquest_ros1([0.4, 0.1, 0.02], 1);
        let (Decoded::Dvl(v), frame) =
            decode(MessageType::LinkquestDvl, &mut Ros1Reader::new(&d), 0).unwrap()
        else {
            panic!("wrong stream");
        };
        assert_eq!(frame, "dvl");
        assert!(v.valid);
        assert_eq!(
            (v.velocity_mps.x, v.velocity_mps.y, v.velocity_mps.z),
            (0.4, -0.1, -0.02)
        );
        let d = linkquest_ros1([0.4, 0.1, 0.02], 0);
        let (Decoded::Dvl(v), _) =
            decode(MessageType::LinkquestDvl, &mut Ros1Reader::new(&d), 0).unwrap()
        else {
            panic!("wrong stream");
        };
        assert!(!v.valid);
        let d = linkquest_ros1([f64::NAN, 0.1, 0.02], 1);
        let err = decode(MessageType::LinkquestDvl, &mut Ros1Reader::new(&d), 0).unwrap_err();
        assert_eq!(err.field, "velocityinst[0]");
    }
}
