//! A simple AUV that follows a route of waypoints: pure-pursuit steering with
//! a rate-limited, first-order yaw response, speed reduced in turns and a
//! gentle sway oscillation (the lateral velocity currents and thrusters give
//! a real vehicle). The result is a smooth ground-truth [`Trajectory`].

use super::{SimError, Trajectory};
use echofield_graph::{Se2, wrap_angle};
use nalgebra::{Vector2, Vector3};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Motion of the simulated vehicle along its route.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VehicleConfig {
    /// Forward speed on straight legs, m/s (AUVs survey at 0.2-0.5).
    pub cruise_speed_mps: f64,
    /// Largest yaw rate the controller commands, rad/s.
    pub max_yaw_rate_radps: f64,
    /// Time constant of the yaw-rate response to a command, s.
    pub yaw_time_constant_s: f64,
    /// Pure-pursuit look-ahead distance along the route, m; larger values
    /// give wider, smoother turns.
    pub lookahead_m: f64,
    /// Amplitude of the lateral (sway) velocity oscillation, m/s.
    pub sway_amplitude_mps: f64,
    /// Period of the sway oscillation, s.
    pub sway_period_s: f64,
    /// Rate of the ground-truth samples the simulator integrates and
    /// interpolates between, Hz.
    pub sample_rate_hz: f64,
}

impl Default for VehicleConfig {
    fn default() -> Self {
        Self {
            cruise_speed_mps: 0.4,
            max_yaw_rate_radps: 0.12,
            yaw_time_constant_s: 1.5,
            lookahead_m: 4.0,
            sway_amplitude_mps: 0.02,
            sway_period_s: 75.0,
            sample_rate_hz: 20.0,
        }
    }
}

impl VehicleConfig {
    pub fn validate(&self) -> Result<(), SimError> {
        let checks = [
            ("vehicle.cruise_speed_mps", self.cruise_speed_mps, 0.01, 5.0),
            (
                "vehicle.max_yaw_rate_radps",
                self.max_yaw_rate_radps,
                1e-3,
                2.0,
            ),
            (
                "vehicle.yaw_time_constant_s",
                self.yaw_time_constant_s,
                0.0,
                60.0,
            ),
            ("vehicle.lookahead_m", self.lookahead_m, 0.1, 100.0),
            (
                "vehicle.sway_amplitude_mps",
                self.sway_amplitude_mps,
                0.0,
                1.0,
            ),
            ("vehicle.sway_period_s", self.sway_period_s, 1.0, 1e5),
            ("vehicle.sample_rate_hz", self.sample_rate_hz, 1.0, 1000.0),
        ];
        super::config::check_ranges(&checks)
    }
}

/// Drives the vehicle along `route` (waypoints `[x, y]` in metres, at least
/// two) from `start_s`, starting at rest on the first waypoint facing the
/// second, and stops at the last waypoint.
pub fn follow_route(
    route: &[[f64; 2]],
    config: &VehicleConfig,
    start_s: f64,
) -> Result<Trajectory, SimError> {
    let path = Path::new(route)?;
    let dt = 1.0 / config.sample_rate_hz;
    let first_dir = path.point_at(0.1) - path.point_at(0.0);
    let mut pos = path.point_at(0.0);
    let mut yaw = first_dir.y.atan2(first_dir.x);
    let (mut speed, mut yaw_rate, mut progress) = (0.0, 0.0, 0.0);
    let accel_mps2 = 0.05;
    // Saturate the steering command beyond this heading error.
    let full_command_error_rad = 0.35;
    let max_steps = ((path.length_m / (0.2 * config.cruise_speed_mps) + 600.0) / dt) as usize;
    let mut poses = Vec::new();
    let mut twists = Vec::new();
    for step in 0..max_steps {
        let t = step as f64 * dt;
        progress = path.closest(pos, progress, 3.0 * config.lookahead_m);
        let sway = config.sway_amplitude_mps * (2.0 * PI * t / config.sway_period_s).sin();
        poses.push(Se2::new(pos.x, pos.y, wrap_angle(yaw)));
        twists.push(Vector3::new(speed, sway, yaw_rate));
        if path.length_m - progress < 0.3 {
            return Trajectory::new(start_s, dt, poses, twists);
        }
        let target = path.point_at(progress + config.lookahead_m);
        let to_target = target - pos;
        let error = wrap_angle(to_target.y.atan2(to_target.x) - yaw);
        let command = (error / full_command_error_rad).clamp(-1.0, 1.0) * config.max_yaw_rate_radps;
        yaw_rate += (command - yaw_rate) * (dt / config.yaw_time_constant_s.max(dt));
        // Slow down in turns and when approaching the end of the route.
        let remaining = path.length_m - progress;
        let turn_factor = 1.0 - 0.5 * (error.abs() / (PI / 2.0)).min(1.0);
        let stop_factor = (remaining / config.lookahead_m).clamp(0.0, 1.0);
        let wanted = config.cruise_speed_mps * turn_factor * stop_factor.max(0.2);
        speed += (wanted - speed).clamp(-accel_mps2 * dt, accel_mps2 * dt);
        let mid_yaw = yaw + 0.5 * yaw_rate * dt;
        let (s, c) = mid_yaw.sin_cos();
        pos += Vector2::new(c * speed - s * sway, s * speed + c * sway) * dt;
        yaw += yaw_rate * dt;
    }
    Err(SimError::InvalidTrajectory {
        message: format!(
            "the vehicle did not reach the end of the {:.0} m route (turns too tight for the vehicle config?)",
            path.length_m
        ),
    })
}

/// A polyline parametrised by arc length.
struct Path {
    points: Vec<Vector2<f64>>,
    cumulative_m: Vec<f64>,
    length_m: f64,
}

impl Path {
    fn new(route: &[[f64; 2]]) -> Result<Self, SimError> {
        let points: Vec<Vector2<f64>> = route.iter().map(|p| Vector2::new(p[0], p[1])).collect();
        if points.len() < 2 || points.iter().any(|p| !(p.x.is_finite() && p.y.is_finite())) {
            return Err(SimError::InvalidTrajectory {
                message: "a route needs at least two finite waypoints".into(),
            });
        }
        let mut cumulative_m = vec![0.0];
        for w in points.windows(2) {
            let last = *cumulative_m.last().unwrap_or(&0.0);
            cumulative_m.push(last + (w[1] - w[0]).norm());
        }
        let length_m = *cumulative_m.last().unwrap_or(&0.0);
        if length_m < 1.0 {
            return Err(SimError::InvalidTrajectory {
                message: format!("route is only {length_m:.2} m long"),
            });
        }
        Ok(Self {
            points,
            cumulative_m,
            length_m,
        })
    }

    fn segment_of(&self, s: f64) -> usize {
        let i = self.cumulative_m.partition_point(|&c| c <= s);
        i.clamp(1, self.points.len() - 1) - 1
    }

    fn point_at(&self, s: f64) -> Vector2<f64> {
        let s = s.clamp(0.0, self.length_m);
        let i = self.segment_of(s);
        let len = self.cumulative_m[i + 1] - self.cumulative_m[i];
        let f = if len > 0.0 {
            (s - self.cumulative_m[i]) / len
        } else {
            0.0
        };
        self.points[i] + (self.points[i + 1] - self.points[i]) * f
    }

    /// Arc length of the point of the path closest to `p`, searched only in
    /// `[progress - 1, progress + window]` so that a route crossing itself
    /// is followed in order.
    fn closest(&self, p: Vector2<f64>, progress: f64, window_m: f64) -> f64 {
        let (lo, hi) = (
            (progress - 1.0).max(0.0),
            (progress + window_m).min(self.length_m),
        );
        let (i0, i1) = (self.segment_of(lo), self.segment_of(hi));
        let mut best = (f64::INFINITY, progress);
        for i in i0..=i1 {
            let (a, b) = (self.points[i], self.points[i + 1]);
            let e = b - a;
            let len2 = e.norm_squared();
            let f = if len2 > 0.0 {
                ((p - a).dot(&e) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let s = (self.cumulative_m[i] + f * len2.sqrt()).clamp(lo, hi);
            let d = (self.point_at(s) - p).norm();
            if d < best.0 {
                best = (d, s);
            }
        }
        best.1.max(progress)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn follows_a_square_at_cruise_speed_with_smooth_heading() {
        let route = [
            [0.0, 0.0],
            [40.0, 0.0],
            [40.0, 40.0],
            [0.0, 40.0],
            [0.0, 0.0],
        ];
        let config = VehicleConfig::default();
        let traj = follow_route(&route, &config, 100.0).unwrap();
        let length = traj.distance_travelled_m();
        assert!((150.0..170.0).contains(&length), "travelled {length} m");
        let end = traj.pose_at(traj.end_s());
        assert!(end.translation().norm() < 1.0, "ends at {end:?}");
        // Heading changes by at most max_yaw_rate · dt per sample.
        let dt = traj.dt_s();
        for w in traj.poses().windows(2) {
            let dyaw = wrap_angle(w[1].theta() - w[0].theta()).abs();
            assert!(dyaw <= config.max_yaw_rate_radps * dt + 1e-9, "{dyaw}");
        }
        // Stays near the route (turn overshoot of a few metres at most).
        for p in traj.poses() {
            let d = [
                p.x().abs(),
                (p.x() - 40.0).abs(),
                p.y().abs(),
                (p.y() - 40.0).abs(),
            ];
            let nearest = d.iter().cloned().fold(f64::INFINITY, f64::min);
            assert!(nearest < 3.0, "{p:?} is {nearest} m off the route");
        }
        let speed = traj.twist_at(traj.start_s() + 50.0).x;
        assert!((speed - config.cruise_speed_mps).abs() < 0.02, "{speed}");
    }

    #[test]
    fn rejects_degenerate_routes() {
        let config = VehicleConfig::default();
        assert!(follow_route(&[[0.0, 0.0]], &config, 0.0).is_err());
        assert!(follow_route(&[[0.0, 0.0], [0.1, 0.0]], &config, 0.0).is_err());
        assert!(follow_route(&[[0.0, 0.0], [f64::NAN, 0.0]], &config, 0.0).is_err());
    }
}
