//! The real St Pere sonar point sets (`datasets/stpere-marina-sonar`,
//! rotations 1-115 in their compact band form) read back as beams beside
//! the mission's real navigation (`datasets/stpere-marina`).

use echofield_datasets::stpere::keyframes::POINT_INTENSITY;
use echofield_datasets::stpere::point_bands::{
    ST_PERE_SETUP, expand_point_bands, read_point_bands,
};
use echofield_datasets::stpere::{SonarSetup, read_stpere_with_keyframes};
use echofield_frontend::sensors::{MountingSource, SweepTiming};
use std::path::{Path, PathBuf};

fn data(dir: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(dir)
}

const SETUP: SonarSetup = ST_PERE_SETUP;

/// The 115 PCD files, expanded into a temporary folder.
fn keyframe_folder() -> (tempfile::TempDir, usize) {
    let dir = tempfile::tempdir().unwrap();
    let sonar = data("stpere-marina-sonar");
    let points = expand_point_bands(
        &sonar.join("bands.csv"),
        &sonar.join("keyFrameTimeStamps.csv"),
        &SETUP,
        dir.path(),
    )
    .unwrap();
    (dir, points)
}

#[test]
fn every_point_goes_back_to_one_bin_of_one_of_200_beams_per_rotation() {
    let (dir, points) = keyframe_folder();
    // The shared folder's README: 1.6k-8.7k points per rotation; these
    // are the 115 files' 479 917 points.
    assert_eq!(points, 479_917);
    let (logs, kf) = read_stpere_with_keyframes(
        &data("stpere-marina"),
        dir.path(),
        SweepTiming::AngleDecreasing,
    )
    .unwrap();
    assert_eq!(kf.rotations.len(), 115);
    assert_eq!(logs.mission.beams.len(), 115 * 200);
    assert_eq!(logs.mission.mounting.sweep, SweepTiming::AngleDecreasing);
    assert_eq!(logs.mission.mounting.source, MountingSource::Assumed);
    let lit: usize = logs
        .mission
        .beams
        .iter()
        .map(|b| {
            b.intensities
                .iter()
                .filter(|&&v| v == POINT_INTENSITY)
                .count()
        })
        .sum();
    assert_eq!(lit, points);
    for r in &kf.rotations {
        assert!((1_500..=9_000).contains(&r.points), "{r:?}");
        assert!(
            r.beams_with_points <= 200 && r.beams_with_points > 20,
            "{r:?}"
        );
        assert!((r.end_s - r.begin_s - 13.8).abs() < 0.5, "{r:?}");
    }
    // Time order, and each rotation's first beam at angle 0 on its CSV time.
    let beams = &logs.mission.beams;
    assert!(beams.windows(2).all(|w| w[1].stamp_s > w[0].stamp_s));
    for (k, r) in kf.rotations.iter().enumerate() {
        let first = &beams[200 * k];
        assert!((first.stamp_s - r.begin_s).abs() < 0.002);
        assert_eq!(first.angle_rad, 0.0);
        // Decreasing sweep: the next beam is one step clockwise.
        assert!((beams[200 * k + 1].angle_rad + std::f64::consts::TAU / 200.0).abs() < 1e-9);
    }
}

#[test]
fn the_sweep_assumption_only_moves_stamps_between_beams_of_a_rotation() {
    let (dir, _) = keyframe_folder();
    let read = |sweep| {
        read_stpere_with_keyframes(&data("stpere-marina"), dir.path(), sweep)
            .unwrap()
            .0
            .mission
    };
    let up = read(SweepTiming::AngleIncreasing);
    let down = read(SweepTiming::AngleDecreasing);
    // Beam j steps into a rotation under one assumption is beam 200 - j under the other.
    for k in 0..115 {
        for j in 1..200 {
            let a = &up.beams[200 * k + j];
            let b = &down.beams[200 * k + 200 - j];
            assert_eq!(a.intensities, b.intensities);
            assert!((a.angle_rad - b.angle_rad).abs() < 1e-9);
        }
    }
}

#[test]
fn the_band_form_rejects_bad_rows_by_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bands.csv");
    std::fs::write(
        &path,
        "keyframe,angle_index,first_bin,last_bin\n1,3,10,12\n1,4,9,x\n",
    )
    .unwrap();
    let err = read_point_bands(&path).unwrap_err().to_string();
    assert!(err.contains("line 3"), "{err}");
    std::fs::write(&path, "keyframe,angle_index,first_bin,last_bin\n1,3,10,8\n").unwrap();
    let err = read_point_bands(&path).unwrap_err().to_string();
    assert!(err.contains("line 2") && err.contains("first_bin"), "{err}");
}
