//! Where a mission lies on the map of others: a global search of the
//! mission's scans over a likelihood field of the map (eq. 5), verified by
//! several independent probes that must agree.
//!
//! The map is the acoustic images `I_j` of the placed missions' nodes at
//! their poses, blended by max into one [`LikelihoodField`] (as
//! `echofield localize` builds its prior map). A *probe* is a short
//! stretch of the new mission: the scans `S_k` of [`PROBE_NODES`]
//! consecutive nodes placed at the mission's own optimised poses in the
//! frame of the middle node (a few rotations see far more of a harbour
//! than one, which makes a wrong place much less likely to fit).
//!
//! Each probe is searched over every covered cell of a coarse, widely
//! smoothed field (cells of [`COARSE_CELL_M`]) and over headings within
//! [`HEADING_WINDOW_RAD`] of the mission's own: the heading is the one
//! thing two missions of a vehicle share, since both dead reckonings take
//! it from the compass, whereas no start position is assumed. The search
//! is a branch and bound over a max-pooled pyramid of the coarse field
//! ([`super::search`]): it returns exactly the best poses of the
//! exhaustive grid search while scoring a small part of them. The best
//! coarse peaks are refined by a local climb on a fine field.
//!
//! With a [`PlacementPrior`] (from position fixes of both missions in one
//! frame, [`prior_from_fixes`]) each probe is searched only within
//! [`PRIOR_GATE_SIGMAS`] of where the prior puts it. When the probes do not
//! agree there, the prior is not trusted: the global search runs as
//! without it, and a placement found far from the prior is reported as
//! such ([`PriorCheck`]). Each probe
//! then implies one `map_from_mission`; the placement is accepted only
//! when at least [`MIN_AGREEING`] probes agree with one another (each
//! predicts the others' map poses within [`AGREE_M`] and [`AGREE_RAD`]),
//! and is refined on all the agreeing probes together. Probes over ground
//! the map never saw fit anywhere or nowhere and do not agree by chance;
//! a mission in another place gives no agreeing set and no placement.

use super::search::{CoarseIndex, Region};
use crate::eval::align_se2;
use crate::slam::SlamOutput;
use crate::slam::outputs::mosaic::{MosaicConfig, build_mosaic};
use anyhow::{Result, bail};
use echofield_frontend::localization::LikelihoodField;
use echofield_graph::Se2;
use echofield_graph::se2::wrap_angle;
use nalgebra::Point2;
use rayon::prelude::*;
use serde::Serialize;
use std::f64::consts::PI;

/// Nodes per probe (consecutive; the middle one is the probe's frame).
pub const PROBE_NODES: usize = 5;
/// Probes spread evenly along a mission.
pub const PROBES: usize = 10;
/// Scan points per probe at most (every n-th), for the coarse search.
const COARSE_POINTS: usize = 200;
/// Scan points per probe at most for the refinement.
const FINE_POINTS: usize = 1500;
/// Cell and smoothing of the coarse field, m: wide enough that the true
/// pose scores near its peak from the nearest grid pose.
const COARSE_CELL_M: f64 = 0.5;
const COARSE_SMOOTHING_M: f64 = 1.0;
/// Heading step of the coarse grid, rad (2°: 0.7 m at 20 m range, within
/// the coarse field's smoothing). The translation step is one coarse
/// cell.
const COARSE_STEP_RAD: f64 = 2.0 * PI / 180.0;
/// Headings searched on either side of the mission's own, rad. Both
/// dead reckonings take their heading from the compass, so the missions'
/// frames differ by little more than the compasses' biases.
pub const HEADING_WINDOW_RAD: f64 = 10.0 * PI / 180.0;
/// Cell and smoothing of the fine field, m.
const FINE_CELL_M: f64 = 0.2;
const FINE_SMOOTHING_M: f64 = 0.3;
/// Coarse peaks refined per probe, at least this far apart, m.
const PEAKS: usize = 6;
const PEAK_SEPARATION_M: f64 = 4.0;
/// Probes that must agree for a placement.
pub const MIN_AGREEING: usize = 3;
/// Other agreeing sets (of at least two probes) kept as alternative
/// placements, at most: tried, in order, only when the placement is
/// confirmed by no cross-mission loop (`confirm_placement` in `super`).
pub const MAX_ALTERNATIVES: usize = 4;
/// Agreement of two probes: each one's `map_from_mission` puts the other
/// probe's middle node within these of where that probe found it.
pub const AGREE_M: f64 = 1.5;
pub const AGREE_RAD: f64 = 3.0 * PI / 180.0;
/// A probe counts only when this share of its points falls on the map's
/// coverage and their mean field value (the fit) is at least
/// [`MIN_FIT`] at its best pose. The floor only drops probes that fit
/// nowhere; the agreement of several probes, not this threshold, is what
/// tells a right placement from a wrong one (a wrong pose on a cluttered
/// map can fit as well as the right one).
const MIN_COVERAGE: f64 = 0.5;
pub const MIN_FIT: f64 = 0.6;

/// One probe's search.
#[derive(Clone, Debug, Serialize)]
pub struct ProbeResult {
    /// The probe's middle node (index in its mission).
    pub node: usize,
    /// Nodes whose scans it holds.
    pub nodes: usize,
    /// Where the search put the middle node, map frame.
    #[serde(serialize_with = "se2_array")]
    pub map_from_node: Se2,
    /// The `map_from_mission` this implies.
    #[serde(serialize_with = "se2_array")]
    pub map_from_mission: Se2,
    /// Mean fine-field value under its covered points at that pose (0-1).
    pub fit: f64,
    /// Share of its points on the map's coverage (0-1).
    pub coverage: f64,
    /// Score of the best refined peak at least [`PEAK_SEPARATION_M`] away
    /// over the best one's (1: as good elsewhere; 0: nothing else).
    pub second_peak_ratio: f64,
    /// Passes [`MIN_FIT`] and the coverage minimum.
    pub usable: bool,
    /// In the agreeing set the placement was made from.
    pub agrees: bool,
    /// Bounds and scores the coarse search evaluated (of the last search,
    /// when the prior's was followed by the global one).
    pub coarse_evaluations: usize,
}

/// A prior on `map_from_mission`, e.g. from position fixes
/// ([`prior_from_fixes`]).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct PlacementPrior {
    #[serde(serialize_with = "se2_array")]
    pub map_from_mission: Se2,
    /// Standard deviation of the position it gives each of the mission's
    /// nodes, m (> 0).
    pub sigma_m: f64,
    /// Standard deviation of its heading, rad (> 0).
    pub sigma_rad: f64,
}

/// A prior's fate.
#[derive(Clone, Debug, Serialize)]
pub struct PriorCheck {
    pub prior: PlacementPrior,
    /// Whether the placement was found within the prior's bounds (else
    /// by the global search, after the probes did not agree there).
    pub bounded: bool,
    /// Mean distance between the placement and the prior at the mission's
    /// nodes, m, and in the prior's sigmas (`None`: not placed).
    pub offset_m: Option<f64>,
    pub offset_sigmas: Option<f64>,
    /// The placement lies within [`PRIOR_GATE_SIGMAS`] of the prior.
    pub consistent: bool,
}

/// A prior bounds each probe's search to this many of its sigmas.
pub const PRIOR_GATE_SIGMAS: f64 = 3.0;

/// The outcome of the search for one mission.
#[derive(Clone, Debug, Serialize)]
pub struct Placement {
    /// `map_from_mission` (the map frame is the first mission's world
    /// frame) when enough probes agreed; `None`: not placed.
    #[serde(serialize_with = "opt_se2_array")]
    pub map_from_mission: Option<Se2>,
    pub probes: Vec<ProbeResult>,
    /// Probes in the agreeing set.
    pub agreeing: usize,
    /// `map_from_mission` of the other agreeing sets of at least two
    /// probes (the largest first, at most [`MAX_ALTERNATIVES`]), each
    /// refined on its probes: the candidates when `map_from_mission` is
    /// confirmed by no cross-mission loop or missing.
    #[serde(skip)]
    pub alternatives: Vec<Se2>,
    /// Cross-mission loops its placement gets accepted before the merged
    /// solve (`None`: not placed, or not checked).
    pub confirming_loops: Option<usize>,
    /// The placement is the alternative of this index (0-based in the
    /// order above), taken because the largest agreeing set's placement
    /// was confirmed by no cross-mission loop or there was none; `None`:
    /// the largest set's.
    pub alternative: Option<usize>,
    /// The prior it was searched with, and whether the placement agrees
    /// with it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prior: Option<PriorCheck>,
    /// Wall time, s.
    pub time_s: f64,
}

pub(crate) fn se2_array<S: serde::Serializer>(p: &Se2, s: S) -> Result<S::Ok, S::Error> {
    [p.x(), p.y(), p.theta()].serialize(s)
}

fn opt_se2_array<S: serde::Serializer>(p: &Option<Se2>, s: S) -> Result<S::Ok, S::Error> {
    p.map(|p| [p.x(), p.y(), p.theta()]).serialize(s)
}

/// The map: a coarse field for the global search, a fine one for the
/// refinement.
pub struct MapFields {
    coarse: CoarseIndex,
    fine: LikelihoodField,
}

/// Radius within which `scan` has 90% of its points, m (0 when empty):
/// the footprint a node "saw", as `frontend::nodes` defines it.
pub fn footprint_m(points: &[Point2<f64>]) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let mut r: Vec<f64> = points.iter().map(|p| p.coords.norm()).collect();
    r.sort_by(f64::total_cmp);
    r[((r.len() - 1) as f64 * 0.9).round() as usize]
}

impl MapFields {
    /// The fields of the nodes of `runs`, each run's node `k` at
    /// `poses[run][k]` (map frame). Errors: no node with an image, a field
    /// that covers nothing.
    pub fn build(runs: &[(&SlamOutput, &[Se2])]) -> Result<Self> {
        let mut images = Vec::new();
        let mut footprints = Vec::new();
        for (run, poses) in runs {
            for (k, pose) in poses.iter().enumerate() {
                let (Some(stored), Some(scan)) = (run.images.get(k), run.scans.get(k)) else {
                    continue;
                };
                if stored.is_empty() || scan.is_empty() {
                    continue;
                }
                images.push((stored.image_once()?, *pose));
                footprints.push((*pose, footprint_m(&scan.points)));
            }
        }
        if images.is_empty() {
            bail!("the map has no node with an acoustic image");
        }
        let grids: Vec<_> = images.iter().map(|(i, p)| (i.grid(), *p)).collect();
        let field = |cell_m: f64, smoothing_m: f64| -> Result<LikelihoodField> {
            let mosaic = build_mosaic(&grids, &MosaicConfig::likelihood_field(cell_m))?;
            Ok(LikelihoodField::new(mosaic, &footprints, smoothing_m)?)
        };
        Ok(Self {
            coarse: CoarseIndex::new(&field(COARSE_CELL_M, COARSE_SMOOTHING_M)?),
            fine: field(FINE_CELL_M, FINE_SMOOTHING_M)?,
        })
    }
}

/// A probe: the scans of nodes `first..first + n` in the middle node's
/// frame.
struct Probe {
    node: usize,
    nodes: usize,
    points: Vec<Point2<f64>>,
}

/// The probes of `run` (its scans at `own`, the run's optimised poses).
fn probes(run: &SlamOutput, own: &[Se2]) -> Vec<Probe> {
    let n = own.len().min(run.scans.len());
    if n < PROBE_NODES {
        return Vec::new();
    }
    let half = PROBE_NODES / 2;
    let count = PROBES.min(n / PROBE_NODES).max(1);
    (0..count)
        .map(|i| {
            // Middles spread evenly over half..n-1-half.
            let span = n - 1 - 2 * half;
            let middle = half + (i * span + span / 2) / count;
            let middle_from_world = own[middle].inverse();
            let mut points = Vec::new();
            let mut nodes = 0;
            let window = middle - half..=middle + half;
            for ((k, pose), scan) in window
                .clone()
                .zip(&own[window.clone()])
                .zip(&run.scans[window])
            {
                if scan.is_empty() || run.nodes.get(k).is_some_and(|r| r.in_dvl_gap) {
                    continue;
                }
                nodes += 1;
                let middle_from_k = middle_from_world.compose(pose);
                points.extend(scan.points.iter().map(|p| middle_from_k.transform_point(p)));
            }
            Probe {
                node: middle,
                nodes,
                points,
            }
        })
        .filter(|p| !p.points.is_empty())
        .collect()
}

/// Every `n`-th of `points` so that at most `max` remain.
fn thinned(points: &[Point2<f64>], max: usize) -> Vec<Point2<f64>> {
    let stride = points.len().div_ceil(max.max(1)).max(1);
    points.iter().step_by(stride).copied().collect()
}

/// Places the mission of `run` (its nodes at `own`, its own frame) on
/// `map` (see the module doc), within the bounds of `prior` first when
/// there is one.
pub fn place(
    map: &MapFields,
    run: &SlamOutput,
    own: &[Se2],
    prior: Option<&PlacementPrior>,
) -> Placement {
    let start = std::time::Instant::now();
    let probes = probes(run, own);
    let global = |node: &Se2| Region {
        disc: None,
        centre_rad: node.theta(),
        step_rad: COARSE_STEP_RAD,
        steps: (HEADING_WINDOW_RAD / COARSE_STEP_RAD).round() as i64,
    };
    let mut placement = None;
    if let Some(prior) = prior {
        let bounded = |node: &Se2| {
            let predicted = prior.map_from_mission.compose(node);
            let window = (PRIOR_GATE_SIGMAS * prior.sigma_rad).min(HEADING_WINDOW_RAD);
            Region {
                disc: Some((
                    predicted.x(),
                    predicted.y(),
                    PRIOR_GATE_SIGMAS * prior.sigma_m + map.coarse.cell_m(),
                )),
                centre_rad: predicted.theta(),
                step_rad: COARSE_STEP_RAD,
                steps: (window / COARSE_STEP_RAD).ceil().max(1.0) as i64,
            }
        };
        let found = search(map, &probes, own, bounded);
        if found.map_from_mission.is_some() {
            placement = Some((found, true));
        }
    }
    let (found, bounded) = placement.unwrap_or_else(|| (search(map, &probes, own, global), false));
    let Found {
        map_from_mission,
        results: probes,
        agreeing,
        alternatives,
    } = found;
    let prior = prior.map(|prior| {
        let offset_m = map_from_mission.map(|t| {
            own.iter()
                .map(|p| distance_m(&t.compose(p), &prior.map_from_mission.compose(p)))
                .sum::<f64>()
                / own.len().max(1) as f64
        });
        let offset_sigmas = offset_m.map(|d| d / prior.sigma_m);
        PriorCheck {
            prior: *prior,
            bounded,
            offset_m,
            offset_sigmas,
            consistent: offset_sigmas.is_some_and(|s| s <= PRIOR_GATE_SIGMAS),
        }
    });
    Placement {
        map_from_mission,
        agreeing,
        alternatives,
        confirming_loops: None,
        alternative: None,
        probes,
        prior,
        time_s: start.elapsed().as_secs_f64(),
    }
}

/// What [`search`] found.
struct Found {
    map_from_mission: Option<Se2>,
    results: Vec<ProbeResult>,
    /// Probes in the agreeing set.
    agreeing: usize,
    /// See [`Placement::alternatives`].
    alternatives: Vec<Se2>,
}

/// Searches every probe over its `region` (a function of its middle
/// node's own pose), then the agreeing sets and the joint refinement of
/// each: the largest set (of at least [`MIN_AGREEING`]) gives the
/// placement, the others of at least two probes the alternatives.
fn search(
    map: &MapFields,
    probes: &[Probe],
    own: &[Se2],
    region: impl Fn(&Se2) -> Region + Sync,
) -> Found {
    let mut results: Vec<ProbeResult> = probes
        .par_iter()
        .map(|p| search_probe(map, p, &own[p.node], &region(&own[p.node])))
        .collect();
    let sets = agreeing_sets(&results, own);
    let refined = |set: &[usize]| {
        let chosen: Vec<&Probe> = set.iter().map(|&i| &probes[i]).collect();
        refine_jointly(map, &chosen, own, results[set[0]].map_from_mission)
    };
    let best = sets.first().filter(|set| set.len() >= MIN_AGREEING);
    let map_from_mission = best.map(|set| refined(set));
    let alternatives = sets
        .iter()
        .skip(usize::from(best.is_some()))
        .filter(|set| set.len() >= 2)
        .take(MAX_ALTERNATIVES)
        .map(|set| refined(set))
        .collect();
    if let Some(set) = best {
        for &i in set {
            results[i].agrees = true;
        }
    }
    Found {
        map_from_mission,
        results,
        agreeing: sets.first().map_or(0, Vec::len),
        alternatives,
    }
}

/// Position fixes of one mission in a frame common to every mission (e.g.
/// GPS fixes at the surface, projected onto one local plane): `(stamp_s,
/// [x_m, y_m])`, and their standard deviation per axis, m.
#[derive(Clone, Debug)]
pub struct PositionFixes {
    pub fixes: Vec<(f64, [f64; 2])>,
    pub sigma_m: f64,
}

impl PositionFixes {
    /// The fixes of `mission` (`None` when it has none): their positions,
    /// and as the one sigma the prior needs the RMS of their standard
    /// deviations (a few poor fixes among good ones widen it, rather than
    /// being hidden by a median).
    pub fn of_mission(mission: &echofield_frontend::sensors::Mission) -> Option<Self> {
        let fixes = &mission.position_fixes;
        if fixes.is_empty() {
            return None;
        }
        let sigma_m =
            (fixes.iter().map(|f| f.std_m.powi(2)).sum::<f64>() / fixes.len() as f64).sqrt();
        Some(Self {
            fixes: fixes.iter().map(|f| (f.stamp_s, [f.x_m, f.y_m])).collect(),
            sigma_m,
        })
    }
}

/// A fix counts for a node when its stamp is within this of the node's, s.
pub const FIX_MATCH_S: f64 = 1.0;
/// Fixes must spread at least this far (RMS distance from their centroid,
/// m) on each side to fix a heading.
pub const MIN_FIX_SPREAD_M: f64 = 5.0;

/// `(position at the node, fix)` for every node of `poses` with a fix
/// within [`FIX_MATCH_S`] of its stamp (the nearest).
fn fix_pairs(
    run: &SlamOutput,
    poses: &[Se2],
    fixes: &PositionFixes,
) -> Vec<(nalgebra::Vector2<f64>, nalgebra::Vector2<f64>)> {
    let mut sorted = fixes.fixes.clone();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    run.nodes
        .iter()
        .zip(poses)
        .filter_map(|(n, p)| {
            let i = sorted.partition_point(|f| f.0 < n.stamp_s);
            let nearest = [i.checked_sub(1), Some(i)]
                .into_iter()
                .flatten()
                .filter_map(|j| sorted.get(j))
                .min_by(|a, b| (a.0 - n.stamp_s).abs().total_cmp(&(b.0 - n.stamp_s).abs()))?;
            ((nearest.0 - n.stamp_s).abs() <= FIX_MATCH_S
                && nearest.1.iter().all(|v| v.is_finite()))
            .then(|| {
                (
                    p.translation(),
                    nalgebra::Vector2::new(nearest.1[0], nearest.1[1]),
                )
            })
        })
        .collect()
}

/// The SE(2) fit `common_from_poses` of `pairs`, its RMS residual and
/// the fixes' spread (m); `None` when the fixes spread less than
/// [`MIN_FIX_SPREAD_M`].
fn fit(pairs: &[(nalgebra::Vector2<f64>, nalgebra::Vector2<f64>)]) -> Option<(Se2, f64, f64)> {
    if pairs.len() < 2 {
        return None;
    }
    let (p, q): (Vec<_>, Vec<_>) = pairs.iter().copied().unzip();
    let n = q.len() as f64;
    let centroid = q.iter().sum::<nalgebra::Vector2<f64>>() / n;
    let spread = (q.iter().map(|v| (v - centroid).norm_squared()).sum::<f64>() / n).sqrt();
    if spread.is_nan() || spread < MIN_FIX_SPREAD_M {
        return None;
    }
    let t = align_se2(&p, &q);
    let rms = (p
        .iter()
        .zip(&q)
        .map(|(a, b)| (t.transform_point(&Point2::from(*a)).coords - b).norm_squared())
        .sum::<f64>()
        / n)
        .sqrt();
    Some((t, rms, spread))
}

/// The prior `map_from_mission` of the mission `run` (its nodes at
/// `own`, its own frame, with `fixes`) from the fixes of the map's
/// missions (`map`: each run with its nodes' map-frame poses and its
/// fixes, all in the same common frame): both sides fitted onto the
/// common frame, `map_from_mission = common_from_map⁻¹ ⊕
/// common_from_mission`. Its sigma adds, in quadrature, both sides' fix
/// sigmas and both fits' RMS residuals (which hold the runs' drift); its
/// heading sigma is that over the smaller spread of fixes. `None` when
/// either side has too few fixes at its nodes or they spread too little
/// to fix a heading ([`MIN_FIX_SPREAD_M`]).
pub fn prior_from_fixes(
    map: &[(&SlamOutput, &[Se2], &PositionFixes)],
    run: &SlamOutput,
    own: &[Se2],
    fixes: &PositionFixes,
) -> Option<PlacementPrior> {
    let map_pairs: Vec<_> = map
        .iter()
        .flat_map(|(r, poses, f)| fix_pairs(r, poses, f))
        .collect();
    let map_sigma = map.iter().map(|(_, _, f)| f.sigma_m).fold(0.0, f64::max);
    let (common_from_map, rms_map, spread_map) = fit(&map_pairs)?;
    let (common_from_mission, rms_mission, spread_mission) = fit(&fix_pairs(run, own, fixes))?;
    let sigma_m =
        (map_sigma.powi(2) + fixes.sigma_m.powi(2) + rms_map.powi(2) + rms_mission.powi(2))
            .sqrt()
            .max(f64::EPSILON);
    Some(PlacementPrior {
        map_from_mission: common_from_map.inverse().compose(&common_from_mission),
        sigma_m,
        sigma_rad: (sigma_m / spread_map.min(spread_mission)).max(f64::EPSILON),
    })
}

/// The search of one probe: the best coarse peaks over `region` by
/// branch and bound ([`CoarseIndex::peaks`], exactly the best poses of the
/// exhaustive grid search), then refined on the fine field.
fn search_probe(
    map: &MapFields,
    probe: &Probe,
    world_from_node: &Se2,
    region: &Region,
) -> ProbeResult {
    let coarse_points = thinned(&probe.points, COARSE_POINTS);
    let fine_points = thinned(&probe.points, FINE_POINTS);
    let found = map
        .coarse
        .peaks(&coarse_points, region, PEAKS, PEAK_SEPARATION_M);
    let mut refined: Vec<(f64, Se2)> = found
        .poses
        .iter()
        .map(|(_, p)| {
            let pose = climb(|q| map.fine.score(q, &fine_points, 1, 0.0).mean, *p);
            (map.fine.score(&pose, &fine_points, 1, 0.0).mean, pose)
        })
        .collect();
    refined.sort_by(|a, b| b.0.total_cmp(&a.0));
    let (best_score, best) = refined.first().copied().unwrap_or((0.0, *world_from_node));
    let second = refined
        .iter()
        .skip(1)
        .find(|(_, p)| distance_m(p, &best) >= PEAK_SEPARATION_M)
        .map_or(0.0, |(s, _)| *s);
    let at_best = map.fine.score(&best, &fine_points, 1, 0.0);
    let map_from_mission = best.compose(&world_from_node.inverse());
    ProbeResult {
        node: probe.node,
        nodes: probe.nodes,
        map_from_node: best,
        map_from_mission,
        fit: at_best.fit,
        coverage: at_best.coverage,
        second_peak_ratio: if best_score > 0.0 {
            second / best_score
        } else {
            1.0
        },
        usable: !found.poses.is_empty()
            && at_best.fit >= MIN_FIT
            && at_best.coverage >= MIN_COVERAGE,
        agrees: false,
        coarse_evaluations: found.evaluations,
    }
}

fn distance_m(a: &Se2, b: &Se2) -> f64 {
    (a.x() - b.x()).hypot(a.y() - b.y())
}

/// A local climb of `score` from `start` over `(x, y, θ)`, steps halved
/// from 0.5 m and 1° to 0.02 m and 0.04°. Written here because argmin's
/// derivative-free methods need a tolerance tuning of their own and the
/// field is piecewise bilinear; six neighbours per step are enough.
fn climb(score: impl Fn(&Se2) -> f64, start: Se2) -> Se2 {
    let mut pose = start;
    let mut best = score(&pose);
    let (mut step_m, mut step_rad) = (0.5, PI / 180.0);
    while step_m >= 0.02 {
        let mut improved = true;
        while improved {
            improved = false;
            for (dx, dy, dt) in [
                (step_m, 0.0, 0.0),
                (-step_m, 0.0, 0.0),
                (0.0, step_m, 0.0),
                (0.0, -step_m, 0.0),
                (0.0, 0.0, step_rad),
                (0.0, 0.0, -step_rad),
            ] {
                let q = Se2::new(pose.x() + dx, pose.y() + dy, pose.theta() + dt);
                let s = score(&q);
                if s > best {
                    (best, pose, improved) = (s, q, true);
                }
            }
        }
        step_m /= 2.0;
        step_rad /= 2.0;
    }
    pose
}

/// The sets of usable probes that agree with one another (see
/// [`AGREE_M`]): for each usable probe (the seed, first in its set, the
/// others in probe order) the probes that agree with it both ways. Sets
/// within an earlier one are dropped; the largest come first, equal sizes
/// in seed order (so the first is the largest set of the lowest seed).
fn agreeing_sets(results: &[ProbeResult], own: &[Se2]) -> Vec<Vec<usize>> {
    let agree = |a: &ProbeResult, b: &ProbeResult| {
        let predicted = a.map_from_mission.compose(&own[b.node]);
        distance_m(&predicted, &b.map_from_node) <= AGREE_M
            && wrap_angle(predicted.theta() - b.map_from_node.theta()).abs() <= AGREE_RAD
    };
    let mut sets: Vec<Vec<usize>> = results
        .iter()
        .enumerate()
        .filter(|(_, a)| a.usable)
        .map(|(i, a)| {
            let mut set = vec![i];
            set.extend(
                results
                    .iter()
                    .enumerate()
                    .filter(|(j, b)| *j != i && b.usable && agree(a, b) && agree(b, a))
                    .map(|(j, _)| j),
            );
            set
        })
        .collect();
    // Stable: equal sizes stay in seed order.
    sets.sort_by_key(|set| std::cmp::Reverse(set.len()));
    let mut kept: Vec<Vec<usize>> = Vec::new();
    for set in sets {
        if !kept.iter().any(|k| set.iter().all(|i| k.contains(i))) {
            kept.push(set);
        }
    }
    kept
}

/// `map_from_mission` refined on every agreeing probe at once, the climb
/// turning about the probes' centroid (a turn about the map's origin would
/// couple heading and position).
fn refine_jointly(map: &MapFields, probes: &[&Probe], own: &[Se2], start: Se2) -> Se2 {
    let clouds: Vec<(Se2, Vec<Point2<f64>>)> = probes
        .iter()
        .map(|p| (own[p.node], thinned(&p.points, FINE_POINTS)))
        .collect();
    let (cx, cy) = clouds.iter().fold((0.0, 0.0), |(x, y), (pose, _)| {
        let q = start.compose(pose);
        (x + q.x(), y + q.y())
    });
    let n = clouds.len().max(1) as f64;
    let centroid = Se2::new(cx / n, cy / n, 0.0);
    let about_centroid = |delta: &Se2| {
        centroid
            .compose(delta)
            .compose(&centroid.inverse())
            .compose(&start)
    };
    let score = |delta: &Se2| {
        let t = about_centroid(delta);
        clouds
            .iter()
            .map(|(pose, pts)| map.fine.score(&t.compose(pose), pts, 1, 0.0).mean)
            .sum::<f64>()
    };
    about_centroid(&climb(score, Se2::identity()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A usable probe of node `node` (own pose `own[node]`) that puts the
    /// mission at `map_from_mission`.
    fn probe(node: usize, own: &[Se2], map_from_mission: Se2) -> ProbeResult {
        ProbeResult {
            node,
            nodes: PROBE_NODES,
            map_from_node: map_from_mission.compose(&own[node]),
            map_from_mission,
            fit: 0.9,
            coverage: 0.9,
            second_peak_ratio: 0.5,
            usable: true,
            agrees: false,
            coarse_evaluations: 0,
        }
    }

    #[test]
    fn agreeing_sets_come_largest_first_without_their_subsets() {
        let own: Vec<Se2> = (0..6)
            .map(|k| Se2::new(10.0 * k as f64, 0.0, 0.0))
            .collect();
        let (right, wrong, lone) = (
            Se2::new(0.0, 0.0, 0.0),
            Se2::new(3.0, 1.0, 0.05),
            Se2::new(-20.0, 5.0, 0.0),
        );
        // Probes 1, 3 and 5 agree on `right`, 0 and 2 on `wrong`, 4 alone.
        let mut results: Vec<ProbeResult> = [wrong, right, wrong, right, lone, right]
            .iter()
            .enumerate()
            .map(|(k, t)| probe(k, &own, *t))
            .collect();
        assert_eq!(
            agreeing_sets(&results, &own),
            [vec![1, 3, 5], vec![0, 2], vec![4]]
        );
        // Equal sizes: the lowest seed's set first; an unusable probe is
        // in no set.
        results[5].usable = false;
        assert_eq!(
            agreeing_sets(&results, &own),
            [vec![0, 2], vec![1, 3], vec![4]]
        );
    }

    #[test]
    fn the_climb_finds_the_peak_of_a_smooth_bowl() {
        let target = Se2::new(1.3, -0.7, 0.05);
        let score = |p: &Se2| {
            -((p.x() - target.x()).powi(2)
                + (p.y() - target.y()).powi(2)
                + 100.0 * (p.theta() - target.theta()).powi(2))
        };
        let found = climb(score, Se2::new(0.0, 0.0, 0.0));
        assert!(distance_m(&found, &target) < 0.03, "{found:?}");
        assert!((found.theta() - target.theta()).abs() < 0.002, "{found:?}");
    }

    #[test]
    fn the_footprint_is_the_ninetieth_percentile_of_the_ranges() {
        let points: Vec<Point2<f64>> = (1..=10).map(|r| Point2::new(r as f64, 0.0)).collect();
        assert_eq!(footprint_m(&points), 9.0);
        assert_eq!(footprint_m(&[]), 0.0);
    }

    #[test]
    fn thinning_keeps_at_most_the_asked_number() {
        let points: Vec<Point2<f64>> = (0..1001).map(|i| Point2::new(i as f64, 0.0)).collect();
        assert!(thinned(&points, 300).len() <= 300);
        assert_eq!(thinned(&points[..10], 300).len(), 10);
    }
}
