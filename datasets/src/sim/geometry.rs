//! 2D environment geometry for the sonar model: line segments with an
//! acoustic material, indexed by a uniform grid so that a ray finds its first
//! hit after visiting only the cells it crosses.
//!
//! The world frame is the simulator's local metric frame (x east, y north,
//! metres). Everything the sonar can see is a segment: quay walls, pontoon
//! edges, rocks, hulls. Segments are opaque: a ray stops at its first hit.

mod grid;

use super::SimError;
use grid::SegmentGrid;
use nalgebra::{Point2, Vector2};

/// Acoustic properties of a surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Fraction of the incident energy sent back at normal incidence, in
    /// [0, 1] (concrete ~0.9, rock ~0.8, hull ~0.7, floating pontoon ~0.5).
    pub reflectivity: f64,
    /// Share of diffuse scattering against specular reflection, in [0, 1]:
    /// a smooth plate (0.1) is bright only near normal incidence, a rubble
    /// mound (0.95) is visible from almost any angle.
    pub roughness: f64,
}

impl Material {
    // At MSIS frequencies (~700 kHz, 2 mm wavelength) concrete and rock
    // are acoustically rough; painted hulls and steel plates much less so.
    pub const CONCRETE: Material = Material {
        reflectivity: 0.9,
        roughness: 0.7,
    };
    pub const ROCK: Material = Material {
        reflectivity: 0.8,
        roughness: 0.95,
    };
    pub const PONTOON: Material = Material {
        reflectivity: 0.55,
        roughness: 0.6,
    };
    pub const HULL: Material = Material {
        reflectivity: 0.7,
        roughness: 0.25,
    };
    pub const STEEL: Material = Material {
        reflectivity: 1.0,
        roughness: 0.4,
    };
}

/// A straight reflecting segment from `a` to `b`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    pub a: Point2<f64>,
    pub b: Point2<f64>,
    pub material: Material,
}

/// The first surface a ray meets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    /// Distance from the ray origin to the hit, metres.
    pub range_m: f64,
    /// Angle between the ray and the surface normal, in [0, π/2] rad
    /// (0 = normal incidence, π/2 = grazing).
    pub incidence_rad: f64,
    /// Index of the segment in [`Environment::segments`].
    pub segment: usize,
}

/// A set of segments with a spatial index for ray casting.
#[derive(Clone, Debug)]
pub struct Environment {
    name: String,
    segments: Vec<Segment>,
    grid: SegmentGrid,
}

impl Environment {
    /// Indexes `segments`. Fails on a non-finite or zero-length segment or a
    /// material outside [0, 1].
    pub fn new(name: impl Into<String>, segments: Vec<Segment>) -> Result<Self, SimError> {
        let name = name.into();
        for (i, s) in segments.iter().enumerate() {
            let bad = |message: &str| SimError::InvalidEnvironment {
                environment: name.clone(),
                segment: i,
                message: message.to_string(),
            };
            let coords = [s.a.x, s.a.y, s.b.x, s.b.y];
            if coords.iter().any(|c| !c.is_finite()) {
                return Err(bad("non-finite vertex"));
            }
            if (s.b - s.a).norm() < 1e-6 {
                return Err(bad("zero-length segment"));
            }
            let m = s.material;
            if !(0.0..=1.0).contains(&m.reflectivity) || !(0.0..=1.0).contains(&m.roughness) {
                return Err(bad("reflectivity and roughness must lie in [0, 1]"));
            }
        }
        let grid = SegmentGrid::build(&segments);
        Ok(Self {
            name,
            segments,
            grid,
        })
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    pub fn segments(&self) -> &[Segment] {
        &self.segments
    }

    /// Axis-aligned bounds `(min, max)` of all segments (a unit box at the
    /// origin for an empty environment).
    pub fn bounds(&self) -> (Point2<f64>, Point2<f64>) {
        self.grid.bounds()
    }

    /// The first segment hit by the ray from `origin` along `bearing_rad`
    /// (world frame, counter-clockwise from x) within `max_range_m`.
    pub fn cast_ray(
        &self,
        origin: Point2<f64>,
        bearing_rad: f64,
        max_range_m: f64,
    ) -> Option<RayHit> {
        let dir = Vector2::new(bearing_rad.cos(), bearing_rad.sin());
        let mut best: Option<RayHit> = None;
        self.grid.traverse(origin, dir, max_range_m, |ids, t_exit| {
            for &id in ids {
                let seg = &self.segments[id as usize];
                if let Some(t) = intersect(origin, dir, seg)
                    && t <= max_range_m
                    && best.is_none_or(|b| t < b.range_m)
                {
                    best = Some(RayHit {
                        range_m: t,
                        incidence_rad: incidence(dir, seg),
                        segment: id as usize,
                    });
                }
            }
            // A hit inside the cells visited so far cannot be beaten by a
            // segment in a farther cell.
            best.is_some_and(|b| b.range_m <= t_exit)
        });
        best
    }

    /// Distance from `p` to the nearest segment (brute force; for route and
    /// map checks, not for the per-beam loop). Infinite when empty.
    pub fn distance_to_nearest(&self, p: Point2<f64>) -> f64 {
        self.segments
            .iter()
            .map(|s| point_segment_distance(p, s.a, s.b))
            .fold(f64::INFINITY, f64::min)
    }
}

/// Ray parameter `t > 0` where `origin + t·dir` crosses the segment.
fn intersect(origin: Point2<f64>, dir: Vector2<f64>, seg: &Segment) -> Option<f64> {
    let e = seg.b - seg.a;
    let denom = cross(dir, e);
    if denom.abs() < 1e-12 {
        return None; // parallel: a grazing ray returns no echo anyway
    }
    let w = seg.a - origin;
    let t = cross(w, e) / denom;
    let s = cross(w, dir) / denom;
    (t > 1e-9 && (0.0..=1.0).contains(&s)).then_some(t)
}

fn incidence(dir: Vector2<f64>, seg: &Segment) -> f64 {
    let e = (seg.b - seg.a).normalize();
    // |sin| of the angle between ray and segment is |cos| of the incidence.
    cross(dir, e).abs().clamp(0.0, 1.0).acos()
}

fn cross(a: Vector2<f64>, b: Vector2<f64>) -> f64 {
    a.x * b.y - a.y * b.x
}

/// Euclidean distance from `p` to the segment `a`-`b`.
pub fn point_segment_distance(p: Point2<f64>, a: Point2<f64>, b: Point2<f64>) -> f64 {
    let e = b - a;
    let len2 = e.norm_squared();
    let s = if len2 > 0.0 {
        ((p - a).dot(&e) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + e * s)).norm()
}

/// Collects segments from polylines and polygons.
#[derive(Clone, Debug, Default)]
pub struct EnvironmentBuilder {
    segments: Vec<Segment>,
}

impl EnvironmentBuilder {
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds the open polyline through `points` (`[x, y]` in metres).
    pub fn polyline(&mut self, points: &[[f64; 2]], material: Material) -> &mut Self {
        for w in points.windows(2) {
            self.segment(w[0], w[1], material);
        }
        self
    }

    /// Adds the closed polygon through `points`.
    pub fn polygon(&mut self, points: &[[f64; 2]], material: Material) -> &mut Self {
        self.polyline(points, material);
        if let (Some(first), Some(last)) = (points.first(), points.last())
            && first != last
        {
            self.segment(*last, *first, material);
        }
        self
    }

    /// Adds the axis-aligned rectangle with corners `min` and `max`.
    pub fn rectangle(&mut self, min: [f64; 2], max: [f64; 2], material: Material) -> &mut Self {
        let pts = [min, [max[0], min[1]], max, [min[0], max[1]]];
        self.polygon(&pts, material)
    }

    /// Adds a closed polygon approximating an ellipse (centre, semi-axes in
    /// metres, orientation of the first axis in rad) with `sides` edges.
    pub fn ellipse(
        &mut self,
        centre: [f64; 2],
        semi_axes_m: [f64; 2],
        orientation_rad: f64,
        sides: usize,
        material: Material,
    ) -> &mut Self {
        let (s, c) = orientation_rad.sin_cos();
        let pts: Vec<[f64; 2]> = (0..sides.max(3))
            .map(|k| {
                let u = 2.0 * std::f64::consts::PI * k as f64 / sides.max(3) as f64;
                let (ex, ey) = (semi_axes_m[0] * u.cos(), semi_axes_m[1] * u.sin());
                [centre[0] + c * ex - s * ey, centre[1] + s * ex + c * ey]
            })
            .collect();
        self.polygon(&pts, material)
    }

    /// Adds one segment.
    pub fn segment(&mut self, a: [f64; 2], b: [f64; 2], material: Material) -> &mut Self {
        self.segments.push(Segment {
            a: Point2::new(a[0], a[1]),
            b: Point2::new(b[0], b[1]),
            material,
        });
        self
    }

    /// Indexes the collected segments.
    pub fn build(&self, name: &str) -> Result<Environment, SimError> {
        Environment::new(name, self.segments.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square_room() -> Environment {
        let mut b = EnvironmentBuilder::new();
        b.rectangle([-5.0, -5.0], [5.0, 5.0], Material::CONCRETE);
        b.build("room").unwrap()
    }

    #[test]
    fn ray_from_centre_hits_each_wall_at_five_metres() {
        let env = square_room();
        for k in 0..4 {
            let bearing = k as f64 * std::f64::consts::FRAC_PI_2;
            let hit = env.cast_ray(Point2::origin(), bearing, 50.0).unwrap();
            assert!(
                (hit.range_m - 5.0).abs() < 1e-9,
                "bearing {bearing}: {hit:?}"
            );
            assert!(hit.incidence_rad.abs() < 1e-9);
        }
    }

    #[test]
    fn oblique_ray_has_expected_range_and_incidence() {
        let env = square_room();
        // 30 deg off the +x wall normal: range 5 / cos 30.
        let bearing = 30f64.to_radians();
        let hit = env.cast_ray(Point2::origin(), bearing, 50.0).unwrap();
        assert!((hit.range_m - 5.0 / bearing.cos()).abs() < 1e-9);
        assert!((hit.incidence_rad - bearing).abs() < 1e-9);
    }

    #[test]
    fn nearest_of_two_parallel_walls_wins_and_range_limit_applies() {
        let mut b = EnvironmentBuilder::new();
        b.segment([20.0, -10.0], [20.0, 10.0], Material::ROCK);
        b.segment([7.5, -10.0], [7.5, 10.0], Material::HULL);
        let env = b.build("walls").unwrap();
        let hit = env.cast_ray(Point2::new(0.0, 1.0), 0.0, 50.0).unwrap();
        assert!((hit.range_m - 7.5).abs() < 1e-9);
        assert_eq!(hit.segment, 1);
        assert!(env.cast_ray(Point2::new(0.0, 1.0), 0.0, 7.0).is_none());
        assert!(
            env.cast_ray(Point2::new(0.0, 1.0), std::f64::consts::PI, 50.0)
                .is_none()
        );
    }

    #[test]
    fn grid_ray_cast_agrees_with_brute_force() {
        let mut b = EnvironmentBuilder::new();
        // A fan of segments of many orientations and lengths.
        for k in 0..60 {
            let a = k as f64 * 0.37;
            let c = [
                10.0 * (a * 1.3).cos() + 0.5 * k as f64,
                10.0 * (a * 0.7).sin(),
            ];
            let len = 0.5 + (k % 7) as f64;
            b.segment(
                c,
                [c[0] + len * a.cos(), c[1] + len * a.sin()],
                Material::ROCK,
            );
        }
        let env = b.build("fan").unwrap();
        for k in 0..720 {
            let origin = Point2::new(3.0 * ((k as f64) * 0.1).sin(), -2.0 + (k % 5) as f64);
            let bearing = k as f64 * 0.0271;
            let fast = env.cast_ray(origin, bearing, 40.0).map(|h| h.range_m);
            let dir = Vector2::new(bearing.cos(), bearing.sin());
            let slow = env
                .segments()
                .iter()
                .filter_map(|s| intersect(origin, dir, s))
                .filter(|&t| t <= 40.0)
                .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.min(t))));
            assert_eq!(fast, slow, "ray {k}");
        }
    }

    #[test]
    fn bad_segments_are_rejected_with_their_index() {
        let mut b = EnvironmentBuilder::new();
        b.segment([0.0, 0.0], [1.0, 0.0], Material::ROCK);
        b.segment([2.0, 2.0], [2.0, 2.0], Material::ROCK);
        let err = b.build("bad").unwrap_err().to_string();
        assert!(
            err.contains("segment 1") && err.contains("zero-length"),
            "{err}"
        );
        let mut b = EnvironmentBuilder::new();
        b.segment([0.0, f64::NAN], [1.0, 0.0], Material::ROCK);
        assert!(b.build("nan").is_err());
        let mut b = EnvironmentBuilder::new();
        let glass = Material {
            reflectivity: 1.5,
            roughness: 0.0,
        };
        b.segment([0.0, 0.0], [1.0, 0.0], glass);
        assert!(b.build("glass").is_err());
    }
}
