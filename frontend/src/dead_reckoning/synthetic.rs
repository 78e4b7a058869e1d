//! Synthetic navigation records with known ground truth, for tests and
//! benchmarks (the full mission simulator lives in `echofield-datasets`).
//!
//! A [`SyntheticPath`] gives the true `world_from_vehicle` in closed form;
//! [`synthetic_mission`] samples DVL velocities (in the DVL frame of the
//! mounting, with the lever-arm term) and attitude from it, with seeded
//! Gaussian noise, a constant heading bias and DVL dropouts.

use crate::sensors::{Attitude, DvlVelocity, GroundTruthPose, Mission, SensorMounting};
use echofield_graph::Se2;
use echofield_graph::se2::wrap_angle;
use nalgebra::{Vector2, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// A vehicle path starting at the world origin at time `SyntheticNavConfig::start_s`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SyntheticPath {
    /// Constant forward speed along a fixed heading (speed 0: standing still).
    Straight { speed_mps: f64, heading_rad: f64 },
    /// Constant forward speed on a circle, starting with heading 0;
    /// counter-clockwise for a positive radius, clockwise for a negative one.
    Circle { speed_mps: f64, radius_m: f64 },
}

impl SyntheticPath {
    /// True `world_from_vehicle` `t_s` seconds after the start.
    pub fn world_from_vehicle(&self, t_s: f64) -> Se2 {
        match *self {
            SyntheticPath::Straight {
                speed_mps,
                heading_rad,
            } => {
                let d = speed_mps * t_s;
                Se2::new(d * heading_rad.cos(), d * heading_rad.sin(), heading_rad)
            }
            SyntheticPath::Circle {
                speed_mps,
                radius_m,
            } => {
                let theta = speed_mps / radius_m * t_s;
                Se2::new(
                    radius_m * theta.sin(),
                    radius_m * (1.0 - theta.cos()),
                    theta,
                )
            }
        }
    }

    /// Velocity of the vehicle origin in the vehicle frame, m/s.
    pub fn body_velocity_mps(&self) -> Vector2<f64> {
        match *self {
            SyntheticPath::Straight { speed_mps, .. } | SyntheticPath::Circle { speed_mps, .. } => {
                Vector2::new(speed_mps, 0.0)
            }
        }
    }

    /// Yaw rate, rad/s.
    pub fn yaw_rate_radps(&self) -> f64 {
        match *self {
            SyntheticPath::Straight { .. } => 0.0,
            SyntheticPath::Circle {
                speed_mps,
                radius_m,
            } => speed_mps / radius_m,
        }
    }
}

/// Sampling and noise of [`synthetic_mission`].
#[derive(Clone, Debug, PartialEq)]
pub struct SyntheticNavConfig {
    /// Absolute stamp of the start, s.
    pub start_s: f64,
    pub duration_s: f64,
    /// DVL sample period, s (St Pere: about 0.67).
    pub dvl_period_s: f64,
    /// Attitude sample period, s (St Pere: 0.1).
    pub attitude_period_s: f64,
    /// Per-axis DVL velocity noise (standard deviation), m/s.
    pub dvl_noise_mps: f64,
    /// Heading noise (standard deviation), rad.
    pub heading_noise_rad: f64,
    /// Constant error added to every reported yaw, rad.
    pub heading_bias_rad: f64,
    /// A wandering error added to every reported yaw: a Gauss-Markov
    /// process of this standard deviation (rad; 0 = none) ...
    pub heading_wander_sigma_rad: f64,
    /// ... and this correlation time, s.
    pub heading_wander_time_constant_s: f64,
    /// Attitude samples carry the true yaw rate (plus `yaw_rate_noise_radps`).
    pub with_yaw_rate: bool,
    pub yaw_rate_noise_radps: f64,
    /// Constant error added to every yaw rate, rad/s.
    pub yaw_rate_bias_radps: f64,
    /// DVL samples inside these intervals (s after the start) are flagged
    /// invalid, their velocity set to NaN.
    pub dvl_dropouts_s: Vec<(f64, f64)>,
    pub mounting: SensorMounting,
}

impl Default for SyntheticNavConfig {
    fn default() -> Self {
        Self {
            start_s: 1000.0,
            duration_s: 60.0,
            dvl_period_s: 0.67,
            attitude_period_s: 0.1,
            dvl_noise_mps: 0.0,
            heading_noise_rad: 0.0,
            heading_bias_rad: 0.0,
            heading_wander_sigma_rad: 0.0,
            heading_wander_time_constant_s: 120.0,
            with_yaw_rate: true,
            yaw_rate_noise_radps: 0.0,
            yaw_rate_bias_radps: 0.0,
            dvl_dropouts_s: Vec::new(),
            mounting: SensorMounting::default(),
        }
    }
}

/// DVL, attitude and ground-truth records of `path` (no beams), with noise
/// drawn from a ChaCha8 generator seeded with `seed`. A test fixture: panics
/// if a noise standard deviation is negative or not finite.
pub fn synthetic_mission(path: &SyntheticPath, config: &SyntheticNavConfig, seed: u64) -> Mission {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // The DVL's draws come first, then the attitude's.
    let dvl = synthetic_dvl(path, config, &mut rng);
    let attitude = synthetic_attitude(path, config, &mut rng);
    let ground_truth = sample_times(config, config.attitude_period_s)
        .map(|t| GroundTruthPose {
            stamp_s: config.start_s + t,
            world_from_vehicle: path.world_from_vehicle(t),
        })
        .collect();
    Mission {
        name: "synthetic".into(),
        mounting: config.mounting.clone(),
        beams: Vec::new(),
        dvl,
        attitude,
        ground_truth,
        position_fixes: Vec::new(),
        warnings: Default::default(),
    }
}

/// A zero-mean normal distribution; panics (a test fixture) when `sigma`
/// is negative or not finite.
fn normal(sigma: f64) -> Normal<f64> {
    Normal::new(0.0, sigma).expect("finite non-negative sigma")
}

/// Times from 0 to `duration_s` every `period_s`, s after `start_s`.
fn sample_times(config: &SyntheticNavConfig, period_s: f64) -> impl Iterator<Item = f64> {
    (0..=(config.duration_s / period_s).floor() as usize).map(move |i| i as f64 * period_s)
}

/// The DVL samples: the velocity of the DVL point (lever arm included) in
/// the DVL frame, with noise; NaN and invalid within the dropouts.
fn synthetic_dvl(
    path: &SyntheticPath,
    config: &SyntheticNavConfig,
    rng: &mut ChaCha8Rng,
) -> Vec<DvlVelocity> {
    let dvl_noise = normal(config.dvl_noise_mps);
    let w = path.yaw_rate_radps();
    let vehicle_from_dvl = &config.mounting.vehicle_from_dvl;
    let lever = vehicle_from_dvl.translation();
    // Velocity of the DVL point in the vehicle frame, then in the DVL frame.
    let v_dvl_vehicle = path.body_velocity_mps() + w * Vector2::new(-lever.y, lever.x);
    let v_dvl = vehicle_from_dvl.rotation_matrix().transpose() * v_dvl_vehicle;
    sample_times(config, config.dvl_period_s)
        .map(|t| {
            let dropped = config.dvl_dropouts_s.iter().any(|&(a, b)| t >= a && t < b);
            let noisy = Vector3::new(
                v_dvl.x + dvl_noise.sample(rng),
                v_dvl.y + dvl_noise.sample(rng),
                0.0,
            );
            DvlVelocity {
                stamp_s: config.start_s + t,
                velocity_mps: if dropped {
                    Vector3::repeat(f64::NAN)
                } else {
                    noisy
                },
                valid: !dropped,
                covariance: None,
            }
        })
        .collect()
}

/// The attitude samples: the true heading plus bias, wander and noise;
/// the yaw rate (when configured) plus bias and noise.
fn synthetic_attitude(
    path: &SyntheticPath,
    config: &SyntheticNavConfig,
    rng: &mut ChaCha8Rng,
) -> Vec<Attitude> {
    let (heading_noise, rate_noise) = (
        normal(config.heading_noise_rad),
        normal(config.yaw_rate_noise_radps),
    );
    let w = path.yaw_rate_radps();
    // The wander starts from its stationary distribution and is exact at
    // the sample period: b' = a·b + √(σ²(1 − a²))·n, a = e^{−Δt/τ}.
    let sigma_b = config.heading_wander_sigma_rad;
    let decay = (-config.attitude_period_s / config.heading_wander_time_constant_s).exp();
    let mut wander = sigma_b * normal(1.0).sample(rng);
    let wander_step = normal(sigma_b * (1.0 - decay * decay).sqrt());
    sample_times(config, config.attitude_period_s)
        .map(|t| {
            let yaw = wrap_angle(
                path.world_from_vehicle(t).theta()
                    + config.heading_bias_rad
                    + wander
                    + heading_noise.sample(rng),
            );
            wander = decay * wander + wander_step.sample(rng);
            Attitude {
                stamp_s: config.start_s + t,
                roll_rad: 0.0,
                pitch_rad: 0.0,
                yaw_rad: yaw,
                yaw_rate_radps: config
                    .with_yaw_rate
                    .then(|| w + config.yaw_rate_bias_radps + rate_noise.sample(rng)),
            }
        })
        .collect()
}
