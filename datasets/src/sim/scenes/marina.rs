//! A 120 m x 240 m marina (x east, y north, origin at the south-west corner
//! of the basin): concrete quays on three sides with a slipway recess and a
//! fuel dock, a rubble breakwater with its entrance in the north-east, a
//! concrete mole in the southern basin, floating pontoons with finger piers
//! and moored boats, and a few mooring blocks.
//!
//! The route (about 950 m, some 40 min at 0.4 m/s) loops around the mole,
//! runs north along the east side, surveys the northern basin with a short
//! lawnmower, enters the channel between the pontoons, comes back south along
//! the east side in the opposite direction and goes half round the mole
//! again the other way: the southern basin and the east side are revisited.

use super::Scene;
use crate::sim::{EnvironmentBuilder, Material, SimError};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Fixed seed of the rubble outlines: the marina is the same for every
/// mission seed.
const GEOMETRY_SEED: u64 = 0x6d61_7269_6e61;

pub fn marina() -> Result<Scene, SimError> {
    let mut rng = ChaCha8Rng::seed_from_u64(GEOMETRY_SEED);
    let mut b = EnvironmentBuilder::new();
    quays(&mut b);
    breakwater(&mut b, &mut rng);
    pontoons(&mut b);
    // The mole in the southern basin.
    b.rectangle([52.0, 32.0], [62.0, 72.0], Material::CONCRETE);
    // Mooring blocks and a sunken barge.
    for c in [[66.0, 112.0], [40.0, 211.0], [104.0, 185.0], [38.0, 58.0]] {
        b.rectangle(
            [c[0] - 0.6, c[1] - 0.6],
            [c[0] + 0.6, c[1] + 0.6],
            Material::CONCRETE,
        );
    }
    b.polygon(
        &[
            [104.0, 100.0],
            [110.0, 102.5],
            [109.0, 106.0],
            [103.0, 104.5],
        ],
        Material::STEEL,
    );
    Ok(Scene {
        environment: b.build("marina")?,
        route: route(),
    })
}

fn quays(b: &mut EnvironmentBuilder) {
    // West quay with a slipway recess, south quay, east quay with a fuel dock.
    b.polyline(
        &[
            [0.0, 240.0],
            [0.0, 96.0],
            [-5.0, 92.0],
            [-5.0, 80.0],
            [0.0, 80.0],
            [0.0, 0.0],
            [120.0, 0.0],
            [120.0, 44.0],
            [113.0, 44.0],
            [113.0, 58.0],
            [120.0, 58.0],
            [120.0, 205.0],
        ],
        Material::CONCRETE,
    );
}

fn breakwater(b: &mut EnvironmentBuilder, rng: &mut ChaCha8Rng) {
    let main = jagged(
        &[[0.0, 240.0], [90.0, 240.0], [100.0, 228.0]],
        2.0,
        0.6,
        rng,
    );
    b.polyline(&main, Material::ROCK);
    let spur = jagged(&[[120.0, 205.0], [114.0, 214.0]], 2.0, 0.5, rng);
    b.polyline(&spur, Material::ROCK);
}

fn pontoons(b: &mut EnvironmentBuilder) {
    // Two pontoons off the west quay, fingers on the north side of the
    // southern one and the south side of the northern one.
    b.rectangle([0.0, 128.0], [46.0, 130.5], Material::PONTOON);
    b.rectangle([0.0, 171.0], [46.0, 173.5], Material::PONTOON);
    for (x, len) in [(9.0, 7.0), (20.0, 8.5), (31.0, 7.5), (42.0, 6.0)] {
        b.rectangle([x, 130.5], [x + 0.8, 130.5 + len], Material::PONTOON);
    }
    for (x, len) in [(6.0, 8.0), (18.0, 6.5), (27.0, 8.0), (39.0, 7.0)] {
        b.rectangle([x, 171.0 - len], [x + 0.8, 171.0], Material::PONTOON);
    }
    // Boats in some berths, long axis along the fingers.
    let half_pi = std::f64::consts::FRAC_PI_2;
    b.ellipse([14.5, 135.0], [4.5, 1.6], half_pi, 12, Material::HULL);
    b.ellipse([36.5, 134.5], [4.0, 1.5], half_pi, 12, Material::HULL);
    b.ellipse([12.0, 166.5], [4.5, 1.7], half_pi, 12, Material::HULL);
    // A short pontoon off the east quay with a boat alongside.
    b.rectangle([100.0, 150.0], [120.0, 152.5], Material::PONTOON);
    b.ellipse([109.0, 147.0], [6.0, 1.8], 0.0, 14, Material::HULL);
}

/// Inserts points every `step_m` along each edge, displaced sideways by a
/// uniform draw in ±`amplitude_m` (a rubble outline).
fn jagged(
    points: &[[f64; 2]],
    step_m: f64,
    amplitude_m: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<[f64; 2]> {
    let mut out = vec![points[0]];
    for w in points.windows(2) {
        let (a, b) = (w[0], w[1]);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len = dx.hypot(dy);
        let n = (len / step_m).ceil().max(1.0) as usize;
        let (nx, ny) = (-dy / len, dx / len);
        for k in 1..n {
            let f = k as f64 / n as f64;
            let off = rng.random_range(-amplitude_m..=amplitude_m);
            out.push([a[0] + f * dx + off * nx, a[1] + f * dy + off * ny]);
        }
        out.push(b);
    }
    out
}

fn route() -> Vec<[f64; 2]> {
    let mut r = Vec::new();
    // Loop 1 around the mole, clockwise.
    r.extend([
        [88.0, 14.0],
        [26.0, 14.0],
        [26.0, 90.0],
        [88.0, 90.0],
        [88.0, 14.0],
        [72.0, 14.0],
    ]);
    // Back up the east side to the northern basin.
    r.extend([
        [78.0, 20.0],
        [88.0, 30.0],
        [92.0, 120.0],
        [84.0, 140.0],
        [84.0, 200.0],
    ]);
    // Lawnmower across the northern basin.
    r.extend([[30.0, 200.0], [30.0, 222.0], [84.0, 222.0], [86.0, 212.0]]);
    // Into the channel between the pontoons and out again.
    r.extend([
        [70.0, 160.0],
        [60.0, 153.0],
        [18.0, 153.0],
        [12.0, 149.5],
        [18.0, 146.0],
        [60.0, 146.0],
    ]);
    // South along the east side, then half a loop around the mole,
    // counter-clockwise.
    r.extend([
        [76.0, 130.0],
        [88.0, 110.0],
        [88.0, 90.0],
        [26.0, 90.0],
        [26.0, 40.0],
    ]);
    r
}
