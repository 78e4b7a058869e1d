//! [`run_mission`]: the stages of the module doc of [`crate::slam`], in
//! order, with their timings.

use super::config::SlamConfig;
use super::estimate::Estimate;
use super::evaluation::evaluate;
use super::loops::LoopCloser;
use super::nodes::{NodeData, build_nodes};
use super::refine::refined_navigation;
use super::result::{
    DEAD_RECKONING_RATE_HZ, DeadReckoningReport, IntensityReport, NodeRecord, OutliersReport,
    RejectReason, Report, SequentialRecord, SkippedRotation, SlamOutput, SolverReport,
    StageTimings, TimeGap,
};
use super::{
    ProgressSink, SlamError, check_sensors, health, input_checks, navigation_rate, odometry_scale,
    sequential,
};
use echofield_backend::{RobustSolveSummary, edge_error};
use echofield_frontend::dead_reckoning::{self, Navigation};
use echofield_frontend::intensity::{self, IntensityKind};
use echofield_frontend::rotation::{Rotation, assemble_rotations};
use echofield_frontend::screening;
use echofield_frontend::sensors::{AngleDirection, Mission, MountingSource, SensorMounting};
use echofield_frontend::warnings::{Warning, WarningKind, Warnings};
use echofield_graph::{EdgeKind, PoseGraph, Se2};
use std::borrow::Cow;
use std::collections::{BTreeMap, HashSet};
use std::time::Instant;

/// Scan-only data: [`intensity::prepare_binary`] on the mission's beams and a
/// copy of the config when the beams' intensities are binary; the mission
/// and the config are borrowed as they are otherwise. The effective config
/// (`config.toml`) carries what was derived.
fn prepare_scan_only<'m, 'c>(
    mission: Cow<'m, Mission>,
    config: &'c SlamConfig,
) -> (Cow<'m, Mission>, Cow<'c, SlamConfig>, IntensityReport) {
    let kind = intensity::detect(&mission.beams);
    if !matches!(kind, IntensityKind::Binary { .. }) {
        let report = IntensityReport {
            kind,
            derived: Vec::new(),
        };
        return (mission, Cow::Borrowed(config), report);
    }
    let mut mission = mission.into_owned();
    let mut config = config.clone();
    let derived = intensity::prepare_binary(
        &mut mission.beams,
        &mut config.segmentation,
        &mut config.image,
    );
    let report = IntensityReport { kind, derived };
    (Cow::Owned(mission), Cow::Owned(config), report)
}

/// The warning of a run whose sonar mounting nobody gave: the scans land
/// wherever the assumed mounting puts them, and a wrong one fails without
/// any other sign.
fn mounting_warning(mounting: &SensorMounting) -> Option<Warning> {
    (mounting.source == MountingSource::Assumed).then(|| {
        let message = format!(
            "the mission records no verified sensor mounting: the sonar head was assumed at \
             ({:.2} m, {:.2} m), its angle zero at {:.1} deg, counting {}; give [mounting] in \
             --config, or let `echofield calibrate` estimate it",
            mounting.vehicle_from_sonar.x(),
            mounting.vehicle_from_sonar.y(),
            mounting.vehicle_from_sonar.theta().to_degrees(),
            match mounting.sonar_angle {
                AngleDirection::CounterClockwise => "counter-clockwise",
                AngleDirection::Clockwise => "clockwise",
            }
        );
        Warning::new(WarningKind::MountingAssumed, 1, message)
    })
}

/// A gap between consecutive nodes longer than this many median node
/// periods is reported.
const NODE_GAP_PERIODS: f64 = 3.0;

/// Runs the whole pipeline on `mission` (see [`crate::slam`]).
///
/// Errors: an invalid config; a mission without beams, valid DVL samples
/// or heading; bad records (non-finite values, time going backwards); no
/// rotation the navigation covers; a failed final solve.
pub fn run_mission(
    mission: &Mission,
    config: &SlamConfig,
    progress: &dyn ProgressSink,
) -> Result<SlamOutput, SlamError> {
    let result = run(mission, config, progress);
    progress.finish();
    result
}

fn run(
    mission: &Mission,
    config: &SlamConfig,
    progress: &dyn ProgressSink,
) -> Result<SlamOutput, SlamError> {
    let start = Instant::now();
    config.validate()?;
    let mission = config.mounting.apply(mission).map_err(|e| match e {
        echofield_frontend::FrontendError::InvalidConfig { field, message } => {
            SlamError::config(format!("mounting.{field}"), message)
        }
        other => SlamError::frontend("mounting", other),
    })?;
    let mut input_warnings = mission.warnings.clone();
    let (screened, dropped) =
        screening::screen(&mission).map_err(|e| SlamError::frontend("sensor records", e))?;
    input_warnings.extend(dropped.iter().cloned());
    let screened = match screened {
        Cow::Borrowed(_) => None,
        Cow::Owned(m) => Some(m),
    };
    let mission = screened.map_or(mission, Cow::Owned);
    let (mission, config, intensity) = prepare_scan_only(mission, config);
    let (mission, config): (&Mission, &SlamConfig) = (&mission, &config);
    check_sensors(mission)?;
    let mut timings = StageTimings::default();

    progress.stage("dead reckoning");
    let t = Instant::now();
    let navigation = dead_reckoning::run(mission, &config.dead_reckoning)
        .map_err(|e| SlamError::frontend("dead reckoning", e))?;
    timings.dead_reckoning_s = t.elapsed().as_secs_f64();

    progress.stage("assembling rotations");
    let t = Instant::now();
    let rotations = assemble_rotations(&mission.beams, &config.rotation)
        .map_err(|e| SlamError::frontend("rotation assembly", e))?;
    input_warnings.extend(input_checks::dropped_rotations(&mission.beams, &rotations));
    timings.scan_image_building_s = t.elapsed().as_secs_f64();
    let mut pass = run_pass(
        mission,
        &rotations,
        &navigation,
        &navigation,
        config,
        progress,
        &mut timings,
    )?;
    if config.motion_compensation.refine {
        progress.stage("refining the motion compensation");
        let t = Instant::now();
        let stamps: Vec<f64> = pass.nodes.iter().map(|n| n.stamp_s).collect();
        let dead_reckoning: Vec<Se2> = pass.nodes.iter().map(|n| n.dead_reckoning).collect();
        let compensation = refined_navigation(
            &navigation,
            &stamps,
            &dead_reckoning,
            &pass.graph.poses(),
            config.dead_reckoning.max_extrapolation_s,
        )
        .map_err(|e| SlamError::frontend("refined motion compensation", e))?;
        timings.scan_image_building_s += t.elapsed().as_secs_f64();
        pass = run_pass(
            mission,
            &rotations,
            &navigation,
            &compensation,
            config,
            progress,
            &mut timings,
        )?;
    }
    let Pass {
        nodes,
        skipped,
        sequential,
        estimate,
        mut closer,
        graph,
        summary,
        warnings: pass_warnings,
    } = pass;
    let mut warnings = input_warnings;
    warnings.extend(mounting_warning(&mission.mounting));
    warnings.extend(pass_warnings.iter().cloned());
    if summary.hit_iteration_cap() {
        warnings.push(Warning::new(
            WarningKind::Solver,
            1,
            format!(
                "the final solve stopped at its iteration cap (backend.solver.max_iterations = {}): the trajectory may not be at the optimum",
                config.backend.solver.max_iterations
            ),
        ));
    }

    let mut records: Vec<NodeRecord> = nodes
        .iter()
        .zip(graph.poses())
        .enumerate()
        .map(|(i, (node, optimised))| NodeRecord {
            id: i as u64,
            rotation_index: node.rotation_index,
            stamp_s: node.stamp_s,
            beams: node.beams.clone(),
            dead_reckoning: node.dead_reckoning,
            optimised,
            ground_truth: None,
            scan_points: node.scan.len(),
            in_dvl_gap: node.in_dvl_gap,
        })
        .collect();
    let time_gaps = time_gaps(&navigation, &nodes, &mut warnings);
    yaw_rate_warning(&navigation, &config.dead_reckoning, &mut warnings);
    let odometry_scale = odometry_scale::odometry_scale(&graph);
    warnings.extend(
        odometry_scale
            .as_ref()
            .and_then(odometry_scale::warning)
            .map(|m| Warning::new(WarningKind::OdometryScale, 1, m)),
    );
    let mut loops = std::mem::take(&mut closer.records);
    let mut report = Report {
        run: None,
        mission: mission.name.clone(),
        echofield_version: env!("CARGO_PKG_VERSION").to_string(),
        rotations: rotations.len(),
        nodes: nodes.len(),
        skipped_rotations: skipped,
        nodes_with_scan: nodes.iter().filter(|n| n.has_scan()).count(),
        sequential_matches: sequential.len(),
        sequential_accepted: sequential.iter().filter(|s| s.accepted).count(),
        loop_candidates: loops.len(),
        loop_matches: loops
            .iter()
            .filter(|l| l.rejected_by != Some(RejectReason::Deferred))
            .count(),
        loop_wide_searches: closer.wide_searches,
        matches_run: closer.matches
            + sequential
                .iter()
                .map(|s| {
                    usize::from(s.matched.is_some() || s.no_match.is_some())
                        + usize::from(s.reverse.is_some())
                })
                .sum::<usize>(),
        loops_accepted: loops.iter().filter(|l| l.accepted).count(),
        loop_densified_candidates: loops.iter().filter(|l| l.densified).count(),
        loops_densified: loops.iter().filter(|l| l.densified && l.accepted).count(),
        loop_rejections: rejections(&loops),
        edges: edge_counts(&graph),
        time_s: 0.0,
        timings,
        solver: SolverReport {
            summary: summary.least_squares.clone(),
            outliers: OutliersReport::from(&summary),
            incremental_solves: estimate.incremental_solves,
            incremental_symbolic_reused: estimate.incremental_symbolic_reused,
            incremental_time_s: estimate.incremental_time_s,
        },
        time_gaps,
        dead_reckoning: DeadReckoningReport {
            dvl_gated: navigation.dvl_gated(),
            yaw_rate_noise_radps: navigation.yaw_rate_noise_radps(),
            yaw_rate_check: navigation.yaw_rate_check().copied(),
            odometry_scale,
        },
        mounting: mission.mounting.clone(),
        intensity,
        health: health::assess(&nodes, &records, &sequential, &loops, &mission.mounting),
        warnings,
        ate_rmse_m: None,
        ate_rmse_dead_reckoning_m: None,
        ate: None,
        ate_dead_reckoning: None,
        ate_navigation_rate: None,
        distance_travelled_m: None,
        rpe: None,
        rpe_dead_reckoning: None,
        loop_precision: None,
        loop_recall: None,
        loop_recall_revisits: None,
        loop_evaluation: None,
        definitions: BTreeMap::new(),
    };

    progress.stage("evaluation");
    let t = Instant::now();
    evaluate(
        &mission.ground_truth,
        &nodes,
        &mut records,
        &mut loops,
        config,
        &mut report,
    );
    let dead_reckoning = dense_dead_reckoning(&navigation);
    let dense = navigation_rate::trajectory(&records, &dead_reckoning);
    navigation_rate::evaluate(&mission.ground_truth, &records, &dense, &mut report);
    report.timings.evaluation_s = t.elapsed().as_secs_f64();
    report.time_s = start.elapsed().as_secs_f64();

    let ground_truth = (!mission.ground_truth.is_empty()).then(|| {
        records
            .iter()
            .filter_map(|n| n.ground_truth.map(|g| (n.stamp_s, g)))
            .collect()
    });
    let (scans, images) = nodes.into_iter().map(|n| (n.scan, n.image)).unzip();
    Ok(SlamOutput {
        mission_name: mission.name.clone(),
        config: config.clone(),
        nodes: records,
        graph,
        dead_reckoning,
        ground_truth,
        loops,
        sequential,
        report,
        scans,
        images,
        image_config: config.image.clone(),
    })
}

/// What one pass of node building, matching and optimisation leaves.
struct Pass<'a> {
    nodes: Vec<NodeData>,
    skipped: Vec<SkippedRotation>,
    sequential: Vec<SequentialRecord>,
    estimate: Estimate,
    closer: LoopCloser<'a>,
    graph: PoseGraph,
    summary: RobustSolveSummary,
    warnings: Warnings,
}

/// Builds the nodes with the beams placed by `compensation`, matches them
/// (sequential and loops, with the incremental solves) and runs the final
/// solve; adds its stage times to `timings`.
fn run_pass<'a>(
    mission: &Mission,
    rotations: &[Rotation],
    navigation: &Navigation,
    compensation: &Navigation,
    config: &'a SlamConfig,
    progress: &dyn ProgressSink,
    timings: &mut StageTimings,
) -> Result<Pass<'a>, SlamError> {
    let mut warnings = Warnings::new();
    progress.stage("building scans and images");
    let t = Instant::now();
    let (nodes, skipped) = build_nodes(mission, rotations, navigation, compensation, config)?;
    timings.scan_image_building_s += t.elapsed().as_secs_f64();
    if nodes.is_empty() {
        return Err(SlamError::NoNodes {
            mission: mission.name.clone(),
            reason: skipped
                .first()
                .map_or_else(|| "no rotation".to_string(), |s| s.reason.clone()),
        });
    }
    report_skipped(&skipped, &mut warnings);
    input_checks::scans_and_images(mission, &nodes, config)?;

    progress.stage("sequential matching");
    let t = Instant::now();
    let sequential = sequential::match_all(&nodes, navigation, config)?;
    let mut matching_s = t.elapsed().as_secs_f64();

    progress.start_nodes(nodes.len());
    let t = Instant::now();
    let mut estimate = Estimate::new(&config.backend)?;
    let mut closer = LoopCloser::new(&config.loops, &config.matcher);
    let mut incremental_error = None;
    for k in 0..nodes.len() {
        add_node(
            k,
            &nodes,
            &sequential,
            navigation,
            config,
            &mut estimate,
            &mut closer,
        )?;
        let mut optimise = |estimate: &mut Estimate| -> Result<(), SlamError> {
            if config.backend.incremental {
                // A failed incremental solve leaves the estimate as it was;
                // the final batch solve decides.
                if let Err(e) = estimate.optimise_incremental() {
                    incremental_error.get_or_insert(e.to_string());
                }
            }
            Ok(())
        };
        closer.close_loops(k, &nodes, &mut estimate, &mut optimise)?;
        progress.node_done(k + 1, closer.accepted.ids.len());
    }
    // Densified loops go straight into the final batch solve.
    closer.densify(&nodes, &mut estimate)?;
    closer.finish();
    if let Some(e) = incremental_error {
        warnings.push(Warning::new(
            WarningKind::Solver,
            1,
            format!("an incremental solve failed ({e}); the final batch solve was run anyway"),
        ));
    }
    if closer.inexact_cliques > 0 {
        warnings.push(format!(
            "{} consistency searches stopped at the work limit (the largest clique found by then was used)",
            closer.inexact_cliques
        ));
    }
    let loop_stage_s = t.elapsed().as_secs_f64();

    progress.stage("optimisation");
    let t = Instant::now();
    let (graph, summary) = final_solve(config, &mut estimate, &mut closer)?;
    timings.optimisation_s += t.elapsed().as_secs_f64() + estimate.incremental_time_s;
    matching_s += loop_stage_s - estimate.incremental_time_s - closer.validation_time_s;
    timings.matching_s += matching_s;
    timings.loop_validation_s += closer.validation_time_s;
    Ok(Pass {
        nodes,
        skipped,
        sequential,
        estimate,
        closer,
        graph,
        summary,
        warnings,
    })
}

/// Adds node `k` with its odometry and (accepted) sequential edges; its
/// initial pose follows the previous node's current estimate.
fn add_node(
    k: usize,
    nodes: &[NodeData],
    sequential: &[SequentialRecord],
    navigation: &Navigation,
    config: &SlamConfig,
    estimate: &mut Estimate,
    closer: &mut LoopCloser,
) -> Result<(), SlamError> {
    let node = &nodes[k];
    let heading_var = navigation
        .covariance_at(node.stamp_s)
        .map_err(|e| SlamError::frontend("dead-reckoning covariance", e))?[(2, 2)];
    if k == 0 {
        estimate.add_node(node.stamp_s, node.dead_reckoning);
        closer.chain.push(
            node.dead_reckoning,
            heading_var,
            &nalgebra::Matrix3::zeros(),
        );
        return Ok(());
    }
    let (odometry, odometry_cov) = sequential::odometry(navigation, &nodes[k - 1], node)?;
    let matched = sequential
        .get(k - 1)
        .filter(|s| s.accepted)
        .and_then(|s| Some((s.measurement?, sequential::edge_covariance(s, config)?, s)));
    // The odometry, not the match: its heading is tied to the compass,
    // while chained matches let the heading random-walk.
    let pose = estimate.poses()[k - 1].compose(&odometry);
    estimate.add_node(node.stamp_s, pose);
    let dt_s = node.stamp_s - nodes[k - 1].stamp_s;
    if let Some(sigma) = config
        .backend
        .heading_prior_sigma(&config.dead_reckoning, dt_s)
    {
        estimate.add_heading_prior(k, node.dead_reckoning, sigma)?;
    }
    estimate.add_chain_edge(EdgeKind::Odometry, k - 1, k, odometry, &odometry_cov, None)?;
    if let Some((z, cov, record)) = matched {
        let metadata = record.quality.as_ref().map(|q| {
            serde_json::json!({
                "mean_intensity": q.mean_intensity,
                "inside_fraction": q.inside_fraction,
                "second_peak_ratio": q.second_peak_ratio,
                "points": q.points,
            })
        });
        estimate.add_chain_edge(EdgeKind::Sequential, k - 1, k, z, &cov, metadata)?;
    }
    closer
        .chain
        .push(node.dead_reckoning, heading_var, &odometry_cov);
    Ok(())
}

/// The final solve: `optimize_robust` with the loop edges as suspects.
/// Loops it switches off are rejected (`robust_kernel`) and leave the
/// graph; every accepted loop records its weight under the loop kernel at
/// the solution.
fn final_solve(
    config: &SlamConfig,
    estimate: &mut Estimate,
    closer: &mut LoopCloser,
) -> Result<(PoseGraph, RobustSolveSummary), SlamError> {
    let kernel = config.backend.solver.robust.kernel(EdgeKind::Loop);
    let (mut graph, summary) = estimate.optimise_robust(&config.backend)?;
    let switched: HashSet<(u64, u64)> = summary
        .switched_off
        .iter()
        .map(|s| (s.from, s.to))
        .collect();
    let poses = graph.poses();
    let mut outliers = Vec::new();
    for measurement in closer.accepted_measurements() {
        let (from, to) = (measurement.from as u64, measurement.to as u64);
        let edge = graph
            .edges()
            .find(|e| e.kind == EdgeKind::Loop && e.from == from && e.to == to);
        let Some(edge) = edge else { continue };
        let e = edge_error(edge, &poses[measurement.from], &poses[measurement.to]);
        let (_, weight) = kernel.evaluate(e.dot(&(edge.information * e)));
        closer.records[measurement.id].robust_weight = Some(weight);
        if switched.contains(&(from, to)) {
            outliers.push(measurement.id);
        }
    }
    if !outliers.is_empty() {
        closer.reject(&outliers, RejectReason::RobustKernel, estimate);
        graph = estimate.graph()?;
    }
    Ok((graph, summary))
}

fn report_skipped(skipped: &[SkippedRotation], warnings: &mut Warnings) {
    if let (Some(first), Some(last)) = (skipped.first(), skipped.last()) {
        let message = format!(
            "{} rotations were skipped (rotations {}-{}): {}",
            skipped.len(),
            first.rotation_index,
            last.rotation_index,
            first.reason
        );
        warnings.push(
            Warning::new(WarningKind::RotationsSkipped, skipped.len(), message)
                .at(format!("rotation {}", first.rotation_index)),
        );
    }
}

/// Says when the yaw-rate check raised the yaw-rate noise above the
/// configured one (a gyro that disagrees with the headings).
fn yaw_rate_warning(
    navigation: &Navigation,
    config: &echofield_frontend::dead_reckoning::DeadReckoningConfig,
    warnings: &mut Warnings,
) {
    let used = navigation.yaw_rate_noise_radps();
    if let Some(check) = navigation.yaw_rate_check()
        && used > config.yaw_rate_noise_radps
    {
        let message = format!(
            "the yaw rates disagree with the headings by {:.2}° RMS over {} s windows: dead reckoning used a yaw-rate noise of {used:.3} rad/s instead of the configured {} (dead_reckoning.yaw_rate_check_window_s)",
            check.disagreement_rad.to_degrees(),
            config.yaw_rate_check_window_s,
            config.yaw_rate_noise_radps,
        );
        warnings.push(Warning::new(WarningKind::YawRateNoise, 1, message));
    }
}

/// DVL gaps and long intervals between nodes, bridged by dead reckoning.
fn time_gaps(navigation: &Navigation, nodes: &[NodeData], warnings: &mut Warnings) -> Vec<TimeGap> {
    let mut gaps: Vec<TimeGap> = navigation
        .dvl_gaps()
        .iter()
        .map(|g| TimeGap {
            kind: "dvl".into(),
            start_s: g.start_s,
            end_s: g.end_s,
        })
        .collect();
    let mut periods: Vec<f64> = nodes
        .windows(2)
        .map(|w| w[1].stamp_s - w[0].stamp_s)
        .collect();
    if !periods.is_empty() {
        let mid = periods.len() / 2;
        let median = *periods.select_nth_unstable_by(mid, f64::total_cmp).1;
        gaps.extend(
            nodes
                .windows(2)
                .filter(|w| w[1].stamp_s - w[0].stamp_s > NODE_GAP_PERIODS * median)
                .map(|w| TimeGap {
                    kind: "sonar".into(),
                    start_s: w[0].stamp_s,
                    end_s: w[1].stamp_s,
                }),
        );
    }
    for gap in &gaps {
        let message = format!(
            "no {} data for {:.1} s from t = {:.3} s: bridged by dead reckoning (report.json \
             time_gaps lists every gap)",
            gap.kind,
            gap.end_s - gap.start_s,
            gap.start_s
        );
        warnings.push(
            Warning::new(WarningKind::TimeGap, 1, message).at(format!("t = {:.3} s", gap.start_s)),
        );
    }
    gaps
}

fn rejections(loops: &[super::result::LoopRecord]) -> BTreeMap<RejectReason, usize> {
    let mut out = BTreeMap::new();
    for reason in loops.iter().filter_map(|l| l.rejected_by) {
        *out.entry(reason).or_insert(0) += 1;
    }
    out
}

fn edge_counts(graph: &PoseGraph) -> BTreeMap<String, usize> {
    let mut out = BTreeMap::new();
    for edge in graph.edges() {
        let name = serde_json::to_value(edge.kind)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default();
        *out.entry(name).or_insert(0) += 1;
    }
    out
}

/// The dead-reckoning pose every `1 / DEAD_RECKONING_RATE_HZ` s and at the
/// last step.
fn dense_dead_reckoning(navigation: &Navigation) -> Vec<(f64, Se2)> {
    let (start_s, end_s) = (navigation.start_s(), navigation.end_s());
    let step_s = 1.0 / DEAD_RECKONING_RATE_HZ;
    let count = ((end_s - start_s) / step_s).floor() as usize;
    let mut out: Vec<(f64, Se2)> = (0..=count)
        .filter_map(|i| {
            let t = start_s + i as f64 * step_s;
            navigation.pose_at(t).ok().map(|p| (t, p))
        })
        .collect();
    if out.last().is_none_or(|(t, _)| *t < end_s)
        && let Ok(p) = navigation.pose_at(end_s)
    {
        out.push((end_s, p));
    }
    out
}
