//! Checks of what the input gave the pipeline, after the stages that can
//! silently come out empty: runs of beams that formed no rotation (a
//! warning), and rotations that gave no scan or no image at all (an error
//! that names the configuration keys that blank the beams, instead of a
//! trajectory that is dead reckoning without a word).

use super::SlamError;
use super::config::SlamConfig;
use echofield_frontend::nodes::NodeData;
use echofield_frontend::warnings::{Warning, WarningKind};
use std::ops::Range;

/// The beams that ended in no rotation between two rotations (cut by a
/// gap, a change of settings or a reversal: see
/// `echofield_frontend::rotation`), one occurrence per run of such beams.
/// The partial turns before the first rotation and after the last are
/// left out: nearly every log starts and ends in the middle of a turn.
///
/// `rotations` holds each rotation's beam range and the stamp of the beam
/// right after it, in order.
pub(super) fn dropped_rotations(rotations: &[(Range<usize>, f64)]) -> Option<Warning> {
    let runs: Vec<(Range<usize>, f64)> = rotations
        .windows(2)
        .filter(|w| w[1].0.start > w[0].0.end)
        .map(|w| (w[0].0.end..w[1].0.start, w[0].1))
        .collect();
    let (first, first_stamp_s) = runs.first()?;
    let dropped: usize = runs.iter().map(|r| r.0.len()).sum();
    let message = format!(
        "{dropped} beams in {} runs between rotations formed no complete rotation or sector \
         sweep (cut by a time gap, a change of the head's settings or a reversal) and were \
         dropped; the first run starts at beam {} (t = {:.3} s). [rotation] keep_partial = \
         true keeps partial ones",
        runs.len(),
        first.start,
        first_stamp_s
    );
    Some(
        Warning::new(WarningKind::RotationsDropped, runs.len(), message)
            .at(format!("beam {}", first.start)),
    )
}

/// An error when no node has a scan, or no node an image: the run would
/// give the dead reckoning alone. The error names the key that blanks the
/// beams when one does (a blind zone or a maximum range beyond or before
/// the beams' reach), else the thresholds that rejected every echo.
/// `reach_m` is the farthest range any beam of `mission` reaches.
pub(super) fn scans_and_images(
    mission: &str,
    reach_m: f64,
    nodes: &[NodeData],
    config: &SlamConfig,
) -> Result<(), SlamError> {
    if !nodes.iter().any(NodeData::has_scan) {
        let seg = &config.segmentation;
        if seg.blind_zone_m >= reach_m {
            return Err(SlamError::config(
                "segmentation.blind_zone_m",
                format!(
                    "{} m blanks every beam (they reach {reach_m:.1} m): no rotation gave a scan",
                    seg.blind_zone_m
                ),
            ));
        }
        return Err(SlamError::NoNodes {
            mission: mission.to_string(),
            reason: format!(
                "none of the {} rotations gave a scan (beams reaching {reach_m:.1} m; \
                 segmentation.blind_zone_m {} m, max_range_m {:?}, min_intensity {}, \
                 min_sigma_above_mean {}, min_scan_points {}): loosen these to get returns",
                nodes.len(),
                seg.blind_zone_m,
                seg.max_range_m,
                seg.min_intensity,
                seg.min_sigma_above_mean,
                seg.min_scan_points
            ),
        });
    }
    if !nodes.iter().any(|n| !n.image.is_empty()) {
        let image = &config.image;
        if image.blind_zone_m >= reach_m {
            return Err(SlamError::config(
                "image.blind_zone_m",
                format!(
                    "{} m blanks every beam (they reach {reach_m:.1} m): no rotation gave an image",
                    image.blind_zone_m
                ),
            ));
        }
        return Err(SlamError::NoNodes {
            mission: mission.to_string(),
            reason: format!(
                "none of the {} rotations gave an acoustic image with an echo (beams reaching \
                 {reach_m:.1} m; image.blind_zone_m {} m, max_range_m {:?}, background_quantile {})",
                nodes.len(),
                image.blind_zone_m,
                image.max_range_m,
                image.background_quantile
            ),
        });
    }
    Ok(())
}
