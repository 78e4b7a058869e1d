//! Optimises each pose-graph file given on the command line with the default
//! configuration and prints one summary line per file; with `--repeat N`
//! every file is solved N times and the fastest solve is reported.
//!
//! `cargo run --release -p echofield-backend --example solve_files -- --repeat 20 datasets/posegraph/*.g2o`

use echofield_backend::{SolverConfig, optimize};
use echofield_graph::io::read_pose_graph;
use std::path::Path;

fn main() {
    let config = SolverConfig::default();
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut repeat = 1;
    if let Some(k) = args.iter().position(|a| a == "--repeat") {
        repeat = args.get(k + 1).and_then(|n| n.parse().ok()).unwrap_or(1);
        args.drain(k..(k + 2).min(args.len()));
    }
    for arg in args {
        let graph = match read_pose_graph(Path::new(&arg)) {
            Ok(g) => g,
            Err(e) => {
                eprintln!("{e}");
                continue;
            }
        };
        let mut best = None::<echofield_backend::SolveSummary>;
        for _ in 0..repeat.max(1) {
            match optimize(&mut graph.clone(), &config) {
                Ok(s) if best.as_ref().is_none_or(|b| s.time_s < b.time_s) => best = Some(s),
                Ok(_) => {}
                Err(e) => {
                    println!("{arg}: error {e}");
                    break;
                }
            }
        }
        if let Some(s) = best {
            println!(
                "{arg}: chi2 {:.10} -> {:.10} (initialised {:.6}), {} iterations, {:?}, {:.4} s (init {:.4} s)",
                s.initial_chi2,
                s.final_chi2,
                s.initialised_chi2,
                s.iterations,
                s.termination,
                s.time_s,
                s.initialisation_time_s
            );
        }
    }
}
