//! Loop densification (step 5 of the module doc of [`super`], on by
//! default, after the mission).
//!
//! The pairs never examined whose relative pose the estimate already
//! knows are matched by a local climb from the estimate, gated by the
//! tighter `densify_max_sigma`, and accepted when they agree with the
//! estimate ([`LoopCloser::densify`]); so are the pairs the mission
//! rejected only for how they were searched (a window too large, a peak at
//! its edge, a match unsure along some direction:
//! [`RejectReason::densification_retries`]). A densified loop's covariance
//! is inflated by the design effect of the loops at its places
//! ([`Places`](echofield_frontend::loops::places::Places)). Densification,
//! too, skips covered pairs: it matches in rounds the pairs that neither an
//! accepted loop nor an earlier pick of the round covers ([`COVER_ROUNDS`],
//! [`cover`]), and takes at most `3 · max_candidates_per_node` pairs per
//! node, the best-overlapping ones. The matches of a round are read in
//! place order ([`place_order`]), so that each image the residency
//! released is built again about once per round.

use super::LoopCloser;
use super::candidates::CANDIDATE_POOL;
use crate::slam::SlamError;
use crate::slam::estimate::Estimate;
use echofield_frontend::loops::checks::Candidate;
use echofield_frontend::loops::config::{
    CONSISTENCY_MAX_CHI2, DENSIFY_MIN_PREDICTED_OVERLAP, densify_max_window,
};
use echofield_frontend::loops::consistency::LoopMeasurement;
use echofield_frontend::loops::cover::LoopCover;
use echofield_frontend::loops::schedule::place_order;
use echofield_frontend::loops::{LoopRecord, RejectReason};
#[cfg(doc)]
use echofield_frontend::loops::{checks, cover};
use echofield_frontend::nodes::NodeData;
use echofield_frontend::uncertainty::{mahalanobis2, with_floor};
use echofield_graph::Se2;
use std::collections::{HashMap, HashSet};

/// Rounds of densification picks under the cover rule ([`cover`]): each
/// round matches the pairs that neither a kept loop nor an earlier pick of
/// the round covers; the next one picks among the pairs only failed picks
/// covered.
pub const COVER_ROUNDS: usize = 3;
/// Densification pairs matched between two looks of the image residency
/// policy: bounds the images a batch builds beyond the budget.
const DENSIFY_BATCH: usize = 64;
/// Nodes within this distance of each other, metres, at the estimate,
/// count as one place for the order of the densification matches
/// ([`place_order`]): passes over a quay a few metres apart are one
/// place. It changes the order of the image reads, never a result.
const PLACE_RADIUS_M: f64 = 5.0;

impl LoopCloser<'_> {
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
            self.densify_round(picked, n - 1, nodes, estimate.poses())?;
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
            let targets: Vec<usize> = pairs.iter().map(|&(j, _)| j).collect();
            let paths = estimate.links().relative_to(k, poses, &targets);
            for ((j, overlap), path) in pairs.into_iter().zip(&paths) {
                let mut c = self.candidate(j, k, overlap, path.as_ref(), poses);
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

    /// Matches the densification pairs `candidates` ([`Self::examine_by_place`]),
    /// judges them in their order ([`Self::judge_dense`]) and keeps those
    /// that agree with the estimate, whose poses are `poses`.
    fn densify_round(
        &mut self,
        candidates: Vec<Candidate>,
        k: usize,
        nodes: &[NodeData],
        poses: &[Se2],
    ) -> Result<(), SlamError> {
        for c in &candidates {
            self.examined.insert((c.from, c.to));
        }
        let records = self.examine_by_place(&candidates, k, nodes, poses)?;
        for (c, record) in candidates.into_iter().zip(records) {
            self.judge_dense(c, record);
        }
        Ok(())
    }

    /// The records of `candidates`, in their order, matched in batches of
    /// [`DENSIFY_BATCH`] pairs (each batch in parallel) taken in place order
    /// ([`place_order`] of the older nodes at `poses`, the places whose
    /// images are held now first), with the image
    /// residency's budget enforced after each batch: the images of a place
    /// are read while its pairs are matched, so a released image is built
    /// again about once per round instead of once per pass over its place.
    /// The order changes which images are held when, never a record.
    /// Errors: the first of [`Self::examine_all`], in place order.
    fn examine_by_place(
        &mut self,
        candidates: &[Candidate],
        k: usize,
        nodes: &[NodeData],
        poses: &[Se2],
    ) -> Result<Vec<LoopRecord>, SlamError> {
        let pairs: Vec<(usize, usize)> = candidates.iter().map(|c| (c.from, c.to)).collect();
        let held = |i: usize| nodes.get(i).is_some_and(|n| n.image.is_resident());
        let order = place_order(&pairs, poses, PLACE_RADIUS_M, held);
        let mut records: Vec<Option<LoopRecord>> = (0..candidates.len()).map(|_| None).collect();
        for batch in order.chunks(DENSIFY_BATCH) {
            let matched: Vec<&Candidate> = batch.iter().map(|&q| &candidates[q]).collect();
            let examined = self.examine_all(&matched, k, nodes)?;
            for (&q, record) in batch.iter().zip(examined) {
                records[q] = Some(record);
            }
            self.residency.enforce(nodes.len(), |i| &nodes[i].image);
        }
        // `order` is a permutation of the candidates: every slot is filled.
        Ok(records.into_iter().flatten().collect())
    }

    /// Records the densified match `record` of `c`: a loop (added to the
    /// cover) when it passed its checks and agrees with the estimate
    /// (squared Mahalanobis distance of the measurement from the prior,
    /// under the floored match covariance plus the prior's, at most
    /// `CONSISTENCY_MAX_CHI2`), else rejected as `inconsistent`.
    fn judge_dense(&mut self, c: Candidate, mut record: LoopRecord) {
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

    /// The pairs the mission pass examined and rejected only for reasons
    /// that [`RejectReason::densification_retries`], with no densified
    /// record yet: densification matches them again. Most were rejected
    /// for their covariance and come back as partial loops (measured, and
    /// against retrying every rejected pair: EXPERIMENTS.md § Loop
    /// densification).
    pub(super) fn retried_pairs(&self) -> Vec<(usize, usize)> {
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
}

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

#[cfg(test)]
mod tests {
    use super::super::fixtures::{closer_on_a_line, measurement};
    use super::*;
    use echofield_frontend::loops::LoopConfig;
    use echofield_frontend::matcher::{MatcherConfig, SearchWindow};
    use nalgebra::Matrix3;

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

    /// A record of the pair `(from, to)` with the given outcome.
    fn record(
        from: usize,
        to: usize,
        rejected_by: Option<RejectReason>,
        densified: bool,
    ) -> LoopRecord {
        let mut candidate = record_candidate(from, to);
        candidate.densify = densified;
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
}
