//! Evaluation of the acoustic-image matcher against ground truth, side by
//! side with point-to-point ICP on the same extracted ranges.
//!
//! **Pairs.** Whether rotation pairs `(K, J)` of a mission with ground
//! truth overlap is decided on ground truth alone, so that every navigation
//! and config evaluated sees the same overlapping pairs (of the rotations
//! it covers): the scans are built with the true motion
//! within each rotation, and a pair overlaps when, with the true pose, at
//! least `min_overlap` of the points of `S_K` land on the cells of side
//! `overlap_cell_m` that hold a point of `S_J` or touch such a cell: the
//! ground-truth scan overlap of [`echofield_frontend::scan::overlap`], the
//! same measure as the loop recall of `echofield run`. Consecutive pairs (`K = J + 1`)
//! and non-consecutive ones (`K ≥ J + 2`) are counted apart; at most
//! `max_pairs_per_kind` of each are drawn with the seed from all the
//! overlapping ones whose two rotations also have a scan with the
//! navigation evaluated (no other filter). That leaves out the rotations
//! with too few ranges and those the navigation does not cover: on the
//! St Pere replay the beams of the first ~183 s precede the first DVL
//! sample, so under dead reckoning (as in the pipeline, which makes no node
//! of them) the rotations before it are not drawn, while the ground truth
//! covers them.
//!
//! **Constraint.** For each pair, the geometry of the overlap decides how
//! well any scan match can be determined: with `n` the normal of `S_J` at
//! each overlapping point (each point of `S_K` that lands on those cells:
//! the minor principal axis of the `S_J` points within `normal_radius_m`
//! of its nearest one), the smallest eigenvalue of
//! the mean `n nᵀ` (0 when all overlapping points lie on walls of one
//! direction, e.g. a corridor or a single quay, where the position along
//! the walls is undetermined; 0.5 when the normals are spread evenly). The
//! table gives the success rate over all pairs and over the pairs with a
//! constraint of at least `min_constraint`.
//!
//! **Trials.** For every pair, `trials_per_pair` initial guesses are drawn
//! around the true `image_from_scan`: a translation error of uniform length
//! in `[0, max_initial_error_m]` and uniform direction, and a heading error
//! uniform in `±max_initial_error_rad`. The matcher searches a window just
//! wider than those errors; ICP starts from the same guess. Both use the
//! scans and images built with the mission's navigation (dead reckoning or
//! ground truth). A trial succeeds when the final error is below
//! `success_m` and `success_rad`.
//!
//! **Bias.** Random errors average out in the pose graph; a systematic
//! one does not: a consecutive match that is short by a fixed fraction of
//! the displacement shrinks the map by that fraction, and a heading error
//! of one sign bends it. [`Evaluation::bias`] gives the mean signed error
//! of the successes with its standard error: along the true displacement
//! (negative: the match is short), and in heading. Use it with
//! `--navigation ground-truth`, so that motion compensation adds nothing.
//! A match that lands on a false peak beside the true one fails and is
//! left out of that mean, though a pose graph takes it if its covariance
//! allows; [`Evaluation::bias_near`] averages every match within
//! [`NEAR_MISS_M`] of the truth, success or not (along a quay, where the
//! score is flat, the false peaks are short: EXPERIMENTS.md § Long
//! missions, "What the short loops are").

use super::MissionRotations;
use super::pull::{PointPull, pull_at_truth};
use crate::slam::SlamConfig;
use anyhow::Result;
use echofield_frontend::icp::{IcpConfig, icp, kdtree::KdTree};
use echofield_frontend::image::AcousticImage;
use echofield_frontend::matcher::{MatchOutcome, SearchWindow, match_scan, mean_score};
use echofield_frontend::motion::reference_from_beams;
use echofield_frontend::off_axis::OffAxisSuppression;
use echofield_frontend::scan::beam_width::BeamWidthCorrection;
use echofield_frontend::scan::overlap::ScanCells;
use echofield_frontend::scan::{Scan, build_scan};
use echofield_frontend::segmentation::SegmentationConfig;
use echofield_graph::{Se2, wrap_angle};
use nalgebra::{Matrix2, Point2, Vector2, Vector3};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::time::Instant;

/// The trial protocol of the matcher evaluation (module doc): how pairs
/// are chosen, how initial guesses are drawn and when a trial succeeds.
///
/// Not [`crate::slam::EvaluationConfig`], which judges a pipeline run's
/// output (trajectory errors, loop precision and recall) against ground
/// truth: this one drives single matches and ICP runs from perturbed
/// guesses. It is not a config-file section; `echofield bench-matcher`
/// sets it from its options.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrialConfig {
    pub trials_per_pair: usize,
    pub max_initial_error_m: f64,
    pub max_initial_error_rad: f64,
    pub success_m: f64,
    pub success_rad: f64,
    pub min_overlap: f64,
    /// Cell side of the ground-truth overlap (module doc), metres.
    pub overlap_cell_m: f64,
    /// Radius of the neighbourhood whose principal axes give the normals
    /// of the constraint measure, metres.
    pub normal_radius_m: f64,
    /// Pairs with at least this constraint (0-0.5) are "constrained".
    pub min_constraint: f64,
    /// At most this many pairs of each kind (chosen with the seed).
    pub max_pairs_per_kind: usize,
    pub seed: u64,
    pub icp: IcpConfig,
    /// Also keep every scan point's value and slope at the true pose
    /// ([`Evaluation::pulls`], [`super::pull`]).
    pub pull_at_truth: bool,
}

impl Default for TrialConfig {
    fn default() -> Self {
        Self {
            trials_per_pair: 5,
            max_initial_error_m: 5.0,
            max_initial_error_rad: 20.0_f64.to_radians(),
            success_m: 0.3,
            success_rad: 2.0_f64.to_radians(),
            min_overlap: 0.5,
            overlap_cell_m: 0.5,
            normal_radius_m: 1.0,
            min_constraint: 0.1,
            max_pairs_per_kind: 60,
            seed: 1,
            icp: IcpConfig::default(),
            pull_at_truth: false,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PairKind {
    Consecutive,
    NonConsecutive,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    AcousticImage,
    Icp,
}

/// A pair of overlapping rotations.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Pair {
    pub scan: usize,
    pub image: usize,
    pub kind: PairKind,
    /// Ground-truth overlap of `S_K` on `S_J` (module doc).
    pub overlap: f64,
    /// The constraint measure of the module doc, 0-0.5.
    pub constraint: f64,
}

/// One matcher or ICP run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Trial {
    pub scan: usize,
    pub image: usize,
    pub kind: PairKind,
    /// The pair's constraint measure (see the module doc).
    pub constraint: f64,
    pub method: Method,
    pub initial_error_m: f64,
    pub initial_error_rad: f64,
    /// `None` when the method gave no result (no match, ICP failure).
    pub final_error_m: Option<f64>,
    pub final_error_rad: Option<f64>,
    pub success: bool,
    pub time_s: f64,
    /// `eᵀ Σ⁻¹ e` of the matcher's covariance (acoustic image only).
    pub nees: Option<f64>,
    /// The matcher's covariance claims success-level precision: standard
    /// deviations below the success thresholds (acoustic image only).
    pub confident: Option<bool>,
    /// Mean score `s(x)/N` (eq. 5) of the matcher's estimate and of the
    /// true pose (acoustic image only): a failure whose estimate scores
    /// higher than the truth is an ambiguity of the score, one that scores
    /// lower is a failure of the search.
    pub mean_score: Option<f64>,
    pub mean_score_at_truth: Option<f64>,
    /// The true `image_from_scan` and the method's estimate `[x, y, θ]`
    /// (m, m, rad), for studying the direction of the errors.
    pub truth: [f64; 3],
    pub estimate: Option<[f64; 3]>,
    /// The matcher's best lattice pose before refinement (acoustic image
    /// only).
    pub coarse_estimate: Option<[f64; 3]>,
}

/// Mean signed error of a method's successes on one kind of pair, with
/// the standard errors of the means (module doc, **Bias**).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Bias {
    /// Matches averaged.
    pub trials: usize,
    /// Error along the unit vector of the true translation, metres
    /// (negative: the estimate is short); matches whose true
    /// translation is under 0.1 m are left out of this one.
    pub along_m: f64,
    pub along_standard_error_m: f64,
    /// Heading error, rad.
    pub heading_rad: f64,
    pub heading_standard_error_rad: f64,
    /// Least-squares slope of the along-track error over the true distance:
    /// the scale error of the estimated displacements (-0.005: 0.5% short).
    pub scale: f64,
}

/// How far from the truth a match may land and still count in
/// [`Evaluation::bias_near`], metres: beyond the success bound, within
/// the reach of a false peak along a wall.
pub const NEAR_MISS_M: f64 = 2.0;

/// Everything measured.
#[derive(Clone, Debug, Serialize)]
pub struct Evaluation {
    pub config: TrialConfig,
    pub rotations: usize,
    /// Rotations without a usable scan (too few ranges).
    pub rotations_without_scan: usize,
    pub pairs: BTreeMap<String, usize>,
    /// Overlapping pairs of each kind before the draw.
    pub overlapping_pairs: BTreeMap<String, usize>,
    pub chosen_pairs: Vec<Pair>,
    pub trials: Vec<Trial>,
    /// Every scan point of every pair evaluated at the true pose, when
    /// [`TrialConfig::pull_at_truth`] (not in the JSON: the command writes
    /// them as CSV).
    #[serde(skip)]
    pub pulls: Vec<PointPull>,
}

/// Runs the evaluation on a mission with ground truth.
///
/// Errors when the mission has no ground truth at any rotation's reference
/// time, when the ground-truth navigation cannot be built, or when an image
/// or a match fails on the mission's data.
pub fn evaluate(
    mission: &MissionRotations,
    config: &SlamConfig,
    eval: &TrialConfig,
) -> Result<Evaluation> {
    let n = mission.rotations.len();
    let scans: Vec<Option<Scan>> = (0..n).map(|k| mission.scan(k, config).ok()).collect();
    let truths = rotation_truths(mission)?;
    let exact_scans = exact_scans(mission, config)?;
    let mut rng = ChaCha8Rng::seed_from_u64(eval.seed);
    let matchable: Vec<bool> = scans.iter().map(Option::is_some).collect();
    let (pairs, overlapping_pairs) =
        choose_pairs(&exact_scans, &truths, &matchable, eval, &mut rng);
    let (trials, pulls) = run_trials(mission, config, eval, &scans, &truths, &pairs, &mut rng)?;
    let mut pair_counts = BTreeMap::new();
    for pair in &pairs {
        *pair_counts.entry(format!("{:?}", pair.kind)).or_insert(0) += 1;
    }
    Ok(Evaluation {
        config: eval.clone(),
        rotations: n,
        rotations_without_scan: scans.iter().filter(|s| s.is_none()).count(),
        pairs: pair_counts,
        overlapping_pairs,
        chosen_pairs: pairs,
        trials,
        pulls,
    })
}

/// The ground-truth pose (world frame) at each rotation's reference time,
/// `None` where the ground truth does not cover it. Errors when it covers
/// none of them.
fn rotation_truths(mission: &MissionRotations) -> Result<Vec<Option<Se2>>> {
    let truths: Vec<Option<Se2>> = mission
        .rotations
        .iter()
        .map(|rotation| {
            super::ground_truth_at(&mission.mission.ground_truth, rotation.reference_stamp_s)
        })
        .collect();
    if truths.iter().all(Option::is_none) {
        anyhow::bail!("the mission has no ground truth at the rotations' reference times");
    }
    Ok(truths)
}

/// The matcher's search window: just wider than the largest initial error
/// drawn (0.5 m and 2° of margin; the heading half-width at most π).
fn trial_window(eval: &TrialConfig) -> SearchWindow {
    SearchWindow::new(
        eval.max_initial_error_m + 0.5,
        eval.max_initial_error_m + 0.5,
        (eval.max_initial_error_rad + 2.0_f64.to_radians()).min(std::f64::consts::PI),
    )
}

/// Runs `trials_per_pair` trials of both methods on every pair, in the
/// order of `pairs` within each image (pairs are grouped by image so each
/// image is built once), and, with [`TrialConfig::pull_at_truth`], every
/// pair's scan points at the true pose. Precondition: every pair has ground
/// truth at both rotations (as [`choose_pairs`] guarantees); pairs whose
/// scan or image rotation has no scan with the evaluated navigation are
/// skipped.
fn run_trials(
    mission: &MissionRotations,
    config: &SlamConfig,
    eval: &TrialConfig,
    scans: &[Option<Scan>],
    truths: &[Option<Se2>],
    pairs: &[Pair],
    rng: &mut ChaCha8Rng,
) -> Result<(Vec<Trial>, Vec<PointPull>)> {
    let window = trial_window(eval);
    let mut trials = Vec::new();
    let mut pulls = Vec::new();
    let mut by_image: BTreeMap<usize, Vec<Pair>> = BTreeMap::new();
    for pair in pairs {
        by_image.entry(pair.image).or_default().push(*pair);
    }
    for (j, group) in by_image {
        let Some(target) = &scans[j] else {
            continue; // not drawn: no scan with this navigation
        };
        let image = mission.image(j, config)?;
        for pair in group {
            let Some(source) = &scans[pair.scan] else {
                continue;
            };
            let (Some(truth_j), Some(truth_k)) = (truths[j], truths[pair.scan]) else {
                continue; // not drawn: choose_pairs keeps pairs with truth only
            };
            let context = TrialContext {
                pair,
                truth: truth_j.between(&truth_k),
                source: &source.points,
                target: &target.points,
                image: &image,
                window: &window,
            };
            if eval.pull_at_truth {
                let key = (pair.scan, pair.image, pair.kind);
                pulls.extend(pull_at_truth(context.source, &image, &context.truth, key));
            }
            for _ in 0..eval.trials_per_pair {
                let (prior, e_m, e_rad) = perturb(&context.truth, eval, rng);
                let start = TrialStart {
                    prior,
                    error_m: e_m,
                    error_rad: e_rad,
                };
                trials.push(matcher_trial(&context, &start, config, eval)?);
                trials.push(icp_trial(&context, &start, eval));
            }
        }
    }
    Ok((trials, pulls))
}

/// What the trials of one pair share.
struct TrialContext<'a> {
    pair: Pair,
    /// The true `image_from_scan`.
    truth: Se2,
    /// `S_K` (scan frame) and `S_J` (image frame).
    source: &'a [Point2<f64>],
    target: &'a [Point2<f64>],
    image: &'a AcousticImage,
    window: &'a SearchWindow,
}

/// The initial guess of one trial and the size of its error (m, |rad|).
struct TrialStart {
    prior: Se2,
    error_m: f64,
    error_rad: f64,
}

impl TrialContext<'_> {
    /// The trial record of `method` with estimate `result`; the fields
    /// that only the acoustic-image matcher fills (scores, coarse estimate)
    /// are `None`.
    fn trial(
        &self,
        start: &TrialStart,
        eval: &TrialConfig,
        method: Method,
        result: Option<Se2>,
        time_s: f64,
    ) -> Trial {
        let error = result.map(|r| self.truth.between(&r));
        let final_error_m = error.map(|e| e.translation().norm());
        let final_error_rad = error.map(|e| e.theta().abs());
        Trial {
            scan: self.pair.scan,
            image: self.pair.image,
            kind: self.pair.kind,
            constraint: self.pair.constraint,
            method,
            initial_error_m: start.error_m,
            initial_error_rad: start.error_rad,
            final_error_m,
            final_error_rad,
            success: final_error_m.is_some_and(|m| m < eval.success_m)
                && final_error_rad.is_some_and(|r| r < eval.success_rad),
            time_s,
            nees: None,
            confident: None,
            mean_score: None,
            mean_score_at_truth: None,
            truth: self.truth.to_vector().into(),
            estimate: result.map(|r| r.to_vector().into()),
            coarse_estimate: None,
        }
    }
}

/// One acoustic-image match from `start.prior`, timed, with its NEES,
/// confidence and the mean scores of its estimate and of the truth.
fn matcher_trial(
    context: &TrialContext,
    start: &TrialStart,
    config: &SlamConfig,
    eval: &TrialConfig,
) -> Result<Trial> {
    let clock = Instant::now();
    let outcome = match_scan(
        context.source,
        context.image,
        &start.prior,
        context.window,
        &config.matcher,
    )?;
    let time_s = clock.elapsed().as_secs_f64();
    let MatchOutcome::Match(m) = &outcome else {
        let mut trial = context.trial(start, eval, Method::AcousticImage, None, time_s);
        trial.confident = Some(false);
        return Ok(trial);
    };
    let truth = &context.truth;
    let e = m.image_from_scan.to_vector() - truth.to_vector();
    let e = Vector3::new(e.x, e.y, wrap_angle(e.z));
    let xy = m.covariance.fixed_view::<2, 2>(0, 0).symmetric_eigen();
    let mut trial = context.trial(
        start,
        eval,
        Method::AcousticImage,
        Some(m.image_from_scan),
        time_s,
    );
    trial.nees = m
        .covariance
        .try_inverse()
        .map(|info| (e.transpose() * info * e)[0]);
    trial.confident = Some(
        xy.eigenvalues.max().sqrt() < eval.success_m
            && m.covariance[(2, 2)].sqrt() < eval.success_rad,
    );
    trial.mean_score = Some(mean_score(
        context.source,
        context.image,
        &m.image_from_scan,
    ));
    trial.mean_score_at_truth = Some(mean_score(context.source, context.image, truth));
    trial.coarse_estimate = Some(m.coarse.to_vector().into());
    Ok(trial)
}

/// One point-to-point ICP run of `S_K` onto `S_J` from `start.prior`,
/// timed; an ICP failure is a trial without an estimate.
fn icp_trial(context: &TrialContext, start: &TrialStart, eval: &TrialConfig) -> Trial {
    let clock = Instant::now();
    let result = icp(context.source, context.target, &start.prior, &eval.icp).ok();
    let time_s = clock.elapsed().as_secs_f64();
    context.trial(
        start,
        eval,
        Method::Icp,
        result.map(|r| r.target_from_source),
        time_s,
    )
}

/// Scans built with the ground truth as navigation (exact motion
/// compensation), without the beam-width correction and without the
/// off-axis suppression, for choosing pairs independently of the navigation
/// and of the scan building evaluated.
fn exact_scans(mission: &MissionRotations, config: &SlamConfig) -> Result<Vec<Option<Scan>>> {
    let truth = super::navigation_eval::ground_truth_navigation(&mission.mission)?;
    let segmentation = SegmentationConfig {
        beam_width: BeamWidthCorrection::off(),
        off_axis: OffAxisSuppression::off(),
        ..config.segmentation.clone()
    };
    Ok(mission
        .rotations
        .iter()
        .map(|rotation| {
            let beams = &mission.mission.beams[rotation.beams.clone()];
            let t_ref = rotation.reference_stamp_s;
            let frames =
                reference_from_beams(beams, &truth, &mission.mission.mounting, t_ref).ok()?;
            build_scan(beams, &frames, t_ref, &segmentation).ok()
        })
        .collect())
}

/// Overlapping pairs of `matchable` rotations (see the module doc), at
/// most `max_pairs_per_kind` of each kind, and how many of them there were
/// of each kind.
fn choose_pairs(
    scans: &[Option<Scan>],
    truths: &[Option<Se2>],
    matchable: &[bool],
    eval: &TrialConfig,
    rng: &mut ChaCha8Rng,
) -> (Vec<Pair>, BTreeMap<String, usize>) {
    let trees: Vec<Option<KdTree>> = scans
        .iter()
        .map(|s| s.as_ref().map(|s| KdTree::new(&s.points)))
        .collect();
    let cells: Vec<Option<ScanCells>> = scans
        .iter()
        .map(|s| {
            s.as_ref()
                .map(|s| ScanCells::new(&s.points, eval.overlap_cell_m))
        })
        .collect();
    let mut consecutive = Vec::new();
    let mut others = Vec::new();
    for k in 0..scans.len() {
        for j in 0..k {
            if !(matchable[k] && matchable[j]) {
                continue;
            }
            let (Some(scan_k), Some(scan_j), Some(tree_j), Some(cells_j), Some(tk), Some(tj)) = (
                &scans[k], &scans[j], &trees[j], &cells[j], truths[k], truths[j],
            ) else {
                continue;
            };
            let truth = tj.between(&tk);
            let overlap = cells_j.overlap(&scan_k.points, &truth);
            if overlap < eval.min_overlap {
                continue;
            }
            let kind = if k == j + 1 {
                PairKind::Consecutive
            } else {
                PairKind::NonConsecutive
            };
            let pair = Pair {
                scan: k,
                image: j,
                kind,
                overlap,
                constraint: constraint(
                    &scan_k.points,
                    &scan_j.points,
                    tree_j,
                    cells_j,
                    &truth,
                    eval,
                ),
            };
            match kind {
                PairKind::Consecutive => consecutive.push(pair),
                PairKind::NonConsecutive => others.push(pair),
            }
        }
    }
    let counts = BTreeMap::from([
        (format!("{:?}", PairKind::Consecutive), consecutive.len()),
        (format!("{:?}", PairKind::NonConsecutive), others.len()),
    ]);
    let mut pairs = Vec::new();
    for mut list in [consecutive, others] {
        list.shuffle(rng);
        list.truncate(eval.max_pairs_per_kind);
        list.sort_by_key(|p| (p.scan, p.image));
        pairs.extend(list);
    }
    (pairs, counts)
}

/// The constraint measure of the module doc for `points` (scan frame)
/// placed by `image_from_scan` on `target` (whose tree is `tree` and
/// whose overlap cells are `cells`).
fn constraint(
    points: &[Point2<f64>],
    target: &[Point2<f64>],
    tree: &KdTree,
    cells: &ScanCells,
    image_from_scan: &Se2,
    eval: &TrialConfig,
) -> f64 {
    let mut sum = Matrix2::zeros();
    let mut count = 0;
    for p in points {
        let q = image_from_scan.transform_point(p);
        if !cells.contains(q.x, q.y) {
            continue;
        }
        let Some((nearest, _)) = tree.nearest(&q, eval.normal_radius_m) else {
            continue;
        };
        let around = tree.within(&target[nearest], eval.normal_radius_m);
        if around.len() < 3 {
            continue;
        }
        let n = around.len() as f64;
        let mean = around
            .iter()
            .map(|&i| target[i].coords)
            .sum::<Vector2<f64>>()
            / n;
        let scatter = around
            .iter()
            .map(|&i| (target[i].coords - mean) * (target[i].coords - mean).transpose())
            .sum::<Matrix2<f64>>();
        let eigen = scatter.symmetric_eigen();
        let minor = if eigen.eigenvalues.x <= eigen.eigenvalues.y {
            0
        } else {
            1
        };
        let normal = eigen.eigenvectors.column(minor).into_owned();
        sum += normal * normal.transpose();
        count += 1;
    }
    if count == 0 {
        return 0.0;
    }
    (sum / f64::from(count)).symmetric_eigenvalues().min()
}

/// The truth with a random error; returns the guess and the error sizes.
fn perturb(truth: &Se2, eval: &TrialConfig, rng: &mut ChaCha8Rng) -> (Se2, f64, f64) {
    let length = eval.max_initial_error_m * rng.random::<f64>();
    let direction = std::f64::consts::TAU * rng.random::<f64>();
    let angle = eval.max_initial_error_rad * (2.0 * rng.random::<f64>() - 1.0);
    // The error is applied in the image frame: translation added to the
    // true translation, angle to the true heading.
    let guess = Se2::new(
        truth.x() + length * direction.cos(),
        truth.y() + length * direction.sin(),
        truth.theta() + angle,
    );
    (guess, length, angle.abs())
}

impl Evaluation {
    /// A Markdown table: per pair kind and method, trials, success rate,
    /// and success by initial translation error; median final error of the
    /// successes, mean time; the matcher's mean NEES.
    pub fn table(&self) -> String {
        let max = self.config.max_initial_error_m;
        let min_c = self.config.min_constraint;
        let near = NEAR_MISS_M;
        let mut out = String::new();
        let _ = writeln!(
            out,
            "| pairs | method | trials | success | constrained pairs (≥ {min_c}) | init <1 m | init 1-3 m | init 3-{max:.0} m | median error (succ.) | mean time | mean NEES (succ.) | confident: share, success | failures scoring ≥ truth | bias (succ.): along, heading, scale | bias within {near:.0} m: along, scale |"
        );
        let _ = writeln!(
            out,
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
        );
        for kind in [PairKind::Consecutive, PairKind::NonConsecutive] {
            for method in [Method::AcousticImage, Method::Icp] {
                let trials: Vec<&Trial> = self
                    .trials
                    .iter()
                    .filter(|t| t.kind == kind && t.method == method)
                    .collect();
                if !trials.is_empty() {
                    out.push_str(&self.table_row(kind, method, &trials));
                }
            }
        }
        out
    }

    /// One row of [`Evaluation::table`]: the `trials` (not empty) of
    /// `method` on `kind` pairs, ending with a newline.
    fn table_row(&self, kind: PairKind, method: Method, trials: &[&Trial]) -> String {
        let bins = [(0.0, 1.0), (1.0, 3.0), (3.0, f64::INFINITY)];
        let by_bin: Vec<String> = bins
            .iter()
            .map(|&(lo, hi)| {
                let ts: Vec<&Trial> = trials
                    .iter()
                    .copied()
                    .filter(|t| t.initial_error_m >= lo && t.initial_error_m < hi)
                    .collect();
                success_cell(&ts)
            })
            .collect();
        let constrained: Vec<&Trial> = trials
            .iter()
            .copied()
            .filter(|t| t.constraint >= self.config.min_constraint)
            .collect();
        let mean_ms = 1e3 * trials.iter().map(|t| t.time_s).sum::<f64>() / trials.len() as f64;
        let (median_error, mean_nees) = (median_error_cell(trials), mean_nees_cell(trials));
        let (confident, ambiguous) = if method == Method::Icp {
            ("-".to_string(), "-".to_string())
        } else {
            (confident_cell(trials), ambiguous_cell(trials))
        };
        let bias = bias_cell(self.bias(kind, method), true);
        let near = bias_cell(self.bias_near(kind, method), false);
        format!(
            "| {kind:?} | {method:?} | {} | {} | {} | {} | {} | {} | {median_error} | {mean_ms:.2} ms | {mean_nees} | {confident} | {ambiguous} | {bias} | {near} |\n",
            trials.len(),
            success_cell(trials),
            success_cell(&constrained),
            by_bin[0],
            by_bin[1],
            by_bin[2],
        )
    }

    /// The mean signed error of `method`'s successes on `kind` pairs
    /// (module doc, **Bias**); `None` with fewer than two successes.
    pub fn bias(&self, kind: PairKind, method: Method) -> Option<Bias> {
        self.bias_where(kind, method, |t| t.success)
    }

    /// [`Self::bias`] over every match of `method` on `kind` pairs that
    /// lands within [`NEAR_MISS_M`] of the truth, success or not (module
    /// doc, **Bias**); `None` with fewer than two.
    pub fn bias_near(&self, kind: PairKind, method: Method) -> Option<Bias> {
        self.bias_where(kind, method, |t| {
            t.estimate
                .is_some_and(|e| (e[0] - t.truth[0]).hypot(e[1] - t.truth[1]) < NEAR_MISS_M)
        })
    }

    /// The bias of the trials of `method` on `kind` pairs that `keep`.
    fn bias_where(
        &self,
        kind: PairKind,
        method: Method,
        keep: impl Fn(&Trial) -> bool,
    ) -> Option<Bias> {
        // (along-track error, true distance, heading error) per match.
        let errors: Vec<(Option<(f64, f64)>, f64)> = self
            .trials
            .iter()
            .filter(|t| t.kind == kind && t.method == method && keep(t))
            .filter_map(|t| {
                let estimate = t.estimate?;
                let truth = Vector2::new(t.truth[0], t.truth[1]);
                let error = Vector2::new(estimate[0] - t.truth[0], estimate[1] - t.truth[1]);
                let distance = truth.norm();
                let along = (distance >= 0.1).then(|| (error.dot(&truth) / distance, distance));
                Some((along, wrap_angle(estimate[2] - t.truth[2])))
            })
            .collect();
        let along: Vec<(f64, f64)> = errors.iter().filter_map(|e| e.0).collect();
        let heading: Vec<f64> = errors.iter().map(|e| e.1).collect();
        if heading.len() < 2 || along.len() < 2 {
            return None;
        }
        let (along_m, along_se) = mean_and_standard_error(along.iter().map(|a| a.0));
        let (heading_rad, heading_se) = mean_and_standard_error(heading.iter().copied());
        let scale = along.iter().map(|(e, d)| e * d).sum::<f64>()
            / along.iter().map(|(_, d)| d * d).sum::<f64>();
        Some(Bias {
            trials: heading.len(),
            along_m,
            along_standard_error_m: along_se,
            heading_rad,
            heading_standard_error_rad: heading_se,
            scale,
        })
    }

    /// Success rate of one method over all pairs, 0-1.
    pub fn success_rate(&self, method: Method) -> f64 {
        self.success_rate_where(method, |_| true)
    }

    /// Success rate of one method over the trials that pass `filter`, 0-1
    /// (0 when none does).
    pub fn success_rate_where(&self, method: Method, filter: impl Fn(&Trial) -> bool) -> f64 {
        let trials: Vec<&Trial> = self
            .trials
            .iter()
            .filter(|t| t.method == method && filter(t))
            .collect();
        if trials.is_empty() {
            return 0.0;
        }
        trials.iter().filter(|t| t.success).count() as f64 / trials.len() as f64
    }
}

/// A bias as a table cell: the along-track mean ± its standard error,
/// the heading's when `heading`, the scale, and the matches averaged when
/// not `heading` (the near misses, whose count the success column does
/// not give); "-" without one.
fn bias_cell(bias: Option<Bias>, heading: bool) -> String {
    let Some(b) = bias else {
        return "-".into();
    };
    let along = format!("{:+.3} ± {:.3} m", b.along_m, b.along_standard_error_m);
    if heading {
        format!(
            "{along}, {:+.3} ± {:.3}°, {:+.2}%",
            b.heading_rad.to_degrees(),
            b.heading_standard_error_rad.to_degrees(),
            100.0 * b.scale
        )
    } else {
        format!("{along}, {:+.2}% ({})", 100.0 * b.scale, b.trials)
    }
}

/// "rate% (successes/trials)" of `trials`, "-" when there are none.
fn success_cell(trials: &[&Trial]) -> String {
    if trials.is_empty() {
        return "-".to_string();
    }
    let ok = trials.iter().filter(|t| t.success).count();
    format!(
        "{:.1}% ({ok}/{})",
        100.0 * ok as f64 / trials.len() as f64,
        trials.len()
    )
}

/// Median final translation (m) and heading (°) error of the successes,
/// "-" when there are none.
fn median_error_cell(trials: &[&Trial]) -> String {
    let mut errors_m: Vec<f64> = trials
        .iter()
        .filter(|t| t.success)
        .filter_map(|t| t.final_error_m)
        .collect();
    let mut errors_deg: Vec<f64> = trials
        .iter()
        .filter(|t| t.success)
        .filter_map(|t| t.final_error_rad.map(f64::to_degrees))
        .collect();
    match (median(&mut errors_m), median(&mut errors_deg)) {
        (Some(m), Some(d)) => format!("{:.3} m, {d:.2}°", m),
        _ => "-".into(),
    }
}

/// Mean NEES of the successes that have one, "-" when none has.
fn mean_nees_cell(trials: &[&Trial]) -> String {
    let nees: Vec<f64> = trials
        .iter()
        .filter(|t| t.success)
        .filter_map(|t| t.nees)
        .collect();
    if nees.is_empty() {
        "-".into()
    } else {
        format!("{:.2}", nees.iter().sum::<f64>() / nees.len() as f64)
    }
}

/// Share of the (not empty) `trials` whose covariance claims success-level
/// precision, and the success rate of those.
fn confident_cell(trials: &[&Trial]) -> String {
    let confident: Vec<&Trial> = trials
        .iter()
        .copied()
        .filter(|t| t.confident == Some(true))
        .collect();
    format!(
        "{:.0}%, {}",
        100.0 * confident.len() as f64 / trials.len() as f64,
        success_cell(&confident)
    )
}

/// "ambiguous/failures": a failure whose estimate scores at least as high
/// as the truth is an ambiguity of eq. (5), not of the search.
fn ambiguous_cell(trials: &[&Trial]) -> String {
    let failures: Vec<&Trial> = trials.iter().copied().filter(|t| !t.success).collect();
    let ambiguous = failures
        .iter()
        .filter(|t| matches!((t.mean_score, t.mean_score_at_truth), (Some(e), Some(t)) if e >= t))
        .count();
    format!("{ambiguous}/{}", failures.len())
}

/// Mean and standard error of the mean (sample standard deviation / √n)
/// of at least two values.
fn mean_and_standard_error(values: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let n = values.clone().count() as f64;
    let mean = values.clone().sum::<f64>() / n;
    let variance = values.map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (variance / n).sqrt())
}

fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    Some(values[values.len() / 2])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn perturbations_stay_within_the_bounds() {
        let eval = TrialConfig::default();
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let truth = Se2::new(3.0, -1.0, 2.9);
        let mut largest = (0.0_f64, 0.0_f64);
        for _ in 0..500 {
            let (guess, m, rad) = perturb(&truth, &eval, &mut rng);
            assert!(m <= 5.0 && rad <= 20.0_f64.to_radians());
            assert!(((guess.translation() - truth.translation()).norm() - m).abs() < 1e-9);
            assert!((wrap_angle(guess.theta() - truth.theta()).abs() - rad).abs() < 1e-9);
            largest = (largest.0.max(m), largest.1.max(rad));
        }
        // The draws reach close to the bounds.
        assert!(largest.0 > 4.8 && largest.1 > 19.0_f64.to_radians());
    }

    /// A trial with the given truth and estimate `[x, y, θ]`.
    fn trial(method: Method, success: bool, truth: [f64; 3], estimate: [f64; 3]) -> Trial {
        Trial {
            scan: 1,
            image: 0,
            kind: PairKind::Consecutive,
            constraint: 0.3,
            method,
            initial_error_m: 1.0,
            initial_error_rad: 0.1,
            final_error_m: None,
            final_error_rad: None,
            success,
            time_s: 0.0,
            nees: None,
            confident: None,
            mean_score: None,
            mean_score_at_truth: None,
            truth,
            estimate: Some(estimate),
            coarse_estimate: None,
        }
    }

    #[test]
    fn bias_averages_the_signed_errors_of_the_successes() {
        // Three successes 1% short along their displacements of 2, 4 and 6 m
        // (in three directions), each also 5 cm off across it, with heading
        // errors of 1, 3 and 2 mrad.
        let (c, s) = (0.6, 0.8);
        let trials = vec![
            trial(
                Method::AcousticImage,
                true,
                [2.0, 0.0, 0.5],
                [1.98, 0.05, 0.501],
            ),
            trial(
                Method::AcousticImage,
                true,
                [0.0, -4.0, -3.1],
                [-0.05, -3.96, -3.097],
            ),
            trial(
                Method::AcousticImage,
                true,
                [6.0 * c, 6.0 * s, 3.13],
                [
                    5.94 * c - 0.05 * s,
                    5.94 * s + 0.05 * c,
                    3.132 - std::f64::consts::TAU,
                ],
            ),
            // Neither a failure nor another method counts; a failure 0.5 m
            // short counts among the near misses, one 4.2 m off does not.
            trial(
                Method::AcousticImage,
                false,
                [2.0, 0.0, 0.0],
                [5.0, 3.0, 1.0],
            ),
            trial(
                Method::AcousticImage,
                false,
                [8.0, 0.0, 0.0],
                [7.5, 0.0, 0.006],
            ),
            trial(Method::Icp, true, [2.0, 0.0, 0.0], [2.2, 0.0, 0.1]),
        ];
        let evaluation = Evaluation {
            config: TrialConfig::default(),
            rotations: 2,
            rotations_without_scan: 0,
            pairs: BTreeMap::new(),
            overlapping_pairs: BTreeMap::new(),
            chosen_pairs: Vec::new(),
            trials,
            pulls: Vec::new(),
        };
        let bias = evaluation
            .bias(PairKind::Consecutive, Method::AcousticImage)
            .unwrap();
        assert_eq!(bias.trials, 3);
        assert!((bias.along_m + 0.04).abs() < 1e-9, "{bias:?}");
        // Along errors -0.02, -0.04, -0.06: sample deviation 0.02, over √3.
        assert!((bias.along_standard_error_m - 0.02 / 3f64.sqrt()).abs() < 1e-9);
        assert!((bias.heading_rad - 0.002).abs() < 1e-9, "{bias:?}");
        assert!((bias.heading_standard_error_rad - 0.001 / 3f64.sqrt()).abs() < 1e-9);
        assert!((bias.scale + 0.01).abs() < 1e-9, "{bias:?}");
        assert!(
            evaluation
                .table()
                .contains("-0.040 ± 0.012 m, +0.115 ± 0.033°, -1.00%")
        );
        // The near misses: the three successes and the failure 0.5 m short
        // of 8 m; along errors -0.02, -0.04, -0.06, -0.5 m.
        let near = evaluation
            .bias_near(PairKind::Consecutive, Method::AcousticImage)
            .unwrap();
        assert_eq!(near.trials, 4);
        assert!((near.along_m + 0.155).abs() < 1e-9, "{near:?}");
        // Σ e·d / Σ d² = (-0.04 - 0.16 - 0.36 - 4) / (4 + 16 + 36 + 64).
        assert!((near.scale + 4.56 / 120.0).abs() < 1e-9, "{near:?}");
        assert!((near.heading_rad - 0.003).abs() < 1e-9, "{near:?}");
        assert!(
            evaluation.table().contains("| -0.155 ± "),
            "{}",
            evaluation.table()
        );
        // One success is not enough for a standard error.
        assert_eq!(evaluation.bias(PairKind::Consecutive, Method::Icp), None);
    }
}
