//! The objective of the calibration: the mean map entropy of windows of
//! consecutive rotations, as a function of the head's mounting.
//!
//! Every return `i` (beam time `t_i`, head angle `θ_i`, range `r_i`) is
//! placed with the dead-reckoned vehicle pose `W(t_i)` and a candidate
//! head `(s, ψ, x, y)`, `s = +1` for a counter-clockwise angle and `−1` for
//! a clockwise one:
//!
//! ```text
//! p_i = W(t_i) ⊕ ( [x, y] + r_i · [cos(ψ + s·θ_i), sin(ψ + s·θ_i)] )   (eq. 3)
//! ```
//!
//! Window `w` holds the returns of rotations `w·d .. w·d + L` (`L` =
//! `window_rotations`, `d = ⌈L/2⌉`: consecutive windows overlap by half,
//! so every rotation lies in two windows and every two rotations less than
//! half a window apart share one, at half the cost of a window starting
//! at every rotation), and its entropy `H_w` is that of
//! [`crate::sharpness`] on cells of `cell_size_m`. The objective over a set
//! `S` of windows is `J_S = (1/|S|) Σ_{w∈S} H_w` (bits; lower is sharper).
//! The vehicle poses do not depend on the head, so they are looked up once.
//!
//! The cells lie on lattices fixed in the world, so that the objective
//! changes only as returns move, not as the lattice follows them. The
//! entropy of a splat still depends on where the returns of a wall sit
//! within their cells (a bilinear splat puts a line of returns through
//! cell centres in one row of cells and a line along cell edges in two),
//! which pulls the minimum towards placements that line walls up with the
//! lattice, and makes `J` ripple with a period of a cell as the head turns.
//! Two measures keep both small: the returns are splatted with the
//! quadratic B-spline ([`Kernel::QuadraticBSpline`]), whose split of a line
//! between rows hardly depends on where it lies, and `H_w` is the mean over
//! two lattices offset by half a cell along both axes, whose ripples are
//! in opposite phase.

use crate::dead_reckoning::Navigation;
use crate::rotation::Rotation;
use crate::sensors::AngleDirection;
use crate::sharpness::{BeamReturn, Kernel, SplatGrid};
use nalgebra::Vector2;
use serde::Serialize;
use std::cell::{Cell, RefCell};
use std::ops::Range;

/// Rotations from the start of one window to the next: half a window
/// (module doc).
pub fn window_stride(window_rotations: usize) -> usize {
    window_rotations.div_ceil(2).max(1)
}

/// Lattices each window is splatted on (module doc).
const LATTICES: usize = 2;

/// The splat kernel (module doc).
const KERNEL: Kernel = Kernel::QuadraticBSpline;

/// A candidate sonar head on the vehicle: the unknowns of the calibration.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct HeadCandidate {
    /// Which way the head's angle counts.
    pub sonar_angle: AngleDirection,
    /// Direction of the head's angle zero, radians counter-clockwise from
    /// the vehicle's x axis.
    pub yaw_rad: f64,
    /// The head's position forward of the vehicle origin, metres.
    pub x_m: f64,
    /// The head's position to port, metres.
    pub y_m: f64,
}

impl HeadCandidate {
    fn sign(&self) -> f64 {
        match self.sonar_angle {
            AngleDirection::CounterClockwise => 1.0,
            AngleDirection::Clockwise => -1.0,
        }
    }
}

/// One return ready to place: the vehicle pose at its beam's time and the
/// beam's range and head angle, with their cosines and sines.
#[derive(Clone, Copy, Debug)]
struct Placeable {
    vehicle_x_m: f64,
    vehicle_y_m: f64,
    cos_heading: f64,
    sin_heading: f64,
    range_m: f64,
    cos_angle: f64,
    sin_angle: f64,
}

/// Buffers reused between evaluations.
#[derive(Debug, Default)]
struct Scratch {
    points: Vec<Vector2<f64>>,
    grid: SplatGrid,
}

/// The returns of one sweep assumption, cut into windows (module doc).
#[derive(Debug)]
pub struct Objective {
    returns: Vec<Placeable>,
    /// Each window's returns, as a range of `returns`.
    windows: Vec<Range<usize>>,
    cell_size_m: f64,
    scratch: RefCell<Scratch>,
    evaluations: Cell<u64>,
}

impl Objective {
    /// Places nothing yet: looks up the vehicle pose of every return
    /// (`returns` in time order; those outside the navigation are left
    /// out) and cuts the windows of `window_rotations` consecutive
    /// `rotations`, one starting every [`window_stride`] rotations while
    /// enough follow.
    pub fn new(
        returns: &[BeamReturn],
        navigation: &Navigation,
        rotations: &[Rotation],
        window_rotations: usize,
        cell_size_m: f64,
    ) -> Self {
        let mut stamps = Vec::with_capacity(returns.len());
        let mut placeable = Vec::with_capacity(returns.len());
        for r in returns {
            let Ok(pose) = navigation.pose_at(r.stamp_s) else {
                continue;
            };
            let (sin_heading, cos_heading) = pose.theta().sin_cos();
            let (sin_angle, cos_angle) = r.angle_rad.sin_cos();
            stamps.push(r.stamp_s);
            placeable.push(Placeable {
                vehicle_x_m: pose.x(),
                vehicle_y_m: pose.y(),
                cos_heading,
                sin_heading,
                range_m: r.range_m,
                cos_angle,
                sin_angle,
            });
        }
        let windows = rotations
            .windows(window_rotations.max(1))
            .step_by(window_stride(window_rotations))
            .map(|w| {
                let (start_s, end_s) = (w[0].start_s, w[w.len() - 1].end_s);
                stamps.partition_point(|&t| t < start_s)..stamps.partition_point(|&t| t <= end_s)
            })
            .collect();
        Self {
            returns: placeable,
            windows,
            cell_size_m,
            scratch: RefCell::default(),
            evaluations: Cell::new(0),
        }
    }

    /// Number of windows.
    pub fn windows(&self) -> usize {
        self.windows.len()
    }

    /// Number of returns placed (those the navigation covers).
    pub fn returns(&self) -> usize {
        self.returns.len()
    }

    /// Calls of [`Objective::mean_entropy`] so far.
    pub fn evaluations(&self) -> u64 {
        self.evaluations.get()
    }

    /// `J_S` of the module doc over the windows `selection` (indices);
    /// `+∞` for an empty selection or a placement the grid refuses (one
    /// spread over kilometres).
    pub fn mean_entropy(&self, head: &HeadCandidate, selection: &[usize]) -> f64 {
        self.evaluations.set(self.evaluations.get() + 1);
        if selection.is_empty() {
            return f64::INFINITY;
        }
        let mut scratch = self.scratch.borrow_mut();
        let Scratch { points, grid } = &mut *scratch;
        self.place(head, points);
        let mut sum = 0.0;
        for &w in selection {
            let Some(range) = self.windows.get(w) else {
                return f64::INFINITY;
            };
            let window = &points[range.clone()];
            for offset in self.lattice_offsets() {
                let filled = grid.fill_on_lattice(window, self.cell_size_m, offset, KERNEL);
                if filled.is_err() {
                    return f64::INFINITY;
                }
                sum += grid.sharpness(window.len(), self.cell_size_m).entropy_bits;
            }
        }
        sum / (LATTICES * selection.len()) as f64
    }

    /// The offsets of the [`LATTICES`] lattices (module doc).
    fn lattice_offsets(&self) -> [Vector2<f64>; LATTICES] {
        [Vector2::zeros(), Vector2::repeat(0.5 * self.cell_size_m)]
    }

    /// Every return placed with `head` (eq. 3 of the module doc).
    fn place(&self, head: &HeadCandidate, out: &mut Vec<Vector2<f64>>) {
        let (sin_yaw, cos_yaw) = head.yaw_rad.sin_cos();
        let s = head.sign();
        out.clear();
        out.extend(self.returns.iter().map(|p| {
            // cos and sin of ψ + s·θ.
            let c = cos_yaw * p.cos_angle - s * sin_yaw * p.sin_angle;
            let d = sin_yaw * p.cos_angle + s * cos_yaw * p.sin_angle;
            let vx = head.x_m + p.range_m * c;
            let vy = head.y_m + p.range_m * d;
            Vector2::new(
                p.vehicle_x_m + p.cos_heading * vx - p.sin_heading * vy,
                p.vehicle_y_m + p.sin_heading * vx + p.cos_heading * vy,
            )
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation::RotationKind;
    use crate::sensors::SensorMounting;
    use crate::sharpness::place_with;
    use echofield_graph::Se2;

    fn rotation(index: usize, start_s: f64) -> Rotation {
        Rotation {
            index,
            beams: 0..1,
            start_s,
            end_s: start_s + 0.95,
            reference_stamp_s: start_s + 0.475,
            coverage_rad: std::f64::consts::TAU,
            kind: RotationKind::Full,
        }
    }

    #[test]
    fn placement_matches_the_mountings_own_beam_frames() {
        let returns: Vec<BeamReturn> = (0..40)
            .map(|i| BeamReturn {
                beam: i,
                stamp_s: i as f64 * 0.1,
                angle_rad: i as f64 * 0.37 - 3.0,
                range_m: 2.0 + i as f64 * 0.2,
            })
            .collect();
        let nav = Navigation::stationary(0.0, 10.0);
        let objective = Objective::new(&returns, &nav, &[rotation(0, 0.0)], 1, 0.5);
        for sonar_angle in [AngleDirection::CounterClockwise, AngleDirection::Clockwise] {
            let head = HeadCandidate {
                sonar_angle,
                yaw_rad: 2.1,
                x_m: 0.4,
                y_m: -0.3,
            };
            let mounting = SensorMounting {
                vehicle_from_sonar: Se2::new(0.4, -0.3, 2.1),
                sonar_angle,
                ..SensorMounting::default()
            };
            let mut mine = Vec::new();
            objective.place(&head, &mut mine);
            let theirs = place_with(&returns, &mounting, |t| nav.pose_at(t).ok());
            assert_eq!(mine.len(), theirs.len());
            for (a, b) in mine.iter().zip(&theirs) {
                assert!((a - b).norm() < 1e-9, "{a} vs {b}");
            }
        }
    }

    #[test]
    fn windows_hold_consecutive_rotations() {
        let returns: Vec<BeamReturn> = (0..50)
            .map(|i| BeamReturn {
                beam: i,
                stamp_s: i as f64 * 0.1,
                angle_rad: 0.0,
                range_m: 1.0,
            })
            .collect();
        let nav = Navigation::stationary(0.0, 10.0);
        let rotations: Vec<Rotation> = (0..5).map(|k| rotation(k, k as f64)).collect();
        let objective = Objective::new(&returns, &nav, &rotations, 2, 0.5);
        // Windows start at rotations 0..=3: [0, 1.95] s, [1, 2.95] s, ...
        assert_eq!(objective.windows, vec![0..20, 10..30, 20..40, 30..50]);
        let head = HeadCandidate {
            sonar_angle: AngleDirection::CounterClockwise,
            yaw_rad: 0.0,
            x_m: 0.0,
            y_m: 0.0,
        };
        // Every return of a stationary vehicle lands on one point: a node of
        // one lattice, where the quadratic B-spline gives (1/8, 3/4, 1/8)
        // along each axis, and a corner of the other, (0, 1/2, 1/2).
        let node = -2.0 * (0.125f64.log2() * 0.25 + 0.75 * 0.75f64.log2());
        let h = objective.mean_entropy(&head, &[0, 1, 2, 3]);
        assert!((h - 0.5 * (node + 2.0)).abs() < 1e-6, "{h}");
        assert_eq!(objective.mean_entropy(&head, &[]), f64::INFINITY);
        assert_eq!(objective.mean_entropy(&head, &[9]), f64::INFINITY);
    }
}
