//! `echofield eval-loops`: precision-recall of the loop-closure gate from a
//! run's `loops.csv`.

use anyhow::Result;
use echofield::slam::outputs::precision_recall::evaluate_loops_dir;
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
#[command(after_help = "\
Examples:
  # Sweep the gate of a run on a mission with ground truth
  echofield eval-loops out/demo

  # Write the curve elsewhere: tuned/pr.csv and tuned/pr.png
  echofield eval-loops out/demo --output-prefix tuned/pr

Swept metrics (from loops.csv): mean_intensity, the mean acoustic-image
value under the scan points at the match (accept when >= t), and
inside_fraction, the share of the scan points
inside the image at the match (accept when >= t). Only candidates with a
ground-truth verdict (column gt_correct) count; a candidate is positive
when its match is within the run's true-positive tolerances. Precision =
TP / accepted, recall = TP / positives, for that one threshold alone (the
other checks of the pipeline are not applied). The best-F1 threshold of
each metric is printed; set it in the [loops] section of the run's config
(min_mean_intensity, min_inside_fraction).")]
pub struct Args {
    /// Output folder of `echofield run` or `echofield demo` (holds loops.csv).
    pub dir: PathBuf,
    /// Write PREFIX.csv and PREFIX.png instead of DIR/loops_pr.csv and
    /// DIR/loops_pr.png.
    #[arg(long)]
    pub output_prefix: Option<PathBuf>,
}

pub fn run(args: Args) -> Result<()> {
    let result = evaluate_loops_dir(&args.dir, args.output_prefix.as_deref())?;
    let (accepted, tp, positives) = result.current_gate;
    println!(
        "{} candidates with ground truth, {positives} correct; the run accepted {accepted} ({tp} correct)",
        result.sweeps.first().map_or(0, |s| s.candidates)
    );
    for sweep in &result.sweeps {
        println!("{}", sweep.summary());
    }
    println!(
        "wrote {} and {}",
        result.csv.display(),
        result.png.display()
    );
    Ok(())
}
