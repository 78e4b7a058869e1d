//! The localised mission's motion between consecutive rotations: the dead
//! reckoning's, fused with the sonar's own sequential match `S_k` vs
//! `I_{k-1}` (the submap of scan-only data), as the SLAM graph constrains a
//! pair of nodes by its odometry and its sequential edge
//! ([`crate::slam::sequential`], the same matching, gates and
//! covariances). The two are independent measurements of one relative
//! pose, so the motion is their information-weighted mean with covariance
//! `(Ω_dr + Ω_seq)⁻¹`. Where the match is not accepted (no echoes, a
//! rotation in a DVL gap, a match that disagrees with the dead reckoning
//! or with its reverse), or sequential matching is off, the motion is the
//! dead reckoning's alone.
//!
//! Why: a third of the real St Pere route of `localize` lies far from the
//! map, where the filter carries on from its motion alone; there the
//! sonar's own chain drifts far less than the DVL's.

use crate::slam::SlamConfig;
use crate::slam::sequential::{ODOMETRY_MIN_SIGMA, edge_covariance, match_next, submap_history};
use anyhow::{Context, Result};
use echofield_frontend::dead_reckoning::Navigation;
use echofield_frontend::loops::SequentialRecord;
use echofield_frontend::matcher::symmetric::weighted_mean_pose;
use echofield_frontend::nodes::NodeData;
use echofield_frontend::uncertainty::with_floor;
use echofield_graph::Se2;
use nalgebra::Matrix3;

/// A relative motion `previous_from_current` and its covariance (m, rad).
pub type Motion = (Se2, Matrix3<f64>);

/// The nodes the next sequential match reads, and the matches between them.
pub struct SonarOdometry<'c> {
    config: &'c SlamConfig,
    /// The last nodes, oldest first: at most the submap's depth plus one.
    nodes: Vec<NodeData>,
    /// `sequential[i]`: `nodes[i + 1]` against `nodes[i]`.
    sequential: Vec<SequentialRecord>,
}

impl<'c> SonarOdometry<'c> {
    /// `config`: the map run's, as the localised mission's nodes are built
    /// with it (`sequential`, `matcher`).
    pub fn new(config: &'c SlamConfig) -> Self {
        Self {
            config,
            nodes: Vec::new(),
            sequential: Vec::new(),
        }
    }

    /// The motion `previous_from_node` from the last node pushed to `node`
    /// and its covariance (m, rad), given the dead reckoning's
    /// (`dead_reckoning`, `None` at the first rotation, then `None` is
    /// returned); the bool says whether the sonar's match went into it.
    /// `navigation` must cover both nodes' stamps. Errors: a match that
    /// fails (an image that cannot be built).
    pub fn motion(
        &mut self,
        node: &NodeData,
        navigation: &Navigation,
        dead_reckoning: Option<Motion>,
    ) -> Result<(Option<Motion>, bool)> {
        let (Some((dr, dr_cov)), Some(prev)) = (dead_reckoning, self.nodes.last()) else {
            return Ok((dead_reckoning, false));
        };
        let k = self.nodes.len();
        let seq = &self.config.sequential;
        let history = submap_history(
            &self.nodes,
            &self.sequential,
            k,
            seq.submap_rotations,
            navigation,
        )
        .context("the sonar's sequential match")?;
        let record = match_next(
            prev,
            &history,
            node,
            k,
            navigation,
            (seq, &self.config.matcher),
        )
        .with_context(|| {
            format!(
                "the sonar's sequential match of rotation {}",
                node.rotation_index
            )
        })?;
        let Some(record) = record else {
            return Ok((Some((dr, dr_cov)), false));
        };
        let sonar = if record.accepted {
            record.measurement.zip(edge_covariance(&record, seq))
        } else {
            None
        };
        let dr_floored = with_floor(&dr_cov, &ODOMETRY_MIN_SIGMA);
        let fused = sonar.and_then(|(z, z_cov)| fuse(&dr, &dr_floored, &z, &z_cov));
        self.sequential.push(record);
        Ok(match fused {
            Some(motion) => (Some(motion), true),
            None => (Some((dr, dr_cov)), false),
        })
    }

    /// Makes `node` the last node (after [`Self::motion`] of it), dropping
    /// those no later match reads.
    pub fn push(&mut self, node: NodeData) {
        if !self.config.sequential.enabled {
            return;
        }
        self.nodes.push(node);
        let dropped = self
            .nodes
            .len()
            .saturating_sub(self.config.sequential.submap_rotations + 1);
        self.nodes.drain(..dropped);
        // `sequential[i]` pairs `nodes[i + 1]` with `nodes[i]`.
        let stale = self.sequential.len().saturating_sub(self.nodes.len() - 1);
        self.sequential.drain(..stale);
    }
}

/// The information-weighted mean of two estimates of one relative pose and
/// its covariance `(Ω_a + Ω_b)⁻¹`; `None` when a covariance is singular.
fn fuse(a: &Se2, cov_a: &Matrix3<f64>, b: &Se2, cov_b: &Matrix3<f64>) -> Option<Motion> {
    let total = (cov_a.try_inverse()? + cov_b.try_inverse()?).try_inverse()?;
    let total = 0.5 * (total + total.transpose());
    Some((weighted_mean_pose(a, cov_a, b, cov_b), total))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn the_fused_motion_leans_on_the_tighter_estimate_and_is_tighter_than_both() {
        let dr = Se2::new(1.0, 0.0, 0.0);
        let sonar = Se2::new(1.2, 0.1, 0.01);
        let dr_cov = Matrix3::from_diagonal(&Vector3::new(0.09, 0.09, 1e-4));
        let sonar_cov = Matrix3::from_diagonal(&Vector3::new(0.01, 0.01, 1e-4));
        let (m, cov) = fuse(&dr, &dr_cov, &sonar, &sonar_cov).unwrap();
        // Per axis (diagonal covariances): (x_a / σ_a² + x_b / σ_b²) / (1 / σ_a² + 1 / σ_b²).
        assert!((m.x() - (1.0 / 0.09 + 1.2 / 0.01) / (1.0 / 0.09 + 1.0 / 0.01)).abs() < 1e-9);
        assert!((m.y() - (0.1 / 0.01) / (1.0 / 0.09 + 1.0 / 0.01)).abs() < 1e-9);
        assert!((m.theta() - 0.005).abs() < 1e-9);
        assert!((cov[(0, 0)] - 1.0 / (1.0 / 0.09 + 1.0 / 0.01)).abs() < 1e-12);
        assert!((cov[(2, 2)] - 0.5e-4).abs() < 1e-12);
        assert!(fuse(&dr, &Matrix3::zeros(), &sonar, &sonar_cov).is_none());
    }
}
