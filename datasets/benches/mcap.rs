//! MCAP mission I/O speed on a St Pere-sized mission: 46 000 beams of 500
//! bins (plus DVL at 5 Hz, attitude at 10 Hz, ground truth at 1 Hz over the
//! same 52 min). Target: reading well under a second or two in release.
//!
//! `cargo bench -p echofield-datasets --bench mcap`
//!
//! - `read_mission/json_46k_x_500`: echofield's JSON format;
//! - `read_mission/ros2_46k_x_500`: the same mission as ROS 2 CDR messages;
//! - `write_mission/json_46k_x_500`: writing it (atomic, zstd).

use criterion::{Criterion, criterion_group, criterion_main};
use echofield_datasets::mcap::fixture::random_mission;
use echofield_datasets::mcap::{Ros2GroundTruth, read_mission, write_mission, write_mission_ros2};
use std::hint::black_box;
use std::time::Duration;

const BEAMS: usize = 46_000;
const BINS: usize = 500;

fn bench_mcap(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("temporary folder");
    let mission = random_mission(BEAMS, BINS, 1);
    let json_path = dir.path().join("mission.mcap");
    let ros2_path = dir.path().join("mission_ros2.mcap");
    write_mission(&json_path, &mission).expect("write");
    write_mission_ros2(&ros2_path, &mission, Ros2GroundTruth::Odometry).expect("write ROS 2");
    for path in [&json_path, &ros2_path] {
        let size = std::fs::metadata(path).expect("size").len();
        eprintln!("{}: {:.1} MB", path.display(), size as f64 / 1e6);
    }

    let mut group = c.benchmark_group("read_mission");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(20));
    group.bench_function("json_46k_x_500", |b| {
        b.iter(|| read_mission(black_box(&json_path)).expect("read"))
    });
    group.bench_function("ros2_46k_x_500", |b| {
        b.iter(|| read_mission(black_box(&ros2_path)).expect("read"))
    });
    group.finish();

    let mut group = c.benchmark_group("write_mission");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(20));
    let out = dir.path().join("written.mcap");
    group.bench_function("json_46k_x_500", |b| {
        b.iter(|| write_mission(black_box(&out), black_box(&mission)).expect("write"))
    });
    group.finish();
}

criterion_group!(benches, bench_mcap);
criterion_main!(benches);
