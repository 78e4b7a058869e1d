//! Single-threaded solve times on the standard 2D benchmarks, read with the
//! graph crate's reader from `datasets/posegraph`.
//!
//! `cargo bench -p echofield-backend --bench posegraph`
//!
//! - `solve/<file>`: a fresh `optimize` with the default configuration
//!   (chordal initialisation, ordering, symbolic analysis, LM iterations);
//! - `resolve/<file>`: the same through a `Solver` that already analysed
//!   the pattern (what a mission re-optimising an unchanged pattern pays).

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use echofield_backend::{Solver, SolverConfig, optimize};
use echofield_graph::PoseGraph;
use echofield_graph::io::read_pose_graph;
use std::hint::black_box;
use std::path::PathBuf;

const FILES: [&str; 4] = ["M3500.g2o", "intel.g2o", "MIT.g2o", "city10000.g2o"];

fn load(file: &str) -> PoseGraph {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../datasets/posegraph")
        .join(file);
    read_pose_graph(&path).unwrap_or_else(|e| panic!("{e}"))
}

fn bench(c: &mut Criterion) {
    let config = SolverConfig {
        threads: 1,
        ..SolverConfig::default()
    };
    let mut group = c.benchmark_group("solve");
    group.sample_size(20);
    for file in FILES {
        let graph = load(file);
        group.bench_function(file, |b| {
            b.iter_batched(
                || graph.clone(),
                |mut g| black_box(optimize(&mut g, &config).expect("solves")),
                BatchSize::LargeInput,
            )
        });
    }
    group.finish();

    let mut group = c.benchmark_group("resolve");
    group.sample_size(20);
    for file in FILES {
        let graph = load(file);
        let mut solver = Solver::new(config.clone()).expect("valid config");
        solver.optimize(&mut graph.clone()).expect("solves");
        group.bench_function(file, |b| {
            b.iter_batched(
                || graph.clone(),
                |mut g| black_box(solver.optimize(&mut g).expect("solves")),
                BatchSize::LargeInput,
            )
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
