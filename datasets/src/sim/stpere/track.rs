//! Ground truth of the St Pere replay from the real logs.
//!
//! Position: the DGPS fixes smoothed by local linear regression with a
//! Gaussian kernel in time (it removes the fix-to-fix noise without the lag
//! or end bias of a moving average) and evaluated on a uniform 10 Hz grid.
//!
//! Heading: the MTi yaw plus one constant offset. A track heading (course
//! over ground) would be wrong whenever the vehicle crabs sideways, turns on
//! the spot or stops, all of which the Ictineu does; the MTi measures the
//! heading itself and its error against the DGPS track is, to first order, a
//! constant (magnetic declination and mounting). The offset is the one the
//! St Pere reader documents and measures
//! ([`crate::stpere::best_yaw_offset`]: the constant that minimises the
//! dead-reckoning error against DGPS), unless the config fixes it. With this
//! choice the navigation sensors relate to the
//! ground truth exactly as a real DVL and compass relate to the true motion:
//! the DVL measures the body velocity of the ground truth with its own noise,
//! and the MTi reads the ground-truth heading minus the constant offset.
//!
//! Before the first fix (the sonar log starts about three minutes before the
//! navigation logs) the vehicle is held at the first ground-truth pose.

use crate::sim::{SimError, Trajectory};
use echofield_frontend::sensors::Attitude;
use echofield_graph::{Se2, wrap_angle};
use nalgebra::Vector2;

/// Gaussian smoothing of the MTi yaw, s (it only removes sample noise).
const YAW_SMOOTHING_S: f64 = 0.3;

/// A DGPS fix in the local metric frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fix {
    pub stamp_s: f64,
    pub position_m: Vector2<f64>,
}

/// Local linear Gaussian-kernel regression of the fixes at `stamp_s`
/// (kernel standard deviation `sigma_s`, support ±4σ). `fixes` sorted by
/// time. Falls back to the nearest fix where the kernel holds fewer than two.
pub fn smoothed_position(fixes: &[Fix], stamp_s: f64, sigma_s: f64) -> Vector2<f64> {
    let lo = fixes.partition_point(|f| f.stamp_s < stamp_s - 4.0 * sigma_s);
    let hi = fixes.partition_point(|f| f.stamp_s <= stamp_s + 4.0 * sigma_s);
    let window = &fixes[lo..hi];
    let nearest = || {
        let i = fixes
            .partition_point(|f| f.stamp_s < stamp_s)
            .min(fixes.len() - 1);
        let j = i.saturating_sub(1);
        if (fixes[j].stamp_s - stamp_s).abs() < (fixes[i].stamp_s - stamp_s).abs() {
            fixes[j].position_m
        } else {
            fixes[i].position_m
        }
    };
    if window.len() < 2 || sigma_s <= 0.0 {
        return nearest();
    }
    // Weighted least squares of p(t) = a + b·(t - stamp): a is the estimate.
    let (mut s0, mut s1, mut s2) = (0.0, 0.0, 0.0);
    let (mut m0, mut m1) = (Vector2::zeros(), Vector2::zeros());
    for f in window {
        let dt = f.stamp_s - stamp_s;
        let w = (-0.5 * (dt / sigma_s).powi(2)).exp();
        s0 += w;
        s1 += w * dt;
        s2 += w * dt * dt;
        m0 += f.position_m * w;
        m1 += f.position_m * (w * dt);
    }
    let det = s0 * s2 - s1 * s1;
    if det.abs() < 1e-12 * s0 * s0.max(1.0) {
        return m0 / s0;
    }
    (m0 * s2 - m1 * s1) / det
}

/// Unwrapped MTi yaw, linearly interpolated at `stamp_s` and smoothed.
struct YawTrack {
    stamps_s: Vec<f64>,
    unwrapped_rad: Vec<f64>,
}

impl YawTrack {
    fn new(attitude: &[Attitude]) -> Self {
        let mut unwrapped_rad = Vec::with_capacity(attitude.len());
        let mut prev: Option<(f64, f64)> = None;
        for a in attitude {
            let u = match prev {
                Some((raw, acc)) => acc + wrap_angle(a.yaw_rad - raw),
                None => a.yaw_rad,
            };
            unwrapped_rad.push(u);
            prev = Some((a.yaw_rad, u));
        }
        Self {
            stamps_s: attitude.iter().map(|a| a.stamp_s).collect(),
            unwrapped_rad,
        }
    }

    fn at(&self, stamp_s: f64) -> f64 {
        let n = self.stamps_s.len();
        let i = self.stamps_s.partition_point(|&t| t < stamp_s);
        if i == 0 {
            return self.unwrapped_rad[0];
        }
        if i >= n {
            return self.unwrapped_rad[n - 1];
        }
        let (t0, t1) = (self.stamps_s[i - 1], self.stamps_s[i]);
        let f = if t1 > t0 {
            (stamp_s - t0) / (t1 - t0)
        } else {
            0.0
        };
        self.unwrapped_rad[i - 1] + f * (self.unwrapped_rad[i] - self.unwrapped_rad[i - 1])
    }

    /// Gaussian-weighted mean of the interpolated yaw over ±2σ.
    fn smoothed(&self, stamp_s: f64) -> f64 {
        let taps = 9;
        let (mut sum, mut weight) = (0.0, 0.0);
        for k in 0..taps {
            let u = -2.0 + 4.0 * k as f64 / (taps - 1) as f64;
            let w = (-0.5 * u * u).exp();
            sum += w * self.at(stamp_s + u * YAW_SMOOTHING_S);
            weight += w;
        }
        sum / weight
    }
}

/// The ground-truth trajectory on a uniform grid of `dt_s` covering
/// `[start_s, end_s]`, held at its first pose before the first fix.
pub fn ground_truth(
    fixes: &[Fix],
    attitude: &[Attitude],
    heading_offset_rad: f64,
    smoothing_s: f64,
    (start_s, end_s): (f64, f64),
    dt_s: f64,
) -> Result<Trajectory, SimError> {
    if fixes.len() < 2 || attitude.is_empty() {
        return Err(SimError::InvalidTrajectory {
            message: format!(
                "the replay needs at least 2 DGPS fixes and 1 attitude sample (got {} and {})",
                fixes.len(),
                attitude.len()
            ),
        });
    }
    let yaw = YawTrack::new(attitude);
    let first_fix = fixes[0].stamp_s;
    let n = ((end_s - start_s) / dt_s).ceil() as usize + 1;
    let poses = (0..n)
        .map(|i| {
            let t = (start_s + i as f64 * dt_s).max(first_fix);
            let p = smoothed_position(fixes, t, smoothing_s);
            Se2::new(p.x, p.y, wrap_angle(yaw.smoothed(t) + heading_offset_rad))
        })
        .collect();
    Trajectory::from_poses(start_s, dt_s, poses)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line_fixes(noise: bool) -> Vec<Fix> {
        (0..300)
            .map(|i| {
                let t = 1000.0 + i as f64;
                let wobble = if noise {
                    0.5 * ((i * 7919) % 13) as f64 / 13.0 - 0.25
                } else {
                    0.0
                };
                Fix {
                    stamp_s: t,
                    position_m: Vector2::new(0.3 * i as f64 + wobble, 0.1 * i as f64 - wobble),
                }
            })
            .collect()
    }

    #[test]
    fn local_linear_smoothing_is_exact_on_a_line_even_at_the_ends() {
        let fixes = line_fixes(false);
        for t in [1000.0, 1000.5, 1150.25, 1299.0] {
            let p = smoothed_position(&fixes, t, 5.0);
            let i = t - 1000.0;
            assert!(
                (p - Vector2::new(0.3 * i, 0.1 * i)).norm() < 1e-9,
                "{t}: {p}"
            );
        }
        let noisy = line_fixes(true);
        let p = smoothed_position(&noisy, 1150.0, 5.0);
        assert!((p - Vector2::new(45.0, 15.0)).norm() < 0.1, "{p}");
    }

    #[test]
    fn heading_is_mti_plus_offset_and_held_before_the_first_fix() {
        let fixes = line_fixes(false);
        let attitude: Vec<Attitude> = (0..3000)
            .map(|i| Attitude {
                stamp_s: 1000.0 + 0.1 * i as f64,
                roll_rad: 0.0,
                pitch_rad: 0.0,
                // Turning slowly through the ±π wrap.
                yaw_rad: wrap_angle(3.0 + 0.001 * i as f64),
                yaw_rate_radps: None,
            })
            .collect();
        let offset = -0.25;
        let gt = ground_truth(&fixes, &attitude, offset, 5.0, (900.0, 1299.0), 0.1).unwrap();
        for i in [100, 1000, 2500] {
            let t = 1000.0 + 0.1 * i as f64;
            let expected = wrap_angle(3.0 + 0.001 * i as f64 + offset);
            assert!(
                wrap_angle(gt.pose_at(t).theta() - expected).abs() < 1e-6,
                "{t}"
            );
            let p = gt.pose_at(t);
            assert!((p.x() - 0.3 * (t - 1000.0)).abs() < 1e-6);
        }
        assert_eq!(gt.pose_at(950.0), gt.pose_at(1000.0));
        assert!(ground_truth(&fixes[..1], &attitude, 0.0, 5.0, (900.0, 1299.0), 0.1).is_err());
    }
}
