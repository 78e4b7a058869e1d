//! From the beam stream to graph nodes: one node per rotation at its central
//! (reference) pose, with its scan `S_k` and acoustic image `I_k` built once
//! and kept for every later match (paper sections 3-4).
//!
//! A rotation becomes a node only when the navigation covers all its beams
//! (dead reckoning extrapolates at most `max_extrapolation_s` beyond its
//! span): on the St Pere logs the first ~183 s of beams precede the first
//! DVL sample, and those rotations are skipped and listed in the report
//! (`SkippedRotation` in `echofield::slam::result`). A rotation with too
//! few ranges still becomes a node (its dead-reckoning edges keep the chain
//! connected and its image can still be matched against); its scan is
//! empty.
//!
//! Rotations are built one at a time, as they complete. Which of them
//! become nodes is [`spacing`]'s rule (every one by default).

pub mod spacing;

use crate::dead_reckoning::Navigation;
use crate::error::{FrontendError, StageError};
use crate::image::{ImageConfig, StoredImage};
use crate::motion::reference_from_beams;
use crate::rotation::Rotation;
use crate::scan::{Scan, build_scan};
use crate::segmentation::SegmentationConfig;
use crate::sensors::{SensorMounting, SonarBeam};
use echofield_graph::Se2;
use std::ops::Range;
use std::sync::Arc;

/// Fraction of a scan's points whose range defines its footprint.
const FOOTPRINT_QUANTILE: f64 = 0.9;

/// A rotation turned into a node.
#[derive(Clone, Debug)]
pub struct NodeData {
    pub rotation_index: usize,
    /// Reference (central) time of the rotation, s.
    pub stamp_s: f64,
    pub beams: Range<usize>,
    /// Dead-reckoning `world_from_vehicle` at `stamp_s`.
    pub dead_reckoning: Se2,
    /// `S_k` in the node's vehicle frame (empty with too few ranges).
    pub scan: Scan,
    /// `I_k` in the node's vehicle frame, kept with its beams so that it
    /// can be released and built again (`ImageResidency`).
    pub image: StoredImage,
    /// Range from the node origin within which `S_k` has 90% of its
    /// points, metres (0 for an empty scan): the area this node "sees".
    pub footprint_m: f64,
    /// The rotation overlaps a gap in the DVL data (longer than
    /// `dead_reckoning.max_dvl_gap_s`): the motion compensation inside it
    /// extrapolated a held velocity, so its scan and image are distorted
    /// and the SLAM frontend does not match it: dead reckoning bridges it.
    /// (The localiser still weighs its particles with the scan: a weight
    /// lasts one step, a graph edge stays.)
    pub in_dvl_gap: bool,
}

impl NodeData {
    /// The scan can be matched.
    pub fn has_scan(&self) -> bool {
        !self.scan.is_empty()
    }

    /// The node's scan and image may be matched.
    pub fn matchable(&self) -> bool {
        self.has_scan() && !self.in_dvl_gap
    }
}

/// Why a rotation did not become a node.
pub enum Skip {
    /// Not navigable: skipped and reported.
    Outside(String),
    /// Bad data: the run fails.
    Fatal(StageError),
}

/// The node of `rotation`, whose beams are `beams` (the rotation's own,
/// in order), placed with `navigation` and the sonar `mounting`.
/// [`Skip::Outside`] when the navigation does not cover the rotation.
pub fn build_node(
    beams: &[SonarBeam],
    rotation: &Rotation,
    navigation: &Navigation,
    mounting: &SensorMounting,
    segmentation: &SegmentationConfig,
    image: &ImageConfig,
) -> Result<NodeData, Skip> {
    let place = NodePlacement {
        navigation,
        mounting,
        segmentation,
        image,
    };
    build_node_from(beams.to_vec(), rotation, &place)
}

/// What places a rotation's beams and makes its scan and image.
#[derive(Clone, Copy)]
pub struct NodePlacement<'a> {
    /// The dead reckoning that places each beam (motion compensation).
    pub navigation: &'a Navigation,
    /// The sonar's mounting on the vehicle.
    pub mounting: &'a SensorMounting,
    /// How the scan's ranges are picked from the beams.
    pub segmentation: &'a SegmentationConfig,
    /// How the acoustic image is built.
    pub image: &'a ImageConfig,
}

/// [`build_node`] taking the rotation's beams: the node keeps them (for
/// its image's rebuilds) without a copy.
pub fn build_node_from(
    beams: Vec<SonarBeam>,
    rotation: &Rotation,
    place: &NodePlacement<'_>,
) -> Result<NodeData, Skip> {
    let NodePlacement {
        navigation,
        mounting,
        segmentation,
        image,
    } = *place;
    let stage = || format!("rotation {}", rotation.index);
    let fatal = |e: FrontendError| Skip::Fatal(StageError::new(stage(), e));
    let skip_outside = |e: FrontendError| match e {
        FrontendError::OutsideNavigation { .. } => Skip::Outside(e.to_string()),
        other => fatal(other),
    };
    let frames = reference_from_beams(&beams, navigation, mounting, rotation.reference_stamp_s)
        .map_err(skip_outside)?;
    let dead_reckoning = navigation
        .pose_at(rotation.reference_stamp_s)
        .map_err(skip_outside)?;
    let scan = match build_scan(&beams, &frames, rotation.reference_stamp_s, segmentation) {
        Ok(scan) => scan,
        Err(FrontendError::TooFewRanges { .. }) => Scan::empty(rotation.reference_stamp_s),
        Err(e) => return Err(fatal(e)),
    };
    let image = StoredImage::build(beams, scan.image_frames(&frames), Arc::new(image.clone()))
        .map_err(fatal)?;
    let footprint_m = footprint(&scan);
    let in_dvl_gap = navigation
        .dvl_gaps()
        .iter()
        .any(|g| g.start_s < rotation.end_s && g.end_s > rotation.start_s);
    Ok(NodeData {
        in_dvl_gap,
        rotation_index: rotation.index,
        stamp_s: rotation.reference_stamp_s,
        beams: rotation.beams.clone(),
        dead_reckoning,
        scan,
        image,
        footprint_m,
    })
}

/// The `FOOTPRINT_QUANTILE` quantile of the point ranges.
fn footprint(scan: &Scan) -> f64 {
    if scan.is_empty() {
        return 0.0;
    }
    let mut ranges: Vec<f64> = scan.points.iter().map(|p| p.coords.norm()).collect();
    let k = ((ranges.len() - 1) as f64 * FOOTPRINT_QUANTILE).round() as usize;
    let (_, value, _) = ranges.select_nth_unstable_by(k, f64::total_cmp);
    *value
}

/// Fraction of `points` (frame of node `k`) that fall within `radius_m` of
/// node `j`'s origin when placed with `j_from_k`; every `stride`-th point.
pub fn predicted_overlap(
    points: &[nalgebra::Point2<f64>],
    j_from_k: &Se2,
    radius_m: f64,
    stride: usize,
) -> f64 {
    let r2 = radius_m * radius_m;
    let (mut inside, mut total) = (0usize, 0usize);
    for p in points.iter().step_by(stride.max(1)) {
        let (x, y) = j_from_k.transform_xy(p.x, p.y);
        total += 1;
        if x * x + y * y <= r2 {
            inside += 1;
        }
    }
    if total == 0 {
        0.0
    } else {
        inside as f64 / total as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point2;

    #[test]
    fn overlap_counts_points_inside_the_other_footprint() {
        // Points on the x axis at 1..=10 m; node j 4 m ahead of node k.
        let points: Vec<Point2<f64>> = (1..=10).map(|i| Point2::new(i as f64, 0.0)).collect();
        let j_from_k = Se2::new(-4.0, 0.0, 0.0);
        // In j's frame the points are at -3..=6 m; within 3.5 m: -3..=3.
        assert!((predicted_overlap(&points, &j_from_k, 3.5, 1) - 0.7).abs() < 1e-12);
        // Every second point: 1, 3, 5, 7, 9 -> -3, -1, 1, 3, 5: four of five.
        assert!((predicted_overlap(&points, &j_from_k, 3.5, 2) - 0.8).abs() < 1e-12);
        assert_eq!(predicted_overlap(&[], &j_from_k, 3.5, 1), 0.0);
    }

    #[test]
    fn footprint_is_the_ninetieth_percentile_of_the_ranges() {
        let scan = Scan {
            reference_stamp_s: 0.0,
            points: (1..=11).map(|i| Point2::new(0.0, i as f64)).collect(),
            intensities: vec![100.0; 11],
            beam_indices: (0..11).collect(),
            range_corrections_m: Vec::new(),
        };
        // Ranges 1..=11, index round(10 * 0.9) = 9: the tenth, 10 m.
        assert_eq!(footprint(&scan), 10.0);
        let empty = Scan::empty(0.0);
        assert_eq!(footprint(&empty), 0.0);
    }
}
