//! Which of a sequence of [`StoredImage`]s stay in memory: a byte budget,
//! least recently read released first.
//!
//! A mission keeps every node's image inputs (beams and frames, see
//! [`super::stored`]) and the images themselves only while
//! [`ImageResidency`] lets it: after each step of work (a node added, a
//! batch of matches) [`ImageResidency::enforce`] releases the least
//! recently read images (ties: the oldest first) until those held fit in
//! the budget, never the newest one (the next sequential match reads it).
//! A released image is built again, cell for cell the same, when a match
//! reads it, so the budget changes a run's memory and time, never its
//! result.
//!
//! Sequences whose images fit in the budget (a few hundred sonar
//! rotations at the default) hold every image and build none twice. On a
//! longer mission the images read are those of the places being
//! revisited, a few per new node, which the rule keeps while the revisit
//! lasts.

use super::stored::StoredImage;

/// Default budget: bytes of images held at most after each step (a step
/// in progress may add the images its matches read). Sized so that a run
/// of the longest benchmark mission (`echofield bench-long`, 1,397
/// rotations), images, beams, navigation and solver together, meets issue
/// 36's 1.5 GB target of resident memory (measured: EXPERIMENTS.md § Long
/// missions).
pub const DEFAULT_BUDGET_BYTES: usize = 704 << 20;

/// The policy's state: when each image was last read.
#[derive(Clone, Debug)]
pub struct ImageResidency {
    /// Per image: its read count when last looked at, and the step at
    /// which that count last changed.
    seen: Vec<(usize, u64)>,
    /// Images that may be resident (not released since last read).
    maybe_resident: Vec<bool>,
    step: u64,
    budget_bytes: usize,
    releases: usize,
}

impl Default for ImageResidency {
    fn default() -> Self {
        Self::new(DEFAULT_BUDGET_BYTES)
    }
}

impl ImageResidency {
    /// A policy holding at most `budget_bytes` of images.
    pub fn new(budget_bytes: usize) -> Self {
        Self {
            seen: Vec::new(),
            maybe_resident: Vec::new(),
            step: 0,
            budget_bytes,
            releases: 0,
        }
    }

    /// Images released so far.
    pub fn releases(&self) -> usize {
        self.releases
    }

    /// Looks at the `n` images `image(0..n)` (the same sequence at every
    /// call, grown at the end) after a step of work and releases the least
    /// recently read ones until those held fit in the budget. Image
    /// `n - 1` stays.
    pub fn enforce<'a>(&mut self, n: usize, image: impl Fn(usize) -> &'a StoredImage) {
        self.step += 1;
        self.seen.resize(n, (0, self.step));
        self.maybe_resident.resize(n, true);
        let step = self.step;
        let mut held: Vec<(u64, usize, usize)> = Vec::new();
        let states = self.seen.iter_mut().zip(&mut self.maybe_resident);
        for (i, (seen, maybe_resident)) in states.enumerate() {
            let reads = image(i).reads();
            if reads != seen.0 {
                *seen = (reads, step);
                *maybe_resident = true;
            }
            if !*maybe_resident || i + 1 == n {
                continue;
            }
            match image(i).resident_bytes() {
                0 => *maybe_resident = false,
                bytes => held.push((seen.1, i, bytes)),
            }
        }
        let newest = n.checked_sub(1).map_or(0, |i| image(i).resident_bytes());
        let mut total = newest + held.iter().map(|h| h.2).sum::<usize>();
        // Least recently read first, then the oldest.
        held.sort_unstable();
        for (_, i, bytes) in held {
            if total <= self.budget_bytes {
                break;
            }
            if image(i).release() {
                self.releases += 1;
                total -= bytes;
            }
            self.maybe_resident[i] = false;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::ImageConfig;
    use crate::image::synthetic::{SceneConfig, static_rotation};
    use std::sync::Arc;

    fn images(n: usize) -> Vec<StoredImage> {
        let config = Arc::new(ImageConfig::default());
        (0..n)
            .map(|seed| {
                let r = static_rotation(&SceneConfig::default(), seed as u64);
                StoredImage::build(r.beams, r.reference_from_beams, Arc::clone(&config)).unwrap()
            })
            .collect()
    }

    #[test]
    fn the_least_recently_read_images_go_first_and_the_newest_stays() {
        let stored = images(5);
        let one = stored[0].resident_bytes();
        // Room for about three images.
        let mut residency = ImageResidency::new(3 * one + one / 2);
        residency.enforce(3, |i| &stored[i]);
        assert_eq!(residency.releases(), 0);
        // Images 0 and 1 read after image 2 was added: 2 is now the least
        // recently read old image, but 3 and 4 need room.
        stored[0].image().unwrap();
        residency.enforce(3, |i| &stored[i]);
        stored[1].image().unwrap();
        residency.enforce(5, |i| &stored[i]);
        let resident: Vec<bool> = stored.iter().map(StoredImage::is_resident).collect();
        assert_eq!(resident, [false, true, false, true, true]);
        assert_eq!(residency.releases(), 2);
        // Reading a released image builds it again; the budget then
        // releases the least recently read other one.
        stored[2].image().unwrap();
        residency.enforce(5, |i| &stored[i]);
        let resident: Vec<bool> = stored.iter().map(StoredImage::is_resident).collect();
        assert_eq!(resident, [false, false, true, true, true]);
        assert_eq!(stored[2].rebuilds(), 1);
    }

    #[test]
    fn a_zero_budget_keeps_only_the_newest() {
        let stored = images(3);
        let mut residency = ImageResidency::new(0);
        residency.enforce(3, |i| &stored[i]);
        let resident: Vec<bool> = stored.iter().map(StoredImage::is_resident).collect();
        assert_eq!(resident, [false, false, true]);
        residency.enforce(0, |i| &stored[i]);
    }
}
