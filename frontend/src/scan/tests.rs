use super::*;
use crate::dead_reckoning::Navigation;
use crate::image::synthetic::{RotationPath, SceneConfig, simulate_rotation};
use crate::motion::{reference_from_beams, uncompensated_reference_from_beams};
use crate::off_axis::OffAxisSuppression;
use crate::scan::beam_width::BeamWidthCorrection;
use crate::segmentation::PeakMode;
use crate::sensors::SensorMounting;
use nalgebra::{Matrix2, Vector2};
use std::f64::consts::FRAC_PI_2;

fn beam(angle_rad: f64, echo_bins: &[(usize, u8)]) -> SonarBeam {
    let mut intensities = vec![5u8; 300];
    for &(bin, v) in echo_bins {
        intensities[bin.saturating_sub(1)] = v / 2;
        intensities[bin] = v;
        intensities[bin + 1] = v / 2;
    }
    SonarBeam {
        stamp_s: 0.0,
        angle_rad,
        bin_size_m: 0.1,
        first_bin_range_m: 0.0,
        intensities,
    }
}

#[test]
fn each_return_lands_at_its_bin_endpoint_in_the_beam_frame() {
    let beams = vec![beam(0.0, &[(29, 200)]), beam(0.0, &[(49, 200), (149, 120)])];
    let frames = vec![Se2::new(1.0, 2.0, FRAC_PI_2), Se2::new(-1.0, 0.0, 0.0)];
    let config = SegmentationConfig {
        mode: PeakMode::Multiple,
        min_scan_points: 3,
        beam_width: BeamWidthCorrection::off(),
        ..SegmentationConfig::default()
    };
    let scan = build_scan(&beams, &frames, 42.0, &config).unwrap();
    assert!(scan.range_corrections_m.is_empty());
    assert_eq!(scan.reference_stamp_s, 42.0);
    assert_eq!(scan.beam_indices, vec![0, 1, 1]);
    let expected = [(1.0, 5.0), (4.0, 0.0), (14.0, 0.0)];
    for (p, (x, y)) in scan.points.iter().zip(expected) {
        assert!((p.x - x).abs() < 1e-9 && (p.y - y).abs() < 1e-9, "{p:?}");
    }
    // Smoothed over 3 bins: (100 + 200 + 100) / 3.
    assert!((scan.intensities[0] - 400.0 / 3.0).abs() < 1e-3);
}

/// RMS distance of points from their total-least-squares line.
fn line_fit_rms(points: &[Point2<f64>]) -> f64 {
    let n = points.len() as f64;
    let mean = points.iter().map(|p| p.coords).sum::<Vector2<f64>>() / n;
    let cov = points
        .iter()
        .map(|p| (p.coords - mean) * (p.coords - mean).transpose())
        .sum::<Matrix2<f64>>()
        / n;
    cov.symmetric_eigenvalues().min().max(0.0).sqrt()
}

#[test]
fn motion_compensated_wall_is_straight_and_uncompensated_is_not() {
    // 0.5 m/s while turning 1.5°/s through a ~13.8 s rotation in the basin,
    // heading for its east wall (x = 18 m, y from -8 to 12 m), which the
    // first and the last beams of the rotation both see, 7 m apart in travel.
    let scene = SceneConfig::default();
    let path = RotationPath {
        world_from_start: Se2::new(-3.0, 1.0, 0.2),
        velocity_mps: (0.5, 0.0),
        yaw_rate_radps: 1.5_f64.to_radians(),
    };
    let rotation = simulate_rotation(&scene, &path, 5);
    let beams = &rotation.beams;
    let t_ref = 0.5 * (beams[0].stamp_s + beams[beams.len() - 1].stamp_s);
    // Dead reckoning stand-in: the true path sampled at 10 Hz.
    let stamps: Vec<f64> = (0..=150).map(|i| i as f64 * 0.1).collect();
    let poses: Vec<Se2> = stamps.iter().map(|&t| path.pose_at(t)).collect();
    let nav = Navigation::from_poses(&stamps, &poses, 0.0).unwrap();
    let mounting = SensorMounting::default();
    // The synthetic scene's echoes are linear with ±40% noise per bin, not
    // decibels: the off-axis margin would drop wall echoes of this test.
    let config = SegmentationConfig {
        off_axis: OffAxisSuppression::off(),
        ..SegmentationConfig::default()
    };

    let frames = reference_from_beams(beams, &nav, &mounting, t_ref).unwrap();
    let compensated = build_scan(beams, &frames, t_ref, &config).unwrap();
    let still = uncompensated_reference_from_beams(beams, &mounting);
    let uncompensated = build_scan(beams, &still, t_ref, &config).unwrap();
    assert_eq!(compensated.beam_indices, uncompensated.beam_indices);

    // Points of the east wall, chosen by where the compensated scan puts
    // them in the world.
    let world_from_reference = path.pose_at(t_ref);
    let on_wall: Vec<usize> = (0..compensated.len())
        .filter(|&i| {
            let w = world_from_reference.transform_point(&compensated.points[i]);
            (w.x - 18.0).abs() < 0.5 && (-7.0..11.0).contains(&w.y)
        })
        .collect();
    assert!(on_wall.len() >= 25, "{} east-wall points", on_wall.len());
    let pick =
        |scan: &Scan| -> Vec<Point2<f64>> { on_wall.iter().map(|&i| scan.points[i]).collect() };
    let rms_with = line_fit_rms(&pick(&compensated));
    let rms_without = line_fit_rms(&pick(&uncompensated));
    assert!(
        rms_with < 0.1,
        "compensated: {rms_with} m RMS from a line (bin 0.1 m)"
    );
    assert!(
        rms_without > 0.5,
        "uncompensated: {rms_without} m RMS from a line"
    );

    // Nearly every compensated point lies on some wall, within a bin plus
    // the echo spread; far fewer uncompensated ones do.
    let near_a_wall = |scan: &Scan| {
        let on_wall = scan.points.iter().filter(|p| {
            let w = world_from_reference.transform_point(p);
            scene
                .walls
                .iter()
                .any(|wall| distance_to_segment(&w, &wall.a, &wall.b) < 0.25)
        });
        on_wall.count() as f64 / scan.len() as f64
    };
    let (with, without) = (near_a_wall(&compensated), near_a_wall(&uncompensated));
    assert!(
        with >= 0.95,
        "compensated: {with} of the points near a wall"
    );
    assert!(
        without < 0.6,
        "uncompensated: {without} of the points near a wall"
    );
}

fn distance_to_segment(p: &Point2<f64>, a: &Point2<f64>, b: &Point2<f64>) -> f64 {
    let e = b - a;
    let t = ((p - a).dot(&e) / e.norm_squared()).clamp(0.0, 1.0);
    (p - (a + e * t)).norm()
}

#[test]
fn a_silent_rotation_is_a_too_few_ranges_error() {
    let beams: Vec<SonarBeam> = (0..200).map(|k| beam(k as f64 * 0.0314, &[])).collect();
    let frames = uncompensated_reference_from_beams(&beams, &SensorMounting::default());
    let err = build_scan(&beams, &frames, 3.5, &SegmentationConfig::default()).unwrap_err();
    assert_eq!(
        err,
        FrontendError::TooFewRanges {
            reference_stamp_s: 3.5,
            found: 0,
            required: 10
        }
    );
    let lenient = SegmentationConfig {
        min_scan_points: 0,
        ..SegmentationConfig::default()
    };
    assert!(
        build_scan(&beams, &frames, 3.5, &lenient)
            .unwrap()
            .is_empty()
    );
    assert!(matches!(
        build_scan(&[], &[], 3.5, &SegmentationConfig::default()),
        Err(FrontendError::TooFewRanges { found: 0, .. })
    ));
}

#[test]
fn inconsistent_or_invalid_input_is_an_error_naming_the_beam() {
    let beams = vec![beam(0.0, &[(29, 200)]), beam(0.1, &[(49, 200)])];
    let frames = vec![Se2::identity(), Se2::identity()];
    let config = SegmentationConfig::default();
    assert!(matches!(
        build_scan(&beams, &frames[..1], 0.0, &config),
        Err(FrontendError::InvalidInput { ref field, .. }) if field == "reference_from_beams"
    ));
    let mut bad = beams.clone();
    bad[1].bin_size_m = -0.1;
    assert!(matches!(
        build_scan(&bad, &frames, 0.0, &config),
        Err(FrontendError::InvalidInput { ref record, ref field, .. })
            if record == "beam 1" && field == "bin_size_m"
    ));
    let nan_frames = vec![Se2::identity(), Se2::new(f64::NAN, 0.0, 0.0)];
    assert!(matches!(
        build_scan(&beams, &nan_frames, 0.0, &config),
        Err(FrontendError::InvalidInput { ref record, ref field, .. })
            if record == "beam 1" && field == "reference_from_beam"
    ));
    let bad_config = SegmentationConfig {
        smoothing_bins: 0,
        ..config
    };
    assert!(matches!(
        build_scan(&beams, &frames, 0.0, &bad_config),
        Err(FrontendError::InvalidConfig { .. })
    ));
}

#[test]
fn the_beam_width_correction_moves_returns_along_their_beams_and_the_image_frames_with_them() {
    // A wall y = 8 m seen by beams at 30-150°: incidences up to 60°.
    let frames: Vec<Se2> = (30..=150)
        .map(|deg| Se2::new(0.5, -0.2, f64::from(deg).to_radians()))
        .collect();
    let beams: Vec<SonarBeam> = frames
        .iter()
        .map(|f| {
            let bin = ((8.2 / f.theta().sin()) / 0.1).round() as usize - 1;
            beam(f.theta(), &[(bin, 200)])
        })
        .collect();
    let at_bins = |beam_width| {
        let config = SegmentationConfig {
            beam_width,
            ..SegmentationConfig::default()
        };
        build_scan(&beams, &frames, 0.0, &config).unwrap()
    };
    let plain = at_bins(BeamWidthCorrection::off());
    let corrected = at_bins(BeamWidthCorrection::default());
    assert_eq!(corrected.range_corrections_m.len(), plain.len());
    let image_frames = corrected.image_frames(&frames);
    for i in 0..plain.len() {
        let b = corrected.beam_indices[i] as usize;
        let axis = frames[b].rotation() * Vector2::x();
        let moved = corrected.points[i] - plain.points[i];
        let dr = f64::from(corrected.range_corrections_m[i]);
        // Outward along the beam, by the recorded amount.
        assert!((moved - axis * dr).norm() < 1e-9, "return {i}");
        assert!(dr > 0.0);
        // The image frame of the beam moved by the same amount.
        let shift = image_frames[b].translation() - frames[b].translation();
        assert!((shift - axis * dr).norm() < 1e-9, "frame {b}");
        assert!((image_frames[b].theta() - frames[b].theta()).abs() < 1e-12);
    }
    // Oblique beams are moved more than the beam at normal incidence.
    let by_beam = |deg: usize| corrected.range_corrections_m[deg - 30];
    assert!(
        by_beam(40) > 5.0 * by_beam(90),
        "{} vs {}",
        by_beam(40),
        by_beam(90)
    );
}
