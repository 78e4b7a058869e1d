use super::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Exp1};

/// A beam of `n` bins of 0.1 m holding `profile`.
fn beam(profile: Vec<u8>) -> SonarBeam {
    SonarBeam {
        stamp_s: 0.0,
        angle_rad: 0.0,
        bin_size_m: 0.1,
        first_bin_range_m: 0.0,
        intensities: profile,
    }
}

/// Adds a triangular echo of half-width 3 bins peaking at `bin`.
fn add_echo(profile: &mut [u8], bin: usize, peak: u8) {
    for (d, scale) in [(0usize, 1.0), (1, 0.75), (2, 0.5), (3, 0.25)] {
        for i in [bin.saturating_sub(d), (bin + d).min(profile.len() - 1)] {
            let v = (peak as f64 * scale) as u8;
            profile[i] = profile[i].max(v);
        }
    }
}

fn bins(returns: &[RangeReturn]) -> Vec<usize> {
    returns.iter().map(|r| r.bin).collect()
}

#[test]
fn strongest_peak_gives_the_far_end_of_its_bin() {
    let mut profile = vec![5u8; 500];
    add_echo(&mut profile, 100, 200);
    add_echo(&mut profile, 300, 150);
    let returns = extract_ranges(&beam(profile.clone()), &SegmentationConfig::default());
    assert_eq!(bins(&returns), vec![100]);
    assert!((returns[0].range_m - 10.1).abs() < 1e-12);
    // Smoothed over 3 bins: (150 + 200 + 150) / 3.
    assert!((returns[0].intensity - 500.0 / 3.0).abs() < 1e-3);

    let mut shifted = beam(profile);
    shifted.first_bin_range_m = 0.5;
    let returns = extract_ranges(&shifted, &SegmentationConfig::default());
    assert!((returns[0].range_m - 10.6).abs() < 1e-12);
}

#[test]
fn the_blind_zone_hides_transducer_ringing() {
    let mut profile = vec![5u8; 500];
    profile[..8].fill(255);
    add_echo(&mut profile, 250, 120);
    let returns = extract_ranges(&beam(profile.clone()), &SegmentationConfig::default());
    assert_eq!(bins(&returns), vec![250]);
    let no_blind_zone = SegmentationConfig {
        blind_zone_m: 0.0,
        ..SegmentationConfig::default()
    };
    // Saturated bins 0-7 smooth to a plateau of 255 over bins 0-6: its centre.
    assert_eq!(
        bins(&extract_ranges(&beam(profile.clone()), &no_blind_zone)),
        vec![3]
    );
    // Bin 9 has its centre at 0.95 m: inside a 0.95 m blind zone's edge, out of a 0.96 m one.
    let mut profile = vec![5u8; 500];
    add_echo(&mut profile, 9, 200);
    let edge = |blind_zone_m| SegmentationConfig {
        blind_zone_m,
        smoothing_bins: 1,
        ..SegmentationConfig::default()
    };
    assert_eq!(
        bins(&extract_ranges(&beam(profile.clone()), &edge(0.95))),
        vec![9]
    );
    assert_eq!(bins(&extract_ranges(&beam(profile), &edge(0.96))), vec![10]);
}

#[test]
fn max_range_limits_the_search() {
    let mut profile = vec![5u8; 500];
    add_echo(&mut profile, 450, 220);
    add_echo(&mut profile, 200, 100);
    let config = SegmentationConfig {
        max_range_m: Some(30.0),
        ..SegmentationConfig::default()
    };
    assert_eq!(bins(&extract_ranges(&beam(profile), &config)), vec![200]);
}

#[test]
fn absolute_and_statistical_thresholds_reject_weak_and_noise_only_beams() {
    let mut weak = vec![5u8; 500];
    add_echo(&mut weak, 100, 45);
    assert!(extract_ranges(&beam(weak), &SegmentationConfig::default()).is_empty());

    // Exponential speckle of mean 30 and nothing else, smoothed over 5 bins:
    // the absolute threshold alone accepts its largest value, six standard
    // deviations above the mean do not.
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let speckle: Vec<u8> = (0..500)
        .map(|_| {
            let e: f64 = Exp1.sample(&mut rng);
            (30.0 * e).min(255.0) as u8
        })
        .collect();
    let absolute_only = SegmentationConfig {
        min_sigma_above_mean: 0.0,
        smoothing_bins: 5,
        ..SegmentationConfig::default()
    };
    assert_eq!(
        extract_ranges(&beam(speckle.clone()), &absolute_only).len(),
        1
    );
    let statistical = SegmentationConfig {
        min_sigma_above_mean: 6.0,
        ..absolute_only.clone()
    };
    assert!(extract_ranges(&beam(speckle.clone()), &statistical).is_empty());
    // The same speckle with a wall echo: found.
    let mut with_wall = speckle;
    add_echo(&mut with_wall, 321, 250);
    assert_eq!(
        bins(&extract_ranges(&beam(with_wall), &statistical)),
        vec![321]
    );

    // A flat profile has no peak above its own mean.
    assert!(extract_ranges(&beam(vec![100; 500]), &SegmentationConfig::default()).is_empty());
}

#[test]
fn multiple_mode_returns_separated_peaks_strongest_first_sorted_by_range() {
    let mut profile = vec![5u8; 500];
    add_echo(&mut profile, 100, 200);
    add_echo(&mut profile, 106, 150); // 0.6 m from the strongest: suppressed
    add_echo(&mut profile, 300, 120);
    add_echo(&mut profile, 400, 90);
    let config = SegmentationConfig {
        mode: PeakMode::Multiple,
        max_peaks: 2,
        min_sigma_above_mean: 0.0,
        ..SegmentationConfig::default()
    };
    assert_eq!(
        bins(&extract_ranges(&beam(profile.clone()), &config)),
        vec![100, 300]
    );
    let three = SegmentationConfig {
        max_peaks: 3,
        ..config.clone()
    };
    assert_eq!(
        bins(&extract_ranges(&beam(profile.clone()), &three)),
        vec![100, 300, 400]
    );
    let close = SegmentationConfig {
        max_peaks: 5,
        min_peak_separation_m: 0.5,
        smoothing_bins: 1,
        ..config
    };
    assert_eq!(
        bins(&extract_ranges(&beam(profile), &close)),
        vec![100, 106, 300, 400]
    );
}

#[test]
fn smoothing_prefers_a_wide_echo_over_a_single_bin_spike() {
    let mut profile = vec![5u8; 500];
    profile[50] = 255; // speckle spike
    add_echo(&mut profile, 200, 180);
    let raw = SegmentationConfig {
        smoothing_bins: 1,
        ..SegmentationConfig::default()
    };
    assert_eq!(
        bins(&extract_ranges(&beam(profile.clone()), &raw)),
        vec![50]
    );
    let smoothed = SegmentationConfig {
        smoothing_bins: 5,
        ..SegmentationConfig::default()
    };
    assert_eq!(bins(&extract_ranges(&beam(profile), &smoothed)), vec![200]);
}

#[test]
fn a_one_bin_echo_keeps_its_bin_after_smoothing_and_shoulders_are_not_peaks() {
    let mut profile = vec![5u8; 500];
    profile[79] = 250;
    profile[200..203].copy_from_slice(&[90, 90, 140]); // a shoulder, then a peak
    let multiple = SegmentationConfig {
        mode: PeakMode::Multiple,
        min_sigma_above_mean: 0.0,
        min_peak_separation_m: 0.0,
        max_peaks: 10,
        smoothing_bins: 1,
        ..SegmentationConfig::default()
    };
    assert_eq!(
        bins(&extract_ranges(&beam(profile.clone()), &multiple)),
        vec![79, 202]
    );
    profile[200..203].fill(5);
    for width in [3, 5] {
        let config = SegmentationConfig {
            smoothing_bins: width,
            ..SegmentationConfig::default()
        };
        // The smoothed spike is a plateau `width` bins wide centred on 79.
        assert_eq!(
            bins(&extract_ranges(&beam(profile.clone()), &config)),
            vec![79]
        );
    }
}

#[test]
fn degenerate_beams_give_no_returns() {
    let config = SegmentationConfig::default();
    assert!(extract_ranges(&beam(Vec::new()), &config).is_empty());
    let mut b = beam(vec![200; 50]);
    b.bin_size_m = f64::NAN;
    assert!(extract_ranges(&b, &config).is_empty());
    // Every bin inside the blind zone.
    let mut short = vec![0u8; 8];
    short[5] = 250;
    assert!(extract_ranges(&beam(short), &config).is_empty());
}

#[test]
fn moving_average_matches_the_definition() {
    let values = [10u8, 20, 30, 40, 50];
    let mut out = Vec::new();
    smooth(&values, 3, &mut out);
    assert_eq!(out, vec![15.0, 20.0, 30.0, 40.0, 45.0]);
    smooth(&values, 4, &mut out); // window [i - 2, i + 1]
    assert_eq!(out, vec![15.0, 20.0, 25.0, 35.0, 40.0]);
    smooth(&values, 1, &mut out);
    assert_eq!(out, vec![10.0, 20.0, 30.0, 40.0, 50.0]);
}

#[test]
fn moving_average_agrees_with_a_direct_sum_on_random_profiles() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for len in [1usize, 2, 3, 7, 40, 500] {
        let profile: Vec<u8> = (0..len).map(|_| rng.random()).collect();
        for width in 1..=9 {
            let mut out = Vec::new();
            smooth(&profile, width, &mut out);
            assert_eq!(out.len(), len);
            for (i, &v) in out.iter().enumerate() {
                let lo = i.saturating_sub(width / 2);
                let hi = (i + width - width / 2).min(len);
                let sum: u32 = profile[lo..hi].iter().map(|&x| x as u32).sum();
                let direct = sum as f32 / (hi - lo) as f32;
                assert!(
                    (v - direct).abs() <= 1e-4 * direct.max(1.0),
                    "len {len} width {width} bin {i}"
                );
            }
        }
    }
}

#[test]
fn config_validation_and_serde() {
    assert!(SegmentationConfig::default().validate().is_ok());
    let bad = [
        SegmentationConfig {
            blind_zone_m: -1.0,
            ..SegmentationConfig::default()
        },
        SegmentationConfig {
            max_range_m: Some(0.5),
            ..SegmentationConfig::default()
        },
        SegmentationConfig {
            min_intensity: 300.0,
            ..SegmentationConfig::default()
        },
        SegmentationConfig {
            max_peaks: 0,
            ..SegmentationConfig::default()
        },
        SegmentationConfig {
            smoothing_bins: 0,
            ..SegmentationConfig::default()
        },
        SegmentationConfig {
            min_sigma_above_mean: f64::NAN,
            ..SegmentationConfig::default()
        },
    ];
    for config in bad {
        assert!(matches!(
            config.validate(),
            Err(FrontendError::InvalidConfig { .. })
        ));
    }
    let parsed: SegmentationConfig =
        serde_json::from_str(r#"{"mode": "multiple", "max_peaks": 2, "max_range_m": 40.0}"#)
            .unwrap();
    assert_eq!(parsed.mode, PeakMode::Multiple);
    assert_eq!(parsed.max_range_m, Some(40.0));
    assert_eq!(
        parsed.blind_zone_m,
        SegmentationConfig::default().blind_zone_m
    );
    let err = serde_json::from_str::<SegmentationConfig>(r#"{"threshold": 3}"#).unwrap_err();
    assert!(err.to_string().contains("threshold"));
}

#[test]
fn ringing_of_varying_length_is_skipped_per_beam() {
    let config = SegmentationConfig {
        blind_zone_m: 0.5,
        ringing_below_intensity: Some(200.0),
        min_sigma_above_mean: 0.0,
        ..SegmentationConfig::default()
    };
    // Ringing saturates bins 0-39 (4 m) in one beam and 0-11 in the other;
    // an echo of 180 at 6 m and one of 150 at 2.5 m.
    let mut long = vec![5u8; 300];
    long[..40].fill(255);
    add_echo(&mut long, 60, 180);
    let mut short = vec![5u8; 300];
    short[..12].fill(255);
    add_echo(&mut short, 25, 150);
    assert_eq!(
        bins(&extract_ranges(&beam(long.clone()), &config)),
        vec![60]
    );
    assert_eq!(
        bins(&extract_ranges(&beam(short.clone()), &config)),
        vec![25]
    );
    // Without it the 0.5 m blind zone leaves the saturated bins in the
    // window, and their plateau wins.
    let fixed = SegmentationConfig {
        ringing_below_intensity: None,
        ..config.clone()
    };
    assert!(extract_ranges(&beam(long), &fixed)[0].bin < 40);
    assert!(extract_ranges(&beam(short.clone()), &fixed)[0].bin < 12);
    // The blind zone still applies when it is farther than the ringing.
    let far_blind = SegmentationConfig {
        blind_zone_m: 3.0,
        ..config.clone()
    };
    assert!(extract_ranges(&beam(short), &far_blind).is_empty());
    // A beam that rings to its end has no return.
    assert!(extract_ranges(&beam(vec![255u8; 100]), &config).is_empty());
}

#[test]
fn ringing_level_is_validated() {
    for level in [0.0, -1.0, 256.0, f64::NAN] {
        let config = SegmentationConfig {
            ringing_below_intensity: Some(level),
            ..SegmentationConfig::default()
        };
        assert!(config.validate().is_err(), "{level}");
    }
    let ok = SegmentationConfig {
        ringing_below_intensity: Some(200.0),
        ..SegmentationConfig::default()
    };
    ok.validate().unwrap();
}
