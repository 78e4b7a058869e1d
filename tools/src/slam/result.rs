//! What a SLAM run returns: the optimised graph, one record per node and
//! per loop-closure candidate, the dense dead-reckoning trajectory, the
//! scans and images of the nodes, and the [`Report`] (`report.json`).
//!
//! Frames: every pose named `world_from_...` or listed as a node pose is in
//! the dead-reckoning world frame (origin where the EKF started, axes of the
//! heading reference). The optimised graph keeps node 0 fixed at its
//! dead-reckoning pose, so both trajectories start together. Ground truth
//! is in its own frame (the simulator's world, the DGPS local plane); the
//! evaluation aligns the estimate to it (SE(2), see [`crate::eval`]).

use super::config::SlamConfig;
use super::health::Health;
use super::odometry_scale::OdometryScale;
use crate::eval::{AteStats, RpeStats};
use echofield_backend::SolveSummary;
use echofield_frontend::dead_reckoning::gyro_check::YawRateCheck;
use echofield_frontend::image::{ImageConfig, StoredImage};
use echofield_frontend::intensity::IntensityKind;
use echofield_frontend::scan::Scan;
use echofield_frontend::sensors::SensorMounting;
use echofield_frontend::warnings::Warnings;
use echofield_graph::io::TrajectoryPose;
use echofield_graph::{PoseGraph, Se2};
use serde::Serialize;
use std::collections::BTreeMap;

/// Everything a run produced; the input of `slam::outputs::write_outputs`.
#[derive(Clone, Debug)]
pub struct SlamOutput {
    pub mission_name: String,
    /// The effective configuration (written as `config.toml`).
    pub config: SlamConfig,
    /// One record per node, in node-id order (`nodes[i].id == i`).
    pub nodes: Vec<NodeRecord>,
    /// The optimised pose graph: odometry, sequential and accepted loop
    /// edges (with their match metadata), node 0 fixed.
    pub graph: PoseGraph,
    /// Dense dead-reckoning trajectory `(stamp_s, world_from_vehicle)`, one
    /// pose every `1 / DEAD_RECKONING_RATE_HZ` seconds over the span of the
    /// navigation (plus the last step).
    pub dead_reckoning: Vec<(f64, Se2)>,
    /// Ground truth at the node stamps (`(stamp_s, world_from_vehicle)`,
    /// ground-truth frame) for the nodes it covers; `None` when the mission
    /// has none.
    pub ground_truth: Option<Vec<(f64, Se2)>>,
    /// Every loop-closure candidate that was considered, in the order they
    /// were examined (accepted, rejected and deferred ones).
    pub loops: Vec<LoopRecord>,
    /// One record per attempted sequential match (node `k-1` to `k`).
    pub sequential: Vec<SequentialRecord>,
    /// The content of `report.json`.
    pub report: Report,
    /// `S_k` of each node (points in the node's vehicle frame), indexed
    /// like `nodes`; empty scans for rotations that gave too few ranges.
    pub scans: Vec<Scan>,
    /// `I_k` of each node (in the node's vehicle frame), indexed like
    /// `nodes`; on a long mission most are released (their beams kept):
    /// [`StoredImage::image_once`] builds one for a look without keeping it.
    pub images: Vec<StoredImage>,
    /// The image configuration the images were built with.
    pub image_config: ImageConfig,
    /// An online run's estimates as they were emitted, one per node in node
    /// order (`world_from_vehicle` at the node stamp, same frame as the
    /// nodes); `None` for a batch run. Written as `online_tum.txt` and drawn
    /// in `trajectory.png`.
    pub emitted: Option<Vec<TrajectoryPose>>,
}

impl SlamOutput {
    /// The optimised trajectory at the rate of [`Self::dead_reckoning`],
    /// the node poses merged in ([`crate::slam::navigation_rate`]).
    pub fn navigation_rate_trajectory(&self) -> Vec<(f64, Se2)> {
        crate::slam::navigation_rate::trajectory(&self.nodes, &self.dead_reckoning)
    }
}

/// Rate of [`SlamOutput::dead_reckoning`], Hz.
pub const DEAD_RECKONING_RATE_HZ: f64 = 10.0;

use super::node_record::NodeRecord;
use echofield_frontend::loops::records::{LoopRecord, RejectReason, SequentialRecord};

/// Wall time per stage, seconds.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct StageTimings {
    /// Reading the mission (set by the caller that read it).
    pub reading_s: Option<f64>,
    pub dead_reckoning_s: f64,
    /// Rotation assembly, motion compensation, `S_k` and `I_k`.
    pub scan_image_building_s: f64,
    /// Sequential and loop matches, reverse checks.
    pub matching_s: f64,
    /// Loop gating and mutual consistency.
    pub loop_validation_s: f64,
    /// Incremental and final solves.
    pub optimisation_s: f64,
    /// Evaluation against ground truth.
    pub evaluation_s: f64,
    /// Writing the outputs (set by the writer).
    pub writing_s: Option<f64>,
}

/// The solves of a run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SolverReport {
    /// The final solve (the least-squares solve over the loops that were
    /// not switched off).
    pub summary: SolveSummary,
    /// How the final solve dealt with false loops.
    pub outliers: OutliersReport,
    /// Incremental solves during the mission.
    pub incremental_solves: usize,
    /// Of which reused the symbolic factorisation of the previous one.
    pub incremental_symbolic_reused: usize,
    /// Their total time, s.
    pub incremental_time_s: f64,
}

/// What `echofield_backend::optimize_robust` did in the final solve.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OutliersReport {
    /// Loop edges judged (the suspects).
    pub suspect_edges: usize,
    /// Of which switched off (rejected as `robust_kernel`).
    pub switched_off: usize,
    /// Solves while growing the graph in node order.
    pub growth_steps: usize,
    /// Least-squares solves while switching loops back on.
    pub rounds: usize,
    /// Whether the final solves stopped at their iteration cap.
    pub hit_iteration_cap: bool,
}

impl From<&echofield_backend::RobustSolveSummary> for OutliersReport {
    fn from(s: &echofield_backend::RobustSolveSummary) -> Self {
        Self {
            suspect_edges: s.suspect_edges,
            switched_off: s.switched_off.len(),
            growth_steps: s.growth_steps,
            rounds: s.rounds,
            hit_iteration_cap: s.hit_iteration_cap(),
        }
    }
}

/// The intensity scale found in the beams (`echofield_frontend::intensity`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IntensityReport {
    pub kind: IntensityKind,
    /// Settings derived for binary data (`key = value`), empty otherwise.
    pub derived: Vec<String>,
}

/// A rotation that did not become a node.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SkippedRotation {
    pub rotation_index: usize,
    pub start_s: f64,
    pub end_s: f64,
    pub reason: String,
}

/// What an online run emitted: one estimate per node, each as it was when
/// its rotation completed (`online_tum.txt`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OnlineReport {
    /// Nodes emitted (one per rotation that became a node).
    pub nodes_emitted: usize,
    /// Wall time of the work done per rotation (node building, matching,
    /// loop closing, incremental solves), ms: median, 95th percentile,
    /// maximum.
    pub latency_p50_ms: f64,
    pub latency_p95_ms: f64,
    pub latency_max_ms: f64,
    /// ATE (SE(2)-aligned position RMSE, m) of the emitted estimates
    /// against ground truth, when the mission has it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ate_rmse_m: Option<f64>,
}

/// A long interval without nodes or without DVL, bridged by dead reckoning.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TimeGap {
    /// `dvl` (no valid DVL sample) or `sonar` (no rotation).
    pub kind: String,
    pub start_s: f64,
    pub end_s: f64,
}

/// Loop-closure evaluation against ground truth.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LoopEvaluation {
    /// Accepted loops within the tolerances / not.
    pub true_positives: usize,
    pub false_positives: usize,
    /// The true-positive tolerances: metres and degrees
    /// (`[evaluation] true_positive_translation_m`, `..._rotation_deg`).
    pub tolerance_m: f64,
    pub tolerance_deg: f64,
    /// Median over the accepted loops of the measurement's error against
    /// the ground-truth relative pose: translation, metres, and heading,
    /// degrees (`None` without an accepted loop that the ground truth
    /// covers). Beside the precision, which counts the errors beyond the
    /// tolerances, it says by how much: against a reference whose own
    /// error is near the tolerance (a GPS fix and a compass heading) the
    /// precision counts the reference's error as much as the loops'.
    pub accepted_median_error_m: Option<f64>,
    pub accepted_median_error_deg: Option<f64>,
    /// Revisit nodes (see `definitions`) and those recognised.
    pub recall_nodes: usize,
    pub recalled_nodes: usize,
    /// Node pairs in the recall set (see `definitions`).
    pub recall_pairs: usize,
    /// Of which joined by an accepted true-positive loop edge.
    pub recalled_pairs: usize,
    /// Revisit nodes with no accepted true-positive loop, for inspection.
    pub missed_revisits: Vec<u64>,
    /// Candidates (matched or not) whose match lies within the tolerances.
    pub candidate_true_positives: usize,
    /// Accepted partial loops (`loops.densify_partial`; included in the
    /// counts above), those of them false by the whole-pose verdict, and
    /// those whose constrained components (the translation across the
    /// unconstrained direction, and θ) are within the tolerances.
    pub partial_loops: usize,
    pub partial_false_positives: usize,
    pub partial_constrained_correct: usize,
    /// The recall pairs and those recalled by ground-truth overlap, in
    /// bins of a tenth from `evaluation.recall_min_overlap` up: how recall
    /// falls off as two scans share less.
    pub recall_by_overlap: Vec<RecallBin>,
    /// Where the recall pairs went: recalled, lost by the gate, by the
    /// matcher or before matching.
    pub recall_budget: RecallBudget,
}

/// The recall pairs split by what became of them, each pair counted once
/// (see `definitions` → `recall_budget`). Says whether a mission's recall
/// is lost by the acceptance checks (tune `[loops]`, see `echofield
/// eval-loops`), by the matcher, or before any match.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RecallBudget {
    /// Joined by an accepted true-positive loop (`recalled_pairs`).
    pub recalled: usize,
    /// Matched right at least once (within the true-positive tolerances)
    /// but no right match accepted: what the checks cost.
    pub right_match_rejected: usize,
    /// ... by the check that rejected the last right match of each pair
    /// (the densification pass comes after the mission's).
    pub right_match_rejected_by: BTreeMap<RejectReason, usize>,
    /// Matched, but never right: what the matcher cost.
    pub matched_wrong: usize,
    /// Never matched: not a candidate, never searched (`deferred`), or
    /// no match or no data.
    pub not_matched: usize,
    /// `(recalled + right_match_rejected) / recall pairs`: the recall that
    /// checks which accepted every right match would give on the same
    /// matches. `None` without recall pairs.
    pub gate_ceiling: Option<f64>,
}

/// Recall over the recall pairs whose ground-truth scan overlap lies in
/// `[min_overlap, max_overlap)` (the last bin includes 1).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RecallBin {
    pub min_overlap: f64,
    pub max_overlap: f64,
    pub pairs: usize,
    pub recalled: usize,
}

/// What dead reckoning measured about the navigation sensors and used.
#[derive(Clone, Debug, Serialize)]
pub struct DeadReckoningReport {
    /// Valid DVL samples the innovation gate rejected
    /// (`dead_reckoning.dvl_gate_chi2`).
    pub dvl_gated: usize,
    /// Standard deviation of one yaw-rate sample the filter used, rad/s:
    /// `dead_reckoning.yaw_rate_noise_radps`, or more when the yaw-rate
    /// check measured more.
    pub yaw_rate_noise_radps: f64,
    /// The yaw-rate check (`dead_reckoning.yaw_rate_check_window_s`); none
    /// when it was off or the attitude unit gives no yaw rates.
    pub yaw_rate_check: Option<YawRateCheck>,
    /// The optimised motion against the odometry edges' (a check of the
    /// DVL's scale, [`super::odometry_scale`]); none when the vehicle
    /// hardly moved.
    pub odometry_scale: Option<OdometryScale>,
}

/// Which run wrote an output folder: `report.json` → `run`. With the wall
/// times (`time_s`, `timings`) it is the only part of `report.json` that
/// differs between two runs of the same input and configuration.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct RunInfo {
    /// Unique on one machine: the start time in nanoseconds since the Unix
    /// epoch and the process id, both in hexadecimal (`{ns}-{pid}`).
    pub id: String,
    /// The start of the command, UTC, RFC 3339 with microseconds.
    pub start_time_utc: String,
    /// The subcommand (`run`, `demo`).
    pub command: String,
    /// The input paths (the mission, and keyframes when given), absolute.
    pub inputs: Vec<String>,
    /// The `--config` file, absolute; `None` for the defaults.
    pub config: Option<String>,
    /// The output folder, absolute.
    pub output: String,
    pub echofield_version: String,
}

impl RunInfo {
    /// The run starting now. Paths are made absolute without touching the
    /// file system (as given when that fails).
    pub fn start(
        command: &str,
        inputs: &[&std::path::Path],
        config: Option<&std::path::Path>,
        output: &std::path::Path,
    ) -> Self {
        let now = std::time::SystemTime::now();
        let since_epoch = now
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        let absolute = |p: &std::path::Path| {
            std::path::absolute(p)
                .unwrap_or_else(|_| p.to_path_buf())
                .display()
                .to_string()
        };
        Self {
            id: format!("{:x}-{:x}", since_epoch.as_nanos(), std::process::id()),
            start_time_utc: humantime::format_rfc3339_micros(now).to_string(),
            command: command.to_string(),
            inputs: inputs.iter().map(|p| absolute(p)).collect(),
            config: config.map(absolute),
            output: absolute(output),
            echofield_version: env!("CARGO_PKG_VERSION").to_string(),
        }
    }
}

/// The content of `report.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The run that wrote the folder, set by the command (`echofield run`,
    /// `demo`); `None` for outputs written through the library alone.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub run: Option<RunInfo>,
    pub mission: String,
    pub echofield_version: String,
    /// Rotations assembled from the beams.
    pub rotations: usize,
    /// Nodes of the graph (rotations that could be navigated).
    pub nodes: usize,
    pub skipped_rotations: Vec<SkippedRotation>,
    /// Rotations dropped by the node spacing (`rotation.node_spacing_m`;
    /// 0 without it): `rotations = nodes + skipped + thinned`.
    pub thinned_rotations: usize,
    /// Nodes with a usable scan.
    pub nodes_with_scan: usize,
    pub sequential_matches: usize,
    pub sequential_accepted: usize,
    /// Loop candidates considered (including deferred ones never matched).
    pub loop_candidates: usize,
    /// Candidates actually matched.
    pub loop_matches: usize,
    /// Of which searched over `loops.gate.max_window` as first contacts.
    pub loop_wide_searches: usize,
    /// Scan matches run in all (sequential, loop, reverse).
    pub matches_run: usize,
    /// Node images built again after the residency budget released them
    /// (`echofield_frontend::image::residency`; outputs not counted).
    pub images_rebuilt: usize,
    pub loops_accepted: usize,
    /// Candidates of the densification pass (`loops.densify`; included in
    /// `loop_candidates`) and those accepted (included in `loops_accepted`).
    pub loop_densified_candidates: usize,
    pub loops_densified: usize,
    /// Rejected candidates per reason.
    pub loop_rejections: BTreeMap<RejectReason, usize>,
    /// Edges of the final graph per kind.
    pub edges: BTreeMap<String, usize>,
    /// Wall time of the pipeline (reading and writing excluded), s.
    pub time_s: f64,
    pub timings: StageTimings,
    pub solver: SolverReport,
    pub time_gaps: Vec<TimeGap>,
    pub dead_reckoning: DeadReckoningReport,
    /// The sensor mounting the run used: the mission's, with the config's
    /// `[mounting]` applied.
    pub mounting: SensorMounting,
    /// What the beams' intensities are, and the settings scan-only
    /// (binary) data changed.
    pub intensity: IntensityReport,
    /// What was repaired or looks wrong (stamps re-sorted, implausible
    /// samples dropped, partial rotations dropped, gaps, an assumed
    /// mounting, ...): one entry per kind, `{kind, count, message,
    /// first_record}` ([`echofield_frontend::warnings`]).
    pub warnings: Warnings,
    /// The run's judgement of its own result, without ground truth
    /// ([`super::health`]).
    pub health: Health,
    /// With ground truth: ATE RMSE of the optimised nodes after SE(2)
    /// alignment, metres.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ate_rmse_m: Option<f64>,
    /// ... of the dead-reckoning poses at the same stamps.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ate_rmse_dead_reckoning_m: Option<f64>,
    /// Full ATE statistics (optimised, dead reckoning).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ate: Option<AteStats>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ate_dead_reckoning: Option<AteStats>,
    /// ATE of the optimised trajectory at the navigation's rate
    /// ([`navigation_rate`](crate::slam::navigation_rate)) over the
    /// ground-truth samples between the first and the last node.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ate_navigation_rate: Option<AteStats>,
    /// Ground-truth path length over the span of the nodes, metres.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub distance_travelled_m: Option<f64>,
    /// Relative pose error per distance (optimised, dead reckoning).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rpe: Option<Vec<RpeStats>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rpe_dead_reckoning: Option<Vec<RpeStats>>,
    /// True positives / accepted loops; 1 when none is accepted (no
    /// accepted loop is wrong). Present whenever the mission has ground
    /// truth.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub loop_precision: Option<f64>,
    /// Recall pairs joined by an accepted true-positive loop / recall
    /// pairs: node pairs whose ground-truth scan overlap reaches
    /// `evaluation.recall_min_overlap` (see `definitions`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub loop_recall: Option<f64>,
    /// Recognised revisit nodes / revisit nodes: the newer node of a recall
    /// pair that is the newer node of an accepted true-positive loop (see
    /// `definitions`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub loop_recall_revisits: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub loop_evaluation: Option<LoopEvaluation>,
    /// The estimates the engine emitted while the run went on (`echofield
    /// run --online`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub online: Option<OnlineReport>,
    /// How each evaluation number is defined, in words.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub definitions: BTreeMap<String, String>,
}

impl Report {
    /// One line on the loop closures against ground truth, for terminal
    /// summaries: precision, recall over node pairs and revisits, and the
    /// recall budget's gate ceiling. `None` without ground truth.
    pub fn loop_summary(&self) -> Option<String> {
        let (precision, recall) = (self.loop_precision?, self.loop_recall?);
        let mut line = format!("loop closures: precision {precision:.3}");
        if let Some(e) = &self.loop_evaluation {
            line += &format!(" (within {} m and {}°", e.tolerance_m, e.tolerance_deg);
            if let (Some(m), Some(deg)) = (e.accepted_median_error_m, e.accepted_median_error_deg) {
                line += &format!("; accepted loops' median error {m:.2} m, {deg:.1}°");
            }
            line += ")";
        }
        line += &format!(", recall {recall:.3} of the overlapping node pairs");
        if let Some(revisits) = self.loop_recall_revisits {
            line += &format!(", {revisits:.3} of the revisits");
        }
        let budget = self.loop_evaluation.as_ref().map(|e| &e.recall_budget);
        if let Some(ceiling) = budget.and_then(|b| b.gate_ceiling) {
            line += &format!(
                "; {ceiling:.3} if the checks accepted every right match \
                 (report.json loop_evaluation.recall_budget)"
            );
        }
        Some(line)
    }
}
