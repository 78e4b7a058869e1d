//! How well the attitude unit's yaw rates agree with its headings, measured
//! on the records before filtering (`yaw_rate_check_window_s`).
//!
//! The filter weighs the two with `heading_noise_rad` and
//! `yaw_rate_noise_radps`, both white per sample. A gyro with a bias, a
//! scale error or a wandering error breaks that model: the filter then
//! trusts the rate's integral where it drifts, and the filtered heading
//! falls behind or runs ahead of the measured one in every turn, distorting
//! those rotations' scans and images. The real St Pere MTi is such a unit
//! (EXPERIMENTS.md § Dead reckoning).
//!
//! Over consecutive windows of about `T` seconds the heading change is
//! compared with the trapezoid integral of the rates, `e = Δψ − ∫ r dt`:
//!
//! - white heading noise of standard deviation `σ_ψ` per sample adds
//!   `2 σ_ψ²` to `E[e²]` whatever the window; it is read from one-sample
//!   windows, where the integral's own error is negligible
//!   (`σ_ψ² = mean(e₁²) / 2`, slightly high, which only makes `σ_r` below
//!   lower);
//! - white rate noise of standard deviation `σ_r` per sample, at the
//!   sample interval `Δt`, adds `σ_r² Δt T`.
//!
//! So `σ_r² = (mean(e_T²) − 2 σ_ψ²) / (Δt T)`: the white rate noise that
//! explains the disagreement seen over `T`. A bias or a scale error is
//! counted as the white noise that would disagree as much over `T`.
//!
//! Where the heading noise dominates (the simulated units: 0.5° per
//! sample against 0.2°/s of rate noise, which adds 2% to `e²` over one
//! second) the difference is mostly the sampling error of `mean(e_T²)`.
//! So the estimate is a lower confidence bound: the excess is reduced by
//! three standard errors of that mean (`sd(e_T²) / √windows`), and a unit
//! whose disagreement is within them gets 0. The filter uses the larger of
//! this and the configured `yaw_rate_noise_radps` (a floor, as for the
//! DVL noise adaptation), so a consistent unit is filtered exactly as
//! configured (what it finds on real and simulated units: EXPERIMENTS.md § Dead
//! reckoning).
//!
//! A window holds `round(T / Δt)` sample intervals, at least one. A unit
//! sampled every `T` seconds or more slowly has one-interval windows only:
//! the two noises cannot be told apart there, and the check gives 0 (the
//! configured noise is used).

use crate::sensors::Attitude;
use echofield_graph::se2::wrap_angle;
use serde::{Deserialize, Serialize};

/// Fewest windows of each length for an estimate.
const MIN_WINDOWS: usize = 20;

/// Standard errors of `mean(e_T²)` taken off the excess (see the module
/// doc).
const CONFIDENCE_SIGMAS: f64 = 3.0;

/// A window is not used across a gap between attitude samples longer than
/// this many median sample intervals.
const MAX_GAP_INTERVALS: f64 = 3.0;

/// What [`check`] measured.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct YawRateCheck {
    /// Median interval between attitude samples, s.
    pub sample_interval_s: f64,
    /// White heading noise per sample, rad.
    pub heading_noise_rad: f64,
    /// Root mean square of `e` over the windows of `window_s`, rad.
    pub disagreement_rad: f64,
    /// The white yaw-rate noise per sample that explains it (its lower
    /// confidence bound), rad/s.
    pub yaw_rate_noise_radps: f64,
}

/// Compares headings and yaw rates over windows of `window_s` seconds.
/// `None` when fewer than `MIN_WINDOWS` (20) windows (of one sample and of
/// `window_s`) have a yaw rate at every sample and no gap, e.g. a unit
/// without yaw rates. `attitude` is in time order (checked by the filter).
pub fn check(attitude: &[Attitude], window_s: f64) -> Option<YawRateCheck> {
    let dt = median_interval(attitude)?;
    let steps = step_disagreements(attitude, MAX_GAP_INTERVALS * dt);
    let one: Vec<f64> = steps.iter().flatten().map(|(_, e)| e * e).collect();
    if one.len() < MIN_WINDOWS {
        return None;
    }
    let heading_var = 0.5 * one.iter().sum::<f64>() / one.len() as f64;
    // ... summed over consecutive windows of about `window_s`.
    let per_window = ((window_s / dt).round() as usize).max(1);
    let windows = WindowMoments::of(&steps, per_window);
    if windows.count < MIN_WINDOWS {
        return None;
    }
    let n = windows.count as f64;
    let mean_e2 = windows.sum_e2 / n;
    let standard_error = ((windows.sum_e4 / n - mean_e2 * mean_e2).max(0.0) / n).sqrt();
    let excess = mean_e2 - 2.0 * heading_var - CONFIDENCE_SIGMAS * standard_error;
    let rate_var = excess.max(0.0) / (dt * windows.sum_span / n);
    Some(YawRateCheck {
        sample_interval_s: dt,
        heading_noise_rad: heading_var.sqrt(),
        disagreement_rad: mean_e2.sqrt(),
        yaw_rate_noise_radps: rate_var.sqrt(),
    })
}

/// The median of the positive intervals between attitude samples, s;
/// `None` with fewer than `MIN_WINDOWS` of them.
fn median_interval(attitude: &[Attitude]) -> Option<f64> {
    let mut intervals: Vec<f64> = attitude
        .windows(2)
        .map(|w| w[1].stamp_s - w[0].stamp_s)
        .filter(|dt| *dt > 0.0)
        .collect();
    if intervals.len() < MIN_WINDOWS {
        return None;
    }
    let mid = intervals.len() / 2;
    Some(*intervals.select_nth_unstable_by(mid, f64::total_cmp).1)
}

/// The disagreement `e` of each sample interval with its span, s (`None`
/// across a gap longer than `max_gap_s` or where a rate is missing): the
/// heading change less the trapezoidal integral of the yaw rates, rad.
fn step_disagreements(attitude: &[Attitude], max_gap_s: f64) -> Vec<Option<(f64, f64)>> {
    attitude
        .windows(2)
        .map(|w| {
            let span = w[1].stamp_s - w[0].stamp_s;
            let (a, b) = (w[0].yaw_rate_radps?, w[1].yaw_rate_radps?);
            (span > 0.0 && span <= max_gap_s).then(|| {
                (
                    span,
                    wrap_angle(w[1].yaw_rad - w[0].yaw_rad) - 0.5 * (a + b) * span,
                )
            })
        })
        .collect()
}

/// Sums over the complete windows of `per_window` consecutive steps (those
/// without a missing step) of the window's disagreement `e`: Σe², Σe⁴, the
/// summed spans (s) and the window count.
struct WindowMoments {
    sum_e2: f64,
    sum_e4: f64,
    sum_span: f64,
    count: usize,
}

impl WindowMoments {
    fn of(steps: &[Option<(f64, f64)>], per_window: usize) -> Self {
        let (mut sum_e2, mut sum_e4, mut sum_span, mut count) = (0.0, 0.0, 0.0, 0usize);
        for chunk in steps.chunks_exact(per_window) {
            let Some((span, e)) = chunk.iter().try_fold((0.0, 0.0), |(s, e), step| {
                step.map(|(ds, de)| (s + ds, e + de))
            }) else {
                continue;
            };
            sum_e2 += e * e;
            sum_e4 += e.powi(4);
            sum_span += span;
            count += 1;
        }
        Self {
            sum_e2,
            sum_e4,
            sum_span,
            count,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// A unit turning at 0.05 rad/s, sampled at 10 Hz for 600 s: heading
    /// noise `heading_sigma`, rate noise `rate_sigma`, rate bias `bias`.
    fn records(heading_sigma: f64, rate_sigma: f64, bias: f64, seed: u64) -> Vec<Attitude> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (h, r) = (
            Normal::new(0.0, heading_sigma).unwrap(),
            Normal::new(0.0, rate_sigma).unwrap(),
        );
        (0..6000)
            .map(|i| {
                let t = i as f64 * 0.1;
                Attitude {
                    stamp_s: 100.0 + t,
                    roll_rad: 0.0,
                    pitch_rad: 0.0,
                    yaw_rad: wrap_angle(0.05 * t + h.sample(&mut rng)),
                    yaw_rate_radps: Some(0.05 + bias + r.sample(&mut rng)),
                }
            })
            .collect()
    }

    #[test]
    fn a_consistent_unit_shows_its_own_noise() {
        // The simulator's unit: 0.5° heading noise, 0.2°/s rate noise.
        let (sigma_h, sigma_r) = (0.5_f64.to_radians(), 0.2_f64.to_radians());
        let c = check(&records(sigma_h, sigma_r, 0.0, 1), 1.0).unwrap();
        assert!((c.sample_interval_s - 0.1).abs() < 1e-9);
        assert!((c.heading_noise_rad / sigma_h - 1.0).abs() < 0.05, "{c:?}");
        // The rate noise hides under the heading noise (its share of e² is
        // 2% over one second, within the sampling error): the bound is
        // below the filter's 0.01 rad/s default.
        assert!(c.yaw_rate_noise_radps < 0.01, "{c:?}");
    }

    #[test]
    fn a_noisy_gyro_beside_a_precise_compass_is_measured() {
        // 600 one-second windows: e² has a relative standard error of
        // √(2/600) = 6%, so the lower bound sits about 9% under σ_r, and
        // 5% more for the rate noise read as heading noise (below).
        let sigma_r = 0.05;
        let c = check(&records(0.0005, sigma_r, 0.0, 2), 1.0).unwrap();
        let ratio = c.yaw_rate_noise_radps / sigma_r;
        assert!((0.8..1.05).contains(&ratio), "{c:?}");
        // One step's trapezoid holds rate noise of variance σ_r² Δt² / 2,
        // read as heading noise: σ_ψ² + σ_r² Δt² / 4.
        let want = (0.0005_f64.powi(2) + (sigma_r * 0.1_f64).powi(2) / 4.0).sqrt();
        assert!((c.heading_noise_rad / want - 1.0).abs() < 0.1, "{c:?}");
    }

    #[test]
    fn a_bias_counts_as_the_noise_that_disagrees_as_much_over_the_window() {
        // Over T the bias b gives e = b T exactly (no noise, so no
        // standard error), which white noise matches when σ_r² Δt T =
        // b² T², i.e. σ_r = b √(T / Δt). The one-sample windows read the
        // bias as heading noise, b² Δt² = 2 σ_ψ², and take it off:
        // σ_r = b √((T² − Δt²) / (Δt T)).
        let (b, dt) = (0.01, 0.1_f64);
        for window_s in [0.5_f64, 1.0, 2.0] {
            let c = check(&records(0.0, 0.0, b, 3), window_s).unwrap();
            let want = b * ((window_s.powi(2) - dt * dt) / (dt * window_s)).sqrt();
            assert!(
                (c.yaw_rate_noise_radps / want - 1.0).abs() < 1e-6,
                "{window_s}: {c:?}"
            );
        }
    }

    #[test]
    fn a_unit_sampled_no_faster_than_the_window_gets_the_configured_noise() {
        // 1 Hz samples and 1 s windows: even a 0.01 rad/s bias, which at
        // 10 Hz reads as 0.03 rad/s, is indistinguishable from heading
        // noise.
        let slow: Vec<Attitude> = records(0.0, 0.0, 0.01, 7).into_iter().step_by(10).collect();
        let c = check(&slow, 1.0).unwrap();
        assert!((c.sample_interval_s - 1.0).abs() < 1e-9, "{c:?}");
        assert_eq!(c.yaw_rate_noise_radps, 0.0, "{c:?}");
    }

    #[test]
    fn no_estimate_without_rates_or_with_too_few_samples() {
        let mut a = records(0.01, 0.01, 0.0, 4);
        assert!(check(&a[..10], 1.0).is_none());
        for s in &mut a {
            s.yaw_rate_radps = None;
        }
        assert!(check(&a, 1.0).is_none());
    }

    #[test]
    fn windows_do_not_span_gaps_or_missing_rates() {
        // A rate missing at every 5th sample leaves no complete 1 s
        // window, and one-sample windows only where both ends have one.
        let mut a = records(0.0, 0.0, 0.0, 5);
        for s in a.iter_mut().step_by(5) {
            s.yaw_rate_radps = None;
        }
        assert!(check(&a, 1.0).is_none());
        // A 30 s gap with a 1 rad jump across it: not a disagreement.
        let mut b = records(0.0, 0.0, 0.0, 6);
        for s in b.iter_mut().skip(3000) {
            s.stamp_s += 30.0;
            s.yaw_rad = wrap_angle(s.yaw_rad + 1.0);
        }
        let c = check(&b, 1.0).unwrap();
        assert!(
            c.disagreement_rad < 1e-9 && c.yaw_rate_noise_radps < 1e-9,
            "{c:?}"
        );
    }
}
