//! `mosaic.png`: the acoustic images of all nodes placed at their optimised
//! poses in one world grid.
//!
//! Each node's `I_k` (built by `frontend::image` during the run: the
//! rotation's beams motion-compensated into the node frame, eq. 3-4, and
//! interpolated as the paper describes) is moved into the world grid by
//! the optimised pose `world_from_node`: each image cell is split into
//! 2 x 2 sub-samples dropped into the world cells under them. Overlapping
//! nodes are blended by max (or mean).
//!
//! Re-rasterising every node's beams at the optimised poses instead costs far
//! more (EXPERIMENTS.md § Speed notes) and differs only by the images' light
//! smoothing.
//!
//! The picture is north up (row 0 is the largest y), one pixel per cell,
//! echoes on a black-red-yellow-white ramp, the optimised trajectory in
//! cyan, cropped to the echoes. `mosaic.pgw` beside it is an ESRI world
//! file (pixel size, rotation terms, centre of the upper-left pixel in the
//! run's world frame, metres) so GIS tools place the picture.

use crate::plots::{FONT, draw_over, encode_png, plot_error};
use anyhow::{Result, bail};
use echofield_frontend::image::{Grid, GridExtent};
use echofield_graph::Se2;
use image::ExtendedColorType;
use plotters::prelude::*;

/// How overlapping nodes combine in a cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MosaicBlend {
    /// The strongest echo any node saw there: walls stay sharp and bright.
    Max,
    /// The mean over the nodes that saw an echo there (> 0): less speckle,
    /// fainter isolated echoes.
    Mean,
}

/// Size and blending of the mosaic.
#[derive(Clone, Debug, PartialEq)]
pub struct MosaicConfig {
    /// Smallest cell, metres.
    pub min_cell_size_m: f64,
    /// Longest side of the picture in pixels before cropping; the cell
    /// grows beyond `min_cell_size_m` to respect it.
    pub max_side_px: usize,
    pub blend: MosaicBlend,
    /// Image cells below this normalised intensity (0-1) are left out:
    /// they show black on the colour ramp anyway, and skipping them makes
    /// placing the images several times faster.
    pub floor: f32,
    /// The picture is cropped to the cells of at least this normalised
    /// intensity (0-1) ...
    pub crop_level: f32,
    /// ... plus this margin, metres: the far field of a sonar that sees
    /// past the walls holds only speckle.
    pub crop_margin_m: f64,
}

impl Default for MosaicConfig {
    fn default() -> Self {
        Self {
            min_cell_size_m: 0.2,
            max_side_px: 2000,
            blend: MosaicBlend::Max,
            floor: 0.1,
            crop_level: 0.5,
            crop_margin_m: 5.0,
        }
    }
}

impl MosaicConfig {
    /// The mosaic behind a likelihood field of node images (the prior map
    /// of `localize`, the placement map of several missions), with cells
    /// of `cell_m`: the strongest echo per cell, every cell down to 0.05
    /// kept (a field needs the faint walls too), cropped 10 m beyond them,
    /// and a side of up to 20,000 cells so that `cell_m` is kept on any
    /// harbour-sized map.
    pub fn likelihood_field(cell_m: f64) -> Self {
        Self {
            min_cell_size_m: cell_m,
            max_side_px: 20_000,
            blend: MosaicBlend::Max,
            floor: 0.05,
            crop_level: 0.05,
            crop_margin_m: 10.0,
        }
    }
}

/// The world-frame corners of a raster of `extent` placed by
/// `world_from_image`.
fn corners(extent: &GridExtent, world_from_image: &Se2) -> [(f64, f64); 4] {
    let (gx, gy) = extent.origin_m;
    let (w, h) = (
        extent.width as f64 * extent.cell_size_m,
        extent.height as f64 * extent.cell_size_m,
    );
    [(gx, gy), (gx + w, gy), (gx, gy + h), (gx + w, gy + h)]
        .map(|(x, y)| world_from_image.transform_xy(x, y))
}

/// Whether an image of `extent` at `pose` is placed in the mosaic.
pub fn placeable(extent: &GridExtent, pose: &Se2) -> bool {
    extent.width > 0 && extent.height > 0 && pose.is_finite()
}

/// Places `images` (each with its `world_from_image` pose) in one world
/// grid and crops it to the echoes. Empty images are skipped.
pub fn build_mosaic(images: &[(&Grid, Se2)], config: &MosaicConfig) -> Result<Grid> {
    let placed: Vec<&(&Grid, Se2)> = images
        .iter()
        .filter(|(g, pose)| placeable(&GridExtent::of(g), pose))
        .collect();
    let mut canvas = MosaicCanvas::new(
        placed.iter().map(|(g, pose)| (GridExtent::of(g), *pose)),
        config,
    )?;
    for (image, pose) in placed {
        canvas.place(image, pose);
    }
    Ok(canvas.finish())
}

/// A mosaic being built image by image, so that the images need not be
/// held at once: sized by the extents of every image to come, then each
/// placed, then cropped.
pub struct MosaicCanvas {
    world: Grid,
    counts: Vec<u16>,
    config: MosaicConfig,
}

impl MosaicCanvas {
    /// The world grid covering every image of `extents` at its pose
    /// (images [`placeable`] only). Errors: no image.
    pub fn new(
        extents: impl IntoIterator<Item = (GridExtent, Se2)>,
        config: &MosaicConfig,
    ) -> Result<Self> {
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        let mut any = false;
        for (extent, pose) in extents {
            any = true;
            for (x, y) in corners(&extent, &pose) {
                x0 = x0.min(x);
                y0 = y0.min(y);
                x1 = x1.max(x);
                y1 = y1.max(y);
            }
        }
        if !any {
            bail!("no node has an acoustic image to place in the mosaic");
        }
        let longest_m = (x1 - x0).max(y1 - y0);
        let cell = config
            .min_cell_size_m
            .max(longest_m / config.max_side_px.max(1) as f64);
        let width = ((x1 - x0) / cell).ceil() as usize + 1;
        let height = ((y1 - y0) / cell).ceil() as usize + 1;
        let counts = match config.blend {
            MosaicBlend::Mean => vec![0u16; width * height],
            MosaicBlend::Max => Vec::new(),
        };
        Ok(Self {
            world: Grid::zeros(x0, y0, cell, width, height),
            counts,
            config: config.clone(),
        })
    }

    /// Blends `image` placed by `world_from_image` (one of the extents
    /// the canvas was sized for).
    pub fn place(&mut self, image: &Grid, world_from_image: &Se2) {
        place_image(
            &mut self.world,
            &mut self.counts,
            image,
            world_from_image,
            self.config.floor,
            self.config.blend,
        );
    }

    /// The mosaic, cropped to the echoes.
    pub fn finish(mut self) -> Grid {
        if self.config.blend == MosaicBlend::Mean {
            for (v, &n) in self.world.values_mut().iter_mut().zip(&self.counts) {
                if n > 0 {
                    *v /= f32::from(n);
                }
            }
        }
        crop_to_echoes(
            &self.world,
            self.config.crop_level,
            self.config.crop_margin_m,
        )
    }
}

/// Blends `image`, placed by `world_from_image`, into `world`. Every image
/// cell of at least `floor` is split into 2 x 2 sub-samples, each dropped
/// into the world cell under it: with world cells no smaller than image
/// cells this leaves no hole whatever the rotation (the sub-sample lattice
/// is finer than a world cell's inscribed circle), and fainter cells, which
/// show black anyway, cost nothing.
fn place_image(
    world: &mut Grid,
    counts: &mut [u16],
    image: &Grid,
    world_from_image: &Se2,
    floor: f32,
    blend: MosaicBlend,
) {
    let lattice = Lattice::new(world, image, world_from_image);
    let iw = image.width();
    let out = world.values_mut();
    for (iy, row) in image.values().chunks_exact(iw).enumerate() {
        // Most cells are fainter than `floor`: runs of them are skipped a
        // vector compare at a time (fewer instructions than a branch per
        // cell).
        for (run, cells) in row.chunks(SKIP_RUN).enumerate() {
            if !cells
                .iter()
                .fold(false, |any, &v| any | (v >= floor) | v.is_nan())
            {
                continue;
            }
            for (ix, &value) in (run * SKIP_RUN..).zip(cells) {
                if value < floor {
                    continue;
                }
                for i in lattice.world_cells(ix, iy) {
                    match blend {
                        MosaicBlend::Max => out[i] = out[i].max(value),
                        MosaicBlend::Mean => {
                            out[i] += value;
                            counts[i] = counts[i].saturating_add(1);
                        }
                    }
                }
            }
        }
    }
}

/// Where the sub-samples of image cells land in the world grid: world cell
/// coordinates are affine in the image cell coordinates,
/// `(fx, fy) = base + ix·step_x + iy·step_y + sub-sample offset`.
struct Lattice {
    base: (f64, f64),
    step_x: (f64, f64),
    step_y: (f64, f64),
    /// The offsets of the 2 x 2 sub-samples at (¼, ¼), (¾, ¼), (¼, ¾),
    /// (¾, ¾) of a cell.
    subs: [(f64, f64); 4],
    /// The world grid's size, cells.
    width: usize,
    size: (f64, f64),
}

impl Lattice {
    fn new(world: &Grid, image: &Grid, world_from_image: &Se2) -> Self {
        let inv_c = 1.0 / world.cell_size_m();
        let (wox, woy) = world.origin_m();
        let (gx, gy) = image.origin_m();
        let cg = image.cell_size_m();
        let (s, c) = world_from_image.theta().sin_cos();
        let (px, py) = world_from_image.transform_xy(gx, gy);
        let step_x = (c * cg * inv_c, s * cg * inv_c);
        let step_y = (-s * cg * inv_c, c * cg * inv_c);
        Self {
            base: ((px - wox) * inv_c, (py - woy) * inv_c),
            step_x,
            step_y,
            subs: [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)]
                .map(|(a, b)| (a * step_x.0 + b * step_y.0, a * step_x.1 + b * step_y.1)),
            width: world.width(),
            size: (world.width() as f64, world.height() as f64),
        }
    }

    /// The world cell index under each sub-sample of image cell `(ix, iy)`
    /// that falls inside the world grid.
    #[inline]
    fn world_cells(&self, ix: usize, iy: usize) -> impl Iterator<Item = usize> + '_ {
        let row_x = self.base.0 + iy as f64 * self.step_y.0;
        let row_y = self.base.1 + iy as f64 * self.step_y.1;
        let (cx, cy) = (
            row_x + ix as f64 * self.step_x.0,
            row_y + ix as f64 * self.step_x.1,
        );
        self.subs.iter().filter_map(move |(dx, dy)| {
            let (fx, fy) = (cx + dx, cy + dy);
            if fx < 0.0 || fy < 0.0 || fx >= self.size.0 || fy >= self.size.1 {
                return None;
            }
            Some(fy as usize * self.width + fx as usize)
        })
    }
}

/// Image cells per run that [`place_image`] tests for echoes at once.
const SKIP_RUN: usize = 16;

/// The part of `grid` holding values of at least `level`, widened by
/// `margin_m` on every side (the whole grid when no value reaches `level`).
/// Cells keep their lattice positions.
pub fn crop_to_echoes(grid: &Grid, level: f32, margin_m: f64) -> Grid {
    let (w, h) = (grid.width(), grid.height());
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    for (iy, row) in grid.values().chunks_exact(w).enumerate() {
        if let Some(first) = row.iter().position(|&v| v >= level) {
            let last = row.iter().rposition(|&v| v >= level).unwrap_or(first);
            x0 = x0.min(first);
            x1 = x1.max(last);
            y0 = y0.min(iy);
            y1 = y1.max(iy);
        }
    }
    if x0 == usize::MAX {
        return grid.clone();
    }
    let margin = (margin_m / grid.cell_size_m()).ceil() as usize;
    let (x0, y0) = (x0.saturating_sub(margin), y0.saturating_sub(margin));
    let (x1, y1) = ((x1 + margin).min(w - 1), (y1 + margin).min(h - 1));
    let (ox, oy) = grid.cell_centre_m(x0 as i64, y0 as i64);
    let cell = grid.cell_size_m();
    let mut out = Grid::zeros(
        ox - 0.5 * cell,
        oy - 0.5 * cell,
        cell,
        x1 - x0 + 1,
        y1 - y0 + 1,
    );
    let out_w = out.width();
    for (dst, iy) in out.values_mut().chunks_exact_mut(out_w).zip(y0..=y1) {
        dst.copy_from_slice(&grid.values()[iy * w + x0..=iy * w + x1]);
    }
    out
}

/// The black-red-yellow-white ramp for `t` in `[0, 1]`.
fn heat(t: f32) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0);
    let r = (3.0 * t).min(1.0);
    let g = (3.0 * t - 1.0).clamp(0.0, 1.0);
    let b = (3.0 * t - 2.0).clamp(0.0, 1.0);
    [(255.0 * r) as u8, (255.0 * g) as u8, (255.0 * b) as u8]
}

/// Colour of the trajectory overlay.
const TRACK: [u8; 3] = [0, 220, 255];

/// The mosaic as an RGB PNG, north up, with `trajectory` (world metres)
/// drawn over it.
pub fn mosaic_png(grid: &Grid, trajectory: &[(f64, f64)]) -> Result<Vec<u8>> {
    mosaic_png_tracks(grid, &[trajectory])
}

/// [`mosaic_png`] with several trajectories, each drawn on its own (no
/// line joins the end of one to the start of the next).
pub fn mosaic_png_tracks(grid: &Grid, trajectories: &[&[(f64, f64)]]) -> Result<Vec<u8>> {
    let (w, h) = (grid.width(), grid.height());
    // A lookup table: 256 levels are plenty for an 8-bit picture.
    let table: Vec<[u8; 3]> = (0..256).map(|i| heat(i as f32 / 255.0)).collect();
    let mut rgb = vec![0u8; w * h * 3];
    let values = grid.values();
    for py in 0..h {
        let src = &values[(h - 1 - py) * w..(h - py) * w];
        let dst = &mut rgb[py * w * 3..(py + 1) * w * 3];
        for (px, v) in dst.chunks_exact_mut(3).zip(src) {
            px.copy_from_slice(&table[(v.clamp(0.0, 1.0) * 255.0) as usize]);
        }
    }
    let (ox, oy) = grid.origin_m();
    let cell = grid.cell_size_m();
    let to_px = |(x, y): (f64, f64)| ((x - ox) / cell, h as f64 - (y - oy) / cell);
    for pair in trajectories.iter().flat_map(|t| t.windows(2)) {
        draw_line(&mut rgb, w, h, to_px(pair[0]), to_px(pair[1]), TRACK);
    }
    let (wp, hp) = (u32::try_from(w)?, u32::try_from(h)?);
    if w >= MIN_ANNOTATED_PX.0 && h >= MIN_ANNOTATED_PX.1 {
        draw_over(&mut rgb, wp, hp, |root| {
            draw_scale_bar(root, cell, w)?;
            draw_north_arrow(root, w)
        })?;
    }
    encode_png(&rgb, wp, hp, ExtendedColorType::Rgb8)
}

/// Pictures smaller than this (width, height in pixels) get no scale bar
/// or north arrow: they would cover most of it.
const MIN_ANNOTATED_PX: (usize, usize) = (200, 120);

/// The longest of 1, 2 or 5 times a power of ten metres that is at most
/// `max_m`.
fn nice_length_m(max_m: f64) -> f64 {
    let power = 10f64.powf(max_m.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|f| f * power)
        .find(|&l| l <= max_m)
        .unwrap_or(power)
}

/// A scale bar in the lower left corner, about a fifth of the picture's
/// width, on a white box, labelled in metres (`cell_m` metres per pixel).
fn draw_scale_bar(root: &Annotated<'_>, cell_m: f64, width_px: usize) -> Result<()> {
    let (_, height) = root.dim_in_pixel();
    let length_m = nice_length_m(0.2 * width_px as f64 * cell_m);
    let length_px = (length_m / cell_m).round() as i32;
    let (left, bottom) = (14, height as i32 - 14);
    let background = [(left - 8, bottom - 40), (left + length_px + 8, bottom + 8)];
    root.draw(&Rectangle::new(background, WHITE.mix(0.85).filled()))
        .map_err(plot_error)?;
    // Two halves, black and white, framed in black.
    let half = length_px / 2;
    for (k, colour) in [(0, BLACK), (1, WHITE)] {
        let x0 = left + k * half;
        let x1 = if k == 0 {
            left + half
        } else {
            left + length_px
        };
        root.draw(&Rectangle::new(
            [(x0, bottom - 8), (x1, bottom)],
            colour.filled(),
        ))
        .map_err(plot_error)?;
    }
    root.draw(&Rectangle::new(
        [(left, bottom - 8), (left + length_px, bottom)],
        BLACK.stroke_width(1),
    ))
    .map_err(plot_error)?;
    let label = format!("{length_m} m");
    root.draw(&Text::new(label, (left, bottom - 30), (FONT, 16)))
        .map_err(plot_error)
}

/// An arrow pointing up (north: the mosaic's y axis) with an "N", in the
/// upper right corner.
fn draw_north_arrow(root: &Annotated<'_>, width_px: usize) -> Result<()> {
    let x = width_px as i32 - 30;
    let top = 12;
    root.draw(&Rectangle::new(
        [(x - 16, top - 4), (x + 16, top + 62)],
        WHITE.mix(0.85).filled(),
    ))
    .map_err(plot_error)?;
    root.draw(&Polygon::new(
        vec![(x, top), (x - 9, top + 22), (x + 9, top + 22)],
        BLACK.filled(),
    ))
    .map_err(plot_error)?;
    root.draw(&PathElement::new(
        [(x, top + 20), (x, top + 36)],
        BLACK.stroke_width(3),
    ))
    .map_err(plot_error)?;
    root.draw(&Text::new("N", (x - 6, top + 40), (FONT, 18)))
        .map_err(plot_error)
}

/// The drawing area [`draw_over`] gives.
type Annotated<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

/// A one-pixel line by uniform sampling (the picture is large and the
/// segments short; no need for anything smarter).
fn draw_line(rgb: &mut [u8], w: usize, h: usize, a: (f64, f64), b: (f64, f64), colour: [u8; 3]) {
    let steps = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as usize).clamp(1, 100_000);
    for s in 0..=steps {
        let f = s as f64 / steps as f64;
        let (x, y) = (a.0 + f * (b.0 - a.0), a.1 + f * (b.1 - a.1));
        if x >= 0.0 && y >= 0.0 && (x as usize) < w && (y as usize) < h {
            let i = (y as usize * w + x as usize) * 3;
            rgb[i..i + 3].copy_from_slice(&colour);
        }
    }
}

/// The ESRI world file of [`mosaic_png`]'s picture.
pub fn world_file(grid: &Grid) -> String {
    let (ox, oy) = grid.origin_m();
    let c = grid.cell_size_m();
    let top = oy + (grid.height() as f64 - 0.5) * c;
    // Millimetres: the lattice arithmetic leaves float noise in the last digits.
    format!("{c:.6}\n0\n0\n{:.6}\n{:.3}\n{top:.3}\n", -c, ox + 0.5 * c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scale_bars_are_one_two_or_five_powers_of_ten() {
        assert_eq!(nice_length_m(37.0), 20.0);
        assert_eq!(nice_length_m(50.0), 50.0);
        assert_eq!(nice_length_m(9.99), 5.0);
        assert_eq!(nice_length_m(1.4), 1.0);
        assert!((nice_length_m(0.3) - 0.2).abs() < 1e-12);
    }

    /// A 400 x 300 px mosaic at 0.25 m per pixel: the scale bar (20 m =
    /// 80 px, black and white halves) sits in the lower left corner and
    /// the north arrow in the upper right; a small picture gets neither.
    #[test]
    fn mosaic_carries_a_scale_bar_and_a_north_arrow() {
        let grid = Grid::zeros(0.0, 0.0, 0.25, 400, 300);
        let png = mosaic_png(&grid, &[]).unwrap();
        let rgb = image::load_from_memory(&png).unwrap().to_rgb8();
        let background = heat(0.0);
        let is = |x: u32, y: u32, c: [u8; 3]| rgb.get_pixel(x, y).0 == c;
        // The bar: 14 px from the left, its lower edge 14 px above the bottom.
        assert!(is(20, 282, [0, 0, 0]), "{:?}", rgb.get_pixel(20, 282));
        assert!(is(80, 282, [255, 255, 255]), "{:?}", rgb.get_pixel(80, 282));
        // Outside the bar's box, the mosaic's own background.
        assert!(is(150, 282, background));
        // The arrow's black head, 30 px from the right edge.
        assert!(is(370, 25, [0, 0, 0]), "{:?}", rgb.get_pixel(370, 25));
        let small = Grid::zeros(0.0, 0.0, 0.25, 100, 80);
        let rgb = image::load_from_memory(&mosaic_png(&small, &[]).unwrap())
            .unwrap()
            .to_rgb8();
        assert!(rgb.pixels().all(|p| p.0 == background));
    }

    #[test]
    fn images_land_at_their_poses_rotated() {
        // A 4 m x 2 m image (1 m cells) with one bright cell at image
        // coordinates x in [3, 4), y in [0, 1).
        let mut image = Grid::zeros(0.0, 0.0, 1.0, 4, 2);
        image.values_mut()[3] = 0.9;
        image.values_mut()[4] = 0.3; // cell (0, 1)
        let config = MosaicConfig {
            min_cell_size_m: 0.5,
            crop_level: 0.0,
            crop_margin_m: 0.0,
            ..MosaicConfig::default()
        };
        // A quarter turn about the origin, then 10 m east: image x points
        // north, the bright cell covers world x in (9, 10), y in (3, 4).
        let pose = Se2::new(10.0, 0.0, std::f64::consts::FRAC_PI_2);
        let mosaic = build_mosaic(&[(&image, pose)], &config).unwrap();
        let at = |x: f64, y: f64| {
            let (ix, iy) = mosaic.cell_of(x, y);
            mosaic.cell(ix, iy)
        };
        assert_eq!(at(9.25, 3.25), 0.9);
        assert_eq!(at(9.75, 3.75), 0.9);
        assert_eq!(at(8.75, 0.25), 0.3, "image cell (0, 1)");
        assert_eq!(at(9.75, 2.75), 0.0);
        assert_eq!(at(10.25, 3.25), 0.0, "outside the image");
        // Max and mean of two overlapping copies.
        let weak = {
            let mut g = image.clone();
            g.values_mut()[3] = 0.5;
            g
        };
        let both = [(&image, pose), (&weak, pose)];
        let max = build_mosaic(&both, &config).unwrap();
        let (ix, iy) = max.cell_of(9.25, 3.25);
        assert_eq!(max.cell(ix, iy), 0.9);
        let mean = build_mosaic(
            &both,
            &MosaicConfig {
                blend: MosaicBlend::Mean,
                ..config.clone()
            },
        )
        .unwrap();
        let (ix, iy) = mean.cell_of(9.25, 3.25);
        assert!((mean.cell(ix, iy) - 0.7).abs() < 1e-6);
    }

    /// Cells are placed whatever their position in the runs that are
    /// skipped together (first, last, a partial last run), from the floor
    /// up; fainter cells never are.
    #[test]
    fn every_cell_from_the_floor_up_is_placed_whatever_its_run() {
        let config = MosaicConfig {
            min_cell_size_m: 0.5,
            crop_level: 0.0,
            crop_margin_m: 0.0,
            ..MosaicConfig::default()
        };
        let floor = config.floor;
        // 37 cells per row: two whole runs of 16 and a partial one.
        let mut image = Grid::zeros(0.0, 0.0, 1.0, 37, 2);
        let lit = [
            (0, 0.8),
            (15, 0.6),
            (16, 0.7),
            (31, 0.9),
            (36, 0.5),
            (20, floor),
        ];
        for &(i, v) in &lit {
            image.values_mut()[37 + i] = v;
        }
        image.values_mut()[37 + 21] = floor * 0.999;
        image.values_mut()[5] = floor * 0.5;
        let mosaic = build_mosaic(&[(&image, Se2::identity())], &config).unwrap();
        let at = |x: f64, y: f64| {
            let (ix, iy) = mosaic.cell_of(x, y);
            mosaic.cell(ix, iy)
        };
        for &(i, v) in &lit {
            for (dx, dy) in [(0.25, 1.25), (0.75, 1.75)] {
                assert_eq!(at(i as f64 + dx, dy), v, "cell {i}");
            }
        }
        assert_eq!(at(21.5, 1.5), 0.0, "just below the floor");
        assert_eq!(at(5.5, 0.5), 0.0, "below the floor");
        let placed = mosaic.values().iter().filter(|&&v| v > 0.0).count();
        assert_eq!(placed, 4 * lit.len(), "2 x 2 world cells per image cell");
    }

    #[test]
    fn crop_keeps_the_echoes_with_a_margin_on_the_lattice() {
        let mut grid = Grid::zeros(-5.0, -5.0, 1.0, 10, 10);
        grid.values_mut()[3 * 10 + 4] = 0.9; // cell (4, 3)
        grid.values_mut()[6 * 10 + 5] = 0.7; // cell (5, 6)
        grid.values_mut()[0] = 0.2; // below the level
        let crop = crop_to_echoes(&grid, 0.5, 1.0);
        assert_eq!((crop.width(), crop.height()), (4, 6));
        assert_eq!(crop.origin_m(), (-2.0, -3.0));
        assert_eq!(crop.cell(1, 1), 0.9);
        assert_eq!(crop.cell(2, 4), 0.7);
        // Nothing above the level: unchanged.
        assert_eq!(crop_to_echoes(&grid, 0.95, 1.0), grid);
    }

    #[test]
    fn world_file_names_the_upper_left_pixel_centre() {
        let grid = Grid::zeros(10.0, -4.0, 0.5, 4, 6);
        let lines: Vec<f64> = world_file(&grid)
            .lines()
            .map(|l| l.parse().unwrap())
            .collect();
        assert_eq!(lines, vec![0.5, 0.0, 0.0, -0.5, 10.25, -1.25]);
    }
}
