//! `localization.mcap` of `echofield localize`.

use super::map_echoes;
use crate::localize::map::PriorMap;
use crate::localize::replay::Localized;
use crate::slam::outputs::foxglove::FRAME_WORLD;
use anyhow::{Context, Result};
use echofield_datasets::mcap::MissionWriter;
use echofield_datasets::mcap::foxglove::ScanPoint;
use echofield_graph::Se2;
use echofield_graph::io::TrajectoryPose;
use std::path::Path;

/// `localization.mcap`: `/map/echoes` and `/map/nodes` once (point
/// clouds), then per rotation `/localize/particles` (point cloud,
/// intensity = weight relative to the largest), `/localize/pose` and, with
/// ground truth, `/localize/ground_truth`; all in frame `world` (the map's).
pub(super) fn write_mcap(
    path: &Path,
    localized: &Localized,
    map: &PriorMap,
    truth: &[TrajectoryPose],
) -> Result<()> {
    let Some(first) = localized.rotations.first() else {
        anyhow::bail!("no rotation was localised");
    };
    let name = format!("{} (echofield localize)", localized.mission_name);
    let mut w = MissionWriter::create(path, &name, &localized.mounting)?;
    let t0 = first.stamp_s;
    let echoes: Vec<ScanPoint> = map_echoes(map, 200_000)
        .into_iter()
        .map(|(x, y, v)| ScanPoint {
            x_m: x,
            y_m: y,
            intensity: v,
        })
        .collect();
    w.write_point_cloud("/map/echoes", t0, FRAME_WORLD, &Se2::identity(), &echoes)?;
    let nodes: Vec<ScanPoint> = map
        .nodes
        .iter()
        .map(|n| ScanPoint {
            x_m: n.x(),
            y_m: n.y(),
            intensity: 1.0,
        })
        .collect();
    w.write_point_cloud("/map/nodes", t0, FRAME_WORLD, &Se2::identity(), &nodes)?;
    let estimate: Vec<Se2> = localized
        .rotations
        .iter()
        .map(|r| r.step.estimate)
        .collect();
    w.write_poses_in_frame("/localize/trajectory", t0, FRAME_WORLD, &estimate)?;
    let mut truth = truth.iter().peekable();
    for r in &localized.rotations {
        w.write_point_cloud(
            "/localize/particles",
            r.stamp_s,
            FRAME_WORLD,
            &Se2::identity(),
            &r.cloud,
        )?;
        w.write_pose_in_frame("/localize/pose", r.stamp_s, FRAME_WORLD, &r.step.estimate)?;
        if let Some(t) = truth.next_if(|t| t.stamp_s <= r.stamp_s) {
            w.write_pose_in_frame("/localize/ground_truth", t.stamp_s, FRAME_WORLD, &t.pose)?;
        }
    }
    w.complete()?
        .persist()
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}
