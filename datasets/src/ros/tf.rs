//! The sonar and DVL mountings from a recording's static transforms
//! (`/tf_static`, `tf2_msgs/TFMessage`).
//!
//! A sensor's frame is the `header.frame_id` of its messages (an
//! Odometry's twist: `child_frame_id`). The static transforms form a tree
//! (each child has one parent); from the sensor's frame the chain of
//! parents is followed up to the vehicle frame: the first of `base_link`,
//! `base_footprint` (REP-105's names) on the chain, else the chain's root.
//! The composed `vehicle_from_frame` (3D) gives the planar mounting:
//! - position: its x, y (m, vehicle frame);
//! - yaw: the direction of the frame's x axis projected on the vehicle's
//!   x-y plane;
//! - angle direction: counter-clockwise when the head's z axis points up
//!   in the vehicle frame, clockwise when it points down (a head mounted
//!   upside down);
//! - tilt: the angle between the head's z axis and the vehicle's vertical,
//!   reported (a head far from horizontal, such as a vertical profiler,
//!   does not image the horizontal plane).
//!
//! ROS 1 bags recorded before tf2's `/tf_static` (the Girona underwater
//! caves data set among them) publish the mountings on `/tf`, repeatedly,
//! beside the moving vehicle: a `/tf` frame pair whose transform never
//! changes over the recording (seen at least twice, equal to
//! [`CONSTANT_TOLERANCE`]) is read as static ([`ConstantTransforms`]), after
//! `/tf_static`, which wins for a child it has.
//!
//! For the DVL only position and yaw are used (`vehicle_from_dvl`): the
//! dead reckoning rotates its velocities by the yaw and removes the lever
//! arm (`v − ω × r`, ω the yaw rate); its messages' own axis conventions
//! (z down for the DVL messages, [`super::messages`]) are already applied.

use super::messages::Transform;
use echofield_frontend::sensors::{AngleDirection, MountingSource, SensorMounting};
use echofield_graph::Se2;
use nalgebra::{Isometry3, Translation3, Vector3};
use std::collections::HashMap;

/// A planar mounting found in the static transforms.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct TfMounting {
    pub vehicle_frame: String,
    /// The sensor's frame.
    pub frame: String,
    pub vehicle_from_frame: Se2,
    /// For a sonar head: which way its angle counts.
    pub sonar_angle: AngleDirection,
    /// Angle between the head's z axis and the vehicle's z axis, rad.
    pub tilt_rad: f64,
}

impl TfMounting {
    /// `base` with the sonar's pose and angle direction replaced, marked
    /// recorded (it comes with the log).
    pub fn apply(&self, base: &SensorMounting) -> SensorMounting {
        SensorMounting {
            vehicle_from_sonar: self.vehicle_from_frame,
            sonar_angle: self.sonar_angle,
            source: MountingSource::Recorded,
            ..base.clone()
        }
    }

    /// `x .. m, y .. m, yaw .. deg` of the frame on the vehicle.
    fn pose_text(&self) -> String {
        format!(
            "{} -> {}: x {:.3} m, y {:.3} m, yaw {:.2} deg",
            self.vehicle_frame,
            self.frame,
            self.vehicle_from_frame.x(),
            self.vehicle_from_frame.y(),
            self.vehicle_from_frame.theta().to_degrees()
        )
    }

    /// One line for the topic summary, as a sonar mounting.
    pub fn describe(&self) -> String {
        format!(
            "sonar mounting {}, angle {}{}",
            self.pose_text(),
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

    /// One line for the topic summary, as a DVL mounting.
    pub fn describe_dvl(&self) -> String {
        format!(
            "DVL mounting {} (velocities rotated by the yaw; the lever arm removed with the yaw rate, v - w x r)",
            self.pose_text()
        )
    }
}

/// How far (m, rad) a `/tf` transform may move between messages and still
/// count as constant (drivers republish the same numbers).
pub(crate) const CONSTANT_TOLERANCE: f64 = 1e-6;

/// The `/tf` frame pairs of a recording, and whether each kept one value.
#[derive(Debug, Default)]
pub(crate) struct ConstantTransforms {
    /// (first transform, messages seen, changed), in the order first seen.
    pairs: Vec<(Transform, u64, bool)>,
    index: HashMap<(String, String), usize>,
}

impl ConstantTransforms {
    /// One transform of a `/tf` message.
    pub fn add(&mut self, t: Transform) {
        let key = (t.parent.clone(), t.child.clone());
        match self.index.get(&key) {
            Some(&i) => {
                let (first, seen, changed) = &mut self.pairs[i];
                *seen += 1;
                let moved = (first.translation - t.translation).norm();
                let turned = first.rotation.angle_to(&t.rotation);
                *changed |= moved > CONSTANT_TOLERANCE || turned > CONSTANT_TOLERANCE;
            }
            None => {
                self.index.insert(key, self.pairs.len());
                self.pairs.push((t, 1, false));
            }
        }
    }

    /// The pairs seen at least twice that never changed.
    pub fn constant(&self) -> impl Iterator<Item = &Transform> {
        self.pairs
            .iter()
            .filter(|(_, seen, changed)| *seen >= 2 && !changed)
            .map(|(t, _, _)| t)
    }

    /// Frame pairs seen.
    pub fn pairs(&self) -> usize {
        self.pairs.len()
    }
}

/// Frames tried as the vehicle frame, in order.
const VEHICLE_FRAMES: [&str; 2] = ["base_link", "base_footprint"];

/// The mounting of the sensor frame `frame` from `transforms` (later
/// transforms of the same child replace earlier ones), or `None` when no
/// transform has it as child.
pub(crate) fn mounting_of(transforms: &[Transform], frame: &str) -> Option<TfMounting> {
    let strip = |f: &str| f.trim_start_matches('/').to_string();
    let parent_of: HashMap<String, &Transform> =
        transforms.iter().map(|t| (strip(&t.child), t)).collect();
    let sensor = strip(frame);
    parent_of.get(&sensor)?;
    let mut frame = sensor.clone();
    let mut vehicle_from_frame = Isometry3::identity();
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
        vehicle_from_frame = parent_from_child * vehicle_from_frame;
        frame = strip(&t.parent);
    }
    let r = vehicle_from_frame.rotation;
    let x_axis = r * Vector3::x();
    let z_axis = r * Vector3::z();
    let p = vehicle_from_frame.translation.vector;
    Some(TfMounting {
        vehicle_frame: frame,
        frame: sensor,
        vehicle_from_frame: Se2::new(p.x, p.y, x_axis.y.atan2(x_axis.x)),
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
        let m = mounting_of(&transforms, "/sonar").unwrap();
        assert_eq!(m.vehicle_frame, "base_link");
        let expected = Se2::new(0.5 + 0.2 * 0.5f64.cos(), 0.2 * 0.5f64.sin(), 0.75);
        assert!((m.vehicle_from_frame.x() - expected.x()).abs() < 1e-12);
        assert!((m.vehicle_from_frame.y() - expected.y()).abs() < 1e-12);
        assert!((m.vehicle_from_frame.theta() - 0.75).abs() < 1e-12);
        assert_eq!(m.sonar_angle, AngleDirection::CounterClockwise);
        assert!(m.tilt_rad < 1e-9);
        assert!(mounting_of(&transforms, "camera").is_none());
    }

    #[test]
    fn only_unchanging_tf_pairs_are_constant() {
        let mut c = ConstantTransforms::default();
        for k in 0..3 {
            let moving = tf("odom", "base_link", [k as f64, 0.0, 0.0], [0.0; 3]);
            c.add(moving);
            c.add(tf("base_link", "sonar", [0.5, 0.0, 0.0], [0.0, 0.0, 0.3]));
        }
        c.add(tf("base_link", "once", [1.0, 0.0, 0.0], [0.0; 3]));
        let constant: Vec<_> = c.constant().map(|t| t.child.as_str()).collect();
        assert_eq!(constant, ["sonar"]);
        assert_eq!(c.pairs(), 3);
    }

    #[test]
    fn upside_down_head_counts_clockwise() {
        let transforms = [tf(
            "base_link",
            "sonar",
            [1.0, -0.1, 0.0],
            [std::f64::consts::PI, 0.0, 0.3],
        )];
        let m = mounting_of(&transforms, "sonar").unwrap();
        assert_eq!(m.sonar_angle, AngleDirection::Clockwise);
        assert!((m.vehicle_from_frame.theta() - 0.3).abs() < 1e-12);
        assert!((m.vehicle_from_frame.y() + 0.1).abs() < 1e-12);
        assert!(m.describe().contains("clockwise"));
    }
}
