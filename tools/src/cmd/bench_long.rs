//! `echofield bench-long`: how the pipeline scales with the number of
//! rotations of a mission (issue 36, "long missions").

use anyhow::{Context, Result, bail};
use echofield::slam::online::run_online_taking_beams;
use echofield::slam::outputs::write_outputs;
use echofield::slam::{NoProgress, SlamConfig, load_mission, run_mission_taking_beams};
use echofield_datasets::mcap::write_mission;
use echofield_datasets::sim::{Scenario, SimConfig, simulate_mission};
use std::path::{Path, PathBuf};
use std::time::Instant;

const EXAMPLES: &str = "\
Examples:
  # The issue's table: the marina (seed 1) at 0.4, 0.2, 0.1 and 0.05 m/s,
  # about 179, 351, 699 and 1,397 rotations
  echofield bench-long --output out/bench-long

  # The same over five simulations of each speed (seeds 1-5), with the
  # mean of each speed: one seed's ATE depends on the loops it happens to
  # accept
  echofield bench-long --output out/bench-long --seeds 1,2,3,4,5

  # Only the smaller sizes, with a pipeline config
  echofield bench-long --output out/bench-long --speeds 0.4,0.2 --config my.toml

  # Every loop pair kept and every rotation a node (no sparsification),
  # as the default `run`
  echofield bench-long --output out/bench-long --cover-spacing-m 0 --node-spacing-m 0

  # The runs online, as `run --online`: the ATE of the estimates as they
  # were emitted and the work per rotation are added to the table
  echofield bench-long --output out/bench-long --online

The simulated marina is surveyed along the same route at each cruise speed
([vehicle] cruise_speed_mps of the simulator), so slower missions see the
same quays with more rotations. The runs sparsify loops with
--cover-spacing-m (loops.cover_spacing_m, default 2 m here, 0 in `run`)
and nodes with --node-spacing-m (rotation.node_spacing_m, 2 m here and
in `run`).
Each mission is written to OUTPUT as
marina-<speed>.mcap and run by `echofield run`'s pipeline in a child
process (outputs in OUTPUT/run-<speed>; with several --seeds,
marina-<speed>-seed<N>.mcap and run-<speed>-seed<N>), whose peak resident memory
(VmHWM, Linux), wall time and CPU time (user + system, all threads,
Linux; unlike the wall time, hardly changed by other programs on a
loaded machine), reading and writing included, are reported
with the run's loop candidates, accepted loops, node images built again
after the memory budget released them, and ATE (dead reckoning's in
brackets); with --online each run goes through the causal engine as
`run --online` does, and the table adds the ATE of the emitted estimates
and the latency per rotation (p50 / p95 / max). With several seeds a row
per seed is followed by the mean of each speed over the seeds. The last
line compares the last speed's times with the first's (the means of each
speed's runs).";

#[derive(Debug, clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// Folder for the missions and the runs' outputs.
    #[arg(long, short)]
    pub output: PathBuf,
    /// Cruise speeds of the simulated vehicle, m/s, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "0.4,0.2,0.1,0.05")]
    pub speeds: Vec<f64>,
    /// Seeds of the simulations, comma separated: each speed is simulated
    /// and run once per seed (`--seed` is the same option).
    #[arg(long, alias = "seed", value_delimiter = ',', default_value = "1")]
    pub seeds: Vec<u64>,
    /// Pipeline configuration (TOML) for the runs.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// `loops.cover_spacing_m` of the runs (loop sparsification), metres
    /// of track; it replaces the config's. 0 keeps every loop pair.
    #[arg(long, default_value_t = 2.0)]
    pub cover_spacing_m: f64,
    /// `rotation.node_spacing_m` of the runs (keyframe selection), metres;
    /// it replaces the config's. 0 makes every rotation a node.
    #[arg(long, default_value_t = 2.0)]
    pub node_spacing_m: f64,
    /// Run each mission online (`run --online`: causal, each node emitted
    /// as its rotation completes) and add the emitted estimates' ATE and
    /// the latency per rotation to the table.
    #[arg(long)]
    pub online: bool,
    /// Internal: run this mission in this process and print its peak
    /// memory (the parent's child process).
    #[arg(long, hide = true)]
    pub child: Option<PathBuf>,
}

/// One row of the table.
struct Row {
    speed_mps: f64,
    seed: u64,
    rotations: usize,
    nodes: usize,
    candidates: usize,
    accepted: usize,
    rebuilt: usize,
    time_s: f64,
    cpu_s: Option<f64>,
    peak_mb: Option<f64>,
    ate_m: Option<f64>,
    ate_dr_m: Option<f64>,
    /// With `--online`: the emitted estimates' ATE and the latency per
    /// rotation p50, p95, max (ms), from `report.json` → `online`.
    online: Option<OnlineFigures>,
}

struct OnlineFigures {
    ate_m: Option<f64>,
    latency_ms: [f64; 3],
}

pub fn run(args: Args) -> Result<()> {
    if let Some(mission) = &args.child {
        return run_child(mission, &args.output, args.config.as_deref(), &args);
    }
    check_lists(&args)?;
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("cannot create folder {}", args.output.display()))?;
    let several = args.seeds.len() > 1;
    let mut rows = Vec::new();
    print_header(args.online, several);
    for &speed in &args.speeds {
        for &seed in &args.seeds {
            let name = if several {
                format!("{speed}-seed{seed}")
            } else {
                speed.to_string()
            };
            let mission = args.output.join(format!("marina-{name}.mcap"));
            simulate(speed, seed, &mission)?;
            let out = args.output.join(format!("run-{name}"));
            let row = measure(speed, seed, &mission, &out, &args)?;
            print_row(&row, several);
            rows.push(row);
        }
    }
    let means = speed_means(&rows);
    if several {
        println!();
        println!("Mean over seeds {}:", join(&args.seeds));
        print_header(args.online, false);
        means.iter().for_each(|row| print_row(row, false));
    }
    print_time_ratio(&means);
    Ok(())
}

/// Errors for speeds that are not positive and for a seed list that is
/// empty or names a seed twice.
fn check_lists(args: &Args) -> Result<()> {
    if args.speeds.is_empty() || args.speeds.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        bail!("--speeds must be positive cruise speeds in m/s");
    }
    if args.seeds.is_empty() {
        bail!("--seeds needs at least one seed");
    }
    let twice = (1..args.seeds.len()).find(|&k| args.seeds[..k].contains(&args.seeds[k]));
    if let Some(k) = twice {
        bail!(
            "--seeds lists seed {} twice (its runs would share one output folder)",
            args.seeds[k]
        );
    }
    Ok(())
}

/// The last line: the last speed's times against the first's (`means`,
/// one row per speed), when there are two speeds or more.
fn print_time_ratio(means: &[Row]) {
    let (Some(first), Some(last)) = (means.first(), means.last()) else {
        return;
    };
    if means.len() < 2 {
        return;
    }
    let cpu = match (last.cpu_s, first.cpu_s) {
        (Some(l), Some(f)) => format!(" ({:.1} times the CPU time)", l / f.max(1e-9)),
        _ => String::new(),
    };
    println!(
        "{} rotations took {:.1} times as long as {}{cpu}",
        last.rotations,
        last.time_s / first.time_s.max(1e-9),
        first.rotations
    );
}

fn join(seeds: &[u64]) -> String {
    seeds
        .iter()
        .map(u64::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

/// One row per speed (in the order of `rows`): each count, time, memory
/// and ATE the mean of that speed's rows (rounded for the counts; a
/// figure missing from any row is missing from the mean).
fn speed_means(rows: &[Row]) -> Vec<Row> {
    let mut speeds: Vec<f64> = Vec::new();
    for row in rows {
        if !speeds.contains(&row.speed_mps) {
            speeds.push(row.speed_mps);
        }
    }
    speeds
        .into_iter()
        .map(|speed| {
            let of: Vec<&Row> = rows.iter().filter(|r| r.speed_mps == speed).collect();
            let n = of.len() as f64;
            let count = |f: fn(&Row) -> usize| {
                (of.iter().map(|r| f(r) as f64).sum::<f64>() / n).round() as usize
            };
            let mean = |f: fn(&Row) -> Option<f64>| mean_of_all(of.iter().map(|r| f(r)));
            let online = of
                .iter()
                .map(|r| r.online.as_ref())
                .collect::<Option<Vec<_>>>()
                .map(|o| OnlineFigures {
                    ate_m: mean_of_all(o.iter().map(|f| f.ate_m)),
                    latency_ms: std::array::from_fn(|k| {
                        o.iter().map(|f| f.latency_ms[k]).sum::<f64>() / n
                    }),
                });
            Row {
                speed_mps: speed,
                // Not shown: mean rows are printed without the seed column.
                seed: of[0].seed,
                rotations: count(|r| r.rotations),
                nodes: count(|r| r.nodes),
                candidates: count(|r| r.candidates),
                accepted: count(|r| r.accepted),
                rebuilt: count(|r| r.rebuilt),
                time_s: of.iter().map(|r| r.time_s).sum::<f64>() / n,
                cpu_s: mean(|r| r.cpu_s),
                peak_mb: mean(|r| r.peak_mb),
                ate_m: mean(|r| r.ate_m),
                ate_dr_m: mean(|r| r.ate_dr_m),
                online,
            }
        })
        .collect()
}

/// The mean of `values`, `None` when any is `None` (or there are none).
fn mean_of_all(values: impl Iterator<Item = Option<f64>>) -> Option<f64> {
    let values: Option<Vec<f64>> = values.collect();
    values
        .filter(|v| !v.is_empty())
        .map(|v| v.iter().sum::<f64>() / v.len() as f64)
}

fn print_header(online: bool, seed_column: bool) {
    let (extra, rule) = if online {
        (
            " online ATE (m) | latency p50 / p95 / max (ms) |",
            "---|---|",
        )
    } else {
        ("", "")
    };
    let (seed, seed_rule) = if seed_column {
        (" seed |", "---|")
    } else {
        ("", "")
    };
    println!(
        "| cruise speed (m/s) |{seed} rotations | nodes | loop candidates | loops accepted | images rebuilt | time (s) | CPU time (s) | peak memory (MB) | ATE (DR) (m) |{extra}"
    );
    println!("|---|{seed_rule}---|---|---|---|---|---|---|---|---|{rule}");
}

fn print_row(row: &Row, seed_column: bool) {
    let show = |v: Option<f64>, digits: usize| {
        v.map_or_else(|| "n/a".to_string(), |v| format!("{v:.digits$}"))
    };
    let online = row.online.as_ref().map_or(String::new(), |o| {
        let [p50, p95, max] = o.latency_ms;
        format!(" {} | {p50:.1} / {p95:.1} / {max:.1} |", show(o.ate_m, 3))
    });
    let seed = if seed_column {
        format!(" {} |", row.seed)
    } else {
        String::new()
    };
    println!(
        "| {} |{seed} {} | {} | {} | {} | {} | {:.1} | {} | {} | {} ({}) |{online}",
        row.speed_mps,
        row.rotations,
        row.nodes,
        row.candidates,
        row.accepted,
        row.rebuilt,
        row.time_s,
        show(row.cpu_s, 1),
        show(row.peak_mb, 0),
        show(row.ate_m, 3),
        show(row.ate_dr_m, 2)
    );
}

/// The marina at `speed_mps`, written to `path`.
fn simulate(speed_mps: f64, seed: u64, path: &Path) -> Result<()> {
    let mut config = SimConfig::default();
    config.vehicle.cruise_speed_mps = speed_mps;
    let scenario = Scenario::build("marina", config, None).context("marina scenario")?;
    let mission = simulate_mission(&scenario, seed).context("simulation failed")?;
    write_mission(path, &mission)?;
    Ok(())
}

/// Runs `mission` (simulated with `seed`) in a child process of this
/// program, its outputs in `out`, and reads its report.
fn measure(speed_mps: f64, seed: u64, mission: &Path, out: &Path, args: &Args) -> Result<Row> {
    let exe = std::env::current_exe().context("cannot find the echofield program")?;
    let mut command = std::process::Command::new(exe);
    command
        .arg("bench-long")
        .arg("--output")
        .arg(out)
        .arg("--child")
        .arg(mission)
        .arg("--cover-spacing-m")
        .arg(args.cover_spacing_m.to_string())
        .arg("--node-spacing-m")
        .arg(args.node_spacing_m.to_string());
    if let Some(config) = &args.config {
        command.arg("--config").arg(config);
    }
    if args.online {
        command.arg("--online");
    }
    let start = Instant::now();
    let result = command
        .output()
        .with_context(|| format!("cannot run {}", mission.display()))?;
    let time_s = start.elapsed().as_secs_f64();
    if !result.status.success() {
        bail!(
            "the run of {} failed: {}",
            mission.display(),
            String::from_utf8_lossy(&result.stderr).trim()
        );
    }
    let stdout = String::from_utf8_lossy(&result.stdout);
    let value = |key: &str| {
        stdout
            .lines()
            .find_map(|l| l.strip_prefix(key)?.trim().parse::<f64>().ok())
    };
    let peak_mb = value("peak_kb ").map(|kb| kb / 1024.0);
    let cpu_s = value("cpu_s ");
    let path = out.join("report.json");
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let report: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{} is not JSON", path.display()))?;
    let count = |key: &str| report[key].as_u64().unwrap_or(0) as usize;
    Ok(Row {
        speed_mps,
        seed,
        rotations: count("rotations"),
        nodes: count("nodes"),
        candidates: count("loop_candidates"),
        accepted: count("loops_accepted"),
        rebuilt: count("images_rebuilt"),
        time_s,
        cpu_s,
        peak_mb,
        ate_m: report["ate_rmse_m"].as_f64(),
        ate_dr_m: report["ate_rmse_dead_reckoning_m"].as_f64(),
        online: online_figures(&report["online"]),
    })
}

/// `report.json` → `online` of a `--online` run; `None` for a batch run.
fn online_figures(online: &serde_json::Value) -> Option<OnlineFigures> {
    let ms = |key: &str| online[key].as_f64();
    Some(OnlineFigures {
        ate_m: online["ate_rmse_m"].as_f64(),
        latency_ms: [
            ms("latency_p50_ms")?,
            ms("latency_p95_ms")?,
            ms("latency_max_ms")?,
        ],
    })
}

/// The child: runs the pipeline on `mission` with `config` and the
/// sparsification spacings of `args` (online with `--online`), writes the outputs to `output` and
/// prints `peak_kb N`, its peak resident memory, and `cpu_s T`, its CPU
/// time.
fn run_child(mission_path: &Path, output: &Path, config: Option<&Path>, args: &Args) -> Result<()> {
    let mut config = SlamConfig::from_optional_toml_file(config)?;
    config.loops.cover_spacing_m = args.cover_spacing_m;
    config.rotation.node_spacing_m = args.node_spacing_m;
    let mut mission = load_mission(mission_path)?;
    let result = if args.online {
        run_online_taking_beams(&mut mission, &config, &NoProgress)
    } else {
        run_mission_taking_beams(&mut mission, &config, &NoProgress)
    }
    .with_context(|| format!("SLAM on {} failed", mission_path.display()))?;
    write_outputs(output, &result, &mission)?;
    if let Some(kb) = peak_resident_kb() {
        println!("peak_kb {kb}");
    }
    if let Some(cpu_s) = cpu_time_s() {
        println!("cpu_s {cpu_s}");
    }
    Ok(())
}

/// Clock ticks per second of `/proc/*/stat`'s times: `USER_HZ`, fixed at
/// 100 in Linux's user-space ABI (whatever the kernel's own tick rate).
const USER_HZ: f64 = 100.0;

/// User plus system CPU time of this process (all its threads) so far, s
/// (Linux); `None` elsewhere.
fn cpu_time_s() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may hold spaces), from field 3
    // (state): utime and stime are fields 14 and 15.
    let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
    let ticks = |i: usize| fields.get(i)?.parse::<f64>().ok();
    Some((ticks(11)? + ticks(12)?) / USER_HZ)
}

/// `VmHWM` of this process in kB (Linux); `None` elsewhere.
fn peak_resident_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    status.lines().find_map(|line| {
        let value = line.strip_prefix("VmHWM:")?;
        value.trim().trim_end_matches("kB").trim().parse().ok()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_online_report_gives_the_online_columns_and_a_batch_one_none() {
        let report: serde_json::Value = serde_json::from_str(
            r#"{"online": {"nodes_emitted": 3, "latency_p50_ms": 1.5,
                "latency_p95_ms": 2.5, "latency_max_ms": 4.0, "ate_rmse_m": 0.7}}"#,
        )
        .unwrap();
        let online = online_figures(&report["online"]).unwrap();
        assert_eq!(online.latency_ms, [1.5, 2.5, 4.0]);
        assert_eq!(online.ate_m, Some(0.7));
        let batch: serde_json::Value = serde_json::from_str(r#"{"online": null}"#).unwrap();
        assert!(online_figures(&batch["online"]).is_none());
        assert!(online_figures(&serde_json::Value::Null).is_none());
    }

    fn row(speed_mps: f64, seed: u64, rotations: usize, ate_m: Option<f64>) -> Row {
        Row {
            speed_mps,
            seed,
            rotations,
            nodes: rotations,
            candidates: 10 * rotations,
            accepted: 3,
            rebuilt: 0,
            time_s: rotations as f64 / 100.0,
            cpu_s: Some(rotations as f64 / 50.0),
            peak_mb: None,
            ate_m,
            ate_dr_m: Some(2.0),
            online: None,
        }
    }

    #[test]
    fn the_means_over_seeds_are_taken_per_speed_in_order() {
        // Two speeds, two seeds each, in the order the runs are made.
        let rows = [
            row(0.4, 1, 179, Some(0.2)),
            row(0.4, 2, 181, Some(0.4)),
            row(0.05, 1, 1397, Some(0.5)),
            row(0.05, 2, 1398, None),
        ];
        let means = speed_means(&rows);
        assert_eq!(means.len(), 2);
        let (fast, slow) = (&means[0], &means[1]);
        assert_eq!(fast.speed_mps, 0.4);
        assert_eq!(fast.rotations, 180);
        assert_eq!(fast.candidates, 1800);
        assert!((fast.ate_m.unwrap() - 0.3).abs() < 1e-12);
        assert!((fast.time_s - 1.8).abs() < 1e-12);
        assert!((fast.cpu_s.unwrap() - 3.6).abs() < 1e-12);
        assert_eq!(fast.peak_mb, None);
        assert_eq!(slow.speed_mps, 0.05);
        // 1397.5 rounds away from zero.
        assert_eq!(slow.rotations, 1398);
        // A seed without an ATE leaves the mean without one.
        assert_eq!(slow.ate_m, None);
        assert_eq!(slow.ate_dr_m, Some(2.0));
    }

    #[test]
    fn speeds_and_seeds_are_checked_before_anything_runs() {
        let args = |speeds: Vec<f64>, seeds: Vec<u64>| Args {
            output: PathBuf::from("unused"),
            speeds,
            seeds,
            config: None,
            cover_spacing_m: 2.0,
            node_spacing_m: 2.0,
            online: false,
            child: None,
        };
        assert!(check_lists(&args(vec![0.4, 0.05], vec![1, 2, 3])).is_ok());
        let twice = check_lists(&args(vec![0.4], vec![1, 2, 1])).unwrap_err();
        assert!(twice.to_string().contains("seed 1 twice"), "{twice}");
        assert!(check_lists(&args(vec![0.4], vec![])).is_err());
        assert!(check_lists(&args(vec![0.0], vec![1])).is_err());
        assert!(check_lists(&args(vec![f64::NAN], vec![1])).is_err());
        assert!(check_lists(&args(vec![], vec![1])).is_err());
    }

    #[test]
    fn reads_its_own_peak_memory() {
        if cfg!(target_os = "linux") {
            let kb = peak_resident_kb().expect("VmHWM on Linux");
            assert!(kb > 100, "{kb} kB");
        }
    }

    #[test]
    fn reads_its_own_cpu_time() {
        if cfg!(target_os = "linux") {
            let before = cpu_time_s().expect("/proc/self/stat on Linux");
            // Spin until the CPU clock has ticked at least twice.
            let mut x = 0u64;
            while cpu_time_s().unwrap() < before + 0.02 {
                x = std::hint::black_box(x.wrapping_add(1));
            }
            assert!(cpu_time_s().unwrap() >= before + 0.02);
        }
    }
}
