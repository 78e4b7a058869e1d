//! The St Pere replay keeps the real beam times and navigation, follows the
//! DGPS track and puts walls where the sonar can see them.

use echofield_datasets::sim::{Scenario, simulate_mission};
use echofield_datasets::stpere::read_stpere_dir;
use echofield_frontend::sensors::Mission;
use nalgebra::Point2;
use std::sync::OnceLock;

fn replay() -> &'static (Scenario, Mission) {
    static REPLAY: OnceLock<(Scenario, Mission)> = OnceLock::new();
    REPLAY.get_or_init(|| {
        let scenario =
            Scenario::named("stpere").expect("the St Pere logs in datasets/stpere-marina");
        let mission = simulate_mission(&scenario, 1).unwrap();
        (scenario, mission)
    })
}

/// The stamps of `_IS_timestamps.log`, read here line by line.
fn logged_beam_stamps() -> Vec<f64> {
    let path = Scenario::default_stpere_dir().join("_040825_1735_IS_timestamps.log");
    let text = std::fs::read_to_string(&path).unwrap();
    text.lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('%'))
        .map(|l| l.split_whitespace().next().unwrap().parse::<f64>().unwrap())
        .collect()
}

#[test]
fn beams_are_simulated_at_every_real_beam_time_with_the_logged_setup() {
    let (_, m) = replay();
    let stamps = logged_beam_stamps();
    assert_eq!(stamps.len(), 46259);
    assert_eq!(m.beams.len(), stamps.len());
    for (beam, stamp) in m.beams.iter().zip(&stamps) {
        assert_eq!(beam.stamp_s, *stamp);
        assert_eq!(beam.intensities.len(), 500);
        assert_eq!(beam.bin_size_m, 0.1);
    }
    // _SETUP.log: 0.0314159 rad per step.
    let step = echofield_graph::wrap_angle(m.beams[1].angle_rad - m.beams[0].angle_rad);
    assert!((step - 0.031_415_9).abs() < 1e-6, "{step}");
}

#[test]
fn navigation_records_are_the_real_ones_unchanged() {
    let (_, m) = replay();
    let logs = read_stpere_dir(&Scenario::default_stpere_dir()).unwrap();
    assert_eq!(m.dvl, logs.mission.dvl);
    assert_eq!(m.attitude, logs.mission.attitude);
    assert_eq!(
        m.mounting.vehicle_from_dvl,
        logs.mission.mounting.vehicle_from_dvl
    );
}

#[test]
fn ground_truth_follows_the_dgps_fixes_and_the_offset_mti_heading() {
    let (scenario, m) = replay();
    let fixes = scenario.dgps_fixes();
    assert!(fixes.len() > 3000);
    let truth = scenario.ground_truth();
    let errors: Vec<f64> = fixes
        .iter()
        .map(|(t, p)| {
            let pose = truth.pose_at(*t);
            (pose.x() - p[0]).hypot(pose.y() - p[1])
        })
        .collect();
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    let worst = errors.iter().cloned().fold(0.0, f64::max);
    assert!(rms < 0.3 && worst < 1.5, "rms {rms:.3} m, max {worst:.3} m");
    // The heading offset is the reader's documented +19.4 deg.
    let offset = scenario.heading_offset_rad().unwrap().to_degrees();
    assert!((offset - 19.4).abs() < 0.5, "{offset}");
    let logs = read_stpere_dir(&Scenario::default_stpere_dir()).unwrap();
    let a = &logs.mission.attitude[5000];
    let expected = echofield_graph::wrap_angle(a.yaw_rad + offset.to_radians());
    let gt_yaw = truth.pose_at(a.stamp_s).theta();
    assert!(echofield_graph::wrap_angle(gt_yaw - expected).abs() < 2f64.to_radians());
    // Ground truth records span the beams and the DGPS.
    assert!(m.ground_truth[0].stamp_s <= m.beams[0].stamp_s);
    assert!(m.ground_truth.last().unwrap().stamp_s >= fixes.last().unwrap().0 - 0.1);
}

#[test]
fn structures_stand_5_to_40_m_from_the_track_and_most_rotations_see_walls() {
    let (scenario, m) = replay();
    let env = scenario.environment();
    let truth = scenario.ground_truth();
    let nearest: Vec<f64> = truth
        .poses()
        .iter()
        .step_by(50)
        .map(|p| env.distance_to_nearest(Point2::new(p.x(), p.y())))
        .collect();
    let min = nearest.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(min >= 5.0, "a structure only {min:.2} m from the track");
    let far = nearest.iter().filter(|d| **d > 40.0).count();
    assert_eq!(far, 0);
    // Per rotation of 200 beams: the share of beams whose axis meets a
    // structure within the 50 m range.
    let mount = m.mounting.vehicle_from_sonar;
    let seeing: Vec<f64> = m
        .beams
        .chunks(200)
        .map(|rotation| {
            let hits = rotation
                .iter()
                .filter(|b| {
                    let head = truth.pose_at(b.stamp_s).compose(&mount);
                    let origin = Point2::new(head.x(), head.y());
                    env.cast_ray(origin, head.theta() + b.angle_rad, 50.0)
                        .is_some()
                })
                .count();
            hits as f64 / rotation.len() as f64
        })
        .collect();
    let good = seeing.iter().filter(|f| **f >= 0.5).count();
    assert!(
        good * 10 >= 9 * seeing.len(),
        "{good} of {} rotations see walls with half their beams",
        seeing.len()
    );
}
