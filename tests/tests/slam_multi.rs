//! Several missions, one map (issue 38, item 3): missions run on their
//! own, placed on one another's map from their scans alone, merged into
//! one graph.
//!
//! - Two simulated marina missions with different routes and starts (seed
//!   1's route from the southern basin; a second route from the northern
//!   basin, south along the east side and round the mole) merge, and the
//!   merged nodes of both, fitted once onto the common ground truth, are
//!   within the 0.3 m.
//! - A canyon mission is not merged with the marina: no placement, an
//!   honest report, each mission's own result written.
//! - The input order does not matter: the marina missions given the other
//!   way round build the same merged map, with the same anchor.
//! - Position fixes (simulated surface GPS: noisy truth, seeded, in the
//!   simulated world shared by both missions) give a prior that bounds the
//!   search: a right one narrows it and places the mission as well; one
//!   shifted far beyond its sigma is reported and not trusted, and the
//!   mission is still placed from its scans.
//! - The merged folder holds `run`'s files: `graph.g2o` of the joint
//!   graph, `mosaic.png` / `mosaic.pgw` and `mission.mcap` with one set of
//!   topics per mission; each parses.
//! - The real St Pere halves (rotations 1-60 and 61-115, cut in time, so
//!   that the second half's dead reckoning starts from nothing at its
//!   first record) merge; their merged ATE against DGPS is printed. DGPS
//!   is their ground truth and is never used as a prior.
//!
//! The errors are recomputed here from the poses and the missions' own
//! ground truth, not read from the report.

use echofield::calibration::{CalibrateSettings, calibrate_mission};
use echofield::eval::{align_se2, aligned_position_rmse};
use echofield::slam::multi::placement::PositionFixes;
use echofield::slam::multi::{MultiOutput, combine, combine_with_fixes, outputs::write_files};
use echofield::slam::{NoProgress, SlamConfig, SlamOutput, run_mission};
use echofield_datasets::sim::scenes::marina;
use echofield_datasets::sim::{Scenario, SimConfig, follow_route, simulate_mission};
use echofield_frontend::sensors::{Mission, SweepTiming};
use echofield_graph::Se2;
use echofield_tests::{split_mission_at, stpere_point_set_mission};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::sync::OnceLock;

/// The run of marina seed 1 (the first mission, the map frame).
fn marina_seed_1() -> &'static SlamOutput {
    static RUN: OnceLock<SlamOutput> = OnceLock::new();
    RUN.get_or_init(|| {
        let mission = simulate_mission(&Scenario::named("marina").unwrap(), 1).unwrap();
        run_mission(&mission, &SlamConfig::default(), &NoProgress).unwrap()
    })
}

/// The run of [`marina_other_route`].
fn marina_other_route_run() -> &'static SlamOutput {
    static RUN: OnceLock<SlamOutput> = OnceLock::new();
    RUN.get_or_init(|| {
        run_mission(&marina_other_route(), &SlamConfig::default(), &NoProgress).unwrap()
    })
}

/// The marina surveyed along another route (about 400 m): from the
/// northern basin's west side east along it, south along the east side,
/// round the mole counter-clockwise; seed 2's sensor noise.
fn marina_other_route() -> Mission {
    let scene = marina().unwrap();
    let route = [
        [40.0, 222.0],
        [84.0, 222.0],
        [84.0, 200.0],
        [84.0, 140.0],
        [92.0, 120.0],
        [88.0, 90.0],
        [26.0, 90.0],
        [26.0, 14.0],
        [88.0, 14.0],
        [88.0, 40.0],
    ];
    let config = SimConfig::default();
    let truth = follow_route(&route, &config.vehicle, config.start_stamp_s).unwrap();
    let scenario = Scenario::custom("marina-north", scene.environment, truth, config).unwrap();
    simulate_mission(&scenario, 2).unwrap()
}

/// Every mission's merged poses with ground truth, and the truth.
fn merged_with_truth(out: &MultiOutput, missions: &[usize]) -> (Vec<Se2>, Vec<Se2>) {
    let mut pairs = Vec::new();
    for &m in missions {
        let poses = out.poses(m);
        for (n, p) in out.runs[m].nodes.iter().zip(poses) {
            if let Some(g) = n.ground_truth {
                pairs.push((p, g));
            }
        }
    }
    pairs.into_iter().unzip()
}

/// `map_from_mission` of mission `m` as the ground truth tells it: each
/// run's own nodes fitted onto their ground truth (`truth_from_own`),
/// then `anchor_from_m = truth_from_anchor⁻¹ ⊕ truth_from_m`.
fn true_placement(out: &MultiOutput, m: usize) -> Se2 {
    let truth_from_own = |run: &SlamOutput| {
        let (p, q): (Vec<_>, Vec<_>) = run
            .nodes
            .iter()
            .filter_map(|n| {
                n.ground_truth
                    .map(|g| (n.optimised.translation(), g.translation()))
            })
            .unzip();
        align_se2(&p, &q)
    };
    truth_from_own(&out.runs[out.order[0]])
        .inverse()
        .compose(&truth_from_own(&out.runs[m]))
}

/// Distance (m) and heading difference (deg) between the found and the
/// true placement at mission `m`'s nodes (mean over them).
fn placement_error(out: &MultiOutput, m: usize) -> (f64, f64) {
    let found = out.placements[m]
        .as_ref()
        .unwrap()
        .map_from_mission
        .unwrap();
    let truth = true_placement(out, m);
    let nodes = &out.runs[m].nodes;
    let d: f64 = nodes
        .iter()
        .map(|n| {
            let (a, b) = (found.compose(&n.optimised), truth.compose(&n.optimised));
            (a.translation() - b.translation()).norm()
        })
        .sum::<f64>()
        / nodes.len() as f64;
    let dtheta = echofield_graph::se2::wrap_angle(found.theta() - truth.theta()).to_degrees();
    (d, dtheta)
}

#[test]
fn two_marina_missions_with_different_routes_and_starts_merge_within_0_3_m() {
    let a = marina_seed_1().clone();
    let b = marina_other_route_run().clone();
    // The two start far apart: no shared start pose to lean on.
    let (start_a, start_b) = (
        a.nodes[0].ground_truth.unwrap(),
        b.nodes[0].ground_truth.unwrap(),
    );
    assert!((start_a.translation() - start_b.translation()).norm() > 100.0);
    let out = combine(vec![a, b], &SlamConfig::default()).unwrap();
    let report = &out.report;
    eprintln!("{}", serde_json::to_string_pretty(report).unwrap());
    assert!(report.merged);
    assert!(report.missions[1].merged);
    let placed = out.order[1];
    let placement = out.placements[placed].as_ref().unwrap();
    assert!(placement.agreeing >= 3, "{placement:?}");
    let evaluations: usize = placement.probes.iter().map(|p| p.coarse_evaluations).sum();
    eprintln!(
        "placement of mission 2: {:.2} s, {evaluations} coarse evaluations over {} probes",
        placement.time_s,
        placement.probes.len()
    );
    assert!(
        report.cross_loops_accepted >= 10,
        "{} cross-mission loops",
        report.cross_loops_accepted
    );
    let (estimate, truth) = merged_with_truth(&out, &[0, 1]);
    let ate = aligned_position_rmse(&estimate, &truth);
    let (estimate_b, truth_b) = merged_with_truth(&out, &[1]);
    let ate_b = aligned_position_rmse(&estimate_b, &truth_b);
    eprintln!("merged ATE {ate:.3} m (mission 2 alone in the merged graph {ate_b:.3} m)");
    assert!(ate <= 0.3, "merged ATE {ate} m");
    let (d, dtheta) = placement_error(&out, placed);
    eprintln!(
        "placement off the truth by {d:.3} m, {dtheta:.2}° (mean over the placed mission's nodes)"
    );
    assert!(d <= 1.0 && dtheta.abs() <= 1.0, "{d} m, {dtheta}°");
    // The report's figure is the same computation.
    assert!((report.merged_ate_rmse_m.unwrap() - ate).abs() < 1e-9);

    // The outputs: a mission column in the nodes and loops tables, both
    // missions in the cross-mission loops, one TUM file per mission.
    let dir = tempfile::tempdir().unwrap();
    write_files(dir.path(), &out).unwrap();
    let poses = std::fs::read_to_string(dir.path().join("poses.csv")).unwrap();
    assert!(poses.starts_with("mission,node,"));
    let rows_of = |m: &str| poses.lines().filter(|l| l.starts_with(m)).count();
    assert_eq!(rows_of("1,"), out.runs[0].nodes.len());
    assert_eq!(rows_of("2,"), out.runs[1].nodes.len());
    let loops = std::fs::read_to_string(dir.path().join("loops.csv")).unwrap();
    let cross_accepted = loops
        .lines()
        .filter(|l| l.starts_with("1,") && l.contains(",2,") && l.contains(",true,true,"))
        .count();
    assert_eq!(cross_accepted, report.cross_loops_accepted);
    for f in [
        "trajectory_1_tum.txt",
        "trajectory_2_tum.txt",
        "trajectory.png",
        "report.json",
    ] {
        assert!(dir.path().join(f).is_file(), "{f}");
    }
}

#[test]
fn a_canyon_mission_is_not_merged_with_the_marina() {
    let a = marina_seed_1().clone();
    let canyon = simulate_mission(&Scenario::named("canyon").unwrap(), 1).unwrap();
    let b = run_mission(&canyon, &SlamConfig::default(), &NoProgress).unwrap();
    let own_b: Vec<Se2> = b.nodes.iter().map(|n| n.optimised).collect();
    let out = combine(vec![a, b], &SlamConfig::default()).unwrap();
    let report = &out.report;
    eprintln!("{}", serde_json::to_string_pretty(report).unwrap());
    assert!(!report.merged);
    assert!(!report.missions[1].merged);
    assert!(out.merged.is_none());
    let placement = out.placements[out.order[1]].as_ref().unwrap();
    assert!(placement.map_from_mission.is_none());
    assert!(placement.agreeing < 3);
    assert_eq!(report.warnings.len(), 1, "{:?}", report.warnings);
    assert!(report.warnings[0].contains("could not be placed"));
    // Its own result, in its own frame.
    assert_eq!(out.poses(1), own_b);
    let dir = tempfile::tempdir().unwrap();
    write_files(dir.path(), &out).unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap())
            .unwrap();
    assert_eq!(json["merged"], false);
    assert_eq!(
        json["missions"][1]["placement"]["map_from_mission"],
        serde_json::Value::Null
    );
}

#[test]
fn the_real_st_pere_halves_merge() {
    let mission = stpere_point_set_mission(Some(SweepTiming::AngleIncreasing));
    let calibration = calibrate_mission(&mission, &CalibrateSettings::default()).unwrap();
    let config = SlamConfig {
        mounting: calibration.mounting_config(),
        ..SlamConfig::default()
    };
    // 200 beams per rotation (README, "Real data"): rotation 61 starts at
    // beam 12 000.
    let cut_s = mission.beams[60 * 200].stamp_s;
    let (mut first, mut second) = split_mission_at(&mission, cut_s);
    first.name += " 1-60";
    second.name += " 61-115";
    let a = run_mission(&first, &config, &NoProgress).unwrap();
    let b = run_mission(&second, &config, &NoProgress).unwrap();
    let out = combine(vec![a, b], &config).unwrap();
    let report = &out.report;
    eprintln!("{}", serde_json::to_string_pretty(report).unwrap());
    let placed = out.order[1];
    let placement = out.placements[placed].as_ref().unwrap();
    let evaluations: usize = placement.probes.iter().map(|p| p.coarse_evaluations).sum();
    eprintln!(
        "anchor: mission {}; placement of mission {}: {:.2} s, {evaluations} coarse evaluations",
        report.anchor,
        placed + 1,
        placement.time_s
    );
    for m in &report.missions {
        eprintln!(
            "mission {} alone: ATE {:?} m (dead reckoning {:?} m); in the merged graph {:?} m",
            m.mission, m.ate_rmse_m, m.ate_rmse_dead_reckoning_m, m.merged_ate_rmse_m
        );
    }
    assert!(report.merged, "{:?}", report.warnings);
    let (estimate, truth) = merged_with_truth(&out, &[0, 1]);
    let ate = aligned_position_rmse(&estimate, &truth);
    eprintln!(
        "real St Pere halves merged: ATE against DGPS {ate:.3} m over {} nodes, {} cross-mission loops",
        estimate.len(),
        report.cross_loops_accepted
    );
    let (d, dtheta) = placement_error(&out, placed);
    eprintln!(
        "placement off the truth by {d:.3} m, {dtheta:.2}° (mean over the placed half's nodes)"
    );
    // Diagnostics of where the merged error comes from: the ATE of the
    // halves as placed (their own poses moved by the placement, before
    // the merged solve), and each accepted cross-mission loop's error
    // against the relative pose DGPS gives its nodes.
    let anchor = out.order[0];
    let transform = placement.map_from_mission.unwrap();
    let (mut e, mut t) = (Vec::new(), Vec::new());
    for (m, map_from) in [(anchor, Se2::identity()), (placed, transform)] {
        for n in &out.runs[m].nodes {
            if let Some(g) = n.ground_truth {
                e.push(map_from.compose(&n.optimised));
                t.push(g);
            }
        }
    }
    eprintln!(
        "ATE of the halves as placed, before the merged solve: {:.3} m",
        aligned_position_rmse(&e, &t)
    );
    for l in out.merged.as_ref().unwrap().cross_loops.iter() {
        let (Some(z), Some(ga), Some(gb)) = (
            l.record.measurement,
            out.runs[l.from_mission].nodes[l.from_node].ground_truth,
            out.runs[l.to_mission].nodes[l.to_node].ground_truth,
        ) else {
            continue;
        };
        let truth = ga.inverse().compose(&gb);
        eprintln!(
            "cross loop {}:{} -> {}:{} accepted {} ({:?}): |t| {:.1} m, error against DGPS {:.2} m, {:.2}°",
            l.from_mission + 1,
            l.from_node,
            l.to_mission + 1,
            l.to_node,
            l.record.accepted,
            l.record.rejected_by,
            truth.translation().norm(),
            (z.translation() - truth.translation()).norm(),
            echofield_graph::se2::wrap_angle(z.theta() - truth.theta()).to_degrees()
        );
    }
    assert!(report.cross_loops_accepted >= 5);
    // Set after measuring (1.04 m, the missions in the canonical order:
    // the second half, with more nodes, is the anchor); the single run of
    // all 115 rotations gives 0.840 m (see the README on why the merge
    // stays above it).
    assert!(ate <= 1.1, "merged ATE {ate} m");
    assert!(
        d <= 1.0 && dtheta.abs() <= 1.0,
        "placement {d} m, {dtheta}°"
    );
}

/// The merged poses of every mission, by input mission.
fn all_poses(out: &MultiOutput) -> Vec<Vec<Se2>> {
    (0..out.runs.len()).map(|m| out.poses(m)).collect()
}

#[test]
fn the_input_order_does_not_change_the_merged_map() {
    let (a, b) = (marina_seed_1().clone(), marina_other_route_run().clone());
    let ab = combine(vec![a.clone(), b.clone()], &SlamConfig::default()).unwrap();
    let ba = combine(vec![b, a], &SlamConfig::default()).unwrap();
    assert!(ab.report.merged && ba.report.merged);
    // The anchor is the same mission (given first in `ab`, second in `ba`).
    assert_eq!(ab.order, vec![ab.order[0], 1 - ab.order[0]]);
    assert_eq!(ba.order, vec![1 - ab.order[0], ab.order[0]]);
    assert_eq!(ab.report.anchor, ab.order[0] + 1);
    assert_eq!(ba.report.anchor, ba.order[0] + 1);
    // The same poses, bit for bit, with the missions swapped.
    let (pab, pba) = (all_poses(&ab), all_poses(&ba));
    assert_eq!(pab[0], pba[1]);
    assert_eq!(pab[1], pba[0]);
    assert_eq!(
        ab.report.cross_loops_accepted,
        ba.report.cross_loops_accepted
    );
    assert_eq!(ab.report.merged_ate_rmse_m, ba.report.merged_ate_rmse_m);
}

/// Simulated surface fixes of `run`: its ground truth every 10 s over the
/// first and the last 200 s (the vehicle at the surface), with Gaussian
/// noise of `sigma_m` per axis (seeded), shifted by `shift_m`. The
/// simulated world is the frame both marina missions share.
fn surface_fixes(run: &SlamOutput, sigma_m: f64, shift_m: [f64; 2], seed: u64) -> PositionFixes {
    let truth = run.ground_truth.as_ref().unwrap();
    let (t0, t1) = (truth[0].0, truth[truth.len() - 1].0);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, sigma_m).unwrap();
    let mut fixes = Vec::new();
    let mut next = t0;
    for (t, pose) in truth {
        if *t < next || (*t > t0 + 200.0 && *t < t1 - 200.0) {
            continue;
        }
        next = t + 10.0;
        fixes.push((
            *t,
            [
                pose.x() + shift_m[0] + noise.sample(&mut rng),
                pose.y() + shift_m[1] + noise.sample(&mut rng),
            ],
        ));
    }
    PositionFixes { fixes, sigma_m }
}

#[test]
fn position_fixes_bound_the_search_and_a_wrong_prior_is_not_trusted() {
    let (a, b) = (marina_seed_1().clone(), marina_other_route_run().clone());
    let config = SlamConfig::default();
    let without = combine(vec![a.clone(), b.clone()], &config).unwrap();
    let evaluations = |out: &MultiOutput| -> usize {
        out.placements[out.order[1]]
            .as_ref()
            .unwrap()
            .probes
            .iter()
            .map(|p| p.coarse_evaluations)
            .sum()
    };
    let fixes_a = surface_fixes(&a, 1.5, [0.0, 0.0], 11);
    let right = surface_fixes(&b, 1.5, [0.0, 0.0], 12);
    assert!(fixes_a.fixes.len() >= 20 && right.fixes.len() >= 20);
    let with = combine_with_fixes(
        vec![a.clone(), b.clone()],
        &[Some(fixes_a.clone()), Some(right)],
        &config,
    )
    .unwrap();
    let placement = with.placements[with.order[1]].as_ref().unwrap();
    let check = placement.prior.as_ref().unwrap();
    eprintln!(
        "right prior: sigma {:.2} m / {:.2}°, {} vs {} coarse evaluations without, {:.2} s vs {:.2} s, offset {:?} m",
        check.prior.sigma_m,
        check.prior.sigma_rad.to_degrees(),
        evaluations(&with),
        evaluations(&without),
        placement.time_s,
        without.placements[without.order[1]]
            .as_ref()
            .unwrap()
            .time_s,
        check.offset_m
    );
    assert!(check.bounded && check.consistent, "{check:?}");
    assert!(
        with.report.warnings.is_empty(),
        "{:?}",
        with.report.warnings
    );
    assert!(evaluations(&with) * 5 < evaluations(&without));
    let (d, dtheta) = placement_error(&with, with.order[1]);
    eprintln!("right prior: placement off the truth by {d:.3} m, {dtheta:.2}°");
    assert!(d <= 1.0 && dtheta.abs() <= 1.0, "{d} m, {dtheta}°");

    // Shifted by 30 m, twenty times its sigma.
    let wrong = surface_fixes(&b, 1.5, [30.0, 0.0], 12);
    let with = combine_with_fixes(vec![a, b], &[Some(fixes_a), Some(wrong)], &config).unwrap();
    let placement = with.placements[with.order[1]].as_ref().unwrap();
    let check = placement.prior.as_ref().unwrap();
    eprintln!(
        "wrong prior: {check:?}; warnings {:?}",
        with.report.warnings
    );
    assert!(!check.bounded && !check.consistent, "{check:?}");
    assert!(check.offset_m.unwrap() > 20.0);
    assert_eq!(with.report.warnings.len(), 1);
    assert!(with.report.warnings[0].contains("not trusted"));
    let (d, dtheta) = placement_error(&with, with.order[1]);
    assert!(d <= 1.0 && dtheta.abs() <= 1.0, "{d} m, {dtheta}°");
    assert!(with.report.merged);
}

#[test]
fn the_merged_folder_holds_the_graph_the_mosaic_and_the_mcap() {
    let (a, b) = (marina_seed_1().clone(), marina_other_route_run().clone());
    let mut out = combine(vec![a, b], &SlamConfig::default()).unwrap();
    // As `run_missions` sets them: the missions' mountings.
    let mounting = SimConfig::default().mounting;
    out.mountings = vec![Some(mounting.clone()), Some(mounting.clone())];
    assert!(out.report.merged);
    let dir = tempfile::tempdir().unwrap();
    write_files(dir.path(), &out).unwrap();
    // The joint graph: every node of both missions, the cross loops among
    // its edges.
    let graph = echofield_graph::io::g2o::read_g2o(&dir.path().join("graph.g2o")).unwrap();
    let merged = out.merged.as_ref().unwrap();
    assert_eq!(
        graph.node_count(),
        out.runs[0].nodes.len() + out.runs[1].nodes.len()
    );
    assert_eq!(graph.edge_count(), merged.graph.edge_count());
    assert_eq!(graph.fixed().len(), 1);
    // The mosaic decodes and its world file has six numbers.
    let png = image::open(dir.path().join("mosaic.png")).unwrap();
    assert!(png.width() > 100 && png.height() > 100);
    let pgw = std::fs::read_to_string(dir.path().join("mosaic.pgw")).unwrap();
    assert_eq!(
        pgw.lines()
            .filter(|l| l.trim().parse::<f64>().is_ok())
            .count(),
        6
    );
    // The MCAP: one set of topics per mission, the mosaic, the cross loops.
    let bytes = std::fs::read(dir.path().join("mission.mcap")).unwrap();
    let mut count = std::collections::BTreeMap::<String, usize>::new();
    let mut json = std::collections::BTreeMap::<String, Vec<serde_json::Value>>::new();
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        let topic = message.channel.topic.clone();
        *count.entry(topic.clone()).or_default() += 1;
        if topic.contains("/dead_reckoning/") || topic.contains("/ground_truth/") || topic == "/tf"
        {
            json.entry(topic)
                .or_default()
                .push(serde_json::from_slice(&message.data).unwrap());
        }
    }
    eprintln!("{count:?}");
    for m in 0..2 {
        let nodes = out.runs[m].nodes.len();
        assert_eq!(count[&format!("/mission_{}/slam/pose", m + 1)], nodes);
        assert!(count[&format!("/mission_{}/slam/scan", m + 1)] > nodes / 2);
        assert!(count[&format!("/mission_{}/slam/acoustic_image", m + 1)] > nodes / 2);
        assert_eq!(count[&format!("/mission_{}/slam/trajectory", m + 1)], 1);
    }
    assert_eq!(count["/slam/mosaic"], 1);
    assert_eq!(count["/slam/loops/cross"], 1);
    // Per node `world` -> `vehicle_M`, and per mission `vehicle_M` ->
    // `sonar_M` (its mounting).
    assert_eq!(
        count["/tf"],
        out.runs[0].nodes.len() + out.runs[1].nodes.len() + 2
    );
    // Each mission's dead reckoning (one pose per node, in the map frame:
    // near its merged poses, within the dead reckoning's drift) and
    // ground truth (its whole trajectory, fitted onto the merged nodes).
    for m in 0..2 {
        let run = &out.runs[m];
        let dr = &json[&format!("/mission_{}/dead_reckoning/trajectory", m + 1)];
        assert_eq!(dr.len(), 1);
        assert_eq!(dr[0]["frame_id"], "world");
        let poses = dr[0]["poses"].as_array().unwrap();
        assert_eq!(poses.len(), run.nodes.len());
        let merged = out.poses(m);
        let first = &poses[0]["position"];
        let gap = (first["x"].as_f64().unwrap() - merged[0].x())
            .hypot(first["y"].as_f64().unwrap() - merged[0].y());
        assert!(gap < 5.0, "mission {}: first DR pose {gap} m off", m + 1);
        let gt = &json[&format!("/mission_{}/ground_truth/trajectory", m + 1)];
        assert_eq!(gt.len(), 1);
        assert_eq!(
            gt[0]["poses"].as_array().unwrap().len(),
            run.ground_truth.as_ref().unwrap().len()
        );
        let sonar = json["/tf"]
            .iter()
            .find(|t| t["child_frame_id"] == format!("sonar_{}", m + 1))
            .unwrap();
        assert_eq!(sonar["parent_frame_id"], format!("vehicle_{}", m + 1));
        assert_eq!(
            sonar["translation"]["x"].as_f64().unwrap(),
            mounting.vehicle_from_sonar.x()
        );
    }
}

/// The real halves with the head's yaw moved within `calibrate`'s own
/// uncertainty (±1.6°), every rotation a node: at +0.6° the largest set
/// of agreeing probes places the first half on a wrong fit, which no
/// cross-mission loop confirms (without the confirmation, +0.6° is not
/// merged). A smaller agreeing set's placement that cross-mission loops
/// confirm is then taken (`Placement::alternative`), and both merge. At
/// +0.9° the largest set's placement was wrong too until the halves'
/// loops were weighted by their places (`LoopConfig::shared_place_errors`);
/// now it stands on the cross-mission loops it gets. Either way a
/// placement stands only on accepted cross-mission loops, an alternative
/// one only on at least 5.
#[test]
fn the_real_halves_merge_across_the_yaws_calibrate_allows() {
    let mission = stpere_point_set_mission(Some(SweepTiming::AngleIncreasing));
    let calibration = calibrate_mission(&mission, &CalibrateSettings::default()).unwrap();
    let cut_s = mission.beams[60 * 200].stamp_s;
    let (first, second) = split_mission_at(&mission, cut_s);
    for offset_deg in [0.6, 0.9] {
        let mut mounting = calibration.mounting_config();
        mounting.sonar_yaw_deg = mounting.sonar_yaw_deg.map(|y| y + offset_deg);
        let mut config = SlamConfig {
            mounting,
            ..SlamConfig::default()
        };
        config.rotation.node_spacing_m = 0.0;
        let a = run_mission(&first, &config, &NoProgress).unwrap();
        let b = run_mission(&second, &config, &NoProgress).unwrap();
        let out = combine(vec![a, b], &config).unwrap();
        let report = &out.report;
        let placement = out.placements[out.order[1]].as_ref().unwrap();
        let (estimate, truth) = merged_with_truth(&out, &[0, 1]);
        let ate = aligned_position_rmse(&estimate, &truth);
        eprintln!(
            "yaw {offset_deg:+}°: merged {}, alternative {:?}, {} cross loops, ATE {ate:.3} m",
            report.merged, placement.alternative, report.cross_loops_accepted
        );
        assert!(
            report.merged && report.cross_loops_accepted >= 1,
            "{:?}",
            report.warnings
        );
        if placement.alternative.is_some() {
            assert!(report.cross_loops_accepted >= 5, "yaw {offset_deg:+}°");
        }
        if offset_deg == 0.6 {
            assert!(placement.alternative.is_some(), "yaw {offset_deg:+}°");
        }
        assert!(ate <= 1.2, "yaw {offset_deg:+}°: ATE {ate:.3} m");
    }
}
