//! Seeded synthetic pose graphs: the optimum recovers the ground truth, both
//! algorithms agree, the gauge follows fixed nodes and priors, and a reused
//! solver gives the same answer as a fresh one.

use echofield_backend::{
    Algorithm, Initialisation, SolveSummary, Solver, SolverConfig, Termination, optimize,
};
use echofield_graph::synthetic::{Noise, SyntheticGraph, circle_pose_graph, grid_pose_graph};
use echofield_graph::{Edge, EdgeKind, PoseGraph, Se2, wrap_angle};
use nalgebra::Matrix3;

/// Largest position (m) and heading (rad) error against the ground truth.
fn max_errors(graph: &PoseGraph, truth: &[Se2]) -> (f64, f64) {
    graph
        .poses()
        .iter()
        .zip(truth)
        .fold((0.0, 0.0), |(dp, dt), (p, t)| {
            let position = (p.translation() - t.translation()).norm();
            let heading = wrap_angle(p.theta() - t.theta()).abs();
            (f64::max(dp, position), f64::max(dt, heading))
        })
}

fn solve(fixture: &mut SyntheticGraph, config: &SolverConfig) -> SolveSummary {
    let summary = optimize(&mut fixture.graph, config).unwrap();
    assert!(
        summary.termination.is_converged(),
        "{:?}",
        summary.termination
    );
    summary
}

/// With (almost) noise-free measurements the optimum is the ground truth.
#[test]
fn noise_free_graphs_recover_the_ground_truth_exactly() {
    let noise = Noise::new(1e-7, 1e-8);
    for (name, mut fixture) in [
        ("circle", circle_pose_graph(200, 3, noise, 1)),
        ("grid", grid_pose_graph(400, noise, 2)),
    ] {
        let start = max_errors(&fixture.graph, &fixture.ground_truth);
        solve(&mut fixture, &SolverConfig::default());
        let (dp, dt) = max_errors(&fixture.graph, &fixture.ground_truth);
        assert!(
            dp < 1e-5 && dt < 1e-6,
            "{name}: {dp} m, {dt} rad (start {start:?})"
        );
    }
}

/// With noisy measurements the solution is close to the truth and closer
/// than dead reckoning (loop closures average the laps); the final χ² is
/// consistent with the noise: its expectation is 3·edges − 3·free poses,
/// its standard deviation √(2·dof).
#[test]
fn noisy_graphs_land_near_the_ground_truth() {
    let noise = Noise::new(0.02, 0.002);
    for (name, mut fixture) in [
        ("circle", circle_pose_graph(300, 4, noise, 11)),
        ("grid", grid_pose_graph(500, noise, 12)),
    ] {
        let (start_dp, _) = max_errors(&fixture.graph, &fixture.ground_truth);
        let summary = solve(&mut fixture, &SolverConfig::default());
        let (dp, dt) = max_errors(&fixture.graph, &fixture.ground_truth);
        assert!(dp < 0.4 && dt < 0.03, "{name}: {dp} m, {dt} rad");
        assert!(
            dp < 0.5 * start_dp,
            "{name}: {dp} m vs dead reckoning {start_dp} m"
        );
        let dof = 3.0 * (summary.edges as f64 - summary.free_poses as f64);
        assert!(
            (summary.final_chi2 - dof).abs() < 5.0 * (2.0 * dof).sqrt(),
            "{name}: chi2 {} for {dof} degrees of freedom",
            summary.final_chi2
        );
    }
}

/// Gauss-Newton and Levenberg-Marquardt, from the chordal start or from dead
/// reckoning, reach the same optimum.
#[test]
fn algorithms_and_starts_agree() {
    let fixture = grid_pose_graph(300, Noise::new(0.05, 0.01), 5);
    let mut results = Vec::new();
    for algorithm in [Algorithm::GaussNewton, Algorithm::LevenbergMarquardt] {
        for initialisation in [Initialisation::Chordal, Initialisation::Current] {
            let mut graph = fixture.graph.clone();
            let config = SolverConfig {
                algorithm,
                initialisation,
                ..SolverConfig::default()
            };
            let summary = optimize(&mut graph, &config).unwrap();
            assert!(
                summary.termination.is_converged(),
                "{algorithm:?} {initialisation:?}"
            );
            results.push((summary.final_chi2, graph.poses()));
        }
    }
    let (chi2, poses) = &results[0];
    for (other_chi2, other_poses) in &results[1..] {
        assert!((chi2 - other_chi2).abs() < 1e-8 * chi2);
        for (a, b) in poses.iter().zip(other_poses) {
            assert!((a.to_vector() - b.to_vector()).norm() < 1e-6);
        }
    }
}

/// Fixed nodes stay where they are; priors replace the default gauge.
#[test]
fn fixed_nodes_and_priors_set_the_gauge() {
    let mut fixture = circle_pose_graph(60, 2, Noise::new(0.05, 0.01), 3);
    let held = fixture.graph.node(30).unwrap().pose;
    fixture.graph.fix(30).unwrap();
    let summary = solve(&mut fixture, &SolverConfig::default());
    assert_eq!(summary.free_poses, 59);
    assert_eq!(fixture.graph.node(30).unwrap().pose, held);

    // A strong prior on node 10 at its true pose and no fixed node: node 0
    // is free and node 10 ends at the prior.
    let mut fixture = circle_pose_graph(60, 2, Noise::new(0.05, 0.01), 3);
    let truth = fixture.ground_truth[10];
    let info = Matrix3::from_diagonal_element(1e8);
    let prior = Edge::new(EdgeKind::Prior, 10, 10, truth, info);
    fixture.graph.add_edge(prior).unwrap();
    let summary = solve(&mut fixture, &SolverConfig::default());
    assert_eq!(summary.free_poses, 60);
    let got = fixture.graph.node(10).unwrap().pose;
    assert!((got.to_vector() - truth.to_vector()).norm() < 1e-4);
}

/// A reused solver keeps its symbolic factorisation while the pattern is
/// unchanged, rebuilds it when the graph grows, and always matches a fresh
/// solve.
#[test]
fn solver_reuses_the_symbolic_factorisation_while_the_pattern_holds() {
    let fixture = circle_pose_graph(120, 2, Noise::new(0.05, 0.01), 9);
    let config = SolverConfig::default();
    let mut solver = Solver::new(config.clone()).unwrap();
    let mut graph = fixture.graph.clone();
    let first = solver.optimize(&mut graph).unwrap();
    assert!(!first.symbolic_reused);
    // Same pattern, new values: perturb one measurement's pose start.
    let mut again = fixture.graph.clone();
    let second = solver.optimize(&mut again).unwrap();
    assert!(second.symbolic_reused);
    assert_eq!(graph.poses(), again.poses());

    // The graph grows by one node and two edges: a new analysis.
    let last = again.node(119).unwrap().pose;
    let step = Se2::new(0.5, 0.0, 0.1);
    again
        .add_node(echofield_graph::Node {
            id: 120,
            pose: last.compose(&step),
            stamp_s: None,
        })
        .unwrap();
    let info = Matrix3::from_diagonal(&nalgebra::Vector3::new(400.0, 400.0, 1e4));
    again
        .add_edge(Edge::new(EdgeKind::Odometry, 119, 120, step, info))
        .unwrap();
    again
        .add_edge(Edge::new(EdgeKind::Loop, 60, 120, step, info))
        .unwrap();
    let mut fresh = again.clone();
    let grown = solver.optimize(&mut again).unwrap();
    assert!(!grown.symbolic_reused);
    let reference = optimize(&mut fresh, &config).unwrap();
    assert!((grown.final_chi2 - reference.final_chi2).abs() <= 1e-12 * reference.final_chi2);
    assert_eq!(again.poses(), fresh.poses());
}

/// Every node fixed: nothing to do, and the poses are untouched.
#[test]
fn nothing_to_optimise() {
    let mut fixture = circle_pose_graph(10, 1, Noise::new(0.05, 0.01), 4);
    for id in 0..10 {
        fixture.graph.fix(id).unwrap();
    }
    let before = fixture.graph.poses();
    let summary = optimize(&mut fixture.graph, &SolverConfig::default()).unwrap();
    assert_eq!(summary.termination, Termination::NothingToOptimise);
    assert_eq!(summary.iterations, 0);
    assert_eq!(fixture.graph.poses(), before);
}

/// The summary serialises with the keys the CLI documents, the termination
/// as a string.
#[test]
fn summary_serialises() {
    let mut fixture = circle_pose_graph(30, 1, Noise::new(0.05, 0.01), 4);
    let summary = solve(&mut fixture, &SolverConfig::default());
    let json = serde_json::to_value(&summary).unwrap();
    for key in [
        "initial_chi2",
        "final_chi2",
        "iterations",
        "time_s",
        "termination",
        "log",
    ] {
        assert!(json.get(key).is_some(), "missing {key}");
    }
    assert!(json["termination"].is_string());
    assert_eq!(json["log"].as_array().unwrap().len(), summary.iterations);
    let first = &json["log"][0];
    for key in ["chi2", "lambda", "step_norm", "time_s"] {
        assert!(first.get(key).is_some(), "log entry misses {key}");
    }
}

/// The parallel factorisation gives the same optimum as the sequential one.
#[test]
fn threads_do_not_change_the_result() {
    let fixture = grid_pose_graph(400, Noise::new(0.05, 0.01), 21);
    let mut sequential = fixture.graph.clone();
    let mut parallel = fixture.graph.clone();
    let one = optimize(&mut sequential, &SolverConfig::default()).unwrap();
    let config = SolverConfig {
        threads: 2,
        ..SolverConfig::default()
    };
    let two = optimize(&mut parallel, &config).unwrap();
    assert!((one.final_chi2 - two.final_chi2).abs() < 1e-9 * one.final_chi2);
    for (a, b) in sequential.poses().iter().zip(parallel.poses().iter()) {
        assert!((a.to_vector() - b.to_vector()).norm() < 1e-8);
    }
}

/// A solver can move to another thread (e.g. a mission's optimisation
/// worker).
#[test]
fn solver_is_send() {
    fn assert_send<T: Send>() {}
    assert_send::<echofield_backend::Solver>();
    assert_send::<SolveSummary>();
}
