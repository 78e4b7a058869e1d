//! The scale of the dead reckoning against the optimised trajectory: a
//! check of the DVL's scale (`report.json`,
//! `dead_reckoning.odometry_scale`).
//!
//! A DVL that reads every velocity `(1 + ε)` times too large (a
//! calibration or beam-angle error, a wrong sound speed set in the
//! instrument) makes every odometry edge `(1 + ε)` times too long, while
//! the scan matches measure the motion with the sonar's ranges. After the
//! final solve, the least-squares scale `s` of `t_opt ≈ s · t_odo` over
//! the odometry edges (each translation in the frame of its first node:
//! the dead-reckoning motion `t_odo` and the optimised motion `t_opt`)
//! estimates `1 / (1 + ε)`.
//!
//! Against the same fit with the ground-truth motion in place of the optimised
//! one (`echofield_tests::ground_truth_odometry_scale`), the check finds the
//! sign and size of a DVL scale error to within about half a percent: the
//! optimised motion keeps a little of the dead reckoning's error (measured:
//! EXPERIMENTS.md § Odometry scale).
//!
//! It is not fed back into the dead reckoning. The scans are motion-compensated
//! with the dead reckoning, so the sonar's constraints carry part of its scale,
//! and a wide beam shortens them further (the last row of `echofield
//! error-budget`); a DVL corrected by the check's own estimate gave worse
//! trajectories (same section).
//!
//! The standard error is the spread of the edges about the fit, as if they
//! were independent; it says how well the fit is determined, not how far
//! the optimised trajectory is from the truth.

use echofield_graph::{EdgeKind, PoseGraph};
use serde::Serialize;

/// The dead reckoning must cover at least this distance (sum of the
/// odometry edges' lengths, metres) for a scale to be fitted.
pub const MIN_DISTANCE_M: f64 = 10.0;

/// A warning is given when the scale is further from 1 than this and than
/// three standard errors: a DVL's own scale accuracy is a few tenths of a
/// percent.
pub const WARN_DEVIATION: f64 = 0.01;

/// See the module doc.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct OdometryScale {
    /// Optimised motion over dead-reckoning motion (below 1: the dead
    /// reckoning overestimates distances).
    pub scale: f64,
    pub standard_error: f64,
    /// Odometry edges fitted.
    pub edges: usize,
    /// Their summed length, metres.
    pub distance_m: f64,
}

/// The fit over the odometry edges of `graph` at its current (optimised)
/// poses; `None` with fewer than two edges or under [`MIN_DISTANCE_M`].
pub fn odometry_scale(graph: &PoseGraph) -> Option<OdometryScale> {
    let poses = graph.poses();
    let (mut zz, mut rz, mut rr, mut edges, mut distance_m) = (0.0, 0.0, 0.0, 0_usize, 0.0);
    for (from, to, edge) in graph.indexed_edges() {
        if edge.kind != EdgeKind::Odometry {
            continue;
        }
        let (a, b) = (poses[from], poses[to]);
        let z = edge.measurement.translation();
        let r = a.between(&b).translation();
        zz += z.norm_squared();
        rz += r.dot(&z);
        rr += r.norm_squared();
        distance_m += z.norm();
        edges += 1;
    }
    // The graph holds finite measurements only, so zz > 0 from here on.
    if edges < 2 || distance_m < MIN_DISTANCE_M {
        return None;
    }
    let scale = rz / zz;
    // Σ|r - s z|² = Σ|r|² - 2 s Σ r·z + s² Σ|z|², two coordinates per edge
    // and one parameter.
    let residual = (rr - 2.0 * scale * rz + scale * scale * zz).max(0.0);
    let variance = residual / (2 * edges - 1) as f64;
    Some(OdometryScale {
        scale,
        standard_error: (variance / zz).sqrt(),
        edges,
        distance_m,
    })
}

/// The warning of a scale further from 1 than [`WARN_DEVIATION`] and three
/// standard errors.
pub fn warning(check: &OdometryScale) -> Option<String> {
    let deviation = check.scale - 1.0;
    if deviation.abs() <= WARN_DEVIATION.max(3.0 * check.standard_error) {
        return None;
    }
    let (percent, error) = (100.0 * deviation.abs(), 100.0 * check.standard_error);
    let (shorter, long) = if deviation < 0.0 {
        ("shorter", "long")
    } else {
        ("longer", "short")
    };
    Some(format!(
        "the optimised motion is {percent:.1} ± {error:.1} % {shorter} than the dead reckoning's over {} odometry edges ({:.0} m): the DVL may read {long} (a scale or sound-speed error; report.json dead_reckoning.odometry_scale)",
        check.edges, check.distance_m,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use echofield_graph::{Edge, Node, Se2};
    use nalgebra::Matrix3;

    /// A zig-zag path of `n` nodes and a graph whose odometry edges are
    /// its motions times `reading` (plus a loop edge that must be
    /// ignored).
    fn graph_reading(n: usize, reading: f64, wobble: f64) -> PoseGraph {
        let poses: Vec<Se2> = (0..n)
            .map(|i| {
                let t = i as f64;
                Se2::new(5.0 * t, 3.0 * (0.4 * t).sin(), 0.3 * (0.7 * t).cos())
            })
            .collect();
        let mut graph = PoseGraph::new();
        for (i, p) in poses.iter().enumerate() {
            graph.add_node(node(i, *p)).unwrap();
        }
        for i in 1..n {
            let truth = poses[i - 1].between(&poses[i]);
            // A deterministic error that averages out over the edges.
            let e = wobble * if i % 2 == 0 { 1.0 } else { -1.0 };
            let measured = Se2::new(
                reading * truth.x() + e,
                reading * truth.y() - e,
                truth.theta(),
            );
            graph
                .add_edge(Edge::new(
                    EdgeKind::Odometry,
                    (i - 1) as u64,
                    i as u64,
                    measured,
                    Matrix3::identity(),
                ))
                .unwrap();
        }
        graph
            .add_edge(Edge::new(
                EdgeKind::Loop,
                0,
                (n - 1) as u64,
                Se2::new(1.0, 2.0, 0.0),
                Matrix3::identity(),
            ))
            .unwrap();
        graph
    }

    fn node(id: usize, pose: Se2) -> Node {
        Node {
            id: id as u64,
            pose,
            stamp_s: None,
        }
    }

    #[test]
    fn a_dvl_reading_long_gives_the_inverse_scale() {
        let check = odometry_scale(&graph_reading(40, 1.03, 0.0)).unwrap();
        assert!((check.scale - 1.0 / 1.03).abs() < 1e-12, "{check:?}");
        assert!(check.standard_error < 1e-9);
        assert_eq!(check.edges, 39);
        let warning = warning(&check).unwrap();
        assert!(warning.contains("2.9 ± 0.0 % shorter"), "{warning}");
        assert!(warning.contains("read long"), "{warning}");
    }

    #[test]
    fn noise_widens_the_standard_error_and_small_deviations_do_not_warn() {
        let check = odometry_scale(&graph_reading(40, 0.995, 0.05)).unwrap();
        assert!((check.scale - 1.0 / 0.995).abs() < 2e-3, "{check:?}");
        assert!(check.standard_error > 1e-4 && check.standard_error < 1e-2);
        assert_eq!(warning(&check), None);

        let warning = warning(&odometry_scale(&graph_reading(40, 0.97, 0.05)).unwrap()).unwrap();
        assert!(warning.contains("longer"), "{warning}");
        assert!(warning.contains("read short"), "{warning}");
    }

    #[test]
    fn no_scale_without_motion() {
        assert_eq!(
            odometry_scale(&graph_reading(2, 1.0, 0.0)),
            None,
            "one edge"
        );
        let mut still = PoseGraph::new();
        for i in 0..5 {
            still.add_node(node(i, Se2::identity())).unwrap();
        }
        for i in 1..5 {
            still
                .add_edge(Edge::new(
                    EdgeKind::Odometry,
                    i - 1,
                    i,
                    Se2::new(0.01, 0.0, 0.0),
                    Matrix3::identity(),
                ))
                .unwrap();
        }
        assert_eq!(odometry_scale(&still), None, "0.04 m of motion");
    }
}
