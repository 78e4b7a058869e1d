//! A seeded synthetic mission for MCAP tests and benchmarks: the right
//! shapes and rates, not a physical simulation (that is `crate::sim`).

use echofield_frontend::sensors::{
    Attitude, DvlVelocity, GroundTruthPose, Mission, SensorMounting, SonarBeam,
};
use echofield_graph::Se2;
use nalgebra::{Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A mission of `n_beams` beams of `n_bins` bins at the seed paper's MSIS
/// timing (200 steps per turn, 68 ms per beam, 0.1 m bins), with DVL at 5 Hz,
/// attitude at 10 Hz and ground truth at 1 Hz over the same time span,
/// starting at Unix time 1.7e9 s. Every optional field is exercised: some DVL
/// samples are invalid, some carry a covariance, some attitude samples carry
/// a yaw rate. Same seed, same mission.
pub fn random_mission(n_beams: usize, n_bins: usize, seed: u64) -> Mission {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let t0_s = 1.7e9;
    let beam_period_s = 0.068;
    let duration_s = n_beams as f64 * beam_period_s;
    let step_rad = 2.0 * std::f64::consts::PI / 200.0;

    let beams = (0..n_beams)
        .map(|k| {
            // Background noise with one echo, so the data compresses like sonar.
            let wall = rng.random_range(0..n_bins.max(1));
            let intensities = (0..n_bins)
                .map(|i| {
                    if i.abs_diff(wall) < 3 {
                        rng.random_range(150..=255)
                    } else {
                        rng.random_range(0..24)
                    }
                })
                .collect();
            SonarBeam {
                stamp_s: t0_s + k as f64 * beam_period_s + rng.random_range(-1e-3..1e-3),
                angle_rad: ((k % 200) as f64 * step_rad) - std::f64::consts::PI,
                bin_size_m: 0.1,
                first_bin_range_m: 0.0,
                intensities,
            }
        })
        .collect();

    let n_dvl = (duration_s * 5.0) as usize;
    let dvl = (0..n_dvl)
        .map(|k| DvlVelocity {
            stamp_s: t0_s + k as f64 * 0.2,
            velocity_mps: Vector3::new(
                rng.random_range(0.2..0.5),
                rng.random_range(-0.05..0.05),
                rng.random_range(-0.02..0.02),
            ),
            valid: k % 17 != 3,
            covariance: (k % 3 == 0).then(|| {
                Matrix3::new(0.01, 0.001, 0.0, 0.001, 0.012, 0.0, 0.0, 0.0, 0.02)
                    * rng.random_range(0.5..2.0)
            }),
        })
        .collect();

    let n_att = (duration_s * 10.0) as usize;
    let attitude = (0..n_att)
        .map(|k| Attitude {
            stamp_s: t0_s + k as f64 * 0.1,
            roll_rad: rng.random_range(-0.05..0.05),
            pitch_rad: rng.random_range(-0.05..0.05),
            yaw_rad: rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
            yaw_rate_radps: (k % 2 == 0).then(|| rng.random_range(-0.1..0.1)),
        })
        .collect();

    let n_gt = duration_s as usize;
    let ground_truth = (0..n_gt)
        .map(|k| GroundTruthPose {
            stamp_s: t0_s + k as f64,
            world_from_vehicle: Se2::new(
                rng.random_range(-60.0..60.0),
                rng.random_range(-120.0..120.0),
                rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
            ),
        })
        .collect();

    Mission {
        name: format!("random mission (seed {seed})"),
        mounting: SensorMounting {
            vehicle_from_sonar: Se2::new(0.6, 0.0, std::f64::consts::PI),
            vehicle_from_dvl: Se2::new(-0.3, 0.05, 0.0),
            heading_offset_rad: 0.25,
            ..Default::default()
        },
        beams,
        dvl,
        attitude,
        ground_truth,
        warnings: Default::default(),
    }
}
