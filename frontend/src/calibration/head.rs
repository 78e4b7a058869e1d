//! The continuous unknowns of the chosen combination: the yaw alone (the
//! lever arm at the mission's value), and the yaw with the lever arm; each
//! with its block-jackknife standard deviation and a cross-validated vote
//! against the mission's values.
//!
//! **Cross-validation.** The leave-one-block-out fits of the jackknife are
//! also predictions: the fit made without block `b` is scored on block `b`
//! alone. The fitted lever arm is kept only when, on the blocks left out,
//! its fits are sharper than the yaw-only fits with the mission's lever
//! arm, significantly by the signed-rank test of [`super::uncertainty`];
//! likewise the fitted yaw against the mission's yaw. A value the data
//! do not prefer to the mission's stays the mission's: a refit always fits
//! the windows it was fitted on a little better, but predicts the others
//! better only when the mission's value is wrong.

use super::objective::{HeadCandidate, Objective};
use super::result::ContinuousEstimate;
use super::search::{self, Found};
use super::uncertainty::{self, Blocks, Vote};

/// Largest standard deviation of the yaw, in steps of the coarse grid,
/// for the yaw to count as resolved: the grid chooses the basin of the
/// minimum at its step, so leave-one-out fits that scatter over half a step
/// leave even the basin in doubt.
pub const MAX_YAW_SPREAD_STEPS: f64 = 0.5;

/// Largest standard deviation of the lever arm on either axis, in cells,
/// for it to count as resolved: half a cell, below which the grid does not
/// resolve a displacement.
pub const MAX_LEVER_ARM_SPREAD_CELLS: f64 = 0.5;

/// The lever arm is searched within this distance of the mission's, per
/// axis, metres: a head several metres from where the mission says is a
/// different vehicle, not a calibration.
const LEVER_ARM_SEARCH_M: f64 = 3.0;

/// Step sizes of the local searches.
pub struct Scales {
    /// The coarse yaw step: the half width of the yaw refinement.
    pub step_rad: f64,
    /// Median range of the returns: Nelder-Mead's scale of the yaw.
    pub rho_m: f64,
    /// Cell size: Nelder-Mead's initial step and the tolerances.
    pub cell_m: f64,
}

/// The yaw and lever arm found, with their decisions.
pub struct HeadEstimates {
    pub yaw: ContinuousEstimate,
    pub x: ContinuousEstimate,
    pub y: ContinuousEstimate,
}

/// The leave-one-block-out fits and their scores on the blocks left out.
#[derive(Default)]
struct LeaveOneOut {
    yaws_1d: Vec<f64>,
    yaws_3d: Vec<f64>,
    xs: Vec<f64>,
    ys: Vec<f64>,
    /// Per block, scored on that block alone: the yaw-only fit, the full
    /// fit, the mission's head, and the full fit with the mission's yaw.
    held_1d: Vec<f64>,
    held_3d: Vec<f64>,
    held_mission: Vec<f64>,
    held_mission_yaw_3d: Vec<f64>,
}

/// Estimates and decides the yaw and the lever arm (module doc), from
/// `yaw_only`, the best yaw with the mission's lever arm; `mission` is
/// the mission's head under the chosen angle convention.
pub fn estimate_head(
    objective: &Objective,
    yaw_only: &Found,
    mission: &HeadCandidate,
    blocks: &Blocks,
    scales: &Scales,
) -> HeadEstimates {
    let all = blocks.all();
    let lever = [mission.x_m, mission.y_m];
    let full = refine_full(objective, yaw_only, &all, scales, lever);
    let loo = leave_one_out(objective, yaw_only, &full, mission, blocks, scales);
    let (x, y) = decide_lever(&loo, yaw_only, &full, mission, scales);
    // The yaw against the mission's, both with the lever arm kept.
    let yaw = if x.determined {
        let mission_yaw = HeadCandidate {
            yaw_rad: mission.yaw_rad,
            ..full.head
        };
        let mission_cost = objective.mean_entropy(&mission_yaw, &all);
        let held = [&loo.held_3d, &loo.held_mission_yaw_3d];
        decide_yaw(&full, &loo.yaws_3d, held, mission, mission_cost, scales)
    } else {
        let mission_cost = objective.mean_entropy(mission, &all);
        let held = [&loo.held_1d, &loo.held_mission];
        decide_yaw(yaw_only, &loo.yaws_1d, held, mission, mission_cost, scales)
    };
    HeadEstimates { yaw, x, y }
}

/// The lever arm of `full`: kept when its jackknife standard deviation is
/// at most half a cell on both axes and its leave-one-out fits predict the
/// blocks left out better than the yaw-only fits (module doc).
fn decide_lever(
    loo: &LeaveOneOut,
    yaw_only: &Found,
    full: &Found,
    mission: &HeadCandidate,
    scales: &Scales,
) -> (ContinuousEstimate, ContinuousEstimate) {
    let (sx, sy) = (
        uncertainty::jackknife_std(&loo.xs),
        uncertainty::jackknife_std(&loo.ys),
    );
    let tolerance_m = MAX_LEVER_ARM_SPREAD_CELLS * scales.cell_m;
    let vote = uncertainty::vote(
        &loo.held_3d,
        std::slice::from_ref(&loo.held_1d),
        yaw_only.mean_entropy_bits - full.mean_entropy_bits,
    );
    let rejection = if sx.max(sy) > tolerance_m {
        let (axis, s) = if sx >= sy { ("x", sx) } else { ("y", sy) };
        Some(format!(
            "cannot be determined from this mission: its standard deviation along {axis}, \
             {s:.2} m, is more than half a cell ({tolerance_m:.2} m); kept from the mission"
        ))
    } else {
        not_preferred(&vote)
    };
    let h = full.head;
    (
        ContinuousEstimate::decided(h.x_m, sx, mission.x_m, vote, rejection.clone()),
        ContinuousEstimate::decided(h.y_m, sy, mission.y_m, vote, rejection),
    )
}

/// The yaw of `fit` (its leave-one-out yaws `yaws`): kept when their
/// jackknife standard deviation is at most half the coarse step and the
/// fits predict the blocks left out (`held[0]`) better than the mission's
/// yaw does (`held[1]`; `mission_cost` over all windows).
fn decide_yaw(
    fit: &Found,
    yaws: &[f64],
    held: [&Vec<f64>; 2],
    mission: &HeadCandidate,
    mission_cost: f64,
    scales: &Scales,
) -> ContinuousEstimate {
    let std = uncertainty::jackknife_std_angle(yaws, fit.head.yaw_rad);
    let tolerance = MAX_YAW_SPREAD_STEPS * scales.step_rad;
    let vote = uncertainty::vote(
        held[0],
        std::slice::from_ref(held[1]),
        mission_cost - fit.mean_entropy_bits,
    );
    let rejection = if std > tolerance {
        Some(format!(
            "cannot be determined from this mission: its standard deviation, {:.1} deg, is \
             more than half the coarse step ({:.1} deg); kept from the mission",
            std.to_degrees(),
            tolerance.to_degrees()
        ))
    } else {
        not_preferred(&vote)
    };
    ContinuousEstimate::decided(fit.head.yaw_rad, std, mission.yaw_rad, vote, rejection)
}

/// The reason a resolved estimate is not kept: the blocks left out do not
/// prefer it to the mission's value; `None` when they do.
fn not_preferred(vote: &Vote) -> Option<String> {
    (!vote.determined).then(|| {
        format!(
            "kept from the mission: the estimate does not predict the windows left out \
             significantly better ({} of {} blocks prefer it, p = {:.3})",
            vote.agreeing_blocks, vote.blocks, vote.p_value
        )
    })
}

/// Nelder-Mead on the yaw and lever arm from `start` over `selection`.
fn refine_full(
    objective: &Objective,
    start: &Found,
    selection: &[usize],
    scales: &Scales,
    lever: [f64; 2],
) -> Found {
    search::refine_head(
        objective,
        start,
        selection,
        scales.rho_m,
        scales.cell_m,
        lever,
        LEVER_ARM_SEARCH_M,
    )
}

/// The fits without each block, from the fits over all windows, and their
/// scores on the block left out.
fn leave_one_out(
    objective: &Objective,
    yaw_only: &Found,
    full: &Found,
    mission: &HeadCandidate,
    blocks: &Blocks,
    scales: &Scales,
) -> LeaveOneOut {
    let lever = [mission.x_m, mission.y_m];
    let mut loo = LeaveOneOut::default();
    for b in 0..blocks.len() {
        let kept = blocks.without(b);
        let held = blocks.only(b);
        let rescored = |f: &Found| Found {
            head: f.head,
            mean_entropy_bits: objective.mean_entropy(&f.head, &kept),
        };
        let h1 = search::refine_yaw(objective, &rescored(yaw_only), &kept, scales.step_rad).head;
        let h3 = refine_full(objective, &rescored(full), &kept, scales, lever).head;
        loo.yaws_1d.push(h1.yaw_rad);
        loo.yaws_3d.push(h3.yaw_rad);
        loo.xs.push(h3.x_m);
        loo.ys.push(h3.y_m);
        loo.held_1d.push(objective.mean_entropy(&h1, &held));
        loo.held_3d.push(objective.mean_entropy(&h3, &held));
        loo.held_mission
            .push(objective.mean_entropy(mission, &held));
        let mission_yaw = HeadCandidate {
            yaw_rad: mission.yaw_rad,
            ..h3
        };
        loo.held_mission_yaw_3d
            .push(objective.mean_entropy(&mission_yaw, &held));
    }
    loo
}
