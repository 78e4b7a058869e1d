//! Seeded synthetic sonar rotations in a small walled scene, for tests and
//! benchmarks of image building and matching that need exact geometry
//! without a whole mission (`echofield_datasets::sim` is the full
//! simulator). Each beam ray-casts line-segment walls with a few sub-rays
//! across the beam width; a hit gives a Gaussian echo over range with
//! multiplicative speckle, range attenuation and an acoustic shadow behind
//! it; all bins carry exponential speckle; the first bins ring.

use crate::sensors::SonarBeam;
use echofield_graph::Se2;
use nalgebra::{Point2, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Exp1};

/// A reflecting wall segment in the world frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Wall {
    pub a: Point2<f64>,
    pub b: Point2<f64>,
    /// Echo strength factor, 0-1.
    pub reflectivity: f64,
}

impl Wall {
    pub fn new(ax: f64, ay: f64, bx: f64, by: f64, reflectivity: f64) -> Self {
        Self {
            a: Point2::new(ax, ay),
            b: Point2::new(bx, by),
            reflectivity,
        }
    }
}

/// The scene and the sonar.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneConfig {
    pub walls: Vec<Wall>,
    /// Beams per 360° turn.
    pub beams_per_turn: usize,
    pub bins: usize,
    pub bin_size_m: f64,
    /// Time between beams, seconds.
    pub beam_period_s: f64,
    /// Horizontal beam width, radians (sampled by 5 sub-rays).
    pub beam_width_rad: f64,
    /// Mean of the exponential speckle of empty bins (intensity units).
    pub speckle_mean: f64,
    /// Peak echo intensity of a wall of reflectivity 1 at 0 m.
    pub echo_peak: f64,
    /// Range spread (standard deviation) of an echo, metres.
    pub echo_spread_m: f64,
}

impl Default for SceneConfig {
    /// A 30 m x 20 m basin with a pier, a jetty and a block, sonar near its
    /// centre; 200 beams of 500 bins of 0.1 m, ~68 ms per beam (the paper's
    /// sonar).
    fn default() -> Self {
        Self {
            walls: vec![
                Wall::new(-12.0, -8.0, 18.0, -8.0, 0.9),
                Wall::new(18.0, -8.0, 18.0, 12.0, 0.8),
                Wall::new(18.0, 12.0, -12.0, 12.0, 0.9),
                Wall::new(-12.0, 12.0, -12.0, -8.0, 0.7),
                Wall::new(4.0, -3.0, 9.0, 1.0, 1.0),
                Wall::new(-6.0, 5.0, -3.0, 7.5, 0.8),
                Wall::new(-6.0, -4.0, -5.0, -4.0, 1.0),
                Wall::new(-5.0, -4.0, -5.0, -5.0, 1.0),
                Wall::new(-5.0, -5.0, -6.0, -5.0, 1.0),
                Wall::new(-6.0, -5.0, -6.0, -4.0, 1.0),
                Wall::new(10.0, 7.0, 13.0, 9.0, 0.6),
            ],
            beams_per_turn: 200,
            bins: 500,
            bin_size_m: 0.1,
            beam_period_s: 0.069,
            beam_width_rad: 3.0_f64.to_radians(),
            speckle_mean: 12.0,
            echo_peak: 230.0,
            echo_spread_m: 0.12,
        }
    }
}

/// The vehicle's motion during a rotation: a start pose in the world and a
/// constant body twist.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RotationPath {
    pub world_from_start: Se2,
    /// Body-frame velocity (forward, left), m/s.
    pub velocity_mps: (f64, f64),
    pub yaw_rate_radps: f64,
}

impl RotationPath {
    pub fn fixed(world_from_vehicle: Se2) -> Self {
        Self {
            world_from_start: world_from_vehicle,
            velocity_mps: (0.0, 0.0),
            yaw_rate_radps: 0.0,
        }
    }

    /// `world_from_vehicle` at `t_s` after the first beam.
    pub fn pose_at(&self, t_s: f64) -> Se2 {
        let twist = Vector3::new(
            self.velocity_mps.0 * t_s,
            self.velocity_mps.1 * t_s,
            self.yaw_rate_radps * t_s,
        );
        self.world_from_start.compose(&Se2::exp(&twist))
    }
}

/// One simulated rotation with its exact geometry.
#[derive(Clone, Debug)]
pub struct SyntheticRotation {
    pub beams: Vec<SonarBeam>,
    /// Exact pose of every beam frame in the reference frame (the vehicle at
    /// the central beam's time), as motion compensation would give it.
    pub reference_from_beams: Vec<Se2>,
    /// The vehicle at the reference time, in the world.
    pub world_from_reference: Se2,
    /// Where each beam's central ray hits a wall (when within range), in the
    /// reference frame: the ideal scan `S_k`.
    pub wall_points: Vec<Point2<f64>>,
}

/// A rotation of a sonar at rest at the world origin.
pub fn static_rotation(scene: &SceneConfig, seed: u64) -> SyntheticRotation {
    simulate_rotation(scene, &RotationPath::fixed(Se2::identity()), seed)
}

/// A rotation along `path`; the sonar sits at the vehicle origin and beam `k`
/// points at `2πk / beams_per_turn` in the vehicle frame.
pub fn simulate_rotation(scene: &SceneConfig, path: &RotationPath, seed: u64) -> SyntheticRotation {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = scene.beams_per_turn;
    let t_ref = (n.saturating_sub(1)) as f64 * 0.5 * scene.beam_period_s;
    let world_from_reference = path.pose_at(t_ref);
    let max_range = scene.bins as f64 * scene.bin_size_m;
    let mut beams = Vec::with_capacity(n);
    let mut reference_from_beams = Vec::with_capacity(n);
    let mut wall_points = Vec::new();
    for k in 0..n {
        let t = k as f64 * scene.beam_period_s;
        let angle = std::f64::consts::TAU * k as f64 / n as f64;
        let world_from_beam = path.pose_at(t).compose(&Se2::new(0.0, 0.0, angle));
        let reference_from_beam = world_from_reference.between(&world_from_beam);
        let mut profile = vec![0.0_f64; scene.bins];
        const SUB_RAYS: usize = 5;
        for s in 0..SUB_RAYS {
            let offset = scene.beam_width_rad * ((s as f64 + 0.5) / SUB_RAYS as f64 - 0.5);
            let ray = world_from_beam.compose(&Se2::new(0.0, 0.0, offset));
            let Some((range, reflectivity)) = cast(&scene.walls, &ray) else {
                continue;
            };
            if s == SUB_RAYS / 2 && range < max_range {
                let (x, y) = reference_from_beam.transform_xy(range, 0.0);
                wall_points.push(Point2::new(x, y));
            }
            let amplitude = scene.echo_peak * reflectivity / (1.0 + range / 30.0);
            for (i, p) in profile.iter_mut().enumerate() {
                let far_m = (i + 1) as f64 * scene.bin_size_m;
                let z = (far_m - range) / scene.echo_spread_m;
                if z.abs() < 4.0 {
                    *p += amplitude * (-0.5 * z * z).exp() / SUB_RAYS as f64;
                }
            }
        }
        let intensities = profile
            .iter()
            .enumerate()
            .map(|(i, &echo)| {
                let far_m = (i + 1) as f64 * scene.bin_size_m;
                let speckle: f64 = Exp1.sample(&mut rng);
                let ringing = if far_m <= 0.6 { 160.0 } else { 0.0 };
                let echo = echo * rng.random_range(0.6..1.4);
                (echo + ringing + scene.speckle_mean * speckle).clamp(0.0, 255.0) as u8
            })
            .collect();
        beams.push(SonarBeam {
            stamp_s: t,
            angle_rad: angle,
            bin_size_m: scene.bin_size_m,
            first_bin_range_m: 0.0,
            intensities,
        });
        reference_from_beams.push(reference_from_beam);
    }
    SyntheticRotation {
        beams,
        reference_from_beams,
        world_from_reference,
        wall_points,
    }
}

/// Nearest wall hit along the x axis of `world_from_ray`: range and
/// reflectivity.
fn cast(walls: &[Wall], world_from_ray: &Se2) -> Option<(f64, f64)> {
    let origin = world_from_ray.translation();
    let (s, c) = world_from_ray.theta().sin_cos();
    let mut best: Option<(f64, f64)> = None;
    for wall in walls {
        let e = wall.b - wall.a;
        let w = wall.a.coords - origin;
        // Solve origin + r·(c, s) = a + t·e.
        let det = e.x * s - e.y * c;
        if det.abs() < 1e-12 {
            continue;
        }
        let r = (e.x * w.y - e.y * w.x) / det;
        let t = (c * w.y - s * w.x) / det;
        if r > 1e-6 && (0.0..=1.0).contains(&t) && best.is_none_or(|(b, _)| r < b) {
            best = Some((r, wall.reflectivity));
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ray_cast_hits_the_nearest_wall() {
        let walls = vec![
            Wall::new(5.0, -1.0, 5.0, 1.0, 0.5),
            Wall::new(3.0, -1.0, 3.0, 1.0, 0.9),
        ];
        let (r, refl) = cast(&walls, &Se2::new(0.0, 0.0, 0.0)).unwrap();
        assert!((r - 3.0).abs() < 1e-12 && refl == 0.9);
        assert!(cast(&walls, &Se2::new(0.0, 0.0, std::f64::consts::PI)).is_none());
        // Diagonal ray from (0, -1) at 45 deg reaches x = 3 at y = 2 and x = 5
        // at y = 4: both outside the walls (|y| <= 1), so no hit.
        assert!(cast(&walls, &Se2::new(0.0, -1.0, std::f64::consts::FRAC_PI_4)).is_none());
    }

    #[test]
    fn echo_peaks_at_the_wall_range_and_is_deterministic() {
        let scene = SceneConfig::default();
        let a = static_rotation(&scene, 9);
        let b = static_rotation(&scene, 9);
        assert_eq!(a.beams, b.beams);
        // Beam 0 points along +x: the pier (4,-3)-(9,1) crosses y = 0 at
        // x = 4 + 5·3/4 = 7.75 m.
        let beam = &a.beams[0];
        let peak = (20..beam.intensities.len())
            .max_by_key(|&i| beam.intensities[i])
            .unwrap();
        let far_m = beam.bin_end_range_m(peak);
        assert!((far_m - 7.75).abs() <= 0.2, "peak at {far_m} m");
        assert!((a.wall_points[0].x - 7.75).abs() < 1e-9);
    }

    #[test]
    fn moving_rotation_reference_is_the_central_beam() {
        let scene = SceneConfig::default();
        let path = RotationPath {
            world_from_start: Se2::new(1.0, 2.0, 0.3),
            velocity_mps: (0.5, 0.0),
            yaw_rate_radps: 0.01,
        };
        let rot = simulate_rotation(&scene, &path, 1);
        let central =
            rot.reference_from_beams[99].compose(&Se2::new(0.0, 0.0, -rot.beams[99].angle_rad));
        // Beam 99 is 0.5 beam periods before the reference time.
        assert!(central.translation().norm() < 0.5 * 0.5 * 0.069 + 1e-9);
        let first = rot.reference_from_beams[0];
        assert!((first.x() + 0.5 * 99.5 * 0.069).abs() < 0.1, "{first:?}");
    }
}
