//! `report.json` of `echofield localize`: the verdict, convergence,
//! kidnappings and recoveries, accuracy against ground truth, particles
//! and time per rotation, and one record per rotation.
//!
//! Accuracy: the estimates live in the map's world frame; they are moved
//! into the ground truth's frame by the map run's own fit onto its ground
//! truth ([`super::map::PriorMap::truth_from_map`]), not fitted again, so
//! that an offset of the localisation shows. `ate_rmse_m` counts the
//! rotations from the first convergence on (the time to converge is
//! reported apart). Dead reckoning over the same rotations is fitted onto
//! the ground truth (its best case: its own frame is unrelated to the
//! map's). The offline smoothed trajectory ([`super::smooth`]) is
//! measured over the same rotations, both ways.

use super::map::PriorMap;
use super::replay::Localized;
use crate::eval::align_se2;
use crate::matching::ground_truth_at;
use crate::slam::RunInfo;
use echofield_frontend::localization::{LocalizationConfig, LocalizationState};
use echofield_graph::Se2;
use nalgebra::Vector2;
use serde::Serialize;

/// The whole report.
#[derive(Clone, Debug, Serialize)]
pub struct LocalizeReport {
    pub echofield_version: String,
    pub mission: String,
    /// The map's mission and its run folder.
    pub map_mission: String,
    pub map_run: String,
    pub map_nodes: usize,
    /// Area the map's sonar covered, m².
    pub map_covered_area_m2: f64,
    pub rotations: usize,
    /// `localised` when the last rotation's state is localised or coasting,
    /// else `not_localised`.
    pub verdict: String,
    /// Index (in `per_rotation`) of the first localised rotation.
    pub converged_rotation: Option<usize>,
    /// Time from the first rotation to the first localised one, s.
    pub time_to_converge_s: Option<f64>,
    /// Share of the rotations from the first convergence on that are
    /// localised or coasting.
    pub localised_share: f64,
    /// Times the filter, once converged, judged itself lost (kidnapped)
    /// and re-seeded. A loss during the global search, before the first
    /// convergence, is the search starting over and is not counted.
    pub recoveries: Vec<Recovery>,
    /// Fit of the scans at the estimates (mean field value of the points
    /// inside the map's coverage): mean and largest over the rotations
    /// with a scan that sees the map.
    pub fit_mean: f64,
    pub fit_max: f64,
    /// ATE RMSE of the estimates from the first convergence on, m (map
    /// frame moved into the ground truth's by the map run's fit).
    pub ate_rmse_m: Option<f64>,
    /// The same estimates fitted onto the ground truth (SE(2)), m.
    pub ate_rmse_aligned_m: Option<f64>,
    /// Forward dead reckoning over the same rotations, fitted, m.
    pub ate_rmse_dead_reckoning_m: Option<f64>,
    /// The offline smoothed trajectory ([`super::smooth`]) over the same
    /// rotations: through the map run's fit, and fitted, m (`None`
    /// without ground truth or without a smoothed trajectory).
    pub ate_rmse_smoothed_m: Option<f64>,
    pub ate_rmse_smoothed_aligned_m: Option<f64>,
    /// Largest position error after convergence, m.
    pub max_error_m: Option<f64>,
    /// Rotations more than [`FAR_FROM_MAP_M`] from any map node (true
    /// position when known, else the estimate), and the ATE over them.
    pub rotations_far_from_map: usize,
    pub ate_rmse_far_from_map_m: Option<f64>,
    /// Rotations whose motion from the previous one took the sonar's
    /// sequential match as well as the dead reckoning
    /// ([`super::odometry`]).
    pub sonar_motion_rotations: usize,
    pub particles: Stats,
    /// Wall time of the filter step per rotation, ms.
    pub filter_time_ms: Stats,
    /// Wall time per rotation with the scan's building, ms.
    pub rotation_time_ms: Stats,
    /// Median time between rotations in the mission, s.
    pub rotation_period_s: f64,
    pub config: LocalizationConfig,
    pub run: Option<RunInfo>,
    pub per_rotation: Vec<RotationRecord>,
}

/// Distance from the map's nodes beyond which a rotation counts as "far
/// from the map" in the report, m.
pub const FAR_FROM_MAP_M: f64 = 20.0;

/// A kidnapping detected and how long the filter took to localise again.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Recovery {
    /// Rotation (index in `per_rotation`) judged lost.
    pub lost_rotation: usize,
    /// First localised rotation after it, if any.
    pub relocalised_rotation: Option<usize>,
}

/// p50, p95, mean and max of a set of values.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Stats {
    pub p50: f64,
    pub p95: f64,
    pub mean: f64,
    pub max: f64,
}

impl Stats {
    pub fn of(values: &[f64]) -> Self {
        if values.is_empty() {
            return Self::default();
        }
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        let q = |f: f64| v[((v.len() - 1) as f64 * f).round() as usize];
        Self {
            p50: q(0.5),
            p95: q(0.95),
            mean: v.iter().sum::<f64>() / v.len() as f64,
            max: v[v.len() - 1],
        }
    }
}

/// One rotation.
#[derive(Clone, Debug, Serialize)]
pub struct RotationRecord {
    pub rotation_index: usize,
    pub stamp_s: f64,
    pub state: LocalizationState,
    /// The estimate, map frame.
    pub x_m: f64,
    pub y_m: f64,
    pub theta_rad: f64,
    pub spread_m: f64,
    pub heading_spread_rad: f64,
    pub particles: usize,
    pub fit: f64,
    pub coverage: f64,
    pub reseeded: bool,
    /// Distance of the estimate to the nearest map node, m.
    pub distance_to_map_m: f64,
    /// Position error against the ground truth (see the module doc), m.
    pub error_m: Option<f64>,
    /// The same for the particles' weighted mean (equal to `error_m` when
    /// the estimate is the mean), m.
    pub mean_error_m: Option<f64>,
    pub filter_ms: f64,
    pub build_ms: f64,
}

fn rmse(errors: &[f64]) -> Option<f64> {
    (!errors.is_empty())
        .then(|| (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt())
}

/// Fitted RMSE of `estimate` onto `reference` (pairs).
fn fitted_rmse(estimate: &[Vector2<f64>], reference: &[Vector2<f64>]) -> Option<f64> {
    if estimate.len() < 2 {
        return None;
    }
    let t = align_se2(estimate, reference);
    let errors: Vec<f64> = estimate
        .iter()
        .zip(reference)
        .map(|(p, q)| {
            let (x, y) = t.transform_xy(p.x, p.y);
            (q - Vector2::new(x, y)).norm()
        })
        .collect();
    rmse(&errors)
}

/// The report of `localized` on `map` (see the module doc).
pub fn build_report(
    localized: &Localized,
    map: &PriorMap,
    map_run: &str,
    config: &LocalizationConfig,
    run: Option<RunInfo>,
) -> LocalizeReport {
    let truth: Vec<Option<Se2>> = localized
        .rotations
        .iter()
        .map(|r| ground_truth_at(&localized.ground_truth, r.stamp_s))
        .collect();
    let per_rotation = rotation_records(localized, map, &truth);
    let converged = per_rotation
        .iter()
        .position(|r| r.state == LocalizationState::Localised);
    let accuracy = Accuracy::of(localized, map, &truth, &per_rotation, converged);
    let (fit_mean, fit_max) = fit_mean_and_max(&per_rotation, config.min_coverage);
    let column =
        |f: fn(&RotationRecord) -> f64| Stats::of(&per_rotation.iter().map(f).collect::<Vec<_>>());
    let localised_at_end = per_rotation.last().is_some_and(|r| r.state.is_localised());
    LocalizeReport {
        echofield_version: env!("CARGO_PKG_VERSION").to_string(),
        mission: localized.mission_name.clone(),
        map_mission: map.mission.display().to_string(),
        map_run: map_run.to_string(),
        map_nodes: map.nodes.len(),
        map_covered_area_m2: map.field.covered_area_m2(),
        rotations: per_rotation.len(),
        verdict: if localised_at_end {
            "localised"
        } else {
            "not_localised"
        }
        .to_string(),
        converged_rotation: converged,
        time_to_converge_s: converged.map(|k| per_rotation[k].stamp_s - per_rotation[0].stamp_s),
        localised_share: localised_share(converged.map_or(&[], |k| &per_rotation[k..])),
        recoveries: recoveries(&per_rotation),
        fit_mean,
        fit_max,
        ate_rmse_m: rmse(&accuracy.errors),
        ate_rmse_aligned_m: fitted_rmse(&accuracy.estimate, &accuracy.truth),
        ate_rmse_dead_reckoning_m: fitted_rmse(&accuracy.dead_reckoning, &accuracy.truth),
        ate_rmse_smoothed_m: rmse(&accuracy.smoothed_errors),
        ate_rmse_smoothed_aligned_m: fitted_rmse(&accuracy.smoothed, &accuracy.truth),
        max_error_m: accuracy.errors.iter().copied().reduce(f64::max),
        rotations_far_from_map: accuracy.far_from_map,
        ate_rmse_far_from_map_m: rmse(&accuracy.far_errors),
        sonar_motion_rotations: localized
            .rotations
            .iter()
            .filter(|r| r.sonar_motion)
            .count(),
        particles: column(|r| r.particles as f64),
        filter_time_ms: column(|r| r.filter_ms),
        rotation_time_ms: column(|r| r.filter_ms + r.build_ms),
        rotation_period_s: rotation_period_s(localized),
        config: config.clone(),
        run,
        per_rotation,
    }
}

/// One record per rotation; `truth` the ground truth at each rotation's
/// stamp (mission frame).
fn rotation_records(
    localized: &Localized,
    map: &PriorMap,
    truth: &[Option<Se2>],
) -> Vec<RotationRecord> {
    localized
        .rotations
        .iter()
        .zip(truth)
        .map(|(r, t)| {
            let e = r.step.estimate;
            let error_of = |p: Se2| {
                t.zip(map.truth_from_map).map(|(t, m)| {
                    let (x, y) = m.transform_xy(p.x(), p.y());
                    (t.x() - x).hypot(t.y() - y)
                })
            };
            RotationRecord {
                rotation_index: r.rotation_index,
                stamp_s: r.stamp_s,
                state: r.step.state,
                x_m: e.x(),
                y_m: e.y(),
                theta_rad: e.theta(),
                spread_m: r.step.spread_m,
                heading_spread_rad: r.step.heading_spread_rad,
                particles: r.step.particles,
                fit: r.step.fit,
                coverage: r.step.coverage,
                reseeded: r.step.reseeded,
                distance_to_map_m: map.distance_to_nodes_m(e.x(), e.y()),
                error_m: error_of(e),
                mean_error_m: error_of(r.step.mean),
                filter_ms: 1e3 * r.filter_s,
                build_ms: 1e3 * r.build_s,
            }
        })
        .collect()
}

/// Share of `after` (the records from the first convergence on) that are
/// localised or coasting; 0 when empty.
fn localised_share(after: &[RotationRecord]) -> f64 {
    if after.is_empty() {
        return 0.0;
    }
    after.iter().filter(|r| r.state.is_localised()).count() as f64 / after.len() as f64
}

/// Mean and largest fit over the rotations whose scan sees the map
/// (coverage at least `min_coverage`); zeros without any.
fn fit_mean_and_max(per_rotation: &[RotationRecord], min_coverage: f64) -> (f64, f64) {
    let fits: Vec<f64> = per_rotation
        .iter()
        .filter(|r| r.coverage >= min_coverage)
        .map(|r| r.fit)
        .collect();
    if fits.is_empty() {
        return (0.0, 0.0);
    }
    let mean = fits.iter().sum::<f64>() / fits.len() as f64;
    (mean, fits.iter().copied().fold(0.0, f64::max))
}

/// Every rotation judged lost after the first localised one, with the
/// first localised one after it.
fn recoveries(per_rotation: &[RotationRecord]) -> Vec<Recovery> {
    let Some(first) = per_rotation
        .iter()
        .position(|r| r.state == LocalizationState::Localised)
    else {
        return Vec::new();
    };
    per_rotation
        .iter()
        .enumerate()
        .skip(first)
        .filter(|(_, r)| r.state == LocalizationState::Lost)
        .map(|(i, _)| Recovery {
            lost_rotation: i,
            relocalised_rotation: per_rotation[i + 1..]
                .iter()
                .position(|r| r.state == LocalizationState::Localised)
                .map(|j| i + 1 + j),
        })
        .collect()
}

/// Median time between consecutive rotations, s (0 with fewer than two).
fn rotation_period_s(localized: &Localized) -> f64 {
    let periods: Vec<f64> = localized
        .rotations
        .windows(2)
        .map(|w| w[1].stamp_s - w[0].stamp_s)
        .collect();
    Stats::of(&periods).p50
}

/// The rotations from the first convergence on, against the ground truth
/// (see the module doc).
struct Accuracy {
    /// Position errors through the map run's fit, m.
    errors: Vec<f64>,
    /// The same for the smoothed trajectory, and its positions (map frame)
    /// at the rotations with ground truth; empty without one.
    smoothed_errors: Vec<f64>,
    smoothed: Vec<Vector2<f64>>,
    /// Estimates (map frame), dead reckoning (mission frame) and ground
    /// truth (its own frame) at the rotations with ground truth.
    estimate: Vec<Vector2<f64>>,
    dead_reckoning: Vec<Vector2<f64>>,
    truth: Vec<Vector2<f64>>,
    /// Rotations more than [`FAR_FROM_MAP_M`] from every map node, and
    /// their errors.
    far_from_map: usize,
    far_errors: Vec<f64>,
}

impl Accuracy {
    fn of(
        localized: &Localized,
        map: &PriorMap,
        truth: &[Option<Se2>],
        per_rotation: &[RotationRecord],
        converged: Option<usize>,
    ) -> Self {
        let start = converged.unwrap_or(per_rotation.len());
        let mut a = Self {
            errors: per_rotation[start..]
                .iter()
                .filter_map(|r| r.error_m)
                .collect(),
            smoothed_errors: Vec::new(),
            smoothed: Vec::new(),
            estimate: Vec::new(),
            dead_reckoning: Vec::new(),
            truth: Vec::new(),
            far_from_map: 0,
            far_errors: Vec::new(),
        };
        let rotations = localized.rotations.iter().zip(truth).enumerate();
        for (k, (r, t)) in rotations.skip(start) {
            // Where the vehicle was, in the map frame: the ground truth
            // when known, else the estimate.
            let place = match (t, map.truth_from_map) {
                (Some(t), Some(m)) => m.inverse().compose(t),
                _ => r.step.estimate,
            };
            if map.distance_to_nodes_m(place.x(), place.y()) > FAR_FROM_MAP_M {
                a.far_from_map += 1;
                a.far_errors.extend(per_rotation[k].error_m);
            }
            if let Some(t) = t {
                if let Some(s) = localized.smoothed.as_ref().and_then(|s| s.get(k)) {
                    a.smoothed.push(s.translation());
                    if let Some(m) = map.truth_from_map {
                        let (x, y) = m.transform_xy(s.x(), s.y());
                        a.smoothed_errors.push((t.x() - x).hypot(t.y() - y));
                    }
                }
                a.estimate.push(r.step.estimate.translation());
                a.dead_reckoning.push(r.dead_reckoning.translation());
                a.truth.push(t.translation());
            }
        }
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use LocalizationState::*;

    fn records(states: &[LocalizationState]) -> Vec<RotationRecord> {
        states
            .iter()
            .enumerate()
            .map(|(k, &state)| RotationRecord {
                rotation_index: k,
                stamp_s: k as f64,
                state,
                x_m: 0.0,
                y_m: 0.0,
                theta_rad: 0.0,
                spread_m: 0.1,
                heading_spread_rad: 0.01,
                particles: 1000,
                fit: 0.9,
                coverage: 1.0,
                reseeded: state == Lost,
                distance_to_map_m: 0.0,
                error_m: None,
                mean_error_m: None,
                filter_ms: 1.0,
                build_ms: 1.0,
            })
            .collect()
    }

    #[test]
    fn only_losses_after_the_first_convergence_are_recoveries() {
        // The global search starts over at 1 (not a kidnapping); converged
        // at 3; kidnapped and lost at 5, localised again at 7; lost at 8
        // and never again.
        let states = [
            Searching, Lost, Searching, Localised, Localised, Lost, Searching, Localised, Lost,
            Searching,
        ];
        let found = recoveries(&records(&states));
        assert_eq!(
            found,
            vec![
                Recovery {
                    lost_rotation: 5,
                    relocalised_rotation: Some(7)
                },
                Recovery {
                    lost_rotation: 8,
                    relocalised_rotation: None
                },
            ]
        );
        // Never converged: no recovery.
        assert!(recoveries(&records(&[Searching, Lost, Searching])).is_empty());
    }
}
