//! End-to-end scenarios across the echofield crates live in `tests/tests/`;
//! this library holds helpers they share (paths to the committed datasets
//! and the matching configs of the real sonar logs).

use echofield::slam::SlamConfig;
use echofield_frontend::off_axis::OffAxisSuppression;
use std::path::PathBuf;

/// The repository's `datasets/` folder.
pub fn datasets_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("datasets")
}

/// The static Ping360 log of `datasets/msis-real/ping360`.
pub fn ping360_log() -> PathBuf {
    datasets_dir().join("msis-real/ping360/Sensor_Log_01__inside_base.bin")
}

/// The config of the matching steps for [`ping360_log`]. At its high gain the head's
/// ringing and near-field reverberation last 0.3-2.9 m, changing from ping
/// to ping, and only strong returns are walls. The off-axis suppression is
/// off: its margins are for heads that show decibels (about 3 counts per
/// dB), while this log saturates its walls, so that a wall's bins differ
/// by tens of counts from beam to beam. With it on, two sweeps keep too few
/// returns for a scan and the images of two rotations lose the walls their
/// scans are matched on.
pub fn ping360_config() -> SlamConfig {
    let mut config = SlamConfig::default();
    config.segmentation.blind_zone_m = 4.0;
    config.segmentation.min_intensity = 150.0;
    config.segmentation.min_sigma_above_mean = 0.0;
    config.segmentation.off_axis = OffAxisSuppression::off();
    config.image.blind_zone_m = 3.0;
    config.image.off_axis = OffAxisSuppression::off();
    config
}

/// The static MiniKing bag of `datasets/msis-real/miniking`.
pub fn miniking_log() -> PathBuf {
    datasets_dir().join("msis-real/miniking/full_sonar_scan_2015-05-26-11-38-04.bag")
}

/// The config of the matching steps for [`miniking_log`]: high gain, so the beam's own
/// spread is large; the strongest bin above the beam's mean is the echo.
pub fn miniking_config() -> SlamConfig {
    let mut config = SlamConfig::default();
    config.segmentation.min_sigma_above_mean = 1.0;
    config.segmentation.min_intensity = 0.0;
    config
}

/// The least-squares scale `s` of `t_true ≈ s · t_odo` over the odometry
/// edges of a run's graph, with the true motion from `truth` (one pose per
/// node, `None` where unknown; edges touching such a node are left out):
/// what the run's `dead_reckoning.odometry_scale` estimates from the
/// optimised poses, computed here from ground truth alone.
pub fn ground_truth_odometry_scale(
    graph: &echofield_graph::PoseGraph,
    truth: &[Option<echofield_graph::Se2>],
) -> f64 {
    let (mut rz, mut zz) = (0.0, 0.0);
    for (from, to, edge) in graph.indexed_edges() {
        if edge.kind != echofield_graph::EdgeKind::Odometry {
            continue;
        }
        if let (Some(a), Some(b)) = (truth[from], truth[to]) {
            let z = edge.measurement.translation();
            rz += a.between(&b).translation().dot(&z);
            zz += z.norm_squared();
        }
    }
    rz / zz
}

/// The real St Pere mission of `datasets/stpere-marina`, its beams rebuilt
/// from the real sonar point sets of `datasets/stpere-marina-sonar`
/// (rotations 1-115, expanded from their compact band form), read as
/// `echofield run datasets/stpere-marina --keyframes KF_DIR` reads them
/// under the assumed `sweep` (`None`: the reader's default), with the
/// logged conventions in its mounting.
pub fn stpere_point_set_mission(
    sweep: Option<echofield_frontend::sensors::SweepTiming>,
) -> echofield_frontend::sensors::Mission {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let keyframes = echofield_datasets::stpere::point_bands::committed_keyframes(dir.path())
        .expect("the committed point bands expand");
    echofield::slam::load_mission_with_keyframes(
        &datasets_dir().join("stpere-marina"),
        Some(&keyframes),
        sweep,
    )
    .expect("the committed St Pere logs read")
}

/// The St Pere sonar conventions that the DGPS track confirms (fitted by
/// hand against it, outside the code under test; issue 34): the head's
/// angle runs clockwise, decreasing with time, its zero 246° counter-
/// clockwise from the vehicle's x axis (with the mission's +19.4° heading
/// calibration), at the starter code's (0.33 m, 0).
pub fn stpere_dgps_conventions() -> echofield_frontend::mounting::MountingConfig {
    use echofield_frontend::sensors::{AngleDirection, SweepTiming};
    echofield_frontend::mounting::MountingConfig {
        sonar_x_m: Some(0.33),
        sonar_y_m: Some(0.0),
        sonar_yaw_deg: Some(246.0),
        sonar_angle: Some(AngleDirection::Clockwise),
        sweep: Some(SweepTiming::AngleDecreasing),
        ..Default::default()
    }
}

/// `mission` cut at `cut_s`: the records (beams, DVL, attitude, ground
/// truth) stamped before it, and those stamped from it on.
pub fn split_mission_at(
    mission: &echofield_frontend::sensors::Mission,
    cut_s: f64,
) -> (
    echofield_frontend::sensors::Mission,
    echofield_frontend::sensors::Mission,
) {
    let mut a = mission.clone();
    let mut b = mission.clone();
    a.beams.retain(|r| r.stamp_s < cut_s);
    b.beams.retain(|r| r.stamp_s >= cut_s);
    a.dvl.retain(|r| r.stamp_s < cut_s);
    b.dvl.retain(|r| r.stamp_s >= cut_s);
    a.attitude.retain(|r| r.stamp_s < cut_s);
    b.attitude.retain(|r| r.stamp_s >= cut_s);
    a.ground_truth.retain(|r| r.stamp_s < cut_s);
    b.ground_truth.retain(|r| r.stamp_s >= cut_s);
    (a, b)
}

/// The prior map of `localize` made from `output`, the SLAM run of
/// `mission` with `config`: its node images at their optimised poses, the
/// map frame related to the mission's ground truth by the run's nodes
/// fitted onto theirs (SE(2); `truth_from_map`).
pub fn prior_map_of_run(
    mission: &echofield_frontend::sensors::Mission,
    output: &echofield::slam::SlamOutput,
    config: &SlamConfig,
    localize: &echofield_frontend::localization::LocalizationConfig,
) -> echofield::localize::PriorMap {
    let trajectory: Vec<echofield_graph::io::TrajectoryPose> = output
        .nodes
        .iter()
        .map(|n| echofield_graph::io::TrajectoryPose {
            stamp_s: n.stamp_s,
            pose: n.optimised,
        })
        .collect();
    let (mut p, mut q) = (Vec::new(), Vec::new());
    for n in &output.nodes {
        if let Some(t) = echofield::matching::ground_truth_at(&mission.ground_truth, n.stamp_s) {
            p.push(n.optimised.translation());
            q.push(t.translation());
        }
    }
    let truth_from_map = echofield::eval::align_se2(&p, &q);
    echofield::localize::build_prior_map(
        mission,
        config,
        &trajectory,
        Some(truth_from_map),
        localize,
    )
    .expect("the prior map builds")
}
