//! `echofield bench-robust`: the backend against false loop closures, in the
//! style of the vertigo benchmarks.

use anyhow::{Context, Result, bail};
use echofield::eval::aligned_position_rmse;
use echofield::output::write_atomic;
use echofield_backend::{OutlierConfig, RobustConfig, SolverConfig, optimize, optimize_robust};
use echofield_graph::PoseGraph;
use echofield_graph::io::{read_pose_graph, write_g2o};
use echofield_graph::synthetic::{FalseLoops, add_false_loops};
use serde::Serialize;
use std::path::PathBuf;

const EXAMPLES: &str = "\
Examples:
  # The issue's table: four benchmarks, 0 / 100 / 1000 false loops, two seeds
  echofield bench-robust datasets/posegraph/manhattan.g2o datasets/posegraph/M3500.g2o datasets/posegraph/vertigo-ring/ring.g2o datasets/posegraph/city10000.g2o --false-loops 0,100,1000 --seeds 1,2

  # Compare with a kernel alone (no growth, no switching off), and keep the
  # corrupted graphs for other solvers
  echofield bench-robust datasets/posegraph/M3500.g2o --method kernel --kernel cauchy --write-graphs out/corrupted

False loops join random pairs of non-consecutive nodes with a random
relative pose (translation uniform in +-max-translation metres per axis,
rotation uniform) and the information of a random loop of the file, as
the vertigo benchmarks' random outliers; each (file, count, seed) draws the
same loops every time. For each graph the ATE is the RMSE of the node
positions, after SE(2) alignment, against the plain least-squares optimum
of the clean file (chordal start, Levenberg-Marquardt). `--method robust`
is the machinery of `optimize --robust` (growth in node order, the
kernel, switching off, least squares on the rest); `--method kernel` is
the kernel alone from the trusted start. Edges between consecutive ids are
trusted (odometry), all others suspect.";

/// What is solved.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Growth in node order, the kernel, switching off, least squares.
    Robust,
    /// The kernel alone, from the trusted edges' start.
    Kernel,
}

#[derive(Debug, clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// Pose graphs (g2o or TORO) without false loops.
    #[arg(required = true)]
    pub graphs: Vec<PathBuf>,
    /// Numbers of false loops to add, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "0,100,1000")]
    pub false_loops: Vec<usize>,
    /// Seeds of the false loops, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    pub seeds: Vec<u64>,
    /// Largest translation component of a false loop, metres.
    #[arg(long, default_value_t = 10.0)]
    pub max_translation: f64,
    #[arg(long, value_enum, default_value = "robust")]
    pub method: Method,
    /// Kernel on the loop closures.
    #[arg(long, value_enum, default_value = "dcs")]
    pub kernel: super::optimize::RobustArg,
    /// Write each corrupted graph here as `<file>-<count>-<seed>.g2o`.
    #[arg(long)]
    pub write_graphs: Option<PathBuf>,
    /// Write the table as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// One row of the table.
#[derive(Debug, Serialize)]
struct Row {
    graph: String,
    false_loops: usize,
    seed: u64,
    method: Method,
    kernel: &'static str,
    ate_m: f64,
    /// False loops switched off (robust method), of `false_loops`.
    false_switched_off: Option<usize>,
    /// True loops (the file's) switched off.
    true_switched_off: Option<usize>,
    hit_iteration_cap: bool,
    time_s: f64,
}

pub fn run(args: Args) -> Result<()> {
    if !(args.max_translation.is_finite() && args.max_translation > 0.0) {
        bail!(
            "--max-translation must be finite and positive, got {}",
            args.max_translation
        );
    }
    let kernel = super::optimize::kernel_of(args.kernel);
    let solver = SolverConfig {
        robust: RobustConfig::loops_only(kernel),
        ..SolverConfig::default()
    };
    let mut rows = Vec::new();
    println!(
        "{:<16} {:>6} {:>4} {:>8} {:>10} {:>12} {:>12} {:>8}",
        "graph", "false", "seed", "kernel", "ATE (m)", "false off", "true off", "time (s)"
    );
    for path in &args.graphs {
        let (clean, reference) = clean_and_reference(path)?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let clean_edges = clean.edge_count();
        for &count in &args.false_loops {
            // Without false loops every seed gives the same graph.
            let seeds = if count == 0 {
                &args.seeds[..1.min(args.seeds.len())]
            } else {
                &args.seeds[..]
            };
            for &seed in seeds {
                let mut graph = clean.clone();
                add_false_loops(
                    &mut graph,
                    FalseLoops {
                        count,
                        max_translation_m: args.max_translation,
                        seed,
                    },
                )
                .with_context(|| format!("cannot add false loops to {}", path.display()))?;
                if let Some(dir) = &args.write_graphs {
                    let out = dir.join(format!("{name}-{count}-{seed}.g2o"));
                    write_atomic(&out, |w| Ok(write_g2o(&graph, w)?))?;
                }
                let row = solve(&name, &graph, &reference, clean_edges, &args, &solver, seed)?;
                print_row(&row, count);
                rows.push(row);
            }
        }
    }
    if let Some(path) = &args.json {
        write_atomic(path, |w| Ok(serde_json::to_writer_pretty(&mut *w, &rows)?))?;
    }
    Ok(())
}

/// The graph of `path` and its least-squares optimum (the reference the
/// corrupted graphs are measured against).
fn clean_and_reference(path: &std::path::Path) -> Result<(PoseGraph, PoseGraph)> {
    let clean = read_pose_graph(path)
        .with_context(|| format!("cannot read pose graph {}", path.display()))?;
    let mut reference = clean.clone();
    optimize(&mut reference, &SolverConfig::default())
        .with_context(|| format!("cannot optimise the clean graph {}", path.display()))?;
    Ok((clean, reference))
}

/// One line of the table on stdout (`count` false loops were added).
fn print_row(row: &Row, count: usize) {
    println!(
        "{:<16} {:>6} {:>4} {:>8} {:>10.6} {:>12} {:>12} {:>8.2}{}",
        row.graph,
        row.false_loops,
        row.seed,
        row.kernel,
        row.ate_m,
        row.false_switched_off
            .map_or("-".into(), |n| format!("{n}/{count}")),
        row.true_switched_off.map_or("-".into(), |n| n.to_string()),
        row.time_s,
        if row.hit_iteration_cap {
            "  (iteration cap)"
        } else {
            ""
        }
    );
}

/// Solves one corrupted graph and measures it against `reference`.
fn solve(
    name: &str,
    graph: &PoseGraph,
    reference: &PoseGraph,
    clean_edges: usize,
    args: &Args,
    solver: &SolverConfig,
    seed: u64,
) -> Result<Row> {
    let mut graph = graph.clone();
    let false_loops = graph.edge_count() - clean_edges;
    let (false_off, true_off, cap, time_s) = match args.method {
        Method::Robust => {
            let summary = optimize_robust(&mut graph, solver, &OutlierConfig::default())
                .with_context(|| format!("robust solve of {name} failed"))?;
            // False loops were appended after the file's edges.
            let false_off = summary
                .switched_off
                .iter()
                .filter(|s| s.edge >= clean_edges)
                .count();
            let true_off = summary.switched_off.len() - false_off;
            (
                Some(false_off),
                Some(true_off),
                summary.hit_iteration_cap(),
                summary.time_s,
            )
        }
        Method::Kernel => {
            let summary =
                optimize(&mut graph, solver).with_context(|| format!("solve of {name} failed"))?;
            (
                None,
                None,
                summary.termination == echofield_backend::Termination::MaxIterations,
                summary.time_s,
            )
        }
    };
    Ok(Row {
        graph: name.to_string(),
        false_loops,
        seed,
        method: args.method,
        kernel: solver.robust.loop_closure.name(),
        ate_m: aligned_position_rmse(&graph.poses(), &reference.poses()),
        false_switched_off: false_off,
        true_switched_off: true_off,
        hit_iteration_cap: cap,
        time_s,
    })
}
