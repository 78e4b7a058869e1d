//! Loop closing: candidates, matches, checks and mutual consistency.
//!
//! For each new node `k` with a scan:
//! 1. **Gating by predicted overlap.** Every older node `j` at least
//!    `min_separation_nodes` rotations back whose image holds echoes is a
//!    candidate when the fraction of `S_k`'s points that the current
//!    estimate places within `j`'s footprint (the range of 90% of `S_j`'s
//!    returns) is at least `min_predicted_overlap`. At most
//!    `max_candidates_per_node` of them are taken, largest overlap first.
//!    Pairs that an accepted loop covers ([`cover`]: both ends within
//!    `cover_spacing_m` of travel of its ends) are not candidates, and of
//!    two candidates of `k` whose older nodes lie within that spacing only
//!    the better-overlapping one is taken: the loops kept per metre of
//!    track are bounded, whatever the rotations per metre.
//! 2. **Gating by uncertainty.** The prior `j_from_k` is the current
//!    estimate; its covariance the relative uncertainty of the two nodes
//!    (module [`echofield_frontend::uncertainty`]). The search window is `n_sigma`
//!    standard deviations per axis, at least `min_window`. A candidate whose
//!    window would exceed `max_window` is *deferred*: it is retried after
//!    the next change of the accepted loops (which usually makes the
//!    relative uncertainty small), and reported as `deferred` if it never
//!    qualifies. Only when none of a node's candidates is certain enough
//!    (a first contact with a place seen long ago) are the best
//!    `WIDE_SEARCHES_PER_NODE` of them searched over `gate.max_window` at once.
//! 3. **Matching and checks** ([`checks`]): `S_k` vs `I_j`, quality,
//!    covariance, window edge, and the symmetric match `S_j` vs `I_k`. A
//!    candidate predicted to overlap almost entirely whose match lands on
//!    nothing is searched again over a wider window (the estimate is
//!    further off than its covariance says).
//! 4. **Mutual consistency** ([`consistency`]): the loops that passed their
//!    own checks form a consistency graph; the accepted loops are its
//!    maximum clique, recomputed whenever a loop is added (so a loop
//!    accepted early can be dropped later when the evidence turns against
//!    it). Accepted loops become `Loop` edges with the match covariance
//!    plus the `min_sigma` floor; the backend's robust kernel on loop edges
//!    is the last line of defence.
//! 5. **Densification** (`densify`, on by default, after the mission):
//!    the pairs never examined whose relative pose the estimate already
//!    knows are matched by a local climb from the estimate, gated by the
//!    tighter `densify_max_sigma`, and accepted when they agree with the
//!    estimate ([`LoopCloser::densify`]); so are the pairs the mission
//!    rejected only for how they were searched (a window too large, a peak
//!    at its edge, a match unsure along some direction:
//!    [`RejectReason::densification_retries`]). Loops that share a node
//!    share its errors: a scan built with a wrong motion within its
//!    rotation, or seen along a wall, misplaces every loop it takes part
//!    in the same way (on the simulated missions and the St Pere replay
//!    the intra-class correlation of the loop errors at a node is
//!    0.2-0.6). Densification adds loops mostly where loops already are,
//!    so treating them as independent would count the same error many
//!    times: a densified loop's covariance is multiplied by the design
//!    effect of equicorrelated measurements, `1 + ρ·(m_j + m_k − 2)`
//!    (`DENSIFY_CORRELATION` = ρ, `m_x` the accepted loops at node `x`,
//!    or within `cover_spacing_m` of travel of it). Densification, too,
//!    skips covered pairs: it matches in rounds the pairs that neither an
//!    accepted loop nor an earlier pick of the round covers
//!    ([`COVER_ROUNDS`]), and takes at most `3 · max_candidates_per_node`
//!    pairs per node, the best-overlapping ones.
//!
//! Node images are read through their [`ImageResidency`], which keeps the
//! images held within a memory budget between matches (densification
//! runs in batches of [`DENSIFY_BATCH`] pairs for it); a released image is
//! built again, the same, when read.
//!
//! The matches of step 3 (a node's candidates, the retried ones, and the
//! whole densification pass) run in parallel with rayon; their records
//! are collected and judged in the candidates' order, so a run gives the
//! same result on any number of threads (timings: EXPERIMENTS.md § Speed
//! notes).

use echofield_frontend::loops::{LoopConfig, checks, consistency, cover};

use super::SlamError;
use super::estimate::{Estimate, make_edge};
use checks::{Candidate, examine};
use consistency::{Clique, ConsistencyGraph, DeadReckoningChain, LoopMeasurement};
use cover::LoopCover;
use echofield_frontend::image::ImageResidency;
use echofield_frontend::loops::config::{
    CONSISTENCY_MAX_CHI2, DENSIFY_CORRELATION, DENSIFY_MIN_PREDICTED_OVERLAP,
    WIDE_SEARCHES_PER_NODE, densify_max_window,
};
use echofield_frontend::loops::{LoopRecord, RejectReason};
use echofield_frontend::matcher::{MatcherConfig, SearchWindow};
use echofield_frontend::nodes::{NodeData, predicted_overlap};
use echofield_frontend::uncertainty::{
    DriftModel, invert, mahalanobis2, translation_trace, with_floor,
};
use echofield_graph::{EdgeKind, Se2};
use nalgebra::Matrix3;
use rayon::prelude::*;
use std::collections::{HashMap, HashSet};

/// Every `OVERLAP_STRIDE`-th scan point is used to predict the overlap.
const OVERLAP_STRIDE: usize = 4;
/// Rounds of retrying deferred candidates after the accepted set changes.
const MAX_RETRY_ROUNDS: usize = 3;
/// Pairs considered per node, in multiples of `max_candidates_per_node`,
/// before the uncertainty gate.
const CANDIDATE_POOL: usize = 3;
/// Deferred candidates kept waiting at most; older ones stay `deferred`.
const MAX_WAITING: usize = 64;
/// Rounds of densification picks under the cover rule ([`cover`]): each
/// round matches the pairs that neither a kept loop nor an earlier pick of
/// the round covers; the next one picks among the pairs only failed picks
/// covered.
pub const COVER_ROUNDS: usize = 3;
/// Densification pairs matched between two looks of the image residency
/// policy: bounds the images a batch builds beyond the budget.
const DENSIFY_BATCH: usize = 64;

/// Keeps the `max` pairs of `pairs` (older node, predicted overlap) with
/// the largest overlap (ties: the older node), in their order. With the
/// cover rule on, it bounds the densification matches per node: on a slow
/// or long mission a node overlaps every node of every earlier pass over
/// its place, far more pairs than add information (module doc of
/// [`cover`]). Off with the rule off: on the St Pere replay it costs a
/// third of the pairs the evaluation counts (EXPERIMENTS.md § Long
/// missions).
fn keep_best_overlaps(pairs: &mut Vec<(usize, f64)>, max: usize) {
    if pairs.len() <= max {
        return;
    }
    let mut ranked: Vec<(usize, f64)> = pairs.clone();
    ranked.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    let kept: HashSet<usize> = ranked.iter().take(max).map(|p| p.0).collect();
    pairs.retain(|p| kept.contains(&p.0));
}

/// The loop-closing state of a run.
pub struct LoopCloser<'a> {
    config: &'a LoopConfig,
    matcher: &'a MatcherConfig,
    /// Every candidate considered, in order; the record index is the loop id.
    pub records: Vec<LoopRecord>,
    candidates: Vec<Candidate>,
    examined: HashSet<(usize, usize)>,
    /// Record indices of deferred candidates still waiting.
    deferred: Vec<usize>,
    consistency: ConsistencyGraph,
    pub chain: DeadReckoningChain,
    /// The current maximum clique.
    pub accepted: Clique,
    /// Loops of the densification pass, accepted against the estimate.
    dense: Vec<LoopMeasurement>,
    /// Clique searches that stopped at the work limit.
    pub inexact_cliques: usize,
    /// Matches run (forward and reverse).
    pub matches: usize,
    /// Time spent on mutual consistency, s.
    pub validation_time_s: f64,
    /// Candidates searched over `max_window` (first contacts).
    pub wide_searches: usize,
    /// The accepted loops (clique and densified), for the cover rule.
    cover: LoopCover,
    /// Which nodes' images stay in memory between matches.
    pub residency: ImageResidency,
}

impl<'a> LoopCloser<'a> {
    pub fn new(config: &'a LoopConfig, matcher: &'a MatcherConfig) -> Self {
        let drift = DriftModel {
            drift_fraction: config.drift_fraction,
            heading_sigma_rad: config.drift_heading_sigma_rad,
        };
        Self {
            config,
            matcher,
            records: Vec::new(),
            candidates: Vec::new(),
            examined: HashSet::new(),
            deferred: Vec::new(),
            consistency: ConsistencyGraph::new(),
            chain: DeadReckoningChain::new(drift),
            accepted: Clique {
                ids: Vec::new(),
                exact: true,
            },
            dense: Vec::new(),
            inexact_cliques: 0,
            matches: 0,
            validation_time_s: 0.0,
            wide_searches: 0,
            cover: LoopCover::new(config.cover_spacing_m),
            residency: ImageResidency::default(),
        }
    }

    /// Looks for loops of the newest node `k`, then retries deferred
    /// candidates while the accepted set changes. Runs the incremental
    /// solves through `optimise` whenever the accepted loops change.
    pub fn close_loops(
        &mut self,
        k: usize,
        nodes: &[NodeData],
        estimate: &mut Estimate,
        optimise: &mut dyn FnMut(&mut Estimate) -> Result<(), SlamError>,
    ) -> Result<(), SlamError> {
        self.residency.enforce(nodes.len(), |i| &nodes[i].image);
        if !self.config.enabled || k < self.config.min_separation_nodes {
            return Ok(());
        }
        let candidates = self.candidates_of(k, nodes, estimate);
        let mut changed = self.process(candidates, k, nodes, estimate)?;
        for _ in 0..MAX_RETRY_ROUNDS {
            if !changed {
                break;
            }
            optimise(estimate)?;
            changed = self.retry_deferred(k, nodes, estimate)?;
        }
        Ok(())
    }

    /// Gated candidates of node `k` (steps 1-2 of the module doc).
    fn candidates_of(
        &mut self,
        k: usize,
        nodes: &[NodeData],
        estimate: &Estimate,
    ) -> Vec<Candidate> {
        let node = &nodes[k];
        if !node.matchable() {
            return Vec::new();
        }
        let poses = estimate.poses();
        let mut overlaps = self.overlapping(k, nodes, poses, self.config.min_predicted_overlap);
        overlaps.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        let max = self.config.max_candidates_per_node;
        overlaps.truncate(CANDIDATE_POOL * max);
        if overlaps.is_empty() {
            return Vec::new();
        }
        let path = estimate.links().relative_from(k, poses);
        // The best-overlapping candidates that can be searched now, and as
        // many again of those too uncertain for now (deferred).
        let (mut ready, mut waiting) = (Vec::new(), Vec::new());
        let s = self.chain.distances();
        // Two candidates of `k` whose older nodes lie within the cover
        // spacing measure nearly the same pair: the better-overlapping one
        // is taken.
        let taken =
            |list: &Vec<Candidate>, j: usize| list.iter().any(|c| self.cover.near(c.from, j, s));
        for (j, overlap) in overlaps {
            let c = self.candidate(j, k, overlap, path[j].as_ref(), poses);
            if !c.too_uncertain(&self.config.gate.max_window) {
                if ready.len() < max && !taken(&ready, j) {
                    ready.push(c);
                }
            } else if waiting.len() < max && !taken(&waiting, j) {
                waiting.push(c);
            }
        }
        // A first contact with a place seen long ago: nothing can be
        // searched in a small window, so the best-overlapping candidates
        // are searched over the largest window now; the checks and the
        // consistency test decide.
        if ready.is_empty() {
            let wide = WIDE_SEARCHES_PER_NODE.min(waiting.len());
            for mut c in waiting.drain(..wide) {
                c.wide = true;
                ready.push(c);
            }
            self.wide_searches += wide;
        }
        ready.extend(waiting);
        ready
    }

    /// The densification pass after the mission (`LoopConfig::densify`):
    /// every pair at least `min_separation_nodes` apart that was never
    /// examined or that `retried_pairs` lists, whose
    /// predicted overlap at the current estimate is at
    /// least `DENSIFY_MIN_PREDICTED_OVERLAP` and whose search window
    /// (`n_sigma` of the relative uncertainty) fits within
    /// `densify_max_window()`, is matched by
    /// climbing from the estimate to the nearest maximum of eq. (6), within
    /// `min_window` ([`match_scan_local`](echofield_frontend::matcher::match_scan_local)),
    /// the symmetric match likewise. A loop that passes the checks of
    /// [`checks`] is accepted when it agrees with the estimate (squared
    /// Mahalanobis distance under its covariance plus the prior's at most
    /// `CONSISTENCY_MAX_CHI2`), else rejected as `inconsistent`; the final
    /// solve's robust kernel still judges it. Pairs covered by accepted
    /// loops are skipped, and the rest matched in rounds of pairs that do
    /// not cover each other ([`cover`]). Returns whether loops were
    /// added.
    pub fn densify(
        &mut self,
        nodes: &[NodeData],
        estimate: &mut Estimate,
    ) -> Result<bool, SlamError> {
        let n = nodes.len();
        let sep = self.config.min_separation_nodes;
        if !self.config.enabled || !self.config.densify || n <= sep {
            return Ok(false);
        }
        let before = self.dense.len();
        for pair in self.retried_pairs() {
            self.examined.remove(&pair);
        }
        let mut pool = self.densification_pairs(nodes, estimate);
        for _ in 0..COVER_ROUNDS {
            if pool.is_empty() {
                break;
            }
            let (picked, rest) = self.pick_uncovered(pool);
            self.densify_round(picked, n - 1, nodes)?;
            pool = rest;
        }
        if self.dense.len() == before {
            return Ok(false);
        }
        estimate.set_loops(self.accepted_edges());
        Ok(true)
    }

    /// The densification pairs at the current estimate, in pair order
    /// (`k`, then `j`), with their priors and windows (`min_window`); pairs
    /// that accepted loops cover ([`cover`]) are left out.
    fn densification_pairs(&self, nodes: &[NodeData], estimate: &Estimate) -> Vec<Candidate> {
        let (min, poses) = (&self.config.gate.min_window, estimate.poses());
        let mut candidates = Vec::new();
        for k in self.config.min_separation_nodes..nodes.len() {
            if !nodes[k].matchable() {
                continue;
            }
            let mut pairs = self.overlapping(k, nodes, poses, DENSIFY_MIN_PREDICTED_OVERLAP);
            if self.cover.enabled() {
                keep_best_overlaps(
                    &mut pairs,
                    CANDIDATE_POOL * self.config.max_candidates_per_node,
                );
            }
            if pairs.is_empty() {
                continue;
            }
            let path = estimate.links().relative_from(k, poses);
            for (j, overlap) in pairs {
                let mut c = self.candidate(j, k, overlap, path[j].as_ref(), poses);
                if c.too_uncertain(&densify_max_window()) {
                    continue;
                }
                c.raw_window = *min;
                c.densify = true;
                candidates.push(c);
            }
        }
        candidates
    }

    /// Splits `pool` (in order) into the pairs to match now, which no
    /// accepted loop and no earlier pick covers, and the pairs only picks
    /// cover (for the next round); pairs accepted loops cover are dropped.
    /// Without the cover rule every pair is picked.
    fn pick_uncovered(&self, pool: Vec<Candidate>) -> (Vec<Candidate>, Vec<Candidate>) {
        let s = self.chain.distances();
        let mut picks = LoopCover::new(self.config.cover_spacing_m);
        let (mut picked, mut rest) = (Vec::new(), Vec::new());
        for c in pool {
            if self.cover.covers(c.from, c.to, s) {
                continue;
            }
            if picks.covers(c.from, c.to, s) {
                rest.push(c);
            } else {
                picks.insert(c.from, c.to);
                picked.push(c);
            }
        }
        (picked, rest)
    }

    /// Matches the densification pairs `candidates` (in parallel), judges
    /// them in order and keeps those that agree with the estimate.
    fn densify_round(
        &mut self,
        candidates: Vec<Candidate>,
        k: usize,
        nodes: &[NodeData],
    ) -> Result<(), SlamError> {
        for c in &candidates {
            self.examined.insert((c.from, c.to));
        }
        let mut records = Vec::with_capacity(candidates.len());
        for batch in candidates.chunks(DENSIFY_BATCH) {
            records.extend(self.examine_all(&batch.iter().collect::<Vec<_>>(), k, nodes)?);
            self.residency.enforce(nodes.len(), |i| &nodes[i].image);
        }
        for (c, mut record) in candidates.into_iter().zip(records) {
            let id = self.records.len();
            if record.rejected_by.is_none()
                && let (Some(z), Some(cov)) = (record.measurement, record.covariance)
            {
                let covariance = with_floor(&cov, &self.config.gate.min_sigma);
                let e = c.prior.inverse().compose(&z);
                let chi2 =
                    mahalanobis2(&e, &(covariance + c.prior_covariance)).unwrap_or(f64::INFINITY);
                if chi2 <= CONSISTENCY_MAX_CHI2 {
                    self.cover.insert(c.from, c.to);
                    self.dense.push(LoopMeasurement {
                        id,
                        from: c.from,
                        to: c.to,
                        z,
                        covariance,
                    });
                } else {
                    record.rejected_by = Some(RejectReason::Inconsistent);
                }
            }
            self.records.push(record);
            self.candidates.push(c);
        }
        Ok(())
    }

    /// The pairs the mission pass examined and rejected only for reasons
    /// that [`RejectReason::densification_retries`], with no densified
    /// record yet: densification matches them again. Most were rejected
    /// for their covariance and come back as partial loops (measured, and
    /// against retrying every rejected pair: EXPERIMENTS.md § Loop
    /// densification).
    fn retried_pairs(&self) -> Vec<(usize, usize)> {
        let mut verdict: HashMap<(usize, usize), bool> = HashMap::new();
        for r in &self.records {
            let pair = (r.from as usize, r.to as usize);
            let retry = !r.densified
                && r.rejected_by
                    .is_some_and(RejectReason::densification_retries);
            verdict
                .entry(pair)
                .and_modify(|v| *v &= retry)
                .or_insert(retry);
        }
        let mut pairs: Vec<_> = verdict
            .into_iter()
            .filter_map(|(pair, retry)| retry.then_some(pair))
            .collect();
        pairs.sort_unstable();
        pairs
    }

    /// Older nodes `j` (at least `min_separation_nodes` back, never
    /// examined with `k`) whose predicted overlap with `k` at `poses` is
    /// at least `min_overlap`, with that overlap.
    fn overlapping(
        &self,
        k: usize,
        nodes: &[NodeData],
        poses: &[Se2],
        min_overlap: f64,
    ) -> Vec<(usize, f64)> {
        let node = &nodes[k];
        let s = self.chain.distances();
        (0..=k - self.config.min_separation_nodes)
            .filter(|&j| nodes[j].matchable() && !self.examined.contains(&(j, k)))
            .filter(|&j| !self.cover.covers(j, k, s))
            .filter_map(|j| {
                let j_from_k = poses[j].between(&poses[k]);
                let reach = nodes[j].footprint_m + node.footprint_m;
                if j_from_k.translation().norm() > reach {
                    return None;
                }
                let overlap = predicted_overlap(
                    &node.scan.points,
                    &j_from_k,
                    nodes[j].footprint_m,
                    OVERLAP_STRIDE,
                );
                (overlap >= min_overlap).then_some((j, overlap))
            })
            .collect()
    }

    /// The prior and window of the pair `(j, k)`.
    fn candidate(
        &self,
        j: usize,
        k: usize,
        overlap: f64,
        k_from_j_cov: Option<&Matrix3<f64>>,
        poses: &[Se2],
    ) -> Candidate {
        let prior = poses[j].between(&poses[k]);
        let k_from_j = prior.inverse();
        let from_path = k_from_j_cov.map(|c| invert(&k_from_j, c).1);
        let from_dr = Some(self.chain.relative(j, k).1);
        // Both are upper bounds of the true relative uncertainty: the
        // window takes the tighter one per axis.
        let covs: Vec<Matrix3<f64>> = from_path.into_iter().chain(from_dr).collect();
        let cov = covs
            .iter()
            .copied()
            .min_by(|a, b| translation_trace(a).total_cmp(&translation_trace(b)))
            .unwrap_or_else(|| Matrix3::from_diagonal(&nalgebra::Vector3::new(1e6, 1e6, 10.0)));
        let n = self.config.gate.n_sigma;
        let sd = |axis: usize| {
            let var = covs
                .iter()
                .map(|c| c[(axis, axis)])
                .fold(f64::INFINITY, f64::min);
            n * if var.is_finite() {
                var.max(0.0).sqrt()
            } else {
                1e3
            }
        };
        Candidate {
            from: j,
            to: k,
            prior,
            prior_covariance: cov,
            predicted_overlap: overlap,
            raw_window: SearchWindow::new(sd(0), sd(1), sd(2).min(std::f64::consts::PI)),
            wide: false,
            densify: false,
        }
    }

    /// Matches or defers `candidates`; returns whether the accepted set
    /// changed.
    fn process(
        &mut self,
        candidates: Vec<Candidate>,
        k: usize,
        nodes: &[NodeData],
        estimate: &mut Estimate,
    ) -> Result<bool, SlamError> {
        let deferred = |c: &Candidate| c.too_uncertain(&self.config.gate.max_window) && !c.wide;
        let searched: Vec<&Candidate> = candidates.iter().filter(|c| !deferred(c)).collect();
        let mut examined = self.examine_all(&searched, k, nodes)?.into_iter();
        let mut passed = Vec::new();
        for candidate in candidates {
            self.examined.insert((candidate.from, candidate.to));
            let id = self.records.len();
            if deferred(&candidate) {
                let mut record = candidate.record(k, self.config);
                record.rejected_by = Some(RejectReason::Deferred);
                self.records.push(record);
                self.candidates.push(candidate);
                self.deferred.push(id);
                if self.deferred.len() > MAX_WAITING {
                    self.deferred.remove(0);
                }
                continue;
            }
            let record = examined.next().expect("one record per searched candidate");
            if record.rejected_by.is_none() {
                passed.push(id);
            }
            self.records.push(record);
            self.candidates.push(candidate);
        }
        Ok(self.admit(passed, estimate))
    }

    /// Matches the candidates independently of each other (in parallel
    /// with rayon; each match reads only the nodes and the configs), and
    /// returns their records in the candidates' order, so the result does
    /// not depend on the number of threads. The first error, in that
    /// order, is returned.
    fn examine_all(
        &mut self,
        candidates: &[&Candidate],
        k: usize,
        nodes: &[NodeData],
    ) -> Result<Vec<LoopRecord>, SlamError> {
        let (matcher, config) = (self.matcher, self.config);
        // Collected whole first: rayon's own `Result` collection may
        // return any of several errors.
        let records = candidates
            .par_iter()
            .map(|c| examine(c, k, nodes, matcher, config))
            .collect::<Vec<_>>()
            .into_iter()
            .collect::<Result<Vec<_>, _>>()?;
        for record in &records {
            self.matches += usize::from(record.matched.is_some() || record.no_match.is_some());
            self.matches += usize::from(record.reverse.is_some());
        }
        Ok(records)
    }

    /// Retries the deferred candidates with the current estimate.
    fn retry_deferred(
        &mut self,
        k: usize,
        nodes: &[NodeData],
        estimate: &mut Estimate,
    ) -> Result<bool, SlamError> {
        let waiting = std::mem::take(&mut self.deferred);
        let (mut ready, mut passed) = (Vec::new(), Vec::new());
        let mut paths: Vec<(usize, Vec<Option<Matrix3<f64>>>)> = Vec::new();
        for id in waiting {
            let (j, to, overlap) = {
                let c = &self.candidates[id];
                (c.from, c.to, c.predicted_overlap)
            };
            if !paths.iter().any(|(t, _)| *t == to) {
                paths.push((to, estimate.links().relative_from(to, estimate.poses())));
            }
            let path = &paths.iter().find(|(t, _)| *t == to).expect("just added").1;
            let candidate = self.candidate(j, to, overlap, path[j].as_ref(), estimate.poses());
            if candidate.too_uncertain(&self.config.gate.max_window) {
                self.deferred.push(id);
                continue;
            }
            ready.push((id, candidate));
        }
        let searched: Vec<&Candidate> = ready.iter().map(|(_, c)| c).collect();
        let records = self.examine_all(&searched, k, nodes)?;
        for ((id, candidate), record) in ready.into_iter().zip(records) {
            if record.rejected_by.is_none() {
                passed.push(id);
            }
            self.records[id] = record;
            self.candidates[id] = candidate;
        }
        Ok(self.admit(passed, estimate))
    }

    /// Adds loops that passed their checks to the consistency graph,
    /// recomputes the maximum clique and updates the estimate's loop
    /// edges. Returns whether the accepted set changed.
    fn admit(&mut self, passed: Vec<usize>, estimate: &mut Estimate) -> bool {
        if passed.is_empty() {
            return false;
        }
        let start = std::time::Instant::now();
        for id in passed {
            let record = &self.records[id];
            let (Some(z), Some(cov)) = (record.measurement, record.covariance) else {
                continue;
            };
            let covariance = with_floor(&cov, &self.config.gate.min_sigma);
            let measurement = LoopMeasurement {
                id,
                from: record.from as usize,
                to: record.to as usize,
                z,
                covariance,
            };
            self.consistency
                .add(measurement, &self.chain, CONSISTENCY_MAX_CHI2);
        }
        let clique = self.consistency.max_clique();
        self.inexact_cliques += usize::from(!clique.exact);
        self.accepted = clique;
        self.validation_time_s += start.elapsed().as_secs_f64();
        self.refresh_cover();
        estimate.set_loops(self.accepted_edges())
    }

    /// Rebuilds the cover ([`cover`]) from the accepted loops: the clique
    /// may have dropped loops that covered pairs.
    fn refresh_cover(&mut self) {
        if !self.cover.enabled() {
            return;
        }
        self.cover.clear();
        for &id in &self.accepted.ids {
            if let Some(m) = self.consistency.measurement(id) {
                self.cover.insert(m.from, m.to);
            }
        }
        for m in &self.dense {
            self.cover.insert(m.from, m.to);
        }
    }

    /// The loop edges of the accepted set, with their covariances: the
    /// clique's loops as matched, the densified ones inflated by their
    /// design effect (`loops::config::DENSIFY_CORRELATION`).
    fn accepted_edges(&self) -> Vec<(usize, echofield_graph::Edge, Matrix3<f64>)> {
        let primary: Vec<&LoopMeasurement> = self
            .accepted
            .ids
            .iter()
            .filter_map(|&id| self.consistency.measurement(id))
            .collect();
        let places = Places::new(
            self.config.cover_spacing_m,
            self.chain.distances(),
            primary.iter().copied().chain(&self.dense),
        );
        let rho = DENSIFY_CORRELATION;
        let inflations = self.dense.iter().map(|m| places.design_effect(m, rho));
        primary
            .into_iter()
            .map(|m| (m, 1.0))
            .chain(self.dense.iter().zip(inflations))
            .filter_map(|(m, inflation)| {
                let id = m.id;
                let covariance = m.covariance * inflation;
                let metadata = loop_metadata(&self.records[id]);
                let edge =
                    make_edge(EdgeKind::Loop, m.from, m.to, m.z, &covariance, metadata).ok()?;
                Some((id, edge, covariance))
            })
            .collect()
    }

    /// Takes accepted loops out again (e.g. outliers of the final solve),
    /// with `reason`, and updates the estimate's loop edges.
    pub fn reject(&mut self, ids: &[usize], reason: RejectReason, estimate: &mut Estimate) {
        self.accepted.ids.retain(|id| !ids.contains(id));
        self.dense.retain(|m| !ids.contains(&m.id));
        for &id in ids {
            self.records[id].accepted = false;
            self.records[id].rejected_by = Some(reason);
        }
        self.refresh_cover();
        estimate.set_loops(self.accepted_edges());
    }

    /// Marks the final verdicts: accepted for the clique members, rejected
    /// as `inconsistent` for loops that passed their checks but are not in
    /// it; deferred candidates keep `deferred`.
    pub fn finish(&mut self) {
        let accepted: HashSet<usize> = self
            .accepted
            .ids
            .iter()
            .copied()
            .chain(self.dense.iter().map(|m| m.id))
            .collect();
        for (id, record) in self.records.iter_mut().enumerate() {
            record.accepted = accepted.contains(&id);
            if record.rejected_by.is_none() && !record.accepted {
                record.rejected_by = Some(RejectReason::Inconsistent);
            }
        }
    }

    /// Ids and measurements of the accepted loops.
    pub fn accepted_measurements(&self) -> Vec<LoopMeasurement> {
        self.accepted
            .ids
            .iter()
            .filter_map(|&id| self.consistency.measurement(id).cloned())
            .chain(self.dense.iter().cloned())
            .collect()
    }
}

/// The loops at each place, for the design effect `1 + ρ·(m_j + m_k − 2)`
/// of a loop `(j, k)`: `m_x` counts the accepted loop ends at node `x`
/// or, with the cover rule on (`spacing_m > 0`), within `spacing_m` of
/// travel of it ([`cover`]): loops seen from nearly the same place share
/// its errors as loops at one node do.
struct Places<'a> {
    spacing_m: f64,
    distance_m: &'a [f64],
    /// The loop ends: node ids, and their travelled distances, ascending.
    nodes: HashMap<usize, usize>,
    ends_m: Vec<f64>,
}

impl<'a> Places<'a> {
    fn new<'m>(
        spacing_m: f64,
        distance_m: &'a [f64],
        loops: impl Iterator<Item = &'m LoopMeasurement>,
    ) -> Self {
        let mut nodes: HashMap<usize, usize> = HashMap::new();
        let mut ends_m = Vec::new();
        for m in loops {
            for x in [m.from, m.to] {
                *nodes.entry(x).or_default() += 1;
                if let Some(&d) = distance_m.get(x) {
                    ends_m.push(d);
                }
            }
        }
        ends_m.sort_unstable_by(f64::total_cmp);
        // A loop end past the known distances (none in a run) makes the
        // count fall back to ends at the node itself.
        let spacing_m = if ends_m.len() == nodes.values().sum::<usize>() {
            spacing_m
        } else {
            0.0
        };
        Self {
            spacing_m,
            distance_m,
            nodes,
            ends_m,
        }
    }

    /// `m_x`: the loop ends at node `x` or near it.
    fn loops_at(&self, x: usize) -> usize {
        match self.distance_m.get(x) {
            Some(&d) if self.spacing_m > 0.0 => {
                let lo = self.ends_m.partition_point(|&e| e < d - self.spacing_m);
                let hi = self.ends_m.partition_point(|&e| e <= d + self.spacing_m);
                hi - lo
            }
            _ => self.nodes.get(&x).copied().unwrap_or(0),
        }
    }

    /// `1 + ρ·(m_j + m_k − 2)` of the accepted loop `m` (counted in
    /// `m_j` and `m_k` itself).
    fn design_effect(&self, m: &LoopMeasurement, rho: f64) -> f64 {
        let others = (self.loops_at(m.from) + self.loops_at(m.to)).saturating_sub(2);
        1.0 + rho * others as f64
    }
}

/// What a loop edge carries besides its measurement (g2o drops it).
pub fn loop_metadata(record: &LoopRecord) -> Option<serde_json::Value> {
    let quality = record.quality.as_ref()?;
    Some(serde_json::json!({
        "score": record.score,
        "mean_intensity": quality.mean_intensity,
        "inside_fraction": quality.inside_fraction,
        "points": quality.points,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn densification_keeps_the_best_overlapping_pairs_of_a_node_in_order() {
        let mut pairs = vec![(3, 0.5), (7, 0.9), (8, 0.45), (12, 0.9), (20, 0.6)];
        keep_best_overlaps(&mut pairs, 3);
        // 0.9, 0.9 and 0.6 stay, in node order.
        assert_eq!(pairs, [(7, 0.9), (12, 0.9), (20, 0.6)]);
        // Equal overlaps: the older node first.
        let mut pairs = vec![(5, 0.7), (2, 0.7), (9, 0.7)];
        keep_best_overlaps(&mut pairs, 2);
        assert_eq!(pairs, [(5, 0.7), (2, 0.7)]);
        let mut few = vec![(1, 0.4)];
        keep_best_overlaps(&mut few, 2);
        assert_eq!(few, [(1, 0.4)]);
    }

    fn measurement(id: usize, from: usize, to: usize) -> LoopMeasurement {
        LoopMeasurement {
            id,
            from,
            to,
            z: Se2::identity(),
            covariance: Matrix3::identity(),
        }
    }

    /// A record of the pair `(from, to)` with the given outcome.
    fn record(
        from: usize,
        to: usize,
        rejected_by: Option<RejectReason>,
        densified: bool,
    ) -> LoopRecord {
        let candidate = Candidate {
            from,
            to,
            prior: Se2::identity(),
            prior_covariance: Matrix3::identity(),
            predicted_overlap: 0.8,
            raw_window: SearchWindow::new(1.0, 1.0, 0.1),
            wide: false,
            densify: densified,
        };
        let mut record = candidate.record(to, &LoopConfig::default());
        record.rejected_by = rejected_by;
        record
    }

    #[test]
    fn densification_retries_the_pairs_rejected_for_how_they_were_searched() {
        let (config, matcher) = (LoopConfig::default(), MatcherConfig::default());
        let mut closer = LoopCloser::new(&config, &matcher);
        closer.records = vec![
            record(0, 12, Some(RejectReason::Covariance), false),
            record(1, 13, Some(RejectReason::WindowEdge), false),
            record(2, 14, Some(RejectReason::Deferred), false),
            // Evidence against the match: not retried.
            record(3, 15, Some(RejectReason::Quality), false),
            record(4, 16, Some(RejectReason::ReverseMismatch), false),
            record(5, 17, Some(RejectReason::Inconsistent), false),
            record(6, 18, Some(RejectReason::NoMatch), false),
            // Deferred, then matched and accepted: not retried.
            record(7, 19, Some(RejectReason::Deferred), false),
            record(7, 19, None, false),
            // Already densified once.
            record(8, 20, Some(RejectReason::Covariance), false),
            record(8, 20, Some(RejectReason::Covariance), true),
        ];
        assert_eq!(closer.retried_pairs(), vec![(0, 12), (1, 13), (2, 14)]);
    }

    fn pair(from: usize, to: usize) -> Candidate {
        let mut c = record_candidate(from, to);
        c.densify = true;
        c
    }

    fn record_candidate(from: usize, to: usize) -> Candidate {
        Candidate {
            from,
            to,
            prior: Se2::identity(),
            prior_covariance: Matrix3::identity(),
            predicted_overlap: 0.8,
            raw_window: SearchWindow::new(1.0, 1.0, 0.1),
            wide: false,
            densify: false,
        }
    }

    /// A closer whose dead-reckoning chain has nodes 1 m apart along x.
    fn closer_on_a_line<'a>(config: &'a LoopConfig, matcher: &'a MatcherConfig) -> LoopCloser<'a> {
        let mut closer = LoopCloser::new(config, matcher);
        for i in 0..40 {
            let cov = Matrix3::identity() * 1e-4;
            closer.chain.push(Se2::new(i as f64, 0.0, 0.0), 1e-4, &cov);
        }
        closer
    }

    #[test]
    fn densification_picks_pairs_that_no_kept_loop_or_earlier_pick_covers() {
        let config = LoopConfig {
            cover_spacing_m: 2.0,
            ..LoopConfig::default()
        };
        let matcher = MatcherConfig::default();
        let mut closer = closer_on_a_line(&config, &matcher);
        // An accepted loop (2, 30): it covers the pairs within 2 m of
        // travel at both ends.
        closer.dense.push(measurement(0, 2, 30));
        closer.refresh_cover();
        let pool = vec![
            pair(1, 29),  // covered by (2, 30): dropped
            pair(4, 32),  // 2 m from both ends: covered, dropped
            pair(5, 30),  // 3 m from node 2: picked
            pair(6, 31),  // covered by the pick (5, 30): next round
            pair(10, 20), // far from everything: picked
            pair(10, 23), // 3 m from (10, 20) at k: picked
        ];
        let (picked, rest) = closer.pick_uncovered(pool);
        let ends = |v: &[Candidate]| v.iter().map(|c| (c.from, c.to)).collect::<Vec<_>>();
        assert_eq!(ends(&picked), vec![(5, 30), (10, 20), (10, 23)]);
        assert_eq!(ends(&rest), vec![(6, 31)]);
        // Without the rule every pair is picked.
        let off = LoopConfig {
            cover_spacing_m: 0.0,
            ..LoopConfig::default()
        };
        let mut closer = closer_on_a_line(&off, &matcher);
        closer.dense.push(measurement(0, 2, 30));
        closer.refresh_cover();
        let (picked, rest) = closer.pick_uncovered(vec![pair(1, 29), pair(2, 30), pair(6, 31)]);
        assert_eq!(picked.len(), 3);
        assert!(rest.is_empty());
    }

    #[test]
    fn a_loop_dropped_from_the_clique_no_longer_covers() {
        let config = LoopConfig {
            cover_spacing_m: 2.0,
            ..LoopConfig::default()
        };
        let matcher = MatcherConfig::default();
        let mut closer = closer_on_a_line(&config, &matcher);
        let chain = closer.chain.clone();
        closer
            .consistency
            .add(measurement(7, 3, 25), &chain, CONSISTENCY_MAX_CHI2);
        closer.accepted = Clique {
            ids: vec![7],
            exact: true,
        };
        closer.refresh_cover();
        let s = closer.chain.distances().to_vec();
        assert!(closer.cover.covers(4, 26, &s));
        closer.accepted.ids.clear();
        closer.refresh_cover();
        assert!(!closer.cover.covers(4, 26, &s));
    }

    #[test]
    fn loops_near_a_node_count_in_its_design_effect() {
        let distance_m: Vec<f64> = (0..40).map(f64::from).collect();
        let loops = [
            measurement(0, 2, 30),
            measurement(1, 3, 31),
            measurement(2, 10, 20),
        ];
        // Spacing 1.5 m: nodes 2 and 3 are one place, so are 30 and 31.
        let places = Places::new(1.5, &distance_m, loops.iter());
        assert_eq!(places.loops_at(2), 2);
        assert_eq!(places.loops_at(31), 2);
        assert_eq!(places.loops_at(10), 1);
        assert_eq!(places.design_effect(&loops[0], 1.0), 3.0);
        assert_eq!(places.design_effect(&loops[2], 1.0), 1.0);
        // Without the rule only the node's own loops count.
        let places = Places::new(0.0, &distance_m, loops.iter());
        assert_eq!(places.design_effect(&loops[0], 1.0), 1.0);
    }

    #[test]
    fn densified_loops_are_inflated_by_the_loops_sharing_their_nodes() {
        let primary = [measurement(0, 0, 20), measurement(1, 1, 20)];
        let primary: Vec<&LoopMeasurement> = primary.iter().collect();
        let dense = [
            // Node 0 holds one other loop, node 21 none.
            measurement(2, 0, 21),
            // Nodes 1 and 20 hold one and two other loops.
            measurement(3, 1, 20),
            // Alone at both ends.
            measurement(4, 5, 30),
        ];
        let effects = |rho: f64| {
            let places = Places::new(0.0, &[], primary.iter().copied().chain(&dense));
            dense
                .iter()
                .map(|m| places.design_effect(m, rho))
                .collect::<Vec<f64>>()
        };
        assert_eq!(effects(0.5), vec![1.5, 1.0 + 0.5 * 3.0, 1.0]);
        assert_eq!(effects(0.0), vec![1.0; 3]);
    }
}
