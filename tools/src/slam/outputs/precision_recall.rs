//! Precision and recall of the loop-closure gate as its threshold moves
//! (`echofield eval-loops`), from the candidates listed in `loops.csv`.
//!
//! Each swept metric is one quality number of the match `S_to` vs `I_from`
//! ([`METRICS`]):
//! - `mean_intensity`: `s(x*) / N`, the mean image value under the scan
//!   points at the optimum (eq. 5 normalised; accept when `≥ t`);
//! - `inside_fraction`: the fraction of the scan points inside the image at
//!   the optimum (accept when `≥ t`). On the simulated marina nearly every
//!   pair of ground-truth overlap ≥ 0.4 that the pipeline's quality gate
//!   rejects fails this test, not the intensity one (`loops.min_inside_fraction`).
//!
//! Only candidates with a ground-truth verdict (`gt_correct`, i.e. matched
//! and covered by ground truth) enter the sweep. A candidate is *positive*
//! when its match lies within the true-positive tolerances of the run
//! (`gt_correct = true`). At threshold `t` the gate accepts the candidates
//! whose metric passes `t` (a candidate without that metric is never
//! accepted); then
//!
//! ```text
//! precision = TP / accepted      recall = TP / positives      F1 = 2PR / (P + R)
//! ```
//!
//! with `positives` counted over all candidates with a verdict. This is the
//! curve of that one gate alone: the pipeline's other checks (covariance,
//! reverse match, mutual consistency, robust kernel) are not applied, so it
//! shows how far a single threshold can separate right from wrong matches.
//! The thresholds are the distinct values of the metric, strictest first.

use super::loops_csv::{LoopRow, read_loops_csv};
use crate::output::write_atomic;
use crate::plots::precision_recall::{PrCurve, precision_recall_png};
use anyhow::{Result, bail};
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Which way a metric is better.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Direction {
    /// Accept when `value >= threshold`.
    AtLeast,
    /// Accept when `value <= threshold`.
    AtMost,
}

/// A metric the gate can threshold.
#[derive(Clone, Copy, Debug)]
pub struct GateMetric {
    pub name: &'static str,
    pub direction: Direction,
    pub value: fn(&LoopRow) -> Option<f64>,
}

/// The metrics `eval-loops` sweeps.
pub const METRICS: [GateMetric; 2] = [
    GateMetric {
        name: "mean_intensity",
        direction: Direction::AtLeast,
        value: |r| r.mean_intensity,
    },
    GateMetric {
        name: "inside_fraction",
        direction: Direction::AtLeast,
        value: |r| r.inside_fraction,
    },
];

/// The gate at one threshold.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PrPoint {
    pub threshold: f64,
    pub accepted: usize,
    pub true_positives: usize,
    pub false_positives: usize,
    pub precision: f64,
    pub recall: f64,
    pub f1: f64,
}

/// The sweep of one metric.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PrSweep {
    pub metric: &'static str,
    pub direction: Direction,
    /// Candidates with a verdict.
    pub candidates: usize,
    /// Of which correct.
    pub positives: usize,
    /// Strictest threshold first.
    pub points: Vec<PrPoint>,
    /// Index in `points` of the best F1 (the strictest on ties); `None`
    /// when there is no positive.
    pub best: Option<usize>,
}

impl PrSweep {
    pub fn best_point(&self) -> Option<&PrPoint> {
        self.best.map(|i| &self.points[i])
    }

    /// One line for the terminal: the best threshold, or why there is none.
    pub fn summary(&self) -> String {
        let op = match self.direction {
            Direction::AtLeast => ">=",
            Direction::AtMost => "<=",
        };
        match self.best_point() {
            Some(p) => format!(
                "{}: best F1 {:.3} at {} {op} {}: precision {:.3}, recall {:.3} ({} accepted, {} false)",
                self.metric,
                p.f1,
                self.metric,
                p.threshold,
                p.precision,
                p.recall,
                p.accepted,
                p.false_positives
            ),
            None if self.points.is_empty() => format!(
                "{}: no candidate has a value, nothing to sweep",
                self.metric
            ),
            None => format!("{}: no correct candidate, no best threshold", self.metric),
        }
    }
}

/// Sweeps `metric` over the rows with a ground-truth verdict.
pub fn sweep(rows: &[LoopRow], metric: &GateMetric) -> PrSweep {
    let judged: Vec<(Option<f64>, bool)> = rows
        .iter()
        .filter_map(|r| r.gt_correct.map(|c| ((metric.value)(r), c)))
        .collect();
    let positives = judged.iter().filter(|(_, c)| *c).count();
    let mut scored: Vec<(f64, bool)> = judged
        .iter()
        .filter_map(|&(v, c)| v.filter(|x| x.is_finite()).map(|x| (x, c)))
        .collect();
    // Strictest first: descending for AtLeast, ascending for AtMost.
    scored.sort_by(|a, b| match metric.direction {
        Direction::AtLeast => b.0.total_cmp(&a.0),
        Direction::AtMost => a.0.total_cmp(&b.0),
    });
    let points = pr_points(&scored, positives);
    let best = (positives > 0)
        .then(|| {
            points
                .iter()
                .enumerate()
                .fold(None::<(usize, f64)>, |best, (i, p)| match best {
                    Some((_, f)) if f >= p.f1 => best,
                    _ => Some((i, p.f1)),
                })
                .map(|(i, _)| i)
        })
        .flatten();
    PrSweep {
        metric: metric.name,
        direction: metric.direction,
        candidates: judged.len(),
        positives,
        points,
        best,
    }
}

/// One point per distinct value of `scored` (strictest first), counting
/// every row up to and including that value as accepted; `positives` is the
/// number of correct candidates, with or without a value.
fn pr_points(scored: &[(f64, bool)], positives: usize) -> Vec<PrPoint> {
    let mut points = Vec::new();
    let (mut tp, mut fp) = (0usize, 0usize);
    for (i, &(value, correct)) in scored.iter().enumerate() {
        if correct {
            tp += 1;
        } else {
            fp += 1;
        }
        // Emit once per distinct value, after all rows equal to it.
        if scored.get(i + 1).is_some_and(|next| next.0 == value) {
            continue;
        }
        let accepted = tp + fp;
        let precision = tp as f64 / accepted as f64;
        let recall = if positives > 0 {
            tp as f64 / positives as f64
        } else {
            0.0
        };
        let f1 = if precision + recall > 0.0 {
            2.0 * precision * recall / (precision + recall)
        } else {
            0.0
        };
        points.push(PrPoint {
            threshold: value,
            accepted,
            true_positives: tp,
            false_positives: fp,
            precision,
            recall,
            f1,
        });
    }
    points
}

/// Sweeps every metric of [`METRICS`]; an error when no row has a
/// ground-truth verdict.
pub fn sweep_all(rows: &[LoopRow], source: &Path) -> Result<Vec<PrSweep>> {
    if !rows.iter().any(|r| r.gt_correct.is_some()) {
        bail!(
            "{}: no candidate has a ground-truth verdict (column `gt_correct` is empty in all {} rows); \
             eval-loops needs loops.csv from a run on a mission with ground truth",
            source.display(),
            rows.len()
        );
    }
    Ok(METRICS.iter().map(|m| sweep(rows, m)).collect())
}

/// Writes the sweeps as CSV: `metric,direction,threshold,accepted,
/// true_positives,false_positives,precision,recall,f1`.
pub fn write_pr_csv(sweeps: &[PrSweep], w: &mut dyn Write) -> std::io::Result<()> {
    writeln!(
        w,
        "metric,direction,threshold,accepted,true_positives,false_positives,precision,recall,f1"
    )?;
    for s in sweeps {
        let direction = match s.direction {
            Direction::AtLeast => "at_least",
            Direction::AtMost => "at_most",
        };
        for p in &s.points {
            writeln!(
                w,
                "{},{direction},{},{},{},{},{},{},{}",
                s.metric,
                p.threshold,
                p.accepted,
                p.true_positives,
                p.false_positives,
                p.precision,
                p.recall,
                p.f1
            )?;
        }
    }
    Ok(())
}

/// What `eval-loops` found and wrote.
#[derive(Clone, Debug)]
pub struct LoopsPrResult {
    pub sweeps: Vec<PrSweep>,
    /// The run's own gate on the same candidates: accepted, true positives,
    /// positives.
    pub current_gate: (usize, usize, usize),
    pub csv: PathBuf,
    pub png: PathBuf,
}

/// Reads `dir/loops.csv`, sweeps the metrics and writes `prefix.csv` and
/// `prefix.png` (default prefix `dir/loops_pr`), each atomically.
pub fn evaluate_loops_dir(dir: &Path, prefix: Option<&Path>) -> Result<LoopsPrResult> {
    let source = dir.join("loops.csv");
    let rows = read_loops_csv(&source)?;
    let sweeps = sweep_all(&rows, &source)?;
    let prefix = prefix.map_or_else(|| dir.join("loops_pr"), Path::to_path_buf);
    let with_extension = |ext: &str| {
        let mut s = prefix.clone().into_os_string();
        s.push(ext);
        PathBuf::from(s)
    };
    let (csv, png) = (with_extension(".csv"), with_extension(".png"));
    write_atomic(&csv, |w| Ok(write_pr_csv(&sweeps, w)?))?;
    let curves: Vec<PrCurve> = sweeps
        .iter()
        .map(|s| PrCurve {
            label: format!(
                "{} ({})",
                s.metric,
                if s.direction == Direction::AtLeast {
                    "≥ t"
                } else {
                    "≤ t"
                }
            ),
            points: s.points.iter().map(|p| (p.recall, p.precision)).collect(),
            best: s.best_point().map(|p| (p.recall, p.precision, p.threshold)),
        })
        .collect();
    let judged: Vec<&LoopRow> = rows.iter().filter(|r| r.gt_correct.is_some()).collect();
    let caption = format!(
        "Loop gate precision-recall ({} candidates, {} correct)",
        judged.len(),
        judged.iter().filter(|r| r.gt_correct == Some(true)).count()
    );
    let bytes = precision_recall_png(&curves, &caption, (900, 700))?;
    write_atomic(&png, |w| Ok(w.write_all(&bytes)?))?;
    let current_gate = (
        judged.iter().filter(|r| r.accepted).count(),
        judged
            .iter()
            .filter(|r| r.accepted && r.gt_correct == Some(true))
            .count(),
        judged.iter().filter(|r| r.gt_correct == Some(true)).count(),
    );
    Ok(LoopsPrResult {
        sweeps,
        current_gate,
        csv,
        png,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(value: Option<f64>, correct: Option<bool>) -> LoopRow {
        LoopRow {
            mean_intensity: value,
            matched: value.is_some(),
            gt_correct: correct,
            ..LoopRow::default()
        }
    }

    #[test]
    fn ties_share_one_point_and_best_is_strictest_on_equal_f1() {
        // Values 0.9 (right), 0.9 (wrong), 0.5 (right): two points.
        let rows = [
            row(Some(0.9), Some(true)),
            row(Some(0.9), Some(false)),
            row(Some(0.5), Some(true)),
        ];
        let s = sweep(&rows, &METRICS[0]);
        assert_eq!(s.points.len(), 2);
        assert_eq!((s.points[0].accepted, s.points[0].true_positives), (2, 1));
        assert_eq!(s.points[1].precision, 2.0 / 3.0);
        assert_eq!(s.best, Some(1));
        // Equal F1 at two thresholds: the stricter one wins.
        let rows = [row(Some(0.9), Some(true)), row(Some(0.1), Some(false))];
        let s = sweep(&rows, &METRICS[0]);
        assert_eq!(s.points[0].f1, 1.0);
        assert_eq!(s.best, Some(0));
    }

    #[test]
    fn no_verdict_is_an_error_and_no_positive_has_no_best() {
        let rows = [row(Some(0.9), None)];
        let err = sweep_all(&rows, Path::new("loops.csv")).unwrap_err();
        assert!(err.to_string().contains("gt_correct"), "{err}");
        let s = sweep(&[row(Some(0.9), Some(false))], &METRICS[0]);
        assert_eq!(s.best, None);
        assert_eq!(s.points[0].precision, 0.0);
    }
}
