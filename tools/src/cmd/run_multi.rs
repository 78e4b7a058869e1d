//! `echofield run A B ...`: several missions merged into one map
//! (`echofield::slam::multi`). Reads every mission, runs and merges them,
//! and writes the folder of `slam::multi::outputs`, checked before any
//! work and replaced whole as a single run's.

use super::run::{Args, BarProgress, print_channels};
use anyhow::{Context, Result, bail};
use echofield::output::folder::OutputFolder;
use echofield::slam::multi::{MultiReport, outputs, run_missions};
use echofield::slam::{RunInfo, SlamConfig, load_mission_choosing};
use echofield_datasets::mcap::TopicChoice;
use std::path::Path;
use std::time::Instant;

pub fn run(args: Args) -> Result<()> {
    if args.keyframes.is_some() {
        bail!(
            "--keyframes takes one St Pere folder: with several missions, convert each first (echofield convert stpere ... --keyframes KF_DIR --output M.mcap)"
        );
    }
    if args.online {
        bail!("--online runs one mission: give one mission, or leave --online out");
    }
    let paths: Vec<&Path> = std::iter::once(args.mission.as_path())
        .chain(args.more_missions.iter().map(|p| p.as_path()))
        .collect();
    let run_info = RunInfo::start("run", &paths, args.config.as_deref(), &args.output);
    super::set_threads(args.threads)?;
    let config = SlamConfig::from_optional_toml_file(args.config.as_deref())?;
    let known = outputs::folder_files();
    let known: Vec<&str> = known.iter().map(String::as_str).collect();
    let folder = OutputFolder::prepare(&args.output, &known)?;
    let start = Instant::now();
    let mut choice = TopicChoice::default();
    for (role, topic) in &args.topics {
        choice.topics[*role] = Some(topic.clone());
    }
    let mut missions = Vec::with_capacity(paths.len());
    for path in &paths {
        let (mission, channels) = load_mission_choosing(path, &choice)?;
        print_channels(&channels);
        missions.push(mission);
    }
    let progress = BarProgress::new();
    let mut output = run_missions(&missions, &config, &progress)
        .with_context(|| format!("SLAM on {} missions failed", missions.len()))?;
    output.report.run = Some(run_info);
    outputs::write_files(folder.path(), &output)
        .and_then(|()| folder.commit())
        .with_context(|| format!("cannot write the outputs into {}", args.output.display()))?;
    print_summary(&output.report, start.elapsed().as_secs_f64(), &args.output);
    for (run, path) in output.runs.iter().zip(&paths) {
        super::check_health(
            &run.report.health,
            &path.display().to_string(),
            args.allow_suspect,
        )?;
    }
    Ok(())
}

/// One line per mission (nodes, loops, ATE, merged or not, the fate of
/// its position fixes), then the
/// merged graph's line; `elapsed_s` since the missions were loaded.
fn print_summary(report: &MultiReport, elapsed_s: f64, output: &Path) {
    for m in &report.missions {
        println!(
            "mission {} ({}): {} nodes, {} loops{}{}{}",
            m.mission,
            m.name,
            m.nodes,
            m.loops_accepted,
            m.ate_rmse_m
                .map_or(String::new(), |a| format!(", ATE alone {a:.3} m")),
            if m.mission == report.anchor {
                ", the anchor (its frame is the map frame)".to_string()
            } else if m.merged {
                m.merged_ate_rmse_m.map_or(", merged".to_string(), |a| {
                    format!(", merged (ATE {a:.3} m)")
                })
            } else {
                ", NOT merged (no placement)".to_string()
            },
            m.fix_prior.map_or(String::new(), |p| format!(
                "; {} fixes: {}",
                m.position_fixes,
                p.describe()
            ))
        );
    }
    if report.merged {
        println!(
            "merged graph: {} nodes, {} of {} cross-mission loop candidates accepted{}; {:.2} s; outputs in {}",
            report.merged_nodes,
            report.cross_loops_accepted,
            report.cross_loop_candidates,
            report.merged_ate_rmse_m.map_or(String::new(), |a| format!(
                ", ATE of all missions together {a:.3} m"
            )),
            elapsed_s,
            output.display()
        );
    } else {
        println!(
            "no mission could be placed on the anchor's map (mission {}): each mission's own result is in {}",
            report.anchor,
            output.display()
        );
    }
}
