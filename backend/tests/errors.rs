//! Bad graphs give the right error value, never a panic, and leave the
//! graph's poses untouched.

use echofield_backend::{
    Algorithm, RobustConfig, RobustKernel, SolveError, SolverConfig, optimize,
};
use echofield_graph::{Edge, EdgeKind, Node, PoseGraph, Se2};
use nalgebra::Matrix3;

fn chain(ids: &[u64]) -> PoseGraph {
    let mut graph = PoseGraph::new();
    for &id in ids {
        let pose = Se2::new(id as f64, 0.0, 0.0);
        graph
            .add_node(Node {
                id,
                pose,
                stamp_s: None,
            })
            .unwrap();
    }
    graph
}

fn odometry(graph: &mut PoseGraph, from: u64, to: u64) {
    let z = Se2::new(1.0, 0.1, 0.05);
    graph
        .add_edge(Edge::new(
            EdgeKind::Odometry,
            from,
            to,
            z,
            Matrix3::identity(),
        ))
        .unwrap();
}

#[test]
fn no_edges() {
    let mut graph = chain(&[0, 1, 2]);
    assert_eq!(
        optimize(&mut graph, &SolverConfig::default()),
        Err(SolveError::NoEdges)
    );
}

#[test]
fn disconnected_graph_names_an_unanchored_node() {
    let mut graph = chain(&[0, 1, 2, 7, 8]);
    odometry(&mut graph, 0, 1);
    odometry(&mut graph, 1, 2);
    odometry(&mut graph, 7, 8);
    let before = graph.poses();
    let err = optimize(&mut graph, &SolverConfig::default()).unwrap_err();
    assert_eq!(
        err,
        SolveError::Disconnected {
            components: 2,
            node: 7
        }
    );
    assert_eq!(graph.poses(), before);
    // A node with no edge at all is a component of its own.
    let mut graph = chain(&[0, 1, 2]);
    odometry(&mut graph, 0, 1);
    let err = optimize(&mut graph, &SolverConfig::default()).unwrap_err();
    assert_eq!(
        err,
        SolveError::Disconnected {
            components: 2,
            node: 2
        }
    );
    // Fixing a node of the second component anchors it.
    let mut graph = chain(&[0, 1, 2, 7, 8]);
    odometry(&mut graph, 0, 1);
    odometry(&mut graph, 1, 2);
    odometry(&mut graph, 7, 8);
    graph.fix(0).unwrap();
    graph.fix(8).unwrap();
    assert!(optimize(&mut graph, &SolverConfig::default()).is_ok());
}

#[test]
fn non_finite_pose() {
    let mut graph = chain(&[0, 1, 2]);
    odometry(&mut graph, 0, 1);
    odometry(&mut graph, 1, 2);
    let mut poses = graph.poses();
    poses[2] = Se2::new(f64::NAN, 0.0, 0.0);
    graph.set_poses(&poses);
    let err = optimize(&mut graph, &SolverConfig::default()).unwrap_err();
    assert_eq!(err, SolveError::NonFinitePose { node: 2 });
}

/// Node 3 hangs on a single loop closure that contradicts everything by
/// 1e85 m: DCS scales its weight to exactly zero, so without damping the
/// pose of node 3 is undetermined and Gauss-Newton must report it; LM's
/// damping keeps the system definite and simply leaves node 3 in place.
#[test]
fn indefinite_system_names_the_node() {
    let mut graph = chain(&[0, 1, 2, 3]);
    odometry(&mut graph, 0, 1);
    odometry(&mut graph, 1, 2);
    let absurd = Se2::new(1e85, 0.0, 0.0);
    graph
        .add_edge(Edge::new(EdgeKind::Loop, 0, 3, absurd, Matrix3::identity()))
        .unwrap();
    let config = SolverConfig {
        algorithm: Algorithm::GaussNewton,
        robust: RobustConfig::loops_only(RobustKernel::DCS_DEFAULT),
        ..SolverConfig::default()
    };
    let before = graph.poses();
    let err = optimize(&mut graph, &config).unwrap_err();
    assert_eq!(err, SolveError::SystemNotPositiveDefinite { node: 3 });
    assert_eq!(graph.poses(), before);
    let lm = SolverConfig {
        algorithm: Algorithm::LevenbergMarquardt,
        ..config
    };
    optimize(&mut graph, &lm).unwrap();
    assert_eq!(graph.node(3).unwrap().pose, before[3]);
}

#[test]
fn invalid_config() {
    let mut graph = chain(&[0, 1]);
    odometry(&mut graph, 0, 1);
    let config = SolverConfig {
        max_iterations: 0,
        ..SolverConfig::default()
    };
    assert!(matches!(
        optimize(&mut graph, &config),
        Err(SolveError::Config(_))
    ));
}
