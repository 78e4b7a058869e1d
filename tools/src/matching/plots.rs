//! PNG pictures of a match: the score surface `s(x)` over x and y at the
//! estimated heading (the paper's Fig. 5, as a heat map), and the acoustic
//! image with the scan placed at the estimate.

use anyhow::{Context, Result};
use echofield_frontend::image::AcousticImage;
use echofield_frontend::matcher::score;
use echofield_graph::Se2;
use image::codecs::png::PngEncoder;
use image::{ImageEncoder, Rgb, RgbImage};
use nalgebra::Point2;

/// A marker drawn on a picture: a pose and a colour.
#[derive(Clone, Copy, Debug)]
pub struct Marker {
    pub pose: Se2,
    pub colour: [u8; 3],
}

pub const ESTIMATE: [u8; 3] = [0, 200, 255];
pub const PRIOR: [u8; 3] = [255, 60, 60];
pub const TRUTH: [u8; 3] = [60, 255, 60];

/// The score surface over `centre ± half_width_m` in x and y at the heading
/// of `centre`, `pixels` per side; brighter is higher (scaled between the
/// surface's minimum and maximum). Markers are drawn as crosses.
pub fn score_surface_png(
    points: &[Point2<f64>],
    image: &AcousticImage,
    centre: &Se2,
    half_width_m: f64,
    pixels: u32,
    markers: &[Marker],
) -> Result<Vec<u8>> {
    let step = 2.0 * half_width_m / f64::from(pixels);
    let mut values = vec![0.0; (pixels * pixels) as usize];
    for row in 0..pixels {
        // Row 0 is the top of the picture: the largest y.
        let y = centre.y() + half_width_m - (f64::from(row) + 0.5) * step;
        for col in 0..pixels {
            let x = centre.x() - half_width_m + (f64::from(col) + 0.5) * step;
            values[(row * pixels + col) as usize] =
                score(points, image, &Se2::new(x, y, centre.theta()));
        }
    }
    let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let span = if hi > lo { hi - lo } else { 1.0 };
    let mut picture = RgbImage::new(pixels, pixels);
    for (i, v) in values.iter().enumerate() {
        let t = (v - lo) / span;
        picture.put_pixel(i as u32 % pixels, i as u32 / pixels, Rgb(heat(t)));
    }
    let to_pixel = |pose: &Se2| {
        (
            (pose.x() - (centre.x() - half_width_m)) / step,
            ((centre.y() + half_width_m) - pose.y()) / step,
        )
    };
    for m in markers {
        let (px, py) = to_pixel(&m.pose);
        cross(&mut picture, px, py, 4, m.colour);
    }
    encode(&picture)
}

/// The acoustic image in grey (one pixel per cell, north up) with the
/// scan points placed by each marker's pose in the marker's colour.
pub fn overlay_png(
    image: &AcousticImage,
    points: &[Point2<f64>],
    markers: &[Marker],
) -> Result<Vec<u8>> {
    let grid = image.grid();
    let (w, h) = (grid.width() as u32, grid.height() as u32);
    let mut picture = RgbImage::new(w, h);
    for iy in 0..h {
        for ix in 0..w {
            let v = grid.cell(i64::from(ix), i64::from(iy)).clamp(0.0, 1.0);
            let g = (255.0 * v.sqrt()) as u8; // sqrt lifts faint echoes
            picture.put_pixel(ix, h - 1 - iy, Rgb([g, g, g]));
        }
    }
    for m in markers {
        for p in points {
            let q = m.pose.transform_point(p);
            let (ix, iy) = grid.cell_of(q.x, q.y);
            if ix >= 0 && iy >= 0 && ix < i64::from(w) && iy < i64::from(h) {
                let (px, py) = (ix as f64 + 0.5, f64::from(h) - 1.0 - iy as f64 + 0.5);
                cross(&mut picture, px, py, 1, m.colour);
            }
        }
        // The scan's origin (the vehicle at the scan's reference time).
        let (ix, iy) = grid.cell_of(m.pose.x(), m.pose.y());
        cross(
            &mut picture,
            ix as f64 + 0.5,
            f64::from(h) - 1.0 - iy as f64 + 0.5,
            5,
            m.colour,
        );
    }
    encode(&picture)
}

/// A black-red-yellow-white ramp for `t` in [0, 1].
fn heat(t: f64) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0);
    let r = (3.0 * t).min(1.0);
    let g = (3.0 * t - 1.0).clamp(0.0, 1.0);
    let b = (3.0 * t - 2.0).clamp(0.0, 1.0);
    [(255.0 * r) as u8, (255.0 * g) as u8, (255.0 * b) as u8]
}

fn cross(picture: &mut RgbImage, x: f64, y: f64, arm: i64, colour: [u8; 3]) {
    let (cx, cy) = (x.floor() as i64, y.floor() as i64);
    for d in -arm..=arm {
        for (px, py) in [(cx + d, cy), (cx, cy + d)] {
            if px >= 0
                && py >= 0
                && px < i64::from(picture.width())
                && py < i64::from(picture.height())
            {
                picture.put_pixel(px as u32, py as u32, Rgb(colour));
            }
        }
    }
}

fn encode(picture: &RgbImage) -> Result<Vec<u8>> {
    let mut bytes = Vec::new();
    PngEncoder::new(&mut bytes)
        .write_image(
            picture.as_raw(),
            picture.width(),
            picture.height(),
            image::ExtendedColorType::Rgb8,
        )
        .context("encoding PNG")?;
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use echofield_frontend::image::Grid;

    #[test]
    fn surface_is_brightest_at_the_best_pose() {
        let mut grid = Grid::zeros(-5.0, -5.0, 0.1, 100, 100);
        let (ix, iy) = grid.cell_of(1.0, -0.5);
        grid.values_mut()[iy as usize * 100 + ix as usize] = 1.0;
        grid.smooth_gaussian(3.0);
        let image = AcousticImage::from_grid(grid, 2);
        let points = [Point2::new(0.0, 0.0)];
        let png =
            score_surface_png(&points, &image, &Se2::new(0.5, 0.0, 0.0), 1.0, 40, &[]).unwrap();
        let decoded = image::load_from_memory(&png).unwrap().to_rgb8();
        assert_eq!(decoded.dimensions(), (40, 40));
        // The bump sits on the centre of the cell holding (1, -0.5); with
        // pixels of 0.05 m from x = -0.5 (left) and y = +1 (top):
        let (bx, by) = image.grid().cell_centre_m(ix, iy);
        let (col, row) = ((bx + 0.5) / 0.05, (1.0 - by) / 0.05);
        let brightest = decoded
            .enumerate_pixels()
            .max_by_key(|(_, _, p)| p.0.iter().map(|&c| u32::from(c)).sum::<u32>())
            .map(|(x, y, _)| (f64::from(x) + 0.5, f64::from(y) + 0.5))
            .unwrap();
        assert!(
            (brightest.0 - col).abs() <= 1.0 && (brightest.1 - row).abs() <= 1.0,
            "{brightest:?} vs ({col}, {row})"
        );
        let overlay = overlay_png(
            &image,
            &points,
            &[Marker {
                pose: Se2::identity(),
                colour: TRUTH,
            }],
        )
        .unwrap();
        assert_eq!(image::load_from_memory(&overlay).unwrap().width(), 100);
    }
}
