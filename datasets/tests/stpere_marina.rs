//! The real St Pere marina logs committed under `datasets/stpere-marina/`.
//!
//! Expected values come from the logs' README and from counting lines with
//! shell tools, not from this reader. Run with `--nocapture` to print the
//! measured facts:
//! `cargo test -p echofield-datasets --test stpere_marina -- --nocapture`.

use echofield_datasets::stpere::{
    MARINA_YAW_OFFSET_RAD, StPereLogs, best_yaw_offset, dead_reckoning_error, read_stpere_dir,
};
use std::path::PathBuf;
use std::sync::OnceLock;

fn marina() -> &'static StPereLogs {
    static LOGS: OnceLock<StPereLogs> = OnceLock::new();
    LOGS.get_or_init(|| {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("stpere-marina");
        read_stpere_dir(&dir).expect("the committed marina logs must read")
    })
}

#[test]
fn record_counts_match_the_files() {
    let logs = marina();
    let m = &logs.mission;
    // `grep -v '^%' FILE | awk 'NF'` line counts.
    assert_eq!(m.dvl.len(), 5045);
    assert_eq!(m.attitude.len(), 33457);
    assert_eq!(logs.dgps.len(), 3342);
    assert_eq!(m.ground_truth.len(), 3342);
    assert_eq!(logs.beam_stamps.len(), 46259);
    assert!(m.beams.is_empty(), "no _IS.log in the public logs");
    assert!(logs.skipped.is_empty(), "{:?}", logs.skipped);
    // 84 DVL rows carry 32767 bottom velocities with status 0.
    assert_eq!(m.dvl.iter().filter(|d| !d.valid).count(), 84);
    let setup = logs.sonar_setup.as_ref().unwrap();
    assert_eq!(
        (setup.range_m, setup.bin_size_m, setup.bins()),
        (50.0, 0.1, 500)
    );
    assert!((setup.step_rad.to_degrees() - 1.8).abs() < 1e-9);
}

#[test]
fn first_records_are_converted_to_echofield_units_and_frames() {
    let logs = marina();
    let m = &logs.mission;
    // DVL line 14: bottom velocity 6.10 -4.90 2.80 cm/s.
    let d = &m.dvl[0];
    assert_eq!(d.stamp_s, 1093455407.147);
    assert!((d.velocity_mps.x - 0.061).abs() < 1e-12 && (d.velocity_mps.y + 0.049).abs() < 1e-12);
    // MTi line 7: heading -126.276 deg clockwise from north = 216.276 deg
    // counter-clockwise from east = -143.724 deg wrapped.
    let a = &m.attitude[0];
    assert!((a.yaw_rad.to_degrees() + 143.724).abs() < 1e-9);
    // DGPS: the first fix is the origin; the area is ~118 x 239 m, south-east
    // of the start (README).
    assert_eq!((logs.dgps[0].east_m, logs.dgps[0].north_m), (0.0, 0.0));
    let (min_e, max_e) = min_max(logs.dgps.iter().map(|f| f.east_m));
    let (min_n, max_n) = min_max(logs.dgps.iter().map(|f| f.north_m));
    assert!((max_e - min_e - 118.0).abs() < 3.0, "{min_e} {max_e}");
    assert!((max_n - min_n - 239.0).abs() < 3.0, "{min_n} {max_n}");
    assert!(min_n < -230.0 && max_e > 110.0);
}

#[test]
fn dvl_dead_reckoning_with_the_recommended_offset_follows_dgps() {
    // A check of the reader's frames: the logs' README reports ~4.7 m mean,
    // ~11.7 m max for the best constant offset, and says a 5 deg error
    // doubles it.
    let m = &marina().mission;
    let good = dead_reckoning_error(m, MARINA_YAW_OFFSET_RAD).unwrap();
    assert!(good.mean_m < 7.0 && good.max_m < 20.0, "{good:?}");
    assert!(good.compared > 3300);
    let off_by_5 = dead_reckoning_error(m, MARINA_YAW_OFFSET_RAD + 5f64.to_radians()).unwrap();
    assert!(off_by_5.mean_m > 1.5 * good.mean_m, "{off_by_5:?}");
    let raw = dead_reckoning_error(m, 0.0).unwrap();
    assert!(raw.mean_m > 4.0 * good.mean_m, "{raw:?}");
}

#[test]
fn best_offset_is_the_readme_minus_20_deg_in_echofield_sign() {
    // README: about -20 deg clockwise-from-north; echofield yaw is
    // counter-clockwise, so about +20 deg.
    let (offset, error) = best_yaw_offset(&marina().mission).unwrap();
    assert!(
        (offset.to_degrees() - 20.0).abs() < 3.0,
        "{}",
        offset.to_degrees()
    );
    assert!((offset - MARINA_YAW_OFFSET_RAD).abs() < 1f64.to_radians());
    assert!(error.mean_m < 6.0, "{error:?}");
}

#[test]
fn measured_facts() {
    let logs = marina();
    let m = &logs.mission;
    let (offset, best) = best_yaw_offset(m).unwrap();
    let raw = dead_reckoning_error(m, 0.0).unwrap();
    let valid = m.dvl.iter().filter(|d| d.valid).count() as f64 / m.dvl.len() as f64;
    let path_raw: f64 = logs
        .dgps
        .windows(2)
        .map(|w| (w[1].east_m - w[0].east_m).hypot(w[1].north_m - w[0].north_m))
        .sum();
    let every_10: Vec<_> = logs.dgps.iter().step_by(10).collect();
    let path_10s: f64 = every_10
        .windows(2)
        .map(|w| (w[1].east_m - w[0].east_m).hypot(w[1].north_m - w[0].north_m))
        .sum();
    let first = &logs.dgps[0];
    let last = logs.dgps.last().unwrap();
    let gaps: Vec<f64> = logs
        .beam_stamps
        .windows(2)
        .map(|w| w[1].stamp_s - w[0].stamp_s)
        .collect();
    let mut sorted = gaps.clone();
    sorted.sort_by(f64::total_cmp);
    let compass_diff = mean_yaw_difference(logs);
    println!("St Pere marina facts:");
    println!(
        "  DVL samples {}, valid {:.1} %",
        m.dvl.len(),
        100.0 * valid
    );
    println!(
        "  MTi samples {}, DGPS fixes {}",
        m.attitude.len(),
        logs.dgps.len()
    );
    println!(
        "  DGPS duration {:.1} min, path {:.0} m raw 1 Hz, {:.0} m every 10 s; start-end {:.0} m",
        (last.stamp_s - first.stamp_s) / 60.0,
        path_raw,
        path_10s,
        (last.east_m - first.east_m).hypot(last.north_m - first.north_m)
    );
    println!(
        "  beams {}: median spacing {:.1} ms, largest gap {:.2} s",
        logs.beam_stamps.len(),
        1e3 * sorted[sorted.len() / 2],
        sorted.last().unwrap()
    );
    println!(
        "  best yaw offset {:+.2} deg: DR mean {:.2} m, max {:.2} m, final {:.2} m over {} fixes",
        offset.to_degrees(),
        best.mean_m,
        best.max_m,
        best.final_m,
        best.compared
    );
    for delta in [-5.0, 5.0] {
        let e = dead_reckoning_error(m, MARINA_YAW_OFFSET_RAD + f64::to_radians(delta)).unwrap();
        println!(
            "  offset {:+.0} deg: DR mean {:.2} m, max {:.2} m",
            20.0 + delta,
            e.mean_m,
            e.max_m
        );
    }
    println!(
        "  no offset: DR mean {:.2} m, max {:.2} m",
        raw.mean_m, raw.max_m
    );
    println!("  DVL compass minus MTi yaw (echofield sign): {compass_diff:+.1} deg");
}

fn mean_yaw_difference(logs: &StPereLogs) -> f64 {
    let att = &logs.mission.attitude;
    let mut sum = 0.0;
    for c in &logs.dvl_compass {
        let k = att
            .partition_point(|a| a.stamp_s < c.stamp_s)
            .min(att.len() - 1);
        sum += echofield_graph::wrap_angle(c.yaw_rad - att[k].yaw_rad);
    }
    (sum / logs.dvl_compass.len() as f64).to_degrees()
}

fn min_max(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    })
}

#[test]
fn the_other_sign_conventions_fit_dgps_much_worse() {
    // The reader's frames: MTi heading clockwise (yaw = pi/2 - heading) and
    // DVL y to port. Flip either (or both) and even the best constant offset
    // leaves dead reckoning far from DGPS.
    let chosen = best_yaw_offset(&marina().mission).unwrap().1.mean_m;
    for (flip_yaw, flip_dvl_y) in [(true, false), (false, true), (true, true)] {
        let mut m = marina().mission.clone();
        if flip_yaw {
            // Heading read counter-clockwise: yaw = pi/2 + heading = pi - yaw.
            for a in &mut m.attitude {
                a.yaw_rad = echofield_graph::wrap_angle(std::f64::consts::PI - a.yaw_rad);
            }
        }
        if flip_dvl_y {
            for d in &mut m.dvl {
                d.velocity_mps.y = -d.velocity_mps.y;
            }
        }
        let other = best_yaw_offset(&m).unwrap().1.mean_m;
        assert!(
            other > 2.0 * chosen,
            "flip yaw {flip_yaw}, flip y {flip_dvl_y}: {other} m vs {chosen} m"
        );
        println!(
            "flip yaw {flip_yaw}, flip DVL y {flip_dvl_y}: best DR mean {other:.1} m (chosen {chosen:.1} m)"
        );
    }
}
