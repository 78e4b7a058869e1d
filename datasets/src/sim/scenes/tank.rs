//! A 20 m x 14 m concrete test tank with three targets in its corners (a
//! box, a steel pillar and an angled plate). The route is two rounded laps of
//! a diamond in the middle, about 50 m: some ten sonar rotations, quick
//! enough for unit tests and the committed sample.

use super::Scene;
use crate::sim::{EnvironmentBuilder, Material, SimError};

pub fn tank() -> Result<Scene, SimError> {
    let mut b = EnvironmentBuilder::new();
    b.rectangle([0.0, 0.0], [20.0, 14.0], Material::CONCRETE);
    b.rectangle([2.0, 2.0], [3.5, 3.0], Material::STEEL);
    b.rectangle([17.2, 10.7], [17.8, 11.3], Material::STEEL);
    b.segment([16.8, 1.5], [18.8, 3.4], Material::STEEL);
    let diamond = [[5.0, 7.0], [10.0, 10.5], [15.0, 7.0], [10.0, 3.5]];
    let mut route = Vec::new();
    for _ in 0..2 {
        route.extend(diamond);
    }
    route.push(diamond[0]);
    Ok(Scene {
        environment: b.build("tank")?,
        route,
    })
}
