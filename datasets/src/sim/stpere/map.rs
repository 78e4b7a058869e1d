//! A marina drawn around the real St Pere track, so that the simulated sonar
//! sees structures wherever the real vehicle went.
//!
//! 1. Rasterise the distance from every point of the area to the track
//!    (1 m cells).
//! 2. The water is the set where that distance is below a wall distance that
//!    varies slowly over the area (`wall_distance_m ± wall_distance_variation_m`);
//!    its boundary, traced by marching squares and simplified by
//!    Douglas-Peucker, becomes the quays (straight pieces, concrete) and
//!    rubble (short pieces, rock). Parts of the area enclosed by the track
//!    but far from it become islands.
//! 3. Pontoons reach from the walls towards the track, stopping 6 m short of
//!    it; mooring blocks and moored boats are scattered 6-30 m from it.
//!
//! The layout depends only on the track and the config (a fixed seed draws
//! the clutter), never on the mission seed.

mod contour;

use crate::sim::{Environment, EnvironmentBuilder, Material, SimError, Trajectory};
use contour::{DistanceField, trace_contours};
use nalgebra::{Point2, Vector2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Fixed seed of the clutter placement.
const CLUTTER_SEED: u64 = 0x7374_7065_7265;
/// Raster cell of the distance field, metres.
const CELL_M: f64 = 1.0;
/// Structures never come nearer to the track than this, metres.
pub const MIN_CLEARANCE_M: f64 = 5.0;

/// Shape parameters of the map (see `ReplayConfig`).
#[derive(Clone, Copy, Debug)]
pub struct MapShape {
    pub wall_distance_m: f64,
    pub wall_distance_variation_m: f64,
    pub clutter_objects: usize,
}

/// Builds the map around the poses of `track` (only its moving part
/// matters; samples closer than 1 m to the previous kept one are skipped).
pub fn marina_around_track(track: &Trajectory, shape: &MapShape) -> Result<Environment, SimError> {
    let points = thin_track(track);
    let reach = shape.wall_distance_m + shape.wall_distance_variation_m + 4.0 * CELL_M;
    let field = DistanceField::new(&points, CELL_M, reach);
    let wall_distance =
        |p: Point2<f64>| shape.wall_distance_m + shape.wall_distance_variation_m * wave(p);
    let level = |p: Point2<f64>, d: f64| d - wall_distance(p);
    let mut b = EnvironmentBuilder::new();
    for chain in trace_contours(&field, level) {
        let simple = douglas_peucker(&chain, 0.4);
        for w in simple.windows(2) {
            let long = (w[1] - w[0]).norm() >= 6.0;
            let material = if long {
                Material::CONCRETE
            } else {
                Material::ROCK
            };
            b.segment([w[0].x, w[0].y], [w[1].x, w[1].y], material);
        }
        add_pontoons(&mut b, &simple, &field);
    }
    add_clutter(&mut b, &field, &level, shape.clutter_objects);
    b.build("stpere-marina")
}

/// A smooth pattern in [-1, 1] over the area.
fn wave(p: Point2<f64>) -> f64 {
    0.6 * (p.x / 17.0 + 0.3).sin() * (p.y / 23.0 + 1.1).cos()
        + 0.4 * ((p.x + p.y) / 11.0 + 2.0).sin()
}

fn thin_track(track: &Trajectory) -> Vec<Point2<f64>> {
    let mut points: Vec<Point2<f64>> = Vec::new();
    for pose in track.poses() {
        let p = Point2::new(pose.x(), pose.y());
        if points.last().is_none_or(|q| (p - q).norm() >= 1.0) {
            points.push(p);
        }
    }
    points
}

/// Pontoons every ~45 m along a wall, pointing down the distance gradient
/// (towards the track), 2.5 m wide, ending `MIN_CLEARANCE_M + 1` m from the
/// track; skipped where that leaves less than 4 m of pontoon.
fn add_pontoons(b: &mut EnvironmentBuilder, wall: &[Point2<f64>], field: &DistanceField) {
    let mut along = 0.0;
    let mut next = 20.0;
    for w in wall.windows(2) {
        along += (w[1] - w[0]).norm();
        if along < next {
            continue;
        }
        next = along + 45.0;
        let root = w[1];
        let Some(towards_track) = field.descent_direction(root) else {
            continue;
        };
        let length = (field.distance(root) - MIN_CLEARANCE_M - 1.0).min(16.0);
        if length < 4.0 {
            continue;
        }
        // The pontoon must stay clear of the track along its whole length.
        let tip = root + towards_track * length;
        if field.distance(tip) < MIN_CLEARANCE_M + 0.5 {
            continue;
        }
        let side = Vector2::new(-towards_track.y, towards_track.x) * 1.25;
        let corners = [root - side, tip - side, tip + side, root + side];
        let pts: Vec<[f64; 2]> = corners.iter().map(|c| [c.x, c.y]).collect();
        b.polygon(&pts, Material::PONTOON);
    }
}

/// Mooring blocks and moored boats in open water 6-30 m from the track.
fn add_clutter<L>(b: &mut EnvironmentBuilder, field: &DistanceField, level: &L, count: usize)
where
    L: Fn(Point2<f64>, f64) -> f64,
{
    let mut rng = ChaCha8Rng::seed_from_u64(CLUTTER_SEED);
    let (lo, hi) = field.bounds();
    let mut placed = 0;
    for _ in 0..count * 200 {
        if placed == count {
            break;
        }
        let c = Point2::new(rng.random_range(lo.x..hi.x), rng.random_range(lo.y..hi.y));
        let boat = rng.random_bool(0.4);
        let size = if boat {
            rng.random_range(3.0..6.0)
        } else {
            rng.random_range(0.5..1.5)
        };
        let d = field.distance(c);
        let clear_of_walls = level(c, d) < -(size + 2.0);
        if !(d - size >= MIN_CLEARANCE_M + 1.0 && d <= 30.0 && clear_of_walls) {
            continue;
        }
        if boat {
            let heading = rng.random_range(0.0..std::f64::consts::PI);
            b.ellipse([c.x, c.y], [size, 0.35 * size], heading, 12, Material::HULL);
        } else {
            b.rectangle(
                [c.x - size, c.y - size],
                [c.x + size, c.y + size],
                Material::CONCRETE,
            );
        }
        placed += 1;
    }
}

/// Douglas-Peucker simplification of an open (or closed, first = last)
/// polyline with tolerance `tol_m`.
fn douglas_peucker(points: &[Point2<f64>], tol_m: f64) -> Vec<Point2<f64>> {
    if points.len() < 3 {
        return points.to_vec();
    }
    let mut keep = vec![false; points.len()];
    keep[0] = true;
    keep[points.len() - 1] = true;
    let mut stack = vec![(0, points.len() - 1)];
    while let Some((a, z)) = stack.pop() {
        let (mut worst, mut worst_d) = (0, 0.0);
        for i in a + 1..z {
            let d = crate::sim::geometry::point_segment_distance(points[i], points[a], points[z]);
            if d > worst_d {
                (worst, worst_d) = (i, d);
            }
        }
        if worst_d > tol_m {
            keep[worst] = true;
            stack.push((a, worst));
            stack.push((worst, z));
        }
    }
    points
        .iter()
        .zip(keep)
        .filter(|(_, k)| *k)
        .map(|(p, _)| *p)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use echofield_graph::Se2;

    #[test]
    fn walls_lie_at_the_wall_distance_from_a_straight_track() {
        let poses: Vec<Se2> = (0..=1000)
            .map(|i| Se2::new(0.1 * i as f64, 0.0, 0.0))
            .collect();
        let track = Trajectory::from_poses(0.0, 1.0, poses).unwrap();
        let shape = MapShape {
            wall_distance_m: 12.0,
            wall_distance_variation_m: 0.0,
            clutter_objects: 0,
        };
        let env = marina_around_track(&track, &shape).unwrap();
        // Looking sideways from the middle of the track: walls at ~12 m,
        // or a pontoon that ends 6 m from the track.
        for x in [30.0, 50.0, 70.0] {
            for bearing in [std::f64::consts::FRAC_PI_2, -std::f64::consts::FRAC_PI_2] {
                let hit = env.cast_ray(Point2::new(x, 0.0), bearing, 50.0).unwrap();
                assert!((5.5..=12.6).contains(&hit.range_m), "x {x}: {hit:?}");
            }
        }
        for s in env.segments() {
            for p in [s.a, s.b] {
                let d = if p.x < 0.0 {
                    p.coords.norm()
                } else if p.x > 100.0 {
                    (p - Point2::new(100.0, 0.0)).norm()
                } else {
                    p.y.abs()
                };
                assert!(d >= MIN_CLEARANCE_M, "{p} only {d} m from the track");
            }
        }
    }

    #[test]
    fn douglas_peucker_keeps_corners_only() {
        let mut pts: Vec<Point2<f64>> = (0..=10)
            .map(|i| Point2::new(i as f64, 0.01 * (i % 2) as f64))
            .collect();
        pts.extend((1..=10).map(|i| Point2::new(10.0, i as f64)));
        let simple = douglas_peucker(&pts, 0.1);
        assert_eq!(
            simple,
            vec![
                Point2::new(0.0, 0.0),
                Point2::new(10.0, 0.0),
                Point2::new(10.0, 10.0)
            ]
        );
    }
}
