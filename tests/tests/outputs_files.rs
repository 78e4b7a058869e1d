//! The output folder of a run: every file is written and parses back to
//! what the run produced (on a short simulated tank mission).

use base64::Engine as _;
use echofield::eval::{Alignment, ate};
use echofield::slam::outputs::loops_csv::{COLUMNS, read_loops_csv};
use echofield::slam::outputs::precision_recall::evaluate_loops_dir;
use echofield::slam::outputs::{PLOT_SIZE_PX, demo::simulated_run, write_outputs};
use echofield::slam::{SlamConfig, SlamOutput};
use echofield_datasets::mcap::read_mission;
use echofield_frontend::sensors::Mission;
use echofield_graph::io::{read_pose_graph, read_tum};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::OnceLock;

/// The tank mission has 10 rotations: allow loops between nodes 4 apart
/// so that it has some.
fn tank_config() -> SlamConfig {
    SlamConfig::from_toml_str("[loops]\nmin_separation_nodes = 4\n").unwrap()
}

/// One run shared by the tests of this file, with its output folder.
struct Fixture {
    _dir: tempfile::TempDir,
    path: std::path::PathBuf,
    mission: Mission,
    output: SlamOutput,
}

fn fixture() -> &'static Fixture {
    static FIXTURE: OnceLock<Fixture> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let (mission, output) = simulated_run("tank", 1, &tank_config()).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out");
        write_outputs(&path, &output, &mission).unwrap();
        Fixture {
            _dir: dir,
            path,
            mission,
            output,
        }
    })
}

#[test]
fn tum_files_hold_the_node_poses_at_the_node_stamps() {
    let f = fixture();
    let nodes = &f.output.nodes;
    assert!(nodes.len() >= 5, "{} nodes", nodes.len());
    let optimised = read_tum(&f.path.join("trajectory_tum.txt")).unwrap();
    let dead_reckoning = read_tum(&f.path.join("dead_reckoning_tum.txt")).unwrap();
    let truth = read_tum(&f.path.join("ground_truth_tum.txt")).unwrap();
    assert_eq!(optimised.len(), nodes.len());
    assert_eq!(dead_reckoning.len(), nodes.len());
    assert_eq!(truth.len(), f.output.ground_truth.as_ref().unwrap().len());
    for ((node, o), d) in nodes.iter().zip(&optimised).zip(&dead_reckoning) {
        // Stamps are written with microseconds.
        assert!((o.stamp_s - node.stamp_s).abs() < 1e-6);
        assert_eq!(o.stamp_s, d.stamp_s);
        assert!((o.pose.translation() - node.optimised.translation()).norm() < 1e-9);
        assert!((o.pose.theta() - node.optimised.theta()).abs() < 1e-9);
        assert!((d.pose.translation() - node.dead_reckoning.translation()).norm() < 1e-9);
    }
    // The files reproduce the report's ATE (same association and alignment).
    let report = &f.output.report;
    let from_files = ate(&optimised, &truth, Alignment::Se2, 0.01).unwrap();
    let expected = report.ate_rmse_m.unwrap();
    assert!((from_files.rmse_m - expected).abs() <= 1e-9 * expected.max(1e-3));
    let dr = ate(&dead_reckoning, &truth, Alignment::Se2, 0.01).unwrap();
    let expected = report.ate_rmse_dead_reckoning_m.unwrap();
    assert!((dr.rmse_m - expected).abs() <= 1e-9 * expected.max(1e-3));
}

/// The navigation-rate trajectory passes through every node pose, moves
/// no faster than the vehicle between samples, agrees between its TUM and
/// KITTI forms, and its ATE in the report agrees with one computed here
/// from the file and the mission's ground truth (nearest-stamp
/// association instead of the report's interpolation).
#[test]
fn navigation_rate_trajectory_is_dense_and_passes_through_the_nodes() {
    let f = fixture();
    let dense = read_tum(&f.path.join("trajectory_nav_tum.txt")).unwrap();
    let kitti = std::fs::read_to_string(f.path.join("trajectory_nav_kitti.txt")).unwrap();
    let times = std::fs::read_to_string(f.path.join("trajectory_nav_times.txt")).unwrap();
    assert_eq!(kitti.lines().count(), dense.len());
    assert_eq!(times.lines().count(), dense.len());
    for ((p, row), t) in dense.iter().zip(kitti.lines()).zip(times.lines()) {
        let m: Vec<f64> = row.split(' ').map(|v| v.parse().unwrap()).collect();
        assert_eq!(m.len(), 12);
        assert!((m[3] - p.pose.x()).abs() < 1e-9 && (m[7] - p.pose.y()).abs() < 1e-9);
        assert!((m[4].atan2(m[0]) - p.pose.theta()).abs() < 1e-9);
        assert!((t.parse::<f64>().unwrap() - p.stamp_s).abs() < 1e-6);
    }
    // At the navigation's rate: far more samples than nodes.
    assert!(dense.len() > 20 * f.output.nodes.len(), "{}", dense.len());
    for node in &f.output.nodes {
        let sample = dense
            .iter()
            .find(|p| (p.stamp_s - node.stamp_s).abs() < 1e-6)
            .expect("every node stamp is a sample");
        assert!((sample.pose.translation() - node.optimised.translation()).norm() < 1e-9);
    }
    // No jump: the tank vehicle moves well under 2 m/s.
    for w in dense.windows(2) {
        let dt = w[1].stamp_s - w[0].stamp_s;
        let step = (w[1].pose.translation() - w[0].pose.translation()).norm();
        assert!(
            dt > 0.0 && step <= 2.0 * dt + 1e-3,
            "{step} m in {dt} s at {}",
            w[1].stamp_s
        );
    }
    let (first, last) = (
        f.output.nodes[0].stamp_s,
        f.output.nodes.last().unwrap().stamp_s,
    );
    let truth: Vec<echofield_graph::io::TrajectoryPose> = f
        .mission
        .ground_truth
        .iter()
        .filter(|g| g.stamp_s >= first && g.stamp_s <= last)
        .map(|g| echofield_graph::io::TrajectoryPose {
            stamp_s: g.stamp_s,
            pose: g.world_from_vehicle,
        })
        .collect();
    let here = ate(&dense, &truth, Alignment::Se2, 0.06).unwrap().rmse_m;
    let report = f.output.report.ate_navigation_rate.as_ref().unwrap();
    assert!(
        report.pairs >= truth.len() - 2,
        "{} of {}",
        report.pairs,
        truth.len()
    );
    assert!(
        (report.rmse_m - here).abs() <= 0.1 * here + 0.01,
        "{} vs {here}",
        report.rmse_m
    );
}

#[test]
fn poses_csv_and_graph_g2o_hold_the_optimised_graph() {
    let f = fixture();
    let csv = std::fs::read_to_string(f.path.join("poses.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("stamp_s,x_m,y_m,theta_rad"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), f.output.nodes.len());
    for (row, node) in rows.iter().zip(&f.output.nodes) {
        assert_eq!(row[1], node.optimised.x());
        assert_eq!(row[2], node.optimised.y());
    }
    let graph = read_pose_graph(&f.path.join("graph.g2o")).unwrap();
    assert_eq!(graph.node_count(), f.output.graph.node_count());
    assert_eq!(graph.edge_count(), f.output.graph.edge_count());
    for (a, b) in graph.poses().iter().zip(f.output.graph.poses()) {
        assert!((a.to_vector() - b.to_vector()).norm() < 1e-12);
    }
    assert_eq!(graph.fixed(), f.output.graph.fixed());
}

#[test]
fn report_json_has_the_issue_keys_and_writing_time() {
    let f = fixture();
    let text = std::fs::read_to_string(f.path.join("report.json")).unwrap();
    let v: Value = serde_json::from_str(&text).unwrap();
    for key in [
        "rotations",
        "nodes",
        "loop_candidates",
        "loops_accepted",
        "time_s",
        "solver",
        "ate_rmse_m",
        "ate_rmse_dead_reckoning_m",
        "distance_travelled_m",
        "rpe",
        "loop_precision",
        "loop_recall",
        "loop_recall_revisits",
    ] {
        assert!(v.get(key).is_some(), "report.json lacks `{key}`");
    }
    assert_eq!(v["nodes"], f.output.nodes.len());
    assert!(v["solver"]["summary"]["final_chi2"].is_number());
    let writing = v["timings"]["writing_s"].as_f64().unwrap();
    assert!(writing > 0.0 && writing < 60.0, "{writing}");
}

#[test]
fn config_toml_is_the_effective_config() {
    let f = fixture();
    let text = std::fs::read_to_string(f.path.join("config.toml")).unwrap();
    assert_eq!(SlamConfig::from_toml_str(&text).unwrap(), f.output.config);
}

#[test]
fn loops_csv_lists_every_candidate_under_the_documented_header() {
    let f = fixture();
    let text = std::fs::read_to_string(f.path.join("loops.csv")).unwrap();
    assert_eq!(text.lines().next().unwrap(), COLUMNS.join(","));
    let rows = read_loops_csv(&f.path.join("loops.csv")).unwrap();
    assert_eq!(rows.len(), f.output.loops.len());
    for (row, record) in rows.iter().zip(&f.output.loops) {
        assert_eq!((row.from, row.to), (record.from, record.to));
        assert_eq!(row.accepted, record.accepted);
        assert_eq!(row.gt_correct, record.true_positive);
        assert_eq!(
            row.mean_intensity,
            record.quality.as_ref().map(|q| q.mean_intensity)
        );
    }
    // The accepted rows are the loop edges of the graph.
    let accepted = rows.iter().filter(|r| r.accepted).count();
    assert!(accepted > 0, "the fixture should close some loops");
    let loop_edges = f
        .output
        .graph
        .edges()
        .filter(|e| e.kind == echofield_graph::EdgeKind::Loop)
        .count();
    assert_eq!(accepted, loop_edges);
    // eval-loops runs on it (the mission has ground truth).
    let pr = evaluate_loops_dir(&f.path, Some(&f.path.join("pr"))).unwrap();
    let judged = rows.iter().filter(|r| r.gt_correct.is_some()).count();
    assert_eq!(pr.sweeps[0].candidates, judged);
}

fn png_size(path: &Path) -> (u32, u32) {
    let picture = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    (picture.width(), picture.height())
}

#[test]
fn pngs_decode_with_their_sizes() {
    let f = fixture();
    assert_eq!(png_size(&f.path.join("trajectory.png")), PLOT_SIZE_PX);
    assert_eq!(png_size(&f.path.join("loops.png")), PLOT_SIZE_PX);
    let (w, h) = png_size(&f.path.join("mosaic.png"));
    // The tank is 20 m x 14 m: cropped to its echoes (+5 m each side) at
    // 0.2 m per pixel the mosaic is a few hundred pixels wide.
    assert!(
        (100..=600).contains(&w) && (100..=600).contains(&h),
        "{w}x{h}"
    );
    let world: Vec<f64> = std::fs::read_to_string(f.path.join("mosaic.pgw"))
        .unwrap()
        .lines()
        .map(|l| l.parse().unwrap())
        .collect();
    assert_eq!(world.len(), 6);
    assert_eq!((world[0], world[3]), (0.2, -0.2));
    // The vehicle's first position lies inside the mosaic.
    let start = f.output.nodes[0].optimised;
    let px = (start.x() - world[4]) / world[0];
    let py = (start.y() - world[5]) / world[3];
    assert!(px > 0.0 && px < f64::from(w) && py > 0.0 && py < f64::from(h));
}

#[test]
fn mission_mcap_holds_poses_scans_and_images_for_foxglove() {
    let f = fixture();
    let path = f.path.join("mission.mcap");
    // The datasets reader opens it (and skips the Foxglove channels).
    let results = read_mission(&path).unwrap();
    assert!(results.beams.is_empty());
    let bytes = std::fs::read(&path).unwrap();
    let mut topics: BTreeMap<String, (String, usize)> = BTreeMap::new();
    let mut first: BTreeMap<String, Value> = BTreeMap::new();
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        let schema = message.channel.schema.as_ref().unwrap().name.clone();
        let topic = message.channel.topic.clone();
        let entry = topics.entry(topic.clone()).or_insert((schema, 0));
        entry.1 += 1;
        first
            .entry(topic)
            .or_insert_with(|| serde_json::from_slice(&message.data).unwrap());
    }
    let first_image = first.get("/slam/acoustic_image").cloned();
    let nodes = f.output.nodes.len();
    let expect = |topic: &str, schema: &str, count: usize| {
        let (s, n) = topics.get(topic).unwrap_or_else(|| panic!("no {topic}"));
        assert_eq!((s.as_str(), *n), (schema, count), "{topic}");
    };
    // vehicle -> sonar once, then world -> vehicle per node.
    expect("/tf", "foxglove.FrameTransform", nodes + 1);
    let tf = &first["/tf"];
    assert_eq!(
        (
            tf["parent_frame_id"].as_str(),
            tf["child_frame_id"].as_str()
        ),
        (Some("vehicle"), Some("sonar"))
    );
    let sonar = f.mission.mounting.vehicle_from_sonar;
    assert_eq!(tf["translation"]["x"].as_f64(), Some(sonar.x()));
    assert_eq!(tf["translation"]["y"].as_f64(), Some(sonar.y()));
    // Loops are lines: two points per loop whose nodes exist; false loops
    // (red) are drawn last, on top.
    expect("/slam/loops/accepted", "foxglove.SceneUpdate", 1);
    expect("/slam/loops/rejected", "foxglove.SceneUpdate", 1);
    let accepted: Vec<_> = f.output.loops.iter().filter(|l| l.accepted).collect();
    let line = &first["/slam/loops/accepted"]["entities"][0]["lines"][0];
    assert_eq!(line["type"], 2, "LINE_LIST");
    let points = line["points"].as_array().unwrap();
    assert_eq!(points.len(), 2 * accepted.len());
    let red: Vec<bool> = line["colors"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["r"].as_f64().unwrap() > 0.8 && c["g"].as_f64().unwrap() < 0.2)
        .collect();
    let false_loops = accepted
        .iter()
        .filter(|l| l.true_positive == Some(false))
        .count();
    assert_eq!(red.iter().filter(|&&r| r).count(), 2 * false_loops);
    assert!(red.windows(2).all(|w| w[0] <= w[1]), "false loops last");
    // The mosaic as a grid of the same size as mosaic.png.
    expect("/slam/mosaic", "foxglove.Grid", 1);
    let mosaic = &first["/slam/mosaic"];
    let png = image::open(f.path.join("mosaic.png")).unwrap();
    assert_eq!(
        mosaic["column_count"].as_u64(),
        Some(u64::from(png.width()))
    );
    let cells = base64::engine::general_purpose::STANDARD
        .decode(mosaic["data"].as_str().unwrap())
        .unwrap();
    assert_eq!(
        cells.len() as u64,
        u64::from(png.width()) * u64::from(png.height())
    );
    assert_eq!(mosaic["cell_size"]["x"].as_f64(), Some(0.2));
    assert!(cells.iter().any(|&c| c > 128), "the mosaic has echoes");
    // Its corner is half a cell left of the world file's first pixel centre.
    let pgw = std::fs::read_to_string(f.path.join("mosaic.pgw")).unwrap();
    let centre_x: f64 = pgw.lines().nth(4).unwrap().parse().unwrap();
    let corner_x = mosaic["pose"]["position"]["x"].as_f64().unwrap();
    assert!(
        (corner_x - (centre_x - 0.1)).abs() < 1e-3,
        "{corner_x} vs {centre_x}"
    );
    expect("/slam/pose", "foxglove.PoseInFrame", nodes);
    expect("/slam/trajectory", "foxglove.PosesInFrame", 1);
    expect("/dead_reckoning/trajectory", "foxglove.PosesInFrame", 1);
    expect("/ground_truth/trajectory", "foxglove.PosesInFrame", 1);
    let scans = f.output.scans.iter().filter(|s| !s.is_empty()).count();
    expect("/slam/scan", "foxglove.PointCloud", scans);
    let images = f.output.images.iter().filter(|i| !i.is_empty()).count();
    expect("/slam/acoustic_image", "foxglove.CompressedImage", images);
    // The first image is a PNG of I_k.
    let image = first_image.unwrap();
    assert_eq!(image["format"], "png");
    let png = base64::engine::general_purpose::STANDARD
        .decode(image["data"].as_str().unwrap())
        .unwrap();
    let decoded = image::load_from_memory(&png).unwrap();
    let k = f.output.images.iter().position(|i| !i.is_empty()).unwrap();
    let image = f.output.images[k].image_once().unwrap();
    let grid = image.grid();
    // One pixel per 2 x 2 cells.
    assert_eq!(
        (decoded.width() as usize, decoded.height() as usize),
        (grid.width().div_ceil(2), grid.height().div_ceil(2))
    );
    // The run's input mission is untouched by the outputs.
    assert!(!f.mission.beams.is_empty());
}

#[test]
fn a_run_without_ground_truth_or_loops_still_writes_everything_else() {
    let f = fixture();
    let mut output = f.output.clone();
    output.ground_truth = None;
    for node in &mut output.nodes {
        node.ground_truth = None;
    }
    output.loops.clear();
    let dir = tempfile::tempdir().unwrap();
    write_outputs(dir.path(), &output, &f.mission).unwrap();
    assert!(!dir.path().join("ground_truth_tum.txt").exists());
    let csv = std::fs::read_to_string(dir.path().join("loops.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1, "header only");
    assert_eq!(png_size(&dir.path().join("trajectory.png")), PLOT_SIZE_PX);
    assert_eq!(png_size(&dir.path().join("loops.png")), PLOT_SIZE_PX);
    let bytes = std::fs::read(dir.path().join("mission.mcap")).unwrap();
    let topics: Vec<String> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| m.unwrap().channel.topic.clone())
        .collect();
    assert!(!topics.iter().any(|t| t == "/ground_truth/trajectory"));
    assert!(topics.iter().any(|t| t == "/slam/trajectory"));
    // eval-loops needs ground-truth verdicts.
    assert!(evaluate_loops_dir(dir.path(), None).is_err());
}
