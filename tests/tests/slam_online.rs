//! Issue 36, item 1: the online engine. A short simulated marina is pushed
//! into `SlamEngine` record by record (beams, DVL and attitude samples
//! interleaved in time order) and what it emits is checked: one event per
//! node in order, each estimate causal (data after its emission cannot
//! change it), close to the ground truth and better than dead reckoning,
//! and `finish()` the same as `run_mission` on the same input.

use echofield::eval::{Alignment, ate};
use echofield::slam::online::{run_online, run_online_taking_beams};
use echofield::slam::outputs::write_outputs;
use echofield::slam::{
    NoProgress, NodeEvent, SlamConfig, SlamEngine, run_mission, run_mission_online,
    run_mission_taking_beams,
};
use echofield_datasets::sim::{Scenario, simulate_mission};
use echofield_frontend::Mission;
use echofield_frontend::warnings::WarningKind;
use echofield_graph::Se2;
use echofield_graph::io::TrajectoryPose;
use std::sync::OnceLock;

/// The first 15 minutes of the simulated marina, seed 2.
fn marina() -> &'static Mission {
    static MISSION: OnceLock<Mission> = OnceLock::new();
    MISSION.get_or_init(|| {
        let mut m = simulate_mission(&Scenario::named("marina").unwrap(), 2).unwrap();
        let end_s = m.beams[0].stamp_s + 900.0;
        m.beams.retain(|b| b.stamp_s < end_s);
        m.dvl.retain(|d| d.stamp_s < end_s + 5.0);
        m.attitude.retain(|a| a.stamp_s < end_s + 5.0);
        m.ground_truth.retain(|g| g.stamp_s < end_s + 5.0);
        m
    })
}

/// One record of the mission, for the interleaving.
#[derive(Clone, Copy)]
enum Record {
    Dvl(usize),
    Attitude(usize),
    Beam(usize),
}

/// Every record of `mission` in time order (DVL, attitude, beams at equal
/// stamps), built here independently of the library's replay.
fn interleaved(mission: &Mission) -> Vec<(f64, Record)> {
    let mut records: Vec<(f64, Record)> = Vec::new();
    records.extend(
        mission
            .dvl
            .iter()
            .enumerate()
            .map(|(i, d)| (d.stamp_s, Record::Dvl(i))),
    );
    records.extend(
        mission
            .attitude
            .iter()
            .enumerate()
            .map(|(i, a)| (a.stamp_s, Record::Attitude(i))),
    );
    records.extend(
        mission
            .beams
            .iter()
            .enumerate()
            .map(|(i, b)| (b.stamp_s, Record::Beam(i))),
    );
    let rank = |r: &Record| match r {
        Record::Dvl(_) => 0,
        Record::Attitude(_) => 1,
        Record::Beam(_) => 2,
    };
    records.sort_by(|a, b| a.0.total_cmp(&b.0).then(rank(&a.1).cmp(&rank(&b.1))));
    records
}

/// Pushes `mission` beam by beam; returns the events with the stamp of the
/// record whose push emitted each, and the finished output.
fn push_all(
    mission: &Mission,
    config: &SlamConfig,
) -> (Vec<(f64, NodeEvent)>, echofield::slam::SlamOutput) {
    let mut engine = SlamEngine::new(config, &mission.name, mission.mounting.clone()).unwrap();
    let mut events = Vec::new();
    for (stamp_s, record) in interleaved(mission) {
        let emitted = match record {
            Record::Dvl(i) => engine.push_dvl(&mission.dvl[i]),
            Record::Attitude(i) => engine.push_attitude(&mission.attitude[i]),
            Record::Beam(i) => engine.push_beam(mission.beams[i].clone()),
        }
        .unwrap();
        events.extend(emitted.into_iter().map(|e| (stamp_s, e)));
    }
    let output = engine.finish(&mission.ground_truth).unwrap();
    (events, output)
}

fn ate_of(poses: &[(f64, Se2)], output: &echofield::slam::SlamOutput) -> f64 {
    let (estimate, reference): (Vec<_>, Vec<_>) = output
        .nodes
        .iter()
        .zip(poses)
        .filter_map(|(node, &(stamp_s, pose))| {
            let truth = node.ground_truth?;
            Some((
                TrajectoryPose { stamp_s, pose },
                TrajectoryPose {
                    stamp_s,
                    pose: truth,
                },
            ))
        })
        .unzip();
    ate(&estimate, &reference, Alignment::Se2, 1e-6)
        .unwrap()
        .rmse_m
}

#[test]
fn beam_by_beam_replay_emits_one_estimate_per_node_in_order_near_the_truth() {
    let mission = marina();
    let config = SlamConfig::default();
    let (events, output) = push_all(mission, &config);
    assert!(events.len() >= 15, "{} nodes", events.len());
    eprintln!(
        "marina seed 2, 15 min: {} nodes, {} loops accepted",
        events.len(),
        output.report.loops_accepted
    );
    assert_eq!(events.len(), output.nodes.len());
    let mut last_emitted_s = f64::NEG_INFINITY;
    for (k, (emitted_s, event)) in events.iter().enumerate() {
        assert_eq!(event.node_id, k);
        assert_eq!(event.poses.len(), k + 1);
        assert_eq!(event.pose, event.poses[k]);
        assert_eq!(event.stamp_s, output.nodes[k].stamp_s);
        assert_eq!(event.rotation_index, output.nodes[k].rotation_index);
        // Emitted once its rotation is over, in time order.
        let rotation_end_s = mission.beams[output.nodes[k].beams.end - 1].stamp_s;
        assert!(*emitted_s >= rotation_end_s && *emitted_s >= last_emitted_s);
        last_emitted_s = *emitted_s;
        assert!(event.latency_s >= 0.0 && event.latency_s.is_finite());
    }
    let emitted: Vec<(f64, Se2)> = events.iter().map(|(_, e)| (e.stamp_s, e.pose)).collect();
    let dead_reckoning: Vec<(f64, Se2)> = output
        .nodes
        .iter()
        .map(|n| (n.stamp_s, n.dead_reckoning))
        .collect();
    let (online, dr) = (ate_of(&emitted, &output), ate_of(&dead_reckoning, &output));
    eprintln!("online ATE {online:.3} m, dead reckoning {dr:.3} m");
    // The emitted estimates have only the loops closed so far, but each is
    // the graph solved with its node's odometry, sequential match and
    // heading prior (not the last solve composed with the odometry, which
    // carries the dead reckoning's drift between loops): README.md
    // § Online gives the figures.
    assert!(online < 0.55, "online ATE {online:.3} m");
    assert!(
        online < 0.6 * dr,
        "online ATE {online:.3} m, dead reckoning {dr:.3} m"
    );
    let finished = output.report.ate_rmse_m.unwrap();
    eprintln!("after finish: {finished:.3} m");
    assert!(finished < online, "finished {finished:.3} m");
}

/// What was emitted for a node depends only on the records pushed before
/// it was emitted: corrupting every record after that moment (DVL 0.3 m/s
/// off, headings 10° off, beams blanked) or dropping them changes nothing
/// of what was already emitted, and changes what comes after.
#[test]
fn emitted_estimates_do_not_depend_on_later_data() {
    let mission = marina();
    let config = SlamConfig::default();
    let (events, _) = push_all(mission, &config);
    let cut = events.len() / 2;
    let cut_s = events[cut].0;
    let mut corrupted = mission.clone();
    for d in corrupted.dvl.iter_mut().filter(|d| d.stamp_s > cut_s) {
        d.velocity_mps.x += 0.3;
    }
    for a in corrupted.attitude.iter_mut().filter(|a| a.stamp_s > cut_s) {
        a.yaw_rad = echofield_graph::se2::wrap_angle(a.yaw_rad + 10f64.to_radians());
    }
    for b in corrupted.beams.iter_mut().filter(|b| b.stamp_s > cut_s) {
        b.intensities.iter_mut().for_each(|v| *v = 0);
    }
    let mut truncated = mission.clone();
    truncated.beams.retain(|b| b.stamp_s <= cut_s);
    truncated.dvl.retain(|d| d.stamp_s <= cut_s);
    truncated.attitude.retain(|a| a.stamp_s <= cut_s);
    for other in [&corrupted, &truncated] {
        let mut engine = SlamEngine::new(&config, &other.name, other.mounting.clone()).unwrap();
        let mut emitted = Vec::new();
        for (_, record) in interleaved(other) {
            emitted.extend(
                match record {
                    Record::Dvl(i) => engine.push_dvl(&other.dvl[i]),
                    Record::Attitude(i) => engine.push_attitude(&other.attitude[i]),
                    Record::Beam(i) => engine.push_beam(other.beams[i].clone()),
                }
                .unwrap(),
            );
        }
        assert!(emitted.len() > cut);
        for k in 0..=cut {
            assert_same_estimate(&emitted[k], &events[k].1);
        }
    }
    let mut engine = SlamEngine::new(&config, "c", corrupted.mounting.clone()).unwrap();
    let mut later = Vec::new();
    for (_, record) in interleaved(&corrupted) {
        later.extend(
            match record {
                Record::Dvl(i) => engine.push_dvl(&corrupted.dvl[i]),
                Record::Attitude(i) => engine.push_attitude(&corrupted.attitude[i]),
                Record::Beam(i) => engine.push_beam(corrupted.beams[i].clone()),
            }
            .unwrap(),
        );
    }
    let last = events.len() - 1;
    assert!(later.len() > last && later[last].pose != events[last].1.pose);
}

/// `finish()` after a beam-by-beam push is `run_mission_online` on the same
/// mission, and `run_mission` once its look-ahead (the smoother, the
/// yaw-rate check over the whole mission) is off.
#[test]
fn finish_gives_the_result_of_run_mission() {
    let mission = marina();
    let mut config = SlamConfig::default();
    let (events, pushed) = push_all(mission, &config);
    let mut emitted = Vec::new();
    let online =
        run_mission_online(mission, &config, &NoProgress, &mut |e| emitted.push(e)).unwrap();
    assert_eq!(emitted.len(), events.len());
    for (a, (_, b)) in emitted.iter().zip(&events) {
        assert_same_estimate(a, b);
    }
    let same = |a: &echofield::slam::SlamOutput, b: &echofield::slam::SlamOutput| {
        assert_eq!(a.nodes, b.nodes);
        assert_eq!(a.graph.poses(), b.graph.poses());
        assert_eq!(a.report.loops_accepted, b.report.loops_accepted);
        assert_eq!(a.report.sequential_accepted, b.report.sequential_accepted);
        assert_eq!(a.report.ate_rmse_m, b.report.ate_rmse_m);
    };
    same(&pushed, &online);
    config.dead_reckoning.smoothing = false;
    config.dead_reckoning.yaw_rate_check_window_s = 0.0;
    let (_, pushed) = push_all(mission, &config);
    let batch = run_mission(mission, &config, &NoProgress).unwrap();
    same(&pushed, &batch);
}

/// `run_mission_taking_beams` (what `echofield run` uses, so that a long
/// mission's beams are held once) gives `run_mission`'s result and leaves
/// the mission without its beams, with the mission as read and with a
/// `[mounting]` that makes the pipeline prepare a copy of it.
#[test]
fn taking_the_beams_gives_the_result_of_run_mission() {
    let mounting = "[mounting]\nsonar_yaw_deg = 1.0\nsonar_x_m = 0.3\n";
    for config in [
        SlamConfig::default(),
        SlamConfig::from_toml_str(mounting).unwrap(),
    ] {
        let borrowed = run_mission(marina(), &config, &NoProgress).unwrap();
        let mut mission = marina().clone();
        let taken = run_mission_taking_beams(&mut mission, &config, &NoProgress).unwrap();
        assert!(mission.beams.is_empty());
        assert_eq!(mission.dvl, marina().dvl);
        assert_eq!(mission.ground_truth, marina().ground_truth);
        assert!(borrowed.nodes.len() >= 15, "{} nodes", borrowed.nodes.len());
        assert_eq!(taken.nodes, borrowed.nodes);
        assert_eq!(taken.graph.poses(), borrowed.graph.poses());
        assert_eq!(taken.loops, borrowed.loops);
        assert_eq!(taken.sequential, borrowed.sequential);
        assert_eq!(taken.report.ate_rmse_m, borrowed.report.ate_rmse_m);
    }
}

/// `run_online_taking_beams` (what `echofield run --online` and
/// `bench-long --online` use) gives `run_online`'s result, the estimates
/// it emitted included, and leaves the mission without its beams.
#[test]
fn taking_the_beams_online_gives_the_result_of_run_online() {
    let config = SlamConfig::default();
    let borrowed = run_online(marina(), &config, &NoProgress).unwrap();
    let mut mission = marina().clone();
    let taken = run_online_taking_beams(&mut mission, &config, &NoProgress).unwrap();
    assert!(mission.beams.is_empty());
    assert_eq!(mission.dvl, marina().dvl);
    assert!(borrowed.nodes.len() >= 15, "{} nodes", borrowed.nodes.len());
    assert_eq!(taken.nodes, borrowed.nodes);
    assert_eq!(taken.emitted, borrowed.emitted);
    assert_eq!(taken.graph.poses(), borrowed.graph.poses());
    assert_eq!(taken.loops, borrowed.loops);
    let ate = |o: &echofield::slam::SlamOutput| o.report.online.as_ref().map(|r| r.ate_rmse_m);
    assert_eq!(ate(&taken), ate(&borrowed));
    assert!(ate(&taken).flatten().is_some());
}

/// Records out of order: going back in time within a stream is an error
/// naming the record; a navigation sample older than one of the other
/// stream already filtered is skipped and counted in the report.
#[test]
fn out_of_order_records_are_errors_or_counted_warnings() {
    let mission = marina();
    let config = SlamConfig::default();
    let mut engine = SlamEngine::new(&config, &mission.name, mission.mounting.clone()).unwrap();
    engine.push_dvl(&mission.dvl[5]).unwrap();
    let err = engine.push_dvl(&mission.dvl[4]).unwrap_err().to_string();
    assert!(
        err.contains("DVL sample 1") && err.contains("stamp_s"),
        "{err}"
    );
    engine.push_beam(mission.beams[10].clone()).unwrap();
    let err = engine
        .push_beam(mission.beams[9].clone())
        .unwrap_err()
        .to_string();
    assert!(err.contains("beam 1") && err.contains("stamp_s"), "{err}");

    // One DVL sample held back and pushed after the next attitude sample.
    let held = mission.dvl.len() / 2;
    let mut engine = SlamEngine::new(&config, &mission.name, mission.mounting.clone()).unwrap();
    let mut waiting = None;
    for (_, record) in interleaved(mission) {
        match record {
            Record::Dvl(i) if i == held => waiting = Some(i),
            Record::Dvl(i) => {
                engine.push_dvl(&mission.dvl[i]).unwrap();
            }
            Record::Attitude(i) => {
                engine.push_attitude(&mission.attitude[i]).unwrap();
                if let Some(d) = waiting.take() {
                    assert!(mission.dvl[d].stamp_s < mission.attitude[i].stamp_s);
                    engine.push_dvl(&mission.dvl[d]).unwrap();
                }
            }
            Record::Beam(i) => {
                engine.push_beam(mission.beams[i].clone()).unwrap();
            }
        }
    }
    let output = engine.finish(&mission.ground_truth).unwrap();
    let late: Vec<_> = output
        .report
        .warnings
        .iter()
        .filter(|w| w.kind == WarningKind::StampsResorted)
        .collect();
    assert_eq!(late.len(), 1, "{:?}", output.report.warnings);
    assert_eq!(late[0].count, 1);
}

/// The same node, pose and estimates (the latencies are wall times).
fn assert_same_estimate(a: &NodeEvent, b: &NodeEvent) {
    assert_eq!(
        (a.node_id, a.rotation_index, a.stamp_s, a.pose, &a.poses),
        (b.node_id, b.rotation_index, b.stamp_s, b.pose, &b.poses)
    );
}

/// `run_online` keeps what it emitted in the output, and the outputs of an
/// online run hold it: `online_tum.txt` (one line per node, as emitted),
/// its track in `trajectory.png` and `mission.mcap`'s `/online/trajectory`;
/// a batch run writes neither.
#[test]
fn an_online_run_writes_what_it_emitted() {
    let mission = marina();
    let config = SlamConfig::default();
    let online = run_online(mission, &config, &NoProgress).unwrap();
    let emitted = online.emitted.as_ref().expect("an online run's estimates");
    assert_eq!(emitted.len(), online.nodes.len());
    let dir = tempfile::tempdir().unwrap();
    write_outputs(&dir.path().join("online"), &online, mission).unwrap();
    let text = std::fs::read_to_string(dir.path().join("online/online_tum.txt")).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), emitted.len());
    for (row, e) in rows.iter().zip(emitted) {
        assert!((row[0] - e.stamp_s).abs() < 1e-5, "{row:?} {e:?}");
        assert!((row[1] - e.pose.x()).abs() < 1e-5 && (row[2] - e.pose.y()).abs() < 1e-5);
    }
    assert!(dir.path().join("online/trajectory.png").exists());
    let topics = |run: &str| -> Vec<String> {
        let bytes = std::fs::read(dir.path().join(run).join("mission.mcap")).unwrap();
        mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| m.unwrap().channel.topic.clone())
            .collect()
    };
    let online_track = "/online/trajectory";
    assert_eq!(
        topics("online")
            .iter()
            .filter(|t| *t == online_track)
            .count(),
        1
    );
    let batch = run_mission(mission, &config, &NoProgress).unwrap();
    assert!(batch.emitted.is_none());
    write_outputs(&dir.path().join("batch"), &batch, mission).unwrap();
    assert!(!dir.path().join("batch/online_tum.txt").exists());
    assert!(!topics("batch").iter().any(|t| t == online_track));
}
