//! The output of a finished run and its [`Report`].

use super::super::SlamEngine;
use crate::slam::estimate::Estimate;
use crate::slam::evaluation::evaluate;
use crate::slam::loops::LoopCloser;
use crate::slam::node_record::NodeRecord;
use crate::slam::odometry_scale::OdometryScale;
use crate::slam::result::{
    DEAD_RECKONING_RATE_HZ, DeadReckoningReport, IntensityReport, OutliersReport, Report,
    SkippedRotation, SlamOutput, SolverReport, StageTimings, TimeGap,
};
use crate::slam::{SlamConfig, SlamError, health, input_checks, navigation_rate, odometry_scale};
use echofield_backend::RobustSolveSummary;
use echofield_frontend::dead_reckoning::{DeadReckoningConfig, Navigation};
use echofield_frontend::loops::{LoopRecord, RejectReason, SequentialRecord};
use echofield_frontend::nodes::NodeData;
use echofield_frontend::sensors::{
    AngleDirection, GroundTruthPose, MountingSource, SensorMounting,
};
use echofield_frontend::warnings::{Warning, WarningKind, Warnings};
use echofield_graph::{PoseGraph, Se2};
use std::collections::BTreeMap;
use std::time::Instant;

/// A gap between consecutive nodes longer than this many median node
/// periods is reported.
const NODE_GAP_PERIODS: f64 = 3.0;

impl<'c> SlamEngine<'c> {
    /// The output of the run after the final solve (`graph`, `summary`,
    /// which took `final_solve_s`), with the warnings of the finish.
    /// Errors when the navigation cannot be finished.
    pub(super) fn output(
        mut self,
        graph: PoseGraph,
        summary: RobustSolveSummary,
        final_solve_s: f64,
        finish_warnings: Warnings,
        ground_truth: &[GroundTruthPose],
    ) -> Result<SlamOutput, SlamError> {
        let (started, config, emitted) = (self.started, self.config, self.emitted.take());
        let (mut run, extras) = self.finished(graph, summary, final_solve_s, finish_warnings)?;
        let mut report = unevaluated_report(&run, extras);
        let dead_reckoning = evaluate_run(
            ground_truth,
            &run.nodes,
            &mut run.records,
            &mut run.loops,
            config,
            &run.navigation,
            &mut report,
        );
        report.time_s = started.elapsed().as_secs_f64();
        let ground_truth = (!ground_truth.is_empty()).then(|| {
            run.records
                .iter()
                .filter_map(|n| n.ground_truth.map(|g| (n.stamp_s, g)))
                .collect()
        });
        let (scans, images) = run.nodes.into_iter().map(|n| (n.scan, n.image)).unzip();
        Ok(SlamOutput {
            mission_name: run.mission_name,
            config: config.clone(),
            nodes: run.records,
            graph: run.graph,
            dead_reckoning,
            ground_truth,
            loops: run.loops,
            sequential: run.sequential,
            report,
            scans,
            images,
            image_config: config.image.clone(),
            emitted,
        })
    }

    /// The engine taken apart after the final solve: the finished run and
    /// what its report takes over (warnings of the input, of the finish and
    /// of the final graph; stage timings; time gaps).
    fn finished(
        self,
        graph: PoseGraph,
        summary: RobustSolveSummary,
        final_solve_s: f64,
        finish_warnings: Warnings,
    ) -> Result<(Finished<'c>, ReportExtras), SlamError> {
        let mut warnings = self.input_warnings(&summary, finish_warnings);
        let navigation = self.navigation.finish()?;
        let graph_state = self.graph;
        let records = node_records(&graph_state.nodes, &graph);
        let time_gaps = time_gaps(&navigation, &graph_state.nodes, &mut warnings);
        yaw_rate_warning(&navigation, &self.config.dead_reckoning, &mut warnings);
        let odometry_scale = odometry_scale_checked(&graph, &mut warnings);
        let mut closer = graph_state.closer;
        let loops = std::mem::take(&mut closer.records);
        let estimate = graph_state.estimate;
        let matching_s = graph_state.sequential_s
            + (graph_state.loops_s - estimate.incremental_time_s - closer.validation_time_s)
                .max(0.0);
        let timings = StageTimings {
            matching_s,
            loop_validation_s: closer.validation_time_s,
            optimisation_s: final_solve_s + estimate.incremental_time_s,
            ..self.timings
        };
        let extras = ReportExtras {
            skipped: self.skipped,
            thinned: self.spacing.thinned(),
            timings,
            time_gaps,
            odometry_scale,
            warnings,
        };
        let run = Finished {
            mission_name: self.mission_name,
            rotations: self.rotation_ranges.len(),
            mounting: self.mounting,
            intensity: self.input.intensity,
            nodes: graph_state.nodes,
            records,
            sequential: graph_state.sequential,
            loops,
            closer,
            estimate,
            graph,
            summary,
            navigation,
        };
        Ok((run, extras))
    }
}

/// The odometry scale of the final graph ([`odometry_scale`]), with its
/// warning when it is off.
fn odometry_scale_checked(graph: &PoseGraph, warnings: &mut Warnings) -> Option<OdometryScale> {
    let scale = odometry_scale::odometry_scale(graph);
    warnings.extend(
        scale
            .as_ref()
            .and_then(odometry_scale::warning)
            .map(|m| Warning::new(WarningKind::OdometryScale, 1, m)),
    );
    scale
}

/// The evaluation against `ground_truth` (nothing without it) into
/// `report`, `records` and `loops`, timed; returns the dense dead-reckoning
/// trajectory (at [`DEAD_RECKONING_RATE_HZ`]) it compares too.
fn evaluate_run(
    ground_truth: &[GroundTruthPose],
    nodes: &[NodeData],
    records: &mut [NodeRecord],
    loops: &mut [LoopRecord],
    config: &SlamConfig,
    navigation: &Navigation,
    report: &mut Report,
) -> Vec<(f64, Se2)> {
    let t = Instant::now();
    evaluate(ground_truth, nodes, records, loops, config, report);
    let dead_reckoning = dense_dead_reckoning(navigation);
    let dense = navigation_rate::trajectory(records, &dead_reckoning);
    navigation_rate::evaluate(ground_truth, records, &dense, report);
    report.timings.evaluation_s = t.elapsed().as_secs_f64();
    dead_reckoning
}

/// The finished run: the engine's mission, the nodes and their records,
/// the matches, the final graph and solve, the navigation.
struct Finished<'c> {
    mission_name: String,
    rotations: usize,
    mounting: SensorMounting,
    intensity: IntensityReport,
    nodes: Vec<NodeData>,
    records: Vec<NodeRecord>,
    sequential: Vec<SequentialRecord>,
    loops: Vec<LoopRecord>,
    closer: LoopCloser<'c>,
    estimate: Estimate,
    graph: PoseGraph,
    summary: RobustSolveSummary,
    navigation: Navigation,
}

/// What the report takes over from the finish.
struct ReportExtras {
    skipped: Vec<SkippedRotation>,
    /// Rotations the node spacing dropped.
    thinned: usize,
    timings: StageTimings,
    time_gaps: Vec<TimeGap>,
    odometry_scale: Option<OdometryScale>,
    warnings: Warnings,
}

/// The report before the evaluation against ground truth: every field the
/// run itself gives, the evaluation's fields `None`, `time_s` 0 (set when
/// the output is complete). One field per line: a struct literal.
fn unevaluated_report(run: &Finished, extras: ReportExtras) -> Report {
    let (loops, sequential, navigation) = (&run.loops, &run.sequential, &run.navigation);
    Report {
        run: None,
        mission: run.mission_name.clone(),
        echofield_version: env!("CARGO_PKG_VERSION").to_string(),
        rotations: run.rotations,
        nodes: run.nodes.len(),
        skipped_rotations: extras.skipped,
        thinned_rotations: extras.thinned,
        nodes_with_scan: run.nodes.iter().filter(|n| n.has_scan()).count(),
        sequential_matches: sequential.len(),
        sequential_accepted: sequential.iter().filter(|s| s.accepted).count(),
        loop_candidates: loops.len(),
        loop_matches: loops
            .iter()
            .filter(|l| l.rejected_by != Some(RejectReason::Deferred))
            .count(),
        loop_wide_searches: run.closer.wide_searches,
        matches_run: run.closer.matches + sequential_matches_run(sequential),
        images_rebuilt: run.nodes.iter().map(|n| n.image.rebuilds()).sum(),
        loops_accepted: loops.iter().filter(|l| l.accepted).count(),
        loop_densified_candidates: loops.iter().filter(|l| l.densified).count(),
        loops_densified: loops.iter().filter(|l| l.densified && l.accepted).count(),
        loop_rejections: rejections(loops),
        edges: edge_counts(&run.graph),
        time_s: 0.0,
        timings: extras.timings,
        solver: SolverReport {
            summary: run.summary.least_squares.clone(),
            outliers: OutliersReport::from(&run.summary),
            incremental_solves: run.estimate.incremental_solves,
            incremental_symbolic_reused: run.estimate.incremental_symbolic_reused,
            incremental_time_s: run.estimate.incremental_time_s,
        },
        time_gaps: extras.time_gaps,
        dead_reckoning: DeadReckoningReport {
            dvl_gated: navigation.dvl_gated(),
            yaw_rate_noise_radps: navigation.yaw_rate_noise_radps(),
            yaw_rate_check: navigation.yaw_rate_check().copied(),
            odometry_scale: extras.odometry_scale,
        },
        mounting: run.mounting.clone(),
        intensity: run.intensity.clone(),
        health: health::assess(&run.nodes, &run.records, sequential, loops, &run.mounting),
        warnings: extras.warnings,
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
        online: None,
        definitions: BTreeMap::new(),
    }
}

impl SlamEngine<'_> {
    /// The warnings about the input and the run, in the order of the
    /// stages: the caller's, dropped and skipped rotations, the mounting,
    /// late navigation samples, the finish's, the final solve's.
    fn input_warnings(&self, summary: &RobustSolveSummary, finish: Warnings) -> Warnings {
        let mut warnings = self.input.warnings.clone();
        warnings.extend(input_checks::dropped_rotations(&self.rotation_ranges));
        warnings.extend(mounting_warning(&self.mounting));
        report_skipped(&self.skipped, &mut warnings);
        let late = self.navigation.late_samples();
        if late > 0 {
            warnings.push(Warning::new(
                WarningKind::StampsResorted,
                late,
                format!("{late} DVL or attitude samples came after a later sample of the other stream and were skipped (push samples in time order)"),
            ));
        }
        warnings.extend(finish.iter().cloned());
        if summary.hit_iteration_cap() {
            warnings.push(Warning::new(
                WarningKind::Solver,
                1,
                format!(
                    "the final solve stopped at its iteration cap (backend.solver.max_iterations = {}): the trajectory may not be at the optimum",
                    self.config.backend.solver.max_iterations
                ),
            ));
        }
        warnings
    }
}

fn node_records(nodes: &[NodeData], graph: &PoseGraph) -> Vec<NodeRecord> {
    nodes
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
        .collect()
}

/// Sequential matches run, forward and reverse.
fn sequential_matches_run(sequential: &[SequentialRecord]) -> usize {
    sequential
        .iter()
        .map(|s| {
            usize::from(s.matched.is_some() || s.no_match.is_some())
                + usize::from(s.reverse.is_some())
        })
        .sum()
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
    config: &DeadReckoningConfig,
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

fn rejections(loops: &[LoopRecord]) -> BTreeMap<RejectReason, usize> {
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
