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
process (outputs in OUTPUT/run-<speed>), whose peak resident memory
(VmHWM, Linux), wall time and CPU time (user + system, all threads,
Linux; unlike the wall time, hardly changed by other programs on a
loaded machine), reading and writing included, are reported
with the run's loop candidates, accepted loops, node images built again
after the memory budget released them, and ATE (dead reckoning's in
brackets); with --online each run goes through the causal engine as
`run --online` does, and the table adds the ATE of the emitted estimates
and the latency per rotation (p50 / p95 / max). The last line compares
the largest mission's times with the smallest's.";

#[derive(Debug, clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// Folder for the missions and the runs' outputs.
    #[arg(long, short)]
    pub output: PathBuf,
    /// Cruise speeds of the simulated vehicle, m/s, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "0.4,0.2,0.1,0.05")]
    pub speeds: Vec<f64>,
    /// Seed of the simulation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
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
    if args.speeds.is_empty() || args.speeds.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        bail!("--speeds must be positive cruise speeds in m/s");
    }
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("cannot create folder {}", args.output.display()))?;
    let mut rows = Vec::new();
    print_header(args.online);
    for &speed in &args.speeds {
        let mission = args.output.join(format!("marina-{speed}.mcap"));
        simulate(speed, args.seed, &mission)?;
        let row = measure(speed, &mission, &args)?;
        print_row(&row);
        rows.push(row);
    }
    if let (Some(first), Some(last)) = (rows.first(), rows.last())
        && rows.len() > 1
    {
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
    Ok(())
}

fn print_header(online: bool) {
    let (extra, rule) = if online {
        (
            " online ATE (m) | latency p50 / p95 / max (ms) |",
            "---|---|",
        )
    } else {
        ("", "")
    };
    println!(
        "| cruise speed (m/s) | rotations | nodes | loop candidates | loops accepted | images rebuilt | time (s) | CPU time (s) | peak memory (MB) | ATE (DR) (m) |{extra}"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|{rule}");
}

fn print_row(row: &Row) {
    let show = |v: Option<f64>, digits: usize| {
        v.map_or_else(|| "n/a".to_string(), |v| format!("{v:.digits$}"))
    };
    let online = row.online.as_ref().map_or(String::new(), |o| {
        let [p50, p95, max] = o.latency_ms;
        format!(" {} | {p50:.1} / {p95:.1} / {max:.1} |", show(o.ate_m, 3))
    });
    println!(
        "| {} | {} | {} | {} | {} | {} | {:.1} | {} | {} | {} ({}) |{online}",
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

/// Runs `mission` in a child process of this program and reads its report.
fn measure(speed_mps: f64, mission: &Path, args: &Args) -> Result<Row> {
    let exe = std::env::current_exe().context("cannot find the echofield program")?;
    let out = args.output.join(format!("run-{speed_mps}"));
    let mut command = std::process::Command::new(exe);
    command
        .arg("bench-long")
        .arg("--output")
        .arg(&out)
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
