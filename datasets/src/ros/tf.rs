//! The sonar mounting from a recording's static transforms (`/tf_static`,
//! `tf2_msgs/TFMessage`).
//!
//! The sonar's frame is the `header.frame_id` of its messages. The static
//! transforms form a tree (each child has one parent); from the sonar
//! frame the chain of parents is followed up to the vehicle frame: the
//! first of `base_link`, `base_footprint` (REP-105's names) on the chain,
//! else the chain's root. The composed `vehicle_from_sonar` (3D) gives the
//! planar mounting:
//! - position: its x, y (m, vehicle frame);
//! - yaw: the direction of the head's x axis projected on the vehicle's
//!   x-y plane;
//! - angle direction: counter-clockwise when the head's z axis points up
//!   in the vehicle frame, clockwise when it points down (a head mounted
//!   upside down);
//! - tilt: the angle between the head's z axis and the vehicle's vertical,
//!   reported (a head far from horizontal, such as a vertical profiler,
//!   does not image the horizontal plane).

use super::messages::Transform;
use echofield_frontend::sensors::{AngleDirection, MountingSource, SensorMounting};
use echofield_graph::Se2;
use nalgebra::{Isometry3, Translation3, Vector3};
use std::collections::HashMap;

/// A planar mounting found in the static transforms.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct TfMounting {
    pub vehicle_frame: String,
    pub sonar_frame: String,
    pub vehicle_from_sonar: Se2,
    pub sonar_angle: AngleDirection,
    /// Angle between the head's z axis and the vehicle's z axis, rad.
    pub tilt_rad: f64,
}

impl TfMounting {
    /// `base` with the sonar's pose and angle direction replaced, marked
    /// recorded (it comes with the log).
    pub fn apply(&self, base: &SensorMounting) -> SensorMounting {
        SensorMounting {
            vehicle_from_sonar: self.vehicle_from_sonar,
            sonar_angle: self.sonar_angle,
            source: MountingSource::Recorded,
            ..base.clone()
        }
    }

    /// One line for the topic summary.
    pub fn describe(&self) -> String {
        format!(
            "sonar mounting {} -> {}: x {:.3} m, y {:.3} m, yaw {:.2} deg, angle {}{}",
            self.vehicle_frame,
            self.sonar_frame,
            self.vehicle_from_sonar.x(),
            self.vehicle_from_sonar.y(),
            self.vehicle_from_sonar.theta().to_degrees(),
            match self.sonar_angle {
                AngleDirection::CounterClockwise => "counter-clockwise",
                AngleDirection::Clockwise => "clockwise (head upside down)",
            },
            if self.tilt_rad > 10f64.to_radians() && self.tilt_rad < 170f64.to_radians() {
                format!(
                    "; the head is tilted {:.0} deg from horizontal",
                    self.tilt_rad
                        .to_degrees()
                        .min(180.0 - self.tilt_rad.to_degrees())
                )
            } else {
                String::new()
            }
        )
    }
}

/// Frames tried as the vehicle frame, in order.
const VEHICLE_FRAMES: [&str; 2] = ["base_link", "base_footprint"];

/// The mounting of `sonar_frame` from `transforms` (later transforms of the
/// same child replace earlier ones), or `None` when no transform has the
/// sonar frame as child.
pub(crate) fn sonar_mounting(transforms: &[Transform], sonar_frame: &str) -> Option<TfMounting> {
    let strip = |f: &str| f.trim_start_matches('/').to_string();
    let parent_of: HashMap<String, &Transform> =
        transforms.iter().map(|t| (strip(&t.child), t)).collect();
    let sonar = strip(sonar_frame);
    parent_of.get(&sonar)?;
    let mut frame = sonar.clone();
    let mut vehicle_from_sonar = Isometry3::identity();
    // The chain is at most as long as the number of transforms (a cycle
    // stops there).
    for _ in 0..=parent_of.len() {
        if VEHICLE_FRAMES.contains(&frame.as_str()) {
            break;
        }
        let Some(t) = parent_of.get(&frame) else {
            break;
        };
        let parent_from_child =
            Isometry3::from_parts(Translation3::from(t.translation), t.rotation);
        vehicle_from_sonar = parent_from_child * vehicle_from_sonar;
        frame = strip(&t.parent);
    }
    let r = vehicle_from_sonar.rotation;
    let x_axis = r * Vector3::x();
    let z_axis = r * Vector3::z();
    let p = vehicle_from_sonar.translation.vector;
    Some(TfMounting {
        vehicle_frame: frame,
        sonar_frame: sonar,
        vehicle_from_sonar: Se2::new(p.x, p.y, x_axis.y.atan2(x_axis.x)),
        sonar_angle: if z_axis.z < 0.0 {
            AngleDirection::Clockwise
        } else {
            AngleDirection::CounterClockwise
        },
        tilt_rad: z_axis.z.clamp(-1.0, 1.0).acos(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::UnitQuaternion;

    fn tf(parent: &str, child: &str, xyz: [f64; 3], rpy: [f64; 3]) -> Transform {
        Transform {
            parent: parent.into(),
            child: child.into(),
            translation: Vector3::from(xyz),
            rotation: UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
        }
    }

    #[test]
    fn chain_to_base_link_is_composed() {
        let transforms = [
            tf("odom", "base_link", [5.0, 5.0, 0.0], [0.0, 0.0, 1.0]),
            tf("base_link", "mast", [0.5, 0.0, 0.3], [0.0, 0.0, 0.5]),
            tf("mast", "sonar", [0.2, 0.0, 0.0], [0.0, 0.0, 0.25]),
        ];
        let m = sonar_mounting(&transforms, "/sonar").unwrap();
        assert_eq!(m.vehicle_frame, "base_link");
        let expected = Se2::new(0.5 + 0.2 * 0.5f64.cos(), 0.2 * 0.5f64.sin(), 0.75);
        assert!((m.vehicle_from_sonar.x() - expected.x()).abs() < 1e-12);
        assert!((m.vehicle_from_sonar.y() - expected.y()).abs() < 1e-12);
        assert!((m.vehicle_from_sonar.theta() - 0.75).abs() < 1e-12);
        assert_eq!(m.sonar_angle, AngleDirection::CounterClockwise);
        assert!(m.tilt_rad < 1e-9);
        assert!(sonar_mounting(&transforms, "camera").is_none());
    }

    #[test]
    fn upside_down_head_counts_clockwise() {
        let transforms = [tf(
            "base_link",
            "sonar",
            [1.0, -0.1, 0.0],
            [std::f64::consts::PI, 0.0, 0.3],
        )];
        let m = sonar_mounting(&transforms, "sonar").unwrap();
        assert_eq!(m.sonar_angle, AngleDirection::Clockwise);
        assert!((m.vehicle_from_sonar.theta() - 0.3).abs() < 1e-12);
        assert!((m.vehicle_from_sonar.y() + 0.1).abs() < 1e-12);
        assert!(m.describe().contains("clockwise"));
    }
}
