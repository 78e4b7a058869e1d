//! A local metric east/north frame about a geodetic origin.
//!
//! Equirectangular projection on the WGS84 ellipsoid, i.e. the local tangent
//! plane to first order: `north = M(φ0)·(φ − φ0)`, `east = N(φ0)·cos φ0·(λ − λ0)`
//! with the meridian radius `M = a(1 − e²)/(1 − e² sin²φ0)^{3/2}` and the
//! prime-vertical radius `N = a/√(1 − e² sin²φ0)`. Within 300 m of the origin
//! the neglected second-order terms stay below 1 cm, far under DGPS noise.

/// WGS84 semi-major axis, metres.
const WGS84_A_M: f64 = 6_378_137.0;
/// WGS84 first eccentricity squared.
const WGS84_E2: f64 = 6.694_379_990_14e-3;

/// The east/north frame about one origin fix (x east, y north, metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalTangentPlane {
    pub origin_latitude_deg: f64,
    pub origin_longitude_deg: f64,
    /// Metres per radian of latitude at the origin (M).
    meridian_radius_m: f64,
    /// Metres per radian of longitude at the origin (N cos φ0).
    parallel_radius_m: f64,
}

impl LocalTangentPlane {
    pub fn new(origin_latitude_deg: f64, origin_longitude_deg: f64) -> Self {
        let phi = origin_latitude_deg.to_radians();
        let s2 = phi.sin() * phi.sin();
        let w = 1.0 - WGS84_E2 * s2;
        Self {
            origin_latitude_deg,
            origin_longitude_deg,
            meridian_radius_m: WGS84_A_M * (1.0 - WGS84_E2) / (w * w.sqrt()),
            parallel_radius_m: WGS84_A_M / w.sqrt() * phi.cos(),
        }
    }

    /// `(east_m, north_m)` of a position in degrees.
    pub fn east_north_m(&self, latitude_deg: f64, longitude_deg: f64) -> (f64, f64) {
        let east =
            (longitude_deg - self.origin_longitude_deg).to_radians() * self.parallel_radius_m;
        let north = (latitude_deg - self.origin_latitude_deg).to_radians() * self.meridian_radius_m;
        (east, north)
    }
}

/// Converts an NMEA `ddmm.mmmm` (or `dddmm.mmmm`) value to decimal degrees.
/// Returns `None` when the minutes are not in [0, 60) or the value is negative.
pub fn nmea_to_degrees(ddmm: f64) -> Option<f64> {
    if ddmm.is_nan() || ddmm < 0.0 {
        return None;
    }
    let degrees = (ddmm / 100.0).floor();
    let minutes = ddmm - 100.0 * degrees;
    if !(0.0..60.0).contains(&minutes) {
        return None;
    }
    Some(degrees + minutes / 60.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nmea_examples_from_the_log_readme() {
        // 4212.225 = 42 deg 12.225 min; 306.2832 = 3 deg 6.2832 min.
        assert!((nmea_to_degrees(4212.225).unwrap() - (42.0 + 12.225 / 60.0)).abs() < 1e-12);
        // 6.2832 / 60 = 0.10472.
        assert!((nmea_to_degrees(306.2832).unwrap() - 3.10472).abs() < 1e-12);
        assert_eq!(nmea_to_degrees(4275.0), None);
        assert_eq!(nmea_to_degrees(-1.0), None);
    }

    #[test]
    fn one_minute_of_latitude_is_about_one_nautical_mile() {
        let plane = LocalTangentPlane::new(42.2, 3.1);
        let (e, n) = plane.east_north_m(42.2 + 1.0 / 60.0, 3.1);
        assert!(e.abs() < 1e-9);
        // Meridian arc of one minute at 42 deg N: 1851.8 m (1852 m nominal).
        assert!((n - 1851.8).abs() < 1.0, "{n}");
        // One minute of longitude shrinks by cos(latitude): 1376 m at 42.2 deg.
        let (e, _) = plane.east_north_m(42.2, 3.1 + 1.0 / 60.0);
        assert!((e - 1376.0).abs() < 2.0, "{e}");
    }
}
