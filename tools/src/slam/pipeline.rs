//! [`run_mission`], [`run_mission_taking_beams`], [`run_mission_online`]
//! and [`run_mission_online_taking_beams`]: a recorded mission prepared
//! (mounting, screening, intensity scale) and replayed, record by record in
//! time order, through the [`SlamEngine`].

use super::config::{SUBMAP_ROTATIONS_SCAN_ONLY, SlamConfig};
use super::engine::{NodeEvent, SlamEngine};
use super::result::{IntensityReport, SlamOutput};
use super::{ProgressSink, SlamError, check_sensors};
use echofield_frontend::dead_reckoning;
use echofield_frontend::intensity::{self, IntensityKind};
use echofield_frontend::replay::{MissionRecord, mission_records, records_with_beams};
use echofield_frontend::screening;
use echofield_frontend::sensors::{Mission, SonarBeam};
use echofield_frontend::warnings::Warnings;
use std::borrow::{Borrow, Cow};
use std::time::Instant;

/// Runs the whole pipeline on `mission` (see [`crate::slam`]) in batch
/// mode: the navigation is computed first over the whole mission
/// ([`dead_reckoning::run`]: smoothed with `dead_reckoning.smoothing`,
/// the yaw-rate check over every attitude sample), then the mission is
/// replayed through [`SlamEngine::with_navigation`].
///
/// Errors: an invalid config; a mission without beams, valid DVL samples
/// or heading; bad records (non-finite values, time going backwards); no
/// rotation the navigation covers; a failed final solve.
pub fn run_mission(
    mission: &Mission,
    config: &SlamConfig,
    progress: &dyn ProgressSink,
) -> Result<SlamOutput, SlamError> {
    let result = run(mission, config, progress, None);
    progress.finish();
    result
}

/// Runs `mission` through the causal engine ([`SlamEngine::new`]): each
/// node is given to `on_event` as its rotation completes, with the
/// estimates as they were then. Errors as [`run_mission`].
pub fn run_mission_online(
    mission: &Mission,
    config: &SlamConfig,
    progress: &dyn ProgressSink,
    on_event: &mut dyn FnMut(NodeEvent),
) -> Result<SlamOutput, SlamError> {
    let result = run(mission, config, progress, Some(on_event));
    progress.finish();
    result
}

/// As [`run_mission`], but the beams are moved out of `mission` into the
/// engine as they are replayed instead of copied: a long mission's beams
/// are then held once (by its nodes) instead of twice. Afterwards
/// `mission.beams` is empty; the rest of `mission` is as it was. The
/// outputs are those of [`run_mission`]. Errors as [`run_mission`].
pub fn run_mission_taking_beams(
    mission: &mut Mission,
    config: &SlamConfig,
    progress: &dyn ProgressSink,
) -> Result<SlamOutput, SlamError> {
    let result = run_taking_beams(mission, config, progress, None);
    progress.finish();
    result
}

/// [`run_mission_online`] with the beams moved out of `mission` as
/// [`run_mission_taking_beams`] does: what a vehicle's engine holds, not
/// the recorded mission as well. The outputs and events are those of
/// [`run_mission_online`]. Errors as [`run_mission`].
pub fn run_mission_online_taking_beams(
    mission: &mut Mission,
    config: &SlamConfig,
    progress: &dyn ProgressSink,
    on_event: &mut dyn FnMut(NodeEvent),
) -> Result<SlamOutput, SlamError> {
    let result = run_taking_beams(mission, config, progress, Some(on_event));
    progress.finish();
    result
}

/// `on_event` given: online, else batch.
fn run(
    mission: &Mission,
    config: &SlamConfig,
    progress: &dyn ProgressSink,
    on_event: Option<&mut dyn FnMut(NodeEvent)>,
) -> Result<SlamOutput, SlamError> {
    config.validate()?;
    let (mission, config, intensity, warnings) = prepare(mission, config)?;
    let (mission, config): (&Mission, &SlamConfig) = (&mission, &config);
    let online = on_event.is_some();
    let (mut engine, dead_reckoning_s) = start(mission, config, progress, online)?;
    engine.set_input_report(intensity, warnings);
    let mut ignore = |_: NodeEvent| {};
    let on_event: &mut dyn FnMut(NodeEvent) = on_event.unwrap_or(&mut ignore);
    replay(mission, &mut engine, progress, on_event)?;
    finish(engine, mission, progress, online, dead_reckoning_s)
}

/// [`run`] with the beams taken out of `mission` (see
/// [`run_mission_taking_beams`]); `on_event` given: online, else batch.
fn run_taking_beams(
    mission: &mut Mission,
    config: &SlamConfig,
    progress: &dyn ProgressSink,
    on_event: Option<&mut dyn FnMut(NodeEvent)>,
) -> Result<SlamOutput, SlamError> {
    config.validate()?;
    let (prepared, config, intensity, warnings) = prepare(mission, config)?;
    let config: &SlamConfig = &config;
    let mut prepared = match prepared {
        Cow::Owned(prepared) => Some(prepared),
        Cow::Borrowed(_) => None,
    };
    // A prepared copy holds its own beams: the original's go now.
    if prepared.is_some() {
        mission.beams = Vec::new();
    }
    let mission = prepared.as_mut().unwrap_or(mission);
    let online = on_event.is_some();
    let (mut engine, dead_reckoning_s) = start(mission, config, progress, online)?;
    engine.set_input_report(intensity, warnings);
    let beams = std::mem::take(&mut mission.beams);
    let mut ignore = |_: NodeEvent| {};
    let on_event: &mut dyn FnMut(NodeEvent) = on_event.unwrap_or(&mut ignore);
    replay_beams(mission, beams, &mut engine, progress, on_event)?;
    finish(engine, mission, progress, online, dead_reckoning_s)
}

/// The engine for `mission`: causal when `online`, else on the navigation
/// computed over the whole mission first (and the seconds that took).
fn start<'c>(
    mission: &Mission,
    config: &'c SlamConfig,
    progress: &dyn ProgressSink,
    online: bool,
) -> Result<(SlamEngine<'c>, f64), SlamError> {
    let total = stages(online);
    let mut dead_reckoning_s = 0.0;
    let engine = if online {
        SlamEngine::new(config, &mission.name, mission.mounting.clone())?
    } else {
        progress.stage(1, total, "dead reckoning");
        let t = Instant::now();
        let navigation = dead_reckoning::run(mission, &config.dead_reckoning)
            .map_err(|e| SlamError::frontend("dead reckoning", e))?;
        dead_reckoning_s = t.elapsed().as_secs_f64();
        SlamEngine::with_navigation(config, &mission.name, mission.mounting.clone(), navigation)?
    };
    progress.stage(total - 1, total, "node by node");
    Ok((engine, dead_reckoning_s))
}

/// The final solve and the report's dead-reckoning time.
fn finish(
    engine: SlamEngine<'_>,
    mission: &Mission,
    progress: &dyn ProgressSink,
    online: bool,
    dead_reckoning_s: f64,
) -> Result<SlamOutput, SlamError> {
    let total = stages(online);
    progress.stage(total, total, "final optimisation");
    let mut output = engine.finish(&mission.ground_truth)?;
    output.report.timings.dead_reckoning_s += dead_reckoning_s;
    output.report.time_s += dead_reckoning_s;
    Ok(output)
}

/// Stages shown by the progress bar: online runs have no dead-reckoning
/// stage before the engine.
fn stages(online: bool) -> usize {
    if online { 2 } else { 3 }
}

/// Pushes every record of `mission` into `engine` in time order (at equal
/// stamps: DVL, attitude, then beams: [`mission_records`], the causal
/// driver's order) and hands each event to `on_event`.
pub fn replay(
    mission: &Mission,
    engine: &mut SlamEngine<'_>,
    progress: &dyn ProgressSink,
    on_event: &mut dyn FnMut(NodeEvent),
) -> Result<(), SlamError> {
    let total = mission.beams.len();
    let records = mission_records(mission);
    replay_records(records, total, engine, progress, on_event, SonarBeam::clone)
}

/// [`replay`] with the mission's beams given apart (taken out of it, in
/// its order): the same records in the same order
/// ([`records_with_beams`]), each beam moved into `engine` instead of
/// copied.
fn replay_beams(
    mission: &Mission,
    beams: Vec<SonarBeam>,
    engine: &mut SlamEngine<'_>,
    progress: &dyn ProgressSink,
    on_event: &mut dyn FnMut(NodeEvent),
) -> Result<(), SlamError> {
    let total = beams.len();
    let records = records_with_beams(mission, beams);
    replay_records(records, total, engine, progress, on_event, |b| b)
}

/// Feeds `records` (`total` beams among them) to `engine`, each beam as
/// `into_beam` makes it, and reports the nodes they complete.
fn replay_records<'m, B: Borrow<SonarBeam>>(
    records: impl Iterator<Item = MissionRecord<'m, B>>,
    total: usize,
    engine: &mut SlamEngine<'_>,
    progress: &dyn ProgressSink,
    on_event: &mut dyn FnMut(NodeEvent),
    into_beam: impl Fn(B) -> SonarBeam,
) -> Result<(), SlamError> {
    for record in records {
        let events = match record {
            MissionRecord::Dvl(s) => engine.push_dvl(s)?,
            MissionRecord::Attitude(a) => engine.push_attitude(a)?,
            MissionRecord::Beam(i, beam) => {
                // A bar redraws at most ~20 times a second anyway: tell it
                // every 256 beams (about one rotation of a MiniKing).
                if i % 256 == 0 {
                    progress.beams(i, total);
                }
                engine.push_beam(into_beam(beam))?
            }
        };
        for event in events {
            progress.node_done(event.node_id + 1, event.loops_accepted);
            on_event(event);
        }
    }
    for event in engine.end_of_data()? {
        progress.node_done(event.node_id + 1, event.loops_accepted);
        on_event(event);
    }
    progress.beams(total, total);
    Ok(())
}

pub(crate) type Prepared<'m, 'c> = (
    Cow<'m, Mission>,
    Cow<'c, SlamConfig>,
    IntensityReport,
    Warnings,
);

/// The mission as the engine gets it: the config's `[mounting]` applied,
/// implausible records screened out (warned), binary intensities prepared
/// ([`prepare_scan_only`]); the sensors it needs checked.
pub(crate) fn prepare<'m, 'c>(
    mission: &'m Mission,
    config: &'c SlamConfig,
) -> Result<Prepared<'m, 'c>, SlamError> {
    let mission = config.mounting.apply(mission).map_err(|e| match e {
        echofield_frontend::FrontendError::InvalidConfig { field, message } => {
            SlamError::config(format!("mounting.{field}"), message)
        }
        other => SlamError::frontend("mounting", other),
    })?;
    let mut warnings = mission.warnings.clone();
    let (screened, dropped) =
        screening::screen(&mission).map_err(|e| SlamError::frontend("sensor records", e))?;
    warnings.extend(dropped.iter().cloned());
    let screened = match screened {
        Cow::Borrowed(_) => None,
        Cow::Owned(m) => Some(m),
    };
    let mission = screened.map_or(mission, Cow::Owned);
    let (mission, config, intensity) = prepare_scan_only(mission, config);
    check_sensors(&mission)?;
    Ok((mission, config, intensity, warnings))
}

/// Scan-only data: [`intensity::prepare_binary`] on the mission's beams and
/// a copy of the config when the beams' intensities are binary, whose
/// sequential matches then read a submap ([`SUBMAP_ROTATIONS_SCAN_ONLY`])
/// and whose loops that share a place share their weight
/// (`LoopConfig::shared_place_errors`); the mission and the config are
/// borrowed as they are otherwise. The effective config (`config.toml`)
/// carries what was derived.
fn prepare_scan_only<'m, 'c>(
    mission: Cow<'m, Mission>,
    config: &'c SlamConfig,
) -> (Cow<'m, Mission>, Cow<'c, SlamConfig>, IntensityReport) {
    let kind = intensity::detect(&mission.beams);
    if !matches!(kind, IntensityKind::Binary { .. }) {
        let report = IntensityReport {
            kind,
            derived: Vec::new(),
        };
        return (mission, Cow::Borrowed(config), report);
    }
    let mut mission = mission.into_owned();
    let mut config = config.clone();
    let mut derived = intensity::prepare_binary(
        &mut mission.beams,
        &mut config.segmentation,
        &mut config.image,
    );
    config.sequential.submap_rotations = SUBMAP_ROTATIONS_SCAN_ONLY;
    derived.push(format!(
        "sequential matches against a submap of the {SUBMAP_ROTATIONS_SCAN_ONLY} rotations before"
    ));
    config.loops.shared_place_errors = true;
    derived.push("loops that share a place weighted by its design effect".to_string());
    let report = IntensityReport { kind, derived };
    (Cow::Owned(mission), Cow::Owned(config), report)
}
