//! `eval-loops` on a hand-made `loops.csv` whose precision-recall curve was
//! computed by hand.

use echofield::slam::outputs::precision_recall::{Direction, evaluate_loops_dir};

/// Eight candidates. Four are correct (rows 1, 2, 4, 6); row 7 was not
/// matched (no metrics, no verdict). The `second_peak_ratio` column of
/// files written before the matcher dropped its second-peak search is
/// read past (an unknown column).
///
/// mean_intensity (accept when >= t), strictest first, positives P = 4:
///
/// | t   | accepted | TP | precision | recall | F1     |
/// |-----|----------|----|-----------|--------|--------|
/// | 0.9 | 1        | 1  | 1         | 1/4    | 2/5    |
/// | 0.8 | 2        | 2  | 1         | 1/2    | 2/3    |
/// | 0.7 | 3        | 2  | 2/3       | 1/2    | 4/7    |
/// | 0.6 | 4        | 3  | 3/4       | 3/4    | 3/4    |
/// | 0.5 | 6        | 4  | 2/3       | 1      | 4/5    |  <- best
/// | 0.3 | 7        | 4  | 4/7       | 1      | 8/11   |
///
/// inside_fraction (accept when >= t):
///
/// | t    | accepted | TP | precision | recall | F1     |
/// |------|----------|----|-----------|--------|--------|
/// | 1.0  | 1        | 1  | 1         | 1/4    | 2/5    |
/// | 0.95 | 2        | 1  | 1/2       | 1/4    | 1/3    |
/// | 0.9  | 3        | 1  | 1/3       | 1/4    | 2/7    |
/// | 0.8  | 4        | 2  | 1/2       | 1/2    | 1/2    |
/// | 0.6  | 6        | 4  | 2/3       | 1      | 4/5    |  <- best
/// | 0.5  | 7        | 4  | 4/7       | 1      | 8/11   |
const LOOPS_CSV: &str = "\
from,to,accepted,rejected_by,matched,mean_intensity,second_peak_ratio,gt_correct,verdict,inside_fraction
0,20,true,,true,0.9,0.2,true,tp,1.0
1,21,true,,true,0.8,0.5,true,tp,0.6
2,22,true,,true,0.7,0.1,false,fp,0.9
3,23,false,quality,true,0.6,0.3,true,fn,0.8
4,24,false,quality,true,0.5,0.6,false,tn,0.5
5,25,false,quality,true,0.5,0.3,true,fn,0.6
6,26,false,no_match,false,,,,,
7,27,false,quality,true,0.3,,false,tn,0.95
";

fn assert_point(
    p: &echofield::slam::outputs::precision_recall::PrPoint,
    expect: (f64, usize, usize, f64, f64, f64),
) {
    let (t, accepted, tp, precision, recall, f1) = expect;
    assert_eq!(p.threshold, t);
    assert_eq!((p.accepted, p.true_positives), (accepted, tp), "at {t}");
    assert_eq!(p.false_positives, accepted - tp);
    for (got, want, what) in [
        (p.precision, precision, "precision"),
        (p.recall, recall, "recall"),
        (p.f1, f1, "F1"),
    ] {
        assert!((got - want).abs() < 1e-12, "{what} at {t}: {got} vs {want}");
    }
}

/// One sweep: its metric and direction, every point (see [`assert_point`])
/// and the threshold of its best F1.
fn assert_sweep(
    sweep: &echofield::slam::outputs::precision_recall::PrSweep,
    metric: (&str, Direction),
    expected: &[(f64, usize, usize, f64, f64, f64)],
    best_threshold: f64,
) {
    assert_eq!((sweep.metric, sweep.direction), metric);
    assert_eq!(sweep.points.len(), expected.len(), "{}", metric.0);
    for (p, &e) in sweep.points.iter().zip(expected) {
        assert_point(p, e);
    }
    assert_eq!(sweep.best_point().unwrap().threshold, best_threshold);
}

#[test]
fn sweep_matches_the_hand_computed_curve() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("loops.csv"), LOOPS_CSV).unwrap();
    let result = evaluate_loops_dir(dir.path(), None).unwrap();
    assert_eq!(result.sweeps.len(), 2);
    // The run's own gate: 3 accepted, 2 of them right, of 4 correct.
    assert_eq!(result.current_gate, (3, 2, 4));

    let mean = &result.sweeps[0];
    assert_sweep(
        mean,
        ("mean_intensity", Direction::AtLeast),
        &[
            (0.9, 1, 1, 1.0, 0.25, 0.4),
            (0.8, 2, 2, 1.0, 0.5, 2.0 / 3.0),
            (0.7, 3, 2, 2.0 / 3.0, 0.5, 4.0 / 7.0),
            (0.6, 4, 3, 0.75, 0.75, 0.75),
            (0.5, 6, 4, 2.0 / 3.0, 1.0, 0.8),
            (0.3, 7, 4, 4.0 / 7.0, 1.0, 8.0 / 11.0),
        ],
        0.5,
    );
    assert_eq!((mean.candidates, mean.positives), (7, 4));

    let inside = &result.sweeps[1];
    assert_sweep(
        inside,
        ("inside_fraction", Direction::AtLeast),
        &[
            (1.0, 1, 1, 1.0, 0.25, 0.4),
            (0.95, 2, 1, 0.5, 0.25, 1.0 / 3.0),
            (0.9, 3, 1, 1.0 / 3.0, 0.25, 2.0 / 7.0),
            (0.8, 4, 2, 0.5, 0.5, 0.5),
            (0.6, 6, 4, 2.0 / 3.0, 1.0, 0.8),
            (0.5, 7, 4, 4.0 / 7.0, 1.0, 8.0 / 11.0),
        ],
        0.6,
    );
    assert_eq!((inside.candidates, inside.positives), (7, 4));

    // The CSV holds the same numbers; the PNG decodes.
    let csv = std::fs::read_to_string(dir.path().join("loops_pr.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        "metric,direction,threshold,accepted,true_positives,false_positives,precision,recall,f1"
    );
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), 12);
    let check = |row: &str, head: &str, numbers: [f64; 3]| {
        let fields: Vec<&str> = row.split(',').collect();
        assert_eq!(fields[..6].join(","), head);
        for (field, want) in fields[6..].iter().zip(numbers) {
            assert!(
                (field.parse::<f64>().unwrap() - want).abs() < 1e-12,
                "{row}"
            );
        }
    };
    check(
        rows[4],
        "mean_intensity,at_least,0.5,6,4,2",
        [2.0 / 3.0, 1.0, 0.8],
    );
    check(
        rows[10],
        "inside_fraction,at_least,0.6,6,4,2",
        [2.0 / 3.0, 1.0, 0.8],
    );
    let png = image::open(dir.path().join("loops_pr.png")).unwrap();
    assert_eq!((png.width(), png.height()), (900, 700));
}

/// A metric that no candidate has: that sweep is empty and says so,
/// instead of claiming there is no correct candidate.
#[test]
fn a_metric_without_values_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let no_inside: String = LOOPS_CSV
        .lines()
        .map(|line| {
            let mut fields: Vec<&str> = line.split(',').collect();
            if fields[9] != "inside_fraction" {
                fields[9] = "";
            }
            fields.join(",") + "\n"
        })
        .collect();
    std::fs::write(dir.path().join("loops.csv"), no_inside).unwrap();
    let result = evaluate_loops_dir(dir.path(), None).unwrap();
    let inside = &result.sweeps[1];
    assert!(inside.points.is_empty() && inside.best_point().is_none());
    assert_eq!(
        inside.summary(),
        "inside_fraction: no candidate has a value, nothing to sweep"
    );
    // The other metric is unaffected.
    assert_eq!(result.sweeps[0].best_point().unwrap().threshold, 0.5);
}

#[test]
fn output_prefix_moves_both_files() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("loops.csv"), LOOPS_CSV).unwrap();
    let prefix = dir.path().join("tuned").join("pr");
    let result = evaluate_loops_dir(dir.path(), Some(&prefix)).unwrap();
    assert_eq!(result.csv, dir.path().join("tuned/pr.csv"));
    assert!(dir.path().join("tuned/pr.csv").is_file());
    assert!(dir.path().join("tuned/pr.png").is_file());
    assert!(!dir.path().join("loops_pr.csv").exists());
}

#[test]
fn loops_without_ground_truth_are_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("loops.csv"),
        "from,to,accepted,mean_intensity,gt_correct\n0,20,true,0.9,\n1,30,false,0.2,\n",
    )
    .unwrap();
    let err = evaluate_loops_dir(dir.path(), None)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("ground-truth") && err.contains("gt_correct"),
        "{err}"
    );
    // A missing loops.csv names the file.
    let empty = tempfile::tempdir().unwrap();
    let err = format!("{:#}", evaluate_loops_dir(empty.path(), None).unwrap_err());
    assert!(err.contains("loops.csv"), "{err}");
}
