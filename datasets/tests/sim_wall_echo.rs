//! A vehicle at a known distance from a wall gets its echo peak within one
//! bin of that range, whether it holds still or moves during the rotation,
//! through the default sonar mounting (0.33 m ahead, turned 180 deg).

use echofield_datasets::sim::{
    EnvironmentBuilder, Material, Scenario, SimConfig, Trajectory, simulate_mission,
};
use echofield_frontend::sensors::{Mission, SonarBeam};
use echofield_graph::{Se2, wrap_angle};
use nalgebra::Vector3;

/// Wall along the y axis at x = `WALL_X_M`.
const WALL_X_M: f64 = 12.0;

fn wall_scenario(truth: Trajectory, config: SimConfig) -> Scenario {
    let mut b = EnvironmentBuilder::new();
    b.segment([WALL_X_M, -80.0], [WALL_X_M, 80.0], Material::CONCRETE);
    Scenario::custom("wall", b.build("wall").unwrap(), truth, config).unwrap()
}

/// A config with every random or spurious part of the echo model off.
fn clean_config() -> SimConfig {
    let mut config = SimConfig::default();
    config.sonar.speckle_looks = 1e6;
    config.sonar.multipath_gain = 0.0;
    config.sonar.spike_probability = 0.0;
    config.sonar.blob_rate_per_min = 0.0;
    config
}

/// Expected range from the sonar head to the wall along the beam, computed
/// here from the geometry: head at `world_from_vehicle ⊕ (0.33, 0, π)`,
/// beam bearing = head yaw + transducer angle.
fn expected_range(world_from_vehicle: &Se2, beam: &SonarBeam) -> Option<f64> {
    let yaw = world_from_vehicle.theta();
    let head_x = world_from_vehicle.x() + 0.33 * yaw.cos();
    let bearing = wrap_angle(yaw + std::f64::consts::PI + beam.angle_rad);
    (bearing.abs() <= 10f64.to_radians()).then(|| (WALL_X_M - head_x) / bearing.cos())
}

/// Bin of the strongest echo beyond the blind zone (1 m).
fn peak_bin(beam: &SonarBeam) -> usize {
    let first = (1.0 / beam.bin_size_m).ceil() as usize;
    (first..beam.intensities.len())
        .max_by_key(|&i| (beam.intensities[i], std::cmp::Reverse(i)))
        .unwrap()
}

/// For each beam facing the wall: (bin error, peak intensity).
fn peak_errors(mission: &Mission, truth: &Trajectory) -> Vec<(i64, u8)> {
    mission
        .beams
        .iter()
        .filter_map(|beam| {
            let range = expected_range(&truth.pose_at(beam.stamp_s), beam)?;
            let expected_bin = (range / beam.bin_size_m).floor() as i64;
            let peak = peak_bin(beam);
            Some((peak as i64 - expected_bin, beam.intensities[peak]))
        })
        .collect()
}

#[test]
fn still_vehicle_sees_the_wall_peak_within_one_bin() {
    let config = clean_config();
    // 3 m from the origin, heading 25 deg: the head is at x = 3 + 0.33 cos 25°.
    let truth = Trajectory::stationary(
        Se2::new(3.0, -1.0, 25f64.to_radians()),
        config.start_stamp_s,
        60.0,
        0.1,
    )
    .unwrap();
    let mission = simulate_mission(&wall_scenario(truth.clone(), config), 11).unwrap();
    let errors = peak_errors(&mission, &truth);
    // 20 deg of 360 per rotation, 4 rotations in 60 s.
    assert!(
        errors.len() >= 40,
        "only {} beams face the wall",
        errors.len()
    );
    for (error, peak) in &errors {
        assert!(error.abs() <= 1, "peak {error} bins off: {errors:?}");
        assert!(*peak >= 100, "weak echo {peak}");
    }
}

#[test]
fn moving_vehicle_sees_the_wall_at_each_beams_own_range() {
    let config = clean_config();
    // Driving at 0.5 m/s towards the wall, heading 0, from x = -10 m: the
    // range shrinks by 3.4 cm per beam, 6.8 m per rotation.
    let start = config.start_stamp_s;
    let poses: Vec<Se2> = (0..=400)
        .map(|i| Se2::new(-10.0 + 0.05 * i as f64, 2.0, 0.0))
        .collect();
    let twists = vec![Vector3::new(0.5, 0.0, 0.0); poses.len()];
    let truth = Trajectory::new(start, 0.1, poses, twists).unwrap();
    let mission = simulate_mission(&wall_scenario(truth.clone(), config), 5).unwrap();
    let errors = peak_errors(&mission, &truth);
    assert!(
        errors.len() >= 25,
        "only {} beams face the wall",
        errors.len()
    );
    for (error, _) in &errors {
        assert!(error.abs() <= 1, "peak {error} bins off: {errors:?}");
    }
    // Had the beams been cast from the rotation's first pose instead, the
    // error would reach tens of bins: make sure the ranges really do change.
    let ranges: Vec<f64> = mission
        .beams
        .iter()
        .filter_map(|b| expected_range(&truth.pose_at(b.stamp_s), b))
        .collect();
    let spread = ranges.iter().cloned().fold(f64::MIN, f64::max)
        - ranges.iter().cloned().fold(f64::MAX, f64::min);
    assert!(spread > 10.0, "{spread}");
}

#[test]
fn full_noise_model_keeps_almost_every_wall_peak_within_one_bin() {
    let config = SimConfig::default();
    let truth = Trajectory::stationary(
        Se2::new(0.0, 0.0, -10f64.to_radians()),
        config.start_stamp_s,
        140.0,
        0.1,
    )
    .unwrap();
    let mission = simulate_mission(&wall_scenario(truth.clone(), config), 2).unwrap();
    let errors = peak_errors(&mission, &truth);
    assert!(errors.len() >= 100, "{}", errors.len());
    let good = errors.iter().filter(|(e, _)| e.abs() <= 1).count();
    assert!(
        good * 100 >= 95 * errors.len(),
        "{good} of {} within one bin: {errors:?}",
        errors.len()
    );
}
