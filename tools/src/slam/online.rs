//! `run --online` (the CLI): a mission replayed through the causal engine,
//! with what it emitted while running (each node's estimate as it was when
//! its rotation completed) and the work each rotation took.

use super::evaluation::MAX_TIME_DIFF_S;
use super::result::{OnlineReport, SlamOutput};
use super::{
    NodeEvent, ProgressSink, SlamConfig, SlamError, run_mission_online,
    run_mission_online_taking_beams,
};
use crate::eval::{Alignment, ate};
use echofield_frontend::sensors::Mission;
use echofield_graph::io::TrajectoryPose;

/// Runs `mission` through [`run_mission_online`]: the output's `emitted`
/// holds each node's estimate as it was emitted (the engine keeps it), its
/// report's `online` their ATE and the work per rotation. Errors as
/// [`super::run_mission`].
pub fn run_online(
    mission: &Mission,
    config: &SlamConfig,
    progress: &dyn ProgressSink,
) -> Result<SlamOutput, SlamError> {
    with_online_report(|on_event| run_mission_online(mission, config, progress, on_event))
}

/// [`run_online`] with the beams moved out of `mission` into the engine
/// ([`run_mission_online_taking_beams`]; `mission.beams` is empty
/// afterwards): the same outputs, and the memory an engine on a vehicle
/// holds. What `echofield run --online` uses.
pub fn run_online_taking_beams(
    mission: &mut Mission,
    config: &SlamConfig,
    progress: &dyn ProgressSink,
) -> Result<SlamOutput, SlamError> {
    with_online_report(|on_event| {
        run_mission_online_taking_beams(mission, config, progress, on_event)
    })
}

/// Runs `run` with an event callback that times the rotations, then adds
/// the report's `online` section.
fn with_online_report(
    run: impl FnOnce(&mut dyn FnMut(NodeEvent)) -> Result<SlamOutput, SlamError>,
) -> Result<SlamOutput, SlamError> {
    let mut latencies_s = Vec::new();
    let mut output = run(&mut |event: NodeEvent| latencies_s.push(event.latency_s))?;
    let emitted = output.emitted.as_deref().unwrap_or_default();
    output.report.online = Some(online_report(&output, emitted, &mut latencies_s));
    Ok(output)
}

fn online_report(
    output: &SlamOutput,
    emitted: &[TrajectoryPose],
    latencies_s: &mut [f64],
) -> OnlineReport {
    latencies_s.sort_by(f64::total_cmp);
    let ms = |q: f64| percentile(latencies_s, q) * 1e3;
    let (estimate, reference): (Vec<TrajectoryPose>, Vec<TrajectoryPose>) = output
        .nodes
        .iter()
        .zip(emitted)
        .filter_map(|(node, e)| {
            let truth = node.ground_truth?;
            Some((
                *e,
                TrajectoryPose {
                    stamp_s: node.stamp_s,
                    pose: truth,
                },
            ))
        })
        .unzip();
    let ate_rmse_m = (reference.len() >= 2)
        .then(|| ate(&estimate, &reference, Alignment::Se2, MAX_TIME_DIFF_S).ok())
        .flatten()
        .map(|a| a.rmse_m);
    OnlineReport {
        nodes_emitted: emitted.len(),
        latency_p50_ms: ms(0.5),
        latency_p95_ms: ms(0.95),
        latency_max_ms: ms(1.0),
        ate_rmse_m,
    }
}

/// The nearest-rank `q` quantile of `sorted` (ascending); 0 when empty.
fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let rank = (q * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

#[cfg(test)]
mod tests {
    use super::percentile;

    #[test]
    fn percentiles_are_nearest_rank() {
        let sorted: Vec<f64> = (1..=20).map(f64::from).collect();
        assert_eq!(percentile(&sorted, 0.5), 10.0);
        assert_eq!(percentile(&sorted, 0.95), 19.0);
        assert_eq!(percentile(&sorted, 1.0), 20.0);
        assert_eq!(percentile(&[], 0.5), 0.0);
        assert_eq!(percentile(&[3.0], 0.95), 3.0);
    }
}
