//! The seed paper's experiment (section 6): the scan `S_k` and the acoustic
//! image `I_k` built from the same rotation, so the true displacement is
//! `[0, 0, 0]`; the argmax of `s(x)` must lie within 0.05 m and 0.5° of it
//! for every rotation of a simulated mission, of the St Pere replay, and of
//! the real static Ping360 and MiniKing recordings.
//!
//! The search starts from a prior 0.36 m and 2° away, in a window of
//! ±0.5 m and ±5°, so the maximum is found, not assumed.

use echofield::matching::{MatchingConfig, MissionRotations};
use echofield_datasets::sim::{Scenario, SimConfig, simulate_mission};
use echofield_frontend::matcher::{MatchOutcome, SearchWindow, match_scan};
use echofield_graph::Se2;
use echofield_tests::{datasets_dir, miniking_config, miniking_log, ping360_config, ping360_log};

const TOLERANCE_M: f64 = 0.05;
const TOLERANCE_DEG: f64 = 0.5;

/// Matches every rotation with a scan against its own image; returns the
/// worst translation (m) and angle (deg) errors and the number of rotations
/// without a scan. Panics naming the rotation on a miss.
fn self_match_every_rotation(
    name: &str,
    mission: &MissionRotations,
    config: &MatchingConfig,
    keep: impl Fn(usize) -> bool,
) -> (f64, f64, usize) {
    let prior = Se2::new(0.3, -0.2, 2.0_f64.to_radians());
    let window = SearchWindow::new(0.5, 0.5, 5.0_f64.to_radians());
    let (mut worst_m, mut worst_deg, mut without_scan, mut matched) = (0.0_f64, 0.0_f64, 0, 0);
    for rotation in mission.rotations.iter().filter(|r| keep(r.index)) {
        let k = rotation.index;
        let Ok((scan, image)) = mission.scan_and_image(k, config) else {
            without_scan += 1;
            continue;
        };
        let outcome = match_scan(&scan.points, &image, &prior, &window, &config.matcher).unwrap();
        let MatchOutcome::Match(m) = outcome else {
            panic!("{name} rotation {k}: {outcome:?}");
        };
        let (dt, dtheta) = (
            m.image_from_scan.translation().norm(),
            m.image_from_scan.theta().abs().to_degrees(),
        );
        assert!(
            dt < TOLERANCE_M && dtheta < TOLERANCE_DEG,
            "{name} rotation {k}: argmax at {:?} ({dt:.3} m, {dtheta:.2} deg)",
            m.image_from_scan.to_vector()
        );
        worst_m = worst_m.max(dt);
        worst_deg = worst_deg.max(dtheta);
        matched += 1;
    }
    assert!(matched > 0, "{name}: no rotation matched");
    (worst_m, worst_deg, without_scan)
}

#[test]
fn simulated_tank_mission() {
    let mission = simulate_mission(&Scenario::named("tank").unwrap(), 1).unwrap();
    let config = MatchingConfig::default();
    let rotations = MissionRotations::new(mission, &config).unwrap();
    assert!(rotations.rotations.len() >= 8);
    let (_, _, without) = self_match_every_rotation("tank", &rotations, &config, |_| true);
    assert_eq!(without, 0);
}

#[test]
fn st_pere_replay() {
    let scenario =
        Scenario::stpere(&datasets_dir().join("stpere-marina"), SimConfig::default()).unwrap();
    let mission = simulate_mission(&scenario, 3).unwrap();
    let config = MatchingConfig::default();
    let rotations = MissionRotations::new(mission, &config).unwrap();
    assert!(
        rotations.rotations.len() > 200,
        "{}",
        rotations.rotations.len()
    );
    let (_, _, without) = self_match_every_rotation("stpere", &rotations, &config, |_| true);
    // Rotations far from every structure give too few ranges for a scan
    // (14 of 231 with seed 3).
    assert!(
        without * 10 <= rotations.rotations.len(),
        "{without} without a scan"
    );
}

#[test]
fn real_ping360_log() {
    let path = ping360_log();
    let config = ping360_config();
    let rotations = MissionRotations::load(&path, &config).unwrap();
    assert!(rotations.stationary);
    // The 10 m and 20 m rotations (full turns and sector sweeps); the first
    // is at the 2 m start-up range, all inside the ringing.
    let long_range = |k: usize| {
        let r = &rotations.rotations[k];
        rotations.mission.beams[r.beams.start].max_range_m() > 5.0
    };
    assert!(
        (0..rotations.rotations.len())
            .filter(|&k| long_range(k))
            .count()
            >= 20
    );
    let (_, _, without) = self_match_every_rotation("ping360", &rotations, &config, long_range);
    // The last sweep, cut short at the end of the log, has no strong return.
    assert!(without <= 1, "{without} without a scan");
}

#[test]
fn real_miniking_log() {
    let path = miniking_log();
    let config = miniking_config();
    let rotations = MissionRotations::load(&path, &config).unwrap();
    assert!(rotations.stationary);
    assert_eq!(rotations.rotations.len(), 2);
    let (_, _, without) = self_match_every_rotation("miniking", &rotations, &config, |_| true);
    assert_eq!(without, 0);
}
