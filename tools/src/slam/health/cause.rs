//! The likely cause of a suspect run, and its remedy.

use super::{Check, HealthEvidence, HealthReason};
use echofield_frontend::loops::RejectReason;
use echofield_frontend::sensors::MountingSource;
use serde::Serialize;

/// The likely cause of a suspect run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Cause {
    /// The sonar head's mounting or angle convention: the mounting was
    /// assumed, or the matches disagree with the odometry in the way a
    /// wrong mounting makes them.
    Mounting,
    /// The navigation (DVL, heading) or its noise model: the matches are
    /// made but disagree with the odometry, under a given mounting.
    Navigation,
    /// Too little structure: most rotations give no scan, or most
    /// sequential pairs no match.
    Structure,
}

impl Cause {
    /// The remedy, for the mission at `mission` (a path or `MISSION`).
    pub fn remedy(self, mission: &str) -> String {
        match self {
            Cause::Mounting => format!(
                "the sonar mounting (head position, yaw or angle direction) is likely wrong: \
                 run `echofield calibrate {mission} --output cal.toml` and pass `--config cal.toml`, \
                 or give the mounting in [mounting] of --config"
            ),
            Cause::Navigation => format!(
                "the navigation likely disagrees with the sonar: check the DVL and heading \
                 (report.json dead_reckoning and warnings) and set [dead_reckoning] to the sensors' \
                 noise; if the mounting may be wrong, run `echofield calibrate {mission} --output cal.toml` \
                 and pass `--config cal.toml`"
            ),
            Cause::Structure => "the sonar saw too little structure to correct the navigation: \
                 the result is close to dead reckoning; check the head's range and gain and \
                 [segmentation] (min_intensity, blind_zone_m)"
                .to_string(),
        }
    }
}

/// Structure when the sonar gave little to match; the mounting when it
/// was assumed or the matches show its signature; else the navigation.
pub fn likely(evidence: &HealthEvidence, reasons: &[HealthReason]) -> Cause {
    let sequential = &evidence.sequential;
    let unmatched = sequential
        .rejected_by
        .get(&RejectReason::NoMatch)
        .copied()
        .unwrap_or(0);
    let scans_failed = reasons.iter().any(|r| r.check == Check::Scans);
    if scans_failed || 2 * unmatched > sequential.attempted {
        return Cause::Structure;
    }
    let signature = reasons.iter().any(|r| {
        matches!(
            r.check,
            Check::RotationSlope | Check::TranslationDirection | Check::HeadOffset
        )
    });
    if signature || evidence.mounting_source == MountingSource::Assumed {
        Cause::Mounting
    } else {
        Cause::Navigation
    }
}
