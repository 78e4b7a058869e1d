//! Simulation speed. The target (issue 3): the St Pere-length mission, about
//! 46k beams x 500 bins, in at most 10 s in release.
//!
//! `cargo bench -p echofield-datasets --bench sim`
//!
//! - `stpere_replay`: every beam of the real St Pere log simulated against
//!   the drawn marina (the logs are read and the map is drawn once, outside
//!   the timing);
//! - `marina`: the built-in 40 min demo mission, sensors and beams;
//! - `beam`: one beam in the marina.

use criterion::{Criterion, criterion_group, criterion_main};
use echofield_datasets::sim::{Scenario, SonarModel, simulate_mission, stream_rng};
use std::hint::black_box;
use std::time::Duration;

fn bench_missions(c: &mut Criterion) {
    let mut group = c.benchmark_group("simulate_mission");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(40));
    match Scenario::named("stpere") {
        Ok(stpere) => {
            let beams = simulate_mission(&stpere, 0)
                .map(|m| m.beams.len())
                .unwrap_or(0);
            eprintln!("stpere_replay: {beams} beams");
            group.bench_function("stpere_replay", |b| {
                b.iter(|| simulate_mission(black_box(&stpere), 1).expect("simulation"))
            });
        }
        Err(e) => eprintln!("skipping stpere_replay: {e}"),
    }
    let marina = Scenario::named("marina").expect("marina scenario");
    group.bench_function("marina", |b| {
        b.iter(|| simulate_mission(black_box(&marina), 1).expect("simulation"))
    });
    group.finish();
}

fn bench_beam(c: &mut Criterion) {
    let marina = Scenario::named("marina").expect("marina scenario");
    let model = SonarModel::new(&marina.config().sonar).expect("sonar model");
    let truth = marina.ground_truth();
    let stamp = truth.start_s() + 300.0;
    let world_from_sonar = truth
        .pose_at(stamp)
        .compose(&marina.config().mounting.vehicle_from_sonar);
    let mut k = 0u64;
    c.bench_function("render_beam/marina", |b| {
        b.iter(|| {
            k += 1;
            let mut rng = stream_rng(1, 1, k);
            let angle = (k % 200) as f64 * 0.0314;
            model.render_beam(
                marina.environment(),
                &[],
                &world_from_sonar,
                angle,
                stamp,
                &mut rng,
            )
        })
    });
}

criterion_group!(benches, bench_missions, bench_beam);
criterion_main!(benches);
