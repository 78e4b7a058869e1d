//! Loop candidates of a node (steps 1-2 of the module doc of [`super`]):
//! the older nodes its scan is predicted to overlap, each with its prior
//! `j_from_k` from the current estimate, the prior's covariance and the
//! search window it implies.

use super::LoopCloser;
use crate::slam::estimate::Estimate;
use echofield_frontend::loops::checks::Candidate;
use echofield_frontend::loops::config::WIDE_SEARCHES_PER_NODE;
use echofield_frontend::matcher::SearchWindow;
use echofield_frontend::nodes::{NodeData, predicted_overlap};
use echofield_frontend::uncertainty::{invert, translation_trace};
use echofield_graph::Se2;
use nalgebra::Matrix3;

/// Every `OVERLAP_STRIDE`-th scan point is used to predict the overlap.
const OVERLAP_STRIDE: usize = 4;
/// Pairs considered per node, in multiples of `max_candidates_per_node`,
/// before the uncertainty gate.
pub(super) const CANDIDATE_POOL: usize = 3;

impl LoopCloser<'_> {
    /// Gated candidates of node `k` (steps 1-2 of the module doc).
    pub(super) fn candidates_of(
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
        let targets: Vec<usize> = overlaps.iter().map(|&(j, _)| j).collect();
        let paths = estimate.links().relative_to(k, poses, &targets);
        // The best-overlapping candidates that can be searched now, and as
        // many again of those too uncertain for now (deferred).
        let (mut ready, mut waiting) = (Vec::new(), Vec::new());
        let s = self.chain.distances();
        // Two candidates of `k` whose older nodes lie within the cover
        // spacing measure nearly the same pair: the better-overlapping one
        // is taken.
        let taken =
            |list: &Vec<Candidate>, j: usize| list.iter().any(|c| self.cover.near(c.from, j, s));
        for ((j, overlap), path) in overlaps.into_iter().zip(&paths) {
            let c = self.candidate(j, k, overlap, path.as_ref(), poses);
            if !c.too_uncertain(&self.config.gate.max_window) {
                if ready.len() < max && !taken(&ready, j) {
                    ready.push(c);
                }
            } else if waiting.len() < max && !taken(&waiting, j) {
                waiting.push(c);
            }
        }
        self.widen_first_contact(&mut ready, &mut waiting);
        ready.extend(waiting);
        ready
    }

    /// A first contact with a place seen long ago: when nothing can be
    /// searched in a small window (`ready` empty), the best-overlapping
    /// `WIDE_SEARCHES_PER_NODE` of `waiting` move to `ready`, to be searched
    /// over the largest window now; the checks and the consistency test
    /// decide.
    fn widen_first_contact(&mut self, ready: &mut Vec<Candidate>, waiting: &mut Vec<Candidate>) {
        if !ready.is_empty() {
            return;
        }
        let wide = WIDE_SEARCHES_PER_NODE.min(waiting.len());
        for mut c in waiting.drain(..wide) {
            c.wide = true;
            ready.push(c);
        }
        self.wide_searches += wide;
    }

    /// Older nodes `j` (at least `min_separation_nodes` back, never
    /// examined with `k`) whose predicted overlap with `k` at `poses` is
    /// at least `min_overlap`, with that overlap.
    pub(super) fn overlapping(
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
    pub(super) fn candidate(
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
}
