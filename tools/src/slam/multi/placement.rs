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
//! smoothed field on a [`COARSE_STEP_M`] grid and over headings within
//! [`HEADING_WINDOW_RAD`] of the mission's own: the heading is the one
//! thing two missions of a vehicle share, since both dead reckonings take
//! it from the compass, whereas no start position is assumed. The best
//! coarse peaks are refined by a local climb on a fine field. Each probe
//! then implies one `map_from_mission`; the placement is accepted only
//! when at least [`MIN_AGREEING`] probes agree with one another (each
//! predicts the others' map poses within [`AGREE_M`] and [`AGREE_RAD`]),
//! and is refined on all the agreeing probes together. Probes over ground
//! the map never saw fit anywhere or nowhere and do not agree by chance;
//! a mission in another place gives no agreeing set and no placement.

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
/// Translation step of the coarse grid, m.
pub const COARSE_STEP_M: f64 = 1.0;
/// Heading step of the coarse grid, rad (2°: 0.7 m at 20 m range, within
/// the coarse field's smoothing).
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
}

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
    coarse: LikelihoodField,
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
            coarse: field(COARSE_CELL_M, COARSE_SMOOTHING_M)?,
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
/// `map` (see the module doc).
pub fn place(map: &MapFields, run: &SlamOutput, own: &[Se2]) -> Placement {
    let start = std::time::Instant::now();
    let probes = probes(run, own);
    let mut results: Vec<ProbeResult> = probes
        .par_iter()
        .map(|p| search_probe(map, p, &own[p.node]))
        .collect();
    let agreeing = agreeing_set(&results, own);
    let map_from_mission = if agreeing.len() >= MIN_AGREEING {
        for &i in &agreeing {
            results[i].agrees = true;
        }
        let chosen: Vec<&Probe> = agreeing.iter().map(|&i| &probes[i]).collect();
        Some(refine_jointly(
            map,
            &chosen,
            own,
            results[agreeing[0]].map_from_mission,
        ))
    } else {
        None
    };
    Placement {
        map_from_mission,
        agreeing: agreeing.len(),
        probes: results,
        time_s: start.elapsed().as_secs_f64(),
    }
}

/// The global search of one probe: coarse grid, then the best peaks
/// refined on the fine field.
fn search_probe(map: &MapFields, probe: &Probe, world_from_node: &Se2) -> ProbeResult {
    let coarse_points = thinned(&probe.points, COARSE_POINTS);
    let fine_points = thinned(&probe.points, FINE_POINTS);
    let field = &map.coarse;
    let grid = field.grid();
    let stride = (COARSE_STEP_M / grid.cell_size_m()).round().max(1.0) as usize;
    let width = grid.width();
    let steps = (HEADING_WINDOW_RAD / COARSE_STEP_RAD).round() as i64;
    // Every (score, pose) of the coarse grid over the covered cells.
    let mut scored: Vec<(f64, Se2)> = Vec::new();
    for &cell in field.covered_cells() {
        let (ix, iy) = (cell as usize % width, cell as usize / width);
        if ix % stride != 0 || iy % stride != 0 {
            continue;
        }
        let (x, y) = grid.cell_centre_m(ix as i64, iy as i64);
        for s in -steps..=steps {
            let theta = wrap_angle(world_from_node.theta() + s as f64 * COARSE_STEP_RAD);
            let pose = Se2::new(x, y, theta);
            let score = field.score(&pose, &coarse_points, 1, 0.0).mean;
            scored.push((score, pose));
        }
    }
    scored.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut peaks: Vec<Se2> = Vec::new();
    for (_, pose) in &scored {
        if peaks.len() >= PEAKS {
            break;
        }
        if peaks
            .iter()
            .all(|p| distance_m(p, pose) >= PEAK_SEPARATION_M)
        {
            peaks.push(*pose);
        }
    }
    let mut refined: Vec<(f64, Se2)> = peaks
        .iter()
        .map(|p| {
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
        usable: at_best.fit >= MIN_FIT && at_best.coverage >= MIN_COVERAGE,
        agrees: false,
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

/// The largest set of usable probes that agree with one another (see
/// [`AGREE_M`]), indices in probe order; the first is the set's seed.
fn agreeing_set(results: &[ProbeResult], own: &[Se2]) -> Vec<usize> {
    let agree = |a: &ProbeResult, b: &ProbeResult| {
        let predicted = a.map_from_mission.compose(&own[b.node]);
        distance_m(&predicted, &b.map_from_node) <= AGREE_M
            && wrap_angle(predicted.theta() - b.map_from_node.theta()).abs() <= AGREE_RAD
    };
    let mut best: Vec<usize> = Vec::new();
    for (i, a) in results.iter().enumerate() {
        if !a.usable {
            continue;
        }
        let set: Vec<usize> = results
            .iter()
            .enumerate()
            .filter(|(j, b)| b.usable && (*j == i || (agree(a, b) && agree(b, a))))
            .map(|(j, _)| j)
            .collect();
        if set.len() > best.len() {
            // The seed first.
            let mut ordered = vec![i];
            ordered.extend(set.into_iter().filter(|&j| j != i));
            best = ordered;
        }
    }
    best
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
