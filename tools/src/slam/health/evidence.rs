//! The figures [`super::assess`] judges a run by, gathered from what the
//! run produced and nothing else (no ground truth).
//!
//! - **Sequential matches** against the odometry they were searched
//!   around: how many were attempted, matched and accepted (and why not);
//!   the squared Mahalanobis distance of each match from its odometry prior
//!   under the sum of both covariances ([`SequentialRecord::prior_chi2`],
//!   3 degrees of freedom); and two fits that show a *systematic*
//!   disagreement, over the matched pairs (odometry `(t_o, θ_o)`, match
//!   `(t_m, θ_m)`, translations in the frame of the older node):
//!
//!   ```text
//!   θ_m ≈ a · θ_o                                  (rotation slope)
//!   t_m ≈ c · t_o + (R(θ_o) − I) · d               (translation fit)
//!   ```
//!
//!   with `c` complex (a translation read as `x + i y`). A head turned
//!   `δ` from where the mounting puts it gives `c = e^{iδ}`; a head whose
//!   angle runs the other way gives mirrored rotations, `a = −1`; a head
//!   sitting at `d` from where the mounting puts it (same yaw) makes each
//!   match see the motion of that point, `t_o + R(θ_o) d − d`. Agreement is
//!   `a = 1`, `c = 1`, `d = 0`. The search windows are centred on the
//!   odometry, so a large error shows only in part in the fits (and more
//!   in the rejections).
//! - **Loop closures**: candidates matched and accepted.
//! - **Map sharpness** ([`echofield_frontend::sharpness`]): every node's
//!   scan `S_k` placed at the node's dead-reckoning pose and at its
//!   optimised pose, on cells of [`MAP_CELL_M`]. The scans are built once,
//!   so the two maps differ by the node poses alone.

use crate::slam::node_record::NodeRecord;
use echofield_frontend::loops::{LoopRecord, RejectReason, SequentialRecord};
use echofield_frontend::nodes::NodeData;
use echofield_frontend::sharpness::{Sharpness, sharpness};
use echofield_graph::Se2;
use nalgebra::{Matrix4, Vector2, Vector4};
use serde::Serialize;
use std::collections::BTreeMap;

/// Cell size of the sharpness maps, metres: about the width of the bands
/// in which walls arrive along range, so that a wall seen twice shares its
/// cells when the poses agree to a fraction of a cell.
pub const MAP_CELL_M: f64 = 0.5;

/// What the sequential matches say about the odometry (module doc).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct SequentialEvidence {
    /// Pairs that were searched (both nodes with data, outside DVL gaps).
    pub attempted: usize,
    /// Of which the matcher found a pose.
    pub matched: usize,
    /// Of which became sequential edges.
    pub accepted: usize,
    /// `accepted / attempted`; `None` without attempts.
    pub accepted_share: Option<f64>,
    /// Median over the matched pairs of the squared Mahalanobis distance
    /// between match and odometry (3 degrees of freedom: 2.37 when both
    /// covariances are honest).
    pub median_chi2: Option<f64>,
    /// Slope `a` of `θ_match ≈ a · θ_odometry` (1 when the sonar turns as
    /// the vehicle does, negative for a mirrored angle convention), and its
    /// standard error; `None` when the vehicle hardly turned.
    pub rotation_slope: Option<Fit>,
    /// The translation fit (module doc); `None` when the vehicle hardly
    /// moved.
    pub translation: Option<TranslationFit>,
    /// Attempted pairs that were not accepted, by the first check that
    /// failed.
    pub rejected_by: BTreeMap<RejectReason, usize>,
}

/// `t_match ≈ c · t_odometry + (R(θ_odometry) − I) d` (module doc).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TranslationFit {
    /// `Re c`: the matched motion along the odometry's direction, as a
    /// fraction of the odometry's (1 when they agree).
    pub along: Fit,
    /// `Im c`: the matched motion across it (0 when they agree; `sin δ`
    /// for a head turned `δ` from where the mounting puts it).
    pub across: Fit,
    /// `d = [x, y]`, metres, vehicle frame: how far the head sits from
    /// where the mounting puts it, as the turns between the matched pairs
    /// show it (0 when they agree); `None` when the vehicle turned too
    /// little.
    pub head_offset: Option<[Fit; 2]>,
}

/// A fitted coefficient and its standard error (spread of the residuals
/// about the fit, as if the pairs were independent).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Fit {
    pub value: f64,
    pub standard_error: f64,
    /// Pairs fitted.
    pub pairs: usize,
}

impl TranslationFit {
    /// `arg c`: the angle from the odometry's motion to the matched one,
    /// radians.
    pub fn direction_rad(&self) -> f64 {
        self.across.value.atan2(self.along.value)
    }

    /// `|d|` and its standard error, metres; `None` without `d`.
    pub fn head_offset_m(&self) -> Option<(f64, f64)> {
        let [x, y] = self.head_offset.as_ref()?;
        let norm = x.value.hypot(y.value);
        let spread = (x.value * x.standard_error).hypot(y.value * y.standard_error);
        let standard_error = if norm > 0.0 {
            spread / norm
        } else {
            x.standard_error.max(y.standard_error)
        };
        Some((norm, standard_error))
    }
}

/// Loop closures matched and accepted.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct LoopEvidence {
    /// Candidates the matcher was run on.
    pub matched: usize,
    pub accepted: usize,
    /// `accepted / matched`; `None` without matches.
    pub accepted_share: Option<f64>,
}

/// Sharpness of the map of placed scans under both trajectories.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct MapEvidence {
    /// Every scan at its node's dead-reckoning pose; `None` without scan
    /// points or when the map is too wide to grid.
    pub dead_reckoning: Option<Sharpness>,
    /// ... at its node's optimised pose.
    pub optimised: Option<Sharpness>,
    /// `optimised − dead_reckoning` entropy, bits (negative: the
    /// optimisation sharpened the map).
    pub entropy_change_bits: Option<f64>,
}

/// The vehicle must turn (sum of `θ_odometry²`, rad²) at least this much
/// over the matched pairs for the rotation slope: five pairs of 5°.
const MIN_ROTATION_RAD2: f64 = 5.0 * 0.087 * 0.087;
/// ... and move (sum of `|t_odometry|²`, m²) at least this much for the
/// translation factor: five pairs of 1 m.
const MIN_TRANSLATION_M2: f64 = 5.0;

/// The sequential evidence of `records`.
pub fn sequential(records: &[SequentialRecord]) -> SequentialEvidence {
    let attempted: Vec<&SequentialRecord> = records
        .iter()
        .filter(|r| {
            !matches!(
                r.rejected_by,
                Some(RejectReason::NoData | RejectReason::DvlGap)
            )
        })
        .collect();
    let pairs: Vec<(Se2, Se2)> = attempted
        .iter()
        .filter_map(|r| Some((r.prior, r.matched?)))
        .collect();
    let accepted = attempted.iter().filter(|r| r.accepted).count();
    let mut chi2: Vec<f64> = attempted.iter().filter_map(|r| r.prior_chi2).collect();
    let mut rejected_by = BTreeMap::new();
    for reason in attempted.iter().filter_map(|r| r.rejected_by) {
        *rejected_by.entry(reason).or_insert(0) += 1;
    }
    SequentialEvidence {
        attempted: attempted.len(),
        matched: pairs.len(),
        accepted,
        accepted_share: share(accepted, attempted.len()),
        median_chi2: median(&mut chi2),
        rotation_slope: rotation_slope(&pairs),
        translation: translation_fit(&pairs),
        rejected_by,
    }
}

/// The loop evidence of `records`.
pub fn loops(records: &[LoopRecord]) -> LoopEvidence {
    let matched = records
        .iter()
        .filter(|l| l.matched.is_some() || l.no_match.is_some())
        .count();
    let accepted = records.iter().filter(|l| l.accepted).count();
    LoopEvidence {
        matched,
        accepted,
        accepted_share: share(accepted, matched),
    }
}

/// The map sharpness of the nodes' scans under both trajectories.
pub fn map(nodes: &[NodeData], records: &[NodeRecord]) -> MapEvidence {
    let placed = |pose: fn(&NodeRecord) -> Se2| -> Option<Sharpness> {
        let points: Vec<Vector2<f64>> = nodes
            .iter()
            .zip(records)
            .flat_map(|(node, record)| {
                let world_from_vehicle = pose(record);
                node.scan.points.iter().map(move |p| {
                    let (x, y) = world_from_vehicle.transform_xy(p.x, p.y);
                    Vector2::new(x, y)
                })
            })
            .collect();
        if points.is_empty() {
            return None;
        }
        sharpness(&points, MAP_CELL_M).ok()
    };
    let dead_reckoning = placed(|r| r.dead_reckoning);
    let optimised = placed(|r| r.optimised);
    let entropy_change_bits = dead_reckoning
        .zip(optimised)
        .map(|(d, o)| o.entropy_bits - d.entropy_bits);
    MapEvidence {
        dead_reckoning,
        optimised,
        entropy_change_bits,
    }
}

fn share(part: usize, whole: usize) -> Option<f64> {
    (whole > 0).then(|| part as f64 / whole as f64)
}

/// The median of `values` (the mean of the two middle ones for an even
/// count; `None` when empty); sorts them.
pub(crate) fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    Some(if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    })
}

/// Least-squares slope through the origin of `θ_match` on `θ_odometry`.
fn rotation_slope(pairs: &[(Se2, Se2)]) -> Option<Fit> {
    let (mut oo, mut om, mut mm) = (0.0, 0.0, 0.0);
    for (odometry, matched) in pairs {
        let (o, m) = (odometry.theta(), matched.theta());
        oo += o * o;
        om += o * m;
        mm += m * m;
    }
    if pairs.len() < 3 || oo < MIN_ROTATION_RAD2 {
        return None;
    }
    let value = om / oo;
    // Σ(m - a o)² = Σm² - 2aΣom + a²Σo², one parameter.
    let residual = (mm - 2.0 * value * om + value * value * oo).max(0.0);
    let variance = residual / (pairs.len() - 1) as f64;
    Some(Fit {
        value,
        standard_error: (variance / oo).sqrt(),
        pairs: pairs.len(),
    })
}

/// Least-squares fit of `t_match ≈ c · t_odometry + (R(θ_odometry) − I) d`
/// over the matched pairs (module doc): `c` as `(Re c, Im c)` and the head
/// offset `d`, with their standard errors. `d` is `None` when the vehicle
/// turned too little to tell it.
fn translation_fit(pairs: &[(Se2, Se2)]) -> Option<TranslationFit> {
    let rows = |odometry: &Se2| {
        let o = odometry.translation();
        let (s, c) = odometry.theta().sin_cos();
        [
            Vector4::new(o.x, -o.y, c - 1.0, -s),
            Vector4::new(o.y, o.x, s, c - 1.0),
        ]
    };
    let (mut normal, mut rhs, mut mm) = (Matrix4::zeros(), Vector4::zeros(), 0.0);
    let (mut oo, mut turn) = (0.0, 0.0);
    for (odometry, matched) in pairs {
        let m = matched.translation();
        for (row, value) in rows(odometry).iter().zip([m.x, m.y]) {
            normal += row * row.transpose();
            rhs += row * value;
            mm += value * value;
        }
        oo += odometry.translation().norm_squared();
        turn += 2.0 - 2.0 * odometry.theta().cos();
    }
    if pairs.len() < 3 || oo < MIN_TRANSLATION_M2 {
        return None;
    }
    let with_offset = turn >= MIN_ROTATION_RAD2;
    let parameters = if with_offset { 4 } else { 2 };
    let normal = normal.view((0, 0), (parameters, parameters)).into_owned();
    let rhs = rhs.rows(0, parameters).into_owned();
    let inverse = normal.clone().try_inverse()?;
    let x = &inverse * &rhs;
    // Σ(m − J x)² = Σm² − xᵀ Jᵀm for the least-squares x.
    let residual = (mm - x.dot(&rhs)).max(0.0);
    let variance = residual / (2 * pairs.len()).saturating_sub(parameters).max(1) as f64;
    let fit = |i: usize| Fit {
        value: x[i],
        standard_error: (variance * inverse[(i, i)]).sqrt(),
        pairs: pairs.len(),
    };
    Some(TranslationFit {
        along: fit(0),
        across: fit(1),
        head_offset: with_offset.then(|| [fit(2), fit(3)]),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Odometry motions that move and turn both ways.
    fn odometry(n: usize) -> Vec<Se2> {
        (0..n)
            .map(|i| {
                let t = i as f64;
                Se2::new(
                    2.0 + (0.7 * t).sin(),
                    0.5 * (1.3 * t).cos(),
                    0.4 * (0.9 * t).sin(),
                )
            })
            .collect()
    }

    #[test]
    fn agreeing_matches_fit_the_identity() {
        let pairs: Vec<(Se2, Se2)> = odometry(30).into_iter().map(|o| (o, o)).collect();
        let slope = rotation_slope(&pairs).unwrap();
        assert!((slope.value - 1.0).abs() < 1e-12 && slope.standard_error < 1e-9);
        let fit = translation_fit(&pairs).unwrap();
        assert!((fit.along.value - 1.0).abs() < 1e-9, "{fit:?}");
        assert!(fit.across.value.abs() < 1e-9 && fit.direction_rad().abs() < 1e-9);
        let (offset_m, error_m) = fit.head_offset_m().unwrap();
        assert!(offset_m < 1e-9 && error_m < 1e-9, "{fit:?}");
    }

    #[test]
    fn a_head_off_where_the_mounting_puts_it_shows_in_the_fit() {
        // The head at d in the vehicle frame, turned δ = 40° from the
        // mounting's yaw: each match sees R(δ)ᵀ-rotated motion of that point.
        let (d, delta) = (Se2::new(1.5, 0.5, 0.0), 40_f64.to_radians());
        let frame = Se2::new(d.x(), d.y(), delta);
        let pairs: Vec<(Se2, Se2)> = odometry(30)
            .into_iter()
            .map(|o| (o, frame.inverse().compose(&o).compose(&frame)))
            .collect();
        let fit = translation_fit(&pairs).unwrap();
        // In the mounting's frame the motion is turned by −δ ...
        assert!((fit.direction_rad() + delta).abs() < 1e-6, "{fit:?}");
        // ... and the offset is d turned into that frame.
        let (offset_m, _) = fit.head_offset_m().unwrap();
        assert!((offset_m - d.translation().norm()).abs() < 1e-6, "{fit:?}");
    }

    #[test]
    fn mirrored_rotations_give_a_negative_slope() {
        let pairs: Vec<(Se2, Se2)> = odometry(30)
            .into_iter()
            .map(|o| (o, Se2::new(o.x(), -o.y(), -o.theta())))
            .collect();
        let slope = rotation_slope(&pairs).unwrap();
        assert!((slope.value + 1.0).abs() < 1e-12, "{slope:?}");
    }

    #[test]
    fn too_little_motion_gives_no_fit() {
        let still: Vec<(Se2, Se2)> = (0..30)
            .map(|_| (Se2::new(0.1, 0.0, 0.001), Se2::new(0.1, 0.0, 0.001)))
            .collect();
        assert_eq!(rotation_slope(&still), None);
        assert_eq!(translation_fit(&still), None);
        // Moving without turning: c, but no d.
        let straight: Vec<(Se2, Se2)> = (0..30)
            .map(|_| (Se2::new(2.0, 0.0, 0.0), Se2::new(2.0, 0.0, 0.0)))
            .collect();
        let fit = translation_fit(&straight).unwrap();
        assert!(fit.head_offset.is_none() && (fit.along.value - 1.0).abs() < 1e-12);
        assert_eq!(median(&mut []), None);
        assert_eq!(median(&mut [3.0, 1.0, 2.0, 10.0]), Some(2.5));
    }
}
