//! The fuzz targets: one per input parser, each with its seeds (small
//! pieces of the committed fixtures under `datasets/` and `tools/configs`)
//! and its grammar-based generator.
//!
//! The seeds are cut down from the fixtures (a few hundred lines, the
//! first kilobytes of a binary log, three keyframes) so that one input
//! parses in milliseconds; mutations still reach every record type.

use super::Input;
use super::generate;
use anyhow::{Context, Result};
use echofield_frontend::sensors::SweepTiming;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

/// Parses the files of one input, written into a folder.
pub type ParseFn = Arc<dyn Fn(&Path) -> Result<(), String> + Send + Sync>;

/// One parser under test.
pub struct Target {
    pub name: &'static str,
    /// What the target reads, for `--help` and the README.
    pub about: &'static str,
    /// The seeds mutations start from.
    pub seeds: fn() -> Result<Vec<Input>>,
    /// A structured random input.
    pub generate: fn(&mut ChaCha8Rng) -> Input,
    /// Reads the input folder with the parser under test.
    pub parse: ParseFn,
}

/// Names of every target, in the order `all` runs them.
pub const TARGET_NAMES: [&str; 9] = [
    "g2o",
    "toro",
    "tum",
    "mcap",
    "stpere",
    "keyframes",
    "ping360",
    "miniking",
    "config",
];

/// Every target.
pub fn all_targets() -> Vec<Target> {
    TARGET_NAMES.iter().filter_map(|n| target(n)).collect()
}

/// The target called `name`.
pub fn target(name: &str) -> Option<Target> {
    let t = match name {
        "g2o" => Target {
            name: "g2o",
            about: "g2o pose graphs (read_pose_graph, then optimised when small)",
            seeds: g2o_seeds,
            generate: |rng| Input::single("graph.g2o", generate::pose_graph_text(rng, false)),
            parse: Arc::new(|dir| read_graph(&dir.join("graph.g2o"))),
        },
        "toro" => Target {
            name: "toro",
            about: "TORO pose graphs (read_pose_graph, then optimised when small)",
            seeds: toro_seeds,
            generate: |rng| Input::single("graph.graph", generate::pose_graph_text(rng, true)),
            parse: Arc::new(|dir| read_graph(&dir.join("graph.graph"))),
        },
        "tum" => Target {
            name: "tum",
            about: "TUM trajectories and the ATE/RPE between two of them",
            seeds: tum_seeds,
            generate: |rng| {
                let mut input = Input::single("estimate.txt", generate::tum_text(rng));
                input
                    .files
                    .push(("reference.txt".into(), generate::tum_text(rng)));
                input
            },
            parse: Arc::new(parse_tum_pair),
        },
        "mcap" => Target {
            name: "mcap",
            about: "MCAP missions (echofield_datasets::mcap::read_mission)",
            seeds: mcap_seeds,
            generate: |rng| Input::single("mission.mcap", random_mcap(rng)),
            parse: Arc::new(|dir| {
                echofield_datasets::mcap::read_mission(&dir.join("mission.mcap"))
                    .map(drop)
                    .map_err(|e| error_chain(&e))
            }),
        },
        "stpere" => Target {
            name: "stpere",
            about: "St Pere navigation folders (DVL, MTi, DGPS, SETUP, IS_timestamps logs)",
            seeds: stpere_seeds,
            generate: |rng| {
                let mut input = stpere_seed_files().clone();
                for (_, bytes) in &mut input.files {
                    *bytes = generate::regenerate_numbers(bytes, rng, 0.01);
                }
                input
            },
            parse: Arc::new(|dir| {
                echofield_datasets::stpere::read_stpere_dir(dir)
                    .map(drop)
                    .map_err(|e| error_chain(&e))
            }),
        },
        "keyframes" => Target {
            name: "keyframes",
            about: "St Pere keyframe point sets (keyFrameTimeStamps.csv + pclKeyFrameK.pcd) with their navigation folder",
            seeds: keyframe_seeds,
            generate: |rng| {
                let mut input = match keyframe_context() {
                    Ok(context) => context.seed.clone(),
                    Err(_) => Input::default(),
                };
                for (_, bytes) in &mut input.files {
                    *bytes = generate::regenerate_numbers(bytes, rng, 0.01);
                }
                input
            },
            parse: Arc::new(parse_keyframes),
        },
        "ping360" => Target {
            name: "ping360",
            about: "Ping360 logs of Ping Viewer (echofield_datasets::ping360::read_ping360)",
            seeds: ping360_seeds,
            generate: |rng| {
                let header = ping360_header().unwrap_or_default();
                Input::single("log.bin", generate::ping360_log(rng, &header))
            },
            parse: Arc::new(|dir| {
                echofield_datasets::ping360::read_ping360(&dir.join("log.bin"))
                    .map(drop)
                    .map_err(|e| error_chain(&e))
            }),
        },
        "miniking" => Target {
            name: "miniking",
            about: "MiniKing ROS 1 bags (echofield_datasets::miniking::read_miniking_bag)",
            seeds: miniking_seeds,
            generate: |rng| Input::single("scan.bag", generate::miniking_bag(rng)),
            parse: Arc::new(|dir| {
                echofield_datasets::miniking::read_miniking_bag(&dir.join("scan.bag"))
                    .map(drop)
                    .map_err(|e| error_chain(&e))
            }),
        },
        "config" => Target {
            name: "config",
            about: "config TOML: run/demo ([SlamConfig]), calibrate, match and simulator files",
            seeds: config_seeds,
            generate: |rng| {
                let text = crate::slam::SlamConfig::default().to_toml_string();
                Input::single(
                    "config.toml",
                    generate::regenerate_numbers(text.as_bytes(), rng, 0.2),
                )
            },
            parse: Arc::new(parse_configs),
        },
        _ => return None,
    };
    Some(t)
}

/// `err` and its sources, as the CLI prints them (`{:#}`).
fn error_chain(err: &(dyn std::error::Error + 'static)) -> String {
    let mut text = err.to_string();
    let mut source = err.source();
    while let Some(s) = source {
        text.push_str(": ");
        text.push_str(&s.to_string());
        source = s.source();
    }
    text
}

/// The repository root (the parent of the tools crate).
fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

fn fixture(relative: &str) -> Result<Vec<u8>> {
    let path = repo_root().join(relative);
    std::fs::read(&path).with_context(|| format!("reading fuzz seed {}", path.display()))
}

/// The first `n` lines of `bytes`.
fn first_lines(bytes: &[u8], n: usize) -> Vec<u8> {
    let end = bytes
        .iter()
        .enumerate()
        .filter(|&(_, &b)| b == b'\n')
        .nth(n.saturating_sub(1))
        .map_or(bytes.len(), |(k, _)| k + 1);
    bytes[..end].to_vec()
}

/// Graphs up to this many nodes are also optimised, as `echofield
/// optimize` would (larger ones would slow the fuzzing down).
const SOLVE_MAX_NODES: usize = 300;

fn read_graph(path: &Path) -> Result<(), String> {
    let mut graph = echofield_graph::io::read_pose_graph(path).map_err(|e| error_chain(&e))?;
    // Writing it back must work for whatever was accepted.
    let mut out = Vec::new();
    echofield_graph::io::write_g2o(&graph, &mut out).map_err(|e| e.to_string())?;
    // Whatever the reader accepts, the solver must take without panicking
    // or hanging (an error is fine).
    if graph.node_count() <= SOLVE_MAX_NODES {
        let config = echofield_backend::SolverConfig::default();
        echofield_backend::optimize(&mut graph, &config).map_err(|e| error_chain(&e))?;
    }
    Ok(())
}

fn g2o_seeds() -> Result<Vec<Input>> {
    let mut seeds = vec![Input::single(
        "graph.g2o",
        fixture("datasets/posegraph/vertigo-ring/ring.g2o")?,
    )];
    for name in ["manhattan", "intel", "city10000", "CSAIL", "MIT"] {
        let bytes = fixture(&format!("datasets/posegraph/{name}.g2o"))?;
        seeds.push(Input::single("graph.g2o", first_lines(&bytes, 300)));
    }
    // M3500 lists its 3500 vertices first: keep the first 100 and the
    // edges between them.
    let m3500 = fixture("datasets/posegraph/M3500.g2o")?;
    let text = String::from_utf8_lossy(&m3500);
    let small: String = text
        .lines()
        .filter(|line| {
            let t: Vec<&str> = line.split_whitespace().collect();
            let small = |k: usize| t.get(k).and_then(|v| v.parse::<u64>().ok()) < Some(100);
            match t.first() {
                Some(&"VERTEX_SE2") => small(1),
                Some(&"EDGE_SE2") => small(1) && small(2),
                _ => true,
            }
        })
        .map(|l| format!("{l}\n"))
        .collect();
    seeds.push(Input::single("graph.g2o", small.into_bytes()));
    Ok(seeds)
}

fn toro_seeds() -> Result<Vec<Input>> {
    let mut seeds = Vec::new();
    for g2o in g2o_seeds()? {
        let text = String::from_utf8_lossy(&g2o.files[0].1).into_owned();
        let graph = echofield_graph::io::parse_pose_graph(&text, Path::new("seed.g2o"))
            .context("a g2o fuzz seed does not parse")?;
        let mut out = Vec::new();
        echofield_graph::io::toro::write_toro(&graph, &mut out)?;
        seeds.push(Input::single("graph.graph", out));
    }
    Ok(seeds)
}

fn tum_seeds() -> Result<Vec<Input>> {
    let graph = echofield_graph::io::read_pose_graph(
        &repo_root().join("datasets/posegraph/vertigo-ring/ring_ground_truth.g2o"),
    )?;
    let poses = echofield_graph::io::graph_trajectory(&graph);
    let mut reference = Vec::new();
    echofield_graph::io::write_tum(&poses, &mut reference)?;
    let optimised = echofield_graph::io::read_pose_graph(
        &repo_root().join("datasets/posegraph/vertigo-ring/ring.g2o"),
    )?;
    let mut estimate = Vec::new();
    echofield_graph::io::write_tum(
        &echofield_graph::io::graph_trajectory(&optimised),
        &mut estimate,
    )?;
    Ok(vec![Input {
        files: vec![
            ("estimate.txt".into(), estimate),
            ("reference.txt".into(), reference),
        ],
    }])
}

/// Reads both trajectories and evaluates one against the other, as
/// `echofield eval` does: an accepted pair must give finite statistics.
fn parse_tum_pair(dir: &Path) -> Result<(), String> {
    use crate::eval::{Alignment, ate, rpe};
    let read =
        |name: &str| echofield_graph::io::read_tum(&dir.join(name)).map_err(|e| error_chain(&e));
    let (estimate, reference) = (read("estimate.txt")?, read("reference.txt")?);
    for alignment in [Alignment::Se2, Alignment::None] {
        match ate(&estimate, &reference, alignment, 0.01) {
            Ok(stats) => {
                let values = [stats.rmse_m, stats.mean_m, stats.median_m, stats.max_m];
                if values.iter().any(|v| !v.is_finite()) {
                    panic!("ATE of accepted trajectories is not finite: {stats:?}");
                }
            }
            Err(e) => return Err(format!("{e:#}")),
        }
    }
    for stats in rpe(&estimate, &reference, &[1.0, 10.0], 0.01) {
        let values = [
            stats.translation_rmse_m,
            stats.translation_rmse_percent,
            stats.rotation_rmse_deg,
        ];
        if values.iter().any(|v| !v.is_finite()) {
            panic!("RPE of accepted trajectories is not finite: {stats:?}");
        }
    }
    Ok(())
}

/// A small mission written by the MCAP writer into memory.
fn mcap_bytes(mission: &echofield_frontend::sensors::Mission, ros2: bool) -> Result<Vec<u8>> {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("m.mcap");
    if ros2 {
        echofield_datasets::mcap::write_mission_ros2(
            &path,
            mission,
            echofield_datasets::mcap::Ros2GroundTruth::PoseStamped,
        )?;
    } else {
        echofield_datasets::mcap::write_mission(&path, mission)?;
    }
    Ok(std::fs::read(&path)?)
}

fn mcap_seeds() -> Result<Vec<Input>> {
    let mut mission = echofield_datasets::mcap::read_mission(
        &repo_root().join("datasets/samples/tank-seed1.mcap"),
    )?;
    mission.beams.truncate(60);
    let end_s = mission.beams.last().map_or(f64::INFINITY, |b| b.stamp_s);
    mission.dvl.retain(|s| s.stamp_s <= end_s);
    mission.attitude.retain(|s| s.stamp_s <= end_s);
    mission.ground_truth.retain(|s| s.stamp_s <= end_s);
    let random = echofield_datasets::mcap::fixture::random_mission(20, 50, 1);
    Ok(vec![
        Input::single("mission.mcap", mcap_bytes(&mission, false)?),
        Input::single("mission.mcap", mcap_bytes(&mission, true)?),
        Input::single("mission.mcap", mcap_bytes(&random, false)?),
        Input::single(
            "mission.mcap",
            fixture("datasets/tests/mcap_data/zstd_no_progress.mcap")?,
        ),
    ])
}

fn random_mcap(rng: &mut ChaCha8Rng) -> Vec<u8> {
    let mut mission = echofield_datasets::mcap::fixture::random_mission(
        rng.random_range(0..30),
        rng.random_range(1..80),
        rng.random(),
    );
    if rng.random_bool(0.3) {
        mission.dvl.clear();
    }
    if rng.random_bool(0.3) {
        mission.ground_truth.clear();
    }
    mcap_bytes(&mission, rng.random_bool(0.3)).unwrap_or_default()
}

/// Header lines plus the first data lines of each St Pere log, so that
/// the folder still parses.
fn stpere_seed_files() -> &'static Input {
    static SEED: OnceLock<Input> = OnceLock::new();
    SEED.get_or_init(|| stpere_logs(200))
}

/// The St Pere logs cut short; `beam_stamps` lines of `_IS_timestamps.log`.
fn stpere_logs(beam_stamps: usize) -> Input {
    let mut input = Input::default();
    for (kind, lines) in [
        ("DVL", 160),
        ("MTI", 120),
        ("DGPS", 60),
        ("SETUP", 5),
        ("IS_timestamps", beam_stamps),
    ] {
        let name = format!("_040825_1735_{kind}.log");
        if let Ok(bytes) = fixture(&format!("datasets/stpere-marina/{name}")) {
            input.files.push((name, first_lines(&bytes, lines)));
        }
    }
    input
}

fn stpere_seeds() -> Result<Vec<Input>> {
    let seed = stpere_seed_files().clone();
    anyhow::ensure!(seed.files.len() == 5, "the St Pere fuzz seeds are missing");
    // The same folder without its optional logs.
    let mut minimal = seed.clone();
    minimal
        .files
        .retain(|(name, _)| !name.contains("SETUP") && !name.contains("IS_"));
    Ok(vec![seed, minimal])
}

/// A seed folder of three keyframes expanded from the committed bands,
/// with the St Pere navigation logs cut to the beam stamps they need (the
/// reader takes the setup and the beam times from those logs).
struct KeyframeContext {
    seed: Input,
}

fn keyframe_context() -> Result<&'static KeyframeContext, String> {
    static CONTEXT: OnceLock<Result<KeyframeContext, String>> = OnceLock::new();
    CONTEXT
        .get_or_init(|| load_keyframe_context().map_err(|e| format!("{e:#}")))
        .as_ref()
        .map_err(Clone::clone)
}

fn load_keyframe_context() -> Result<KeyframeContext> {
    use echofield_datasets::stpere::keyframes::KEYFRAME_CSV;
    use echofield_datasets::stpere::point_bands::{ST_PERE_SETUP, expand_point_bands};
    let dir = tempfile::tempdir()?;
    let sonar = repo_root().join("datasets/stpere-marina-sonar");
    expand_point_bands(
        &sonar.join("bands.csv"),
        &sonar.join(KEYFRAME_CSV),
        &ST_PERE_SETUP,
        dir.path(),
    )?;
    let csv = std::fs::read(dir.path().join(KEYFRAME_CSV))?;
    // Keyframe 3 ends 52 s after the first beam stamp, at about 0.07 s per
    // beam.
    let mut seed = stpere_logs(800);
    seed.files.push((KEYFRAME_CSV.into(), first_lines(&csv, 4)));
    for k in 1..=3 {
        let name = format!("pclKeyFrame{k}.pcd");
        seed.files
            .push((name.clone(), std::fs::read(dir.path().join(&name))?));
    }
    let check = tempfile::tempdir()?;
    seed.write_to(check.path())?;
    read_keyframe_folder(check.path()).map_err(anyhow::Error::msg)?;
    Ok(KeyframeContext { seed })
}

fn keyframe_seeds() -> Result<Vec<Input>> {
    let context = keyframe_context().map_err(anyhow::Error::msg)?;
    Ok(vec![context.seed.clone()])
}

/// The navigation logs and keyframes of one folder, read as `echofield
/// convert stpere DIR --keyframes DIR` does.
fn read_keyframe_folder(dir: &Path) -> Result<(), String> {
    echofield_datasets::stpere::read_stpere_with_keyframes(dir, dir, SweepTiming::AngleIncreasing)
        .map(drop)
        .map_err(|e| error_chain(&e))
}

fn parse_keyframes(dir: &Path) -> Result<(), String> {
    read_keyframe_folder(dir)
}

const PING360_LOGS: [&str; 3] = [
    "Sensor_Log_01__inside_base.bin",
    "Corrupted__20210619-213338492.bin",
    "Sensor_Log_02__20210829-003011721.bin",
];

/// The bytes before the first record of a real Ping360 log: the magic,
/// version, five strings and two integers.
fn ping360_header() -> Result<Vec<u8>> {
    let bytes = fixture(&format!("datasets/msis-real/ping360/{}", PING360_LOGS[2]))?;
    let mut pos = 0usize;
    let qstring = |pos: &mut usize| -> Option<()> {
        let len = u32::from_be_bytes(bytes.get(*pos..*pos + 4)?.try_into().ok()?);
        *pos += 4 + if len == u32::MAX { 0 } else { len as usize };
        Some(())
    };
    let steps = (|| {
        qstring(&mut pos)?;
        pos += 4;
        for _ in 0..5 {
            qstring(&mut pos)?;
        }
        pos += 8;
        Some(())
    })();
    anyhow::ensure!(
        steps.is_some() && pos <= bytes.len(),
        "the Ping360 fixture has no readable header"
    );
    Ok(bytes[..pos].to_vec())
}

fn ping360_seeds() -> Result<Vec<Input>> {
    PING360_LOGS
        .iter()
        .map(|name| {
            let bytes = fixture(&format!("datasets/msis-real/ping360/{name}"))?;
            Ok(Input::single(
                "log.bin",
                bytes[..bytes.len().min(48 * 1024)].to_vec(),
            ))
        })
        .collect()
}

fn miniking_seeds() -> Result<Vec<Input>> {
    [
        "full_sonar_scan_2015-05-26-11-38-04.bag",
        "narrow_sonar_scan_2015-05-26-11-41-49.bag",
    ]
    .iter()
    .map(|name| {
        Ok(Input::single(
            "scan.bag",
            fixture(&format!("datasets/msis-real/miniking/{name}"))?,
        ))
    })
    .collect()
}

fn config_seeds() -> Result<Vec<Input>> {
    let mut seeds = vec![Input::single(
        "config.toml",
        crate::slam::SlamConfig::default()
            .to_toml_string()
            .into_bytes(),
    )];
    for path in [
        "tools/configs/default.toml",
        "tools/configs/no_loops.toml",
        "tools/configs/sim/exact_navigation.toml",
        "tools/configs/sim/exact_navigation_narrow_beam.toml",
        "tools/configs/sim/flat_echo.toml",
        "datasets/samples/tank-seed1.sim.toml",
    ] {
        seeds.push(Input::single("config.toml", fixture(path)?));
    }
    Ok(seeds)
}

/// Reads the file as every kind of config the CLI takes; accepted when
/// one of them takes it.
fn parse_configs(dir: &Path) -> Result<(), String> {
    let path = dir.join("config.toml");
    let slam = crate::slam::SlamConfig::from_toml_file(&path).map(drop);
    let calibrate =
        crate::calibration::CalibrateSettings::from_optional_file(Some(&path)).map(drop);
    let sim = std::fs::read_to_string(&path)
        .map_err(anyhow::Error::from)
        .and_then(|text| {
            let config: echofield_datasets::sim::SimConfig = crate::config_file::from_toml_over(
                &text,
                &echofield_datasets::sim::SimConfig::default(),
            )?;
            config.validate()?;
            Ok(())
        });
    // `match` and the matcher benchmarks read the run's config (`slam`).
    match (slam, calibrate, sim) {
        (Err(e), Err(_), Err(_)) => Err(format!("{e:#}")),
        _ => Ok(()),
    }
}
