//! Covariance of a match from the shape of the score surface.
//!
//! The score `s` of eq. (5) on the raster is evaluated on a 5 x 5 x 5 lattice around the
//! estimate `x*` (steps: one cell in x and y, and the angle that moves a
//! point at the scan's RMS range by one cell), and a full quadratic
//! `s(x* + δ) ≈ c + gᵀδ + ½ δᵀ H δ` is fitted by least squares. Reading
//! `exp(s(x) / τ)` as the likelihood of the pose (`τ` is
//! `MatcherConfig::covariance_scale`, intensity units), the Laplace
//! approximation gives the covariance `Σ = τ (-H)⁻¹`. Because `s` sums `N`
//! per-point terms, `Σ` shrinks like `1/N`, as for independent measurements.
//!
//! Directions in which the surface is flat or curves upwards (a corridor, a
//! single wall, a saddle) are clamped: their variance is at most the squared
//! half-width of the search window, i.e. the match adds no information
//! there beyond the prior's window. The clamp works on eigenvalues in the
//! lattice-normalised coordinates (each axis divided by its step), where
//! metres and radians are commensurable.

use crate::image::{CellValue, Grid};
use echofield_graph::Se2;
use nalgebra::{Cholesky, Const, Matrix3, Point2, SMatrix, SVector, Vector3};
use std::sync::OnceLock;

/// The fitted surface and the covariance derived from it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceFit {
    /// Hessian of `s` at the estimate, in (x m, y m, θ rad) units.
    pub hessian: Matrix3<f64>,
    /// Covariance of `(x, y, θ)`, m² and rad².
    pub covariance: Matrix3<f64>,
    /// RMS residual of the quadratic fit relative to the score's range over
    /// the lattice (0 = perfectly quadratic).
    pub relative_fit_residual: f64,
    /// The fitted quadratic's peak relative to the lattice centre, `(x m,
    /// y m, θ rad)` (added to the pose's vector form): the Newton step
    /// `-H⁻¹ g` over the directions the surface constrains (information
    /// above the window clamp), zero along the others, shortened to stay
    /// within one lattice step per axis.
    pub peak_offset: Vector3<f64>,
}

/// Fits the quadratic to the score on `grid` around `pose` and derives the
/// covariance.
///
/// The lattice steps are one raster cell in x and y and `angle_step_rad`
/// in θ, and `radius` the lattice's half-size in steps (2 for the
/// covariance: 5 x 5 x 5 samples, at most
/// [`MAX_SHIFT_RADIUS`](crate::image::grid::MAX_SHIFT_RADIUS)); `window`
/// the search half-widths `(m, m, rad)` that bound the variance; `tau` the
/// scale. Because the translation steps are whole cells, the scores of one
/// angle share every point's fractional cell position
/// ([`Grid::add_bilinear_shifts`](crate::image::Grid::add_bilinear_shifts)).
pub fn fit_surface<T: CellValue>(
    points: &[Point2<f64>],
    grid: &Grid<T>,
    pose: &Se2,
    angle_step_rad: f64,
    radius: usize,
    window: &Vector3<f64>,
    tau: f64,
) -> SurfaceFit {
    let cell_m = grid.cell_size_m();
    let steps = Vector3::new(cell_m, cell_m, angle_step_rad);
    let radius = radius.clamp(1, crate::image::grid::MAX_SHIFT_RADIUS);
    let lattice = Lattice::of_radius(radius);
    let sampled = sample_lattice(points, grid, pose, angle_step_rad, radius, lattice);
    let beta = lattice.normal.solve(&sampled.rhs);
    let inner = lattice.inner_normal.solve(&sampled.inner_rhs);
    // Hessian in normalised coordinates: s = ... + β4 u1² + ... + β7 u1u2 ...
    let hn = hessian_n(&beta);
    let scale = Matrix3::from_diagonal(&steps.map(|s| 1.0 / s));
    // No direction may have a variance larger than the window.
    let window_n = window.component_div(&steps).max();
    let min_information = 1.0 / (window_n * window_n);
    let covariance = laplace_covariance(&hn, &steps, min_information, tau);
    SurfaceFit {
        hessian: scale * hn * scale,
        covariance: 0.5 * (covariance + covariance.transpose()),
        relative_fit_residual: relative_fit_residual(lattice, &sampled.scores, &beta),
        peak_offset: peak_offset_n(&inner, min_information, tau).component_mul(&steps),
    }
}

/// The scores of a fit's lattice and the right-hand sides of its two
/// least-squares fits (whole lattice, inner nodes).
struct LatticeSamples {
    scores: Vec<f64>,
    rhs: SVector<f64, 10>,
    inner_rhs: SVector<f64, 10>,
}

/// The raster score of `points` at every node of `lattice` (radius
/// `radius`) around `pose`, in the lattice's node order.
fn sample_lattice<T: CellValue>(
    points: &[Point2<f64>],
    grid: &Grid<T>,
    pose: &Se2,
    angle_step_rad: f64,
    radius: usize,
    lattice: &Lattice,
) -> LatticeSamples {
    let n = 2 * radius + 1;
    let r = radius as i32;
    let mut out = LatticeSamples {
        scores: Vec::with_capacity(n * n * n),
        rhs: SVector::zeros(),
        inner_rhs: SVector::zeros(),
    };
    let mut sums = vec![0.0; n * n];
    for c in -r..=r {
        let (sin, cos) = (pose.theta() + f64::from(c) * angle_step_rad).sin_cos();
        sums.fill(0.0);
        for p in points {
            let x = cos * p.x - sin * p.y + pose.x();
            let y = sin * p.x + cos * p.y + pose.y();
            grid.add_bilinear_shifts(x, y, radius, &mut sums);
        }
        // `sums` is in row-major order of (b, a), as the lattice's nodes of
        // this c.
        for &s in &sums {
            let node = &lattice.nodes[out.scores.len()];
            out.rhs += node.features * s;
            if node.inner {
                out.inner_rhs += node.features * s;
            }
            out.scores.push(s);
        }
    }
    out
}

/// RMS residual of the quadratic `beta` over the lattice's scores,
/// relative to their range (0 for a flat surface).
fn relative_fit_residual(lattice: &Lattice, scores: &[f64], beta: &SVector<f64, 10>) -> f64 {
    let (mut lo, mut hi, mut sq) = (f64::MAX, f64::MIN, 0.0);
    for (node, s) in lattice.nodes.iter().zip(scores) {
        let r = s - node.features.dot(beta);
        sq += r * r;
        lo = lo.min(*s);
        hi = hi.max(*s);
    }
    if hi > lo {
        (sq / scores.len() as f64).sqrt() / (hi - lo)
    } else {
        0.0
    }
}

/// The Laplace covariance (m², rad²) from the normalised Hessian `hn`:
/// information `-hn / tau` in normalised coordinates, eigenvalues clamped
/// at `min_information`, scaled back by the lattice `steps`. Not yet
/// symmetrised.
fn laplace_covariance(
    hn: &Matrix3<f64>,
    steps: &Vector3<f64>,
    min_information: f64,
    tau: f64,
) -> Matrix3<f64> {
    let info = -hn / tau;
    let eig = info.symmetric_eigen();
    let inv_values = eig.eigenvalues.map(|l| 1.0 / l.max(min_information));
    let cov_n =
        eig.eigenvectors * Matrix3::from_diagonal(&inv_values) * eig.eigenvectors.transpose();
    let step_diag = Matrix3::from_diagonal(steps);
    step_diag * cov_n * step_diag
}

/// The peak of the inner fit `inner`, in lattice steps: `u* = (-H)⁻¹ g`
/// on the eigen-directions whose information exceeds `min_information`
/// only (`-H = τ · info`), scaled back to at most one step on the largest
/// axis.
fn peak_offset_n(inner: &SVector<f64, 10>, min_information: f64, tau: f64) -> Vector3<f64> {
    let gradient_n = Vector3::new(inner[1], inner[2], inner[3]);
    let inner_eig = (-hessian_n(inner)).symmetric_eigen();
    let mut peak_n = Vector3::zeros();
    for (i, &l) in inner_eig.eigenvalues.iter().enumerate() {
        if l / tau > min_information {
            let v = inner_eig.eigenvectors.column(i);
            peak_n += v * (v.dot(&gradient_n) / l);
        }
    }
    let reach = peak_n.amax();
    if reach > 1.0 {
        peak_n /= reach;
    }
    peak_n
}

/// The sampling lattice of [`fit_surface`] for one radius: every node's
/// features in the order the scores are computed (`c`, then `b`, then `a`,
/// each from `-r` to `r`), and the factored normal matrices of the
/// least-squares fits over the whole lattice and over its inner 3 x 3 x 3
/// nodes. They depend on the radius alone, so they are built once.
struct Lattice {
    nodes: Vec<LatticeNode>,
    normal: Cholesky<f64, Const<10>>,
    inner_normal: Cholesky<f64, Const<10>>,
}

struct LatticeNode {
    features: SVector<f64, 10>,
    /// Within one step of the centre on every axis.
    inner: bool,
}

impl Lattice {
    /// The lattice of `radius` (1 to
    /// [`MAX_SHIFT_RADIUS`](crate::image::grid::MAX_SHIFT_RADIUS)).
    fn of_radius(radius: usize) -> &'static Self {
        static LATTICES: [OnceLock<Lattice>; crate::image::grid::MAX_SHIFT_RADIUS] =
            [const { OnceLock::new() }; crate::image::grid::MAX_SHIFT_RADIUS];
        LATTICES[radius - 1].get_or_init(|| Self::build(radius as i32))
    }

    fn build(r: i32) -> Self {
        let mut nodes = Vec::new();
        let mut normal = SMatrix::<f64, 10, 10>::zeros();
        let mut inner_normal = normal;
        for c in -r..=r {
            for b in -r..=r {
                for a in -r..=r {
                    let features =
                        features(&Vector3::new(f64::from(a), f64::from(b), f64::from(c)));
                    let inner = a.abs() <= 1 && b.abs() <= 1 && c.abs() <= 1;
                    normal += features * features.transpose();
                    if inner {
                        inner_normal += features * features.transpose();
                    }
                    nodes.push(LatticeNode { features, inner });
                }
            }
        }
        // The lattices are symmetric and full (at least 3 nodes per axis),
        // so both normal matrices are positive definite.
        let factor =
            |m: SMatrix<f64, 10, 10>| m.cholesky().expect("a full lattice's normal matrix");
        Self {
            nodes,
            normal: factor(normal),
            inner_normal: factor(inner_normal),
        }
    }
}

/// The Hessian of the fitted quadratic (coefficients as [`features`]).
fn hessian_n(beta: &SVector<f64, 10>) -> Matrix3<f64> {
    Matrix3::new(
        2.0 * beta[4],
        beta[7],
        beta[8],
        beta[7],
        2.0 * beta[5],
        beta[9],
        beta[8],
        beta[9],
        2.0 * beta[6],
    )
}

/// `[1, u1, u2, u3, u1², u2², u3², u1u2, u1u3, u2u3]`.
fn features(u: &Vector3<f64>) -> SVector<f64, 10> {
    SVector::<f64, 10>::from_column_slice(&[
        1.0,
        u.x,
        u.y,
        u.z,
        u.x * u.x,
        u.y * u.y,
        u.z * u.z,
        u.x * u.y,
        u.x * u.z,
        u.y * u.z,
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A raster whose value is a known quadratic of x and y near the origin
    /// (a paraboloid), so the score of a one-point scan is known exactly.
    /// In `f32`: an image's quantised raster would blur the curvature by
    /// its rounding, which this test is not about.
    fn paraboloid(ax: f64, ay: f64) -> Grid {
        let n = 200;
        let mut grid = Grid::zeros(-10.0, -10.0, 0.1, n, n);
        for iy in 0..n as i64 {
            for ix in 0..n as i64 {
                let (x, y) = grid.cell_centre_m(ix, iy);
                let v = 1.0 - ax * x * x - ay * y * y;
                grid.values_mut()[iy as usize * n + ix as usize] = v.max(0.0) as f32;
            }
        }
        grid
    }

    #[test]
    fn recovers_the_curvature_of_a_paraboloid() {
        // One point at the scan origin: s(x) = 1 - 0.5 x² - 2 y², flat in θ.
        let grid = paraboloid(0.5, 2.0);
        let points = [Point2::new(0.0, 0.0)];
        // Sample on cell centres so bilinear interpolation is exact.
        let pose = Se2::new(-0.05, -0.05, 0.0);
        let steps = Vector3::new(0.1, 0.1, 0.01);
        let window = Vector3::new(1.0, 1.0, 0.1);
        let fit = fit_surface(&points, &grid, &pose, steps.z, 2, &window, 0.5);
        assert!((fit.hessian[(0, 0)] + 1.0).abs() < 1e-4, "{}", fit.hessian);
        assert!((fit.hessian[(1, 1)] + 4.0).abs() < 1e-4, "{}", fit.hessian);
        assert!(fit.hessian[(0, 1)].abs() < 1e-4);
        assert!(fit.relative_fit_residual < 1e-6);
        // The paraboloid's peak is at the origin, 0.05 m from the lattice
        // centre on both axes; θ is unconstrained: no move.
        assert!(
            (fit.peak_offset.x - 0.05).abs() < 1e-6,
            "{}",
            fit.peak_offset
        );
        assert!(
            (fit.peak_offset.y - 0.05).abs() < 1e-6,
            "{}",
            fit.peak_offset
        );
        assert!(fit.peak_offset.z.abs() < 1e-12, "{}", fit.peak_offset);
        // Σ = τ (-H)⁻¹ = 0.5 / 1 and 0.5 / 4 in x and y.
        assert!(
            (fit.covariance[(0, 0)] - 0.5).abs() < 1e-4,
            "{}",
            fit.covariance
        );
        assert!(
            (fit.covariance[(1, 1)] - 0.125).abs() < 1e-4,
            "{}",
            fit.covariance
        );
        // θ is unobservable from one point: its variance is the clamp, the
        // largest normalised window (1.0 / 0.1 = 10 steps) squared, in rad².
        let clamp = (10.0 * 0.01_f64).powi(2);
        assert!(
            (fit.covariance[(2, 2)] - clamp).abs() < 1e-9,
            "{}",
            fit.covariance
        );
    }
}
