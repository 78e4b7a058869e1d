//! Reading the committed benchmark graphs and round-tripping them.

use echofield_graph::io::{
    GraphFormat, detect_format, parse_pose_graph, read_pose_graph, toro, write_g2o,
};
use std::path::{Path, PathBuf};

/// Values written with shortest round-trip formatting come back exactly,
/// except θ, which goes through (cos θ, sin θ) and back: allow 1 ulp-ish.
fn assert_close(a: &echofield_graph::Se2, b: &echofield_graph::Se2) {
    assert_eq!((a.x(), a.y()), (b.x(), b.y()));
    assert!((a.theta() - b.theta()).abs() < 1e-15, "{a:?} vs {b:?}");
}

fn posegraph_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../datasets/posegraph")
}

/// (file, vertices, edges) as counted with `grep -c` on the files.
const FILES: [(&str, usize, usize); 8] = [
    ("M3500.g2o", 3500, 5453),
    ("manhattan.g2o", 3500, 5453),
    ("vertigo-manhattan/manhattanOlson3500.g2o", 3500, 5598),
    ("intel.g2o", 1728, 2512),
    ("CSAIL.g2o", 1045, 1172),
    ("MIT.g2o", 808, 827),
    ("city10000.g2o", 10000, 20687),
    ("vertigo-ring/ring.g2o", 434, 459),
];

#[test]
fn benchmark_files_load_with_expected_sizes() {
    for (file, nodes, edges) in FILES {
        let graph = read_pose_graph(&posegraph_dir().join(file)).unwrap();
        assert_eq!(graph.node_count(), nodes, "{file}");
        assert_eq!(graph.edge_count(), edges, "{file}");
        assert!(graph.is_connected(), "{file}");
    }
}

#[test]
fn g2o_write_read_is_exact() {
    let graph = read_pose_graph(&posegraph_dir().join("intel.g2o")).unwrap();
    let mut buf = Vec::new();
    write_g2o(&graph, &mut buf).unwrap();
    let back = parse_pose_graph(std::str::from_utf8(&buf).unwrap(), Path::new("mem.g2o")).unwrap();
    for (a, b) in graph.poses().iter().zip(back.poses()) {
        assert_close(a, &b);
    }
    assert_eq!(graph.edge_count(), back.edge_count());
    for (a, b) in graph.edges().zip(back.edges()) {
        assert_eq!((a.from, a.to, a.kind), (b.from, b.to, b.kind));
        assert_eq!(a.information, b.information);
        assert_close(&a.measurement, &b.measurement);
    }
}

#[test]
fn toro_write_read_keeps_information_order() {
    let graph = read_pose_graph(&posegraph_dir().join("MIT.g2o")).unwrap();
    let mut buf = Vec::new();
    toro::write_toro(&graph, &mut buf).unwrap();
    let text = std::str::from_utf8(&buf).unwrap();
    assert_eq!(detect_format(text), Some(GraphFormat::Toro));
    let back = parse_pose_graph(text, Path::new("mem.graph")).unwrap();
    for (a, b) in graph.edges().zip(back.edges()) {
        assert_eq!(a.information, b.information);
        assert_close(&a.measurement, &b.measurement);
    }
}

#[test]
fn toro_information_order_is_xx_xy_yy_tt_xt_yt() {
    let text = "VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0\nEDGE2 0 1 1 0 0 10 1 20 30 2 3\n";
    let graph = parse_pose_graph(text, Path::new("t.graph")).unwrap();
    let info = graph.edges().next().unwrap().information;
    let expected = nalgebra::Matrix3::new(10.0, 1.0, 2.0, 1.0, 20.0, 3.0, 2.0, 3.0, 30.0);
    assert_eq!(info, expected);
}

#[test]
fn files_without_vertices_start_from_the_odometry_chain() {
    // A square driven with odometry, plus a loop edge with a wrong
    // measurement: the start must follow the chain, not the loop.
    let text = "\
EDGE_SE2 0 1 1 0 1.5707963267948966 1 0 0 1 0 1
EDGE_SE2 1 2 1 0 1.5707963267948966 1 0 0 1 0 1
EDGE_SE2 0 3 5 5 0 1 0 0 1 0 1
EDGE_SE2 2 3 1 0 1.5707963267948966 1 0 0 1 0 1
";
    let graph = parse_pose_graph(text, Path::new("square.g2o")).unwrap();
    let p3 = graph.node(3).unwrap().pose;
    assert!(
        (p3.x() - 0.0).abs() < 1e-12 && (p3.y() - 1.0).abs() < 1e-12,
        "{p3:?}"
    );
    assert_eq!(graph.index_of(0), Some(0));
    assert_eq!(graph.index_of(3), Some(3));
}

/// GTSAM's `readG2o` stops at the first record it does not know, so the
/// writer puts every `EDGE_SE2` before the priors (g2o's own tag,
/// `EDGE_PRIOR_SE2`) and `FIX` last; reading the file back gives the same
/// edges, whichever tag a prior carries.
#[test]
fn g2o_writes_relative_edges_first_then_priors_then_fix() {
    use echofield_graph::{Edge, EdgeKind, Node, PoseGraph, Se2};
    use nalgebra::Matrix3;
    let mut graph = PoseGraph::new();
    for id in 0..3u64 {
        let pose = Se2::new(id as f64, 0.5 * id as f64, 0.1 * id as f64);
        graph
            .add_node(Node {
                id,
                pose,
                stamp_s: None,
            })
            .unwrap();
    }
    let info = Matrix3::from_diagonal(&nalgebra::Vector3::new(4.0, 5.0, 6.0));
    let step = Se2::new(1.0, 0.5, 0.1);
    let heading = Matrix3::from_diagonal(&nalgebra::Vector3::new(1e-12, 1e-12, 40.0));
    // Priors interleaved with the relative edges, as the pipeline adds them.
    graph
        .add_edge(Edge::new(EdgeKind::Odometry, 0, 1, step, info))
        .unwrap();
    graph
        .add_edge(Edge::new(
            EdgeKind::Prior,
            1,
            1,
            Se2::new(1.0, 0.5, 0.0),
            heading,
        ))
        .unwrap();
    graph
        .add_edge(Edge::new(EdgeKind::Odometry, 1, 2, step, info))
        .unwrap();
    graph
        .add_edge(Edge::new(
            EdgeKind::Prior,
            2,
            2,
            Se2::new(2.0, 1.0, 0.2),
            heading,
        ))
        .unwrap();
    graph
        .add_edge(Edge::new(
            EdgeKind::Loop,
            0,
            2,
            Se2::new(2.0, 1.0, 0.2),
            info,
        ))
        .unwrap();
    graph.fix(0).unwrap();

    let mut buf = Vec::new();
    write_g2o(&graph, &mut buf).unwrap();
    let text = String::from_utf8(buf).unwrap();
    let tags: Vec<&str> = text.lines().map(|l| l.split(' ').next().unwrap()).collect();
    assert_eq!(
        tags,
        [
            "VERTEX_SE2",
            "VERTEX_SE2",
            "VERTEX_SE2",
            "EDGE_SE2",
            "EDGE_SE2",
            "EDGE_SE2",
            "EDGE_PRIOR_SE2",
            "EDGE_PRIOR_SE2",
            "FIX"
        ]
    );
    assert!(text.contains("\nEDGE_PRIOR_SE2 1 1 0.5 0 0.000000000001 0 0 0.000000000001 0 40\n"));
    assert!(text.ends_with("FIX 0\n"));

    let legacy = text.replace("EDGE_PRIOR_SE2", "EDGE_SE2_PRIOR");
    for source in [text, legacy] {
        let back = parse_pose_graph(&source, Path::new("mem.g2o")).unwrap();
        assert_eq!(back.fixed().iter().copied().collect::<Vec<_>>(), [0]);
        let key = |e: &Edge| (e.from, e.to, e.kind);
        let mut a: Vec<_> = graph.edges().map(key).collect();
        let mut b: Vec<_> = back.edges().map(key).collect();
        a.sort();
        b.sort();
        assert_eq!(a, b);
    }
}
