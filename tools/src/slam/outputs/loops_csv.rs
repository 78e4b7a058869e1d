//! `loops.csv`: one row per loop-closure candidate, for evaluating and
//! tuning the loop gate (`echofield eval-loops`).
//!
//! Comma separated, a header row, empty fields for values that do not
//! exist (no match, no ground truth) or are not finite. Columns ([`COLUMNS`]):
//!
//! | column | meaning |
//! |---|---|
//! | `from`, `to` | node ids; `S_to` was matched against `I_from` |
//! | `examined_at` | newest node when the candidate was examined |
//! | `densified` | `true` for a pair of the densification pass after the mission (`loops.densify`) |
//! | `predicted_overlap` | overlap predicted from the prior (0-1) |
//! | `prior_sigma_xy_m`, `prior_sigma_theta_deg` | standard deviations of the prior (largest xy axis; θ) |
//! | `matched` | `true` when the matcher returned a pose |
//! | `x_m`, `y_m`, `theta_rad` | the matched `from_from_to` |
//! | `score` | `s(x*)` of eq. (5) |
//! | `mean_intensity` | `s(x*) / N`: mean image value under the points (0-1, higher is better) |
//! | `inside_fraction` | fraction of the points inside the image (0-1) |
//! | `points` | scan points used |
//! | `surface_fit_residual` | relative RMS residual of the quadratic fit of the peak |
//! | `cov_xx` ... `cov_tt` | covariance of the loop's measurement (m², m·rad, rad²): xx, xy, xt, yy, yt, tt; the match's, or for a partial loop its marginal across the unconstrained direction with 10 m along it |
//! | `partial` | `true` for a partial loop (`loops.densify_partial`): constrained across one horizontal direction and in heading only, its component along that direction taken from the estimate |
//! | `reverse_translation_m`, `reverse_rotation_deg` | disagreement of the symmetric match `S_from` vs `I_to` |
//! | `robust_weight` | weight of the edge under the robust kernel at the solution |
//! | `accepted` | `true` when the loop is an edge of the final graph |
//! | `rejected_by` | the first check that failed (`quality`, `covariance`, `inconsistent`, ...) |
//! | `gt_error_m`, `gt_error_deg` | error of the match against the ground-truth relative pose |
//! | `gt_overlap` | ground-truth scan overlap of the pair (0-1) |
//! | `gt_correct` | `true` when the match is within the true-positive tolerances |
//! | `verdict` | `tp` accepted and correct, `fp` accepted and wrong, `fn` rejected but correct, `tn` rejected and wrong |

use anyhow::{Context, Result, bail};
use echofield_frontend::loops::LoopRecord;
use std::io::Write;
use std::path::Path;

/// The header of `loops.csv`, in order.
pub const COLUMNS: [&str; 33] = [
    "from",
    "to",
    "examined_at",
    "densified",
    "predicted_overlap",
    "prior_sigma_xy_m",
    "prior_sigma_theta_deg",
    "matched",
    "x_m",
    "y_m",
    "theta_rad",
    "score",
    "mean_intensity",
    "inside_fraction",
    "points",
    "surface_fit_residual",
    "cov_xx",
    "cov_xy",
    "cov_xt",
    "cov_yy",
    "cov_yt",
    "cov_tt",
    "partial",
    "reverse_translation_m",
    "reverse_rotation_deg",
    "robust_weight",
    "accepted",
    "rejected_by",
    "gt_error_m",
    "gt_error_deg",
    "gt_overlap",
    "gt_correct",
    "verdict",
];

/// One row of `loops.csv` (see the module doc for each field).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoopRow {
    pub from: u64,
    pub to: u64,
    pub examined_at: Option<u64>,
    pub densified: Option<bool>,
    pub predicted_overlap: Option<f64>,
    pub matched: bool,
    /// `from_from_to` as `[x_m, y_m, theta_rad]`.
    pub pose: Option<[f64; 3]>,
    pub score: Option<f64>,
    pub mean_intensity: Option<f64>,
    pub inside_fraction: Option<f64>,
    pub points: Option<usize>,
    pub surface_fit_residual: Option<f64>,
    /// `[xx, xy, xt, yy, yt, tt]`.
    pub covariance: Option<[f64; 6]>,
    /// A partial loop; `None` without a measurement.
    pub partial: Option<bool>,
    pub reverse_translation_m: Option<f64>,
    pub reverse_rotation_deg: Option<f64>,
    pub robust_weight: Option<f64>,
    pub accepted: bool,
    pub rejected_by: Option<String>,
    pub gt_error_m: Option<f64>,
    pub gt_error_deg: Option<f64>,
    pub gt_overlap: Option<f64>,
    pub gt_correct: Option<bool>,
    /// Square roots of the prior covariance's largest xy eigenvalue (m)
    /// and of its θ variance (deg): how uncertain the pair was.
    pub prior_sigma_xy_m: Option<f64>,
    pub prior_sigma_theta_deg: Option<f64>,
}

impl LoopRow {
    /// The row of a pipeline candidate.
    pub fn from_record(r: &LoopRecord) -> Self {
        let c = r.covariance;
        let prior_xy = r
            .prior_covariance
            .fixed_view::<2, 2>(0, 0)
            .symmetric_eigenvalues();
        Self {
            from: r.from,
            to: r.to,
            examined_at: Some(r.examined_at),
            densified: Some(r.densified),
            predicted_overlap: Some(r.predicted_overlap),
            matched: r.matched.is_some(),
            pose: r.matched.map(|p| [p.x(), p.y(), p.theta()]),
            score: r.score,
            mean_intensity: r.quality.as_ref().map(|q| q.mean_intensity),
            inside_fraction: r.quality.as_ref().map(|q| q.inside_fraction),
            points: r.quality.as_ref().map(|q| q.points),
            surface_fit_residual: r.quality.as_ref().map(|q| q.surface_fit_residual),
            covariance: c.map(|c| {
                [
                    c[(0, 0)],
                    c[(0, 1)],
                    c[(0, 2)],
                    c[(1, 1)],
                    c[(1, 2)],
                    c[(2, 2)],
                ]
            }),
            partial: r.measurement.map(|_| r.unconstrained_direction.is_some()),
            reverse_translation_m: r.reverse.as_ref().and_then(|v| v.translation_diff_m),
            reverse_rotation_deg: r
                .reverse
                .as_ref()
                .and_then(|v| v.rotation_diff_rad)
                .map(f64::to_degrees),
            robust_weight: r.robust_weight,
            accepted: r.accepted,
            rejected_by: r.rejected_by.map(reason_name),
            gt_error_m: r.gt_error_m,
            gt_error_deg: r.gt_error_deg,
            gt_overlap: r.gt_overlap,
            gt_correct: r.true_positive,
            prior_sigma_xy_m: Some(prior_xy.max().max(0.0).sqrt()),
            prior_sigma_theta_deg: Some(r.prior_covariance[(2, 2)].max(0.0).sqrt().to_degrees()),
        }
    }

    /// `tp`, `fp`, `fn` or `tn` when the row has a ground-truth verdict.
    pub fn verdict(&self) -> Option<&'static str> {
        self.gt_correct
            .map(|correct| match (self.accepted, correct) {
                (true, true) => "tp",
                (true, false) => "fp",
                (false, true) => "fn",
                (false, false) => "tn",
            })
    }

    fn fields(&self) -> Vec<String> {
        // A non-finite value (a degenerate covariance, say) is written as
        // missing, so that the file always reads back.
        let f = |v: Option<f64>| {
            v.filter(|x| x.is_finite())
                .map(|x| x.to_string())
                .unwrap_or_default()
        };
        let mut out = vec![
            self.from.to_string(),
            self.to.to_string(),
            self.examined_at.map(|v| v.to_string()).unwrap_or_default(),
            self.densified.map(|v| v.to_string()).unwrap_or_default(),
            f(self.predicted_overlap),
            f(self.prior_sigma_xy_m),
            f(self.prior_sigma_theta_deg),
            self.matched.to_string(),
        ];
        out.extend((0..3).map(|i| f(self.pose.map(|p| p[i]))));
        out.extend([
            f(self.score),
            f(self.mean_intensity),
            f(self.inside_fraction),
            self.points.map(|v| v.to_string()).unwrap_or_default(),
            f(self.surface_fit_residual),
        ]);
        out.extend((0..6).map(|i| f(self.covariance.map(|c| c[i]))));
        out.extend([
            self.partial.map(|v| v.to_string()).unwrap_or_default(),
            f(self.reverse_translation_m),
            f(self.reverse_rotation_deg),
            f(self.robust_weight),
            self.accepted.to_string(),
            self.rejected_by.clone().unwrap_or_default(),
            f(self.gt_error_m),
            f(self.gt_error_deg),
            f(self.gt_overlap),
            self.gt_correct.map(|v| v.to_string()).unwrap_or_default(),
            self.verdict().unwrap_or("").to_string(),
        ]);
        out
    }
}

/// The snake_case name of a reject reason (as in `report.json`).
pub fn reason_name(reason: echofield_frontend::loops::RejectReason) -> String {
    match serde_json::to_value(reason) {
        Ok(serde_json::Value::String(s)) => s,
        _ => format!("{reason:?}"),
    }
}

/// Writes the header and one line per row (the `csv` crate: fields with a
/// comma or quote are quoted, so any reject reason reads back).
pub fn write_loops_csv(rows: &[LoopRow], w: &mut dyn Write) -> std::io::Result<()> {
    let mut writer = csv::Writer::from_writer(w);
    writer.write_record(COLUMNS)?;
    for row in rows {
        writer.write_record(row.fields())?;
    }
    writer.flush()
}

/// Reads `loops.csv`. Columns are found by their header names (their order
/// may differ and unknown columns are ignored); `from`, `to` and `accepted`
/// are required. Errors name the file, the line (1-based) and the column.
pub fn read_loops_csv(path: &Path) -> Result<Vec<LoopRow>> {
    // UTF-8 errors name line and byte offset; a byte-order mark is dropped.
    let text = echofield_graph::io::read_text(path)?;
    parse_loops_csv(text.strip_prefix('\u{feff}').unwrap_or(&text), path)
}

/// Parses `loops.csv` text with the `csv` crate (fields trimmed, blank
/// lines skipped); `path` only names the source in errors.
pub fn parse_loops_csv(text: &str, path: &Path) -> Result<Vec<LoopRow>> {
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let at = |e: &csv::Error| {
        let line = e
            .position()
            .map_or(String::new(), |p| format!("line {}: ", p.line()));
        format!("{}: {line}", path.display())
    };
    let names: Vec<String> = match reader.headers() {
        Ok(h) if !h.is_empty() => h.iter().map(str::to_string).collect(),
        Ok(_) => bail!(
            "{}: empty file, expected a loops.csv header",
            path.display()
        ),
        Err(e) => bail!("{}{e}", at(&e)),
    };
    for required in ["from", "to", "accepted"] {
        if !names.iter().any(|n| n == required) {
            bail!(
                "{}: line 1: the header has no `{required}` column",
                path.display()
            );
        }
    }
    let mut rows = Vec::new();
    for record in reader.records() {
        let record = match record {
            Ok(r) => r,
            Err(e) => match e.kind() {
                csv::ErrorKind::UnequalLengths { len, .. } => {
                    bail!("{}{len} fields, the header has {}", at(&e), names.len())
                }
                _ => bail!("{}{e}", at(&e)),
            },
        };
        let line = record.position().map_or(0, |p| p.line() as usize);
        let get = |name: &str| -> Option<&str> {
            names
                .iter()
                .position(|n| n == name)
                .and_then(|i| record.get(i))
                .filter(|v| !v.is_empty())
        };
        rows.push(
            RowParser {
                path,
                line,
                get: &get,
            }
            .row()?,
        );
    }
    Ok(rows)
}

/// Typed access to the fields of one line.
struct RowParser<'a> {
    path: &'a Path,
    line: usize,
    get: &'a dyn Fn(&str) -> Option<&'a str>,
}

impl RowParser<'_> {
    fn parse<T: std::str::FromStr>(&self, column: &str, what: &str) -> Result<Option<T>> {
        match (self.get)(column) {
            None => Ok(None),
            Some(v) => v.parse::<T>().map(Some).map_err(|_| {
                anyhow::anyhow!(
                    "{}: line {}: column `{column}`: `{v}` is not {what}",
                    self.path.display(),
                    self.line
                )
            }),
        }
    }

    fn number(&self, column: &str) -> Result<Option<f64>> {
        let v = self.parse::<f64>(column, "a number")?;
        match v {
            Some(x) if !x.is_finite() => bail!(
                "{}: line {}: column `{column}`: {x} is not finite",
                self.path.display(),
                self.line
            ),
            _ => Ok(v),
        }
    }

    fn required<T>(&self, column: &str, v: Option<T>) -> Result<T> {
        v.with_context(|| {
            format!(
                "{}: line {}: column `{column}` is empty",
                self.path.display(),
                self.line
            )
        })
    }

    /// The three numbers of `names`, `None` unless all three are given.
    fn triple(&self, names: [&str; 3]) -> Result<Option<[f64; 3]>> {
        let v = [
            self.number(names[0])?,
            self.number(names[1])?,
            self.number(names[2])?,
        ];
        Ok(match v {
            [Some(a), Some(b), Some(c)] => Some([a, b, c]),
            _ => None,
        })
    }

    /// The upper triangle of the covariance (`cov_xx` ... `cov_tt`), `None`
    /// unless all six are given.
    fn covariance(&self) -> Result<Option<[f64; 6]>> {
        let cov_names = ["cov_xx", "cov_xy", "cov_xt", "cov_yy", "cov_yt", "cov_tt"];
        let mut cov = [0.0; 6];
        let mut has_cov = true;
        for (slot, name) in cov.iter_mut().zip(cov_names) {
            match self.number(name)? {
                Some(v) => *slot = v,
                None => has_cov = false,
            }
        }
        Ok(has_cov.then_some(cov))
    }

    /// The row of the current line; errors name the line and column. A
    /// `verdict` column, when present, must agree with its inputs.
    fn row(&self) -> Result<LoopRow> {
        let covariance = self.covariance()?;
        let row = LoopRow {
            from: self.required("from", self.parse("from", "a node id")?)?,
            to: self.required("to", self.parse("to", "a node id")?)?,
            examined_at: self.parse("examined_at", "a node id")?,
            densified: self.parse("densified", "true or false")?,
            predicted_overlap: self.number("predicted_overlap")?,
            matched: self.parse("matched", "true or false")?.unwrap_or(false),
            pose: self.triple(["x_m", "y_m", "theta_rad"])?,
            score: self.number("score")?,
            mean_intensity: self.number("mean_intensity")?,
            inside_fraction: self.number("inside_fraction")?,
            points: self.parse("points", "a count")?,
            surface_fit_residual: self.number("surface_fit_residual")?,
            covariance,
            partial: self.parse("partial", "true or false")?,
            reverse_translation_m: self.number("reverse_translation_m")?,
            reverse_rotation_deg: self.number("reverse_rotation_deg")?,
            robust_weight: self.number("robust_weight")?,
            accepted: self.required("accepted", self.parse("accepted", "true or false")?)?,
            rejected_by: (self.get)("rejected_by").map(str::to_string),
            gt_error_m: self.number("gt_error_m")?,
            gt_error_deg: self.number("gt_error_deg")?,
            gt_overlap: self.number("gt_overlap")?,
            gt_correct: self.parse("gt_correct", "true or false")?,
            prior_sigma_xy_m: self.number("prior_sigma_xy_m")?,
            prior_sigma_theta_deg: self.number("prior_sigma_theta_deg")?,
        };
        if let Some(v) = (self.get)("verdict")
            && Some(v) != row.verdict()
        {
            bail!(
                "{}: line {}: column `verdict`: `{v}` contradicts accepted = {} and gt_correct = {:?}",
                self.path.display(),
                self.line,
                row.accepted,
                row.gt_correct
            );
        }
        Ok(row)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> LoopRow {
        LoopRow {
            from: 3,
            to: 40,
            examined_at: Some(40),
            densified: Some(false),
            predicted_overlap: Some(0.8),
            matched: true,
            pose: Some([1.5, -0.25, 0.125]),
            score: Some(210.5),
            mean_intensity: Some(0.625),
            inside_fraction: Some(1.0),
            points: Some(337),
            surface_fit_residual: Some(0.03),
            covariance: Some([0.01, 0.0, 0.001, 0.02, 0.0, 0.0004]),
            partial: Some(false),
            reverse_translation_m: Some(0.04),
            reverse_rotation_deg: Some(0.2),
            robust_weight: Some(1.0),
            accepted: false,
            rejected_by: Some("inconsistent".into()),
            gt_error_m: Some(0.1),
            gt_error_deg: Some(0.5),
            gt_overlap: Some(0.7),
            gt_correct: Some(true),
            prior_sigma_xy_m: Some(1.25),
            prior_sigma_theta_deg: Some(2.0),
        }
    }

    #[test]
    fn rows_round_trip_and_empty_fields_are_none() {
        let rows = vec![
            sample(),
            LoopRow {
                from: 1,
                to: 9,
                ..LoopRow::default()
            },
        ];
        let mut bytes = Vec::new();
        write_loops_csv(&rows, &mut bytes).unwrap();
        let text = String::from_utf8(bytes).unwrap();
        assert!(text.starts_with("from,to,examined_at,"));
        assert!(text.lines().nth(1).unwrap().ends_with(",true,fn"), "{text}");
        let back = parse_loops_csv(&text, Path::new("loops.csv")).unwrap();
        assert_eq!(back, rows);
        // A field with a comma and a quote is quoted, and reads back.
        let odd = vec![LoopRow {
            rejected_by: Some("a, \"b\"".into()),
            ..sample()
        }];
        let mut bytes = Vec::new();
        write_loops_csv(&odd, &mut bytes).unwrap();
        let text = String::from_utf8(bytes).unwrap();
        assert_eq!(parse_loops_csv(&text, Path::new("loops.csv")).unwrap(), odd);
        // Blank lines and CRLF line ends are accepted.
        let crlf = text.replace('\n', "\r\n\r\n");
        assert_eq!(parse_loops_csv(&crlf, Path::new("loops.csv")).unwrap(), odd);
    }

    #[test]
    fn bad_fields_are_errors_naming_line_and_column() {
        let text = "from,to,accepted,mean_intensity\n1,5,true,0.5\n2,6,false,abc\n";
        let err = parse_loops_csv(text, Path::new("x.csv"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("line 3") && err.contains("mean_intensity"),
            "{err}"
        );
        let err = parse_loops_csv("from,to\n1,2\n", Path::new("x.csv"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("accepted"), "{err}");
        let err = parse_loops_csv("from,to,accepted\n1,2\n", Path::new("x.csv"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("line 2") && err.contains("2 fields"), "{err}");
        let err = parse_loops_csv(
            "from,to,accepted,gt_correct,verdict\n1,2,true,false,tp\n",
            Path::new("x.csv"),
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("verdict"), "{err}");
        let err = parse_loops_csv("from,to,accepted,score\n1,2,true,NaN\n", Path::new("x.csv"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("not finite"), "{err}");
        assert!(parse_loops_csv("", Path::new("x.csv")).is_err());
    }
}
