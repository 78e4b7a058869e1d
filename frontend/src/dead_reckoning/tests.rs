use super::synthetic::{SyntheticNavConfig, SyntheticPath, synthetic_mission};
use super::*;
use echofield_graph::Se2;
use echofield_graph::se2::wrap_angle;
use nalgebra::{Matrix3, Vector3};

const STRAIGHT: SyntheticPath = SyntheticPath::Straight {
    speed_mps: 0.5,
    heading_rad: 2.5,
};
const CIRCLE: SyntheticPath = SyntheticPath::Circle {
    speed_mps: 0.4,
    radius_m: -6.0,
};

fn truth_at(path: &SyntheticPath, config: &SyntheticNavConfig, stamp_s: f64) -> Se2 {
    path.world_from_vehicle(stamp_s - config.start_s)
}

fn pose_error(a: &Se2, b: &Se2) -> (f64, f64) {
    (
        (a.translation() - b.translation()).norm(),
        wrap_angle(a.theta() - b.theta()).abs(),
    )
}

#[test]
fn noise_free_straight_and_circular_motion_is_recovered() {
    let sim = SyntheticNavConfig::default();
    for path in [STRAIGHT, CIRCLE] {
        let mission = synthetic_mission(&path, &sim, 1);
        let nav = run(&mission, &DeadReckoningConfig::default()).unwrap();
        assert_eq!(nav.start_s(), sim.start_s);
        // 60 s on a 6 m circle is 0.64 turns: the heading crosses ±π.
        for k in 0..=120 {
            let t = sim.start_s + 0.5 * k as f64 + 0.013;
            let (dp, dth) = pose_error(&nav.pose_at(t).unwrap(), &truth_at(&path, &sim, t));
            assert!(dp < 2e-3 && dth < 1e-6, "{path:?} t={t}: {dp} m, {dth} rad");
        }
    }
}

#[test]
fn circle_without_yaw_rate_stays_close_using_heading_updates_only() {
    let sim = SyntheticNavConfig {
        with_yaw_rate: false,
        ..SyntheticNavConfig::default()
    };
    let mission = synthetic_mission(&CIRCLE, &sim, 1);
    let nav = run(&mission, &DeadReckoningConfig::default()).unwrap();
    let end = sim.start_s + sim.duration_s;
    let (dp, dth) = pose_error(&nav.pose_at(end).unwrap(), &truth_at(&CIRCLE, &sim, end));
    // The heading lags by about two attitude periods: 0.067 rad/s x 0.2 s.
    assert!(dp < 0.3 && dth < 0.02, "{dp} m, {dth} rad");
}

#[test]
fn heading_offset_cancels_a_constant_heading_bias() {
    let sim = SyntheticNavConfig {
        heading_bias_rad: 0.35,
        ..SyntheticNavConfig::default()
    };
    let mission = synthetic_mission(&STRAIGHT, &sim, 1);
    let end = sim.start_s + sim.duration_s;
    let truth = truth_at(&STRAIGHT, &sim, end);
    let biased = run(&mission, &DeadReckoningConfig::default()).unwrap();
    assert!(pose_error(&biased.pose_at(end).unwrap(), &truth).0 > 5.0);
    let config = DeadReckoningConfig {
        heading_offset_rad: -0.35,
        ..DeadReckoningConfig::default()
    };
    let corrected = run(&mission, &config).unwrap();
    let (dp, dth) = pose_error(&corrected.pose_at(end).unwrap(), &truth);
    assert!(dp < 2e-3 && dth < 1e-6, "{dp} m, {dth} rad");
}

#[test]
fn dvl_mounting_rotation_and_lever_arm_are_compensated() {
    let sim = SyntheticNavConfig {
        mounting: crate::sensors::SensorMounting {
            vehicle_from_sonar: Se2::identity(),
            vehicle_from_dvl: Se2::new(1.2, -0.4, std::f64::consts::FRAC_PI_2),
            heading_offset_rad: 0.0,
            ..Default::default()
        },
        ..SyntheticNavConfig::default()
    };
    let mission = synthetic_mission(&CIRCLE, &sim, 1);
    let end = sim.start_s + sim.duration_s;
    let truth = truth_at(&CIRCLE, &sim, end);
    let nav = run(&mission, &DeadReckoningConfig::default()).unwrap();
    let (dp, _) = pose_error(&nav.pose_at(end).unwrap(), &truth);
    assert!(dp < 2e-3, "{dp} m");
    let no_lever = DeadReckoningConfig {
        lever_arm_compensation: false,
        ..DeadReckoningConfig::default()
    };
    let nav = run(&mission, &no_lever).unwrap();
    // ω × r = 0.067 rad/s x 1.26 m: about 0.08 m/s of error for 60 s.
    assert!(pose_error(&nav.pose_at(end).unwrap(), &truth).0 > 1.0);
}

#[test]
fn covariance_grows_through_a_dvl_dropout_and_the_gap_is_reported() {
    let sim = SyntheticNavConfig {
        dvl_dropouts_s: vec![(20.0, 40.0)],
        ..SyntheticNavConfig::default()
    };
    let mission = synthetic_mission(&STRAIGHT, &sim, 1);
    let run_with = |smoothing| {
        let config = DeadReckoningConfig {
            smoothing,
            ..DeadReckoningConfig::default()
        };
        run(&mission, &config).unwrap()
    };
    let (filtered, smoothed) = (run_with(false), run_with(true));
    let var_xy = |nav: &Navigation, t: f64| {
        let p = nav.covariance_at(sim.start_s + t).unwrap();
        p[(0, 0)] + p[(1, 1)]
    };
    // Growth over 10 s before, inside and after the dropout. Without
    // velocity measurements the velocity error is integrated over the
    // whole gap (and the velocity random walk on top); the smoother bridges
    // the gap from both ends, so its growth inside is smaller.
    for (nav, factor) in [(&filtered, 20.0), (&smoothed, 5.0)] {
        let before = var_xy(nav, 19.0) - var_xy(nav, 9.0);
        let inside = var_xy(nav, 39.0) - var_xy(nav, 29.0);
        let after = var_xy(nav, 59.0) - var_xy(nav, 49.0);
        assert!(inside > factor * before, "before {before}, inside {inside}");
        assert!(
            (after - before).abs() < 0.2 * before,
            "before {before}, after {after}"
        );
        assert!(var_xy(nav, 39.0) > var_xy(nav, 20.0));
    }
    // Smoothing never adds uncertainty.
    for k in 0..=600 {
        let t = 0.1 * f64::from(k);
        let (f, s) = (var_xy(&filtered, t), var_xy(&smoothed, t));
        assert!(s <= f * (1.0 + 1e-9), "t {t}: filtered {f}, smoothed {s}");
    }
    let nav = smoothed;
    // The gap runs from the last valid sample before 20 s to the first at or after 40 s.
    assert_eq!(nav.dvl_gaps().len(), 1);
    let gap = nav.dvl_gaps()[0];
    assert!((gap.start_s - (sim.start_s + 29.0 * 0.67)).abs() < 1e-9);
    assert!((gap.end_s - (sim.start_s + 60.0 * 0.67)).abs() < 1e-9);
    // The last velocity is held through the dropout: exact on a straight path.
    let t = sim.start_s + 35.0;
    assert!(pose_error(&nav.pose_at(t).unwrap(), &truth_at(&STRAIGHT, &sim, t)).0 < 1e-3);
}

/// Sample covariance of vector errors.
fn sample_covariance(errors: &[Vector3<f64>]) -> Matrix3<f64> {
    let n = errors.len() as f64;
    let mean = errors.iter().sum::<Vector3<f64>>() / n;
    errors
        .iter()
        .map(|e| (e - mean) * (e - mean).transpose())
        .sum::<Matrix3<f64>>()
        / (n - 1.0)
}

fn error_vector(estimate: &Se2, truth: &Se2) -> Vector3<f64> {
    let d = estimate.translation() - truth.translation();
    Vector3::new(d.x, d.y, wrap_angle(estimate.theta() - truth.theta()))
}

/// Monte-Carlo check of the covariances: over 300 seeded missions the
/// sample covariance of the errors of `pose_at(t_b)` and of
/// `relative(t_a, t_b)` matches the predicted one (per axis, within
/// 0.8-1.25), for the filter and the smoother, on a circle over a long
/// interval, over one sonar rotation (13.6 s) and through a DVL dropout.
/// The filter's model matches the simulation: constant velocities and yaw
/// rate (no process noise), the simulated measurement noise levels.
#[test]
fn absolute_and_relative_covariances_match_monte_carlo_errors() {
    let circle = SyntheticNavConfig {
        dvl_noise_mps: 0.1,
        heading_noise_rad: 0.03,
        yaw_rate_noise_radps: 2e-3,
        ..SyntheticNavConfig::default()
    };
    let dropout = SyntheticNavConfig {
        dvl_dropouts_s: vec![(20.0, 40.0)],
        ..circle.clone()
    };
    for smoothing in [false, true] {
        let config = DeadReckoningConfig {
            dvl_velocity_noise_mps: 0.1,
            heading_noise_rad: 0.03,
            velocity_random_walk_mps_per_sqrt_s: 0.0,
            yaw_rate_random_walk_radps_per_sqrt_s: 1e-6,
            heading_random_walk_rad_per_sqrt_s: 0.0,
            yaw_rate_noise_radps: 2e-3,
            smoothing,
            // The linear-Gaussian filter: the gate and the noise adaptation
            // (a floor on the noise) are tested on their own below.
            dvl_gate_chi2: 0.0,
            dvl_noise_adaptation_samples: 0,
            // The synthetic heading has white noise only.
            heading_bias_sigma_rad: 0.0,
            ..DeadReckoningConfig::default()
        };
        check_monte_carlo(&CIRCLE, &circle, &config, (15.3, 52.1));
        // From before the dropout to its end.
        check_monte_carlo(&CIRCLE, &dropout, &config, (12.2, 39.5));
        // Over one rotation the relative motion is better known than the
        // absolute pose: the cross-covariance removes what both ends share
        // (without it the prediction would be about P_a + P_b, more than
        // the absolute one, and the Monte-Carlo check above would fail).
        let (relative, absolute) = check_monte_carlo(&CIRCLE, &circle, &config, (38.0, 51.6));
        assert!(
            relative < absolute,
            "smoothing {smoothing}: relative {relative}, absolute {absolute}"
        );
    }
}

/// Runs the Monte-Carlo check from `t_a` to `t_b` (s after the start);
/// returns the mean predicted position variances (x + y) of the relative
/// motion and of the absolute pose at `t_b`.
fn check_monte_carlo(
    path: &SyntheticPath,
    sim: &SyntheticNavConfig,
    config: &DeadReckoningConfig,
    (a, b): (f64, f64),
) -> (f64, f64) {
    let (t_a, t_b) = (sim.start_s + a, sim.start_s + b);
    let (truth_a, truth_b) = (truth_at(path, sim, t_a), truth_at(path, sim, t_b));
    let truth_rel = truth_a.between(&truth_b);
    let (mut abs_errors, mut rel_errors) = (Vec::new(), Vec::new());
    let (mut abs_cov, mut rel_cov) = (Matrix3::zeros(), Matrix3::zeros());
    let runs = 300;
    for seed in 0..runs {
        let mission = synthetic_mission(path, sim, seed);
        let nav = run(&mission, config).unwrap();
        abs_errors.push(error_vector(&nav.pose_at(t_b).unwrap(), &truth_b));
        abs_cov += nav.covariance_at(t_b).unwrap() / runs as f64;
        let (rel, cov) = nav.relative(t_a, t_b).unwrap();
        rel_errors.push(error_vector(&rel, &truth_rel));
        rel_cov += cov / runs as f64;
    }
    let abs_sample = sample_covariance(&abs_errors);
    let rel_sample = sample_covariance(&rel_errors);
    let what = format!(
        "smoothing {}, dropouts {:?}, {a}-{b} s",
        config.smoothing, sim.dvl_dropouts_s
    );
    for i in 0..3 {
        let (a, b) = (
            abs_sample[(i, i)] / abs_cov[(i, i)],
            rel_sample[(i, i)] / rel_cov[(i, i)],
        );
        assert!(
            (0.8..1.25).contains(&a),
            "{what}: absolute axis {i}: sample/predicted {a}"
        );
        assert!(
            (0.8..1.25).contains(&b),
            "{what}: relative axis {i}: sample/predicted {b}"
        );
    }
    (
        rel_cov[(0, 0)] + rel_cov[(1, 1)],
        abs_cov[(0, 0)] + abs_cov[(1, 1)],
    )
}

#[test]
fn relative_is_consistent_with_pose_at() {
    let sim = SyntheticNavConfig {
        dvl_noise_mps: 0.1,
        heading_noise_rad: 0.02,
        ..SyntheticNavConfig::default()
    };
    let nav = run(
        &synthetic_mission(&CIRCLE, &sim, 3),
        &DeadReckoningConfig::default(),
    )
    .unwrap();
    let (t_a, t_b) = (sim.start_s + 3.21, sim.start_s + 47.77);
    let (rel, cov) = nav.relative(t_a, t_b).unwrap();
    let composed = nav.pose_at(t_a).unwrap().compose(&rel);
    let (dp, dth) = pose_error(&composed, &nav.pose_at(t_b).unwrap());
    assert!(dp < 1e-9 && dth < 1e-12);
    assert!(cov.symmetric_eigenvalues().iter().all(|&e| e > 0.0));

    let (back, back_cov) = nav.relative(t_b, t_a).unwrap();
    let (dp, dth) = pose_error(&back, &rel.inverse());
    assert!(dp < 1e-9 && dth < 1e-12);
    // Same uncertainty seen from the other end: equal trace of the
    // heading variance, positive definite.
    assert!((back_cov[(2, 2)] - cov[(2, 2)]).abs() < 1e-12);
    assert!(back_cov.symmetric_eigenvalues().iter().all(|&e| e > 0.0));

    let (zero, zero_cov) = nav.relative(t_a, t_a).unwrap();
    assert!(zero.translation().norm() < 1e-12 && zero.theta().abs() < 1e-12);
    assert!(zero_cov.norm() < 1e-12);
}

#[test]
fn queries_outside_the_navigation_span_extrapolate_briefly_then_fail() {
    let sim = SyntheticNavConfig::default();
    let mission = synthetic_mission(&STRAIGHT, &sim, 1);
    let nav = run(&mission, &DeadReckoningConfig::default()).unwrap();
    let end = nav.end_s();
    let t = end + 1.5;
    let (dp, _) = pose_error(&nav.pose_at(t).unwrap(), &truth_at(&STRAIGHT, &sim, t));
    assert!(dp < 1e-3, "{dp}");
    let before = sim.start_s - 1.0;
    let (dp, _) = pose_error(
        &nav.pose_at(before).unwrap(),
        &truth_at(&STRAIGHT, &sim, before),
    );
    assert!(dp < 1e-3, "{dp}");
    assert!(nav.covariance_at(t).unwrap()[(0, 0)] > nav.covariance_at(end).unwrap()[(0, 0)]);
    assert!(matches!(
        nav.pose_at(end + 2.5),
        Err(FrontendError::OutsideNavigation { .. })
    ));
    assert!(matches!(
        nav.relative(sim.start_s - 3.0, end),
        Err(FrontendError::OutsideNavigation { .. })
    ));
    assert!(matches!(
        nav.pose_at(f64::NAN),
        Err(FrontendError::InvalidInput { .. })
    ));
}

#[test]
fn the_filter_starts_when_both_velocity_and_heading_exist() {
    let sim = SyntheticNavConfig::default();
    let mut mission = synthetic_mission(&STRAIGHT, &sim, 1);
    mission.dvl.drain(..3);
    let nav = run(&mission, &DeadReckoningConfig::default()).unwrap();
    assert_eq!(nav.start_s(), mission.dvl[0].stamp_s);
    assert_eq!(nav.steps()[0].world_from_vehicle.translation().norm(), 0.0);
}

#[test]
fn bad_records_give_errors_naming_the_record_and_field() {
    let sim = SyntheticNavConfig::default();
    let good = synthetic_mission(&STRAIGHT, &sim, 1);
    let config = DeadReckoningConfig::default();
    let field_of = |mission: &Mission| match run(mission, &config) {
        Err(FrontendError::InvalidInput { record, field, .. }) => format!("{record}/{field}"),
        Err(FrontendError::InsufficientData { what, .. }) => format!("insufficient {what}"),
        other => format!("unexpected {other:?}"),
    };

    let mut m = good.clone();
    m.dvl.clear();
    assert_eq!(field_of(&m), "insufficient dead reckoning");
    let mut m = good.clone();
    m.dvl.iter_mut().for_each(|s| s.valid = false);
    assert_eq!(field_of(&m), "insufficient dead reckoning");
    let mut m = good.clone();
    m.attitude.clear();
    assert_eq!(field_of(&m), "insufficient dead reckoning");
    let mut m = good.clone();
    m.attitude[12].yaw_rad = f64::NAN;
    assert_eq!(field_of(&m), "attitude sample 12/yaw_rad");
    let mut m = good.clone();
    m.attitude[4].yaw_rate_radps = Some(f64::INFINITY);
    assert_eq!(field_of(&m), "attitude sample 4/yaw_rate_radps");
    let mut m = good.clone();
    m.dvl[7].velocity_mps.y = f64::NAN;
    assert_eq!(field_of(&m), "DVL sample 7/velocity_mps");
    let mut m = good.clone();
    m.dvl[9].stamp_s = m.dvl[3].stamp_s;
    assert_eq!(field_of(&m), "DVL sample 9/stamp_s");
    let mut m = good.clone();
    m.attitude[30].stamp_s = f64::NAN;
    assert_eq!(field_of(&m), "attitude sample 30/stamp_s");
    let mut m = good.clone();
    m.dvl[2].covariance = Some(Matrix3::from_element(f64::NAN));
    assert_eq!(field_of(&m), "DVL sample 2/covariance");

    // An invalid sample is skipped whatever it holds.
    let mut m = good.clone();
    m.dvl[7].velocity_mps.y = f64::NAN;
    m.dvl[7].valid = false;
    assert!(run(&m, &config).is_ok());
}

#[test]
fn config_validation_and_serde() {
    assert!(DeadReckoningConfig::default().validate().is_ok());
    let bad = [
        DeadReckoningConfig {
            dvl_velocity_noise_mps: 0.0,
            ..DeadReckoningConfig::default()
        },
        DeadReckoningConfig {
            heading_noise_rad: f64::NAN,
            ..DeadReckoningConfig::default()
        },
        DeadReckoningConfig {
            velocity_random_walk_mps_per_sqrt_s: -1.0,
            ..DeadReckoningConfig::default()
        },
        DeadReckoningConfig {
            heading_offset_rad: f64::INFINITY,
            ..DeadReckoningConfig::default()
        },
    ];
    for config in &bad {
        assert!(matches!(
            config.validate(),
            Err(FrontendError::InvalidConfig { .. })
        ));
        let mission = synthetic_mission(&STRAIGHT, &SyntheticNavConfig::default(), 1);
        assert!(run(&mission, config).is_err());
    }
    let parsed: DeadReckoningConfig =
        serde_json::from_str(r#"{"heading_offset_rad": -0.35}"#).unwrap();
    assert_eq!(parsed.heading_offset_rad, -0.35);
    assert_eq!(
        parsed.heading_noise_rad,
        DeadReckoningConfig::default().heading_noise_rad
    );
    let err = serde_json::from_str::<DeadReckoningConfig>(r#"{"heading_ofset_rad": 0.1}"#);
    assert!(err.unwrap_err().to_string().contains("heading_ofset_rad"));
}

#[test]
fn navigation_from_known_poses_and_stationary() {
    let stamps = [10.0, 11.0, 12.0];
    let poses = [
        Se2::new(0.0, 0.0, 0.0),
        Se2::new(1.0, 0.0, 0.2),
        Se2::new(2.0, 0.5, 0.4),
    ];
    let nav = Navigation::from_poses(&stamps, &poses, 1.0).unwrap();
    let mid = nav.pose_at(10.5).unwrap();
    assert!((mid.x() - 0.5).abs() < 1e-12 && (mid.theta() - 0.1).abs() < 1e-12);
    assert_eq!(nav.pose_at(12.0).unwrap(), poses[2]);
    assert!(nav.pose_at(13.5).is_err());
    assert!(Navigation::from_poses(&[1.0, 1.0], &poses[..2], 1.0).is_err());
    assert!(Navigation::from_poses(&stamps, &poses[..2], 1.0).is_err());

    let still = Navigation::stationary(0.0, 100.0);
    assert_eq!(still.pose_at(-50.0).unwrap(), Se2::identity());
    assert_eq!(still.pose_at(1e6).unwrap(), Se2::identity());
    let (rel, cov) = still.relative(3.0, 70.0).unwrap();
    assert_eq!(rel, Se2::identity());
    assert_eq!(cov, Matrix3::zeros());
}

#[test]
fn dvl_outliers_are_gated_out() {
    // A straight run with DVL noise of the configured size and three
    // isolated 1 m/s outliers across track (lost bottom lock).
    let sim = SyntheticNavConfig {
        dvl_noise_mps: 0.1,
        ..SyntheticNavConfig::default()
    };
    let mut mission = synthetic_mission(&STRAIGHT, &sim, 3);
    let outliers = [20, 45, 70];
    for &i in &outliers {
        mission.dvl[i].velocity_mps.y += 1.0;
    }
    let end_s = mission.dvl[85].stamp_s;
    let end_error = |config: &DeadReckoningConfig| {
        let nav = run(&mission, config).unwrap();
        let error = pose_error(
            &nav.pose_at(end_s).unwrap(),
            &truth_at(&STRAIGHT, &sim, end_s),
        );
        (nav.dvl_gated(), error.0)
    };
    let (gated, with_gate) = end_error(&DeadReckoningConfig::default());
    let (none, without_gate) = end_error(&DeadReckoningConfig {
        dvl_gate_chi2: 0.0,
        ..DeadReckoningConfig::default()
    });
    assert_eq!(none, 0);
    // The outliers, and at most a few of the ~90 good samples
    // (p = 0.001 each with the configured noise).
    assert!((3..=5).contains(&gated), "{gated} gated");
    // Each outlier integrates to ~1 m/s over a sample interval, averaged
    // by the smoother: without the gate the across-track error shows it.
    assert!(
        with_gate < 0.6 * without_gate,
        "gated {with_gate:.3} m, ungated {without_gate:.3} m"
    );
}

#[test]
fn noisier_dvl_than_configured_widens_the_covariance() {
    // The configured noise is 0.14 m/s; the instrument gives 0.4 m/s.
    let sim = SyntheticNavConfig {
        dvl_noise_mps: 0.4,
        ..SyntheticNavConfig::default()
    };
    let fixed = DeadReckoningConfig {
        dvl_noise_adaptation_samples: 0,
        ..DeadReckoningConfig::default()
    };
    let adaptive = DeadReckoningConfig::default();
    let (from_s, to_s) = (sim.start_s + 20.0, sim.start_s + 34.0);
    let mut sq = [0.0, 0.0];
    let mut var = [0.0, 0.0];
    let runs = 20;
    for seed in 0..runs {
        let mission = synthetic_mission(&STRAIGHT, &sim, 100 + seed);
        let truth = truth_at(&STRAIGHT, &sim, from_s).between(&truth_at(&STRAIGHT, &sim, to_s));
        for (i, config) in [&fixed, &adaptive].into_iter().enumerate() {
            let nav = run(&mission, config).unwrap();
            let (motion, cov) = nav.relative(from_s, to_s).unwrap();
            sq[i] += (motion.translation() - truth.translation()).norm_squared();
            var[i] += cov[(0, 0)] + cov[(1, 1)];
        }
    }
    // Ratio of the actual squared error to the claimed variance (1 for an
    // honest covariance): far above 1 without adaptation, near 1 with it.
    let ratio = |i: usize| sq[i] / var[i];
    assert!(ratio(0) > 3.0, "fixed noise: {:.2}", ratio(0));
    assert!(
        (0.4..2.0).contains(&ratio(1)),
        "adaptive noise: {:.2}",
        ratio(1)
    );
    // With the configured noise right, adaptation changes little.
    let mission = synthetic_mission(
        &STRAIGHT,
        &SyntheticNavConfig {
            dvl_noise_mps: 0.14,
            ..SyntheticNavConfig::default()
        },
        7,
    );
    let cov = |config| {
        run(&mission, config)
            .unwrap()
            .relative(from_s, to_s)
            .unwrap()
            .1
    };
    let (a, b) = (cov(&fixed), cov(&adaptive));
    let growth = (b[(0, 0)] + b[(1, 1)]) / (a[(0, 0)] + a[(1, 1)]);
    assert!((1.0..1.6).contains(&growth), "{growth}");
}

/// A heading unit whose error wanders (Gauss-Markov, 2°, 120 s): the
/// filter alone claims the heading change over 13 s to within a fraction of
/// the actual error; with the wander's change variance added by
/// `relative`, the prediction matches 300 Monte-Carlo runs. Measured
/// (sample / predicted variance of the heading change): 0.87 with it, 5.2
/// without.
#[test]
fn relative_heading_covariance_accounts_for_a_wandering_compass() {
    let sim = SyntheticNavConfig {
        dvl_noise_mps: 0.1,
        heading_noise_rad: 0.02,
        heading_wander_sigma_rad: 2f64.to_radians(),
        heading_wander_time_constant_s: 120.0,
        with_yaw_rate: false,
        ..SyntheticNavConfig::default()
    };
    let (t_a, t_b) = (sim.start_s + 40.0, sim.start_s + 53.0);
    let truth_rel = truth_at(&CIRCLE, &sim, t_a).between(&truth_at(&CIRCLE, &sim, t_b));
    let ratio = |config: &DeadReckoningConfig| {
        let runs = 300;
        let mut errors = Vec::new();
        let mut predicted = 0.0;
        for seed in 0..runs {
            let nav = run(&synthetic_mission(&CIRCLE, &sim, seed), config).unwrap();
            let (rel, cov) = nav.relative(t_a, t_b).unwrap();
            errors.push(error_vector(&rel, &truth_rel));
            predicted += cov[(2, 2)] / runs as f64;
        }
        sample_covariance(&errors)[(2, 2)] / predicted
    };
    let with_bias = DeadReckoningConfig {
        heading_bias_sigma_rad: 2f64.to_radians(),
        heading_bias_time_constant_s: 120.0,
        ..DeadReckoningConfig::default()
    };
    let without = DeadReckoningConfig {
        heading_bias_sigma_rad: 0.0,
        ..with_bias.clone()
    };
    let (with_bias, without) = (ratio(&with_bias), ratio(&without));
    assert!(
        (0.75..1.33).contains(&with_bias),
        "sample / predicted {with_bias}"
    );
    assert!(
        without > 2.0,
        "without the wander: sample / predicted {without}"
    );
}

#[test]
fn the_wander_change_variance_follows_the_gauss_markov_law() {
    use crate::dead_reckoning::HeadingBias;
    let bias = HeadingBias {
        sigma_rad: 0.03,
        time_constant_s: 100.0,
    };
    assert_eq!(bias.change_variance(0.0), 0.0);
    // Short intervals: about 2σ²Δt/τ; long ones: 2σ².
    assert!((bias.change_variance(1.0) - 2.0 * 0.03f64.powi(2) * 0.01).abs() < 1e-7);
    assert!((bias.change_variance(1e4) - 2.0 * 0.03f64.powi(2)).abs() < 1e-12);
    assert_eq!(bias.change_variance(-5.0), bias.change_variance(5.0));
    assert_eq!(HeadingBias::default().change_variance(10.0), 0.0);
}

/// RMS heading error against the truth, every 0.5 s.
fn rms_heading_error(nav: &Navigation, path: &SyntheticPath, sim: &SyntheticNavConfig) -> f64 {
    let n = (sim.duration_s / 0.5) as usize;
    let sum: f64 = (1..n)
        .map(|k| {
            let t = sim.start_s + 0.5 * k as f64;
            pose_error(&nav.pose_at(t).unwrap(), &truth_at(path, sim, t))
                .1
                .powi(2)
        })
        .sum();
    (sum / (n - 1) as f64).sqrt()
}

/// Dead reckoning of `mission` with `config`, and with the yaw-rate check
/// off.
fn with_and_without_check(
    mission: &Mission,
    config: &DeadReckoningConfig,
) -> (Navigation, Navigation) {
    let unchecked = DeadReckoningConfig {
        yaw_rate_check_window_s: 0.0,
        ..config.clone()
    };
    (
        run(mission, config).unwrap(),
        run(mission, &unchecked).unwrap(),
    )
}

#[test]
fn a_biased_gyro_is_detected_and_no_longer_drags_the_heading() {
    // A precise compass (0.05°) beside a gyro reading 1°/s off, on the
    // circle (as the real St Pere MTi: 0.66°/s and a 6% scale error).
    let sim = SyntheticNavConfig {
        duration_s: 120.0,
        heading_noise_rad: 0.05_f64.to_radians(),
        yaw_rate_bias_radps: 1.0_f64.to_radians(),
        ..SyntheticNavConfig::default()
    };
    let mission = synthetic_mission(&CIRCLE, &sim, 3);
    let config = DeadReckoningConfig::default();
    let (checked, unchecked) = with_and_without_check(&mission, &config);
    assert_eq!(
        unchecked.yaw_rate_noise_radps(),
        config.yaw_rate_noise_radps
    );
    assert!(unchecked.yaw_rate_check().is_none());
    // A bias b reads as b √((T² − Δt²) / (Δt T)) = 0.0175 · √9.9 = 0.055
    // rad/s over T = 1 s (gyro_check's module doc).
    let noise = checked.yaw_rate_noise_radps();
    assert!((noise / 0.055 - 1.0).abs() < 0.05, "{noise}");
    let (with, without) = (
        rms_heading_error(&checked, &CIRCLE, &sim),
        rms_heading_error(&unchecked, &CIRCLE, &sim),
    );
    assert!(
        with < 0.5 * without,
        "{with} rad with the check, {without} without"
    );
}

#[test]
fn a_gyro_as_consistent_as_configured_is_filtered_as_configured() {
    // The simulator's units: 0.5° compass noise, 0.2°/s gyro noise.
    let sim = SyntheticNavConfig {
        duration_s: 300.0,
        heading_noise_rad: 0.5_f64.to_radians(),
        yaw_rate_noise_radps: 0.2_f64.to_radians(),
        ..SyntheticNavConfig::default()
    };
    let mission = synthetic_mission(&CIRCLE, &sim, 4);
    let config = DeadReckoningConfig::default();
    let (checked, unchecked) = with_and_without_check(&mission, &config);
    let check = checked.yaw_rate_check().unwrap();
    assert!(
        check.yaw_rate_noise_radps < config.yaw_rate_noise_radps,
        "{check:?}"
    );
    assert_eq!(checked.yaw_rate_noise_radps(), config.yaw_rate_noise_radps);
    assert_eq!(checked.steps(), unchecked.steps());
}
