//! Weighted particles over SE(2): their mean and spread, and resampling by
//! KLD sampling (Fox, "Adapting the sample size in particle filters through
//! KLD-sampling", IJRR 2003), which draws particles until their number
//! bounds the Kullback-Leibler distance between the sample-based
//! approximation and the belief, given how many histogram bins the drawn
//! particles occupy: many when the belief is spread, few when it is
//! concentrated.

use echofield_graph::{Se2, wrap_angle};
use nalgebra::{Matrix3, Vector3};
use std::collections::HashSet;

/// One hypothesis of the vehicle's `world_from_vehicle` (map frame) and
/// its normalised weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Particle {
    pub pose: Se2,
    pub weight: f64,
}

/// The weighted mean pose (circular mean of the heading) and spread of a
/// particle set whose weights sum to 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Belief {
    pub mean: Se2,
    /// Square root of the trace of the weighted position covariance, m.
    pub spread_m: f64,
    /// Circular standard deviation of the heading, rad.
    pub heading_spread_rad: f64,
}

/// [`Belief`] of `particles` (weights summing to 1; an empty set gives the
/// identity with infinite spread).
pub fn belief(particles: &[Particle]) -> Belief {
    if particles.is_empty() {
        return Belief {
            mean: Se2::identity(),
            spread_m: f64::INFINITY,
            heading_spread_rad: f64::INFINITY,
        };
    }
    let (mut x, mut y, mut s, mut c) = (0.0, 0.0, 0.0, 0.0);
    for p in particles {
        x += p.weight * p.pose.x();
        y += p.weight * p.pose.y();
        let (sin, cos) = p.pose.theta().sin_cos();
        s += p.weight * sin;
        c += p.weight * cos;
    }
    let mut variance = 0.0;
    for p in particles {
        let (dx, dy) = (p.pose.x() - x, p.pose.y() - y);
        variance += p.weight * (dx * dx + dy * dy);
    }
    // Circular standard deviation sqrt(-2 ln R), R the mean resultant length.
    let r = (s * s + c * c).sqrt().clamp(1e-12, 1.0);
    Belief {
        mean: Se2::new(x, y, s.atan2(c)),
        spread_m: variance.max(0.0).sqrt(),
        heading_spread_rad: (-2.0 * r.ln()).max(0.0).sqrt(),
    }
}

/// The weighted covariance of `particles` about `mean` (their
/// [`Belief::mean`]) in `(x, y, θ)` (world frame, m² and rad²; headings
/// unwrapped about the mean): with the mean, the Gaussian that stands for
/// the cloud. Singular for a single pose (one particle, or all on one).
pub fn covariance(particles: &[Particle], mean: &Se2) -> Matrix3<f64> {
    let mut covariance = Matrix3::zeros();
    for p in particles {
        let d = offset(&p.pose, mean);
        covariance += p.weight * d * d.transpose();
    }
    covariance
}

/// `pose − mean` in `(x, y, θ)` (world frame, m and rad), the heading
/// wrapped to `(−π, π]`: the offset a Gaussian in those coordinates
/// ([`covariance`]) measures.
pub fn offset(pose: &Se2, mean: &Se2) -> Vector3<f64> {
    Vector3::new(
        pose.x() - mean.x(),
        pose.y() - mean.y(),
        wrap_angle(pose.theta() - mean.theta()),
    )
}

/// Sets the weights of `particles` from their log-weights (the largest
/// maps to 1 before normalising, so no exponential overflows); returns the
/// effective sample size `1 / Σ w²`.
pub fn set_weights(particles: &mut [Particle], log_weights: &[f64]) -> f64 {
    let max = log_weights
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(f64::NEG_INFINITY, f64::max);
    if !max.is_finite() {
        let w = 1.0 / particles.len().max(1) as f64;
        particles.iter_mut().for_each(|p| p.weight = w);
        return particles.len() as f64;
    }
    let mut sum = 0.0;
    for (p, &l) in particles.iter_mut().zip(log_weights) {
        p.weight *= if l.is_finite() { (l - max).exp() } else { 0.0 };
        sum += p.weight;
    }
    if sum <= 0.0 || !sum.is_finite() {
        let w = 1.0 / particles.len().max(1) as f64;
        particles.iter_mut().for_each(|p| p.weight = w);
        return particles.len() as f64;
    }
    let mut squares = 0.0;
    for p in particles.iter_mut() {
        p.weight /= sum;
        squares += p.weight * p.weight;
    }
    1.0 / squares
}

/// How KLD sampling bins and bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KldBounds {
    pub min_particles: usize,
    pub max_particles: usize,
    pub epsilon: f64,
    pub z: f64,
    pub bin_m: f64,
    pub bin_rad: f64,
}

impl KldBounds {
    /// Fox's bound: particles needed so that, with probability `1 - δ`
    /// (upper quantile `z`), the KL distance to a belief over `k` bins stays
    /// below `ε` (the Wilson-Hilferty approximation of the χ² quantile).
    pub fn needed(&self, k: usize) -> usize {
        if k < 2 {
            return self.min_particles;
        }
        let km1 = (k - 1) as f64;
        let a = 2.0 / (9.0 * km1);
        let n = km1 / (2.0 * self.epsilon) * (1.0 - a + a.sqrt() * self.z).powi(3);
        (n.ceil() as usize).clamp(self.min_particles, self.max_particles)
    }
}

/// Draws a new equally weighted set from `particles` (their weights sum
/// to one) by KLD sampling. `u0` in `[0, 1)` is the one random number
/// used: the draws are `u0 + j·φ mod 1` (φ the golden ratio's fractional
/// part), a low-discrepancy sequence that, like systematic resampling,
/// keeps a particle's copies close to `N·w`, yet needs no sample count
/// fixed in advance, which KLD sampling does not know until it stops.
pub fn kld_resample(particles: &[Particle], u0: f64, bounds: &KldBounds) -> Vec<Particle> {
    const PHI: f64 = 0.618_033_988_749_894_8;
    if particles.is_empty() {
        return Vec::new();
    }
    let mut cumulative = Vec::with_capacity(particles.len());
    let mut sum = 0.0;
    for p in particles {
        sum += p.weight.max(0.0);
        cumulative.push(sum);
    }
    let mut bins: HashSet<(i64, i64, i64)> = HashSet::new();
    let mut out = Vec::new();
    let mut u = u0.rem_euclid(1.0);
    while out.len() < bounds.max_particles {
        let target = u * sum;
        let i = cumulative
            .partition_point(|&c| c <= target)
            .min(particles.len() - 1);
        let pose = particles[i].pose;
        out.push(pose);
        bins.insert((
            (pose.x() / bounds.bin_m).floor() as i64,
            (pose.y() / bounds.bin_m).floor() as i64,
            (wrap_angle(pose.theta()) / bounds.bin_rad).floor() as i64,
        ));
        if out.len() >= bounds.needed(bins.len()) {
            break;
        }
        u = (u + PHI).fract();
    }
    let w = 1.0 / out.len() as f64;
    out.into_iter()
        .map(|pose| Particle { pose, weight: w })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bounds() -> KldBounds {
        KldBounds {
            min_particles: 50,
            max_particles: 5000,
            epsilon: 0.05,
            z: 2.326,
            bin_m: 0.5,
            bin_rad: 0.1745,
        }
    }

    #[test]
    fn the_covariance_of_a_cloud_is_weighted_about_its_mean() {
        // Two equally weighted particles at (±1, 0, ±0.1) and one of no
        // weight far away: mean at the origin, variances 1 (x) and 0.01
        // (θ), covariance of x and θ 0.1, nothing in y.
        let cloud = [
            Particle {
                pose: Se2::new(1.0, 0.0, 0.1),
                weight: 0.5,
            },
            Particle {
                pose: Se2::new(-1.0, 0.0, -0.1),
                weight: 0.5,
            },
            Particle {
                pose: Se2::new(50.0, 50.0, 3.0),
                weight: 0.0,
            },
        ];
        let mean = belief(&cloud).mean;
        assert!(mean.translation().norm() < 1e-12 && mean.theta().abs() < 1e-12);
        let c = covariance(&cloud, &mean);
        let expected = Matrix3::new(1.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.1, 0.0, 0.01);
        assert!((c - expected).norm() < 1e-12, "{c}");
        // One particle: no spread, no inverse.
        let one = &cloud[..1];
        assert!(covariance(one, &belief(one).mean).try_inverse().is_none());
    }

    #[test]
    fn the_bound_grows_with_the_occupied_bins() {
        let b = bounds();
        assert_eq!(b.needed(1), 50);
        // Fox 2003, Fig. 3 order of magnitude: ~100 bins need ~1300 samples
        // at ε = 0.05, δ = 0.01. The formula by hand for k = 100:
        // 99/0.1 · (1 - 0.002245 + 0.04738·2.326)^3 = 990 · 1.1080^3 = 1346.6.
        assert_eq!(b.needed(100), 1347);
        assert_eq!(b.needed(100_000), 5000);
    }

    #[test]
    fn a_concentrated_belief_keeps_few_particles_a_spread_one_many() {
        let concentrated: Vec<Particle> = (0..2000)
            .map(|i| Particle {
                pose: Se2::new(0.1 + 1e-5 * i as f64, 0.1, 0.05),
                weight: 1.0 / 2000.0,
            })
            .collect();
        assert_eq!(kld_resample(&concentrated, 0.3, &bounds()).len(), 50);
        let spread: Vec<Particle> = (0..2000)
            .map(|i| Particle {
                pose: Se2::new((i % 50) as f64, (i / 50) as f64, 0.0),
                weight: 1.0 / 2000.0,
            })
            .collect();
        let n = kld_resample(&spread, 0.3, &bounds()).len();
        assert!(n > 1000, "{n}");
    }

    #[test]
    fn resampling_copies_particles_in_proportion_to_their_weights() {
        let particles = [
            Particle {
                pose: Se2::new(0.0, 0.0, 0.0),
                weight: 0.75,
            },
            Particle {
                pose: Se2::new(10.0, 0.0, 0.0),
                weight: 0.25,
            },
        ];
        let b = KldBounds {
            min_particles: 400,
            ..bounds()
        };
        let out = kld_resample(&particles, 0.123, &b);
        assert_eq!(out.len(), 400);
        let near = out.iter().filter(|p| p.pose.x() < 5.0).count();
        // The golden-ratio sequence is within a few draws of 300 of 400.
        assert!((near as i64 - 300).abs() <= 3, "{near}");
    }

    #[test]
    fn the_belief_of_two_particles_and_weights_from_logs() {
        let mut particles = [
            Particle {
                pose: Se2::new(0.0, 0.0, 3.0),
                weight: 1.0,
            },
            Particle {
                pose: Se2::new(2.0, 0.0, -3.0),
                weight: 1.0,
            },
        ];
        let ess = set_weights(&mut particles, &[0.0, 0.0]);
        assert!((ess - 2.0).abs() < 1e-12);
        let b = belief(&particles);
        assert!((b.mean.x() - 1.0).abs() < 1e-12);
        assert!((b.spread_m - 1.0).abs() < 1e-12);
        // Headings 3 and -3 rad average across ±π, not to 0.
        assert!(b.mean.theta().abs() > 3.1, "{}", b.mean.theta());
        let ess = set_weights(&mut particles, &[0.0, f64::ln(3.0)]);
        assert!((particles[1].weight - 0.75).abs() < 1e-12);
        assert!((ess - 1.0 / (0.0625 + 0.5625)).abs() < 1e-12);
    }
}
