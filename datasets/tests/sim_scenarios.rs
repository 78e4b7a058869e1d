//! The built-in scenarios have what the SLAM evaluation needs: realistic
//! speeds, revisits, walls in sonar range, and dead reckoning that drifts.

use echofield_datasets::sim::{Scenario, simulate_mission};
use echofield_frontend::sensors::Mission;
use nalgebra::{Point2, Vector2};

/// Plain dead reckoning: DVL velocities (vehicle frame, the DVL is mounted
/// at the origin) rotated by the nearest earlier attitude yaw, integrated
/// from the first ground-truth pose. Returns the position error at every
/// ground-truth record.
fn dead_reckoning_errors(m: &Mission) -> Vec<f64> {
    let start = &m.ground_truth[0];
    let mut pos = start.world_from_vehicle.translation();
    let mut t = start.stamp_s;
    let mut dvl = m.dvl.iter().filter(|d| d.valid).peekable();
    let mut velocity = Vector2::zeros();
    let mut errors = Vec::new();
    for gt in &m.ground_truth {
        while let Some(d) = dvl.next_if(|d| d.stamp_s <= gt.stamp_s) {
            pos += velocity * (d.stamp_s - t);
            t = d.stamp_s;
            let k = m
                .attitude
                .partition_point(|a| a.stamp_s <= d.stamp_s)
                .max(1)
                - 1;
            let (s, c) = m.attitude[k].yaw_rad.sin_cos();
            let v = d.velocity_mps;
            velocity = Vector2::new(c * v.x - s * v.y, s * v.x + c * v.y);
        }
        let here = pos + velocity * (gt.stamp_s - t);
        errors.push((here - gt.world_from_vehicle.translation()).norm());
    }
    errors
}

/// Fraction of ground-truth records that come back within `radius_m` of a
/// place visited more than `after_s` earlier.
fn revisit_fraction(m: &Mission, radius_m: f64, after_s: f64) -> f64 {
    let poses: Vec<(f64, Vector2<f64>)> = m
        .ground_truth
        .iter()
        .step_by(20)
        .map(|g| (g.stamp_s, g.world_from_vehicle.translation()))
        .collect();
    let revisits = poses
        .iter()
        .filter(|(t, p)| {
            poses
                .iter()
                .take_while(|(s, _)| *s < t - after_s)
                .any(|(_, q)| (p - q).norm() < radius_m)
        })
        .count();
    revisits as f64 / poses.len() as f64
}

/// Fraction of ground-truth records with a structure within `range_m`.
fn seeing_fraction(scenario: &Scenario, m: &Mission, range_m: f64) -> f64 {
    let env = scenario.environment();
    let samples: Vec<_> = m.ground_truth.iter().step_by(50).collect();
    let seen = samples
        .iter()
        .filter(|g| {
            let p = g.world_from_vehicle.translation();
            env.distance_to_nearest(Point2::new(p.x, p.y)) <= range_m
        })
        .count();
    seen as f64 / samples.len() as f64
}

fn speeds(m: &Mission) -> Vec<f64> {
    m.ground_truth
        .windows(2)
        .map(|w| {
            (w[1].world_from_vehicle.translation() - w[0].world_from_vehicle.translation()).norm()
                / (w[1].stamp_s - w[0].stamp_s)
        })
        .collect()
}

#[test]
fn marina_is_long_revisits_its_places_sees_walls_and_drifts() {
    let scenario = Scenario::named("marina").unwrap();
    let m = simulate_mission(&scenario, 1).unwrap();
    let duration_min = scenario.ground_truth().duration_s() / 60.0;
    assert!((20.0..=45.0).contains(&duration_min), "{duration_min} min");
    let distance = scenario.ground_truth().distance_travelled_m();
    assert!((500.0..1200.0).contains(&distance), "{distance} m");
    let v = speeds(&m);
    let cruising = v.iter().filter(|s| (0.2..=0.5).contains(*s)).count();
    assert!(cruising * 10 >= 9 * v.len(), "{cruising} of {}", v.len());
    assert!(v.iter().all(|s| *s <= 0.5), "too fast");
    let revisits = revisit_fraction(&m, 10.0, 120.0);
    assert!(
        revisits >= 0.3,
        "only {revisits:.2} of the poses revisit a place"
    );
    assert!(seeing_fraction(&scenario, &m, 40.0) >= 0.98);
    // Dead reckoning drifts by a few metres (the scale and heading biases
    // and the DVL noise), so SLAM has something to correct.
    let dr = dead_reckoning_errors(&m);
    let worst = dr.iter().cloned().fold(0.0, f64::max);
    let rmse = (dr.iter().map(|e| e * e).sum::<f64>() / dr.len() as f64).sqrt();
    assert!(
        (3.0..=40.0).contains(&worst),
        "max dead-reckoning error {worst:.2} m"
    );
    assert!(rmse >= 1.5, "dead-reckoning RMSE {rmse:.2} m");
}

#[test]
fn canyon_goes_out_and_back_between_rock_walls() {
    let scenario = Scenario::named("canyon").unwrap();
    let m = simulate_mission(&scenario, 1).unwrap();
    let duration_min = scenario.ground_truth().duration_s() / 60.0;
    assert!((10.0..=40.0).contains(&duration_min), "{duration_min} min");
    assert!(revisit_fraction(&m, 15.0, 120.0) >= 0.4);
    assert!(seeing_fraction(&scenario, &m, 25.0) >= 0.98);
    let v = speeds(&m);
    assert!(v.iter().all(|s| *s <= 0.5));
}

#[test]
fn tank_sees_its_walls_all_the_time() {
    let scenario = Scenario::named("tank").unwrap();
    let m = simulate_mission(&scenario, 1).unwrap();
    assert!(seeing_fraction(&scenario, &m, 8.0) == 1.0);
    // Some ten rotations of 200 beams.
    assert!((1600..=2800).contains(&m.beams.len()), "{}", m.beams.len());
}
