//! Time of writing a run's output folder for a St Pere-length mission (the
//! St Pere replay: about 231 rotations, 46k beams), the whole and its two
//! heavy parts (the mosaic grid and `mission.mcap`).
//!
//! `cargo bench -p echofield --bench outputs` (release). The setup simulates
//! the replay and runs the pipeline once (several seconds).

use criterion::{Criterion, criterion_group, criterion_main};
use echofield::slam::SlamConfig;
use echofield::slam::outputs::demo::simulated_run;
use echofield::slam::outputs::foxglove::write_results_mcap;
use echofield::slam::outputs::loops_csv::LoopRow;
use echofield::slam::outputs::{mosaic_grid, world_from_ground_truth, write_outputs};
use std::time::Duration;

fn outputs(c: &mut Criterion) {
    let (mission, output) = simulated_run("stpere", 1, &SlamConfig::default())
        .expect("the St Pere replay (datasets/stpere-marina) runs");
    eprintln!(
        "St Pere replay: {} beams, {} nodes, {} loop candidates",
        mission.beams.len(),
        output.nodes.len(),
        output.loops.len()
    );
    let dir = tempfile::tempdir().unwrap();
    let mut group = c.benchmark_group("outputs_stpere");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(20));
    group.bench_function("write_outputs", |b| {
        let out = dir.path().join("out");
        b.iter(|| write_outputs(&out, &output, &mission).unwrap())
    });
    group.bench_function("mosaic_grid", |b| b.iter(|| mosaic_grid(&output).unwrap()));
    let loops: Vec<LoopRow> = output.loops.iter().map(LoopRow::from_record).collect();
    let world_from_gt = world_from_ground_truth(&output);
    let path = dir.path().join("results.mcap");
    let mosaic = mosaic_grid(&output).unwrap();
    group.bench_function("mission_mcap", |b| {
        b.iter(|| {
            let m = &mission.mounting;
            write_results_mcap(&path, &output, m, &loops, world_from_gt, Some(&mosaic)).unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, outputs);
criterion_main!(benches);
