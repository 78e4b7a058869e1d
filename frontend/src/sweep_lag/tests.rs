use super::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::TAU;

/// One head step: 400 per turn, like a Ping360.
const STEP: f64 = TAU / 400.0;

/// Point targets (true angle rad, range m, strength) in a sector around π
/// (so that the sweeps cross the ±π wrap).
fn targets(seed: u64) -> Vec<(f64, f64, f64)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..40)
        .map(|_| {
            (
                std::f64::consts::PI + STEP * rng.random_range(-28.0..28.0),
                rng.random_range(1.0..9.0),
                rng.random_range(80.0..250.0),
            )
        })
        .collect()
}

/// Beams of `sweeps` back-and-forth sweeps over ±30 steps around π, the
/// first increasing, reported `lag_rad` ahead of the true angle in the
/// direction of travel; echoes 1.5 steps wide in angle, plus noise.
fn sector_scan(
    scene: &[(f64, f64, f64)],
    lag_rad: f64,
    sweeps: usize,
    seed: u64,
) -> Vec<SonarBeam> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut beams = Vec::new();
    for s in 0..sweeps {
        let direction = if s % 2 == 0 { 1.0 } else { -1.0 };
        let ks: Vec<i32> = if direction > 0.0 {
            (-30..30).collect()
        } else {
            (-29..=30).rev().collect()
        };
        for k in ks {
            let reported = std::f64::consts::PI + f64::from(k) * STEP;
            let true_angle = reported - direction * lag_rad;
            let intensities = (0..100)
                .map(|bin| {
                    let range = (bin as f64 + 0.5) * 0.1;
                    let echo: f64 = scene
                        .iter()
                        .map(|&(a, r, v)| {
                            let da = wrap_angle(true_angle - a) / (1.5 * STEP);
                            let dr = (range - r) / 0.2;
                            v * (-0.5 * (da * da + dr * dr)).exp()
                        })
                        .sum();
                    (echo + rng.random_range(0.0..20.0)).min(255.0) as u8
                })
                .collect();
            beams.push(SonarBeam {
                stamp_s: beams.len() as f64 * 0.05,
                angle_rad: wrap_angle(reported),
                bin_size_m: 0.1,
                first_bin_range_m: 0.0,
                intensities,
            });
        }
    }
    beams
}

#[test]
fn a_known_lag_is_estimated_and_corrected() {
    let scene = targets(1);
    for lag_steps in [0.5, -0.3, 0.0, 1.2] {
        let mut beams = sector_scan(&scene, lag_steps * STEP, 8, 2);
        let estimate = estimate_sweep_lag(&beams, &SweepLagConfig::default()).unwrap();
        assert!(
            (estimate.lag_rad / STEP - lag_steps).abs() < 0.1,
            "{lag_steps}: {estimate:?}"
        );
        // The first and the last sweep are cut by the ends of the data, six
        // run from reversal to reversal: five pairs.
        assert_eq!(estimate.pairs, 5, "{estimate:?}");
        assert!(estimate.correlation > 0.5, "{estimate:?}");
        correct_sweep_lag(&mut beams, estimate.lag_rad).unwrap();
        let after = estimate_sweep_lag(&beams, &SweepLagConfig::default()).unwrap();
        assert!(after.lag_rad.abs() / STEP < 0.1, "{lag_steps}: {after:?}");
    }
}

#[test]
fn sweeps_without_repeatable_structure_give_no_estimate() {
    // A new random scene on every sweep: nothing persists.
    let mut beams = Vec::new();
    for s in 0..8u64 {
        let sweep = sector_scan(&targets(100 + s), 0.0, 8, 3 + s);
        let per_sweep = sweep.len() / 8;
        let part = &sweep[s as usize * per_sweep..(s as usize + 1) * per_sweep];
        beams.extend(part.iter().cloned());
    }
    for (i, b) in beams.iter_mut().enumerate() {
        b.stamp_s = i as f64 * 0.05;
    }
    let err = estimate_sweep_lag(&beams, &SweepLagConfig::default()).unwrap_err();
    assert!(err.to_string().contains("correlates above"), "{err}");
}

#[test]
fn correction_follows_the_last_move_including_jumps_and_repeats() {
    let angles = [0.0, 0.0, 1.0, 2.0, 2.0, 1.0, 3.0, 3.0];
    let mut beams: Vec<SonarBeam> = angles
        .iter()
        .enumerate()
        .map(|(i, &k)| SonarBeam {
            stamp_s: i as f64,
            angle_rad: k * STEP,
            bin_size_m: 0.1,
            first_bin_range_m: 0.0,
            intensities: vec![0; 4],
        })
        .collect();
    correct_sweep_lag(&mut beams, 0.25 * STEP).unwrap();
    let got: Vec<f64> = beams.iter().map(|b| b.angle_rad / STEP).collect();
    // Leading repeats take the first move (+); the repeat at 2 keeps +; the
    // step back to 1 is -; the jump to 3 is +.
    let expected = [-0.25, -0.25, 0.75, 1.75, 1.75, 1.25, 2.75, 2.75];
    for (g, e) in got.iter().zip(expected) {
        assert!((g - e).abs() < 1e-9, "{got:?}");
    }
    assert!(correct_sweep_lag(&mut beams, f64::NAN).is_err());
}

#[test]
fn config_is_validated() {
    SweepLagConfig::default().validate().unwrap();
    let bad = [
        SweepLagConfig {
            max_shift_steps: 0,
            ..SweepLagConfig::default()
        },
        SweepLagConfig {
            min_range_m: -1.0,
            ..SweepLagConfig::default()
        },
        SweepLagConfig {
            max_range_m: Some(0.0),
            ..SweepLagConfig::default()
        },
        SweepLagConfig {
            min_correlation: 2.0,
            ..SweepLagConfig::default()
        },
        SweepLagConfig {
            min_peak_contrast: -0.1,
            ..SweepLagConfig::default()
        },
        SweepLagConfig {
            min_common_angles: 1,
            ..SweepLagConfig::default()
        },
    ];
    for config in bad {
        assert!(config.validate().is_err(), "{config:?}");
    }
    let parsed: SweepLagConfig = serde_json::from_str(r#"{"min_range_m": 0.5}"#).unwrap();
    assert_eq!(parsed.min_range_m, 0.5);
    assert!(serde_json::from_str::<SweepLagConfig>(r#"{"min_range": 0.5}"#).is_err());
}
