use super::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const STEP_RAD: f64 = TAU / 200.0;
const PERIOD_S: f64 = 0.068;

fn beam(stamp_s: f64, angle_rad: f64) -> SonarBeam {
    SonarBeam {
        stamp_s,
        angle_rad,
        bin_size_m: 0.1,
        first_bin_range_m: 0.0,
        intensities: vec![0; 50],
    }
}

/// Beams at a regular period with the given transducer angles.
fn beams_from_angles(angles: impl IntoIterator<Item = f64>) -> Vec<SonarBeam> {
    angles
        .into_iter()
        .enumerate()
        .map(|(i, a)| beam(100.0 + i as f64 * PERIOD_S, a))
        .collect()
}

/// A continuously rotating head: `n` beams from `start_rad`, `sign` = ±1,
/// angles reported wrapped to (-π, π] as real heads do.
fn continuous(n: usize, start_rad: f64, sign: f64) -> Vec<SonarBeam> {
    beams_from_angles((0..n).map(|i| wrap_angle(start_rad + sign * i as f64 * STEP_RAD)))
}

fn ranges(rotations: &[Rotation]) -> Vec<Range<usize>> {
    rotations.iter().map(|r| r.beams.clone()).collect()
}

#[test]
fn continuous_rotation_wraps_around_pi_into_200_beam_rotations() {
    // Starts at 3 rad, so every rotation crosses the ±π wrap.
    let beams = continuous(1000, 3.0, 1.0);
    let rotations = assemble_rotations(&beams, &RotationConfig::default()).unwrap();
    assert_eq!(
        ranges(&rotations),
        vec![0..200, 200..400, 400..600, 600..800, 800..1000]
    );
    for (k, r) in rotations.iter().enumerate() {
        assert_eq!(r.index, k);
        assert_eq!(r.kind, RotationKind::Full);
        assert!((r.coverage_rad - TAU).abs() < 1e-9);
        assert_eq!(r.start_s, beams[r.beams.start].stamp_s);
        assert_eq!(r.end_s, beams[r.beams.end - 1].stamp_s);
        assert!((r.reference_stamp_s - 0.5 * (r.start_s + r.end_s)).abs() < 1e-12);
    }
}

#[test]
fn clockwise_rotation_with_timing_jitter_gives_the_same_boundaries() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut beams = continuous(600, -1.0, -1.0);
    for b in &mut beams {
        b.stamp_s += rng.random_range(-0.01..0.01);
    }
    let rotations = assemble_rotations(&beams, &RotationConfig::default()).unwrap();
    assert_eq!(ranges(&rotations), vec![0..200, 200..400, 400..600]);
}

#[test]
fn partial_last_rotation_is_dropped_by_default_and_kept_on_request() {
    let beams = continuous(520, 0.0, 1.0); // 2 rotations + 120 beams (216°)
    let default = assemble_rotations(&beams, &RotationConfig::default()).unwrap();
    assert_eq!(ranges(&default), vec![0..200, 200..400]);

    let keep = RotationConfig {
        keep_partial: true,
        ..RotationConfig::default()
    };
    let kept = assemble_rotations(&beams, &keep).unwrap();
    assert_eq!(ranges(&kept), vec![0..200, 200..400, 400..520]);
    assert_eq!(kept[2].kind, RotationKind::Partial);
    assert!((kept[2].coverage_rad - 120.0 * STEP_RAD).abs() < 1e-9);

    let too_small = RotationConfig {
        keep_partial: true,
        min_partial_coverage_rad: 1.5 * PI,
        ..RotationConfig::default()
    };
    assert_eq!(
        ranges(&assemble_rotations(&beams, &too_small).unwrap()),
        vec![0..200, 200..400]
    );
}

#[test]
fn a_time_gap_drops_the_cut_rotation_and_restarts_after_it() {
    let mut beams = continuous(800, 0.5, 1.0);
    for b in &mut beams[350..] {
        b.stamp_s += 10.6; // the St Pere log has one gap of this length
    }
    let rotations = assemble_rotations(&beams, &RotationConfig::default()).unwrap();
    assert_eq!(ranges(&rotations), vec![0..200, 350..550, 550..750]);
    // A gap just under the limit does not split.
    let mut beams = continuous(400, 0.5, 1.0);
    for b in &mut beams[100..] {
        b.stamp_s += 1.9 * PERIOD_S; // 2.9 periods between beams 99 and 100
    }
    let rotations = assemble_rotations(&beams, &RotationConfig::default()).unwrap();
    assert_eq!(ranges(&rotations), vec![0..200, 200..400]);
}

#[test]
fn back_and_forth_sector_scan_gives_one_unit_per_sweep() {
    // ±45° sector, 50 steps each way, reversing at each end.
    let half = 25.0 * STEP_RAD;
    let sweep_up: Vec<f64> = (0..=50).map(|i| -half + i as f64 * STEP_RAD).collect();
    let mut angles = Vec::new();
    for s in 0..5 {
        let sweep: Vec<f64> = if s % 2 == 0 {
            sweep_up.clone()
        } else {
            sweep_up.iter().rev().copied().collect()
        };
        // The end angle is not repeated when the head turns back.
        angles.extend(if s == 0 { &sweep[..] } else { &sweep[1..] });
    }
    let beams = beams_from_angles(angles);
    assert_eq!(beams.len(), 251);
    let rotations = assemble_rotations(&beams, &RotationConfig::default()).unwrap();
    // The first sweep starts at the start of the data, so it is partial and
    // dropped; each later sweep runs from one reversal to the next, except
    // the last, which ends with the data.
    assert_eq!(ranges(&rotations), vec![51..101, 101..151, 151..201]);
    for r in &rotations {
        assert_eq!(r.kind, RotationKind::SectorSweep);
        assert!((r.coverage_rad - 50.0 * STEP_RAD).abs() < 1e-9);
    }
}

#[test]
fn fly_back_sector_scan_splits_at_each_jump() {
    // 0..90° forward, then jump back to 0.
    let angles = (0..4).flat_map(|_| (0..50).map(|i| i as f64 * STEP_RAD));
    let beams = beams_from_angles(angles);
    let rotations = assemble_rotations(&beams, &RotationConfig::default()).unwrap();
    assert_eq!(ranges(&rotations), vec![50..100, 100..150]);
    assert!(
        rotations
            .iter()
            .all(|r| r.kind == RotationKind::SectorSweep)
    );
}

#[test]
fn direction_reversal_in_a_continuous_rotation_drops_the_cut_turn() {
    let mut angles: Vec<f64> = (0..300).map(|i| i as f64 * STEP_RAD).collect();
    let turn_rad = 299.0 * STEP_RAD;
    angles.extend((1..=400).map(|i| turn_rad - i as f64 * STEP_RAD));
    let beams = beams_from_angles(angles.into_iter().map(wrap_angle));
    let rotations = assemble_rotations(&beams, &RotationConfig::default()).unwrap();
    // 0..200 full; 200..300 ends at the reversal but did not start at one:
    // partial, dropped; then two clockwise turns.
    assert_eq!(ranges(&rotations), vec![0..200, 300..500, 500..700]);
    assert!(rotations.iter().all(|r| r.kind == RotationKind::Full));
}

#[test]
fn a_change_of_bin_count_or_bin_size_splits_the_rotation() {
    let mut beams = continuous(700, 0.0, 1.0);
    for b in &mut beams[250..] {
        b.intensities = vec![0; 40];
    }
    let rotations = assemble_rotations(&beams, &RotationConfig::default()).unwrap();
    assert_eq!(ranges(&rotations), vec![0..200, 250..450, 450..650]);

    let mut beams = continuous(700, 0.0, 1.0);
    for b in &mut beams[250..] {
        b.bin_size_m = 0.2;
    }
    let rotations = assemble_rotations(&beams, &RotationConfig::default()).unwrap();
    assert_eq!(ranges(&rotations), vec![0..200, 250..450, 450..650]);
}

#[test]
fn repeated_angles_stay_in_the_rotation() {
    // Each angle reported twice: 400 beams per turn.
    let beams = beams_from_angles((0..800).map(|i| wrap_angle((i / 2) as f64 * STEP_RAD)));
    let rotations = assemble_rotations(&beams, &RotationConfig::default()).unwrap();
    assert_eq!(ranges(&rotations), vec![0..400, 400..800]);
}

#[test]
fn bad_input_gives_errors_naming_the_beam_and_field() {
    let config = RotationConfig::default();
    assert!(matches!(
        assemble_rotations(&[], &config),
        Err(FrontendError::InsufficientData { .. })
    ));

    let mut beams = continuous(400, 0.0, 1.0);
    beams[17].angle_rad = f64::NAN;
    let err = assemble_rotations(&beams, &config).unwrap_err();
    assert_eq!(
        err,
        FrontendError::input("beam 17", "angle_rad", "not finite")
    );

    let mut beams = continuous(400, 0.0, 1.0);
    beams[5].stamp_s = f64::NAN;
    let err = assemble_rotations(&beams, &config).unwrap_err();
    assert!(
        matches!(err, FrontendError::InvalidInput { ref record, ref field, .. }
        if record == "beam 5" && field == "stamp_s")
    );

    let mut beams = continuous(400, 0.0, 1.0);
    beams[30].stamp_s = beams[28].stamp_s;
    let err = assemble_rotations(&beams, &config).unwrap_err();
    assert!(
        matches!(err, FrontendError::InvalidInput { ref record, ref field, .. }
        if record == "beam 30" && field == "stamp_s")
    );

    let mut beams = continuous(400, 0.0, 1.0);
    beams[3].bin_size_m = 0.0;
    let err = assemble_rotations(&beams, &config).unwrap_err();
    assert!(matches!(err, FrontendError::InvalidInput { ref field, .. } if field == "bin_size_m"));

    let beams = continuous(150, 0.0, 1.0);
    assert!(matches!(
        assemble_rotations(&beams, &config),
        Err(FrontendError::InsufficientData { .. })
    ));
}

#[test]
fn config_validation_rejects_out_of_range_values() {
    assert!(RotationConfig::default().validate().is_ok());
    let bad = [
        RotationConfig {
            max_gap_beam_periods: 1.0,
            ..RotationConfig::default()
        },
        RotationConfig {
            beam_period_s: Some(-0.1),
            ..RotationConfig::default()
        },
        RotationConfig {
            min_partial_coverage_rad: 7.0,
            ..RotationConfig::default()
        },
    ];
    for config in bad {
        assert!(matches!(
            config.validate(),
            Err(FrontendError::InvalidConfig { .. })
        ));
    }
}

#[test]
fn an_explicit_beam_period_sets_the_gap_threshold() {
    let mut beams = continuous(400, 0.0, 1.0);
    for b in &mut beams[100..] {
        b.stamp_s += 0.5;
    }
    let config = RotationConfig {
        beam_period_s: Some(0.5),
        ..RotationConfig::default()
    };
    // 0.568 s < 3 x 0.5 s: no gap.
    assert_eq!(
        ranges(&assemble_rotations(&beams, &config).unwrap()),
        vec![0..200, 200..400]
    );
    // With the derived 0.068 s period it is a gap.
    assert_eq!(
        ranges(&assemble_rotations(&beams, &RotationConfig::default()).unwrap()),
        vec![100..300]
    );
}

#[test]
fn config_reads_from_json_with_defaults_and_rejects_unknown_keys() {
    let parsed: RotationConfig =
        serde_json::from_str(r#"{"keep_partial": true, "beam_period_s": 0.07}"#).unwrap();
    assert!(parsed.keep_partial);
    assert_eq!(parsed.beam_period_s, Some(0.07));
    assert_eq!(parsed.max_gap_beam_periods, 3.0);
    let err = serde_json::from_str::<RotationConfig>(r#"{"max_gap": 2}"#).unwrap_err();
    assert!(err.to_string().contains("max_gap"));
}

#[test]
fn the_beam_period_is_that_of_each_range_setting() {
    // 600 beams at the short range (0.068 s apart), then 400 at a long range
    // pinging every 0.2 s with one late reply of 0.5 s (2.5 periods, not a
    // gap there, though more than 3 periods of the short range).
    let mut beams = continuous(1000, 0.0, 1.0);
    for (i, b) in beams.iter_mut().enumerate().skip(600) {
        b.intensities = vec![0; 80];
        b.stamp_s = 100.0 + 600.0 * PERIOD_S + (i - 600) as f64 * 0.2;
        if i >= 700 {
            b.stamp_s += 0.3;
        }
    }
    let rotations = assemble_rotations(&beams, &RotationConfig::default()).unwrap();
    assert_eq!(
        ranges(&rotations),
        vec![0..200, 200..400, 400..600, 600..800, 800..1000]
    );
    // A real gap of the long range (4 periods) still cuts.
    for b in &mut beams[750..] {
        b.stamp_s += 0.6;
    }
    let rotations = assemble_rotations(&beams, &RotationConfig::default()).unwrap();
    assert_eq!(
        ranges(&rotations),
        vec![0..200, 200..400, 400..600, 750..950]
    );
}

/// Every rotation of `beams` as [`RotationStream`] returns them, beam by
/// beam and at the end.
fn streamed(beams: &[SonarBeam], config: &RotationConfig) -> Vec<Rotation> {
    let mut stream = RotationStream::new(config).unwrap();
    let mut rotations: Vec<Rotation> = beams
        .iter()
        .filter_map(|b| stream.push(b).unwrap())
        .collect();
    rotations.extend(stream.finish());
    rotations
}

/// On a head with steady settings the stream's causal thresholds cut where
/// the batch function does: continuous turns with jitter, a time gap,
/// sector scans, a reversal, a partial end kept on request.
#[test]
fn the_stream_cuts_like_the_batch_function() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut jittered = continuous(1200, -1.0, -1.0);
    for b in &mut jittered {
        b.stamp_s += rng.random_range(-0.01..0.01);
    }
    let mut gap = continuous(800, 0.5, 1.0);
    for b in &mut gap[350..] {
        b.stamp_s += 10.6;
    }
    let fly_back = beams_from_angles((0..4).flat_map(|_| (0..50).map(|i| i as f64 * STEP_RAD)));
    let mut reversal: Vec<f64> = (0..300).map(|i| i as f64 * STEP_RAD).collect();
    reversal.extend((1..=400).map(|i| 299.0 * STEP_RAD - i as f64 * STEP_RAD));
    let reversal = beams_from_angles(reversal.into_iter().map(wrap_angle));
    let keep = RotationConfig {
        keep_partial: true,
        ..RotationConfig::default()
    };
    let cases = [
        (continuous(1000, 3.0, 1.0), RotationConfig::default()),
        (jittered, RotationConfig::default()),
        (gap, RotationConfig::default()),
        (fly_back, RotationConfig::default()),
        (reversal, RotationConfig::default()),
        (continuous(520, 0.0, 1.0), keep),
    ];
    for (k, (beams, config)) in cases.iter().enumerate() {
        let batch = assemble_rotations(beams, config).unwrap();
        let stream = streamed(beams, config);
        assert_eq!(ranges(&stream), ranges(&batch), "case {k}");
        for (s, b) in stream.iter().zip(&batch) {
            assert_eq!(
                (s.index, s.kind, s.start_s, s.end_s),
                (b.index, b.kind, b.start_s, b.end_s)
            );
            // The median step of a window, not of the whole stream.
            assert!((s.coverage_rad - b.coverage_rad).abs() < 1e-6, "case {k}");
        }
    }
}

#[test]
fn the_stream_names_the_beam_that_goes_back_in_time() {
    let beams = continuous(10, 0.0, 1.0);
    let mut stream = RotationStream::new(&RotationConfig::default()).unwrap();
    stream.push(&beams[5]).unwrap();
    let err = stream.push(&beams[4]).unwrap_err().to_string();
    assert!(err.contains("beam 1") && err.contains("stamp_s"), "{err}");
    assert_eq!(stream.beams(), 1);
}
