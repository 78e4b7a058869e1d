//! `calibrate` on simulated missions written with deliberately wrong
//! mountings: the sign of the head's angle and its yaw come back to the
//! simulator's truth, and the file written is a config `run` accepts.
//!
//! The mission: the simulated marina's first 11 waypoints (once round the
//! mole and up the east side, about 22 minutes, 89 rotations), seed 1.
//! Its head is the simulator's: counter-clockwise, yaw 180°, at (0.33 m, 0).
//! The tests allow the 1° on the yaw.

use echofield::calibration::output::config_toml;
use echofield::calibration::{CalibrateSettings, calibrate_mission};
use echofield::slam::SlamConfig;
use echofield_datasets::sim::{Scenario, SimConfig, follow_route, scenes, simulate_mission};
use echofield_frontend::calibration::Calibration;
use echofield_frontend::sensors::{AngleDirection, Mission, SweepTiming};
use echofield_graph::{Se2, wrap_angle};
use std::sync::OnceLock;

/// The first 11 waypoints of the simulated marina, seed 1, as simulated.
fn marina_start() -> &'static Mission {
    static MISSION: OnceLock<Mission> = OnceLock::new();
    MISSION.get_or_init(|| {
        let scene = scenes::marina().unwrap();
        let config = SimConfig::default();
        let route = &scene.route[..11];
        let truth = follow_route(route, &config.vehicle, config.start_stamp_s).unwrap();
        let scenario = Scenario::custom("marina-start", scene.environment, truth, config).unwrap();
        simulate_mission(&scenario, 1).unwrap()
    })
}

/// The simulator's head: what every case must come back to.
fn true_head() -> (AngleDirection, f64) {
    let m = SimConfig::default().mounting;
    (m.sonar_angle, m.vehicle_from_sonar.theta())
}

fn calibrate(mission: &Mission) -> Calibration {
    calibrate_mission(mission, &CalibrateSettings::default()).unwrap()
}

fn yaw_error_deg(result: &Calibration, truth_rad: f64) -> f64 {
    wrap_angle(result.sonar_yaw_rad.value - truth_rad)
        .abs()
        .to_degrees()
}

/// The mission with its head recorded `offset_deg` away from the truth.
fn turned(offset_deg: f64) -> Mission {
    let mut m = marina_start().clone();
    let s = m.mounting.vehicle_from_sonar;
    m.mounting.vehicle_from_sonar = Se2::new(
        s.x(),
        s.y(),
        wrap_angle(s.theta() + offset_deg.to_radians()),
    );
    m
}

#[test]
fn the_head_is_simulated_counter_clockwise_at_180_degrees() {
    // What the cases below assume of the simulator.
    let (angle, yaw) = true_head();
    assert_eq!(angle, AngleDirection::CounterClockwise);
    assert!((yaw.abs() - std::f64::consts::PI).abs() < 1e-12);
    assert_eq!(marina_start().mounting.sonar_angle, angle);
    assert_eq!(marina_start().mounting.sweep, SweepTiming::Logged);
}

#[test]
fn a_mirrored_head_recorded_counter_clockwise_comes_out_clockwise() {
    // Every angle negated: the true head now counts clockwise (the beam at
    // logged angle −θ points where the simulator's beam at θ did).
    let mut m = marina_start().clone();
    for beam in &mut m.beams {
        beam.angle_rad = wrap_angle(-beam.angle_rad);
    }
    m.mounting.sonar_angle = AngleDirection::CounterClockwise;
    assert_sign_and_yaw(&m, AngleDirection::Clockwise);
}

#[test]
fn a_head_recorded_clockwise_comes_out_counter_clockwise() {
    let mut m = marina_start().clone();
    m.mounting.sonar_angle = AngleDirection::Clockwise;
    assert_sign_and_yaw(&m, AngleDirection::CounterClockwise);
}

/// Calibrates `m` and checks that the sign comes out as `expected`, decided
/// by the data, and the yaw within 1° of the simulator's.
fn assert_sign_and_yaw(m: &Mission, expected: AngleDirection) {
    let result = calibrate(m);
    assert_eq!(result.sonar_angle.value, expected);
    assert!(
        result.sonar_angle.vote.determined,
        "{:?}",
        result.sonar_angle
    );
    let (_, yaw) = true_head();
    assert!(
        yaw_error_deg(&result, yaw) < 1.0,
        "{:?}",
        result.sonar_yaw_rad
    );
}

/// The head recorded `offset_deg` off the truth comes back to it.
fn recovers_a_yaw_offset_of(offset_deg: f64) {
    let (angle, yaw) = true_head();
    let result = calibrate(&turned(offset_deg));
    assert_eq!(result.sonar_angle.value, angle);
    let err = yaw_error_deg(&result, yaw);
    assert!(err < 1.0, "{err} deg: {:?}", result.sonar_yaw_rad);
    assert!(
        result.sonar_yaw_rad.determined,
        "{:?}",
        result.sonar_yaw_rad
    );
    // A constant heading offset cannot be seen: it is kept.
    assert!(!result.heading_offset_rad.determined);
}

#[test]
fn a_yaw_offset_of_30_degrees_is_recovered_within_a_degree() {
    recovers_a_yaw_offset_of(30.0);
}

#[test]
fn a_yaw_offset_of_90_degrees_is_recovered_within_a_degree() {
    recovers_a_yaw_offset_of(90.0);
}

#[test]
fn a_yaw_offset_of_180_degrees_is_recovered_within_a_degree() {
    recovers_a_yaw_offset_of(180.0);
}

#[test]
fn the_file_written_is_a_config_run_accepts_with_the_calibrated_mounting() {
    let m = turned(90.0);
    let settings = CalibrateSettings::from_toml_str(
        "[calibration]\ncoarse_yaw_step_deg = 6.0\n\n[segmentation]\nmin_intensity = 55.0\n",
    )
    .unwrap();
    let result = calibrate_mission(&m, &settings).unwrap();
    let text = config_toml(&result, &m.name, &settings.other_sections);
    let config = SlamConfig::from_toml_str(&text).unwrap();
    // The pipeline's settings travel with the mounting.
    assert_eq!(config.segmentation.min_intensity, 55.0);
    let applied = config.mounting.apply(&m).unwrap();
    let mounting = &applied.mounting;
    assert_eq!(mounting.sonar_angle, result.sonar_angle.value);
    let (_, yaw) = true_head();
    assert!(wrap_angle(mounting.vehicle_from_sonar.theta() - yaw).abs() < 1f64.to_radians());
    assert_eq!(mounting.heading_offset_rad, m.mounting.heading_offset_rad);
    assert!(
        text.contains("sonar_x_m = ") && text.contains("sonar_y_m = "),
        "{text}"
    );
    assert!(
        !text.contains("sweep"),
        "a logged mission takes no sweep: {text}"
    );
}
