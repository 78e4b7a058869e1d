//! The calibration on a small synthetic mission: a vehicle circling in a
//! walled basin, every beam's echo cast from the true pose through the
//! true head, the mission recorded with another head.

use super::objective::{HeadCandidate, Objective};
use super::*;
use crate::dead_reckoning::synthetic::{SyntheticNavConfig, SyntheticPath, synthetic_mission};
use crate::dead_reckoning::{self, DeadReckoningConfig};
use crate::mounting::restamp_sweep;
use crate::rotation::assemble_rotations;
use crate::sensors::{SonarBeam, SweepTiming};
use crate::sharpness::beam_returns;
use echofield_graph::{Se2, wrap_angle};

const BEAMS_PER_TURN: usize = 100;
const BEAM_PERIOD_S: f64 = 0.1;
const BIN_M: f64 = 0.1;
const BINS: usize = 400;

/// The basin's walls: a 50 m x 55 m box, a slanted quay and a block, all
/// clear of the vehicle's circle (centre (0, 12), radius 12).
const WALLS: [([f64; 2], [f64; 2]); 9] = [
    ([-25.0, -15.0], [25.0, -15.0]),
    ([25.0, -15.0], [25.0, 40.0]),
    ([25.0, 40.0], [-25.0, 40.0]),
    ([-25.0, 40.0], [-25.0, -15.0]),
    ([15.0, 32.0], [22.0, 24.0]),
    ([-20.0, -9.0], [-16.0, -9.0]),
    ([-16.0, -9.0], [-16.0, -5.0]),
    ([-16.0, -5.0], [-20.0, -5.0]),
    ([-20.0, -5.0], [-20.0, -9.0]),
];

/// Range from `from` along `heading_rad` to the nearest wall.
fn cast(from: (f64, f64), heading_rad: f64) -> Option<f64> {
    let (dx, dy) = (heading_rad.cos(), heading_rad.sin());
    WALLS
        .iter()
        .filter_map(|&(a, b)| {
            let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
            let det = ex * dy - ey * dx;
            if det.abs() < 1e-12 {
                return None;
            }
            let (wx, wy) = (a[0] - from.0, a[1] - from.1);
            let t = (ex * wy - ey * wx) / det;
            let s = (dx * wy - dy * wx) / det;
            (t > 0.0 && (0.0..=1.0).contains(&s)).then_some(t)
        })
        .min_by(f64::total_cmp)
}

/// The beams of `seconds` of a vehicle at `world_from_vehicle(t)` (`t`
/// from the start), cast through `truth`: one echo per beam, at the
/// nearest wall.
fn cast_beams(
    world_from_vehicle: impl Fn(f64) -> Se2,
    truth: &SensorMounting,
    start_s: f64,
    seconds: f64,
) -> Vec<SonarBeam> {
    let beams = (seconds / BEAM_PERIOD_S) as usize;
    (0..beams)
        .map(|k| {
            let t = k as f64 * BEAM_PERIOD_S;
            let angle_rad = wrap_angle(k as f64 * std::f64::consts::TAU / BEAMS_PER_TURN as f64);
            let beam = world_from_vehicle(t).compose(&truth.vehicle_from_beam(angle_rad));
            let mut intensities = vec![0u8; BINS];
            if let Some(r) = cast((beam.x(), beam.y()), beam.theta()) {
                let bin = (r / BIN_M) as usize;
                for (i, v) in [(bin.wrapping_sub(1), 120), (bin, 220), (bin + 1, 120)] {
                    if i < BINS {
                        intensities[i] = v;
                    }
                }
            }
            SonarBeam {
                stamp_s: start_s + t,
                angle_rad,
                bin_size_m: BIN_M,
                first_bin_range_m: 0.0,
                intensities,
            }
        })
        .collect()
}

/// `seconds` of the vehicle circling at 0.5 m/s (centre (0, 12), radius
/// 12), with noisy DVL and heading; beams cast through `truth`, the
/// mission's mounting `recorded`.
fn mission(truth: &SensorMounting, recorded: &SensorMounting, seconds: f64) -> Mission {
    let path = SyntheticPath::Circle {
        speed_mps: 0.5,
        radius_m: 12.0,
    };
    let config = SyntheticNavConfig {
        duration_s: seconds + 1.0,
        dvl_noise_mps: 0.02,
        heading_noise_rad: 0.002,
        ..SyntheticNavConfig::default()
    };
    let mut m = synthetic_mission(&path, &config, 3);
    m.beams = cast_beams(
        |t| path.world_from_vehicle(t),
        truth,
        config.start_s,
        seconds,
    );
    m.mounting = recorded.clone();
    m
}

/// `seconds` of a vehicle weaving east at 0.3 m/s (its heading swinging
/// ±60° with a period of 80 s) from (−16, 12), and its exact navigation:
/// turns both ways, which a lever arm along the vehicle needs (on a circle
/// it is a turn of the head).
fn weaving_mission(
    truth: &SensorMounting,
    recorded: &SensorMounting,
    seconds: f64,
) -> (Mission, Navigation) {
    let start_s = 1000.0;
    let dt = 0.05;
    let mut poses = vec![Se2::new(-16.0, 12.0, 0.0)];
    let heading = |t: f64| 60f64.to_radians() * (std::f64::consts::TAU * t / 80.0).sin();
    for k in 0..(seconds / dt) as usize + 2 {
        let (p, psi) = (poses[k], heading((k as f64 + 0.5) * dt));
        poses.push(Se2::new(
            p.x() + 0.3 * dt * psi.cos(),
            p.y() + 0.3 * dt * psi.sin(),
            heading((k + 1) as f64 * dt),
        ));
    }
    let stamps: Vec<f64> = (0..poses.len()).map(|k| start_s + k as f64 * dt).collect();
    let navigation = Navigation::from_poses(&stamps, &poses, 1.0).unwrap();
    let pose_at = |t: f64| navigation.pose_at(start_s + t).unwrap();
    let m = Mission {
        beams: cast_beams(pose_at, truth, start_s, seconds),
        mounting: recorded.clone(),
        ..Mission::default()
    };
    (m, navigation)
}

fn head(angle: AngleDirection, yaw_deg: f64, x_m: f64, y_m: f64) -> SensorMounting {
    SensorMounting {
        vehicle_from_sonar: Se2::new(x_m, y_m, yaw_deg.to_radians()),
        sonar_angle: angle,
        ..SensorMounting::default()
    }
}

fn config() -> CalibrationConfig {
    CalibrationConfig {
        window_rotations: 3,
        ..CalibrationConfig::default()
    }
}

fn run(m: &Mission) -> Result<Calibration, FrontendError> {
    let navigation = dead_reckoning::run(m, &DeadReckoningConfig::default())?;
    calibrate(
        m,
        &navigation,
        &RotationConfig::default(),
        &SegmentationConfig::default(),
        &config(),
    )
}

fn yaw_error_deg(result: &Calibration, truth_deg: f64) -> f64 {
    wrap_angle(result.sonar_yaw_rad.value - truth_deg.to_radians())
        .abs()
        .to_degrees()
}

#[test]
fn a_mirrored_head_turned_by_100_degrees_is_recovered() {
    let truth = head(AngleDirection::Clockwise, 100.0, 0.4, -0.2);
    let recorded = head(AngleDirection::CounterClockwise, 0.0, 0.4, -0.2);
    let result = run(&mission(&truth, &recorded, 130.0)).unwrap();
    assert_eq!(result.sonar_angle.value, AngleDirection::Clockwise);
    assert!(
        result.sonar_angle.vote.determined,
        "{:?}",
        result.sonar_angle
    );
    assert!(result.sweep.is_none());
    assert!(
        yaw_error_deg(&result, 100.0) < 0.5,
        "{:?}",
        result.sonar_yaw_rad
    );
    assert!(result.sonar_yaw_rad.determined);
    // The calibrated mounting is the truth's convention and yaw.
    let m = &result.mounting;
    assert_eq!(m.sonar_angle, AngleDirection::Clockwise);
    assert_eq!(m.source, crate::sensors::MountingSource::Config);
    assert!(!result.heading_offset_rad.determined);
}

#[test]
fn a_right_mounting_is_kept() {
    let truth = head(AngleDirection::CounterClockwise, -30.0, 0.4, -0.2);
    let result = run(&mission(&truth, &truth, 130.0)).unwrap();
    assert_eq!(result.sonar_angle.value, AngleDirection::CounterClockwise);
    assert!(
        yaw_error_deg(&result, -30.0) < 0.5,
        "{:?}",
        result.sonar_yaw_rad
    );
    // The lever arm given is right: a refit within the noise does not
    // replace it.
    assert_eq!(result.sonar_x_m.value, 0.4, "{:?}", result.sonar_x_m);
    assert_eq!(result.sonar_y_m.value, -0.2, "{:?}", result.sonar_y_m);
}

#[test]
fn a_lever_arm_a_metre_off_is_found_when_the_vehicle_turns_both_ways() {
    let truth = head(AngleDirection::CounterClockwise, -30.0, 0.4, -0.2);
    let wrong = head(AngleDirection::CounterClockwise, -30.0, -0.6, 0.8);
    let (m, navigation) = weaving_mission(&truth, &wrong, 240.0);
    let result = calibrate(
        &m,
        &navigation,
        &RotationConfig::default(),
        &SegmentationConfig::default(),
        &config(),
    )
    .unwrap();
    assert!(result.sonar_x_m.determined, "{:?}", result.sonar_x_m);
    let (dx, dy) = (result.sonar_x_m.value - 0.4, result.sonar_y_m.value + 0.2);
    assert!(dx.hypot(dy) < 0.2, "({dx}, {dy})");
    assert!(
        yaw_error_deg(&result, -30.0) < 0.5,
        "{:?}",
        result.sonar_yaw_rad
    );
}

#[test]
fn the_sweep_of_a_reconstruction_is_found() {
    // Beams whose stamps were rebuilt assuming the wrong sweep.
    let truth = head(AngleDirection::CounterClockwise, 45.0, 0.0, 0.0);
    let mut m = mission(&truth, &truth, 130.0);
    restamp_sweep(&mut m.beams).unwrap();
    m.mounting.sweep = SweepTiming::AngleDecreasing;
    let result = run(&m).unwrap();
    let sweep = result.sweep.unwrap();
    assert_eq!(sweep.value, SweepTiming::AngleIncreasing, "{sweep:?}");
    assert!(
        yaw_error_deg(&result, 45.0) < 0.5,
        "{:?}",
        result.sonar_yaw_rad
    );
}

#[test]
fn the_objective_is_lowest_at_the_true_head_and_the_search_finds_it() {
    let truth = head(AngleDirection::Clockwise, 100.0, 0.4, -0.2);
    let m = mission(&truth, &truth, 60.0);
    let start_s = SyntheticNavConfig::default().start_s;
    let stamps: Vec<f64> = (0..600).map(|k| start_s + k as f64 * 0.1).collect();
    let path = SyntheticPath::Circle {
        speed_mps: 0.5,
        radius_m: 12.0,
    };
    let poses: Vec<Se2> = stamps
        .iter()
        .map(|t| path.world_from_vehicle(t - start_s))
        .collect();
    let exact = Navigation::from_poses(&stamps, &poses, 1.0).unwrap();
    let rotations = assemble_rotations(&m.beams, &RotationConfig::default()).unwrap();
    let returns = beam_returns(&m.beams, &SegmentationConfig::default());
    let objective = Objective::new(&returns, &exact, &rotations, 3, 0.5);
    let all: Vec<usize> = (0..objective.windows()).collect();
    let at = |yaw_deg: f64, angle| HeadCandidate {
        sonar_angle: angle,
        yaw_rad: yaw_deg.to_radians(),
        x_m: 0.4,
        y_m: -0.2,
    };
    let best = objective.mean_entropy(&at(100.0, AngleDirection::Clockwise), &all);
    for other in [98.0, 102.0, 110.0, -80.0] {
        assert!(objective.mean_entropy(&at(other, AngleDirection::Clockwise), &all) > best);
    }
    let coarse = search::coarse_yaw(&objective, &at(0.0, AngleDirection::Clockwise), &all, 0.1);
    let found = search::refine_yaw(&objective, &coarse, &all, 0.1);
    assert!(
        (found.head.yaw_rad.to_degrees() - 100.0).abs() < 0.1,
        "{found:?}"
    );
    let mirrored = search::coarse_yaw(
        &objective,
        &at(0.0, AngleDirection::CounterClockwise),
        &all,
        0.1,
    );
    assert!(mirrored.mean_entropy_bits > found.mean_entropy_bits + 0.1);
}

#[test]
fn missions_that_cannot_be_calibrated_are_errors() {
    let truth = head(AngleDirection::CounterClockwise, 0.0, 0.0, 0.0);
    // Five rotations: fewer than a window of 3 and 6 blocks need.
    let err = run(&mission(&truth, &truth, 50.0)).unwrap_err().to_string();
    assert!(err.contains("rotations") && err.contains("window"), "{err}");
    let mut broken = mission(&truth, &truth, 130.0);
    broken.mounting.vehicle_from_sonar = Se2::new(f64::NAN, 0.0, 0.0);
    let err = run(&broken).unwrap_err().to_string();
    assert!(err.contains("vehicle_from_sonar"), "{err}");
    let mut silent = mission(&truth, &truth, 130.0);
    silent.beams.iter_mut().for_each(|b| b.intensities.fill(0));
    let err = run(&silent).unwrap_err().to_string();
    assert!(err.contains("echo"), "{err}");
    let mut empty = silent;
    empty.beams.clear();
    let err = run(&empty).unwrap_err().to_string();
    assert!(err.contains("no sonar beams"), "{err}");
}
