//! Reading the committed real logs: the St Pere marina folder (33k MTi lines,
//! 46k beam stamps), the richest Ping360 log and the full MiniKing bag.
//!
//! `cargo bench -p echofield-datasets --bench readers`

use criterion::{Criterion, criterion_group, criterion_main};
use echofield_datasets::miniking::read_miniking_bag;
use echofield_datasets::ping360::read_ping360;
use echofield_datasets::stpere::{best_yaw_offset, read_stpere_dir};
use std::hint::black_box;
use std::path::PathBuf;

fn data(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn readers(c: &mut Criterion) {
    let marina = data("stpere-marina");
    c.bench_function("read_stpere_dir marina", |b| {
        b.iter(|| read_stpere_dir(black_box(&marina)).unwrap())
    });
    let logs = read_stpere_dir(&marina).unwrap();
    c.bench_function("best_yaw_offset marina", |b| {
        b.iter(|| best_yaw_offset(black_box(&logs.mission)).unwrap())
    });
    let ping = data("msis-real/ping360/Sensor_Log_01__inside_base.bin");
    c.bench_function("read_ping360 inside_base", |b| {
        b.iter(|| read_ping360(black_box(&ping)).unwrap())
    });
    let bag = data("msis-real/miniking/full_sonar_scan_2015-05-26-11-38-04.bag");
    c.bench_function("read_miniking_bag full scan", |b| {
        b.iter(|| read_miniking_bag(black_box(&bag)).unwrap())
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = readers
}
criterion_main!(benches);
