//! Several missions, one map (`echofield run A.mcap B.mcap ... --output
//! DIR`, issue 38 item 3).
//!
//! 1. Each mission is run on its own ([`run_mission`]): its own dead
//!    reckoning, its own chain of sequential matches, its own loops and
//!    solve, in its own world frame.
//! 2. The missions are taken in a canonical order that does not depend on
//!    the order they were given in ([`canonical_order`]): the *anchor*
//!    first (the mission with the most nodes; ties by name, then by its
//!    node stamps), whose world frame is the map frame, then the others by
//!    the same rule. `run A B` and `run B A` therefore build the same
//!    merged map; the outputs keep the input order (the `mission` column)
//!    and the report names the anchor.
//! 3. Each later mission is placed on the map of the missions placed
//!    before it ([`placement`]): a global search of several probes of its
//!    scans over the map's likelihood field, accepted only when enough
//!    probes agree. No shared start pose is assumed; only the heading
//!    reference (the compass) is shared. The placement must then get a
//!    cross-mission loop accepted ([`merge::confirming_loops`]); when it
//!    gets none, or too few probes agreed, the placement of a smaller
//!    agreeing set that [`ALTERNATIVE_MIN_LOOPS`] loops confirm is taken
//!    ([`confirm_placement`]): on the real St Pere halves the largest set
//!    can agree on the fit of a near-parallel quay.
//! 4. The placed missions become one graph ([`mod@merge`]): cross-mission loop
//!    candidates are matched and checked like a run's loops, and the graph
//!    is solved with only the anchor's first node fixed.
//!
//! A mission that cannot be placed is left out of the merged graph and
//! keeps its own result (in its own frame); the report says so, and a
//! warning is logged. Ground truth: when every mission has it, in one
//! frame (the same simulated world, the same DGPS plane), the merged
//! nodes are evaluated against it together (one SE(2) fit over all
//! missions' nodes), which tests the relative placement; each mission is
//! also evaluated alone.

pub mod merge;
pub mod outputs;
pub mod placement;
pub mod search;

use crate::eval::aligned_position_rmse;
use crate::slam::result::OutliersReport;
use crate::slam::{ProgressSink, SlamConfig, SlamOutput, run_mission};
use anyhow::{Context, Result};
use echofield_backend::SolveSummary;
use echofield_frontend::loops::records::LoopRecord;
use echofield_frontend::sensors::Mission;
use echofield_graph::Se2;
use merge::{Merged, merge};
use placement::{MapFields, Placement, PositionFixes, place, prior_from_fixes};
use serde::Serialize;

/// What a run of several missions produced.
pub struct MultiOutput {
    /// Each mission's own run, in input order (its own frame).
    pub runs: Vec<SlamOutput>,
    /// Each mission's placement search, in input order (`None` for the
    /// anchor, which defines the map frame).
    pub placements: Vec<Option<Placement>>,
    /// The missions (input indices) in the order they were placed and
    /// merged; the first is the anchor ([`canonical_order`]).
    pub order: Vec<usize>,
    /// The merged graph, when at least one later mission was placed.
    pub merged: Option<Merged>,
    /// Each mission's sensor mounting, in input order, when known (from
    /// [`run_missions`]; `None` from [`combine`], which sees only runs):
    /// for `mission.mcap`.
    pub mountings: Vec<Option<echofield_frontend::sensors::SensorMounting>>,
    pub report: MultiReport,
}

impl MultiOutput {
    /// Mission `m`'s node poses as written: in the merged graph (map
    /// frame) when it is a member, else its own run's optimised poses
    /// (its own frame).
    pub fn poses(&self, m: usize) -> Vec<Se2> {
        let run = &self.runs[m];
        self.merged
            .as_ref()
            .and_then(|g| g.poses_of(m, run.nodes.len()))
            .unwrap_or_else(|| run.nodes.iter().map(|n| n.optimised).collect())
    }
}

/// `report.json` of a run of several missions.
#[derive(Clone, Debug, Serialize)]
pub struct MultiReport {
    /// Who wrote it (set by the command).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub run: Option<crate::slam::RunInfo>,
    pub missions: Vec<MissionReport>,
    /// The anchor (1-based input number, as the `mission` column): its
    /// world frame is the map frame, its first node is fixed.
    pub anchor: usize,
    /// The missions (1-based input numbers) in the order they were placed.
    pub order: Vec<usize>,
    /// Whether at least one later mission was merged with the anchor.
    pub merged: bool,
    /// Nodes of the merged graph (0 when nothing was merged).
    pub merged_nodes: usize,
    /// Cross-mission loop candidates and accepted loops.
    pub cross_loop_candidates: usize,
    pub cross_loops_accepted: usize,
    /// ATE (SE(2)-aligned position RMSE over every merged node at once
    /// against its ground truth, m), when every merged mission has ground
    /// truth at its nodes: the test of the relative placement.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub merged_ate_rmse_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub merged_solve: Option<SolveSummary>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub merged_outliers: Option<OutliersReport>,
    /// Wall time, s.
    pub time_s: f64,
    pub warnings: Vec<String>,
    pub definitions: Definitions,
}

/// Per mission.
#[derive(Clone, Debug, Serialize)]
pub struct MissionReport {
    /// 1-based, as in the output files' `mission` column.
    pub mission: usize,
    pub name: String,
    pub nodes: usize,
    /// Its own run's loops.
    pub loops_accepted: usize,
    /// Its own run's ATE and dead reckoning's, m (as a single run).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ate_rmse_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ate_rmse_dead_reckoning_m: Option<f64>,
    /// Its nodes in the merged graph against its ground truth (fitted
    /// alone), m.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub merged_ate_rmse_m: Option<f64>,
    /// In the merged graph.
    pub merged: bool,
    /// Its own run's health verdict.
    pub health: String,
    /// Its position fixes (0: none).
    pub position_fixes: usize,
    /// What became of the prior its fixes give; absent without fixes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fix_prior: Option<FixPrior>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub placement: Option<Placement>,
}

/// The fate of a mission's position fixes in the merge.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FixPrior {
    /// The anchor, whose fixes are the map's side of the priors of the
    /// missions placed after it.
    Map,
    /// The fixes gave no prior (too few at its nodes or at the map's, too
    /// little spread, or the map has none): searched without.
    Unused,
    /// The placement from the scans lies within the prior's gate.
    Confirmed,
    /// The scans placed it outside the prior's gate, or found nothing
    /// within it: the fixes were not trusted.
    Rejected,
}

impl FixPrior {
    /// Of a mission with `fixes` fixes and `placement` (`None`: the
    /// anchor, whose fixes served only if `any_prior`, another mission
    /// having got a prior from them); `None` without fixes.
    fn of(fixes: usize, placement: Option<&Placement>, any_prior: bool) -> Option<Self> {
        if fixes == 0 {
            return None;
        }
        Some(match placement {
            None if any_prior => FixPrior::Map,
            None => FixPrior::Unused,
            Some(p) => match &p.prior {
                None => FixPrior::Unused,
                Some(check) if check.consistent => FixPrior::Confirmed,
                Some(_) => FixPrior::Rejected,
            },
        })
    }

    /// For the summary line.
    pub fn describe(self) -> &'static str {
        match self {
            FixPrior::Map => "its position fixes place the map",
            FixPrior::Unused => "its position fixes gave no prior",
            FixPrior::Confirmed => "the prior from its position fixes confirmed by the sonar",
            FixPrior::Rejected => {
                "the prior from its position fixes REJECTED by the sonar (not trusted)"
            }
        }
    }
}

/// What the report's figures mean.
#[derive(Clone, Debug, Serialize)]
pub struct Definitions {
    pub merged_ate_rmse_m: &'static str,
    pub placement: &'static str,
    pub fix_prior: &'static str,
}

const DEFINITIONS: Definitions = Definitions {
    merged_ate_rmse_m: "position RMSE of every merged node (all missions) after one SE(2) fit onto the ground truth at the node stamps, m",
    placement: "map_from_mission [x_m, y_m, theta_rad]: the mission's world frame in the anchor's (the map frame); found by probes of several consecutive scans searched over the map's likelihood field, accepted when at least 3 usable probes agree and it gets at least one cross-mission loop accepted (confirming_loops); otherwise the placement of a smaller agreeing set (of at least 2 probes) that at least 5 cross-mission loops confirm is taken (alternative: its index, 0-based), and with none the first stands",
    fix_prior: "what became of a mission's position fixes (the /position/fix channel): map (the anchor's fixes are the map's side of the others' priors), unused (too few, too little spread or no counterpart on the map to give a prior), confirmed (the placement from the scans lies within the prior's gate, 3 sigma), rejected (it does not, or nothing was found within the prior: the fixes were not trusted)",
};

/// Runs every mission and merges them (see the module doc), with the
/// position fixes of the missions that carry them as the placement prior
/// ([`combine_with_fixes`]). Errors: a mission's own run failing (naming
/// it), a failed merged solve.
pub fn run_missions(
    missions: &[Mission],
    config: &SlamConfig,
    progress: &dyn ProgressSink,
) -> Result<MultiOutput> {
    let start = std::time::Instant::now();
    let mut runs = Vec::with_capacity(missions.len());
    for (m, mission) in missions.iter().enumerate() {
        let run = run_mission(mission, config, progress)
            .with_context(|| format!("mission {} ({})", m + 1, mission.name))?;
        runs.push(run);
    }
    let fixes: Vec<Option<PositionFixes>> =
        missions.iter().map(PositionFixes::of_mission).collect();
    let mut output = combine_with_fixes(runs, &fixes, config)?;
    output.mountings = missions.iter().map(|m| Some(m.mounting.clone())).collect();
    output.report.time_s = start.elapsed().as_secs_f64();
    Ok(output)
}

/// The order in which `runs` are placed and merged (input indices): by
/// node count, most first, then by mission name, then by the node stamps
/// (two missions alike in all three are the same mission twice, and
/// either order gives the same map). Independent of the input order.
pub fn canonical_order(runs: &[SlamOutput]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..runs.len()).collect();
    order.sort_by(|&a, &b| {
        let (ra, rb) = (&runs[a], &runs[b]);
        rb.nodes
            .len()
            .cmp(&ra.nodes.len())
            .then_with(|| ra.mission_name.cmp(&rb.mission_name))
            .then_with(|| {
                let stamps = |r: &SlamOutput| r.nodes.iter().map(|n| n.stamp_s).collect::<Vec<_>>();
                stamps(ra)
                    .partial_cmp(&stamps(rb))
                    .unwrap_or(std::cmp::Ordering::Equal)
            })
            .then(a.cmp(&b))
    });
    order
}

/// Steps 2-4 of the module doc on finished `runs` (given in any order;
/// the anchor defines the map frame). Errors: a failed cross-mission match
/// or merged solve.
pub fn combine(runs: Vec<SlamOutput>, config: &SlamConfig) -> Result<MultiOutput> {
    combine_with_fixes(runs, &[], config)
}

/// [`combine`] with position fixes of the missions (`fixes[m]` of input
/// mission `m`, all in one common frame; missing or `None`: none): a
/// mission with fixes, placed on a map of which some missions have fixes
/// too, is searched first within their prior
/// ([`placement::prior_from_fixes`]); a placement that disagrees with the
/// prior beyond its gate is reported with a warning.
pub fn combine_with_fixes(
    runs: Vec<SlamOutput>,
    fixes: &[Option<PositionFixes>],
    config: &SlamConfig,
) -> Result<MultiOutput> {
    let start = std::time::Instant::now();
    let mut warnings = Vec::new();
    let order = canonical_order(&runs);
    let mut transforms: Vec<Option<Se2>> = vec![None; runs.len()];
    let mut placements: Vec<Option<Placement>> = vec![None; runs.len()];
    if let Some(&anchor) = order.first() {
        transforms[anchor] = Some(Se2::identity());
    }
    // The cross-mission matches each placement was confirmed with, which
    // the merge takes instead of matching them again.
    let mut examined = Vec::new();
    for position in 1..order.len() {
        let m = order[position];
        let mut placement = place_on_earlier(&runs, fixes, &order[..position], &transforms, m)?;
        examined.extend(confirm_placement(
            &runs,
            &order[..=position],
            &transforms,
            &mut placement,
            config,
        )?);
        warnings.extend(placement_warnings(&runs[m], m, &placement, fixes.get(m)));
        transforms[m] = placement.map_from_mission;
        placements[m] = Some(placement);
    }
    let merged = if order.iter().skip(1).any(|&m| transforms[m].is_some()) {
        let merged = merge(&runs, &transforms, &order, config, &examined)?;
        if merged.accepted_cross() == 0 {
            warnings.push(warn(
                "the missions were placed but no cross-mission loop was accepted: the merged graph rests on the placement alone".to_string(),
            ));
        }
        Some(merged)
    } else {
        None
    };
    let runs_len = runs.len();
    let fix_counts: Vec<usize> = (0..runs_len)
        .map(|m| {
            fixes
                .get(m)
                .and_then(Option::as_ref)
                .map_or(0, |f| f.fixes.len())
        })
        .collect();
    let mut output = MultiOutput {
        report: MultiReport::unfilled(&order, warnings),
        runs,
        placements,
        mountings: vec![None; runs_len],
        order,
        merged,
    };
    fill_report(&mut output);
    let any_prior = output
        .placements
        .iter()
        .flatten()
        .any(|p| p.prior.is_some());
    for (report, &count) in output.report.missions.iter_mut().zip(&fix_counts) {
        report.position_fixes = count;
        let placement = output.placements[report.mission - 1].as_ref();
        report.fix_prior = FixPrior::of(count, placement, any_prior);
    }
    output.report.time_s = start.elapsed().as_secs_f64();
    Ok(output)
}

/// Alternative placements are taken only when cross-mission loops
/// confirm one: at least this many accepted (a wrong place passes a few
/// loop checks by chance far more rarely than this many).
pub const ALTERNATIVE_MIN_LOOPS: usize = 5;

/// Checks `placement` of mission `m`, the last of `order` (the earlier
/// ones placed by `transforms`), by the cross-mission loops it gets
/// accepted ([`merge::confirming_loops`]). A placement with at least one
/// stands. Otherwise (none, or not placed) the alternatives of smaller
/// agreeing sets are tried in order, and the first with the most loops,
/// at least [`ALTERNATIVE_MIN_LOOPS`], becomes the placement; with none
/// the placement stays as it was. Returns the cross-mission matches of
/// the placement kept (none when not placed), for the merge. Errors: a
/// failed match.
fn confirm_placement(
    runs: &[SlamOutput],
    order: &[usize],
    transforms: &[Option<Se2>],
    placement: &mut Placement,
    config: &SlamConfig,
) -> Result<Vec<LoopRecord>> {
    let Some(&m) = order.last() else {
        return Ok(Vec::new());
    };
    let mut trial = transforms.to_vec();
    let mut loops_at = |t: Se2| {
        trial[m] = Some(t);
        merge::confirming_loops(runs, &trial, order, config)
    };
    let mut kept = Vec::new();
    if let Some(t) = placement.map_from_mission {
        let (n, records) = loops_at(t)?;
        placement.confirming_loops = Some(n);
        if n > 0 {
            return Ok(records);
        }
        kept = records;
    }
    let mut best: Option<(usize, usize, Vec<LoopRecord>)> = None;
    for (k, &t) in placement.alternatives.iter().enumerate() {
        let (n, records) = loops_at(t)?;
        if n >= ALTERNATIVE_MIN_LOOPS && best.as_ref().is_none_or(|(_, b, _)| n > *b) {
            best = Some((k, n, records));
        }
    }
    if let Some((k, n, records)) = best {
        placement.map_from_mission = Some(placement.alternatives[k]);
        placement.confirming_loops = Some(n);
        placement.alternative = Some(k);
        kept = records;
    }
    Ok(kept)
}

/// Logs `message` as a warning and returns it for the report.
fn warn(message: String) -> String {
    tracing::warn!("{message}");
    message
}

/// Places mission `m` on the map of the missions `earlier` (canonical
/// order) that were placed (`transforms`), with the prior from position
/// fixes when `m` and the map have them. Errors: the map's fields cannot
/// be built.
fn place_on_earlier(
    runs: &[SlamOutput],
    fixes: &[Option<PositionFixes>],
    earlier: &[usize],
    transforms: &[Option<Se2>],
    m: usize,
) -> Result<Placement> {
    let own: Vec<Se2> = runs[m].graph.poses();
    let placed: Vec<(usize, Vec<Se2>)> = earlier
        .iter()
        .filter_map(|&i| {
            let t = transforms[i]?;
            Some((
                i,
                runs[i].graph.poses().iter().map(|p| t.compose(p)).collect(),
            ))
        })
        .collect();
    let map_runs: Vec<(&SlamOutput, &[Se2])> = placed
        .iter()
        .map(|(i, p)| (&runs[*i], p.as_slice()))
        .collect();
    let fields = MapFields::build(&map_runs).context("the map for the placement")?;
    let fixes_of = |i: usize| fixes.get(i).and_then(Option::as_ref);
    let prior = fixes_of(m).and_then(|own_fixes| {
        let map_fixes: Vec<(&SlamOutput, &[Se2], &PositionFixes)> = placed
            .iter()
            .filter_map(|(i, p)| fixes_of(*i).map(|f| (&runs[*i], p.as_slice(), f)))
            .collect();
        prior_from_fixes(&map_fixes, &runs[m], &own, own_fixes)
    });
    Ok(place(&fields, &runs[m], &own, prior.as_ref()))
}

/// The warnings of mission `m`'s placement (logged): fixes that gave no
/// prior, a prior the scans did not confirm, a mission not placed.
fn placement_warnings(
    run: &SlamOutput,
    m: usize,
    placement: &Placement,
    fixes: Option<&Option<PositionFixes>>,
) -> Vec<String> {
    let mut warnings = Vec::new();
    let name = format!("mission {} ({})", m + 1, run.mission_name);
    if fixes.is_some_and(Option::is_some) && placement.prior.is_none() {
        warnings.push(warn(format!(
            "{name}: its position fixes give no prior (too few fixes at its nodes or at the map's, or too little spread): searched without"
        )));
    }
    if let Some(check) = &placement.prior
        && !check.consistent
    {
        warnings.push(warn(format!(
            "{name}: the placement from the scans {} the prior from position fixes (sigma {:.1} m){}: the fixes were not trusted",
            if placement.map_from_mission.is_some() {
                "disagrees with"
            } else {
                "found nothing within"
            },
            check.prior.sigma_m,
            check.offset_m.map_or(String::new(), |d| format!(
                ", off by {d:.1} m ({:.1} sigma)",
                d / check.prior.sigma_m
            ))
        )));
    }
    if let (Some(k), Some(n)) = (placement.alternative, placement.confirming_loops) {
        warnings.push(warn(format!(
            "{name}: the largest set of agreeing probes ({} of {}) gave {}; the placement of a smaller agreeing set (report.json placement.alternative = {}) is confirmed by {n} cross-mission loops and taken",
            placement.agreeing,
            placement.probes.len(),
            if placement.agreeing >= placement::MIN_AGREEING {
                "a placement that no cross-mission loop confirms"
            } else {
                "no placement"
            },
            k
        )));
    }
    if placement.map_from_mission.is_none() {
        warnings.push(warn(format!(
            "{name} could not be placed on the map of the missions before it ({} of {} probes agree, {} needed): it is not merged; its own result is written in its own frame",
            placement.agreeing,
            placement.probes.len(),
            placement::MIN_AGREEING
        )));
    }
    warnings
}

impl MultiReport {
    /// The report before [`fill_report`]: the order and the warnings.
    fn unfilled(order: &[usize], warnings: Vec<String>) -> Self {
        Self {
            run: None,
            missions: Vec::new(),
            anchor: order.first().map_or(0, |a| a + 1),
            order: order.iter().map(|m| m + 1).collect(),
            merged: false,
            merged_nodes: 0,
            cross_loop_candidates: 0,
            cross_loops_accepted: 0,
            merged_ate_rmse_m: None,
            merged_solve: None,
            merged_outliers: None,
            time_s: 0.0,
            warnings,
            definitions: DEFINITIONS,
        }
    }
}

/// `(estimate, truth)` of the nodes of `run` at `poses` that have ground
/// truth.
fn with_truth(run: &SlamOutput, poses: &[Se2]) -> (Vec<Se2>, Vec<Se2>) {
    run.nodes
        .iter()
        .zip(poses)
        .filter_map(|(n, p)| n.ground_truth.map(|g| (*p, g)))
        .unzip()
}

fn fill_report(output: &mut MultiOutput) {
    let mut missions = Vec::new();
    let (mut all_estimate, mut all_truth) = (Vec::new(), Vec::new());
    let mut every_has_truth = true;
    // The joint figure sums the missions in the merge order, so that it
    // does not depend on the input order either.
    let mut joint: Vec<(usize, Vec<Se2>, Vec<Se2>)> = Vec::new();
    for (m, run) in output.runs.iter().enumerate() {
        let member = output
            .merged
            .as_ref()
            .is_some_and(|g| g.members.iter().any(|(i, _)| *i == m));
        let poses = output.poses(m);
        let merged_ate = if member {
            let (e, t) = with_truth(run, &poses);
            if e.len() < 2 {
                every_has_truth = false;
            }
            let ate = (e.len() >= 2).then(|| aligned_position_rmse(&e, &t));
            joint.push((m, e, t));
            ate
        } else {
            None
        };
        missions.push(MissionReport {
            mission: m + 1,
            name: run.mission_name.clone(),
            nodes: run.nodes.len(),
            loops_accepted: run.report.loops_accepted,
            ate_rmse_m: run.report.ate_rmse_m,
            ate_rmse_dead_reckoning_m: run.report.ate_rmse_dead_reckoning_m,
            merged_ate_rmse_m: merged_ate,
            merged: member,
            health: format!("{:?}", run.report.health.verdict).to_lowercase(),
            position_fixes: 0,
            fix_prior: None,
            placement: output.placements[m].clone(),
        });
    }
    joint.sort_by_key(|(m, ..)| output.order.iter().position(|o| o == m));
    for (_, e, t) in joint {
        all_estimate.extend(e);
        all_truth.extend(t);
    }
    let report = &mut output.report;
    report.missions = missions;
    if let Some(merged) = &output.merged {
        report.merged = true;
        report.merged_nodes = merged.graph.node_count();
        report.cross_loop_candidates = merged.cross_loops.len();
        report.cross_loops_accepted = merged.accepted_cross();
        report.merged_solve = Some(merged.summary.clone());
        report.merged_outliers = Some(merged.outliers.clone());
        if every_has_truth && all_estimate.len() >= 2 {
            report.merged_ate_rmse_m = Some(aligned_position_rmse(&all_estimate, &all_truth));
        }
    }
}
