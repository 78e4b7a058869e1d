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
    /// design effect (`loops::config::DENSIFY_CORRELATION`). Without
    /// metadata: [`Self::attach_metadata`] gives it to the final ones.
    pub(super) fn accepted_edges(&self) -> Vec<(usize, echofield_graph::Edge, Matrix3<f64>)> {
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
                let edge = make_edge(EdgeKind::Loop, m.from, m.to, m.z, &covariance, None).ok()?;
                Some((id, edge, covariance))
            })
            .collect()
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
    use super::super::fixtures::{closer_on_a_line, measurement};
    use echofield_frontend::loops::LoopConfig;
    use echofield_frontend::loops::config::CONSISTENCY_MAX_CHI2;
    use echofield_frontend::loops::consistency::Clique;
    use echofield_frontend::matcher::MatcherConfig;

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
}
