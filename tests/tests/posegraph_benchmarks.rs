//! Every standard 2D benchmark in `datasets/posegraph` reaches the best known
//! χ² (g2o error, the column echofield uses in REFERENCE.md) to 1e-6
//! relative, starting from the file's own vertices (or the odometry chain
//! for files without vertices), with the default solver configuration.

use echofield_backend::{SolverConfig, graph_chi2, optimize};
use echofield_graph::io::read_pose_graph;
use echofield_tests::datasets_dir;

const TOLERANCE: f64 = 1e-6;

/// Solves `file` and checks its χ² against `best`.
fn reaches(file: &str, best: f64) {
    let path = datasets_dir().join("posegraph").join(file);
    let mut graph = read_pose_graph(&path).unwrap_or_else(|e| panic!("{e}"));
    let summary = optimize(&mut graph, &SolverConfig::default()).unwrap();
    assert!(
        summary.termination.is_converged(),
        "{file}: {:?}",
        summary.termination
    );
    // The summary agrees with a fresh evaluation of the returned poses.
    let chi2 = graph_chi2(&graph);
    assert!((chi2 - summary.final_chi2).abs() <= 1e-9 * chi2);
    let relative = (chi2 - best) / best;
    assert!(
        relative.abs() <= TOLERANCE,
        "{file}: chi2 {chi2:.10} vs best {best:.10} (relative {relative:.2e}, {} iterations)",
        summary.iterations
    );
}

#[test]
fn m3500() {
    reaches("M3500.g2o", 137.9129509);
}

#[test]
fn manhattan_from_odometry() {
    // g2o's LM from the same start stops at 146120.6695.
    reaches("manhattan.g2o", 3549.036796);
}

#[test]
fn manhattan_olson_3500() {
    reaches("vertigo-manhattan/manhattanOlson3500.g2o", 146.0766129);
}

#[test]
fn intel() {
    reaches("intel.g2o", 45.00469581);
}

#[test]
fn csail_from_odometry() {
    reaches("CSAIL.g2o", 40.55512885);
}

/// REFERENCE.md lists 526.3310383 as the best χ² of MIT (g2o's LM from the
/// file's start; GTSAM stops at 770.24), but that is a local minimum too.
/// echofield reaches 41.16326884; this value was checked independently of
/// echofield: the χ² of the written poses recomputed in Python from the
/// file's edges, and g2o's own LM (g2opy 2.3.0, first vertex fixed) started
/// from those poses stays at 41.16326883521 (and GTSAM 4.3.0 polishes them
/// to 41.2069 under its Lie error, against its 525.33 "best").
#[test]
fn mit_beats_the_reference() {
    let reference = 526.3310383;
    reaches("MIT.g2o", 41.16326884);
    assert!(41.16326884 < reference);
}

#[test]
fn city10000() {
    // g2o's LM from the same start stops at 1484.685685.
    reaches("city10000.g2o", 511.9851636);
}

#[test]
fn ring() {
    reaches("vertigo-ring/ring.g2o", 11.16310083);
}
