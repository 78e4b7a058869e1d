//! A winding submarine canyon about 220 m long and 22-40 m wide, with
//! irregular rock walls, a closed head and scattered boulders. The route
//! goes up the canyon, circles in the wide section near its head and comes
//! back down along the other side: every place is revisited in the opposite
//! direction (about 420 m, some 18 min at 0.4 m/s).

use super::Scene;
use crate::sim::{EnvironmentBuilder, Material, SimError};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Fixed seed of the wall outlines: the canyon is the same for every mission
/// seed.
const GEOMETRY_SEED: u64 = 0x6361_6e79_6f6e;

/// Along-canyon spacing of wall vertices, metres.
const WALL_STEP_M: f64 = 2.5;

/// Centre line `x` of the canyon at `y` (a slow meander).
fn centre_x(y: f64) -> f64 {
    14.0 * (y / 55.0).sin()
}

/// Half width of the canyon at `y`: narrow in the middle, wide near the head.
fn half_width(y: f64) -> f64 {
    11.0 + 4.0 * (y / 23.0 + 1.0).sin().abs() + 9.0 * ((y - 150.0) / 70.0).clamp(0.0, 1.0)
}

pub fn canyon() -> Result<Scene, SimError> {
    let mut rng = ChaCha8Rng::seed_from_u64(GEOMETRY_SEED);
    let mut west = Vec::new();
    let mut east = Vec::new();
    let length = 220.0;
    let steps = (length / WALL_STEP_M) as usize;
    for k in 0..=steps {
        let y = -10.0 + k as f64 * WALL_STEP_M;
        let (c, w) = (centre_x(y), half_width(y));
        west.push([
            c - w + rng.random_range(-1.2..1.2),
            y + rng.random_range(-0.8..0.8),
        ]);
        east.push([
            c + w + rng.random_range(-1.2..1.2),
            y + rng.random_range(-0.8..0.8),
        ]);
    }
    // Close the head with a rounded rock wall.
    let head_y = -10.0 + steps as f64 * WALL_STEP_M;
    let (hc, hw) = (centre_x(head_y), half_width(head_y));
    let mut wall = west.clone();
    for k in 1..12 {
        let a = std::f64::consts::PI * (1.0 - k as f64 / 12.0);
        let r = hw + rng.random_range(-1.0..1.0);
        wall.push([hc + r * a.cos(), head_y + 0.6 * r * a.sin()]);
    }
    wall.extend(east.iter().rev());
    let mut b = EnvironmentBuilder::new();
    b.polyline(&wall, Material::ROCK);
    for (y, side) in [
        (30.0, -0.85),
        (75.0, 0.85),
        (120.0, -0.85),
        (140.0, 0.85),
        (165.0, -0.85),
    ] {
        let centre = [centre_x(y) + side * half_width(y), y];
        boulder(&mut b, centre, &mut rng);
    }
    Ok(Scene {
        environment: b.build("canyon")?,
        route: route(),
    })
}

/// An irregular rock of 0.8-1.8 m mean radius.
fn boulder(b: &mut EnvironmentBuilder, centre: [f64; 2], rng: &mut ChaCha8Rng) {
    let sides = rng.random_range(5..9);
    let radius = rng.random_range(0.8..1.8);
    let pts: Vec<[f64; 2]> = (0..sides)
        .map(|k| {
            let a = 2.0 * std::f64::consts::PI * k as f64 / sides as f64;
            let r = radius * rng.random_range(0.7..1.3);
            [centre[0] + r * a.cos(), centre[1] + r * a.sin()]
        })
        .collect();
    b.polygon(&pts, Material::ROCK);
}

/// Up the canyon a quarter of the width east of the centre line, a
/// circle near the head, back down a quarter to the west.
fn route() -> Vec<[f64; 2]> {
    let lane = |y: f64, side: f64| [centre_x(y) + side * half_width(y), y];
    let mut r: Vec<[f64; 2]> = (0..=17)
        .map(|k| lane(5.0 + 10.0 * k as f64, 0.25))
        .collect();
    let (cx, cy) = (centre_x(190.0), 190.0);
    for k in 0..=16 {
        let a = -std::f64::consts::FRAC_PI_2 + 2.0 * std::f64::consts::PI * k as f64 / 16.0;
        r.push([cx + 10.0 * a.cos(), cy + 10.0 * a.sin()]);
    }
    r.extend((0..=17).rev().map(|k| lane(5.0 + 10.0 * k as f64, -0.25)));
    r
}
