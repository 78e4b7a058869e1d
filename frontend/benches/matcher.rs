//! Speed of the acoustic-image measurement model on the paper's sonar
//! (200 beams x 500 bins of 0.1 m per rotation, a 30 m x 20 m basin):
//! building `I_k` for one rotation, and one match of a scan against the
//! image of another rotation, for a sequential-size window and for the
//! evaluation's widest one, and over a loop's smallest window by search and
//! by local climb. Targets (release, one core): `I_k` ≤ 5 ms, one
//! match ≤ 5 ms.
//!
//! `cargo bench -p echofield-frontend --bench matcher`

use criterion::{Criterion, criterion_group, criterion_main};
use echofield_frontend::image::synthetic::{
    RotationPath, SceneConfig, simulate_rotation, static_rotation,
};
use echofield_frontend::image::{AcousticImage, ImageConfig, Interpolation, PoseFitRaster};
use echofield_frontend::matcher::{MatcherConfig, SearchWindow, match_scan, match_scan_local};
use echofield_graph::Se2;
use std::hint::black_box;

fn build_image(c: &mut Criterion) {
    let rotation = simulate_rotation(
        &SceneConfig::default(),
        &RotationPath {
            world_from_start: Se2::identity(),
            velocity_mps: (0.4, 0.0),
            yaw_rate_radps: 0.01,
        },
        1,
    );
    let mut group = c.benchmark_group("build_image_200x500");
    let without_pose_fit = PoseFitRaster {
        enabled: false,
        ..PoseFitRaster::default()
    };
    for (name, interpolation, pose_fit) in [
        (
            "angular_window",
            Interpolation::AngularWindow,
            PoseFitRaster::default(),
        ),
        (
            "angular_window_without_pose_fit_raster",
            Interpolation::AngularWindow,
            without_pose_fit.clone(),
        ),
        ("nearest", Interpolation::Nearest, PoseFitRaster::default()),
        (
            "nearest_without_pose_fit_raster",
            Interpolation::Nearest,
            without_pose_fit.clone(),
        ),
    ] {
        let config = ImageConfig {
            interpolation,
            pose_fit,
            ..ImageConfig::default()
        };
        group.bench_function(name, |b| {
            b.iter(|| {
                AcousticImage::build(
                    black_box(&rotation.beams),
                    black_box(&rotation.reference_from_beams),
                    &config,
                )
                .unwrap()
            })
        });
    }
    group.finish();
}

fn match_one(c: &mut Criterion) {
    let scene = SceneConfig::default();
    let a = static_rotation(&scene, 1);
    let image =
        AcousticImage::build(&a.beams, &a.reference_from_beams, &ImageConfig::default()).unwrap();
    let world_from_b = Se2::new(1.2, -0.7, 0.15);
    let b = simulate_rotation(&scene, &RotationPath::fixed(world_from_b), 2);
    let truth = a.world_from_reference.between(&b.world_from_reference);
    let prior = truth.compose(&Se2::new(0.3, -0.2, 0.03));
    let config = MatcherConfig::default();
    let mut group = c.benchmark_group("match_scan");
    for (name, window) in [
        (
            "window_1m_10deg",
            SearchWindow::new(1.0, 1.0, 10.0_f64.to_radians()),
        ),
        (
            "window_5m_20deg",
            SearchWindow::new(5.0, 5.0, 20.0_f64.to_radians()),
        ),
    ] {
        group.bench_function(name, |bench| {
            bench.iter(|| {
                match_scan(black_box(&b.wall_points), &image, &prior, &window, &config).unwrap()
            })
        });
    }
    // The SLAM pipeline's setting over a loop candidate's smallest window.
    let small = SearchWindow::new(0.5, 0.5, 3.0_f64.to_radians());
    group.bench_function("pipeline_window_0.5m_3deg", |bench| {
        bench.iter(|| {
            match_scan(black_box(&b.wall_points), &image, &prior, &small, &config).unwrap()
        })
    });
    // The same with the local climb of loop densification.
    group.bench_function("pipeline_local_0.5m_3deg", |bench| {
        bench.iter(|| {
            match_scan_local(black_box(&b.wall_points), &image, &prior, &small, &config).unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, build_image, match_one);
criterion_main!(benches);
