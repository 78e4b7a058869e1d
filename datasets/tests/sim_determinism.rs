//! Same seed, same mission (whatever the number of threads); another seed,
//! another mission; and the mission has the shape the config asks for.

use echofield_datasets::sim::{Scenario, SimConfig, SimError, simulate_mission};
use echofield_graph::wrap_angle;
use std::f64::consts::PI;

#[test]
fn same_seed_gives_the_same_mission_on_any_thread_count() {
    let scenario = Scenario::named("tank").unwrap();
    let a = simulate_mission(&scenario, 3).unwrap();
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let b = one_thread.install(|| simulate_mission(&scenario, 3).unwrap());
    assert!(a == b, "missions differ between runs");
    let c = simulate_mission(&Scenario::named("tank").unwrap(), 3).unwrap();
    assert!(a == c, "missions differ between scenario instances");
}

#[test]
fn another_seed_changes_the_noise_but_not_the_world() {
    let scenario = Scenario::named("tank").unwrap();
    let a = simulate_mission(&scenario, 3).unwrap();
    let b = simulate_mission(&scenario, 4).unwrap();
    assert_eq!(a.ground_truth, b.ground_truth);
    assert_eq!(a.beams.len(), b.beams.len());
    let same_beams = a
        .beams
        .iter()
        .zip(&b.beams)
        .filter(|(x, y)| x.intensities == y.intensities)
        .count();
    assert_eq!(same_beams, 0);
    assert_ne!(a.dvl, b.dvl);
    assert_ne!(a.attitude, b.attitude);
}

#[test]
fn tank_mission_has_the_configured_shape() {
    let scenario = Scenario::named("tank").unwrap();
    let config = SimConfig::default();
    let m = simulate_mission(&scenario, 9).unwrap();
    let duration = scenario.ground_truth().duration_s();
    assert!((100.0..300.0).contains(&duration), "{duration}");
    // Beams: 68 ms apart on average, jitter under 2 ms, 200 steps per turn.
    let n = m.beams.len() as f64;
    assert!(
        (n - duration / 0.068).abs() <= 2.0,
        "{n} beams in {duration} s"
    );
    for (k, w) in m.beams.windows(2).enumerate() {
        let dt = w[1].stamp_s - w[0].stamp_s;
        assert!((0.064..=0.072).contains(&dt), "beam {k}: {dt}");
        let step = wrap_angle(w[1].angle_rad - w[0].angle_rad);
        assert!((step - 2.0 * PI / 200.0).abs() < 1e-9);
    }
    for b in &m.beams {
        assert_eq!(b.intensities.len(), 500);
        assert_eq!(b.bin_size_m, 0.1);
        assert!(b.angle_rad > -PI && b.angle_rad <= PI);
    }
    // DVL at ~3 Hz minus gaps; attitude and ground truth at 10 Hz.
    let dvl_rate = m.dvl.len() as f64 / duration;
    assert!((2.0..=3.05).contains(&dvl_rate), "{dvl_rate}");
    assert!(m.dvl.windows(2).all(|w| w[1].stamp_s > w[0].stamp_s));
    assert!((m.attitude.len() as f64 - 10.0 * duration).abs() <= 2.0);
    assert!((m.ground_truth.len() as f64 - 10.0 * duration).abs() <= 2.0);
    assert_eq!(m.mounting, config.mounting);
    assert!(m.name.contains("tank") && m.name.contains('9'));
    assert_eq!(m.ground_truth[0].stamp_s, config.start_stamp_s);
}

#[test]
fn unknown_scenario_and_bad_config_are_errors() {
    match Scenario::named("harbour") {
        Err(SimError::UnknownScenario { name, known }) => {
            assert_eq!(name, "harbour");
            assert!(known.contains("marina") && known.contains("stpere"));
        }
        other => panic!("{other:?}"),
    }
    let mut config = SimConfig::default();
    config.sonar.sub_rays = 0;
    let err = Scenario::build("tank", config, None).unwrap_err();
    assert!(err.to_string().contains("sonar.sub_rays"), "{err}");
    let missing = std::path::Path::new("/nonexistent/stpere");
    let err = Scenario::build("stpere", SimConfig::default(), Some(missing)).unwrap_err();
    assert!(err.to_string().contains("/nonexistent/stpere"), "{err}");
}

/// `[gps]`: off by default (no fixes, the mission as before); on, fixes
/// at the configured period within `surface_s` of the start and the end,
/// each off the ground truth by the configured noise, from a random
/// stream of their own (every other stream unchanged), seeded.
#[test]
fn gps_fixes_are_off_by_default_and_seeded_noisy_truth_when_on() {
    use echofield_datasets::sim::GpsSimConfig;
    let plain = simulate_mission(&Scenario::named("tank").unwrap(), 5).unwrap();
    assert!(plain.position_fixes.is_empty());
    let config = SimConfig {
        gps: GpsSimConfig {
            period_s: 1.0,
            noise_std_m: 1.5,
            surface_s: 40.0,
        },
        ..SimConfig::default()
    };
    let scenario = Scenario::build("tank", config, None).unwrap();
    let with = simulate_mission(&scenario, 5).unwrap();
    assert_eq!(with, simulate_mission(&scenario, 5).unwrap());
    let mut without_fixes = with.clone();
    without_fixes.position_fixes.clear();
    assert!(without_fixes == plain, "the other streams changed");

    let truth = scenario.ground_truth();
    let (start, end) = (truth.start_s(), truth.end_s());
    let fixes = &with.position_fixes;
    // 40 or 41 stamps in each window of 40 s at 1 s (the windows do not
    // overlap on the tank's mission, which is longer than 80 s).
    assert!(end - start > 80.0);
    assert!((80..=82).contains(&fixes.len()), "{} fixes", fixes.len());
    let mut squares = 0.0;
    for f in fixes {
        assert!(f.stamp_s - start <= 40.0 || end - f.stamp_s <= 40.0);
        assert_eq!(f.std_m, 1.5);
        let p = truth.pose_at(f.stamp_s);
        squares += (f.x_m - p.x()).powi(2) + (f.y_m - p.y()).powi(2);
    }
    // Per-axis RMS of 164 draws of N(0, 1.5²): within 20 % of 1.5 m
    // (about 2.6 standard errors).
    let rms = (squares / (2.0 * fixes.len() as f64)).sqrt();
    assert!((rms - 1.5).abs() < 0.3, "per-axis RMS {rms} m");
    let other_seed = simulate_mission(&scenario, 6).unwrap();
    assert_ne!(other_seed.position_fixes, with.position_fixes);
}
