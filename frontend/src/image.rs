//! The acoustic image `I_k` of one sonar rotation (paper section 4).
//!
//! All bins of the rotation's beams are placed in the frame of the rotation's
//! reference pose (motion-compensated with eq. 3-4: the caller passes the
//! pose of every beam frame in that reference frame, see
//! `motion::reference_from_beams`) and rasterised on a regular grid. Bin `i`
//! of a beam is a sample at its *far end*, `reference_from_beam ⊕
//! [bin_end_range_m(i), 0]`, as in eq. (3).
//!
//! Building an image has four steps:
//! 1. [`normalise`]: intensities to `[0, 1]` — optionally smoothed along
//!    range like the segmentation smooths them, blind zone masked, an optional
//!    per-range background (a quantile over the rotation's beams, which
//!    removes rings at a constant range such as near-field ringing and the
//!    range-dependent noise floor) subtracted, then divided by a high
//!    quantile of the rotation's values and clamped to 1.
//! 2. [`raster`]: the two interpolations the paper names, filling the wedge
//!    between consecutive beams ([`Interpolation`]).
//! 3. An optional Gaussian smoothing that widens the basin of the score.
//! 4. [`pyramid`]: max-pooled coarse levels for the branch-and-bound search.
//!
//! With [`ImageConfig::pose_fit`] on (the default), steps 1-3 also give a
//! second raster of the same beams with a smaller off-axis margin and no
//! range smoothing, painted in the same sweep; only the matcher's last
//! step, the sub-cell pose fit, reads it ([`PoseFitRaster`]).
//!
//! `I(x)` is the bilinear interpolation of the cell values between cell
//! centres ([`AcousticImage::value_at`]); outside the grid it is 0. The
//! same interpolation evaluated directly on the samples, without the
//! raster's quantisation, is [`AcousticImage::fine_value_at`] ([`polar`]):
//! the matcher searches on the raster and refines on the samples.

pub mod grid;
pub mod normalise;
pub mod polar;
pub mod pyramid;
pub mod raster;
pub mod reach;
pub mod residency;
pub mod stored;
pub mod synthetic;

pub use grid::{CellValue, Grid, QuantisedGrid};
pub use polar::PolarSamples;
pub use pyramid::Pyramid;
pub use reach::Reach;
pub use residency::ImageResidency;
pub use stored::{GridExtent, StoredImage};

use crate::config_check::check_positive;
use crate::error::FrontendError;
use crate::off_axis::OffAxisSuppression;
use crate::sensors::SonarBeam;
use echofield_graph::Se2;
use nalgebra::Vector2;
use serde::{Deserialize, Serialize};
use std::cell::RefCell;

/// How cells between beam samples get their value (paper section 4).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Interpolation {
    /// Each cell takes the value of the sample closest to its centre (the
    /// paper's Fig. 4-b): nearest beam in angle, nearest bin endpoint in range.
    Nearest,
    /// Each point of the fan takes a weighted mean of the samples of the
    /// beams whose bearing lies within `angular_half_width_rad` of its own
    /// (triangular weights `1 - |Δφ| / w`), at its range bin; a cell holds the
    /// mean of the points that fall in it (the paper's Fig. 1-a).
    AngularWindow,
}

/// Configuration of acoustic-image building.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImageConfig {
    /// Side of one grid cell, metres. `None` derives it from the beams:
    /// their longest range / 250 (a grid about 500 cells across), clamped
    /// to [0.02, 0.2] m — 0.2 m for 50 m beams, 0.04 m for 10 m ones.
    /// Smaller cells resolve more detail and cost quadratically more.
    pub cell_size_m: Option<f64>,
    /// Interpolation between beam samples.
    pub interpolation: Interpolation,
    /// Half-width of the angular window of [`Interpolation::AngularWindow`],
    /// radians. Widened per wedge to at least the angle between its two
    /// beams, so the fan has no holes.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): half the horizontal beam width, and widened per wedge to the beams' spacing anyway.
    #[serde(skip)]
    pub angular_half_width_rad: f64,
    /// Consecutive beams further apart than this (radians) are not joined
    /// into a wedge: the gap stays empty (sector ends, lost beams).
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): a guard that leaves sector ends and lost beams empty.
    #[serde(skip)]
    pub max_wedge_rad: f64,
    /// Width (bins) of a centred moving average applied along each beam
    /// before anything else; 1 disables it. Use the segmentation's
    /// `smoothing_bins`: the scan's ranges are the peaks of the smoothed
    /// profiles, and the image then peaks at the same ranges.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): derived from `segmentation.smoothing_bins` (`SlamConfig::derive`), so that the image peaks at the scan's ranges.
    #[serde(skip)]
    pub range_smoothing_bins: usize,
    /// Bins whose far end is closer than this range (metres) are set to 0:
    /// the transducer's ringing and the vehicle's own echoes.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): derived from `segmentation.blind_zone_m` (`SlamConfig::derive`): the same ringing and own echoes.
    #[serde(skip)]
    pub blind_zone_m: f64,
    /// Bins farther than this range (metres) are ignored; `None` keeps all.
    pub max_range_m: Option<f64>,
    /// Quantile (0-1) over the rotation's beams of each range bin that is
    /// subtracted as background; 0 subtracts nothing.
    pub background_quantile: f64,
    /// Quantile (0-1] of all background-subtracted samples that maps to
    /// intensity 1 (larger values clamp to 1); 1.0 divides by the maximum.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): a robust maximum; the image's scale is divided out by the match's mean intensity gates.
    #[serde(skip)]
    pub normalisation_quantile: f64,
    /// Exponent `γ` applied to the normalised intensity (`v^γ`); values
    /// above 1 favour the strongest echoes over the weaker reverberation
    /// behind them and over speckle.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): 1 (the identity): the off-axis suppression and the background subtraction do what a larger exponent was meant to.
    #[serde(skip)]
    pub intensity_exponent: f64,
    /// Standard deviation of the Gaussian smoothing of the raster, metres;
    /// 0 disables it.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): 0: the pyramid and the sub-cell pose fit do without a smoothed raster.
    #[serde(skip)]
    pub smoothing_sigma_m: f64,
    /// Number of max-pooled pyramid levels above the raster for the coarse
    /// search; level `h` bounds translations of `2^h` cells.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): seven levels bound translations of 128 cells, beyond any window of the gates.
    #[serde(skip)]
    pub pyramid_levels: usize,
    /// Clears the bins that a neighbouring beam hears much louder at about
    /// the same range ([`crate::off_axis`]), before the background is
    /// subtracted. Default on, margin 25 (above the scan's 15, so that the
    /// returns the scan keeps stay in the image).
    pub off_axis: OffAxisSuppression,
    /// A second raster that only the matcher's final sub-cell pose fit
    /// reads ([`AcousticImage::pose_fit_grid`], [`PoseFitRaster`]).
    pub pose_fit: PoseFitRaster,
}

impl Default for ImageConfig {
    fn default() -> Self {
        Self {
            cell_size_m: None,
            interpolation: Interpolation::AngularWindow,
            angular_half_width_rad: 1.5_f64.to_radians(),
            max_wedge_rad: 6.0_f64.to_radians(),
            range_smoothing_bins: 3,
            blind_zone_m: 1.0,
            max_range_m: None,
            background_quantile: 0.5,
            normalisation_quantile: 0.999,
            intensity_exponent: 1.0,
            smoothing_sigma_m: 0.0,
            pyramid_levels: 7,
            off_axis: OffAxisSuppression::for_images(),
            pose_fit: PoseFitRaster::default(),
        }
    }
}

/// The raster of the matcher's pose fit (TOML `[image.pose_fit]`): the
/// same beams, with the off-axis suppression at a smaller margin and less
/// range smoothing.
///
/// Why a second raster: the search and the quality gates need the weaker
/// echoes and the wider ridges of the image, but those also bias where the
/// score peaks. The arcs that a wide beam draws around strong targets
/// turn the matches by a few hundredths of a degree, always the same way
/// ([`crate::off_axis`], "The image's margin and the heading bias"), and
/// range smoothing over an echo with a tail behind it moves the ridge
/// outward. A smaller margin and no smoothing for the whole image cost
/// loop recall (the gates then reject right loops), so the image keeps
/// them and the matcher's last step, a quadratic fit around the found
/// peak that moves it by at most half a lattice step, reads this raster
/// ([`crate::matcher`]).
///
/// The cost: the second raster is painted in the same sweep as the first
/// ([`raster::rasterise_pair`]), holds 4 more bytes per cell and rotation, and
/// the pose fit reads it once per match. Accuracy and cost, measured:
/// EXPERIMENTS.md § Pose-fit raster.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PoseFitRaster {
    /// Off: the pose fit reads the image itself. Default on.
    pub enabled: bool,
    /// `off_axis.margin` of the raster (0-255 units; its suppression is on
    /// whatever the image's `off_axis.enabled`, with the image's other
    /// off-axis settings). Default 10.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): 10, below the image's own margin: the pose fit needs the peaks unbiased, not the weaker echoes.
    #[serde(skip)]
    pub off_axis_margin: f64,
    /// `range_smoothing_bins` of the raster (1 = none). Default 1.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): 1, no smoothing, so that the pose fit
    /// reads the peaks where the beams put them.
    #[serde(skip)]
    pub range_smoothing_bins: usize,
}

impl Default for PoseFitRaster {
    fn default() -> Self {
        Self {
            enabled: true,
            off_axis_margin: 10.0,
            range_smoothing_bins: 1,
        }
    }
}

impl PoseFitRaster {
    /// Errors name the field as `pose_fit.<field>`.
    pub fn validate(&self) -> Result<(), FrontendError> {
        if !(self.off_axis_margin.is_finite() && (0.0..=255.0).contains(&self.off_axis_margin)) {
            return Err(FrontendError::config(
                "pose_fit.off_axis_margin",
                format!("must lie in [0, 255], got {}", self.off_axis_margin),
            ));
        }
        if self.range_smoothing_bins == 0 {
            return Err(FrontendError::config(
                "pose_fit.range_smoothing_bins",
                "must be at least 1 (1 = no smoothing)",
            ));
        }
        Ok(())
    }

    /// The image config of the raster: `image` with this margin and
    /// smoothing.
    pub(crate) fn image_config(&self, image: &ImageConfig) -> ImageConfig {
        ImageConfig {
            off_axis: OffAxisSuppression {
                enabled: true,
                margin: self.off_axis_margin,
                ..image.off_axis.clone()
            },
            range_smoothing_bins: self.range_smoothing_bins,
            ..image.clone()
        }
    }
}

/// The largest `ImageConfig::smoothing_sigma_m`, metres.
const MAX_SMOOTHING_SIGMA_M: f64 = 100.0;

/// Cells across the longest beam range when the cell size is derived.
const AUTO_CELLS_PER_RANGE: f64 = 250.0;
/// Limits of a derived cell size, metres.
const AUTO_CELL_MIN_M: f64 = 0.02;
const AUTO_CELL_MAX_M: f64 = 0.2;

impl ImageConfig {
    /// The cell size for these beams: `cell_size_m`, or the derived one
    /// (see the field's doc).
    pub fn cell_size_for(&self, beams: &[SonarBeam]) -> f64 {
        if let Some(cell) = self.cell_size_m {
            return cell;
        }
        let longest = beams.iter().map(SonarBeam::max_range_m).fold(0.0, f64::max);
        let range = self.max_range_m.map_or(longest, |r| r.min(longest));
        (range / AUTO_CELLS_PER_RANGE).clamp(AUTO_CELL_MIN_M, AUTO_CELL_MAX_M)
    }

    pub fn validate(&self) -> Result<(), FrontendError> {
        if let Some(cell) = self.cell_size_m {
            check_positive("cell_size_m", cell)?;
        }
        check_positive("angular_half_width_rad", self.angular_half_width_rad)?;
        check_positive("max_wedge_rad", self.max_wedge_rad)?;
        if self.range_smoothing_bins == 0 {
            return Err(FrontendError::config(
                "range_smoothing_bins",
                "must be at least 1 (1 = no smoothing)",
            ));
        }
        if !(self.blind_zone_m.is_finite() && self.blind_zone_m >= 0.0) {
            return Err(FrontendError::config(
                "blind_zone_m",
                format!("must be finite and >= 0, got {}", self.blind_zone_m),
            ));
        }
        if let Some(r) = self.max_range_m {
            check_positive("max_range_m", r)?;
        }
        if !(0.0..=1.0).contains(&self.background_quantile) {
            return Err(FrontendError::config(
                "background_quantile",
                format!("must lie in [0, 1], got {}", self.background_quantile),
            ));
        }
        if !(self.normalisation_quantile > 0.0 && self.normalisation_quantile <= 1.0) {
            return Err(FrontendError::config(
                "normalisation_quantile",
                format!("must lie in (0, 1], got {}", self.normalisation_quantile),
            ));
        }
        check_positive("intensity_exponent", self.intensity_exponent)?;
        // The smoothing's cost does not depend on σ (`Grid::smooth_gaussian`);
        // beyond the reach of any sonar it only blanks the image.
        if !(self.smoothing_sigma_m.is_finite()
            && (0.0..=MAX_SMOOTHING_SIGMA_M).contains(&self.smoothing_sigma_m))
        {
            return Err(FrontendError::config(
                "smoothing_sigma_m",
                format!(
                    "must lie in [0, {MAX_SMOOTHING_SIGMA_M}] m, got {}",
                    self.smoothing_sigma_m
                ),
            ));
        }
        self.off_axis.validate()?;
        self.pose_fit.validate()?;
        if self.pyramid_levels > 12 {
            return Err(FrontendError::config(
                "pyramid_levels",
                format!(
                    "at most 12 levels (4096 cells), got {}",
                    self.pyramid_levels
                ),
            ));
        }
        Ok(())
    }
}

thread_local! {
    /// The paired profiles of [`AcousticImage::build`] (eight bytes per
    /// bin), kept per thread between images: a fresh buffer of that size
    /// per image comes from `mmap` and costs a page fault per 4 KiB (as
    /// the raster's accumulators, see [`raster`]).
    static PAIRED: RefCell<Vec<[f32; 2]>> = const { RefCell::new(Vec::new()) };
}

/// The acoustic image `I_k`: a grid of intensities in `[0, 1]` in the frame
/// of the rotation's reference pose, plus its search pyramid.
#[derive(Clone, Debug)]
pub struct AcousticImage {
    grid: Grid,
    pyramid: Pyramid,
    /// The samples behind the raster (`None` for images made from a grid).
    polar: Option<PolarSamples>,
    /// The raster of the pose fit, when it differs from `grid`
    /// ([`ImageConfig::pose_fit`]). Quantised: only the last, sub-cell
    /// step of a match reads it, so its `u16` cells cost no measurable
    /// time and halve its memory, while the search's `grid` stays `f32`
    /// (converting cells in the search's inner loops was slower:
    /// EXPERIMENTS.md § Speed notes).
    fit_grid: Option<QuantisedGrid>,
    /// Where the beams reached (`None` for images made from a grid).
    reach: Option<Reach>,
    /// The largest value of the grid (0 for an empty image).
    max_value: f32,
}

impl AcousticImage {
    /// Builds `I_k` from the beams of one rotation and the pose of each beam
    /// frame in the reference frame (`reference_from_beams[j]` for
    /// `beams[j]`: origin at the transducer, x along the beam).
    ///
    /// Errors: invalid config; mismatched lengths; a beam with a non-finite
    /// angle, bin size or first-bin range, or a non-positive bin size; a
    /// non-finite pose; no beams. A rotation whose echoes are all zero gives
    /// an image whose [`AcousticImage::is_empty`] is true, not an error.
    pub fn build(
        beams: &[SonarBeam],
        reference_from_beams: &[Se2],
        config: &ImageConfig,
    ) -> Result<Self, FrontendError> {
        config.validate()?;
        validate_beams(beams, reference_from_beams)?;
        let coded = normalise::normalise_beams_coded(beams, config);
        let cell_m = config.cell_size_for(beams);
        let frames = reference_from_beams;
        let (mut grid, mut fit_grid) = if config.pose_fit.enabled {
            let fit_coded =
                normalise::normalise_beams_coded(beams, &config.pose_fit.image_config(config));
            // Paired straight from the codes (the same values as pairing
            // the decoded profiles, without their two `f32` copies), in
            // this thread's buffer.
            let (grid, fit) = match coded.paired_in(&fit_coded, PAIRED.take()) {
                Some(paired) => {
                    let grids = raster::rasterise_paired(beams, frames, &paired, cell_m, config);
                    PAIRED.set(paired.into_values());
                    grids?
                }
                None => raster::rasterise_pair(
                    beams,
                    frames,
                    &coded.decoded(),
                    &fit_coded.decoded(),
                    cell_m,
                    config,
                )?,
            };
            (grid, Some(fit))
        } else {
            let grid = raster::rasterise(beams, frames, &coded.decoded(), cell_m, config)?;
            (grid, None)
        };
        if config.smoothing_sigma_m > 0.0 {
            grid.smooth_gaussian(config.smoothing_sigma_m / cell_m);
            if let Some(fit) = &mut fit_grid {
                fit.smooth_gaussian(config.smoothing_sigma_m / cell_m);
            }
        }
        let mut image = Self::from_grid(grid, config.pyramid_levels);
        image.fit_grid = fit_grid.map(|fit| fit.quantised());
        image.reach = Reach::of_beams(
            beams,
            reference_from_beams,
            config.max_range_m,
            config.max_wedge_rad,
        );
        image.polar = Some(PolarSamples::new(
            beams,
            reference_from_beams,
            coded,
            config,
        ));
        Ok(image)
    }

    /// The search raster of [`Self::build`] alone (its [`Self::grid`],
    /// cell for cell), without the pyramid, the pose-fit raster and the
    /// polar samples: for a look at the image (outputs), at a fraction of
    /// the cost. Preconditions and errors as [`Self::build`].
    pub fn build_grid(
        beams: &[SonarBeam],
        reference_from_beams: &[Se2],
        config: &ImageConfig,
    ) -> Result<Grid, FrontendError> {
        config.validate()?;
        validate_beams(beams, reference_from_beams)?;
        // The same profiles as `build` (coded, then decoded), so that the
        // cells are the same.
        let profiles = normalise::normalise_beams_coded(beams, config).decoded();
        let cell_m = config.cell_size_for(beams);
        let mut grid = raster::rasterise(beams, reference_from_beams, &profiles, cell_m, config)?;
        if config.smoothing_sigma_m > 0.0 {
            grid.smooth_gaussian(config.smoothing_sigma_m / cell_m);
        }
        Ok(grid)
    }

    /// Wraps an existing grid (for tests and for images made elsewhere).
    pub fn from_grid(grid: Grid, pyramid_levels: usize) -> Self {
        let pyramid = Pyramid::build(&grid, pyramid_levels);
        let max_value = pyramid.max_value();
        Self {
            grid,
            pyramid,
            polar: None,
            fit_grid: None,
            reach: None,
            max_value,
        }
    }

    /// This image with `grid` as its pose-fit raster
    /// ([`Self::pose_fit_grid`]), for images made from grids.
    pub fn with_pose_fit_grid(mut self, grid: Grid) -> Self {
        self.fit_grid = Some(grid.quantised());
        self
    }

    /// This image with `reach` as the reach of its beams ([`Self::reach`]),
    /// for images made from grids whose beams are known.
    pub fn with_reach(mut self, reach: Reach) -> Self {
        self.reach = Some(reach);
        self
    }

    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// The raster the matcher's final sub-cell pose fit reads, built as
    /// [`ImageConfig::pose_fit`] says; `None` for images made from a grid
    /// or with the pose-fit raster disabled (the fit then has nothing to
    /// add to the search's estimate).
    pub fn pose_fit_grid(&self) -> Option<&QuantisedGrid> {
        self.fit_grid.as_ref()
    }

    pub fn pyramid(&self) -> &Pyramid {
        &self.pyramid
    }

    pub fn cell_size_m(&self) -> f64 {
        self.grid.cell_size_m()
    }

    /// True when no cell holds any echo (nothing to match against).
    pub fn is_empty(&self) -> bool {
        self.max_value <= 0.0
    }

    /// `I(x, y)`: bilinear interpolation between cell centres, 0 outside.
    pub fn value_at(&self, x_m: f64, y_m: f64) -> f64 {
        self.grid.bilinear(x_m, y_m)
    }

    /// `I(x, y)` and its analytic gradient `(∂I/∂x, ∂I/∂y)` in 1/m. On a cell
    /// boundary the gradient of the cell above/right is returned.
    pub fn value_and_gradient(&self, x_m: f64, y_m: f64) -> (f64, Vector2<f64>) {
        self.grid.bilinear_with_gradient(x_m, y_m)
    }

    /// `I(x, y)` interpolated from the samples themselves (see [`polar`]);
    /// the raster's bilinear value for images made from a grid.
    pub fn fine_value_at(&self, x_m: f64, y_m: f64) -> f64 {
        match &self.polar {
            Some(p) => p.value_at(x_m, y_m),
            None => self.grid.bilinear(x_m, y_m),
        }
    }

    /// [`AcousticImage::fine_value_at`] and its gradient in 1/m (central
    /// differences over a quarter of the finest bin for the samples).
    pub fn fine_value_and_gradient(&self, x_m: f64, y_m: f64) -> (f64, Vector2<f64>) {
        match &self.polar {
            Some(p) => p.value_and_gradient(x_m, y_m, 0.25 * p.finest_bin_m()),
            None => self.grid.bilinear_with_gradient(x_m, y_m),
        }
    }

    /// Bytes the image holds on the heap (rasters, built pyramid levels,
    /// samples): what a node's image costs for the rest of the mission.
    pub fn heap_bytes(&self) -> usize {
        self.grid.heap_bytes()
            + self.fit_grid.as_ref().map_or(0, Grid::heap_bytes)
            + self.pyramid.heap_bytes()
            + self.polar.as_ref().map_or(0, PolarSamples::heap_bytes)
            + self.reach.as_ref().map_or(0, Reach::heap_bytes)
    }

    /// Where the image's beams reached ([`reach`]); `None` for images made
    /// from a grid, whose reach is unknown.
    pub fn reach(&self) -> Option<&Reach> {
        self.reach.as_ref()
    }

    /// The sample model behind the raster, when the image was built from beams.
    pub fn samples(&self) -> Option<&PolarSamples> {
        self.polar.as_ref()
    }
}

fn validate_beams(beams: &[SonarBeam], reference_from_beams: &[Se2]) -> Result<(), FrontendError> {
    if beams.is_empty() {
        return Err(FrontendError::insufficient(
            "acoustic image",
            "the rotation has no beams",
        ));
    }
    if beams.len() != reference_from_beams.len() {
        return Err(FrontendError::input(
            "acoustic image",
            "reference_from_beams",
            format!(
                "{} poses for {} beams",
                reference_from_beams.len(),
                beams.len()
            ),
        ));
    }
    for (j, (beam, pose)) in beams.iter().zip(reference_from_beams).enumerate() {
        let record = || format!("beam {j} (stamp {} s)", beam.stamp_s);
        if !beam.angle_rad.is_finite() {
            return Err(FrontendError::input(record(), "angle_rad", "not finite"));
        }
        if !(beam.bin_size_m.is_finite() && beam.bin_size_m > 0.0) {
            return Err(FrontendError::input(
                record(),
                "bin_size_m",
                format!("must be positive and finite, got {}", beam.bin_size_m),
            ));
        }
        if !(beam.first_bin_range_m.is_finite() && beam.first_bin_range_m >= 0.0) {
            return Err(FrontendError::input(
                record(),
                "first_bin_range_m",
                format!("must be finite and >= 0, got {}", beam.first_bin_range_m),
            ));
        }
        if !pose.is_finite() {
            return Err(FrontendError::input(
                record(),
                "reference_from_beam",
                "pose is not finite",
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::synthetic::{SceneConfig, static_rotation};

    #[test]
    fn default_config_is_valid_and_bad_values_are_named() {
        ImageConfig::default().validate().unwrap();
        let bad = ImageConfig {
            cell_size_m: Some(0.0),
            ..ImageConfig::default()
        };
        let err = bad.validate().unwrap_err();
        assert!(err.to_string().contains("cell_size_m"), "{err}");
        let bad = ImageConfig {
            background_quantile: 1.5,
            ..ImageConfig::default()
        };
        assert!(
            bad.validate()
                .unwrap_err()
                .to_string()
                .contains("background_quantile")
        );
        for (pose_fit, field) in [
            (
                PoseFitRaster {
                    off_axis_margin: 300.0,
                    ..PoseFitRaster::default()
                },
                "pose_fit.off_axis_margin",
            ),
            (
                PoseFitRaster {
                    range_smoothing_bins: 0,
                    ..PoseFitRaster::default()
                },
                "pose_fit.range_smoothing_bins",
            ),
        ] {
            let bad = ImageConfig {
                pose_fit,
                ..ImageConfig::default()
            };
            let err = bad.validate().unwrap_err().to_string();
            assert!(err.contains(field), "{err}");
        }
    }

    #[test]
    fn an_image_holds_its_f32_raster_u16_fit_raster_byte_levels_and_coded_samples() {
        let rotation = synthetic::static_rotation(&synthetic::SceneConfig::default(), 2);
        let (beams, frames) = (&rotation.beams, &rotation.reference_from_beams);
        let config = ImageConfig::default();
        let image = AcousticImage::build(beams, frames, &config).unwrap();
        let cells = image.grid().width() * image.grid().height();
        let levels = config.pyramid_levels.min(pyramid::EAGER_LEVELS);
        assert_eq!(image.pyramid().built_levels(), levels);
        let bins: usize = beams.iter().map(|b| b.intensities.len()).sum();
        // Levels 1 and 2 hold a byte per cell, level h > 2 one per
        // 2^(h-2) x 2^(h-2) cells.
        let level_bytes = |h: usize| {
            let s = pyramid::stride(h);
            image.grid().width().div_ceil(s) * image.grid().height().div_ceil(s)
        };
        let rasters = 4 * cells + 2 * cells + (1..=levels).map(level_bytes).sum::<usize>();
        // The samples: one byte per bin, plus a few hundred bytes per beam
        // and the code table at most.
        let samples = image.heap_bytes() - rasters;
        assert!(
            samples >= bins && samples <= bins + 200 * beams.len() + 1024,
            "{samples} bytes for {bins} bins"
        );
        // Levels built later count when built.
        image.pyramid().level(levels + 1);
        assert_eq!(
            image.heap_bytes(),
            rasters + samples + level_bytes(levels + 1)
        );
    }

    #[test]
    fn the_pose_fit_raster_has_its_own_margin_and_smoothing() {
        let rotation = synthetic::static_rotation(&synthetic::SceneConfig::default(), 2);
        let (beams, frames) = (&rotation.beams, &rotation.reference_from_beams);
        let with = AcousticImage::build(beams, frames, &ImageConfig::default()).unwrap();
        let off = ImageConfig {
            pose_fit: PoseFitRaster {
                enabled: false,
                ..PoseFitRaster::default()
            },
            ..ImageConfig::default()
        };
        let without = AcousticImage::build(beams, frames, &off).unwrap();
        // The searched raster does not depend on the pose-fit raster.
        assert_eq!(with.grid(), without.grid());
        assert!(without.pose_fit_grid().is_none());
        // The pose-fit raster is the image built with its settings.
        let fit_config = ImageConfig {
            off_axis: OffAxisSuppression {
                margin: 10.0,
                ..OffAxisSuppression::for_images()
            },
            range_smoothing_bins: 1,
            ..off
        };
        let alone = AcousticImage::build(beams, frames, &fit_config).unwrap();
        // (Kept quantised: see `AcousticImage::fit_grid`.)
        assert_eq!(with.pose_fit_grid(), Some(&alone.grid().quantised()));
        assert_ne!(with.pose_fit_grid(), Some(&with.grid().quantised()));
    }

    #[test]
    fn cell_size_is_derived_from_the_range_unless_given() {
        let beam = |bins: usize, bin_size_m: f64| SonarBeam {
            stamp_s: 0.0,
            angle_rad: 0.0,
            bin_size_m,
            first_bin_range_m: 0.0,
            intensities: vec![0; bins],
        };
        let auto = ImageConfig::default();
        assert!((auto.cell_size_for(&[beam(500, 0.1)]) - 0.2).abs() < 1e-12);
        assert!((auto.cell_size_for(&[beam(1200, 10.0 / 1200.0)]) - 0.04).abs() < 1e-12);
        assert!((auto.cell_size_for(&[beam(200, 0.01)]) - 0.02).abs() < 1e-12);
        assert!((auto.cell_size_for(&[beam(1000, 1.0)]) - 0.2).abs() < 1e-12);
        let clipped = ImageConfig {
            max_range_m: Some(20.0),
            ..ImageConfig::default()
        };
        assert!((clipped.cell_size_for(&[beam(500, 0.1)]) - 0.08).abs() < 1e-12);
        let fixed = ImageConfig {
            cell_size_m: Some(0.15),
            ..ImageConfig::default()
        };
        assert_eq!(fixed.cell_size_for(&[beam(500, 0.1)]), 0.15);
    }

    #[test]
    fn config_rejects_unknown_keys() {
        let err = serde_json::from_str::<ImageConfig>(r#"{"cell_size": 0.1}"#).unwrap_err();
        assert!(err.to_string().contains("cell_size"), "{err}");
        let cfg: ImageConfig =
            serde_json::from_str(r#"{"interpolation": "nearest", "cell_size_m": 0.1}"#).unwrap();
        assert_eq!(cfg.interpolation, Interpolation::Nearest);
        assert_eq!(cfg.cell_size_m, Some(0.1));
    }

    #[test]
    fn bad_beams_are_errors_naming_the_beam() {
        let rotation = static_rotation(&SceneConfig::default(), 1);
        let mut beams = rotation.beams.clone();
        beams[7].angle_rad = f64::NAN;
        let err = AcousticImage::build(
            &beams,
            &rotation.reference_from_beams,
            &ImageConfig::default(),
        )
        .unwrap_err();
        assert!(err.to_string().contains("beam 7"), "{err}");
        assert!(err.to_string().contains("angle_rad"), "{err}");

        let mut beams = rotation.beams.clone();
        beams[3].bin_size_m = 0.0;
        let err = AcousticImage::build(
            &beams,
            &rotation.reference_from_beams,
            &ImageConfig::default(),
        )
        .unwrap_err();
        assert!(err.to_string().contains("bin_size_m"), "{err}");

        let mut poses = rotation.reference_from_beams.clone();
        poses[2] = Se2::new(f64::NAN, 0.0, 0.0);
        let err =
            AcousticImage::build(&rotation.beams, &poses, &ImageConfig::default()).unwrap_err();
        assert!(err.to_string().contains("beam 2"), "{err}");

        let err = AcousticImage::build(
            &rotation.beams,
            &rotation.reference_from_beams[1..],
            &ImageConfig::default(),
        )
        .unwrap_err();
        assert!(err.to_string().contains("poses for"), "{err}");
        assert!(AcousticImage::build(&[], &[], &ImageConfig::default()).is_err());
    }

    #[test]
    fn silent_rotation_gives_an_empty_image() {
        let rotation = static_rotation(&SceneConfig::default(), 1);
        let mut beams = rotation.beams.clone();
        for beam in &mut beams {
            beam.intensities.iter_mut().for_each(|v| *v = 0);
        }
        let image = AcousticImage::build(
            &beams,
            &rotation.reference_from_beams,
            &ImageConfig::default(),
        )
        .unwrap();
        assert!(image.is_empty());
        assert_eq!(image.value_at(3.0, 2.0), 0.0);
    }

    #[test]
    fn both_interpolations_show_the_walls_and_not_the_open_water() {
        let scene = SceneConfig::default();
        let rotation = static_rotation(&scene, 3);
        for interpolation in [Interpolation::Nearest, Interpolation::AngularWindow] {
            let config = ImageConfig {
                interpolation,
                smoothing_sigma_m: 0.0,
                ..ImageConfig::default()
            };
            let image =
                AcousticImage::build(&rotation.beams, &rotation.reference_from_beams, &config)
                    .unwrap();
            // The true wall hits are bright, points 1.5 m inside them are dark.
            let mut on_wall = 0.0;
            let mut inside = 0.0;
            for p in &rotation.wall_points {
                on_wall += image.value_at(p.x, p.y);
                let r = p.coords.norm();
                let q = p.coords * ((r - 1.5) / r);
                inside += image.value_at(q.x, q.y);
            }
            let n = rotation.wall_points.len() as f64;
            assert!(
                on_wall / n > 0.3,
                "{interpolation:?}: wall mean {}",
                on_wall / n
            );
            assert!(
                inside / n < 0.05,
                "{interpolation:?}: water mean {}",
                inside / n
            );
        }
    }
}
