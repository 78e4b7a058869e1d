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
    let duration_s = n_beams as f64 * BEAM_PERIOD_S;
    // One generator, drawn from stream after stream in this order.
    let beams = random_beams(&mut rng, n_beams, n_bins);
    let dvl = random_dvl(&mut rng, (duration_s * 5.0) as usize);
    let attitude = random_attitude(&mut rng, (duration_s * 10.0) as usize);
    let ground_truth = random_ground_truth(&mut rng, duration_s as usize);
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
        // None: the ROS 2 writer has no channel for them, and its tests
        // compare whole missions (the echofield round trip of fixes has
        // its own test).
        position_fixes: Vec::new(),
        warnings: Default::default(),
    }
}

/// The first stamp of every stream, s (Unix time).
const T0_S: f64 = 1.7e9;
/// The seed paper's beam period, s.
const BEAM_PERIOD_S: f64 = 0.068;

/// `n` beams of `n_bins` bins, 200 steps per turn: background noise with
/// one echo each (so the data compresses like sonar), stamps jittered by
/// up to 1 ms.
fn random_beams(rng: &mut ChaCha8Rng, n: usize, n_bins: usize) -> Vec<SonarBeam> {
    let step_rad = 2.0 * std::f64::consts::PI / 200.0;
    (0..n)
        .map(|k| {
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
                stamp_s: T0_S + k as f64 * BEAM_PERIOD_S + rng.random_range(-1e-3..1e-3),
                angle_rad: ((k % 200) as f64 * step_rad) - std::f64::consts::PI,
                bin_size_m: 0.1,
                first_bin_range_m: 0.0,
                intensities,
            }
        })
        .collect()
}

/// `n` DVL samples at 5 Hz; every 17th (from the 4th) invalid, every 3rd
/// with a covariance.
fn random_dvl(rng: &mut ChaCha8Rng, n: usize) -> Vec<DvlVelocity> {
    (0..n)
        .map(|k| DvlVelocity {
            stamp_s: T0_S + k as f64 * 0.2,
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
        .collect()
}

/// `n` attitude samples at 10 Hz; every other one with a yaw rate.
fn random_attitude(rng: &mut ChaCha8Rng, n: usize) -> Vec<Attitude> {
    (0..n)
        .map(|k| Attitude {
            stamp_s: T0_S + k as f64 * 0.1,
            roll_rad: rng.random_range(-0.05..0.05),
            pitch_rad: rng.random_range(-0.05..0.05),
            yaw_rad: rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
            yaw_rate_radps: (k % 2 == 0).then(|| rng.random_range(-0.1..0.1)),
        })
        .collect()
}

/// `n` ground-truth poses at 1 Hz, anywhere in a 120 m x 240 m box.
fn random_ground_truth(rng: &mut ChaCha8Rng, n: usize) -> Vec<GroundTruthPose> {
    (0..n)
        .map(|k| GroundTruthPose {
            stamp_s: T0_S + k as f64,
            world_from_vehicle: Se2::new(
                rng.random_range(-60.0..60.0),
                rng.random_range(-120.0..120.0),
                rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
            ),
        })
        .collect()
}
