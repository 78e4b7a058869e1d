//! Mounting calibration from the data alone: which way the sonar head's
//! angle counts, its yaw and position on the vehicle, and (for beams rebuilt
//! from point sets) which way its angle ran with time. No ground truth.
//!
//! # Principle
//!
//! A wall seen from many places lands on the same cells of a map only
//! when the returns are placed with the right mounting. With the
//! dead-reckoned vehicle poses, every return is placed in the world under
//! a candidate head (eq. 3 in [`objective`]) and the sharpness of the
//! placed returns (the entropy of their splat on a grid, as in
//! [`crate::sharpness`]) is measured in windows of a few consecutive
//! rotations, so that the dead reckoning's drift over the whole mission
//! does not blur the comparison. The objective is the mean entropy over the windows; the
//! right mounting minimises it.
//!
//! # What the data can tell
//!
//! - **The angle convention** (counter-clockwise or clockwise): a mirrored
//!   scan turns the wrong way when the vehicle turns and is seen from the
//!   wrong side when it moves.
//! - **The head's yaw**: a wrong yaw turns each rotation about the vehicle,
//!   so rotations seen from different places or headings disagree.
//! - **The sweep** (reconstructed stamps only): the wrong direction gives
//!   each beam the pose of its mirror image's time; it shows only as far
//!   as the vehicle moves during a rotation.
//! - **The lever arm** `(x, y)`: it shifts a rotation by `R(heading)·(x, y)`,
//!   so it shows only through the heading changes within a window, by
//!   `2 sin(Δψ/2)·|(x, y)|`; often less than a cell. It is the head's
//!   position relative to the point the dead reckoning tracks (the DVL's,
//!   when `vehicle_from_dvl` is the identity). On a path of constant
//!   curvature its component along the vehicle is a turn of the head, and
//!   cannot be told from the yaw: it needs turns both ways.
//! - **Not the heading calibration.** A constant heading offset turns the
//!   whole dead-reckoned map rigidly, which changes no window's sharpness;
//!   it needs an absolute reference such as GPS. It is reported as such
//!   and kept from the mission. Likewise a yaw misalignment of the DVL
//!   turns the track but not the headings, which is a rigid turn plus a
//!   change of the head's yaw: the yaw found is the head's relative to the
//!   DVL's axes as the mission gives them.
//!
//! # Search
//!
//! For every combination of the discrete choices (angle convention; sweep
//! only when the mission's stamps were reconstructed, [`SweepTiming`]): a
//! coarse grid over the full circle of the yaw, then a fine grid and
//! Brent's method about its best point, the lever arm at the mission's
//! ([`search`]). For the chosen combination, Nelder-Mead on the yaw and
//! the lever arm together. Brent and Nelder-Mead are argmin's.
//!
//! # Uncertainty and decisions
//!
//! The windows are cut into blocks of consecutive windows
//! ([`uncertainty`]). Leaving out one block at a time gives a block
//! jackknife standard deviation of every continuous value, and the fits
//! without a block, scored on that block, a cross-validation ([`head`]).
//! A value replaces the mission's only when the data determine it:
//!
//! - a discrete choice, when the blocks, each on its own windows, prefer
//!   it beyond chance (Wilcoxon's signed-rank test at
//!   [`uncertainty::VOTE_SIGNIFICANCE`]);
//! - the lever arm, when its standard deviation on both axes is at most
//!   half a cell (the grid does not resolve less) and the fits with it
//!   predict the blocks left out better than the mission's lever arm does
//!   (the same test);
//! - the yaw, when its standard deviation is at most half the coarse
//!   grid's step (which chooses the basin of the minimum;
//!   [`head::MAX_YAW_SPREAD_STEPS`]) and its fits predict the blocks left
//!   out better than the mission's yaw.
//!
//! Otherwise the mission's value is kept and the reason reported: either
//! the data cannot determine it (too uncertain), or they do not prefer
//! the estimate to the mission's value (a right value is not replaced by
//! a refit within the noise).
//!
//! ```no_run
//! use echofield_frontend::calibration::{CalibrationConfig, calibrate};
//! use echofield_frontend::dead_reckoning::{self, DeadReckoningConfig};
//! # fn mission() -> echofield_frontend::Mission { unimplemented!() }
//! let mission = mission();
//! let navigation = dead_reckoning::run(&mission, &DeadReckoningConfig::default())?;
//! let result = calibrate(
//!     &mission,
//!     &navigation,
//!     &Default::default(),
//!     &Default::default(),
//!     &CalibrationConfig::default(),
//! )?;
//! println!("yaw {:.1} deg", result.sonar_yaw_rad.value.to_degrees());
//! # Ok::<(), echofield_frontend::FrontendError>(())
//! ```

pub mod config;
pub mod head;
pub mod objective;
mod prepare;
pub mod result;
pub mod search;
pub mod uncertainty;

pub use config::CalibrationConfig;
pub use objective::{HeadCandidate, Objective};
pub use result::{Calibration, Combination, ContinuousEstimate, DiscreteEstimate};

use crate::dead_reckoning::Navigation;
use crate::error::FrontendError;
use crate::rotation::RotationConfig;
use crate::segmentation::SegmentationConfig;
use crate::sensors::{AngleDirection, Mission, SensorMounting, SweepTiming};
use search::Found;
use uncertainty::{Blocks, Vote};

/// The angle conventions, in the order they are searched.
const ANGLES: [AngleDirection; 2] = [AngleDirection::CounterClockwise, AngleDirection::Clockwise];

/// Calibrates `mission`'s sonar mounting (module doc) from its beams and
/// `navigation` (its dead reckoning), with the scans' own rotation and
/// segmentation settings. The mission's mounting is the starting point:
/// its lever arm for the yaw search, and every value the data cannot
/// determine.
///
/// Errors: an invalid config; a non-finite mounting; no beams, no echo,
/// no return within the navigation; too few rotations within the
/// navigation for six windows (`window_rotations + 5·⌈window_rotations/2⌉`);
/// beams marked as rebuilt from point sets that are not.
pub fn calibrate(
    mission: &Mission,
    navigation: &Navigation,
    rotation: &RotationConfig,
    segmentation: &SegmentationConfig,
    config: &CalibrationConfig,
) -> Result<Calibration, FrontendError> {
    config.validate()?;
    segmentation.validate()?;
    if !mission.mounting.vehicle_from_sonar.is_finite() {
        return Err(FrontendError::input(
            "mounting",
            "vehicle_from_sonar",
            "not finite: the search starts from it",
        ));
    }
    let prepared = prepare::prepare(mission, navigation, rotation, segmentation, config)?;
    let blocks = Blocks::new(prepared.objectives[0].1.windows(), config.jackknife_blocks);
    let step_rad = config.coarse_yaw_step_deg.to_radians();
    let start = &mission.mounting;
    let combos = search_combinations(&prepared, start, &blocks, step_rad);
    let (sonar_angle, sweep) = decide_discrete(&prepared, &combos, &blocks, start);
    let chosen = combos
        .iter()
        .find(|c| {
            c.found.head.sonar_angle == sonar_angle.value
                && sweep.is_none_or(|s| c.sweep == s.value)
        })
        .copied()
        .unwrap_or(combos[0]);
    let objective = &prepared.objectives[chosen.objective].1;
    let scales = head::Scales {
        step_rad,
        rho_m: prepared.median_range_m,
        cell_m: prepared.cell_size_m,
    };
    let mission_head = HeadCandidate {
        sonar_angle: sonar_angle.value,
        yaw_rad: start.vehicle_from_sonar.theta(),
        x_m: start.vehicle_from_sonar.x(),
        y_m: start.vehicle_from_sonar.y(),
    };
    let continuous = head::estimate_head(objective, &chosen.found, &mission_head, &blocks, &scales);
    let summary = summarise(&prepared, config, &blocks, objective.returns());
    Ok(assemble(
        summary,
        &combos,
        sonar_angle,
        sweep,
        continuous,
        mission,
    ))
}

/// Every combination of the discrete choices at its best yaw (the lever
/// arm at the mission's), best first.
fn search_combinations(
    prepared: &prepare::Prepared,
    start: &SensorMounting,
    blocks: &Blocks,
    step_rad: f64,
) -> Vec<Combo> {
    let all = blocks.all();
    let mut combos = Vec::new();
    for (k, (sweep, objective)) in prepared.objectives.iter().enumerate() {
        for sonar_angle in ANGLES {
            let head = HeadCandidate {
                sonar_angle,
                yaw_rad: start.vehicle_from_sonar.theta(),
                x_m: start.vehicle_from_sonar.x(),
                y_m: start.vehicle_from_sonar.y(),
            };
            let coarse = search::coarse_yaw(objective, &head, &all, step_rad);
            combos.push(Combo {
                objective: k,
                sweep: *sweep,
                found: search::refine_yaw(objective, &coarse, &all, step_rad),
            });
        }
    }
    combos.sort_by(|a, b| {
        a.found
            .mean_entropy_bits
            .total_cmp(&b.found.mean_entropy_bits)
    });
    combos
}

/// The block votes on the angle convention and (for a reconstruction) the
/// sweep, and the values they decide.
fn decide_discrete(
    prepared: &prepare::Prepared,
    combos: &[Combo],
    blocks: &Blocks,
    start: &SensorMounting,
) -> (
    DiscreteEstimate<AngleDirection>,
    Option<DiscreteEstimate<SweepTiming>>,
) {
    let block_costs: Vec<Vec<f64>> = combos
        .iter()
        .map(|c| {
            let objective = &prepared.objectives[c.objective].1;
            (0..blocks.len())
                .map(|b| objective.mean_entropy(&c.found.head, &blocks.only(b)))
                .collect()
        })
        .collect();
    let angle_vote = vote_on(combos, &block_costs, |c| c.found.head.sonar_angle);
    let sonar_angle = decide(
        combos[0].found.head.sonar_angle,
        start.sonar_angle,
        angle_vote,
    );
    let sweep = (start.sweep != SweepTiming::Logged).then(|| {
        let vote = vote_on(combos, &block_costs, |c| c.sweep);
        decide(combos[0].sweep, start.sweep, vote)
    });
    (sonar_angle, sweep)
}

fn summarise(
    prepared: &prepare::Prepared,
    config: &CalibrationConfig,
    blocks: &Blocks,
    returns: usize,
) -> result::CalibrationSummary {
    result::CalibrationSummary {
        rotations: prepared.rotations,
        window_rotations: config.window_rotations,
        windows: prepared.objectives[0].1.windows(),
        blocks: blocks.len(),
        returns,
        median_range_m: prepared.median_range_m,
        cell_size_m: prepared.cell_size_m,
        cell_size_derived: prepared.cell_size_derived,
        binary_intensities: prepared.binary_intensities,
        evaluations: prepared
            .objectives
            .iter()
            .map(|(_, o)| o.evaluations())
            .sum(),
    }
}

/// One searched combination: which objective (sweep) and its best head.
#[derive(Clone, Copy, Debug)]
struct Combo {
    objective: usize,
    sweep: SweepTiming,
    found: Found,
}

/// The block vote for the best combination's value of one discrete choice
/// (`value` of a combination) against every combination with another.
fn vote_on<T: PartialEq>(
    combos: &[Combo],
    block_costs: &[Vec<f64>],
    value: impl Fn(&Combo) -> T,
) -> Vote {
    let winner = value(&combos[0]);
    let others: Vec<usize> = (1..combos.len())
        .filter(|&k| value(&combos[k]) != winner)
        .collect();
    let gap_bits = others
        .iter()
        .map(|&k| combos[k].found.mean_entropy_bits - combos[0].found.mean_entropy_bits)
        .fold(f64::INFINITY, f64::min);
    let contenders: Vec<Vec<f64>> = others.iter().map(|&k| block_costs[k].clone()).collect();
    uncertainty::vote(&block_costs[0], &contenders, gap_bits)
}

fn decide<T: Copy>(estimate: T, mission: T, vote: Vote) -> DiscreteEstimate<T> {
    DiscreteEstimate {
        estimate,
        mission,
        value: if vote.determined { estimate } else { mission },
        vote,
    }
}

fn assemble(
    summary: result::CalibrationSummary,
    combos: &[Combo],
    sonar_angle: DiscreteEstimate<AngleDirection>,
    sweep: Option<DiscreteEstimate<SweepTiming>>,
    head: head::HeadEstimates,
    mission: &Mission,
) -> Calibration {
    let combinations = combos
        .iter()
        .map(|c| Combination {
            sonar_angle: c.found.head.sonar_angle,
            sweep: c.sweep,
            yaw_rad: c.found.head.yaw_rad,
            mean_entropy_bits: c.found.mean_entropy_bits,
        })
        .collect();
    let mut calibration = Calibration {
        summary,
        combinations,
        sonar_angle,
        sweep,
        sonar_yaw_rad: head.yaw,
        sonar_x_m: head.x,
        sonar_y_m: head.y,
        heading_offset_rad: ContinuousEstimate::kept(
            mission.mounting.heading_offset_rad,
            result::HEADING_OFFSET_REASON,
        ),
        mounting: mission.mounting.clone(),
    };
    calibration.mounting = calibration
        .mounting_config()
        .mounting_over(&mission.mounting);
    calibration
}

#[cfg(test)]
mod tests;
