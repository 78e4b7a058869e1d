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
