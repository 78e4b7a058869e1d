//! The built-in worlds: an environment and the route the vehicle follows in
//! it. Geometry is fixed per scene (the mission seed only drives sensor
//! noise), so every seed of a scenario surveys the same place.

mod canyon;
mod marina;
mod tank;

pub use canyon::canyon;
pub use marina::marina;
pub use tank::tank;

use super::Environment;

/// An environment and a route of waypoints `[x, y]` (metres, world frame).
#[derive(Clone, Debug)]
pub struct Scene {
    pub environment: Environment,
    pub route: Vec<[f64; 2]>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{VehicleConfig, follow_route};
    use nalgebra::Point2;

    /// Follows the route and measures, along the way, the clearance to the
    /// nearest structure.
    fn clearances(scene: &Scene) -> Vec<f64> {
        let traj = follow_route(&scene.route, &VehicleConfig::default(), 0.0).unwrap();
        traj.poses()
            .iter()
            .step_by(20)
            .map(|p| {
                scene
                    .environment
                    .distance_to_nearest(Point2::new(p.x(), p.y()))
            })
            .collect()
    }

    fn check(scene: &Scene, min_clearance_m: f64, max_clearance_m: f64) {
        let c = clearances(scene);
        let min = c.iter().cloned().fold(f64::INFINITY, f64::min);
        let far = c.iter().filter(|&&d| d > max_clearance_m).count();
        assert!(
            min >= min_clearance_m,
            "{}: comes within {min:.2} m of a structure",
            scene.environment.name()
        );
        assert!(
            far * 50 <= c.len(),
            "{}: {far} of {} samples have nothing within {max_clearance_m} m",
            scene.environment.name(),
            c.len()
        );
    }

    #[test]
    fn marina_route_keeps_clear_of_structures_and_sees_them() {
        check(&marina().unwrap(), 4.0, 40.0);
    }

    #[test]
    fn tank_route_keeps_clear_of_structures() {
        check(&tank().unwrap(), 1.5, 10.0);
    }

    #[test]
    fn canyon_route_keeps_clear_of_structures_and_sees_them() {
        check(&canyon().unwrap(), 4.0, 40.0);
    }
}
