//! The MSIS model: one beam of echo intensities from the environment, the
//! pose of the sonar head at the beam's time and the transducer angle.
//!
//! Per beam, in echo energy relative to the mean background noise:
//! 1. the horizontal beam (Gaussian two-way pattern, full width
//!    `beam_width_rad`) is sampled by `sub_rays` rays over ±`beam_width_rad`;
//!    each ray's first hit returns `10^(echo_snr_db/10) · w_j ·
//!    backscatter(α) · transmission(r)` ([`echo`]), spread in range by the
//!    pulse length and by the ray's footprint on an oblique surface, with a
//!    tail from the vertical beam reaching higher and lower parts of a wall;
//! 2. each hit also returns two weaker surface-bounce multipath ghosts at
//!    longer ranges;
//! 3. spurious blobs (fish, particles; [`blobs`]) add echoes that are not in
//!    the map;
//! 4. the echo is multiplied by speckle (Gamma-distributed with mean 1 and
//!    `speckle_looks` looks; 1 look is the exponential law of fully developed
//!    speckle), exponential background noise of mean 1 and isolated
//!    single-bin spikes are added, and the blind zone near the head holds
//!    transducer ringing instead of echoes;
//! 5. like the 8-bit output of common heads (a Tritech Miniking maps about
//!    80 dB onto 0-255), the energy is shown in decibels:
//!    `count = counts_per_db · (10·log10(E) − display_floor_db)`, rounded
//!    and clamped to 0-255. The log scale keeps weak oblique and distant
//!    walls visible next to strong normal-incidence ones.
//!
//! Typical counts with the defaults: background noise has median 5 and
//! 99.9th percentile 38; walls at 5-40 m peak at about 100-190 (concrete
//! at normal incidence near 180 at 10 m); fish blobs 90-140; spikes 60-140;
//! the ringing starts near 175 at the head and fades out by 1 m. A beam
//! segmenter that skips the blind zone and keeps peaks above ~70 finds the
//! walls and a few spurious echoes.

pub mod blobs;
pub mod echo;

use super::{Environment, SimError};
use blobs::{Blob, beam_pattern, blob_echo};
use echofield_graph::Se2;
use nalgebra::Point2;
use rand::Rng;
use rand_distr::{Distribution, Exp1, Gamma, Poisson};
use serde::{Deserialize, Serialize};

/// Sonar head settings and echo model. Defaults follow the Ictineu's
/// Tritech Miniking in the St Pere marina data set (200 steps per rotation,
/// 68 ms per beam, 500 bins of 0.1 m, 3 deg x 40 deg beam).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SonarSimConfig {
    /// Transducer steps per 360 deg rotation (200 = 1.8 deg per beam).
    pub steps_per_rotation: u32,
    /// Nominal time between beams, s.
    pub beam_period_s: f64,
    /// Each beam time is displaced from the nominal grid by a uniform draw
    /// in ±`beam_time_jitter_s`, s (the real head alternates 68 and 72 ms).
    pub beam_time_jitter_s: f64,
    /// Range bins per beam.
    pub bins: usize,
    /// Length of one bin, m.
    pub bin_size_m: f64,
    /// Horizontal two-way -3 dB beam width, rad.
    pub beam_width_rad: f64,
    /// Vertical beam width, rad: the echo of a wall gets a tail out to the
    /// range at which the edge of the vertical beam meets it.
    pub vertical_beam_width_rad: f64,
    /// Rays sampling the horizontal beam pattern (odd numbers keep one on axis).
    pub sub_rays: usize,
    /// Range resolution of the pulse, m: an echo spreads over a Gaussian of
    /// standard deviation half this length.
    pub pulse_length_m: f64,
    /// Echoes nearer than this range are lost in the transducer's ringing, m.
    pub blind_zone_m: f64,
    /// Ringing at the head relative to the mean noise, dB, falling linearly
    /// (in dB) to 0 dB at the end of the blind zone.
    pub ringing_snr_db: f64,
    /// Echo of a perfect reflector at normal incidence at 1 m relative to the
    /// mean noise, dB (source level, target gain and receiver gain in one).
    pub echo_snr_db: f64,
    /// Two-way spreading loss left after the time-varied gain, dB per decade
    /// of range.
    pub spreading_loss_db_per_decade: f64,
    /// Two-way absorption left after the time-varied gain, dB per metre.
    pub absorption_db_per_m: f64,
    /// A surface returns less as the incidence grows ([`echo::backscatter`];
    /// default on). Off: every surface returns its reflectivity at any
    /// incidence, so a wall is as bright seen obliquely as squarely. A
    /// diagnostic: with this, `footprint_lowers_peak` and both losses off,
    /// how bright a wall looks no longer depends on where it is seen from.
    pub backscatter_falls_with_incidence: bool,
    /// The echo of a sub-ray spread in range by its footprint on an oblique
    /// surface keeps its energy, so its peak falls as it widens (default
    /// on). Off: the peak stays that of a hit at normal incidence (a
    /// diagnostic, as `backscatter_falls_with_incidence`).
    pub footprint_lowers_peak: bool,
    /// Energy of the vertical-beam tail behind a wall echo relative to the
    /// echo peak, 0-1.
    pub echo_tail_gain: f64,
    /// Number of looks of the Gamma speckle (1 = exponential, larger = milder).
    pub speckle_looks: f64,
    /// Probability of an isolated spike in a bin (particles, interference);
    /// spikes are 15-40 dB above the mean noise.
    pub spike_probability: f64,
    /// Output counts per dB of echo energy.
    pub counts_per_db: f64,
    /// Energy relative to the mean noise shown as count 0, dB (lower values
    /// brighten the background).
    pub display_floor_db: f64,
    /// Depth of the sonar below the water surface, m; sets the ranges of the
    /// surface-bounce multipath ghosts.
    pub depth_m: f64,
    /// Energy of a multipath ghost per surface bounce relative to the direct
    /// echo, 0-1 (0 turns ghosts off).
    pub multipath_gain: f64,
    /// Spurious blobs (fish, bubbles) appearing per minute near the vehicle.
    pub blob_rate_per_min: f64,
    /// Mean life of a blob, s.
    pub blob_lifetime_s: f64,
    /// Peak echo of the strongest blobs relative to the mean noise, dB
    /// (others are up to 15 dB weaker).
    pub blob_snr_db: f64,
}

impl Default for SonarSimConfig {
    fn default() -> Self {
        Self {
            steps_per_rotation: 200,
            beam_period_s: 0.068,
            beam_time_jitter_s: 0.002,
            bins: 500,
            bin_size_m: 0.1,
            beam_width_rad: 3f64.to_radians(),
            vertical_beam_width_rad: 40f64.to_radians(),
            sub_rays: 9,
            pulse_length_m: 0.1,
            blind_zone_m: 1.0,
            ringing_snr_db: 55.0,
            echo_snr_db: 65.0,
            spreading_loss_db_per_decade: 10.0,
            absorption_db_per_m: 0.05,
            backscatter_falls_with_incidence: true,
            footprint_lowers_peak: true,
            echo_tail_gain: 0.05,
            speckle_looks: 4.0,
            spike_probability: 2e-4,
            counts_per_db: 3.2,
            display_floor_db: -3.0,
            depth_m: 2.0,
            multipath_gain: 0.02,
            blob_rate_per_min: 3.0,
            blob_lifetime_s: 20.0,
            blob_snr_db: 40.0,
        }
    }
}

impl SonarSimConfig {
    /// Far end of the last bin, m.
    pub fn max_range_m(&self) -> f64 {
        self.bins as f64 * self.bin_size_m
    }

    /// Angle the transducer turns between beams, rad.
    pub fn step_rad(&self) -> f64 {
        2.0 * std::f64::consts::PI / self.steps_per_rotation as f64
    }

    pub fn validate(&self) -> Result<(), SimError> {
        if !(4..=100_000).contains(&self.steps_per_rotation) {
            return Err(SimError::config(
                "sonar.steps_per_rotation",
                "must lie in [4, 100000]",
            ));
        }
        if !(1..=100_000).contains(&self.bins) {
            return Err(SimError::config("sonar.bins", "must lie in [1, 100000]"));
        }
        if !(1..=255).contains(&self.sub_rays) {
            return Err(SimError::config("sonar.sub_rays", "must lie in [1, 255]"));
        }
        super::config::check_ranges(&self.ranges())
    }

    /// Each real-valued setting with its name and allowed range
    /// `[min, max]`, for [`SonarSimConfig::validate`].
    fn ranges(&self) -> Vec<(&'static str, f64, f64, f64)> {
        let pi = std::f64::consts::PI;
        vec![
            ("sonar.beam_period_s", self.beam_period_s, 1e-4, 10.0),
            (
                "sonar.beam_time_jitter_s",
                self.beam_time_jitter_s,
                0.0,
                0.45 * self.beam_period_s,
            ),
            ("sonar.bin_size_m", self.bin_size_m, 1e-3, 10.0),
            ("sonar.beam_width_rad", self.beam_width_rad, 1e-4, pi / 4.0),
            (
                "sonar.vertical_beam_width_rad",
                self.vertical_beam_width_rad,
                0.0,
                0.99 * pi,
            ),
            ("sonar.pulse_length_m", self.pulse_length_m, 1e-3, 10.0),
            (
                "sonar.blind_zone_m",
                self.blind_zone_m,
                0.0,
                self.max_range_m(),
            ),
            ("sonar.ringing_snr_db", self.ringing_snr_db, 0.0, 200.0),
            ("sonar.echo_snr_db", self.echo_snr_db, 0.0, 200.0),
            (
                "sonar.spreading_loss_db_per_decade",
                self.spreading_loss_db_per_decade,
                0.0,
                80.0,
            ),
            (
                "sonar.absorption_db_per_m",
                self.absorption_db_per_m,
                0.0,
                10.0,
            ),
            ("sonar.echo_tail_gain", self.echo_tail_gain, 0.0, 1.0),
            ("sonar.speckle_looks", self.speckle_looks, 0.1, 1e6),
            ("sonar.spike_probability", self.spike_probability, 0.0, 0.1),
            ("sonar.counts_per_db", self.counts_per_db, 0.01, 255.0),
            (
                "sonar.display_floor_db",
                self.display_floor_db,
                -100.0,
                100.0,
            ),
            ("sonar.depth_m", self.depth_m, 0.0, 1e4),
            ("sonar.multipath_gain", self.multipath_gain, 0.0, 1.0),
            ("sonar.blob_rate_per_min", self.blob_rate_per_min, 0.0, 1e3),
            ("sonar.blob_lifetime_s", self.blob_lifetime_s, 1e-3, 1e5),
            ("sonar.blob_snr_db", self.blob_snr_db, 0.0, 200.0),
        ]
    }
}

/// A validated sonar configuration with its sub-ray fan precomputed.
#[derive(Clone, Debug)]
pub struct SonarModel {
    config: SonarSimConfig,
    /// `(offset from the beam axis in rad, normalised weight)` per sub-ray.
    sub_rays: Vec<(f64, f64)>,
    /// Angle each sub-ray stands for, rad.
    sub_ray_span_rad: f64,
    speckle: Gamma<f64>,
}

impl SonarModel {
    pub fn new(config: &SonarSimConfig) -> Result<Self, SimError> {
        config.validate()?;
        let n = config.sub_rays;
        let w = config.beam_width_rad;
        let offsets: Vec<f64> = if n == 1 {
            vec![0.0]
        } else {
            (0..n)
                .map(|j| -w + 2.0 * w * j as f64 / (n - 1) as f64)
                .collect()
        };
        let total: f64 = offsets.iter().map(|&o| beam_pattern(o, w)).sum();
        let sub_rays = offsets
            .iter()
            .map(|&o| (o, beam_pattern(o, w) / total))
            .collect();
        let sub_ray_span_rad = if n == 1 { w } else { 2.0 * w / (n - 1) as f64 };
        let looks = config.speckle_looks;
        let speckle = Gamma::new(looks, 1.0 / looks)
            .map_err(|e| SimError::config("sonar.speckle_looks", e.to_string()))?;
        Ok(Self {
            config: config.clone(),
            sub_rays,
            sub_ray_span_rad,
            speckle,
        })
    }

    pub fn config(&self) -> &SonarSimConfig {
        &self.config
    }

    /// Intensities of one beam fired at `stamp_s` from the sonar head at
    /// `world_from_sonar` with the transducer at `transducer_angle_rad`
    /// (counter-clockwise in the head frame).
    pub fn render_beam<R: Rng>(
        &self,
        env: &Environment,
        blobs: &[Blob],
        world_from_sonar: &Se2,
        transducer_angle_rad: f64,
        stamp_s: f64,
        rng: &mut R,
    ) -> Vec<u8> {
        let c = &self.config;
        let mut echo = vec![0.0; c.bins];
        let origin = Point2::new(world_from_sonar.x(), world_from_sonar.y());
        let bearing = world_from_sonar.theta() + transducer_angle_rad;
        let axis_hit = self.add_structure_echoes(&mut echo, env, origin, bearing);
        self.add_blob_echoes(&mut echo, blobs, origin, bearing, stamp_s, axis_hit);
        self.finish(echo, rng)
    }

    /// Direct echoes, vertical tails and multipath ghosts of every sub-ray's
    /// first hit. Returns the range of the on-axis hit (for blob occlusion).
    fn add_structure_echoes(
        &self,
        echo: &mut [f64],
        env: &Environment,
        origin: Point2<f64>,
        bearing: f64,
    ) -> f64 {
        let c = &self.config;
        let max_range = c.max_range_m();
        let sigma0 = 0.5 * c.pulse_length_m;
        let tail_stretch = 1.0 / (0.5 * c.vertical_beam_width_rad).cos() - 1.0;
        let mut axis_hit = f64::INFINITY;
        for &(offset, weight) in &self.sub_rays {
            let Some(hit) = env.cast_ray(origin, bearing + offset, max_range) else {
                continue;
            };
            if offset.abs() < 0.5 * self.sub_ray_span_rad {
                axis_hit = hit.range_m;
            }
            if hit.range_m < c.blind_zone_m {
                continue;
            }
            let material = &env.segments()[hit.segment].material;
            let backscatter = if c.backscatter_falls_with_incidence {
                echo::backscatter(material, hit.incidence_rad)
            } else {
                material.reflectivity
            };
            let amplitude = 10f64.powf(c.echo_snr_db / 10.0)
                * weight
                * backscatter
                * echo::transmission_factor(
                    hit.range_m,
                    c.spreading_loss_db_per_decade,
                    c.absorption_db_per_m,
                );
            // The ray stands for a slice of the beam whose footprint on an
            // oblique wall spans r·Δφ·tan α in range.
            let tan_incidence = hit.incidence_rad.min(85f64.to_radians()).tan();
            let footprint = 0.5 * hit.range_m * self.sub_ray_span_rad * tan_incidence;
            let sigma = (sigma0 * sigma0 + footprint * footprint).sqrt();
            let peak = if c.footprint_lowers_peak {
                amplitude * sigma0 / sigma
            } else {
                amplitude
            };
            echo::deposit(echo, c.bin_size_m, hit.range_m, sigma, peak);
            deposit_tail(
                echo,
                c.bin_size_m,
                hit.range_m,
                hit.range_m * tail_stretch,
                peak * c.echo_tail_gain,
            );
            if c.multipath_gain > 0.0 {
                let [once, twice] = echo::multipath_ranges_m(hit.range_m, c.depth_m);
                echo::deposit(echo, c.bin_size_m, once, sigma, peak * c.multipath_gain);
                let twice_gain = c.multipath_gain * c.multipath_gain;
                echo::deposit(echo, c.bin_size_m, twice, sigma, peak * twice_gain);
            }
        }
        axis_hit
    }

    fn add_blob_echoes(
        &self,
        echo: &mut [f64],
        blobs: &[Blob],
        origin: Point2<f64>,
        bearing: f64,
        stamp_s: f64,
        axis_hit_m: f64,
    ) {
        let c = &self.config;
        let max_range = c.max_range_m().min(axis_hit_m);
        for blob in blobs {
            if let Some((range, weight)) =
                blob_echo(blob, origin, bearing, stamp_s, c.beam_width_rad, max_range)
                && range >= c.blind_zone_m
            {
                let sigma = (0.5 * blob.radius_m).max(0.5 * c.pulse_length_m);
                echo::deposit(echo, c.bin_size_m, range, sigma, blob.level * weight);
            }
        }
    }

    /// Speckle, noise, spikes, ringing and the decibel display.
    fn finish<R: Rng>(&self, mut energy: Vec<f64>, rng: &mut R) -> Vec<u8> {
        let c = &self.config;
        for value in energy.iter_mut() {
            if *value > 1e-3 {
                *value *= self.speckle.sample(rng);
            }
            let noise: f64 = Exp1.sample(rng);
            *value += noise;
        }
        let expected_spikes = c.spike_probability * c.bins as f64;
        if expected_spikes > 0.0 {
            let count = Poisson::new(expected_spikes).map_or(0.0, |p| p.sample(rng)) as usize;
            for _ in 0..count {
                let bin = rng.random_range(0..c.bins);
                energy[bin] += 10f64.powf(rng.random_range(1.5..4.0));
            }
        }
        for (i, value) in energy.iter_mut().enumerate() {
            let r = (i as f64 + 0.5) * c.bin_size_m;
            if r >= c.blind_zone_m {
                break;
            }
            *value += 10f64.powf(0.1 * c.ringing_snr_db * (1.0 - r / c.blind_zone_m));
        }
        energy
            .iter()
            .map(|&e| {
                (c.counts_per_db * (10.0 * e.log10() - c.display_floor_db))
                    .round()
                    .clamp(0.0, 255.0) as u8
            })
            .collect()
    }
}

/// The vertical-beam tail: a linear ramp from `peak` just behind `range_m`
/// down to zero `length_m` further.
fn deposit_tail(echo: &mut [f64], bin_size_m: f64, range_m: f64, length_m: f64, peak: f64) {
    if length_m <= bin_size_m || peak <= 0.0 {
        return;
    }
    let first = (range_m / bin_size_m + 0.5).ceil() as usize;
    let last = (((range_m + length_m) / bin_size_m - 0.5).floor() as usize)
        .min(echo.len().saturating_sub(1));
    for (i, bin) in echo.iter_mut().enumerate().take(last + 1).skip(first) {
        let behind = (i as f64 + 0.5) * bin_size_m - range_m;
        *bin += peak * (1.0 - behind / length_m).max(0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{EnvironmentBuilder, Material};

    /// The bin in which the ray of [`peak_on_oblique_wall`] meets the wall.
    const WALL_BIN: usize = 100;

    /// The incidence of that ray on the wall, radians.
    fn incidence() -> f64 {
        60f64.to_radians()
    }

    /// The range at which the ray meets the wall, m: the centre of
    /// [`WALL_BIN`], where a deposit's Gaussian peaks in full.
    fn wall_range_m(config: &SonarSimConfig) -> f64 {
        (WALL_BIN as f64 + 0.5) * config.bin_size_m
    }

    /// The echo energy in [`WALL_BIN`] of one on-axis ray that meets a
    /// concrete wall at [`wall_range_m`] with [`incidence`], without
    /// losses or ghosts (the vertical tail starts one bin behind).
    fn peak_on_oblique_wall(config: SonarSimConfig) -> f64 {
        let range = wall_range_m(&config);
        let mut b = EnvironmentBuilder::new();
        // The wall y = d, whose normal is the y axis; a ray from the
        // origin at the complement of the incidence above x meets it at
        // `range`.
        let d = range * incidence().cos();
        b.segment([-100.0, d], [100.0, d], Material::CONCRETE);
        let env = b.build("wall").unwrap();
        let model = SonarModel::new(&SonarSimConfig {
            sub_rays: 1,
            spreading_loss_db_per_decade: 0.0,
            absorption_db_per_m: 0.0,
            multipath_gain: 0.0,
            ..config
        })
        .unwrap();
        let mut echo = vec![0.0; model.config().bins];
        let bearing = std::f64::consts::FRAC_PI_2 - incidence();
        model.add_structure_echoes(&mut echo, &env, Point2::origin(), bearing);
        echo[WALL_BIN]
    }

    #[test]
    fn the_viewpoint_free_echo_switches_keep_an_oblique_wall_as_bright_as_a_square_one() {
        let c = SonarSimConfig::default();
        let source = 10f64.powf(c.echo_snr_db / 10.0);
        let concrete = Material::CONCRETE;
        // Default: the backscatter law at the incidence, and the peak
        // lowered by the footprint's spread r·w·tan α / 2 (one ray spans
        // the whole width w).
        let sigma0 = 0.5 * c.pulse_length_m;
        let footprint = 0.5 * wall_range_m(&c) * c.beam_width_rad * incidence().tan();
        let spread = sigma0 / (sigma0 * sigma0 + footprint * footprint).sqrt();
        let want = source * echo::backscatter(&concrete, incidence()) * spread;
        let got = peak_on_oblique_wall(c.clone());
        assert!((got / want - 1.0).abs() < 1e-9, "{got} against {want}");
        // Both off: the reflectivity alone, as at normal incidence.
        let flat = peak_on_oblique_wall(SonarSimConfig {
            backscatter_falls_with_incidence: false,
            footprint_lowers_peak: false,
            ..c
        });
        let want = source * concrete.reflectivity;
        assert!((flat / want - 1.0).abs() < 1e-9, "{flat} against {want}");
    }
}
