//! An acoustic image kept for the rest of a mission at the cost of its
//! inputs, not of its rasters.
//!
//! A node's image `I_k` is a loop-closure target until the mission ends,
//! but on a long mission only the images of the places being revisited
//! are read at any time. A [`StoredImage`] keeps what the image is built
//! from (the rotation's beams and their motion-compensated frames, and the
//! [`ImageConfig`]) and, while it is in use, the image itself. Releasing
//! it ([`StoredImage::release`]) drops the rasters, the pyramid and the
//! samples; the next read ([`StoredImage::image`]) builds the image again
//! with [`AcousticImage::build`] from the same inputs, which gives the same
//! image, cell for cell, so every match against it gives the same result
//! (the build is deterministic and single-threaded).
//!
//! Cost model: a resident image holds about 12 bytes per raster cell plus
//! a byte per bin (module doc of [`super`]); a released one holds its
//! beams (a byte per bin plus a few dozen bytes per beam) and one
//! [`Se2`] per beam. Who releases what, and when, is the owner's policy.
//!
//! Reads and releases take `&self` and may come from several threads: a
//! build happens under the image's own lock, so concurrent readers of a
//! released image wait for one build instead of each doing it.

use super::{AcousticImage, Grid, ImageConfig};
use crate::error::FrontendError;
use crate::sensors::SonarBeam;
use echofield_graph::Se2;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

/// Where an image's raster lies in the image's frame, known without
/// building it: lower-left corner of cell (0, 0), metres; cell size,
/// metres; cells per row and column.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridExtent {
    pub origin_m: (f64, f64),
    pub cell_size_m: f64,
    pub width: usize,
    pub height: usize,
}

impl GridExtent {
    /// The extent of `grid`.
    pub fn of<T: super::CellValue>(grid: &Grid<T>) -> Self {
        Self {
            origin_m: grid.origin_m(),
            cell_size_m: grid.cell_size_m(),
            width: grid.width(),
            height: grid.height(),
        }
    }
}

/// What an image is built from.
#[derive(Clone, Debug)]
struct ImageSource {
    beams: Vec<SonarBeam>,
    /// `reference_from_beams`, one per beam.
    frames: Vec<Se2>,
    config: Arc<ImageConfig>,
}

/// An acoustic image that can be released and built again on demand (see
/// the module doc).
#[derive(Debug)]
pub struct StoredImage {
    /// `None` for images wrapped with [`StoredImage::resident_only`].
    source: Option<ImageSource>,
    resident: Mutex<Option<Arc<AcousticImage>>>,
    /// [`AcousticImage::is_empty`], kept so that it needs no build.
    empty: bool,
    /// The raster's extent, likewise.
    extent: GridExtent,
    /// Reads so far ([`StoredImage::image`]), for the owner's policy.
    reads: AtomicUsize,
    /// Builds after a release so far.
    rebuilds: AtomicUsize,
}

impl StoredImage {
    /// Builds the image of `beams` with their frames `reference_from_beams`
    /// (as [`AcousticImage::build`]) and keeps it resident, with its inputs.
    /// Errors: those of [`AcousticImage::build`].
    pub fn build(
        beams: Vec<SonarBeam>,
        reference_from_beams: Vec<Se2>,
        config: Arc<ImageConfig>,
    ) -> Result<Self, FrontendError> {
        let image = AcousticImage::build(&beams, &reference_from_beams, &config)?;
        Ok(Self {
            empty: image.is_empty(),
            extent: GridExtent::of(image.grid()),
            resident: Mutex::new(Some(Arc::new(image))),
            source: Some(ImageSource {
                beams,
                frames: reference_from_beams,
                config,
            }),
            reads: AtomicUsize::new(0),
            rebuilds: AtomicUsize::new(0),
        })
    }

    /// Wraps an image without its inputs (made from a grid, in tests):
    /// it is never released.
    pub fn resident_only(image: AcousticImage) -> Self {
        Self {
            empty: image.is_empty(),
            extent: GridExtent::of(image.grid()),
            resident: Mutex::new(Some(Arc::new(image))),
            source: None,
            reads: AtomicUsize::new(0),
            rebuilds: AtomicUsize::new(0),
        }
    }

    /// The image: the resident one, or built again from its inputs and kept
    /// resident. Errors: those of [`AcousticImage::build`], which succeeded
    /// on the same inputs before, so only a corrupted store fails.
    pub fn image(&self) -> Result<Arc<AcousticImage>, FrontendError> {
        self.reads.fetch_add(1, Ordering::Relaxed);
        let mut resident = self.lock();
        if let Some(image) = resident.as_ref() {
            return Ok(Arc::clone(image));
        }
        let Some(source) = &self.source else {
            // Images without inputs are never released.
            return Err(FrontendError::insufficient(
                "stored image",
                "released image without its beams",
            ));
        };
        let image = Arc::new(AcousticImage::build(
            &source.beams,
            &source.frames,
            &source.config,
        )?);
        self.rebuilds.fetch_add(1, Ordering::Relaxed);
        *resident = Some(Arc::clone(&image));
        Ok(image)
    }

    /// The image for one look (an output): the resident one, or built
    /// from its inputs and not kept. Errors as [`Self::image`]. Does not
    /// count as a read.
    pub fn image_once(&self) -> Result<Arc<AcousticImage>, FrontendError> {
        if let Some(image) = self.lock().as_ref() {
            return Ok(Arc::clone(image));
        }
        let Some(source) = &self.source else {
            return Err(FrontendError::insufficient(
                "stored image",
                "released image without its beams",
            ));
        };
        AcousticImage::build(&source.beams, &source.frames, &source.config).map(Arc::new)
    }

    /// The image's search raster ([`AcousticImage::grid`]) for one look
    /// (an output): copied from the resident image, or built alone from
    /// the inputs ([`AcousticImage::build_grid`], the same cells) and not
    /// kept. Errors as [`Self::image`]. Does not count as a read.
    pub fn grid_once(&self) -> Result<Grid, FrontendError> {
        if let Some(image) = self.lock().as_ref() {
            return Ok(image.grid().clone());
        }
        let Some(source) = &self.source else {
            return Err(FrontendError::insufficient(
                "stored image",
                "released image without its beams",
            ));
        };
        AcousticImage::build_grid(&source.beams, &source.frames, &source.config)
    }

    /// A submap: one image built from this image's beams and those of
    /// `others`, each other image's beam frames carried into this image's
    /// frame by its `reference_from_other` (as [`AcousticImage::build`] on
    /// the union; where beams of several rotations cover a cell, the cell
    /// is their mean, as where the beams of one rotation overlap). Neither
    /// image is read or built. `None` when this image or one of `others`
    /// was made without its inputs ([`StoredImage::resident_only`]).
    /// Errors: those of [`AcousticImage::build`].
    pub fn composite(
        &self,
        others: &[(&StoredImage, Se2)],
    ) -> Option<Result<AcousticImage, FrontendError>> {
        let source = self.source.as_ref()?;
        let mut beams = source.beams.clone();
        let mut frames = source.frames.clone();
        for (other, reference_from_other) in others {
            let other = other.source.as_ref()?;
            beams.extend(other.beams.iter().cloned());
            frames.extend(other.frames.iter().map(|f| reference_from_other.compose(f)));
        }
        Some(AcousticImage::build(&beams, &frames, &source.config))
    }

    /// Drops the resident image (readers holding it keep their copy until
    /// they finish). Returns whether an image was dropped: `false` when
    /// none was resident, and for images without their inputs, which stay.
    pub fn release(&self) -> bool {
        self.source.is_some() && self.lock().take().is_some()
    }

    /// Bytes of the resident image (0 when released).
    pub fn resident_bytes(&self) -> usize {
        self.lock().as_ref().map_or(0, |i| i.heap_bytes())
    }

    /// Whether the image is held now.
    pub fn is_resident(&self) -> bool {
        self.lock().is_some()
    }

    /// [`AcousticImage::is_empty`], without building.
    pub fn is_empty(&self) -> bool {
        self.empty
    }

    /// The raster's extent, without building.
    pub fn extent(&self) -> GridExtent {
        self.extent
    }

    /// Reads so far.
    pub fn reads(&self) -> usize {
        self.reads.load(Ordering::Relaxed)
    }

    /// Builds after a release so far.
    pub fn rebuilds(&self) -> usize {
        self.rebuilds.load(Ordering::Relaxed)
    }

    /// Bytes held on the heap: the inputs and, while resident, the image.
    pub fn heap_bytes(&self) -> usize {
        use std::mem::size_of;
        let source = self.source.as_ref().map_or(0, |s| {
            s.beams.capacity() * size_of::<SonarBeam>()
                + s.beams
                    .iter()
                    .map(|b| b.intensities.capacity())
                    .sum::<usize>()
                + s.frames.capacity() * size_of::<Se2>()
        });
        source + self.resident_bytes()
    }

    /// The lock, also after a panic of another holder (the guarded value is
    /// a cache: any state of it is valid).
    fn lock(&self) -> MutexGuard<'_, Option<Arc<AcousticImage>>> {
        self.resident.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl Clone for StoredImage {
    fn clone(&self) -> Self {
        Self {
            source: self.source.clone(),
            resident: Mutex::new(self.lock().clone()),
            empty: self.empty,
            extent: self.extent,
            reads: AtomicUsize::new(self.reads()),
            rebuilds: AtomicUsize::new(self.rebuilds()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::synthetic::{SceneConfig, static_rotation};

    fn stored() -> (StoredImage, AcousticImage) {
        let rotation = static_rotation(&SceneConfig::default(), 3);
        let config = ImageConfig::default();
        let image =
            AcousticImage::build(&rotation.beams, &rotation.reference_from_beams, &config).unwrap();
        let stored = StoredImage::build(
            rotation.beams.clone(),
            rotation.reference_from_beams.clone(),
            Arc::new(config),
        )
        .unwrap();
        (stored, image)
    }

    #[test]
    fn a_released_image_is_built_again_cell_for_cell_in_far_fewer_bytes() {
        let (stored, image) = stored();
        assert!(stored.is_resident() && !stored.is_empty());
        assert_eq!(stored.extent(), GridExtent::of(image.grid()));
        let resident_bytes = stored.heap_bytes();
        assert!(stored.release());
        assert!(!stored.release());
        assert!(!stored.is_resident() && !stored.is_empty());
        // The beams are a small part of what the image holds.
        assert!(
            stored.heap_bytes() * 4 < resident_bytes,
            "{} of {resident_bytes} bytes",
            stored.heap_bytes()
        );
        // A look for an output builds it without keeping it; the raster
        // alone is the same too.
        assert_eq!(stored.image_once().unwrap().grid(), image.grid());
        assert_eq!(&stored.grid_once().unwrap(), image.grid());
        assert!(!stored.is_resident());
        assert!(!stored.is_resident() && stored.resident_bytes() == 0);
        let back = stored.image().unwrap();
        assert!(stored.is_resident());
        assert_eq!(stored.resident_bytes(), image.heap_bytes());
        assert_eq!(stored.rebuilds(), 1);
        assert_eq!(back.grid(), image.grid());
        assert_eq!(back.pose_fit_grid(), image.pose_fit_grid());
        assert_eq!(back.pyramid(), image.pyramid());
        for (x, y) in [(1.0, 2.0), (-3.5, 0.25), (7.0, -4.0)] {
            assert_eq!(back.fine_value_at(x, y), image.fine_value_at(x, y));
        }
        // A resident read builds nothing.
        stored.image().unwrap();
        assert_eq!((stored.reads(), stored.rebuilds()), (2, 1));
    }

    #[test]
    fn a_submap_holds_the_echoes_of_the_older_rotation_where_it_placed_them() {
        // The newer rotation heard nothing (a thresholded log that dropped
        // every wall); the older one heard the scene, from a pose 1.5 m
        // and 0.2 rad away in the newer one's frame.
        let rotation = static_rotation(&SceneConfig::default(), 3);
        let config = Arc::new(ImageConfig::default());
        let mut silent = rotation.beams.clone();
        for beam in &mut silent {
            beam.intensities.iter_mut().for_each(|v| *v = 0);
        }
        let frames = rotation.reference_from_beams.clone();
        let newer = StoredImage::build(silent, frames.clone(), Arc::clone(&config)).unwrap();
        let older = StoredImage::build(rotation.beams.clone(), frames, config).unwrap();
        assert!(newer.is_empty() && !older.is_empty());
        let newer_from_older = Se2::new(1.5, -0.5, 0.2);
        let submap = newer
            .composite(&[(&older, newer_from_older)])
            .unwrap()
            .unwrap();
        // The older image's brightest place, on a 0.25 m lattice.
        let old = older.image().unwrap();
        let lattice = (-120..=120).flat_map(|i| (-120..=120).map(move |j| (i, j)));
        let (x, y) = lattice
            .map(|(i, j)| (f64::from(i) * 0.25, f64::from(j) * 0.25))
            .max_by(|a, b| old.value_at(a.0, a.1).total_cmp(&old.value_at(b.0, b.1)))
            .unwrap();
        let peak = old.value_at(x, y);
        assert!(peak > 0.5, "{peak}");
        // In the submap it is where the older pose puts it, not where it
        // was in the older frame (the rotation moved it by > 1 m there).
        let (u, v) = newer_from_older.transform_xy(x, y);
        assert!(
            submap.value_at(u, v) > 0.25 * peak,
            "{}",
            submap.value_at(u, v)
        );
        assert!(submap.value_at(x, y) < submap.value_at(u, v));
        // Images made without their inputs give no submap.
        let bare = StoredImage::resident_only(old.as_ref().clone());
        assert!(bare.composite(&[(&older, newer_from_older)]).is_none());
        assert!(newer.composite(&[(&bare, newer_from_older)]).is_none());
    }

    #[test]
    fn a_released_old_image_still_matches_a_new_scan_as_before() {
        use crate::image::synthetic::{RotationPath, simulate_rotation};
        use crate::matcher::{MatcherConfig, SearchWindow, match_scan};
        // An old rotation's image, and a scan of a later rotation 0.8 m on.
        let scene = SceneConfig::default();
        let (old, _) = stored();
        let path = RotationPath::fixed(Se2::new(0.8, -0.3, 0.04));
        let new = simulate_rotation(&scene, &path, 7);
        let (prior, window) = (Se2::new(0.6, -0.1, 0.0), SearchWindow::new(1.0, 1.0, 0.1));
        let config = MatcherConfig::default();
        let run = |image: &AcousticImage| {
            match_scan(&new.wall_points, image, &prior, &window, &config)
                .unwrap()
                .matched()
                .cloned()
                .expect("a match")
        };
        let resident = run(&old.image().unwrap());
        assert!(old.release());
        let rebuilt = run(&old.image().unwrap());
        assert_eq!(old.rebuilds(), 1);
        assert_eq!(rebuilt.image_from_scan, resident.image_from_scan);
        assert_eq!(rebuilt.score, resident.score);
        assert_eq!(rebuilt.covariance, resident.covariance);
        // And the match is the right one: the new rotation is at
        // (0.8, -0.3, 0.04) in the old one's frame.
        let t = rebuilt.image_from_scan.translation();
        assert!((t.x - 0.8).abs() < 0.1 && (t.y + 0.3).abs() < 0.1, "{t:?}");
    }

    #[test]
    fn concurrent_readers_of_a_released_image_share_one_build() {
        let (stored, _) = stored();
        stored.release();
        std::thread::scope(|s| {
            for _ in 0..4 {
                s.spawn(|| stored.image().unwrap());
            }
        });
        assert_eq!(stored.rebuilds(), 1);
        assert_eq!(stored.reads(), 4);
    }

    #[test]
    fn an_image_without_inputs_stays_resident() {
        let (_, image) = stored();
        let stored = StoredImage::resident_only(image.clone());
        assert!(!stored.release());
        assert!(stored.is_resident());
        assert_eq!(stored.image().unwrap().grid(), image.grid());
        let copy = stored.clone();
        assert!(copy.is_resident() && !copy.is_empty());
    }
}
