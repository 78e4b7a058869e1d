//! The accepted loops: the clique's and the densified ones, as the
//! estimate's loop edges, as the cover of the cover rule, and as the final
//! verdicts of the records.

use super::LoopCloser;
use crate::slam::estimate::{Estimate, make_edge};
use echofield_frontend::loops::config::DENSIFY_CORRELATION;
use echofield_frontend::loops::consistency::LoopMeasurement;
#[cfg(doc)]
use echofield_frontend::loops::cover;
use echofield_frontend::loops::places::Places;
use echofield_frontend::loops::{LoopRecord, RejectReason};
use echofield_graph::EdgeKind;
use nalgebra::Matrix3;
use std::collections::HashSet;

impl LoopCloser<'_> {
    /// Rebuilds the cover ([`cover`]) from the accepted loops: the clique
    /// may have dropped loops that covered pairs.
    pub(super) fn refresh_cover(&mut self) {
        if !self.cover.enabled() {
            return;
        }
        self.cover.clear();
        for id in self.in_estimate() {
            if let Some(m) = self.consistency.measurement(id) {
                self.cover.insert(m.from, m.to);
            }
        }
        for m in &self.dense {
            self.cover.insert(m.from, m.to);
        }
    }

    /// Brings the cover and the estimate's loop edges from the clique
    /// `previous` (ids ascending) to the current one, with no densified
    /// loop yet: only the loops that left or joined are touched, so a
    /// mission whose clique changes at nearly every node does not remake
    /// every loop's edge each time (work that grew with nodes × loops).
    /// Precondition: the cover and the estimate's loops are those of
    /// `previous`, as [`Self::admit`] leaves them. Ends in the state
    /// [`Self::refresh_cover`] and `estimate.set_loops(self.accepted_edges())`
    /// would leave (the links of a node in another order, which no path
    /// search depends on), and returns what that `set_loops` would.
    pub(super) fn apply_clique_change(
        &mut self,
        previous: &[usize],
        estimate: &mut Estimate,
    ) -> bool {
        debug_assert!(self.dense.is_empty(), "densified loops need set_loops");
        let (left, joined) = sorted_difference(previous, &self.in_estimate());
        for &id in &left {
            if let Some(m) = self.consistency.measurement(id) {
                self.cover.remove(m.from, m.to);
            }
        }
        let mut edges = Vec::with_capacity(joined.len());
        for &id in &joined {
            if let Some(m) = self.consistency.measurement(id) {
                self.cover.insert(m.from, m.to);
                edges.extend(loop_edge(m, 1.0));
            }
        }
        estimate.update_loops(&left, edges)
    }

    /// The loop edges of the accepted set, with their covariances: the
    /// clique's loops as matched (inflated by their design effect too with
    /// `shared_place_errors`), the densified ones inflated by their
    /// design effect (`loops::config::DENSIFY_CORRELATION`). Without
    /// metadata: [`Self::attach_metadata`] gives it to the final ones.
    pub(super) fn accepted_edges(&self) -> Vec<(usize, echofield_graph::Edge, Matrix3<f64>)> {
        let primary: Vec<&LoopMeasurement> = self
            .in_estimate()
            .into_iter()
            .filter_map(|id| self.consistency.measurement(id))
            .collect();
        let places = Places::new(
            self.config.cover_spacing_m,
            self.chain.distances(),
            primary.iter().copied().chain(&self.dense),
        );
        let rho = DENSIFY_CORRELATION;
        let inflations = self.dense.iter().map(|m| places.design_effect(m, rho));
        let shared = self.config.shared_place_errors;
        let clique_inflation = |m: &LoopMeasurement| {
            if shared {
                places.design_effect(m, rho)
            } else {
                1.0
            }
        };
        primary
            .into_iter()
            .map(|m| (m, clique_inflation(m)))
            .chain(self.dense.iter().zip(inflations))
            .filter_map(|(m, inflation)| loop_edge(m, inflation))
            .collect()
    }

    /// The clique's loops the estimate holds: its members but the held
    /// ones (ids ascending).
    pub(super) fn in_estimate(&self) -> Vec<usize> {
        let (_, kept) = sorted_difference(&self.held, &self.accepted.ids);
        kept
    }

    /// Ends the wait for contested loops (the mission pass is over, no
    /// candidate will come to decide them): the estimate and the cover take
    /// the whole clique. Returns whether the estimate's loops changed.
    pub fn settle(&mut self, estimate: &mut Estimate) -> bool {
        if self.held.is_empty() {
            return false;
        }
        let previous = self.in_estimate();
        self.held.clear();
        self.update_estimate(&previous, estimate)
    }

    /// Brings the cover and the estimate's loop edges from the loops
    /// `previous` (ids ascending, what the estimate held) to
    /// [`Self::in_estimate`]: by the change alone while no loop is
    /// densified, else remade whole (a design effect depends on every
    /// accepted loop). Returns whether the estimate's loops changed.
    pub(super) fn update_estimate(&mut self, previous: &[usize], estimate: &mut Estimate) -> bool {
        if !self.dense.is_empty() {
            self.refresh_cover();
            return estimate.set_loops(self.accepted_edges());
        }
        self.apply_clique_change(previous, estimate)
    }

    /// The end of the mission pass: with `shared_place_errors` the
    /// estimate's loop edges are remade whole, the clique's loops weighted
    /// by the design effect of their places from now on (until then they
    /// entered as matched). Returns whether the estimate's loops changed.
    pub fn weigh_shared_places(&mut self, estimate: &mut Estimate) -> bool {
        self.config.shared_place_errors && estimate.set_loops(self.accepted_edges())
    }

    /// Gives the estimate's loop edges their metadata ([`loop_metadata`]
    /// of their records), before a graph leaves the estimate.
    pub fn attach_metadata(&self, estimate: &mut Estimate) {
        estimate.attach_loop_metadata(|id| loop_metadata(&self.records[id]));
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

/// The loop edge of `m` with its covariance times `inflation` (id, edge,
/// covariance), without metadata; `None` when that covariance is not
/// positive definite (the loop then stays out of the graph).
fn loop_edge(
    m: &LoopMeasurement,
    inflation: f64,
) -> Option<(usize, echofield_graph::Edge, Matrix3<f64>)> {
    let covariance = m.covariance * inflation;
    let edge = make_edge(EdgeKind::Loop, m.from, m.to, m.z, &covariance, None).ok()?;
    Some((m.id, edge, covariance))
}

/// The ids of `old` not in `new` and of `new` not in `old` (both
/// ascending), each ascending.
fn sorted_difference(old: &[usize], new: &[usize]) -> (Vec<usize>, Vec<usize>) {
    let (mut left, mut joined) = (Vec::new(), Vec::new());
    let (mut old, mut new) = (old.iter().peekable(), new.iter().peekable());
    loop {
        match (old.peek(), new.peek()) {
            (Some(a), Some(b)) if a == b => {
                old.next();
                new.next();
            }
            (Some(&&a), Some(&&b)) if a < b => {
                left.push(a);
                old.next();
            }
            (_, Some(&&b)) => {
                joined.push(b);
                new.next();
            }
            (Some(&&a), None) => {
                left.push(a);
                old.next();
            }
            (None, None) => return (left, joined),
        }
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
    use super::super::LoopCloser;
    use super::super::fixtures::{closer_on_a_line, measurement};
    use super::{DENSIFY_CORRELATION, sorted_difference};
    use crate::slam::config::BackendConfig;
    use crate::slam::estimate::Estimate;
    use echofield_frontend::loops::LoopConfig;
    use echofield_frontend::loops::config::CONSISTENCY_MAX_CHI2;
    use echofield_frontend::loops::consistency::{Clique, LoopMeasurement};
    use echofield_frontend::matcher::MatcherConfig;
    use echofield_graph::{EdgeKind, Se2};
    use nalgebra::Matrix3;

    /// Loops kept within 2 m of track cover each other.
    fn spaced_config() -> LoopConfig {
        LoopConfig {
            cover_spacing_m: 2.0,
            ..LoopConfig::default()
        }
    }

    /// A loop `from -> to` of `closer_on_a_line`, measured as the line has
    /// it (`to - from` metres along x).
    fn line_loop(id: usize, from: usize, to: usize) -> LoopMeasurement {
        let mut m = measurement(id, from, to);
        m.z = Se2::new((to - from) as f64, 0.0, 0.0);
        m
    }

    #[test]
    fn a_loop_dropped_from_the_clique_no_longer_covers() {
        let config = spaced_config();
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
    fn sorted_difference_lists_the_ids_that_left_and_joined() {
        assert_eq!(
            sorted_difference(&[1, 3, 5, 9], &[2, 3, 9, 11, 12]),
            (vec![1, 5], vec![2, 11, 12])
        );
        assert_eq!(sorted_difference(&[], &[4]), (vec![], vec![4]));
        assert_eq!(sorted_difference(&[4, 6], &[]), (vec![4, 6], vec![]));
        assert_eq!(sorted_difference(&[4, 6], &[4, 6]), (vec![], vec![]));
    }

    /// The 40 nodes of `closer_on_a_line` in an estimate, chained by 1 m
    /// odometry edges.
    fn line_estimate() -> Estimate {
        let mut estimate = Estimate::new(&BackendConfig::default()).unwrap();
        let cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(0.01, 0.02, 1e-4));
        for i in 0..40 {
            estimate.add_node(i as f64, Se2::new(i as f64, 0.1 * i as f64, 0.0));
            if i > 0 {
                let step = Se2::new(1.0, 0.0, 0.0);
                let kind = EdgeKind::Odometry;
                estimate
                    .add_chain_edge(kind, i - 1, i, step, &cov, None)
                    .unwrap();
            }
        }
        estimate
    }

    /// Everything the cover and the estimate's loops answer: covered pairs,
    /// loop ids, the graph's edges, every node's path covariances.
    fn state(closer: &LoopCloser, estimate: &Estimate) -> String {
        let s = closer.chain.distances();
        let covered: Vec<(usize, usize)> = (0..40)
            .flat_map(|j| (j..40).map(move |k| (j, k)))
            .filter(|&(j, k)| closer.cover.covers(j, k, s))
            .collect();
        let ids: Vec<usize> = estimate.loop_ids().collect();
        let edges: Vec<_> = estimate.graph().unwrap().edges().cloned().collect();
        let paths: Vec<_> = (0..40)
            .map(|i| estimate.links().relative_from(i, estimate.poses()))
            .collect();
        format!("{covered:?}\n{ids:?}\n{edges:?}\n{paths:?}")
    }

    #[test]
    fn a_clique_change_ends_where_remaking_every_loop_ends() {
        let config = spaced_config();
        let matcher = MatcherConfig::default();
        let (mut by_change, mut remade) = (
            closer_on_a_line(&config, &matcher),
            closer_on_a_line(&config, &matcher),
        );
        let (mut estimate_a, mut estimate_b) = (line_estimate(), line_estimate());
        for closer in [&mut by_change, &mut remade] {
            let chain = closer.chain.clone();
            for (id, from, to) in [(7, 3, 25), (9, 5, 30), (12, 1, 38), (15, 10, 22)] {
                let mut m = line_loop(id, from, to);
                m.covariance *= 0.01 * id as f64;
                closer.consistency.add(m, &chain, CONSISTENCY_MAX_CHI2);
            }
        }
        // Loops joining, leaving, coming back, and nothing changing.
        let cliques: [&[usize]; 6] = [&[7], &[7, 9, 12], &[9, 15], &[7, 9, 15], &[7, 9, 15], &[]];
        for ids in cliques {
            let previous = std::mem::replace(&mut by_change.accepted.ids, ids.to_vec());
            let changed_a = by_change.apply_clique_change(&previous, &mut estimate_a);
            remade.accepted.ids = ids.to_vec();
            remade.refresh_cover();
            let changed_b = estimate_b.set_loops(remade.accepted_edges());
            assert_eq!(changed_a, changed_b, "{ids:?}");
            assert_eq!(
                state(&by_change, &estimate_a),
                state(&remade, &estimate_b),
                "{ids:?}"
            );
        }
    }

    /// With `shared_place_errors`, two clique loops between the same two
    /// nodes enter with their covariance times the design effect
    /// `1 + ρ·(2 + 2 − 2)` (ρ = `DENSIFY_CORRELATION` = 1: 3), a loop alone
    /// at its nodes as matched; without it every clique loop enters as
    /// matched.
    #[test]
    fn loops_that_share_a_place_share_their_weight_when_told_to() {
        let matcher = MatcherConfig::default();
        let covariance_of = |shared: bool| {
            let config = LoopConfig {
                shared_place_errors: shared,
                ..LoopConfig::default()
            };
            let mut closer = closer_on_a_line(&config, &matcher);
            let chain = closer.chain.clone();
            // Loops 7 and 9 both join nodes 3 and 25; loop 12 is alone.
            for (id, from, to) in [(7, 3, 25), (9, 3, 25), (12, 10, 38)] {
                closer
                    .consistency
                    .add(line_loop(id, from, to), &chain, CONSISTENCY_MAX_CHI2);
            }
            closer.accepted.ids = vec![7, 9, 12];
            let mut estimate = line_estimate();
            assert!(closer.update_estimate(&[], &mut estimate));
            let as_matched = estimate.graph().unwrap();
            assert_eq!(closer.weigh_shared_places(&mut estimate), shared);
            let weighed = estimate.graph().unwrap();
            // Sorted: the loops' order in the graph is not the point here.
            let loop_information = |g: &echofield_graph::PoseGraph| -> Vec<f64> {
                let mut v: Vec<f64> = g
                    .edges()
                    .filter(|e| e.kind == EdgeKind::Loop)
                    .map(|e| e.information[(0, 0)])
                    .collect();
                v.sort_by(f64::total_cmp);
                v
            };
            let (before, after) = (loop_information(&as_matched), loop_information(&weighed));
            assert_eq!(before.len(), 3);
            // The pass's edges are as matched; the weighed ones lighter where shared.
            assert!(
                before.iter().zip(&after).all(|(b, a)| a <= b),
                "{before:?} {after:?}"
            );
            assert_eq!(
                before.iter().zip(&after).filter(|(b, a)| a < b).count(),
                if shared { 2 } else { 0 }
            );
            let matched = line_loop(0, 3, 25).covariance;
            closer
                .accepted_edges()
                .into_iter()
                .map(|(id, _, cov)| (id, cov[(0, 0)] / matched[(0, 0)]))
                .collect::<Vec<_>>()
        };
        let ratio = |v: &[(usize, f64)], id: usize| v.iter().find(|(i, _)| *i == id).unwrap().1;
        assert_eq!(
            DENSIFY_CORRELATION, 1.0,
            "the expected factors below assume ρ = 1"
        );
        let shared = covariance_of(true);
        assert!((ratio(&shared, 7) - 3.0).abs() < 1e-12, "{shared:?}");
        assert!((ratio(&shared, 9) - 3.0).abs() < 1e-12, "{shared:?}");
        assert!((ratio(&shared, 12) - 1.0).abs() < 1e-12, "{shared:?}");
        let independent = covariance_of(false);
        assert!(
            independent.iter().all(|(_, r)| (r - 1.0).abs() < 1e-12),
            "{independent:?}"
        );
    }

    #[test]
    fn held_loops_stay_out_of_the_estimate_and_the_cover_until_settled() {
        let config = spaced_config();
        let matcher = MatcherConfig::default();
        let mut closer = closer_on_a_line(&config, &matcher);
        let mut estimate = line_estimate();
        let chain = closer.chain.clone();
        for (id, from, to) in [(7, 3, 25), (9, 5, 30)] {
            let m = line_loop(id, from, to);
            closer.consistency.add(m, &chain, CONSISTENCY_MAX_CHI2);
        }
        closer.accepted.ids = vec![7, 9];
        closer.held = vec![9];
        assert!(closer.apply_clique_change(&[], &mut estimate));
        let s = closer.chain.distances().to_vec();
        assert_eq!(estimate.loop_ids().collect::<Vec<_>>(), vec![7]);
        assert!(closer.cover.covers(4, 26, &s));
        assert!(!closer.cover.covers(6, 31, &s));
        assert!(closer.settle(&mut estimate));
        let mut ids: Vec<usize> = estimate.loop_ids().collect();
        ids.sort_unstable();
        assert_eq!(ids, vec![7, 9]);
        assert!(closer.cover.covers(6, 31, &s));
        assert!(!closer.settle(&mut estimate), "nothing left to settle");
    }
}
