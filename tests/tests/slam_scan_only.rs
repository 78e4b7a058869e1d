//! Scan-only data end to end: the St Pere replay (real navigation,
//! simulated beams) thresholded as the published St Pere point sets were,
//! and reduced to one range per beam as a LaserScan would carry it. The
//! pipeline must find out that the intensities are binary, derive its
//! settings for them (`echofield_frontend::intensity`) and still remove
//! most of the dead reckoning's drift.

use echofield::slam::{NoProgress, SlamConfig, run_mission};
use echofield_datasets::sim::point_sets::to_point_sets;
use echofield_datasets::sim::{Mission, Scenario, simulate_mission};
use echofield_frontend::intensity::IntensityKind;

fn replay() -> Mission {
    simulate_mission(&Scenario::named("stpere").unwrap(), 1).unwrap()
}

fn run(mission: &Mission) -> echofield::slam::Report {
    run_mission(mission, &SlamConfig::default(), &NoProgress)
        .unwrap()
        .report
}

/// The run's ATE and the dead reckoning's, metres (printed).
fn ate_and_dead_reckoning(report: &echofield::slam::Report) -> (f64, f64) {
    let (ate, dr) = (
        report.ate_rmse_m.unwrap(),
        report.ate_rmse_dead_reckoning_m.unwrap(),
    );
    eprintln!("ATE {ate:.3} m, dead reckoning {dr:.3} m");
    (ate, dr)
}

#[test]
fn point_sets_are_detected_and_still_remove_the_drift() {
    let mut mission = replay();
    to_point_sets(&mut mission.beams);
    let report = run(&mission);
    assert_eq!(
        report.intensity.kind,
        IntensityKind::Binary {
            level: echofield_datasets::sim::point_sets::KEPT_INTENSITY
        }
    );
    assert!(
        report
            .intensity
            .derived
            .iter()
            .any(|d| d == "segmentation.off_axis.enabled = false"),
        "{:?}",
        report.intensity.derived
    );
    let (ate, dr) = ate_and_dead_reckoning(&report);
    // The measured figures, with the graded beams of the same replay for
    // comparison: EXPERIMENTS.md § Where the loops' excess length comes from.
    assert!(
        ate < 0.45 && ate * 5.0 < dr,
        "ATE {ate} m, dead reckoning {dr} m"
    );
}

#[test]
fn ranges_only_are_detected_and_still_remove_the_drift() {
    let mut mission = replay();
    for beam in &mut mission.beams {
        let strongest = beam
            .intensities
            .iter()
            .enumerate()
            .skip(10)
            .max_by_key(|(i, v)| (**v, std::cmp::Reverse(*i)))
            .filter(|(_, v)| **v > 100)
            .map(|(i, _)| i);
        beam.intensities.fill(0);
        if let Some(i) = strongest {
            beam.intensities[i] = 1;
        }
    }
    let report = run(&mission);
    assert_eq!(report.intensity.kind, IntensityKind::Binary { level: 1 });
    let (ate, dr) = ate_and_dead_reckoning(&report);
    assert!(
        ate < 0.6 && ate * 4.0 < dr,
        "ATE {ate} m, dead reckoning {dr} m"
    );
}

#[test]
fn graded_beams_are_left_as_they_are() {
    let report = run(&replay());
    assert_eq!(report.intensity.kind, IntensityKind::Graded);
    assert!(report.intensity.derived.is_empty());
}
