//! The measurement model on real echoes of static sonar heads (the true
//! displacement between any two rotations of one log is zero):
//! consecutive rotations matched against each other, and known offsets
//! (up to 3 m and 15°) applied to a real scan and recovered, to 0.1 m and
//! 1°.

use echofield::matching::MissionRotations;
use echofield::slam::SlamConfig;
use echofield_frontend::image::AcousticImage;
use echofield_frontend::matcher::{MatchOutcome, SearchWindow, match_scan};
use echofield_frontend::scan::Scan;
use echofield_graph::Se2;
use echofield_tests::{miniking_config, miniking_log, ping360_config, ping360_log};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const TOLERANCE_M: f64 = 0.1;
const TOLERANCE_DEG: f64 = 1.0;

fn miniking() -> (MissionRotations, SlamConfig) {
    let config = miniking_config();
    (
        MissionRotations::load(&miniking_log(), &config).unwrap(),
        config,
    )
}

fn ping360() -> (MissionRotations, SlamConfig) {
    let config = ping360_config();
    (
        MissionRotations::load(&ping360_log(), &config).unwrap(),
        config,
    )
}

/// `image_from_scan` found from `prior` in `window`, or a panic naming what.
fn estimate(
    what: &str,
    scan: &Scan,
    image: &AcousticImage,
    prior: &Se2,
    window: &SearchWindow,
    config: &SlamConfig,
) -> Se2 {
    match match_scan(&scan.points, image, prior, window, &config.matcher).unwrap() {
        MatchOutcome::Match(m) => m.image_from_scan,
        other => panic!("{what}: {other:?}"),
    }
}

fn assert_close(what: &str, estimate: &Se2, truth: &Se2) {
    let e = truth.between(estimate);
    let (dt, deg) = (e.translation().norm(), e.theta().abs().to_degrees());
    assert!(
        dt < TOLERANCE_M && deg < TOLERANCE_DEG,
        "{what}: error {dt:.3} m, {deg:.2} deg (estimate {:?}, truth {:?})",
        estimate.to_vector(),
        truth.to_vector()
    );
}

#[test]
fn miniking_consecutive_rotations_do_not_move() {
    let (rotations, config) = miniking();
    let (scan, _) = rotations.scan_and_image(1, &config).unwrap();
    let image = rotations.image(0, &config).unwrap();
    let window = SearchWindow::new(1.0, 1.0, 10.0_f64.to_radians());
    for (i, prior) in [
        Se2::identity(),
        Se2::new(0.5, -0.4, 0.08),
        Se2::new(-0.7, 0.2, -0.12),
    ]
    .iter()
    .enumerate()
    {
        let m = estimate("miniking 1 vs 0", &scan, &image, prior, &window, &config);
        assert_close(&format!("miniking 1 vs 0, prior {i}"), &m, &Se2::identity());
    }
}

/// Moves `scan` so that the true `image_from_scan` becomes `offset`.
fn moved(scan: &Scan, offset: &Se2) -> Scan {
    let scan_from_image = offset.inverse();
    Scan {
        points: scan
            .points
            .iter()
            .map(|p| scan_from_image.transform_point(p))
            .collect(),
        ..scan.clone()
    }
}

/// Seeded offsets up to 3 m and 15 degrees.
fn offsets(seed: u64, n: usize) -> Vec<Se2> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let length = 3.0 * rng.random::<f64>();
            let direction = std::f64::consts::TAU * rng.random::<f64>();
            let angle = 15.0_f64.to_radians() * (2.0 * rng.random::<f64>() - 1.0);
            Se2::new(length * direction.cos(), length * direction.sin(), angle)
        })
        .collect()
}

#[test]
fn miniking_known_offsets_are_recovered() {
    let (rotations, config) = miniking();
    let scan = rotations.scan(1, &config).unwrap();
    let image = rotations.image(0, &config).unwrap();
    let window = SearchWindow::new(3.5, 3.5, 17.0_f64.to_radians());
    for (i, offset) in offsets(11, 8).iter().enumerate() {
        let m = estimate(
            "miniking",
            &moved(&scan, offset),
            &image,
            &Se2::identity(),
            &window,
            &config,
        );
        assert_close(&format!("miniking offset {i}"), &m, offset);
    }
}

#[test]
fn ping360_known_offsets_are_recovered_on_its_own_image() {
    let (rotations, config) = ping360();
    // Rotation 1 is the first full turn at the 10 m range.
    let (scan, image) = rotations.scan_and_image(1, &config).unwrap();
    let window = SearchWindow::new(3.5, 3.5, 17.0_f64.to_radians());
    for (i, offset) in offsets(12, 8).iter().enumerate() {
        let m = estimate(
            "ping360",
            &moved(&scan, offset),
            &image,
            &Se2::identity(),
            &window,
            &config,
        );
        assert_close(&format!("ping360 offset {i}"), &m, offset);
    }
}

/// Cannot pass on this log, because the head did not keep its heading
/// (measured in `datasets/tests/ping360_logs.rs`; numbers from the runs of
/// 2026-11-22):
/// - Rotations 1 and 2 are the only two full turns. Between them (beam 931,
///   45.86 s) the head reports angle 331 twice after a 266 ms late reply,
///   and the walls seen at 40-100 grad appear 7-8 grad further round before
///   that repeat than after it (polar correlation 0.57 at -8 grad, 0.23 at
///   0), in a run that never changes direction, with the same step, beam
///   period and pulse on both sides. The matcher finds 0.78 m / 1.8°
///   between them: one-sided structure turns the rotation partly into a
///   translation.
/// - Rotations 3-17 are 59° sweeps of a sector whose echoes do not repeat
///   from sweep to sweep (the best correlation of two sweeps in the same
///   direction over ±8 grad stays below 0.3 and is flat in the shift), so
///   sweep-to-sweep displacement is unobservable there; the matcher's
///   answers scatter over ±10° with both signs in both pairing orders.
/// - The direction-dependent lag of the Ping360 is real but small: 0.46
///   grad (0.4°) per direction, i.e. 0.8° between opposite sweeps, measured
///   on the one sector with repeatable echoes (40 m range of the corrupted
///   log) by `echofield_frontend::sweep_lag::estimate_sweep_lag`.
///   Correcting it (`correct_sweep_lag`) does not change the picture here.
///
/// - The source's two other static logs, not committed
///   (`datasets/msis-real/README.md`), cannot stand in: at 60 m they hold
///   2.07 and 2.55 turns, but their echoes lie within about 3 m of the head
///   (tens to a few hundred scan points over speckle). Matched with blind
///   zones of 1-2 m and intensity floors of 50-100 (2026-12-04, `echofield
///   match --window 1,1,15`), rotation 1 against 0 and 0 against 1 do not
///   agree with each other: +7.0° to +9.2° against -1.0° to +1.6° on
///   `20210829-001755317`, -5.3° to -15.1° against +9.2° to +10.3° (and
///   0.2-1.1 m) on `20200926-110158491`.
///
/// Kept to measure progress should a static Ping360 log with two full turns
/// of persistent structure be added.
#[test]
#[ignore = "inside_base: the heading jumps 7-8 grad between its two full turns and its sector echoes do not repeat (see the doc comment)"]
fn ping360_consecutive_rotations_do_not_move() {
    let (rotations, config) = ping360();
    let window = SearchWindow::new(1.0, 1.0, 10.0_f64.to_radians());
    for k in 2..18 {
        let scan = rotations.scan(k, &config).unwrap();
        let image = rotations.image(k - 1, &config).unwrap();
        let m = estimate("ping360", &scan, &image, &Se2::identity(), &window, &config);
        assert_close(&format!("ping360 {k} vs {}", k - 1), &m, &Se2::identity());
    }
}
