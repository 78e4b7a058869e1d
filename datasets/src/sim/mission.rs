//! From a scenario and a seed to a whole mission.
//!
//! Determinism: every random draw comes from a ChaCha8 stream keyed by the
//! seed and by what it is for (beam `k`, the DVL, the heading unit, the
//! blobs), so the output does not depend on evaluation order: beams are
//! rendered in parallel with rayon and collected in index order.

use super::scenario::Source;
use super::sonar::blobs::{Blob, BlobProcess, spawn_blobs};
use super::{Scenario, SimError, SonarModel, navigation};
use echofield_frontend::sensors::{
    Attitude, DvlVelocity, GroundTruthPose, Mission, SensorMounting, SonarBeam,
};
use echofield_graph::{Se2, wrap_angle};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Purposes of the random streams (high bits of the ChaCha stream id).
const STREAM_BEAM: u64 = 1;
const STREAM_DVL: u64 = 2;
const STREAM_HEADING: u64 = 3;
const STREAM_BLOBS: u64 = 4;
const STREAM_GPS: u64 = 5;

/// The random stream for `purpose` and `index` under `seed`.
pub fn stream_rng(seed: u64, purpose: u64, index: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream((purpose << 48) | (index & ((1 << 48) - 1)));
    rng
}

/// Simulates the sonar beams, navigation records and ground truth of
/// `scenario`. The same scenario and seed give an identical mission.
pub fn simulate_mission(scenario: &Scenario, seed: u64) -> Result<Mission, SimError> {
    let config = scenario.config();
    let truth = scenario.ground_truth();
    let sonar = SonarModel::new(&config.sonar)?;
    let blobs = spawn_blobs(
        truth,
        &BlobProcess {
            rate_per_min: sonar.config().blob_rate_per_min,
            mean_lifetime_s: sonar.config().blob_lifetime_s,
            snr_db: sonar.config().blob_snr_db,
            max_range_m: sonar.config().max_range_m(),
        },
        &mut stream_rng(seed, STREAM_BLOBS, 0),
    );
    let (beam_stamps, dvl, attitude, vehicle_from_dvl) = navigation_records(scenario, seed);
    let vehicle_from_sonar = config.mounting.vehicle_from_sonar;
    let beams = render_beams(
        scenario,
        &sonar,
        &blobs,
        &beam_stamps,
        &vehicle_from_sonar,
        seed,
    );
    Ok(Mission {
        name: format!("{} (simulated, seed {seed})", scenario.name()),
        mounting: SensorMounting {
            vehicle_from_sonar,
            vehicle_from_dvl,
            // The replay's navigation is the real, uncalibrated MTi yaw: the
            // calibration that relates it to the true heading travels with
            // the mission, as it would for a real vehicle.
            heading_offset_rad: scenario.heading_offset_rad().unwrap_or(0.0),
            ..SensorMounting::default()
        },
        beams,
        dvl,
        attitude,
        ground_truth: ground_truth_records(scenario),
        position_fixes: super::gps::simulate_fixes(
            truth,
            &config.gps,
            &mut stream_rng(seed, STREAM_GPS, 0),
        ),
        warnings: Default::default(),
    })
}

/// The beam stamps (s), DVL and attitude records and the DVL's mounting
/// `vehicle_from_dvl`: simulated along the ground truth (each from its own
/// random stream) for a synthetic scenario, the logged ones for a replay.
fn navigation_records(
    scenario: &Scenario,
    seed: u64,
) -> (Vec<f64>, Vec<DvlVelocity>, Vec<Attitude>, Se2) {
    let config = scenario.config();
    let truth = scenario.ground_truth();
    match &scenario.source {
        Source::Synthetic => {
            let stamps = synthetic_beam_stamps(scenario, seed);
            let mounting = &config.mounting;
            let dvl = navigation::simulate_dvl(
                truth,
                &config.dvl,
                &mounting.vehicle_from_dvl,
                &mut stream_rng(seed, STREAM_DVL, 0),
            );
            let attitude = navigation::simulate_attitude(
                truth,
                &config.heading,
                &mut stream_rng(seed, STREAM_HEADING, 0),
            );
            (stamps, dvl, attitude, mounting.vehicle_from_dvl)
        }
        Source::Replay(data) => (
            data.beam_stamps_s.clone(),
            data.dvl.clone(),
            data.attitude.clone(),
            data.vehicle_from_dvl,
        ),
    }
}

/// One beam per stamp, beam `k` at angle `k · step` (wrapped), rendered in
/// parallel from the true pose at its own time (the vehicle moves during
/// the rotation), each with its own random stream.
fn render_beams(
    scenario: &Scenario,
    sonar: &SonarModel,
    blobs: &[Blob],
    beam_stamps: &[f64],
    vehicle_from_sonar: &Se2,
    seed: u64,
) -> Vec<SonarBeam> {
    let truth = scenario.ground_truth();
    let step = sonar.config().step_rad();
    let bin_size_m = sonar.config().bin_size_m;
    let env = scenario.environment();
    beam_stamps
        .par_iter()
        .enumerate()
        .map(|(k, &stamp_s)| {
            let mut rng = stream_rng(seed, STREAM_BEAM, k as u64);
            let angle_rad = wrap_angle(k as f64 * step);
            let world_from_sonar = truth.pose_at(stamp_s).compose(vehicle_from_sonar);
            SonarBeam {
                stamp_s,
                angle_rad,
                bin_size_m,
                first_bin_range_m: 0.0,
                intensities: sonar.render_beam(
                    env,
                    blobs,
                    &world_from_sonar,
                    angle_rad,
                    stamp_s,
                    &mut rng,
                ),
            }
        })
        .collect()
}

/// Beam times on the nominal grid of the head from the start of the ground
/// truth, each displaced by its own jitter draw (strictly increasing since
/// the jitter is below half a period).
fn synthetic_beam_stamps(scenario: &Scenario, seed: u64) -> Vec<f64> {
    let truth = scenario.ground_truth();
    let sonar = &scenario.config().sonar;
    let period = sonar.beam_period_s;
    let count = ((truth.duration_s() - 2.0 * sonar.beam_time_jitter_s) / period)
        .floor()
        .max(0.0) as usize;
    (0..count)
        .map(|k| {
            // A separate stream index range from the beam renderer's.
            let mut rng = stream_rng(seed, STREAM_BEAM, (1 << 47) | k as u64);
            let jitter = sonar.beam_time_jitter_s * rng.random_range(-1.0..=1.0);
            truth.start_s() + sonar.beam_time_jitter_s + k as f64 * period + jitter
        })
        .collect()
}

fn ground_truth_records(scenario: &Scenario) -> Vec<GroundTruthPose> {
    let truth = scenario.ground_truth();
    let period = 1.0 / scenario.config().ground_truth_rate_hz;
    let count = (truth.duration_s() / period).floor() as usize + 1;
    (0..count)
        .map(|k| {
            let stamp_s = truth.start_s() + k as f64 * period;
            GroundTruthPose {
                stamp_s,
                world_from_vehicle: truth.pose_at(stamp_s),
            }
        })
        .collect()
}
