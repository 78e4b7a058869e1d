//! The committed sample is what the simulator produces today, and writing
//! the same simulation twice gives the same bytes.

use echofield_datasets::mcap::{read_mission, write_mission};
use echofield_datasets::sim::{Scenario, simulate_mission};
use echofield_frontend::sensors::Mission;
use std::path::Path;

fn sample_path() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/tank-seed1.mcap")
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * (1.0 + a.abs().max(b.abs()) * 1e-6)
}

/// Equal up to last-bit differences of the maths library (see the samples
/// README).
fn assert_same_mission(committed: &Mission, fresh: &Mission) {
    assert_eq!(committed.name, fresh.name);
    assert_eq!(committed.mounting, fresh.mounting);
    assert_eq!(committed.beams.len(), fresh.beams.len());
    assert_eq!(committed.dvl.len(), fresh.dvl.len());
    assert_eq!(committed.attitude.len(), fresh.attitude.len());
    assert_eq!(committed.ground_truth.len(), fresh.ground_truth.len());
    let (mut bins, mut differing) = (0usize, 0usize);
    for (k, (a, b)) in committed.beams.iter().zip(&fresh.beams).enumerate() {
        assert!(
            close(a.stamp_s, b.stamp_s) && close(a.angle_rad, b.angle_rad),
            "beam {k}"
        );
        assert_eq!(a.intensities.len(), b.intensities.len(), "beam {k}");
        for (x, y) in a.intensities.iter().zip(&b.intensities) {
            bins += 1;
            if x != y {
                differing += 1;
                assert!(x.abs_diff(*y) <= 1, "beam {k}: {x} vs {y}");
            }
        }
    }
    assert!(
        differing * 10_000 <= bins,
        "{differing} of {bins} bins differ"
    );
    for (k, (a, b)) in committed.dvl.iter().zip(&fresh.dvl).enumerate() {
        assert!(close(a.stamp_s, b.stamp_s) && a.valid == b.valid, "dvl {k}");
        assert!((a.velocity_mps - b.velocity_mps).norm() <= 1e-9, "dvl {k}");
    }
    for (k, (a, b)) in committed.attitude.iter().zip(&fresh.attitude).enumerate() {
        assert!(
            close(a.stamp_s, b.stamp_s) && close(a.yaw_rad, b.yaw_rad),
            "attitude {k}"
        );
    }
    for (k, (a, b)) in committed
        .ground_truth
        .iter()
        .zip(&fresh.ground_truth)
        .enumerate()
    {
        let d = a.world_from_vehicle.to_vector() - b.world_from_vehicle.to_vector();
        assert!(
            close(a.stamp_s, b.stamp_s) && d.norm() <= 1e-9,
            "ground truth {k}"
        );
    }
}

#[test]
fn committed_sample_equals_a_fresh_simulation() {
    let path = sample_path();
    let size = std::fs::metadata(&path).unwrap().len();
    assert!(size < 2_000_000, "sample is {size} bytes");
    let committed = read_mission(&path).unwrap();
    let fresh = simulate_mission(&Scenario::named("tank").unwrap(), 1).unwrap();
    assert_same_mission(&committed, &fresh);
}

#[test]
fn writing_the_same_simulation_twice_gives_identical_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = Scenario::named("tank").unwrap();
    let (a, b) = (dir.path().join("a.mcap"), dir.path().join("b.mcap"));
    write_mission(&a, &simulate_mission(&scenario, 21).unwrap()).unwrap();
    write_mission(&b, &simulate_mission(&scenario, 21).unwrap()).unwrap();
    assert!(std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap());
    // And the file reads back to the simulated mission (poses travel as
    // [x, y, θ], so their rotations may differ in the last bit).
    assert_same_mission(
        &read_mission(&a).unwrap(),
        &simulate_mission(&scenario, 21).unwrap(),
    );
}
