//! Evaluation of a run against the mission's ground truth. Runs after the
//! estimation is finished; nothing here feeds back into it.
//!
//! Definitions (also written into `report.json` under `definitions`):
//! - **ATE**: RMSE of the position error of the optimised node poses (and,
//!   for comparison, of the dead-reckoning poses at the same stamps)
//!   against the ground truth interpolated at the node stamps, after the
//!   best SE(2) alignment ([`crate::eval::ate`]).
//! - **RPE** per distance: [`crate::eval::rpe`] over the node poses.
//! - **Distance travelled**: the ground-truth path length between the first
//!   and the last node stamp (every ground-truth sample in between).
//! - **True positive loop**: its measurement (`from_from_to` of the edge)
//!   is within
//!   `true_positive_translation_m` and `true_positive_rotation_deg` of the
//!   ground-truth relative pose. **Precision** = true positives / accepted
//!   loops (1 when none is accepted). A partial loop
//!   (`loops.densify_partial`) is judged the same way, on its whole
//!   measurement, although its component along the unconstrained
//!   direction is the estimate's; `loop_evaluation` also counts how many
//!   partial loops are right on their constrained components alone
//!   (translation across that direction, and heading).
//! - **Ground-truth scan overlap** of a node pair `(j, k)`: the fraction of
//!   the points of `S_k`, placed in `j`'s frame with the ground-truth
//!   relative pose, that fall in a cell of side `overlap_distance_m`
//!   holding a point of `S_j` or next to such a cell (so within about
//!   1-2 cell sides of a point of `S_j`): the share of what `k` saw that
//!   `j` saw too ([`echofield_frontend::scan::overlap`]; `echofield
//!   bench-matcher` draws its pairs by the same measure).
//! - **Recall pairs**: node pairs `(j, k)` with `k - j >=
//!   loops.min_separation_nodes` and ground-truth scan overlap at least
//!   `recall_min_overlap` (default 0.4, the lowest overlap at which a
//!   correctly registered pair passes the loop quality gate, see
//!   [`super::config::EvaluationConfig`]), whether or not the pipeline
//!   picked them as candidates.
//! - **Recall** (`loop_recall`) = recall pairs joined by an accepted
//!   true-positive loop / recall pairs. While the mission runs the
//!   pipeline matches each node against at most
//!   `loops.max_candidates_per_node` older ones, while a return to a known
//!   place overlaps many older nodes; the pairs left are matched after the
//!   mission only with `loops.densify`, without which this pair-level
//!   figure stays well below 1.
//! - A **revisit** is a node `k` that is the newer node of at least one
//!   recall pair: the vehicle is back where it has been. **Revisit
//!   recall** (`loop_recall_revisits`) = revisits that are the newer node
//!   of at least one accepted true-positive loop / revisits: how many of
//!   the returns to a known place the pipeline recognised.
//! - **Recall by overlap** (`loop_evaluation.recall_by_overlap`): the
//!   recall pairs and those recalled in bins of ground-truth overlap, a
//!   tenth wide from `recall_min_overlap` up. Pairs that share little are
//!   the hard ones (EXPERIMENTS.md § Evaluation).
//! - **Recall budget** (`loop_evaluation.recall_budget`): each recall pair
//!   once, as recalled; matched right at least once but never accepted
//!   right (`right_match_rejected`, by the check that rejected its last
//!   right match); matched but never right (`matched_wrong`); or never
//!   matched (`not_matched`). `gate_ceiling` is the recall if the checks
//!   accepted every right match: what tuning `[loops]` can reach at best
//!   with the same matches.

use super::config::{EvaluationConfig, SlamConfig};
use super::health::evidence::median;
use super::node_record::NodeRecord;
use super::result::{LoopEvaluation, RecallBin, RecallBudget, Report};
use crate::eval::{Alignment, ate, cumulative_distance, rpe};
use crate::matching::ground_truth_at;
use echofield_frontend::loops::{LoopRecord, RejectReason};
use echofield_frontend::nodes::NodeData;
use echofield_frontend::scan::overlap::ScanCells;
use echofield_frontend::sensors::GroundTruthPose;
use echofield_graph::Se2;
use echofield_graph::io::TrajectoryPose;
use std::collections::{BTreeMap, HashMap, HashSet};

/// Time tolerance of the ATE/RPE association between a node's pose and its
/// ground truth: stamps of the same node agree exactly, so any small value
/// works (also used by [`super::error_budget`]).
pub(crate) const MAX_TIME_DIFF_S: f64 = 1e-3;

/// Fills the ground-truth fields of `nodes`, `loops` and `report`. Does
/// nothing when `ground_truth` is empty.
pub fn evaluate(
    ground_truth: &[GroundTruthPose],
    node_data: &[NodeData],
    nodes: &mut [NodeRecord],
    loops: &mut [LoopRecord],
    config: &SlamConfig,
    report: &mut Report,
) {
    if ground_truth.is_empty() {
        return;
    }
    for node in nodes.iter_mut() {
        node.ground_truth = ground_truth_at(ground_truth, node.stamp_s);
    }
    trajectory_errors(ground_truth, nodes, config, report);
    let eval = &config.evaluation;
    let truth = PairTruth::new(nodes, node_data, eval.overlap_distance_m);
    let verdicts = judge_loops(loops, &truth, eval);
    let recall = recall(loops, &truth, &verdicts, config);
    // No accepted loop: no false positive, precision 1 by convention (the
    // counts in `loop_evaluation` show that nothing was accepted).
    let (tp, fp) = (verdicts.true_positives, verdicts.false_positives);
    report.loop_precision = Some(if tp + fp > 0 {
        tp as f64 / (tp + fp) as f64
    } else {
        1.0
    });
    let mut budget = recall.budget;
    let (pairs, recalled_pairs) = (recall.pairs, budget.recalled);
    report.loop_recall = (pairs > 0).then(|| recalled_pairs as f64 / pairs as f64);
    budget.gate_ceiling =
        (pairs > 0).then(|| (budget.recalled + budget.right_match_rejected) as f64 / pairs as f64);
    report.loop_recall_revisits =
        (recall.nodes > 0).then(|| recall.recalled_nodes as f64 / recall.nodes as f64);
    let accepted = || loops.iter().filter(|r| r.accepted);
    let median_of = |mut v: Vec<f64>| median(&mut v);
    report.loop_evaluation = Some(LoopEvaluation {
        true_positives: tp,
        false_positives: fp,
        tolerance_m: eval.true_positive_translation_m,
        tolerance_deg: eval.true_positive_rotation_deg,
        accepted_median_error_m: median_of(accepted().filter_map(|r| r.gt_error_m).collect()),
        accepted_median_error_deg: median_of(accepted().filter_map(|r| r.gt_error_deg).collect()),
        recall_nodes: recall.nodes,
        recalled_nodes: recall.recalled_nodes,
        recall_pairs: pairs,
        recalled_pairs,
        missed_revisits: recall.missed_revisits,
        candidate_true_positives: verdicts.candidate_true_positives,
        partial_loops: verdicts.partial,
        partial_false_positives: verdicts.partial_false_positives,
        partial_constrained_correct: verdicts.partial_constrained_correct,
        recall_by_overlap: recall.by_overlap,
        recall_budget: budget,
    });
    report.definitions = definitions(config);
}

/// The ground truth of node pairs: relative poses and scan overlaps.
struct PairTruth<'a> {
    /// Ground-truth pose per node (`None` outside the ground truth).
    poses: Vec<Option<Se2>>,
    node_data: &'a [NodeData],
    /// Each node's scan as occupied cells (overlap of the module doc,
    /// [`echofield_frontend::scan::overlap`]).
    grids: Vec<ScanCells>,
}

impl<'a> PairTruth<'a> {
    fn new(nodes: &[NodeRecord], node_data: &'a [NodeData], cell_m: f64) -> Self {
        Self {
            poses: nodes.iter().map(|n| n.ground_truth).collect(),
            node_data,
            grids: node_data
                .iter()
                .map(|n| ScanCells::new(&n.scan.points, cell_m))
                .collect(),
        }
    }

    /// Ground-truth `j_from_k`.
    fn relative(&self, j: usize, k: usize) -> Option<Se2> {
        Some(self.poses[j]?.between(&self.poses[k]?))
    }

    /// Ground-truth scan overlap of `(j, k)` (0 when the footprints are
    /// too far apart to meet).
    fn overlap(&self, j: usize, k: usize) -> Option<f64> {
        let j_from_k = self.relative(j, k)?;
        let reach = self.node_data[j].footprint_m + self.node_data[k].footprint_m;
        if j_from_k.translation().norm() > reach {
            return Some(0.0);
        }
        Some(self.grids[j].overlap(&self.node_data[k].scan.points, &j_from_k))
    }
}

/// The verdicts on the examined loop candidates.
#[derive(Default)]
struct LoopVerdicts {
    true_positives: usize,
    false_positives: usize,
    candidate_true_positives: usize,
    partial: usize,
    partial_false_positives: usize,
    partial_constrained_correct: usize,
    /// The pairs `(j, k)` joined by an accepted true-positive loop.
    true_positive_pairs: HashSet<(usize, usize)>,
}

/// Fills each loop record's ground-truth fields and judges it against the
/// true-positive tolerances (module doc).
fn judge_loops(
    loops: &mut [LoopRecord],
    truth: &PairTruth,
    eval: &EvaluationConfig,
) -> LoopVerdicts {
    let mut v = LoopVerdicts::default();
    let within = |translation_m: f64, error: &Se2| {
        translation_m <= eval.true_positive_translation_m
            && error.theta().abs().to_degrees() <= eval.true_positive_rotation_deg
    };
    for record in loops.iter_mut() {
        let (j, k) = (record.from as usize, record.to as usize);
        record.ground_truth = truth.relative(j, k);
        record.gt_overlap = truth.overlap(j, k);
        let (Some(gt), Some(matched)) = (record.ground_truth, record.measurement) else {
            continue;
        };
        let error = gt.between(&matched);
        record.gt_error_m = Some(error.translation().norm());
        record.gt_error_deg = Some(error.theta().abs().to_degrees());
        let is_tp = within(error.translation().norm(), &error);
        record.true_positive = Some(is_tp);
        v.candidate_true_positives += usize::from(is_tp);
        if !record.accepted {
            continue;
        }
        if is_tp {
            v.true_positives += 1;
            v.true_positive_pairs.insert((j, k));
        } else {
            v.false_positives += 1;
        }
        if let Some([ux, uy]) = record.unconstrained_direction {
            v.partial += 1;
            v.partial_false_positives += usize::from(!is_tp);
            // The error across the unconstrained direction, in `from`'s
            // frame like the direction.
            let across = (matched.translation() - gt.translation())
                .dot(&nalgebra::Vector2::new(-uy, ux))
                .abs();
            v.partial_constrained_correct += usize::from(within(across, &error));
        }
    }
    v
}

/// The recall figures over the recall pairs (module doc).
struct Recall {
    pairs: usize,
    nodes: usize,
    recalled_nodes: usize,
    missed_revisits: Vec<u64>,
    by_overlap: Vec<RecallBin>,
    budget: RecallBudget,
}

/// Every recall pair's fate, from the judged `loops` (after
/// [`judge_loops`]), and the revisits.
fn recall(
    loops: &[LoopRecord],
    truth: &PairTruth,
    verdicts: &LoopVerdicts,
    config: &SlamConfig,
) -> Recall {
    let eval = &config.evaluation;
    let mut outcomes: HashMap<(usize, usize), Vec<MatchOutcome>> = HashMap::new();
    for record in loops {
        outcomes
            .entry((record.from as usize, record.to as usize))
            .or_default()
            .push(MatchOutcome::of(record));
    }
    let mut r = Recall {
        pairs: 0,
        nodes: 0,
        recalled_nodes: 0,
        missed_revisits: Vec::new(),
        by_overlap: overlap_bins(eval.recall_min_overlap),
        budget: RecallBudget::default(),
    };
    let min_separation = config.loops.min_separation_nodes;
    let closed: HashSet<usize> = verdicts
        .true_positive_pairs
        .iter()
        .map(|&(_, k)| k)
        .collect();
    for k in min_separation..truth.poses.len() {
        let mut revisit = false;
        for j in 0..=k - min_separation {
            let Some(o) = truth
                .overlap(j, k)
                .filter(|&o| o >= eval.recall_min_overlap)
            else {
                continue;
            };
            revisit = true;
            let pair_outcomes = outcomes.get(&(j, k)).map_or(&[][..], Vec::as_slice);
            r.count_pair(o, PairFate::of(pair_outcomes));
        }
        if revisit {
            r.nodes += 1;
            if closed.contains(&k) {
                r.recalled_nodes += 1;
            } else {
                r.missed_revisits.push(k as u64);
            }
        }
    }
    r
}

impl Recall {
    /// Counts one recall pair of ground-truth overlap `overlap` that ended
    /// as `fate`, in the totals and in its overlap bin (overlaps are at
    /// most 1: past every bin's end is the last's).
    fn count_pair(&mut self, overlap: f64, fate: PairFate) {
        self.pairs += 1;
        self.budget.add(fate);
        let bins = &mut self.by_overlap;
        let bin = bins
            .iter()
            .position(|b| overlap < b.max_overlap)
            .unwrap_or(bins.len().saturating_sub(1));
        if let Some(bin) = bins.get_mut(bin) {
            bin.pairs += 1;
            bin.recalled += usize::from(fate == PairFate::Recalled);
        }
    }
}

/// How one examined candidate of a node pair ended.
#[derive(Clone, Copy, Debug)]
struct MatchOutcome {
    /// Its measurement within the true-positive tolerances; `None` when it
    /// has no measurement (not searched, no match, no data).
    right: Option<bool>,
    accepted: bool,
    rejected_by: Option<RejectReason>,
}

impl MatchOutcome {
    fn of(record: &LoopRecord) -> Self {
        Self {
            right: record.true_positive,
            accepted: record.accepted,
            rejected_by: record.rejected_by,
        }
    }
}

/// What became of a recall pair, from its candidates' outcomes in the
/// order they were examined.
#[derive(Clone, Copy, Debug, PartialEq)]
enum PairFate {
    Recalled,
    /// Matched right, never accepted right; the check that rejected the
    /// last right match.
    RightMatchRejected(Option<RejectReason>),
    MatchedWrong,
    NotMatched,
}

impl PairFate {
    fn of(outcomes: &[MatchOutcome]) -> Self {
        if outcomes.iter().any(|o| o.accepted && o.right == Some(true)) {
            return Self::Recalled;
        }
        if let Some(last_right) = outcomes.iter().rev().find(|o| o.right == Some(true)) {
            return Self::RightMatchRejected(last_right.rejected_by);
        }
        if outcomes.iter().any(|o| o.right.is_some()) {
            Self::MatchedWrong
        } else {
            Self::NotMatched
        }
    }
}

impl RecallBudget {
    fn add(&mut self, fate: PairFate) {
        match fate {
            PairFate::Recalled => self.recalled += 1,
            PairFate::RightMatchRejected(reason) => {
                self.right_match_rejected += 1;
                if let Some(reason) = reason {
                    *self.right_match_rejected_by.entry(reason).or_default() += 1;
                }
            }
            PairFate::MatchedWrong => self.matched_wrong += 1,
            PairFate::NotMatched => self.not_matched += 1,
        }
    }
}

/// Empty recall bins from `min_overlap` to 1, with edges at the tenths
/// above `min_overlap` (one bin `[1, 1]` when `min_overlap` is 1).
fn overlap_bins(min_overlap: f64) -> Vec<RecallBin> {
    let mut edges = vec![min_overlap];
    edges.extend(
        (1..=10)
            .map(|k| f64::from(k) / 10.0)
            .filter(|&e| e > min_overlap + 1e-9),
    );
    if edges.len() == 1 {
        edges.push(min_overlap);
    }
    edges
        .windows(2)
        .map(|w| RecallBin {
            min_overlap: w[0],
            max_overlap: w[1],
            pairs: 0,
            recalled: 0,
        })
        .collect()
}

/// ATE, RPE and distance travelled.
fn trajectory_errors(
    ground_truth: &[GroundTruthPose],
    nodes: &[NodeRecord],
    config: &SlamConfig,
    report: &mut Report,
) {
    let covered: Vec<&NodeRecord> = nodes.iter().filter(|n| n.ground_truth.is_some()).collect();
    let trajectory = |pose: &dyn Fn(&NodeRecord) -> Se2| -> Vec<TrajectoryPose> {
        covered
            .iter()
            .map(|n| TrajectoryPose {
                stamp_s: n.stamp_s,
                pose: pose(n),
            })
            .collect()
    };
    let reference = trajectory(&|n| n.ground_truth.expect("filtered"));
    let optimised = trajectory(&|n| n.optimised);
    let dead_reckoning = trajectory(&|n| n.dead_reckoning);
    if reference.len() < 2 {
        return;
    }
    report.ate = ate(&optimised, &reference, Alignment::Se2, MAX_TIME_DIFF_S).ok();
    report.ate_dead_reckoning =
        ate(&dead_reckoning, &reference, Alignment::Se2, MAX_TIME_DIFF_S).ok();
    report.ate_rmse_m = report.ate.as_ref().map(|a| a.rmse_m);
    report.ate_rmse_dead_reckoning_m = report.ate_dead_reckoning.as_ref().map(|a| a.rmse_m);
    let distances = &config.evaluation.rpe_distances_m;
    report.rpe = Some(rpe(&optimised, &reference, distances, MAX_TIME_DIFF_S));
    report.rpe_dead_reckoning = Some(rpe(&dead_reckoning, &reference, distances, MAX_TIME_DIFF_S));
    let (start_s, end_s) = (reference[0].stamp_s, reference[reference.len() - 1].stamp_s);
    let mut path: Vec<Se2> = vec![reference[0].pose];
    path.extend(
        ground_truth
            .iter()
            .filter(|g| g.stamp_s > start_s && g.stamp_s < end_s)
            .map(|g| g.world_from_vehicle),
    );
    path.push(reference[reference.len() - 1].pose);
    report.distance_travelled_m = cumulative_distance(&path).last().copied();
}

/// The definitions of the evaluation numbers, for `report.json`.
fn definitions(config: &SlamConfig) -> BTreeMap<String, String> {
    let e = &config.evaluation;
    let entries = [
        ("ate_rmse_m", "RMSE of the position error of the optimised node poses against the ground truth interpolated at the node stamps, after the best SE(2) alignment".to_string()),
        ("ate_rmse_dead_reckoning_m", "the same for the dead-reckoning poses at the node stamps".to_string()),
        ("ate_navigation_rate", "ATE of the optimised trajectory at the navigation's rate (trajectory_nav_tum.txt: the dead reckoning corrected by the optimised nodes, exact at the nodes, continuous between them), interpolated at every ground-truth sample between the first and the last node stamp, after the best SE(2) alignment".to_string()),
        ("distance_travelled_m", "ground-truth path length between the first and the last node stamp".to_string()),
        ("rpe", "relative pose error over the node poses: for each node, the later node whose distance along the ground-truth path is nearest to d, kept within d/10 (evo_rpe tum ground_truth_tum.txt trajectory_tum.txt --delta d --delta_unit m --all_pairs --pairs_from_reference)".to_string()),
        ("true_positive", format!("an accepted loop whose edge measurement is within {} m and {} deg of the ground-truth relative pose", e.true_positive_translation_m, e.true_positive_rotation_deg)),
        ("accepted_median_error", "loop_evaluation.accepted_median_error_m and _deg: the median over the accepted loops of the translation (m) and heading (deg) error of the measurement against the ground-truth relative pose; with a reference whose own error is near the true-positive tolerances (GPS fixes, a compass), the precision counts the reference's error too".to_string()),
        ("loop_precision", "true positives / accepted loops (1 when no loop is accepted: no accepted loop is wrong; `loop_evaluation` then shows 0 true and 0 false positives)".to_string()),
        ("gt_overlap", format!("fraction of the points of S_k, placed in node j's frame with the ground-truth relative pose, that fall in a {0} m cell holding a point of S_j or next to one", e.overlap_distance_m)),
        ("recall_pair", format!("a node pair (j, k) with k - j >= {} and ground-truth scan overlap >= {} (below that overlap a correctly registered pair cannot reach the quality gate's mean intensity {})", config.loops.min_separation_nodes, e.recall_min_overlap, config.loops.gate.min_mean_intensity)),
        ("loop_recall", format!("recall pairs joined by an accepted true-positive loop, over all recall pairs (while the mission runs each node is matched against at most {} older ones; with loops.densify the overlapping pairs left are matched after it)", config.loops.max_candidates_per_node)),
        ("partial_loop", format!("an accepted densified loop constrained across one horizontal direction and in heading only (loops.densify_partial); it is true or false by the whole-pose verdict like every loop, and `partial_constrained_correct` counts those whose error across that direction is within {} m and whose heading error is within {} deg", e.true_positive_translation_m, e.true_positive_rotation_deg)),
        ("loop_recall_revisits", "revisit nodes (the newer node of at least one recall pair) that are the newer node of an accepted true-positive loop, over all revisit nodes: how many returns to a known place were recognised".to_string()),
        ("recall_budget", "loop_evaluation.recall_budget: each recall pair counted once as recalled; right_match_rejected (some match of the pair was within the true-positive tolerances, none of them accepted; by the check that rejected the last one); matched_wrong (matched, never right); not_matched (never a candidate, or never searched, or no match); gate_ceiling = (recalled + right_match_rejected) / recall pairs, the recall if the checks accepted every right match".to_string()),
        ("recall_by_overlap", "loop_evaluation.recall_by_overlap: the recall pairs and those recalled in bins of ground-truth scan overlap (edges at the tenths above the recall threshold; the last bin includes 1)".to_string()),
    ];
    entries
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outcome(right: Option<bool>, rejected_by: Option<RejectReason>) -> MatchOutcome {
        MatchOutcome {
            right,
            accepted: rejected_by.is_none() && right.is_some(),
            rejected_by,
        }
    }

    #[test]
    fn each_recall_pair_has_one_fate() {
        use RejectReason::*;
        let fate = |outcomes: &[MatchOutcome]| PairFate::of(outcomes);
        assert_eq!(fate(&[]), PairFate::NotMatched);
        assert_eq!(
            fate(&[outcome(None, Some(Deferred)), outcome(None, Some(NoMatch))]),
            PairFate::NotMatched
        );
        assert_eq!(
            fate(&[outcome(Some(false), Some(Quality))]),
            PairFate::MatchedWrong
        );
        // A wrong match accepted is still a pair matched wrong.
        assert_eq!(fate(&[outcome(Some(false), None)]), PairFate::MatchedWrong);
        // Right in the mission, rejected; retried by densification and
        // rejected again: the last right match's check counts.
        assert_eq!(
            fate(&[
                outcome(Some(true), Some(Covariance)),
                outcome(Some(false), Some(ReverseMismatch)),
                outcome(Some(true), Some(Quality)),
            ]),
            PairFate::RightMatchRejected(Some(Quality))
        );
        // Any accepted right match recalls the pair, whatever came before.
        assert_eq!(
            fate(&[
                outcome(Some(true), Some(Covariance)),
                outcome(Some(true), None),
            ]),
            PairFate::Recalled
        );
        // Accepted, then dropped by the robust kernel: rejected.
        let dropped = MatchOutcome {
            right: Some(true),
            accepted: false,
            rejected_by: Some(RobustKernel),
        };
        assert_eq!(
            fate(&[dropped]),
            PairFate::RightMatchRejected(Some(RobustKernel))
        );

        let mut budget = RecallBudget::default();
        for f in [
            PairFate::Recalled,
            PairFate::Recalled,
            PairFate::RightMatchRejected(Some(Quality)),
            PairFate::RightMatchRejected(Some(Quality)),
            PairFate::RightMatchRejected(Some(Covariance)),
            PairFate::RightMatchRejected(None),
            PairFate::MatchedWrong,
            PairFate::NotMatched,
        ] {
            budget.add(f);
        }
        assert_eq!(
            (
                budget.recalled,
                budget.right_match_rejected,
                budget.matched_wrong,
                budget.not_matched
            ),
            (2, 4, 1, 1)
        );
        assert_eq!(
            budget.right_match_rejected_by,
            BTreeMap::from([(Quality, 2), (Covariance, 1)])
        );
    }

    #[test]
    fn recall_bins_run_from_the_threshold_to_one_at_the_tenths() {
        let edges = |min: f64| -> Vec<(f64, f64)> {
            overlap_bins(min)
                .iter()
                .map(|b| (b.min_overlap, b.max_overlap))
                .collect()
        };
        assert_eq!(
            edges(0.4),
            [
                (0.4, 0.5),
                (0.5, 0.6),
                (0.6, 0.7),
                (0.7, 0.8),
                (0.8, 0.9),
                (0.9, 1.0)
            ]
        );
        assert_eq!(edges(0.85), [(0.85, 0.9), (0.9, 1.0)]);
        assert_eq!(edges(0.0).len(), 10);
        assert_eq!(edges(1.0), [(1.0, 1.0)]);
        assert!(
            overlap_bins(0.3)
                .iter()
                .all(|b| b.pairs == 0 && b.recalled == 0)
        );
    }
}
