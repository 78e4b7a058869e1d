//! No silent failure: a run judges its own result without ground truth
//! (`report.json` → `health`).
//!
//! The evidence ([`evidence`]) is what the sonar says about the navigation
//! and about itself: how the sequential matches agree with the odometry
//! against their covariances and whether they disagree systematically (as
//! a wrong mounting makes them), how many sequential matches and loop
//! candidates were accepted, and how sharp the map of placed scans is under
//! dead reckoning and under the optimised trajectory. Each check of
//! [`checks`] compares one figure with a limit; a failed check is a
//! [`HealthReason`] and makes the verdict [`Verdict::Suspect`]. A suspect
//! run names its likely [`Cause`] and the remedy.
//!
//! What it cannot see: an error the sonar shares with the navigation (a
//! heading offset of the compass moves both alike), and a wrong mounting
//! on a mission where no sequential match can be made (then the checks of
//! the matches are not made, and a mission without scans fails its own
//! check). The mounting's source ([`MountingSource`]) is reported: an
//! assumed mounting is not a reason by itself, but it makes the mounting
//! the likely cause of a suspect run.
//!
//! `echofield run` and `echofield demo` exit with [`SUSPECT_EXIT_STATUS`]
//! after writing every output of a suspect run, unless given
//! `--allow-suspect`.

pub mod cause;
pub mod checks;
pub mod evidence;

pub use cause::Cause;

use super::node_record::NodeRecord;
use echofield_frontend::loops::{LoopRecord, SequentialRecord};
use echofield_frontend::nodes::NodeData;
use echofield_frontend::sensors::{MountingSource, SensorMounting};
use evidence::{LoopEvidence, MapEvidence, SequentialEvidence};
use serde::Serialize;

/// Exit status of `echofield run` and `echofield demo` for a suspect run
/// (1 is any error, 2 a command-line error).
pub const SUSPECT_EXIT_STATUS: u8 = 3;

/// `report.json` → `health`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Health {
    pub verdict: Verdict,
    /// The failed checks; empty for an ok run.
    pub reasons: Vec<HealthReason>,
    /// For a suspect run: what most likely went wrong, and what to do.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cause: Option<Cause>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub remedy: Option<String>,
    pub evidence: HealthEvidence,
}

/// The verdict of a run on itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// Every check that the evidence allowed passed.
    Ok,
    /// At least one check failed: the sonar and the navigation disagree.
    Suspect,
}

/// The checks of [`checks`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Check {
    /// The share of rotations that gave a scan.
    Scans,
    /// The median χ² of the sequential matches against the odometry.
    SequentialAgreement,
    /// The slope of the matched rotations on the odometry's.
    RotationSlope,
    /// The angle from the odometry's motion to the matched one.
    TranslationDirection,
    /// The head offset the turns between rotations show.
    HeadOffset,
    /// The share of sequential matches accepted.
    SequentialAcceptance,
    /// The share of matched loop candidates accepted.
    LoopAcceptance,
    /// The map of placed scans under the optimised trajectory against
    /// dead reckoning.
    MapSharpening,
}

/// One failed check: its figure, the limit it broke, and a sentence.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HealthReason {
    pub check: Check,
    pub figure: f64,
    pub limit: f64,
    pub message: String,
}

/// Everything the verdict was drawn from.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct HealthEvidence {
    /// Where the run's sonar mounting came from.
    pub mounting_source: MountingSource,
    /// Nodes, and nodes whose rotation gave a scan.
    pub nodes: usize,
    pub nodes_with_scan: usize,
    pub sequential: SequentialEvidence,
    pub loops: LoopEvidence,
    pub map: MapEvidence,
}

/// Judges a finished run from its nodes (scans), node records (both
/// trajectories), sequential and loop records, and the mounting it used.
pub fn assess(
    nodes: &[NodeData],
    records: &[NodeRecord],
    sequential: &[SequentialRecord],
    loops: &[LoopRecord],
    mounting: &SensorMounting,
) -> Health {
    judge(HealthEvidence {
        mounting_source: mounting.source,
        nodes: nodes.len(),
        nodes_with_scan: nodes.iter().filter(|n| n.has_scan()).count(),
        sequential: evidence::sequential(sequential),
        loops: evidence::loops(loops),
        map: evidence::map(nodes, records),
    })
}

/// The verdict, reasons and cause of `evidence`.
pub fn judge(evidence: HealthEvidence) -> Health {
    let mut reasons: Vec<HealthReason> = Vec::new();
    reasons.extend(checks::scans(evidence.nodes, evidence.nodes_with_scan));
    reasons.extend(checks::sequential(&evidence.sequential));
    reasons.extend(checks::loops(&evidence.loops));
    reasons.extend(checks::map(&evidence.map));
    if reasons.is_empty() {
        return Health {
            verdict: Verdict::Ok,
            reasons,
            cause: None,
            remedy: None,
            evidence,
        };
    }
    let cause = cause::likely(&evidence, &reasons);
    Health {
        verdict: Verdict::Suspect,
        reasons,
        cause: Some(cause),
        remedy: Some(cause.remedy("MISSION")),
        evidence,
    }
}

impl Health {
    /// Lines for a terminal summary: the verdict, and for a suspect run
    /// each reason, the likely cause and the remedy for `mission`.
    pub fn summary_lines(&self, mission: &str) -> Vec<String> {
        let s = &self.evidence.sequential;
        let map = &self.evidence.map;
        let sharpness = match (&map.dead_reckoning, &map.optimised) {
            (Some(d), Some(o)) => format!(
                ", map entropy {:.2} bits under dead reckoning, {:.2} optimised",
                d.entropy_bits, o.entropy_bits
            ),
            _ => String::new(),
        };
        let figures = format!(
            "{} of {} sequential matches accepted, {} of {} matched loops{sharpness}",
            s.accepted, s.attempted, self.evidence.loops.accepted, self.evidence.loops.matched
        );
        let Some(cause) = self.cause else {
            return vec![format!("health: ok ({figures})")];
        };
        let mut lines = vec![format!(
            "health: SUSPECT, the sonar and the navigation disagree ({figures}):"
        )];
        lines.extend(self.reasons.iter().map(|r| format!("  - {}", r.message)));
        if self.evidence.mounting_source == MountingSource::Assumed {
            lines.push("  - the sonar mounting was assumed, not given".to_string());
        }
        lines.push(format!(
            "likely cause and remedy: {}",
            cause.remedy(mission)
        ));
        lines
    }
}

#[cfg(test)]
mod tests {
    use super::evidence::{Fit, TranslationFit};
    use super::*;
    use echofield_frontend::loops::RejectReason;
    use echofield_frontend::sharpness::Sharpness;

    fn fit(value: f64, standard_error: f64) -> Fit {
        Fit {
            value,
            standard_error,
            pairs: 99,
        }
    }

    fn map_entropy(bits: f64) -> Sharpness {
        Sharpness {
            entropy_bits: bits,
            occupied_cells: 1000,
            area_m2: 250.0,
            points: 10_000,
            cell_size_m: 0.5,
        }
    }

    /// A run whose sonar and navigation agree.
    fn agreeing() -> HealthEvidence {
        HealthEvidence {
            mounting_source: MountingSource::Recorded,
            nodes: 100,
            nodes_with_scan: 100,
            sequential: SequentialEvidence {
                attempted: 99,
                matched: 99,
                accepted: 97,
                accepted_share: Some(97.0 / 99.0),
                median_chi2: Some(1.0),
                rotation_slope: Some(fit(1.0, 0.01)),
                translation: Some(TranslationFit {
                    along: fit(0.98, 0.01),
                    across: fit(0.0, 0.01),
                    head_offset: Some([fit(0.05, 0.05), fit(0.05, 0.05)]),
                }),
                rejected_by: [(RejectReason::ReverseMismatch, 2)].into(),
            },
            loops: LoopEvidence {
                matched: 500,
                accepted: 300,
                accepted_share: Some(0.6),
            },
            map: MapEvidence {
                dead_reckoning: Some(map_entropy(13.0)),
                optimised: Some(map_entropy(12.0)),
                entropy_change_bits: Some(-1.0),
            },
        }
    }

    fn checks_failed(evidence: HealthEvidence) -> Vec<Check> {
        judge(evidence).reasons.iter().map(|r| r.check).collect()
    }

    #[test]
    fn agreement_is_ok_without_reasons() {
        let health = judge(agreeing());
        assert_eq!(health.verdict, Verdict::Ok);
        assert!(health.reasons.is_empty() && health.cause.is_none() && health.remedy.is_none());
        let lines = health.summary_lines("m.mcap");
        assert_eq!(lines.len(), 1);
        assert!(
            lines[0].starts_with("health: ok (97 of 99 sequential"),
            "{lines:?}"
        );
    }

    #[test]
    fn each_check_fails_on_its_own_figure() {
        type Spoil = fn(&mut HealthEvidence);
        let cases: [(Check, Spoil); 8] = [
            (Check::Scans, |e| e.nodes_with_scan = 40),
            (Check::SequentialAgreement, |e| {
                e.sequential.median_chi2 = Some(7.0)
            }),
            (Check::RotationSlope, |e| {
                e.sequential.rotation_slope = Some(fit(-0.9, 0.05))
            }),
            (Check::TranslationDirection, |e| {
                let t = e.sequential.translation.as_mut().unwrap();
                (t.along, t.across) = (fit(0.7, 0.01), fit(0.7, 0.01));
            }),
            (Check::HeadOffset, |e| {
                let t = e.sequential.translation.as_mut().unwrap();
                t.head_offset = Some([fit(0.8, 0.1), fit(0.3, 0.1)]);
            }),
            (Check::SequentialAcceptance, |e| {
                e.sequential.accepted_share = Some(0.5)
            }),
            (Check::LoopAcceptance, |e| {
                e.loops.accepted_share = Some(0.1)
            }),
            (Check::MapSharpening, |e| {
                e.map.entropy_change_bits = Some(0.2)
            }),
        ];
        for (check, spoil) in cases {
            let mut evidence = agreeing();
            spoil(&mut evidence);
            let health = judge(evidence);
            assert_eq!(health.verdict, Verdict::Suspect, "{check:?}");
            let failed: Vec<Check> = health.reasons.iter().map(|r| r.check).collect();
            assert_eq!(failed, [check]);
            let reason = &health.reasons[0];
            assert!(reason.figure.is_finite() && !reason.message.is_empty());
        }
    }

    #[test]
    fn thin_evidence_makes_no_check() {
        let mut evidence = agreeing();
        // An offset within three standard errors of zero is not one.
        evidence
            .sequential
            .translation
            .as_mut()
            .unwrap()
            .head_offset = Some([fit(0.8, 0.3), fit(0.0, 0.3)]);
        // A map a little less sharp: within the noise of a map the
        // optimisation had little to correct.
        evidence.map.entropy_change_bits = Some(0.05);
        // Too few loop matches to judge their share.
        evidence.loops = LoopEvidence {
            matched: 10,
            accepted: 0,
            accepted_share: Some(0.0),
        };
        assert!(checks_failed(evidence).is_empty());
        // A loop share just under its limit from few candidates is chance
        // (34 of 143: the upper end of its interval is 0.32); far under
        // it (15 of 143), or under it from many candidates, a failure.
        let loops = |matched: usize, accepted: usize| {
            let mut evidence = agreeing();
            evidence.loops = LoopEvidence {
                matched,
                accepted,
                accepted_share: Some(accepted as f64 / matched as f64),
            };
            checks_failed(evidence)
        };
        assert!(loops(143, 34).is_empty());
        assert_eq!(loops(143, 15), [Check::LoopAcceptance]);
        assert_eq!(loops(4000, 800), [Check::LoopAcceptance]);
        // Too few sequential pairs: none of their checks.
        let mut evidence = agreeing();
        evidence.sequential.matched = checks::MIN_PAIRS - 1;
        evidence.sequential.accepted_share = Some(0.0);
        evidence.sequential.median_chi2 = Some(100.0);
        assert!(checks_failed(evidence).is_empty());
    }

    #[test]
    fn the_share_bound_is_the_wilson_score_interval() {
        // p = 0.5, n = 100, z = 2: (0.52 + 2·√0.0026) / 1.04.
        let expected = (0.52 + 2.0 * 0.0026_f64.sqrt()) / 1.04;
        assert!((checks::share_upper_bound(0.5, 100, 2.0) - expected).abs() < 1e-12);
        // None accepted of 4: (0.5 + 2·√(1/16)) / 2.
        assert!((checks::share_upper_bound(0.0, 4, 2.0) - 0.5).abs() < 1e-12);
        assert_eq!(checks::share_upper_bound(1.0, 10, 2.0), 1.0);
        assert_eq!(checks::share_upper_bound(0.0, 0, 2.0), 1.0);
    }

    #[test]
    fn the_likely_cause_follows_the_evidence() {
        let cause = |spoil: fn(&mut HealthEvidence)| {
            let mut evidence = agreeing();
            spoil(&mut evidence);
            judge(evidence).cause
        };
        // Rejections under a given mounting: the navigation ...
        let rejected = |e: &mut HealthEvidence| e.sequential.accepted_share = Some(0.4);
        assert_eq!(cause(rejected), Some(Cause::Navigation));
        // ... under an assumed one, or with its signature: the mounting.
        assert_eq!(
            cause(|e| {
                e.sequential.accepted_share = Some(0.4);
                e.mounting_source = MountingSource::Assumed;
            }),
            Some(Cause::Mounting)
        );
        assert_eq!(
            cause(|e| e.sequential.rotation_slope = Some(fit(-1.0, 0.1))),
            Some(Cause::Mounting)
        );
        // Most pairs without a match, or most rotations without a scan.
        assert_eq!(
            cause(|e| {
                e.sequential.accepted_share = Some(0.3);
                e.sequential.rejected_by = [(RejectReason::NoMatch, 60)].into();
            }),
            Some(Cause::Structure)
        );
        assert_eq!(cause(|e| e.nodes_with_scan = 10), Some(Cause::Structure));
    }

    #[test]
    fn a_suspect_summary_gives_reasons_cause_and_remedy() {
        let mut evidence = agreeing();
        evidence.mounting_source = MountingSource::Assumed;
        evidence.sequential.accepted_share = Some(0.04);
        evidence.sequential.accepted = 4;
        let health = judge(evidence);
        assert_eq!(health.cause, Some(Cause::Mounting));
        let remedy = health.remedy.as_deref().unwrap();
        assert!(remedy.contains("echofield calibrate MISSION --output cal.toml"));
        let text = health.summary_lines("dive.mcap").join("\n");
        assert!(text.starts_with("health: SUSPECT"), "{text}");
        assert!(text.contains("only 4 of 99 sequential matches"), "{text}");
        assert!(text.contains("assumed"), "{text}");
        assert!(
            text.contains("echofield calibrate dive.mcap --output cal.toml"),
            "{text}"
        );
        // The report gives the verdict and the check names in snake case.
        let json = serde_json::to_value(&health).unwrap();
        assert_eq!(json["verdict"], "suspect");
        assert_eq!(json["reasons"][0]["check"], "sequential_acceptance");
        assert_eq!(json["cause"], "mounting");
    }
}
