//! What pulls a match along its displacement: every scan point's image
//! value and slope at the true pose (`bench-matcher --pull-at-truth`).
//!
//! At the true pose `x*` of a pair, the derivative of eq. (5)'s score
//! `s(x) = Σ I(x ⊕ p_i)` along the unit vector `u` of the true
//! translation (image frame) is `Σ ∇I(x* ⊕ p_i) · u`. Summed over a pair's
//! points it says which way the score would move the scan from the truth:
//! negative towards the image's centre (a shorter displacement), positive
//! away from it. Each point's term is kept with its margin to the rim of
//! the image's reach (the images built from beams have one), so that the
//! pull of the rim (points that a longer displacement carries out of the
//! image, where `I` is 0) can be told from the pull of the walls inside.
//!
//! A slope is not a bias: the estimate also depends on the search, the
//! covariance fit and the pose fit, and one pair's sum is dominated by its
//! walls' noise. Averages over hundreds of pairs, with their standard
//! errors (`tools/peers/pull_at_truth.py`), are what tell a pull from
//! noise. Two of the images a match reads are reported: the search raster
//! ([`AcousticImage::value_and_gradient`], which the lattice search and the
//! covariance fit read) and the image interpolated from the samples
//! ([`AcousticImage::fine_value_and_gradient`], eq. (5)'s
//! [`echofield_frontend::matcher::score`], which the match's quality
//! reads). The pose fit's own raster is not.

use super::evaluation::PairKind;
use echofield_frontend::image::AcousticImage;
use echofield_graph::Se2;
use nalgebra::Point2;
use serde::Serialize;

/// One scan point of one pair at the true pose: a row of the
/// `--pull-at-truth` CSV.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PointPull {
    /// The scan's rotation `K` and the image's `J`.
    pub scan: usize,
    pub image: usize,
    pub kind: PairKind,
    /// Length of the true translation of `image_from_scan`, metres.
    pub displacement_m: f64,
    /// The point in the scan's frame, metres.
    pub scan_x_m: f64,
    pub scan_y_m: f64,
    /// Its margin to the rim of the image's reach at the true pose, metres
    /// (negative outside; `None` for an image without a reach).
    pub rim_margin_m: Option<f64>,
    /// `I(x* ⊕ p)` of the search raster (0-1).
    pub value: f64,
    /// `∇I(x* ⊕ p) · u` of the search raster, 1/m.
    pub slope_along_per_m: f64,
    /// `∇I(x* ⊕ p) · u` of the image interpolated from the samples, 1/m.
    pub fine_slope_along_per_m: f64,
}

/// The rows of one pair: scan `points` (scan frame) of rotation `scan`
/// against `image` of rotation `image_index` at `truth` (`image_from_scan`).
/// Empty when the true translation is shorter than 1 mm (no direction to
/// measure along).
pub fn pull_at_truth(
    points: &[Point2<f64>],
    image: &AcousticImage,
    truth: &Se2,
    (scan, image_index, kind): (usize, usize, PairKind),
) -> Vec<PointPull> {
    let t = truth.translation();
    let displacement_m = t.norm();
    if displacement_m < 1e-3 {
        return Vec::new();
    }
    let u = t / displacement_m;
    let reach = image.reach();
    points
        .iter()
        .map(|p| {
            let q = truth.transform_point(p);
            let (value, gradient) = image.value_and_gradient(q.x, q.y);
            let (_, fine_gradient) = image.fine_value_and_gradient(q.x, q.y);
            PointPull {
                scan,
                image: image_index,
                kind,
                displacement_m,
                scan_x_m: p.x,
                scan_y_m: p.y,
                rim_margin_m: reach.map(|r| r.margin(&q)),
                value,
                slope_along_per_m: gradient.dot(&u),
                fine_slope_along_per_m: fine_gradient.dot(&u),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use echofield_frontend::image::{Grid, Reach};

    /// Slope of [`ramp_image`] along x, 1/m.
    const RAMP_PER_M: f64 = 0.02;
    /// Radius of [`ramp_image`]'s reach, metres.
    const RIM_M: f64 = 8.0;

    /// An image whose value is `0.5 + RAMP_PER_M · x` over a square
    /// centred on the origin (larger than every point the tests place),
    /// with the reach of beams of `RIM_M` all round the origin when
    /// `reach`.
    fn ramp_image(reach: bool) -> AcousticImage {
        let (cell, n) = (0.1, 200);
        let half_m = 0.5 * cell * n as f64;
        let mut grid = Grid::zeros(-half_m, -half_m, cell, n, n);
        for (k, v) in grid.values_mut().iter_mut().enumerate() {
            let x = -half_m + ((k % n) as f64 + 0.5) * cell;
            *v = (0.5 + RAMP_PER_M * x) as f32;
        }
        let image = AcousticImage::from_grid(grid, 0);
        if !reach {
            return image;
        }
        image.with_reach(Reach::disc(Point2::origin(), RIM_M))
    }

    #[test]
    fn the_slope_is_taken_along_the_true_displacement() {
        let image = ramp_image(false);
        let points = [Point2::new(1.0, 0.0), Point2::new(0.0, 2.0)];
        let key = (4, 3, PairKind::Consecutive);
        // A translation along +x: the ramp's whole slope, and the points'
        // values where the truth puts them (x = 2 and x = 1).
        let along_x = pull_at_truth(&points, &image, &Se2::new(1.0, 0.0, 0.0), key);
        assert_eq!(along_x.len(), 2);
        for (row, x) in along_x.iter().zip([2.0, 1.0]) {
            assert!((row.slope_along_per_m - RAMP_PER_M).abs() < 1e-4, "{row:?}");
            assert!(
                (row.fine_slope_along_per_m - RAMP_PER_M).abs() < 1e-4,
                "{row:?}"
            );
            assert!((row.value - (0.5 + RAMP_PER_M * x)).abs() < 1e-4, "{row:?}");
            assert!((row.displacement_m - 1.0).abs() < 1e-12);
            assert_eq!(row.rim_margin_m, None);
            assert_eq!((row.scan, row.image, row.kind), key);
        }
        // Along −x the same ramp pulls the other way, along +y not at all.
        let back = pull_at_truth(&points, &image, &Se2::new(-2.0, 0.0, 0.0), key);
        assert!(
            back.iter()
                .all(|r| (r.slope_along_per_m + RAMP_PER_M).abs() < 1e-4)
        );
        let across = pull_at_truth(&points, &image, &Se2::new(0.0, 1.5, 0.0), key);
        assert!(across.iter().all(|r| r.slope_along_per_m.abs() < 1e-4));
        // The scan's own coordinates are kept, not the image's.
        assert_eq!((across[1].scan_x_m, across[1].scan_y_m), (0.0, 2.0));
    }

    #[test]
    fn the_margin_is_to_the_rim_where_the_truth_puts_the_point() {
        let image = ramp_image(true);
        // The truth puts the points at (3, 0) and (2, 9): inside the rim
        // and outside it.
        let points = [Point2::new(1.0, 0.0), Point2::new(0.0, 9.0)];
        let rows = pull_at_truth(
            &points,
            &image,
            &Se2::new(2.0, 0.0, 0.0),
            (1, 0, PairKind::NonConsecutive),
        );
        let margins: Vec<f64> = rows
            .iter()
            .map(|r| r.rim_margin_m.expect("a reach"))
            .collect();
        let outside = RIM_M - 2.0_f64.hypot(9.0);
        assert!(outside < 0.0);
        assert!((margins[0] - (RIM_M - 3.0)).abs() < 0.05, "{margins:?}");
        assert!((margins[1] - outside).abs() < 0.05, "{margins:?}");
    }

    #[test]
    fn a_pair_without_displacement_has_no_rows() {
        let rows = pull_at_truth(
            &[Point2::new(1.0, 0.0)],
            &ramp_image(false),
            &Se2::new(0.0, 0.0, 0.3),
            (1, 0, PairKind::Consecutive),
        );
        assert!(rows.is_empty());
    }
}
