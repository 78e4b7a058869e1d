//! The ground-truth motion of the vehicle: poses and body-frame velocities on
//! a uniform time grid, interpolated at any time in between.
//!
//! `world_from_vehicle` poses use the frame conventions of
//! [`echofield_frontend::sensors`]: vehicle x forward, y to port, yaw
//! counter-clockwise. The twist is `(v_x, v_y, ω)`: velocity over ground in
//! the vehicle frame (m/s) and yaw rate (rad/s).

use super::SimError;
use echofield_graph::Se2;
use echofield_graph::se2::wrap_angle;
use nalgebra::Vector3;

/// Poses and twists sampled every `dt_s` from `start_s`.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    start_s: f64,
    dt_s: f64,
    poses: Vec<Se2>,
    twists: Vec<Vector3<f64>>,
}

impl Trajectory {
    /// Wraps uniformly sampled poses and twists. Fails when fewer than two
    /// samples are given, the lengths differ, `dt_s` is not positive or a
    /// value is not finite.
    pub fn new(
        start_s: f64,
        dt_s: f64,
        poses: Vec<Se2>,
        twists: Vec<Vector3<f64>>,
    ) -> Result<Self, SimError> {
        let bad = |message: String| SimError::InvalidTrajectory { message };
        if !(start_s.is_finite() && dt_s.is_finite() && dt_s > 0.0) {
            return Err(bad(format!(
                "start {start_s} s and step {dt_s} s must be finite, step > 0"
            )));
        }
        if poses.len() < 2 || poses.len() != twists.len() {
            return Err(bad(format!(
                "need at least 2 samples and as many twists as poses (got {} poses, {} twists)",
                poses.len(),
                twists.len()
            )));
        }
        if let Some(i) = poses.iter().position(|p| !p.is_finite()) {
            return Err(bad(format!("pose sample {i} is not finite")));
        }
        if let Some(i) = twists.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
            return Err(bad(format!("twist sample {i} is not finite")));
        }
        Ok(Self {
            start_s,
            dt_s,
            poses,
            twists,
        })
    }

    /// Poses only; twists from central differences of the poses (used by the
    /// replay, whose ground truth comes from positions and headings).
    pub fn from_poses(start_s: f64, dt_s: f64, poses: Vec<Se2>) -> Result<Self, SimError> {
        let n = poses.len();
        let twists = (0..n)
            .map(|i| {
                let (a, b) = (i.saturating_sub(1), (i + 1).min(n.saturating_sub(1)));
                if a == b {
                    return Vector3::zeros();
                }
                let span_s = (b - a) as f64 * dt_s;
                let (pa, pb, p) = (&poses[a], &poses[b], &poses[i]);
                let world_v = (pb.translation() - pa.translation()) / span_s;
                let body_v = p.rotation().inverse() * world_v;
                let yaw_rate = wrap_angle(pb.theta() - pa.theta()) / span_s;
                Vector3::new(body_v.x, body_v.y, yaw_rate)
            })
            .collect();
        Self::new(start_s, dt_s, poses, twists)
    }

    /// A vehicle holding `pose` for `duration_s`.
    pub fn stationary(
        pose: Se2,
        start_s: f64,
        duration_s: f64,
        dt_s: f64,
    ) -> Result<Self, SimError> {
        let n = ((duration_s / dt_s).ceil() as usize).max(1) + 1;
        Self::new(start_s, dt_s, vec![pose; n], vec![Vector3::zeros(); n])
    }

    pub fn start_s(&self) -> f64 {
        self.start_s
    }

    pub fn end_s(&self) -> f64 {
        self.start_s + (self.poses.len() - 1) as f64 * self.dt_s
    }

    pub fn duration_s(&self) -> f64 {
        self.end_s() - self.start_s
    }

    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// The samples themselves.
    pub fn poses(&self) -> &[Se2] {
        &self.poses
    }

    /// Index of the sample at or before `t` and the fraction towards the next
    /// one; times outside the trajectory clamp to its ends.
    fn locate(&self, stamp_s: f64) -> (usize, f64) {
        let u = ((stamp_s - self.start_s) / self.dt_s).clamp(0.0, (self.poses.len() - 1) as f64);
        let i = (u.floor() as usize).min(self.poses.len() - 2);
        (i, u - i as f64)
    }

    /// `world_from_vehicle` at `stamp_s`: linear in position, shortest-arc in
    /// heading.
    pub fn pose_at(&self, stamp_s: f64) -> Se2 {
        let (i, f) = self.locate(stamp_s);
        let (a, b) = (&self.poses[i], &self.poses[i + 1]);
        let t = a.translation() + (b.translation() - a.translation()) * f;
        let theta = a.theta() + wrap_angle(b.theta() - a.theta()) * f;
        Se2::new(t.x, t.y, wrap_angle(theta))
    }

    /// Body-frame twist `(v_x, v_y, ω)` at `stamp_s`, linearly interpolated.
    pub fn twist_at(&self, stamp_s: f64) -> Vector3<f64> {
        let (i, f) = self.locate(stamp_s);
        self.twists[i] * (1.0 - f) + self.twists[i + 1] * f
    }

    /// Length of the sampled path, metres.
    pub fn distance_travelled_m(&self) -> f64 {
        self.poses
            .windows(2)
            .map(|w| (w[1].translation() - w[0].translation()).norm())
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn interpolates_position_and_heading_across_the_wrap() {
        let poses = vec![Se2::new(0.0, 0.0, PI - 0.1), Se2::new(1.0, 2.0, -PI + 0.1)];
        let traj = Trajectory::from_poses(10.0, 1.0, poses).unwrap();
        let mid = traj.pose_at(10.5);
        assert!((mid.x() - 0.5).abs() < 1e-12 && (mid.y() - 1.0).abs() < 1e-12);
        // Halfway between π - 0.1 and -π + 0.1 along the short arc is π.
        assert!((mid.theta().abs() - PI).abs() < 1e-12, "{}", mid.theta());
        // Clamped outside.
        assert_eq!(traj.pose_at(0.0), traj.poses()[0]);
        assert_eq!(traj.pose_at(99.0).x(), 1.0);
    }

    #[test]
    fn twists_from_poses_are_body_frame() {
        // Heading north (π/2) while moving north at 0.5 m/s: body v_x = 0.5.
        let poses: Vec<Se2> = (0..5)
            .map(|i| Se2::new(3.0, 0.5 * i as f64, PI / 2.0))
            .collect();
        let traj = Trajectory::from_poses(0.0, 1.0, poses).unwrap();
        let v = traj.twist_at(2.0);
        assert!(
            (v.x - 0.5).abs() < 1e-12 && v.y.abs() < 1e-12 && v.z.abs() < 1e-12,
            "{v}"
        );
    }

    #[test]
    fn rejects_bad_samples() {
        assert!(Trajectory::from_poses(0.0, 1.0, vec![Se2::identity()]).is_err());
        assert!(Trajectory::from_poses(0.0, 0.0, vec![Se2::identity(); 3]).is_err());
        let poses = vec![Se2::identity(), Se2::new(f64::NAN, 0.0, 0.0)];
        let err = Trajectory::from_poses(0.0, 1.0, poses)
            .unwrap_err()
            .to_string();
        assert!(err.contains("sample 1"), "{err}");
    }
}
