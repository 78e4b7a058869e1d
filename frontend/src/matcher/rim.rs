//! Step 2 of a match: the estimate refined away from the rim of the
//! image's reach.
//!
//! A scan point that a pose carries past the rim of the image's reach
//! ([`crate::image::reach`]) scores 0 there, so eq. (5) rewards poses that
//! keep points inside the rim: along a wall that runs out of the image the
//! score prefers a displacement that is too short. The coarse search keeps
//! the sum of eq. (5) over every point (the far walls help it find the
//! right basin); from its lattice pose, the estimate is then refined by a
//! climb on the same lattice, at most [`CLIMB_STEPS`] steps along each
//! axis, on a score that neither rewards a point for entering the reach
//! nor punishes it for leaving: the mean of `I` over the points that the
//! pose puts inside the rim ([`mean_inside`]). The usual quadratic fits
//! ([`super::covariance`], the pose fit), which move the estimate by at
//! most [`FIT_STEPS`] steps more, then use only the points that stay at
//! least [`Refinement::margin_m`] inside the rim at the climb's end, so
//! that no pose the fits read carries any of them across it.
//!
//! When every point stays that far inside for the whole refinement, or too
//! few would, nothing is refined: the match is that of eq. (6) on all
//! points. Images without a known reach (made from a grid) are not
//! refined either. Deterministic: a fixed neighbour order, ties keep the
//! current pose.

use super::search::{Discretisation, Leaf};
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

/// How far a pose may move during a refinement, and so how far inside the
/// rim a point must lie to stay inside for every pose of it.
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
/// prior (see the module doc): a climb on the mean over the points inside
/// `reach`'s rim, within the search window, then the points for the fits.
/// `None` when nothing needs refining: every point stays inside for every
/// pose of the refinement, or fewer than `min_points` do (at the coarse
/// pose for the whole refinement, or at the climb's end for the fits), or
/// no pose of the climb puts a point inside.
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
    // The climb stays in the search window: at most the room the coarse
    // leaf leaves on each side.
    let room = |steps: i32, at: i32| CLIMB_STEPS.min(steps - at.abs()).max(0);
    let climb = [
        room(disc.cells_x, leaf.dx),
        room(disc.cells_y, leaf.dy),
        room(disc.angle_steps, leaf.angle),
    ];
    let steps = Vector3::new(cell_m, cell_m, disc.angle_step_rad);
    let refinement = Refinement::new(&steps, climb);
    let inside = points
        .iter()
        .filter(|p| reach.covers(&coarse.transform_point(p), refinement.margin_m(p)))
        .count();
    if inside == points.len() || inside < min_points {
        return None;
    }
    let local = Discretisation {
        angle_step_rad: disc.angle_step_rad,
        angle_steps: climb[2],
        cells_x: climb[0],
        cells_y: climb[1],
    };
    normalised_climb(points, image, reach, coarse, &local, &steps, min_points)
}

/// The mean of `I` over the points of `points` that `pose` puts inside
/// `reach`'s rim (margin ≥ 0), and how many those are; (0, 0) when none.
/// A point outside the rim takes no part, neither in the sum nor in the
/// count: it is not rewarded for entering the reach, nor punished.
fn mean_inside(
    points: &[Point2<f64>],
    image: &AcousticImage,
    reach: &Reach,
    pose: &Se2,
) -> (f64, usize) {
    let (mut sum, mut n) = (0.0, 0usize);
    for p in points {
        let q = pose.transform_point(p);
        if reach.covers(&q, 0.0) {
            sum += image.value_at(q.x, q.y);
            n += 1;
        }
    }
    if n == 0 {
        (0.0, 0)
    } else {
        (sum / n as f64, n)
    }
}

/// The climb of [`refine_inside_reach`] on the mean over the points inside
/// the rim at each pose ([`mean_inside`]): every point takes part wherever
/// it lies inside, and none changes the score by crossing the rim. Moves to the best
/// of the up to 26 lattice neighbours within `local` while the mean rises
/// strictly (so it ends), from `coarse` (leaf (0, 0, 0)). The fits that
/// follow use the points that stay inside the rim for every move the fits
/// can make from the climb's end ([`FIT_STEPS`]); `None` when fewer than
/// `min_points` do, or no pose has a point inside.
fn normalised_climb(
    points: &[Point2<f64>],
    image: &AcousticImage,
    reach: &Reach,
    coarse: &Se2,
    local: &Discretisation,
    steps: &Vector3<f64>,
    min_points: usize,
) -> Option<Refined> {
    let cell_m = image.cell_size_m();
    let mut memo = std::collections::HashMap::new();
    let mut score = |a: i32, x: i32, y: i32| -> f64 {
        *memo.entry((a, x, y)).or_insert_with(|| {
            let leaf = Leaf {
                angle: a,
                dx: x,
                dy: y,
                score: 0.0,
            };
            let pose = leaf.pose(coarse, local, cell_m);
            mean_inside(points, image, reach, &pose).0
        })
    };
    let mut at: (i32, i32, i32) = (0, 0, 0);
    let mut best_score = score(0, 0, 0);
    loop {
        let mut next = at;
        for da in -1..=1 {
            for ex in -1..=1 {
                for ey in -1..=1 {
                    let (a, x, y) = (at.0 + da, at.1 + ex, at.2 + ey);
                    if a.abs() > local.angle_steps
                        || x.abs() > local.cells_x
                        || y.abs() > local.cells_y
                    {
                        continue;
                    }
                    let s = score(a, x, y);
                    if s > best_score {
                        best_score = s;
                        next = (a, x, y);
                    }
                }
            }
        }
        if next == at {
            break;
        }
        at = next;
    }
    if best_score <= 0.0 {
        return None;
    }
    let leaf = Leaf {
        angle: at.0,
        dx: at.1,
        dy: at.2,
        score: best_score as f32,
    };
    let pose = leaf.pose(coarse, local, cell_m);
    let fits = Refinement::new(steps, [0, 0, 0]);
    let inside: Vec<Point2<f64>> = points
        .iter()
        .filter(|p| reach.covers(&pose.transform_point(p), fits.margin_m(p)))
        .copied()
        .collect();
    (inside.len() >= min_points).then_some(Refined {
        pose,
        points: inside,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::Grid;
    use crate::matcher::search::{SearchProblem, SearchStats};

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
                let pier = if (7.5..10.5).contains(&y) {
                    ridge(x - 5.0)
                } else {
                    0.0
                };
                grid.values_mut()[iy as usize * n + ix as usize] = quay.max(pier) as f32;
            }
        }
        let reach = Reach::disc(Point2::origin(), reach_m);
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
    fn the_rim_pulls_the_sum_short_and_not_the_mean_inside_it() {
        let (image, reach) = quay_image();
        let points = quay_scan();
        let disc = window();
        // All points, climbing from the truth: the pull of the rim moves
        // the scan back along the quay.
        let problem = SearchProblem::new(&points, &image, &Se2::identity(), &disc);
        let all = problem.local_max(&mut SearchStats::default()).unwrap();
        let all = all.pose(&Se2::identity(), &disc, 0.2);
        assert!(all.x() < -0.1, "{all:?}");
        // Refined from where that climb ended, on the mean over the points
        // inside the rim: back to the truth.
        let leaf = Leaf {
            angle: ((all.theta()) / disc.angle_step_rad).round() as i32,
            dx: (all.x() / 0.2).round() as i32,
            dy: (all.y() / 0.2).round() as i32,
            score: 0.0,
        };
        let refined = refine_inside_reach(&points, &image, &reach, &all, &leaf, &disc, 10).unwrap();
        let p = refined.pose;
        assert!(
            p.x().abs() < 0.11 && p.y().abs() < 0.11 && p.theta().abs() < 0.006,
            "{p:?} (all points: {all:?})"
        );
        // The fits keep only the points that no fit can carry across the
        // rim: inside it by the fits' margin at the refined pose.
        let fits = Refinement::new(&Vector3::new(0.2, 0.2, disc.angle_step_rad), [0, 0, 0]);
        assert!(refined.points.len() < points.len());
        assert!(
            refined
                .points
                .iter()
                .all(|q| reach.margin(&p.transform_point(q)) >= fits.margin_m(q))
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

    /// A whole match of the quay scan against the quay image, from a prior
    /// off the truth by 0.3 m along the quay: on the sum of eq. (5) over
    /// every point it ends short along the quay; refined away from the rim
    /// it ends at the truth (the identity, by construction of the scan).
    #[test]
    fn a_match_along_a_quay_past_the_rim_is_not_short() {
        use crate::matcher::{MatcherConfig, SearchWindow, match_scan_local};
        let (image, reach) = quay_image();
        let image = image.with_reach(reach);
        let points = quay_scan();
        let prior = Se2::new(0.3, 0.0, 0.0);
        let window = SearchWindow::new(1.0, 1.0, 3.0_f64.to_radians());
        let run = |refine_inside_reach: bool| {
            let config = MatcherConfig {
                refine_inside_reach,
                max_points: 1000,
                ..MatcherConfig::default()
            };
            let outcome = match_scan_local(&points, &image, &prior, &window, &config).unwrap();
            outcome.matched().expect("a match").image_from_scan
        };
        let sum = run(false);
        assert!(sum.x() < -0.1, "{sum:?}");
        let refined = run(true);
        assert!(
            refined.x().abs() < 0.1 && refined.y().abs() < 0.1 && refined.theta().abs() < 0.006,
            "{refined:?} (on the sum: {sum:?})"
        );
    }
}
