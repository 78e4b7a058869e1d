//! Navigation sensors from the ground truth: a DVL (body-frame velocity over
//! ground with noise, a scale error, invalid samples and gaps without any
//! output) and an attitude unit (yaw with noise and a constant bias, yaw rate
//! with noise, small roll and pitch). The yaw error also wanders slowly (a
//! first-order Gauss-Markov process, like the compass deviation a vehicle
//! meets near steel hulls and pontoons), so dead reckoning is distorted in a
//! way no rigid alignment removes.

use super::{SimError, Trajectory};
use echofield_frontend::sensors::{Attitude, DvlVelocity};
use echofield_graph::{Se2, wrap_angle};
use nalgebra::{Rotation2, Vector2, Vector3};
use rand::Rng;
use rand_distr::{Distribution, Exp, StandardNormal};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The simulated Doppler velocity log.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DvlSimConfig {
    /// Output rate, Hz.
    pub rate_hz: f64,
    /// Uniform jitter of each sample time around its nominal slot, ± s.
    pub time_jitter_s: f64,
    /// Standard deviation of the white noise on each horizontal axis, m/s.
    pub noise_std_mps: f64,
    /// Standard deviation of the noise on the vertical axis, m/s.
    pub vertical_noise_std_mps: f64,
    /// Scale error: the DVL reports `(1 + scale_error)` times the true
    /// velocity (a sound-speed or calibration error), dimensionless.
    pub scale_error: f64,
    /// Probability that a sample is flagged invalid (`valid = false`, zero
    /// velocity), e.g. a lost beam.
    pub invalid_probability: f64,
    /// Losses of bottom lock per hour during which the DVL outputs nothing.
    pub gap_rate_per_hour: f64,
    /// Mean length of such a gap, s (exponentially distributed).
    pub gap_mean_s: f64,
}

impl Default for DvlSimConfig {
    fn default() -> Self {
        Self {
            rate_hz: 3.0,
            time_jitter_s: 0.02,
            noise_std_mps: 0.12,
            vertical_noise_std_mps: 0.03,
            scale_error: 0.015,
            invalid_probability: 0.02,
            gap_rate_per_hour: 4.0,
            gap_mean_s: 6.0,
        }
    }
}

impl DvlSimConfig {
    pub fn validate(&self) -> Result<(), SimError> {
        super::config::check_ranges(&[
            ("dvl.rate_hz", self.rate_hz, 0.01, 1000.0),
            (
                "dvl.time_jitter_s",
                self.time_jitter_s,
                0.0,
                0.45 / self.rate_hz.max(0.01),
            ),
            ("dvl.noise_std_mps", self.noise_std_mps, 0.0, 10.0),
            (
                "dvl.vertical_noise_std_mps",
                self.vertical_noise_std_mps,
                0.0,
                10.0,
            ),
            ("dvl.scale_error", self.scale_error, -0.5, 0.5),
            (
                "dvl.invalid_probability",
                self.invalid_probability,
                0.0,
                1.0,
            ),
            ("dvl.gap_rate_per_hour", self.gap_rate_per_hour, 0.0, 3600.0),
            ("dvl.gap_mean_s", self.gap_mean_s, 0.0, 3600.0),
        ])
    }
}

/// The simulated attitude and heading unit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HeadingSimConfig {
    /// Output rate, Hz.
    pub rate_hz: f64,
    /// Standard deviation of the white noise on yaw, rad.
    pub yaw_noise_std_rad: f64,
    /// Constant yaw error (magnetic disturbance, misalignment), rad: the unit
    /// reports true yaw plus this.
    pub yaw_bias_rad: f64,
    /// Stationary standard deviation of the slowly wandering yaw error, rad.
    pub yaw_drift_std_rad: f64,
    /// Correlation time of the wandering yaw error, s.
    pub yaw_drift_time_constant_s: f64,
    /// Standard deviation of the white noise on the yaw rate, rad/s.
    pub yaw_rate_noise_std_radps: f64,
    /// Amplitude of the slow roll and pitch oscillations, rad.
    pub roll_pitch_amplitude_rad: f64,
    /// Standard deviation of the noise on roll and pitch, rad.
    pub roll_pitch_noise_std_rad: f64,
}

impl Default for HeadingSimConfig {
    fn default() -> Self {
        Self {
            rate_hz: 10.0,
            yaw_noise_std_rad: 0.5f64.to_radians(),
            yaw_bias_rad: 1.5f64.to_radians(),
            yaw_drift_std_rad: 1.5f64.to_radians(),
            yaw_drift_time_constant_s: 240.0,
            yaw_rate_noise_std_radps: 0.2f64.to_radians(),
            roll_pitch_amplitude_rad: 1.5f64.to_radians(),
            roll_pitch_noise_std_rad: 0.2f64.to_radians(),
        }
    }
}

impl HeadingSimConfig {
    pub fn validate(&self) -> Result<(), SimError> {
        super::config::check_ranges(&[
            ("heading.rate_hz", self.rate_hz, 0.01, 1000.0),
            ("heading.yaw_noise_std_rad", self.yaw_noise_std_rad, 0.0, PI),
            ("heading.yaw_bias_rad", self.yaw_bias_rad, -PI, PI),
            ("heading.yaw_drift_std_rad", self.yaw_drift_std_rad, 0.0, PI),
            (
                "heading.yaw_drift_time_constant_s",
                self.yaw_drift_time_constant_s,
                1e-3,
                1e7,
            ),
            (
                "heading.yaw_rate_noise_std_radps",
                self.yaw_rate_noise_std_radps,
                0.0,
                10.0,
            ),
            (
                "heading.roll_pitch_amplitude_rad",
                self.roll_pitch_amplitude_rad,
                0.0,
                0.5 * PI,
            ),
            (
                "heading.roll_pitch_noise_std_rad",
                self.roll_pitch_noise_std_rad,
                0.0,
                0.5 * PI,
            ),
        ])
    }
}

fn normal<R: Rng>(rng: &mut R) -> f64 {
    StandardNormal.sample(rng)
}

/// DVL records over the whole trajectory. `vehicle_from_dvl` places the
/// instrument: the velocity of its own point (lever arm included) is reported
/// in its own axes.
pub fn simulate_dvl<R: Rng>(
    trajectory: &Trajectory,
    config: &DvlSimConfig,
    vehicle_from_dvl: &Se2,
    rng: &mut R,
) -> Vec<DvlVelocity> {
    let gaps = draw_gaps(trajectory, config, rng);
    let period = 1.0 / config.rate_hz;
    let count = (trajectory.duration_s() / period).floor() as usize;
    let lever = vehicle_from_dvl.translation();
    let dvl_from_vehicle_rot = Rotation2::new(-vehicle_from_dvl.theta());
    let mut out = Vec::with_capacity(count);
    for k in 0..count {
        let jitter = config.time_jitter_s * rng.random_range(-1.0..=1.0);
        let stamp_s = trajectory.start_s() + (k as f64 + 0.5) * period + jitter;
        let invalid = rng.random_bool(config.invalid_probability);
        let noise = Vector3::new(normal(rng), normal(rng), normal(rng));
        if gaps.iter().any(|&(a, b)| (a..b).contains(&stamp_s)) {
            continue;
        }
        if invalid {
            out.push(DvlVelocity {
                stamp_s,
                velocity_mps: Vector3::zeros(),
                valid: false,
                covariance: None,
            });
            continue;
        }
        let twist = trajectory.twist_at(stamp_s);
        // Velocity of the instrument's point: v + ω × r.
        let at_dvl = Vector2::new(twist.x - twist.z * lever.y, twist.y + twist.z * lever.x);
        let in_dvl = dvl_from_vehicle_rot * at_dvl * (1.0 + config.scale_error);
        out.push(DvlVelocity {
            stamp_s,
            velocity_mps: Vector3::new(
                in_dvl.x + config.noise_std_mps * noise.x,
                in_dvl.y + config.noise_std_mps * noise.y,
                config.vertical_noise_std_mps * noise.z,
            ),
            valid: true,
            covariance: None,
        });
    }
    out
}

/// Intervals `[start, end)` without DVL output (a Poisson process of gaps).
fn draw_gaps<R: Rng>(
    trajectory: &Trajectory,
    config: &DvlSimConfig,
    rng: &mut R,
) -> Vec<(f64, f64)> {
    let mut gaps = Vec::new();
    let (Ok(between), Ok(length)) = (
        Exp::new(config.gap_rate_per_hour / 3600.0),
        Exp::new(1.0 / config.gap_mean_s.max(1e-9)),
    ) else {
        return gaps;
    };
    if config.gap_rate_per_hour <= 0.0 || config.gap_mean_s <= 0.0 {
        return gaps;
    }
    let mut t = trajectory.start_s() + between.sample(rng);
    while t < trajectory.end_s() {
        let end = t + length.sample(rng);
        gaps.push((t, end));
        t = end + between.sample(rng);
    }
    gaps
}

/// Attitude records over the whole trajectory.
pub fn simulate_attitude<R: Rng>(
    trajectory: &Trajectory,
    config: &HeadingSimConfig,
    rng: &mut R,
) -> Vec<Attitude> {
    let period = 1.0 / config.rate_hz;
    let count = (trajectory.duration_s() / period).floor() as usize + 1;
    let amp = config.roll_pitch_amplitude_rad;
    // Exact discretisation of the Gauss-Markov process at the sample period.
    let keep = (-period / config.yaw_drift_time_constant_s).exp();
    let innovation = config.yaw_drift_std_rad * (1.0 - keep * keep).sqrt();
    let mut drift = config.yaw_drift_std_rad * normal(rng);
    (0..count)
        .map(|k| {
            let stamp_s = trajectory.start_s() + k as f64 * period;
            let age = stamp_s - trajectory.start_s();
            let truth = trajectory.pose_at(stamp_s);
            let rate = trajectory.twist_at(stamp_s).z;
            let roll_noise = config.roll_pitch_noise_std_rad * normal(rng);
            let pitch_noise = config.roll_pitch_noise_std_rad * normal(rng);
            let yaw_error = config.yaw_bias_rad + drift + config.yaw_noise_std_rad * normal(rng);
            let rate_noise = config.yaw_rate_noise_std_radps * normal(rng);
            drift = keep * drift + innovation * normal(rng);
            Attitude {
                stamp_s,
                roll_rad: amp * (2.0 * PI * age / 7.0).sin() + roll_noise,
                pitch_rad: amp * (2.0 * PI * age / 11.0 + 1.0).sin() + pitch_noise,
                yaw_rad: wrap_angle(truth.theta() + yaw_error),
                yaw_rate_radps: Some(rate + rate_noise),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn straight_line() -> Trajectory {
        // Heading north-east at 0.4 m/s forward, 0.1 m/s to port.
        let yaw = PI / 4.0;
        let (s, c) = yaw.sin_cos();
        let (u, v) = (0.4, 0.1);
        let poses = (0..=6000)
            .map(|i| {
                let t = i as f64 * 0.1;
                Se2::new((c * u - s * v) * t, (s * u + c * v) * t, yaw)
            })
            .collect();
        Trajectory::from_poses(1000.0, 0.1, poses).unwrap()
    }

    #[test]
    fn dvl_mean_velocity_shows_the_scale_error_and_noise_level() {
        let config = DvlSimConfig {
            gap_rate_per_hour: 0.0,
            ..DvlSimConfig::default()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let dvl = simulate_dvl(&straight_line(), &config, &Se2::identity(), &mut rng);
        let valid: Vec<_> = dvl.iter().filter(|d| d.valid).collect();
        let n = valid.len() as f64;
        assert!(
            n > 1700.0 && (dvl.len() as f64) < 1801.0,
            "{} of {}",
            n,
            dvl.len()
        );
        let mean_x = valid.iter().map(|d| d.velocity_mps.x).sum::<f64>() / n;
        let mean_y = valid.iter().map(|d| d.velocity_mps.y).sum::<f64>() / n;
        // 0.4 · 1.015 = 0.406, standard error 0.12 / sqrt(1760) ≈ 0.003.
        assert!((mean_x - 0.406).abs() < 0.01, "{mean_x}");
        assert!((mean_y - 0.1015).abs() < 0.01, "{mean_y}");
        let var_x = valid
            .iter()
            .map(|d| (d.velocity_mps.x - mean_x).powi(2))
            .sum::<f64>()
            / n;
        assert!((var_x.sqrt() - 0.12).abs() < 0.01, "{}", var_x.sqrt());
        assert!(dvl.windows(2).all(|w| w[1].stamp_s > w[0].stamp_s));
    }

    #[test]
    fn dvl_mounted_backwards_reports_negated_velocity_and_gaps_drop_samples() {
        let config = DvlSimConfig {
            noise_std_mps: 0.0,
            invalid_probability: 0.0,
            gap_rate_per_hour: 60.0,
            gap_mean_s: 10.0,
            ..DvlSimConfig::default()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let backwards = Se2::new(0.0, 0.0, PI);
        let dvl = simulate_dvl(&straight_line(), &config, &backwards, &mut rng);
        let first = &dvl[0];
        assert!(
            (first.velocity_mps.x + 0.406).abs() < 1e-6,
            "{:?}",
            first.velocity_mps
        );
        assert!((first.velocity_mps.y + 0.1015).abs() < 1e-6);
        // 600 s at 3 Hz is 1800 slots; ~10 gaps of ~10 s remove ~300.
        assert!(dvl.len() < 1750, "{}", dvl.len());
        let largest_gap = dvl
            .windows(2)
            .map(|w| w[1].stamp_s - w[0].stamp_s)
            .fold(0.0, f64::max);
        assert!(largest_gap > 3.0, "{largest_gap}");
    }

    #[test]
    fn heading_carries_its_bias_and_noise() {
        let config = HeadingSimConfig {
            yaw_drift_std_rad: 0.0,
            ..HeadingSimConfig::default()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let att = simulate_attitude(&straight_line(), &config, &mut rng);
        assert_eq!(att.len(), 6001);
        let errors: Vec<f64> = att
            .iter()
            .map(|a| wrap_angle(a.yaw_rad - PI / 4.0))
            .collect();
        let mean = errors.iter().sum::<f64>() / errors.len() as f64;
        assert!((mean - config.yaw_bias_rad).abs() < 0.001, "{mean}");
        let std =
            (errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / errors.len() as f64).sqrt();
        assert!((std - config.yaw_noise_std_rad).abs() < 0.001, "{std}");
        assert!(
            att.iter()
                .all(|a| a.roll_rad.abs() < 0.05 && a.yaw_rate_radps.is_some())
        );
    }

    #[test]
    fn heading_drift_wanders_slowly_with_its_configured_spread() {
        let config = HeadingSimConfig {
            yaw_bias_rad: 0.0,
            yaw_noise_std_rad: 0.0,
            yaw_drift_std_rad: 0.02,
            yaw_drift_time_constant_s: 5.0,
            ..HeadingSimConfig::default()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let att = simulate_attitude(&straight_line(), &config, &mut rng);
        let errors: Vec<f64> = att
            .iter()
            .map(|a| wrap_angle(a.yaw_rad - PI / 4.0))
            .collect();
        let n = errors.len() as f64;
        let std = (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
        // 600 s is 120 correlation times: the spread is within ~15%.
        assert!((std - 0.02).abs() < 0.004, "{std}");
        // Correlated: errors one sample apart are nearly equal.
        let lag1 = errors.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / (n - 1.0) / (std * std);
        assert!(lag1 > 0.95, "{lag1}");
    }
}
