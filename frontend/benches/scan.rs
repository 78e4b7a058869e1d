//! Speed of the frontend stages before the image: dead reckoning over a
//! St Pere-length mission (about 5k DVL samples, 33k attitude samples,
//! 46k beams, 55.7 min), rotation assembly of its beams, and building `S_k`
//! for one rotation (200 beams x 500 bins): motion compensation (eq. 3-4)
//! plus segmentation and scan building.

use criterion::{Criterion, criterion_group, criterion_main};
use echofield_frontend::dead_reckoning::synthetic::{
    SyntheticNavConfig, SyntheticPath, synthetic_mission,
};
use echofield_frontend::dead_reckoning::{self, DeadReckoningConfig, Navigation};
use echofield_frontend::image::synthetic::{RotationPath, SceneConfig, simulate_rotation};
use echofield_frontend::motion::reference_from_beams;
use echofield_frontend::rotation::{RotationConfig, assemble_rotations};
use echofield_frontend::scan::build_scan;
use echofield_frontend::segmentation::SegmentationConfig;
use echofield_frontend::{Mission, SensorMounting, SonarBeam};
use echofield_graph::Se2;
use echofield_graph::se2::wrap_angle;
use std::hint::black_box;

const START_S: f64 = 1_093_448_100.0;
const DURATION_S: f64 = 3340.0;
const BEAM_PERIOD_S: f64 = 0.0722;

/// Navigation records of a St Pere-length mission: 4986 DVL samples
/// (0.67 s, 2% dropped), 33 401 attitude samples (10 Hz) with yaw rate.
fn stpere_length_mission() -> Mission {
    let path = SyntheticPath::Circle {
        speed_mps: 0.3,
        radius_m: 40.0,
    };
    let config = SyntheticNavConfig {
        start_s: START_S,
        duration_s: DURATION_S,
        dvl_noise_mps: 0.14,
        heading_noise_rad: 0.02,
        yaw_rate_noise_radps: 0.005,
        dvl_dropouts_s: (0..66)
            .map(|k| (k as f64 * 50.0, k as f64 * 50.0 + 1.0))
            .collect(),
        ..SyntheticNavConfig::default()
    };
    synthetic_mission(&path, &config, 7)
}

/// 46 259 beams of 500 bins, 200 steps per turn, one every 72.2 ms.
fn stpere_length_beams() -> Vec<SonarBeam> {
    (0..46_259)
        .map(|k| SonarBeam {
            stamp_s: START_S + k as f64 * BEAM_PERIOD_S,
            angle_rad: wrap_angle(k as f64 * std::f64::consts::TAU / 200.0),
            bin_size_m: 0.1,
            first_bin_range_m: 0.0,
            intensities: vec![0; 500],
        })
        .collect()
}

fn dead_reckoning_and_rotations(c: &mut Criterion) {
    let mission = stpere_length_mission();
    let config = DeadReckoningConfig::default();
    let mut group = c.benchmark_group("stpere_length");
    group.sample_size(20);
    group.bench_function("dead_reckoning_run", |b| {
        b.iter(|| dead_reckoning::run(black_box(&mission), &config).unwrap())
    });
    let nav = dead_reckoning::run(&mission, &config).unwrap();
    let beams = stpere_length_beams();
    group.bench_function("pose_at_every_beam", |b| {
        b.iter(|| {
            beams
                .iter()
                .map(|beam| nav.pose_at(beam.stamp_s).unwrap().x())
                .sum::<f64>()
        })
    });
    group.bench_function("assemble_rotations", |b| {
        b.iter(|| assemble_rotations(black_box(&beams), &RotationConfig::default()).unwrap())
    });
    group.finish();
}

/// One moving rotation of the synthetic basin, placed 1000 s into the
/// St Pere-length navigation so that lookups search the full history.
fn rotation_in_mission(nav_start_s: f64) -> Vec<SonarBeam> {
    let path = RotationPath {
        world_from_start: Se2::new(-3.0, 1.0, 0.2),
        velocity_mps: (0.5, 0.0),
        yaw_rate_radps: 0.02,
    };
    let mut beams = simulate_rotation(&SceneConfig::default(), &path, 3).beams;
    for beam in &mut beams {
        beam.stamp_s += nav_start_s + 1000.0;
    }
    beams
}

fn build_sk(c: &mut Criterion) {
    let nav: Navigation =
        dead_reckoning::run(&stpere_length_mission(), &DeadReckoningConfig::default()).unwrap();
    let beams = rotation_in_mission(nav.start_s());
    let t_ref = 0.5 * (beams[0].stamp_s + beams[beams.len() - 1].stamp_s);
    let mounting = SensorMounting {
        vehicle_from_sonar: Se2::new(0.33, 0.0, std::f64::consts::PI),
        vehicle_from_dvl: Se2::identity(),
        heading_offset_rad: 0.0,
        ..Default::default()
    };
    let config = SegmentationConfig::default();
    let frames = reference_from_beams(&beams, &nav, &mounting, t_ref).unwrap();
    let mut group = c.benchmark_group("build_sk_200x500");
    group.bench_function("motion_compensation", |b| {
        b.iter(|| reference_from_beams(black_box(&beams), &nav, &mounting, t_ref).unwrap())
    });
    group.bench_function("segmentation_and_scan", |b| {
        b.iter(|| build_scan(black_box(&beams), &frames, t_ref, &config).unwrap())
    });
    group.bench_function("total", |b| {
        b.iter(|| {
            let frames = reference_from_beams(black_box(&beams), &nav, &mounting, t_ref).unwrap();
            build_scan(&beams, &frames, t_ref, &config).unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, dead_reckoning_and_rotations, build_sk);
criterion_main!(benches);
