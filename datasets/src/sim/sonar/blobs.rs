//! Spurious echoes that are not part of the map: clouds of fish, bubbles or
//! suspended particles. Each blob lives for a while at a drifting position
//! in the world, so consecutive beams see it coherently, as a real school of
//! fish appears in an MSIS image; it then vanishes, so it never repeats at a
//! revisit.

use super::super::Trajectory;
use echofield_graph::wrap_angle;
use nalgebra::{Point2, Vector2};
use rand::Rng;
use rand_distr::{Distribution, Exp};

/// One spurious scatterer.
#[derive(Clone, Debug, PartialEq)]
pub struct Blob {
    /// World position at `start_s`, metres.
    pub centre: Point2<f64>,
    /// Drift velocity in the world, m/s.
    pub velocity_mps: Vector2<f64>,
    pub start_s: f64,
    pub end_s: f64,
    /// Radius of the cloud, metres: sets its angular size and range spread.
    pub radius_m: f64,
    /// Peak echo energy (relative to the mean noise) when the beam axis goes
    /// through its centre.
    pub level: f64,
}

impl Blob {
    pub fn position_at(&self, stamp_s: f64) -> Point2<f64> {
        self.centre + self.velocity_mps * (stamp_s - self.start_s)
    }
}

/// Settings of the blob process (see `SonarSimConfig` for their meaning).
#[derive(Clone, Copy, Debug)]
pub struct BlobProcess {
    pub rate_per_min: f64,
    pub mean_lifetime_s: f64,
    /// Peak energy of the strongest blobs, relative to the mean noise, dB.
    pub snr_db: f64,
    pub max_range_m: f64,
}

/// Draws the blobs of a whole mission: births form a Poisson process in
/// time; each blob appears 3 m to 80% of the sonar range from the vehicle at
/// its birth, in a random direction.
pub fn spawn_blobs<R: Rng>(
    trajectory: &Trajectory,
    process: &BlobProcess,
    rng: &mut R,
) -> Vec<Blob> {
    let mut blobs = Vec::new();
    if process.rate_per_min <= 0.0 {
        return blobs;
    }
    let Ok(gap) = Exp::new(process.rate_per_min / 60.0) else {
        return blobs;
    };
    let Ok(life) = Exp::new(1.0 / process.mean_lifetime_s.max(1e-3)) else {
        return blobs;
    };
    let mut t = trajectory.start_s() + gap.sample(rng);
    let far = (0.8 * process.max_range_m).max(3.5);
    while t < trajectory.end_s() {
        let vehicle = trajectory.pose_at(t);
        let range = rng.random_range(3.0..far);
        let bearing = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        let drift_dir = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        let drift = rng.random_range(0.0..0.15);
        blobs.push(Blob {
            centre: Point2::new(
                vehicle.x() + range * bearing.cos(),
                vehicle.y() + range * bearing.sin(),
            ),
            velocity_mps: Vector2::new(drift_dir.cos(), drift_dir.sin()) * drift,
            start_s: t,
            end_s: t + 2.0 + life.sample(rng),
            radius_m: rng.random_range(0.2..1.2),
            level: 10f64.powf(0.1 * (process.snr_db - rng.random_range(0.0..15.0))),
        });
        t += gap.sample(rng);
    }
    blobs
}

/// Range and angular weight of a blob seen along the beam from `origin` at
/// `bearing_rad` with Gaussian two-way pattern of full width
/// `beam_width_rad`, or `None` when it is out of the beam, out of range or
/// not alive at `stamp_s`.
pub fn blob_echo(
    blob: &Blob,
    origin: Point2<f64>,
    bearing_rad: f64,
    stamp_s: f64,
    beam_width_rad: f64,
    max_range_m: f64,
) -> Option<(f64, f64)> {
    if stamp_s < blob.start_s || stamp_s > blob.end_s {
        return None;
    }
    let d = blob.position_at(stamp_s) - origin;
    let range = d.norm();
    if range <= blob.radius_m || range > max_range_m + blob.radius_m {
        return None;
    }
    let half_angle = (blob.radius_m / range).asin();
    let off_axis = (wrap_angle(d.y.atan2(d.x) - bearing_rad).abs() - half_angle).max(0.0);
    if off_axis > beam_width_rad {
        return None;
    }
    Some((range, beam_pattern(off_axis, beam_width_rad)))
}

/// Two-way Gaussian beam pattern with -3 dB full width `beam_width_rad`.
pub fn beam_pattern(off_axis_rad: f64, beam_width_rad: f64) -> f64 {
    let u = off_axis_rad / beam_width_rad;
    (-4.0 * std::f64::consts::LN_2 * u * u).exp()
}

#[cfg(test)]
mod tests {
    use super::*;
    use echofield_graph::Se2;
    use rand::SeedableRng;

    #[test]
    fn pattern_is_half_power_at_half_width() {
        assert!((beam_pattern(0.05, 0.1) - 0.5).abs() < 1e-12);
        assert_eq!(beam_pattern(0.0, 0.1), 1.0);
    }

    #[test]
    fn blob_is_seen_only_on_axis_and_while_alive() {
        let blob = Blob {
            centre: Point2::new(10.0, 0.0),
            velocity_mps: Vector2::zeros(),
            start_s: 5.0,
            end_s: 15.0,
            radius_m: 0.5,
            level: 100.0,
        };
        let (r, w) = blob_echo(&blob, Point2::origin(), 0.0, 10.0, 0.05, 50.0).unwrap();
        assert!((r - 10.0).abs() < 1e-12 && (w - 1.0).abs() < 1e-12);
        assert!(blob_echo(&blob, Point2::origin(), 0.5, 10.0, 0.05, 50.0).is_none());
        assert!(blob_echo(&blob, Point2::origin(), 0.0, 20.0, 0.05, 50.0).is_none());
        assert!(blob_echo(&blob, Point2::origin(), 0.0, 10.0, 0.05, 5.0).is_none());
    }

    #[test]
    fn spawn_rate_matches_the_process() {
        let traj = crate::sim::Trajectory::stationary(Se2::identity(), 0.0, 3600.0, 1.0).unwrap();
        let process = BlobProcess {
            rate_per_min: 2.0,
            mean_lifetime_s: 10.0,
            snr_db: 40.0,
            max_range_m: 50.0,
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let blobs = spawn_blobs(&traj, &process, &mut rng);
        // 120 expected, Poisson standard deviation ~11.
        assert!((80..160).contains(&blobs.len()), "{}", blobs.len());
        for b in &blobs {
            let r = b.centre.coords.norm();
            assert!((3.0..=40.0).contains(&r) && b.end_s > b.start_s && b.level <= 1e4);
        }
    }
}
