//! Step 2 of a match: the estimate refined away from the rim of the
//! image's reach.
//!
//! A scan point that a pose carries past the rim of the image's reach
//! ([`crate::image::reach`]) scores 0 there, so eq. (5) rewards poses that
//! keep points inside the rim: along a wall that runs out of the image the
//! score prefers a displacement that is too short. The coarse search keeps
//! every point (the far walls help it find the right basin); from its
//! lattice pose, the estimate is then refined with only the points that
//! stay at least [`Refinement::margin_m`] inside the rim, so far that no
//! pose the refinement can reach moves any of them across it, and no pose
//! gains by it. The refinement is a climb on the same lattice to the
//! nearest maximum of that score, at most [`CLIMB_STEPS`] steps along each
//! axis, followed by the usual quadratic fits ([`super::covariance`], the
//! pose fit), which move it by at most [`FIT_STEPS`] steps more.
//!
//! When every point already stays inside, or too few would, nothing is
//! refined: the match is that of eq. (6) on all points.

use super::search::{Discretisation, Leaf, SearchProblem, SearchStats};
use crate::image::{AcousticImage, Reach};
use echofield_graph::Se2;
use nalgebra::{Point2, Vector3};

/// Largest move of the climb from the coarse lattice pose, in lattice steps
/// along each axis (cells in x and y, angle steps in θ).
pub const CLIMB_STEPS: i32 = 5;

/// Largest move of the fits after the climb, in lattice steps along each
/// axis: the covariance fit's lattice (2 steps) and its Newton step (1),
/// and the pose fit's half step, rounded up.
pub const FIT_STEPS: i32 = 4;

/// How far a pose may move during the refinement, and so how far inside
/// the rim a point must lie at the coarse pose to take part.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refinement {
    /// Largest translation, metres (both axes at their largest move).
    pub translation_m: f64,
    /// Largest rotation, radians.
    pub rotation_rad: f64,
}

impl Refinement {
    /// The refinement's reach for lattice `steps` (x cell, y cell, angle
    /// step) and a climb bounded by `climb` steps per axis.
    pub fn new(steps: &Vector3<f64>, climb: [i32; 3]) -> Self {
        let moves = |axis: usize| f64::from(climb[axis] + FIT_STEPS) * steps[axis];
        Self {
            translation_m: moves(0).hypot(moves(1)),
            rotation_rad: moves(2),
        }
    }

    /// The margin point `p` (scan frame) needs: the refinement moves
    /// `x ⊕ p` by at most the translation plus the rotation times `|p|`.
    pub fn margin_m(&self, p: &Point2<f64>) -> f64 {
        self.translation_m + self.rotation_rad * p.coords.norm()
    }
}

/// The refined lattice pose and the points it was refined with.
pub struct Refined {
    pub pose: Se2,
    pub points: Vec<Point2<f64>>,
}

/// Refines `coarse`, the search's best lattice `leaf` of `disc` around the
/// prior, with the points of `points` that stay inside `reach`'s rim (see
/// the module doc). `None` when nothing needs refining: every point stays
/// inside, or fewer than `min_points` would, or the climb finds no pose
/// with a score.
pub fn refine_inside_reach(
    points: &[Point2<f64>],
    image: &AcousticImage,
    reach: &Reach,
    coarse: &Se2,
    leaf: &Leaf,
    disc: &Discretisation,
    min_points: usize,
) -> Option<Refined> {
    let cell_m = image.cell_size_m();
    let env = |k: &str, d: i32| std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d);
    if env("RIM_OFF", 0) == 1 || disc.cells_x.max(disc.cells_y) > env("RIM_MAXWIN", 1000) {
        return None;
    }
    let climb_steps = env("RIM_CLIMB", CLIMB_STEPS);
    let climb_angle = env("RIM_CLIMB_ANGLE", CLIMB_STEPS);
    // The climb stays in the search window: at most the room the coarse
    // leaf leaves on each side.
    let room = |c: i32, steps: i32, at: i32| c.min(steps - at.abs()).max(0);
    let climb = [
        room(climb_steps, disc.cells_x, leaf.dx),
        room(climb_steps, disc.cells_y, leaf.dy),
        room(climb_angle, disc.angle_steps, leaf.angle),
    ];
    let steps = Vector3::new(cell_m, cell_m, disc.angle_step_rad);
    let refinement = Refinement::new(&steps, climb);
    let inside: Vec<Point2<f64>> = points
        .iter()
        .filter(|p| reach.margin(&coarse.transform_point(p)) >= refinement.margin_m(p))
        .copied()
        .collect();
    if inside.len() == points.len() || inside.len() < min_points {
        return None;
    }
    let local = Discretisation {
        angle_step_rad: disc.angle_step_rad,
        angle_steps: climb[2],
        cells_x: climb[0],
        cells_y: climb[1],
    };
    let problem = SearchProblem::new(&inside, image, coarse, &local);
    let best = problem.local_max(&mut SearchStats::default())?;
    Some(Refined {
        pose: best.pose(coarse, &local, cell_m),
        points: inside,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::Grid;
    use crate::sensors::SonarBeam;

    #[test]
    fn a_point_needs_the_translation_plus_the_rotation_times_its_range() {
        let r = Refinement::new(&Vector3::new(0.2, 0.2, 0.01), [5, 5, 5]);
        let t = (9.0_f64 * 0.2).hypot(9.0 * 0.2);
        assert!((r.translation_m - t).abs() < 1e-12);
        assert!((r.rotation_rad - 0.09).abs() < 1e-12);
        assert!((r.margin_m(&Point2::new(30.0, 40.0)) - (t + 4.5)).abs() < 1e-12);
    }

    /// A quay along y = 10 m out past the rim of an image
    /// whose beams reach 30 m from the origin, and a short pier across
    /// it at x = 5 m (y from 8 to 10 m) that fixes the position along the
    /// quay: walls as Gaussian ridges of 0.5 m.
    fn quay_image() -> (AcousticImage, Reach) {
        let (cell, reach_m) = (0.2, 30.0);
        let n = 400;
        let mut grid = Grid::zeros(-40.0, -40.0, cell, n, n);
        for iy in 0..n as i64 {
            for ix in 0..n as i64 {
                let (x, y) = grid.cell_centre_m(ix, iy);
                if x.hypot(y) > reach_m {
                    continue;
                }
                let ridge = |d: f64| (-0.5 * (d / 0.5).powi(2)).exp();
                let quay = ridge(y - 10.0);
                let pier = if (7.5..10.5).contains(&y) { ridge(x - 5.0) } else { 0.0 };
                grid.values_mut()[iy as usize * n + ix as usize] = quay.max(pier) as f32;
            }
        }
        let (beams, frames): (Vec<SonarBeam>, Vec<Se2>) = (0..720)
            .map(|j| {
                let a = std::f64::consts::TAU * f64::from(j) / 720.0;
                let beam = SonarBeam {
                    stamp_s: 0.0,
                    angle_rad: a,
                    bin_size_m: 0.1,
                    first_bin_range_m: 0.0,
                    intensities: vec![0; (reach_m / 0.1).round() as usize],
                };
                (beam, Se2::new(0.0, 0.0, a))
            })
            .unzip();
        let reach = Reach::of_beams(&beams, &frames, None, 0.1).unwrap();
        (AcousticImage::from_grid(grid, 6), reach)
    }

    /// The scan of the same quay and pier from the image's own pose (the
    /// truth is the identity), the quay seen from x = 0 out to 39 m.
    fn quay_scan() -> Vec<Point2<f64>> {
        let quay = (0..195).map(|k| Point2::new(f64::from(k) * 0.2, 10.0));
        let pier = (0..10).map(|k| Point2::new(5.0, 8.0 + f64::from(k) * 0.2));
        quay.chain(pier).collect()
    }

    fn window() -> Discretisation {
        Discretisation {
            angle_step_rad: 0.2 / 20.0,
            angle_steps: 8,
            cells_x: 10,
            cells_y: 10,
        }
    }

    #[test]
    fn the_rim_pulls_the_whole_scan_short_and_not_the_points_inside_it() {
        let (image, reach) = quay_image();
        let points = quay_scan();
        let disc = window();
        // All points, climbing from the truth: the pull of the rim moves
        // the scan back along the quay.
        let problem = SearchProblem::new(&points, &image, &Se2::identity(), &disc);
        let all = problem.local_max(&mut SearchStats::default()).unwrap();
        let all = all.pose(&Se2::identity(), &disc, 0.2);
        assert!(all.x() < -0.1, "{all:?}");
        // Refined from where that climb ended: back to the truth.
        let leaf = Leaf {
            angle: ((all.theta()) / disc.angle_step_rad).round() as i32,
            dx: (all.x() / 0.2).round() as i32,
            dy: (all.y() / 0.2).round() as i32,
            score: 0.0,
        };
        let refined =
            refine_inside_reach(&points, &image, &reach, &all, &leaf, &disc, 10).unwrap();
        assert!(refined.points.len() < points.len());
        let p = refined.pose;
        assert!(
            p.x().abs() < 0.11 && p.y().abs() < 0.11 && p.theta().abs() < 0.006,
            "{p:?} (all points: {all:?})"
        );
    }

    #[test]
    fn nothing_is_refined_when_every_point_stays_inside() {
        let (image, reach) = quay_image();
        let points: Vec<Point2<f64>> = quay_scan().into_iter().filter(|p| p.x < 10.0).collect();
        let leaf = Leaf {
            angle: 0,
            dx: 0,
            dy: 0,
            score: 0.0,
        };
        let got = refine_inside_reach(
            &points,
            &image,
            &reach,
            &Se2::identity(),
            &leaf,
            &window(),
            10,
        );
        assert!(got.is_none());
    }
}
