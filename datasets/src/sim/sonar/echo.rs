//! The echo of one surface hit: backscatter against incidence, transmission
//! loss against range, the range spread of the echo and its multipath ghosts.
//! All factors apply to echo energy.

use super::super::geometry::Material;

/// Exponent of the specular lobe: a smooth surface returns `cos^8` of the
/// incidence angle (down 3 dB at about 16 deg off normal).
const SPECULAR_EXPONENT: i32 = 8;

/// Backscattered energy of `material` at `incidence_rad`, relative to a
/// perfect reflector at normal incidence: a specular lobe `(1-ρ)·cos^8 α`
/// plus a diffuse Lambertian term `ρ·cos² α` (ρ = roughness), scaled by the
/// reflectivity.
pub fn backscatter(material: &Material, incidence_rad: f64) -> f64 {
    let c = incidence_rad.cos().max(0.0);
    let rough = material.roughness;
    material.reflectivity * ((1.0 - rough) * c.powi(SPECULAR_EXPONENT) + rough * c * c)
}

/// Two-way transmission loss remaining after the sonar's time-varied gain,
/// as an energy factor: `spreading_db_per_decade · log10(r / 1 m)` of
/// residual spreading plus `absorption_db_per_m · r` of absorption. Ranges
/// under 1 m count as 1 m.
pub fn transmission_factor(
    range_m: f64,
    spreading_db_per_decade: f64,
    absorption_db_per_m: f64,
) -> f64 {
    let r = range_m.max(1.0);
    let loss_db = spreading_db_per_decade * r.log10() + absorption_db_per_m * r;
    10f64.powf(-loss_db / 10.0)
}

/// Apparent ranges of the two surface-bounce multipath echoes of a target at
/// `range_m` seen by a sonar `depth_m` below a flat surface: the path that
/// goes out directly and returns via the surface (apparent range = half the
/// total path), and the path that goes both ways via the surface.
pub fn multipath_ranges_m(range_m: f64, depth_m: f64) -> [f64; 2] {
    let bounced = (range_m * range_m + 4.0 * depth_m * depth_m).sqrt();
    [0.5 * (range_m + bounced), bounced]
}

/// Adds a Gaussian echo of peak `amplitude` at `range_m` with standard
/// deviation `sigma_m` into `bins` (bin `i` centred at
/// `(i + 0.5)·bin_size_m`). Contributions further than 3σ are skipped.
pub fn deposit(bins: &mut [f64], bin_size_m: f64, range_m: f64, sigma_m: f64, amplitude: f64) {
    if amplitude <= 0.0 || bins.is_empty() {
        return;
    }
    let reach = 3.0 * sigma_m;
    let first = ((range_m - reach) / bin_size_m - 0.5).ceil().max(0.0) as usize;
    let last = ((range_m + reach) / bin_size_m - 0.5).floor();
    if last < 0.0 || first >= bins.len() {
        return;
    }
    let last = (last as usize).min(bins.len() - 1);
    let inv_two_var = 0.5 / (sigma_m * sigma_m);
    for (i, bin) in bins.iter_mut().enumerate().take(last + 1).skip(first) {
        let d = (i as f64 + 0.5) * bin_size_m - range_m;
        *bin += amplitude * (-d * d * inv_two_var).exp();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backscatter_is_reflectivity_at_normal_and_falls_with_incidence() {
        let m = Material {
            reflectivity: 0.8,
            roughness: 0.3,
        };
        assert!((backscatter(&m, 0.0) - 0.8).abs() < 1e-12);
        let at_60 = backscatter(&m, 60f64.to_radians());
        // 0.8 · (0.7 · 0.5^8 + 0.3 · 0.5²)
        assert!((at_60 - 0.8 * (0.7 / 256.0 + 0.075)).abs() < 1e-12);
        assert!(backscatter(&m, std::f64::consts::FRAC_PI_2) < 1e-12);
    }

    #[test]
    fn transmission_factor_matches_decibels() {
        // 10 dB/decade at 10 m plus 0.1 dB/m · 10 m = 11 dB.
        let f = transmission_factor(10.0, 10.0, 0.1);
        assert!((10.0 * f.log10() + 11.0).abs() < 1e-9);
        assert_eq!(transmission_factor(0.3, 10.0, 0.0), 1.0);
    }

    #[test]
    fn multipath_ghosts_lie_beyond_the_target() {
        let [one, two] = multipath_ranges_m(3.0, 2.0);
        assert!((two - 5.0).abs() < 1e-12); // 3-4-5 triangle
        assert!((one - 4.0).abs() < 1e-12);
    }

    #[test]
    fn deposit_peaks_in_the_bin_holding_the_range() {
        let mut bins = vec![0.0; 100];
        deposit(&mut bins, 0.1, 4.23, 0.05, 10.0);
        let peak = (0..100)
            .max_by(|&a, &b| bins[a].total_cmp(&bins[b]))
            .unwrap();
        assert_eq!(peak, 42);
        assert!(bins[42] > 9.0 && bins[42] <= 10.0);
        assert_eq!(bins[30], 0.0);
        // Off the ends: no panic, nothing written.
        deposit(&mut bins, 0.1, -5.0, 0.05, 10.0);
        deposit(&mut bins, 0.1, 50.0, 0.05, 10.0);
    }
}
