//! The built-in demo (`echofield demo`): simulate a mission, keep it in the
//! output folder, run the whole pipeline on it and write every output.

use super::{FOLDER_FILES, write_output_files};
use crate::output::folder::OutputFolder;
use crate::slam::{NoProgress, ProgressSink, RunInfo, SlamConfig, SlamOutput, run_mission};
use anyhow::{Context, Result};
use echofield_datasets::mcap::write_mission;
use echofield_datasets::sim::{Scenario, simulate_mission};
use echofield_frontend::sensors::Mission;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// File name of the simulated mission inside the demo folder.
pub const SIMULATED_MISSION: &str = "simulated_mission.mcap";

/// What the demo did, for its closing summary.
#[derive(Clone, Debug)]
pub struct DemoSummary {
    pub dir: PathBuf,
    /// The simulated input mission (MCAP).
    pub mission_path: PathBuf,
    pub scenario: String,
    pub seed: u64,
    pub beams: usize,
    pub simulation_s: f64,
    /// The pipeline alone (`report.time_s`).
    pub pipeline_s: f64,
    pub writing_s: f64,
    pub output: SlamOutput,
}

impl DemoSummary {
    /// A few lines for the terminal: accuracy, loops and where to look.
    pub fn text(&self) -> String {
        let r = &self.output.report;
        let mut lines = vec![format!(
            "simulated `{}` (seed {}): {} beams in {:.1} s -> {}",
            self.scenario,
            self.seed,
            self.beams,
            self.simulation_s,
            self.mission_path.display()
        )];
        let partial = self
            .output
            .loops
            .iter()
            .filter(|l| l.accepted && l.unconstrained_direction.is_some())
            .count();
        lines.push(format!(
            "SLAM: {} rotations, {} nodes, {} loop candidates, {} loops accepted ({partial} of them partial: one wall, constrained across it); pipeline {:.2} s, outputs {:.2} s",
            r.rotations, r.nodes, r.loop_candidates, r.loops_accepted, self.pipeline_s, self.writing_s
        ));
        if let (Some(ate), Some(dr)) = (r.ate_rmse_m, r.ate_rmse_dead_reckoning_m) {
            let distance = r
                .distance_travelled_m
                .map(|d| format!(" over {d:.0} m ({:.2}% of the distance)", 100.0 * ate / d))
                .unwrap_or_default();
            lines.push(format!(
                "ATE RMSE: {ate:.2} m optimised vs {dr:.2} m dead reckoning{distance}, {:.1}x better",
                dr / ate.max(1e-9)
            ));
        }
        lines.extend(r.loop_summary());
        if let Some(check) = r.dead_reckoning.odometry_scale {
            // Dead reckoning over optimised distance is 1 / scale.
            let excess = 1.0 / check.scale - 1.0;
            let error = check.standard_error / check.scale.powi(2);
            lines.push(format!(
                "DVL scale check: dead reckoning's distances are {:.1} ± {:.1}% {} than the optimised ones \
                 (report.json dead_reckoning.odometry_scale)",
                100.0 * excess.abs(),
                100.0 * error,
                if excess >= 0.0 { "longer" } else { "shorter" }
            ));
        }
        let d = self.dir.display();
        lines.push(format!(
            "look at {d}/trajectory.png, {d}/loops.png and {d}/mosaic.png; \
             open {d}/mission.mcap in Foxglove; numbers in {d}/report.json"
        ));
        lines.join("\n")
    }
}

/// Simulates `scenario` with `seed`, writes it to `dir/simulated_mission.mcap`,
/// runs the pipeline with `config` (read from `config_path`, for the
/// report's `run` block) and writes the outputs into `dir`. The folder is
/// checked before the simulation and written whole (`OutputFolder`): on an
/// error `dir` keeps its previous content.
pub fn run_demo(
    dir: &Path,
    scenario: &Scenario,
    seed: u64,
    config: &SlamConfig,
    config_path: Option<&Path>,
    progress: &dyn ProgressSink,
) -> Result<DemoSummary> {
    let mission_path = dir.join(SIMULATED_MISSION);
    let run = RunInfo::start("demo", &[&mission_path], config_path, dir);
    let folder = OutputFolder::prepare(dir, FOLDER_FILES)?;
    let t = Instant::now();
    let mission = simulate(scenario, seed)?;
    let simulation_s = t.elapsed().as_secs_f64();
    write_mission(&folder.path().join(SIMULATED_MISSION), &mission)
        .with_context(|| format!("cannot write {}", mission_path.display()))?;
    let mut output = run_mission(&mission, config, progress).context("SLAM pipeline")?;
    output.report.run = Some(run);
    let t = Instant::now();
    write_output_files(folder.path(), &output, &mission)?;
    folder.commit()?;
    Ok(DemoSummary {
        dir: dir.to_path_buf(),
        mission_path,
        scenario: scenario.name().to_string(),
        seed,
        beams: mission.beams.len(),
        simulation_s,
        pipeline_s: output.report.time_s,
        writing_s: t.elapsed().as_secs_f64(),
        output,
    })
}

fn simulate(scenario: &Scenario, seed: u64) -> Result<Mission> {
    simulate_mission(scenario, seed)
        .with_context(|| format!("simulating scenario `{}`", scenario.name()))
}

/// A fixture for tests and benchmarks: the built-in scenario `name`
/// simulated with `seed` and run through the pipeline with `config`.
pub fn simulated_run(name: &str, seed: u64, config: &SlamConfig) -> Result<(Mission, SlamOutput)> {
    let scenario =
        Scenario::named(name).with_context(|| format!("cannot set up scenario `{name}`"))?;
    let mission = simulate(&scenario, seed)?;
    let output = run_mission(&mission, config, &NoProgress).context("SLAM pipeline")?;
    Ok((mission, output))
}
