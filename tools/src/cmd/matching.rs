//! `echofield match`: match the scan of one rotation against the acoustic
//! image of another (the paper's measurement model, eq. 5-6).

use anyhow::{Context, Result, bail};
use echofield::matching::MissionRotations;
use echofield::matching::plots::{self, Marker};
use echofield::output::write_bytes_atomic;
use echofield::slam::SlamConfig;
use echofield_frontend::image::AcousticImage;
use echofield_frontend::matcher::{MatchOutcome, SearchWindow, match_scan};
use echofield_graph::Se2;
use nalgebra::Matrix3;
use serde_json::json;
use std::path::PathBuf;

const EXAMPLES: &str = "\
Examples:
  # Rotation 12 against rotation 11 of a simulated mission, prior from dead
  # reckoning, with the score surface (paper Fig. 5) and an overlay
  echofield simulate --scenario tank --seed 1 --output tank.mcap
  echofield match tank.mcap --scan 8 --image 7 --json m.json \\
      --surface surface.png --overlay overlay.png

  # The paper's experiment: a scan against the image of its own rotation
  echofield match tank.mcap --scan 5 --image 5 --json self.json

  # A real static MiniKing log (no navigation: the sonar is taken to be at
  # rest), consecutive rotations, with a prior and window given by hand and
  # a config for its high gain ([segmentation] min_sigma_above_mean = 1.0,
  # min_intensity = 0.0)
  echofield match datasets/msis-real/miniking/full_sonar_scan_2015-05-26-11-38-04.bag \\
      --scan 1 --image 0 --prior 0.5,-0.3,5 --window 2,2,15 --config miniking.toml \\
      --json miniking.json

For the bundled Ping360 log (high gain, saturated walls) set
[segmentation.off_axis] and [image.off_axis] enabled = false: their
margins are for heads that show decibels.

MISSION is an echofield MCAP file, a St Pere log folder, a Ping360 .bin
log or a MiniKing .bag. Rotations are numbered from 0 in time order.
Without --prior the prior is the dead-reckoning motion between the two
rotations' central times and the window is that of a loop candidate
(config [loops.gate]: n_sigma standard deviations of it, clamped to
min_window and max_window; max_window without a covariance); --prior x,y,theta (metres, metres, degrees) is the
pose of the scan's frame in the image's frame.

OUT.json holds pose [x, y, theta] (theta in radians), score (eq. 5),
quality (mean_intensity, inside_fraction, ...), both
read at searched_peak, the peak on the searched image that the last
step's pose fit ([image.pose_fit]) moved to pose,
covariance (3x3, m and rad), the prior and window, and ground_truth and
error when the mission has ground truth. A scan that cannot be matched
(too few points, no echo under any pose of the window) gives matched:
false and a reason, and exit status 0.

In the pictures the estimate is cyan, the prior red and the ground truth
green; the surface is s(x, y) at the estimated heading over the window.";

#[derive(Debug, clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// Mission: MCAP file, St Pere folder, Ping360 .bin or MiniKing .bag.
    pub mission: PathBuf,
    /// Rotation whose scan S_K is matched.
    #[arg(long)]
    pub scan: usize,
    /// Rotation whose acoustic image I_J is matched against.
    #[arg(long)]
    pub image: usize,
    /// Prior pose of the scan in the image frame: x,y,theta (m, m, degrees).
    #[arg(long, value_parser = parse_triple, allow_hyphen_values = true)]
    pub prior: Option<[f64; 3]>,
    /// Search half-widths: x,y,theta (m, m, degrees); overrides the window
    /// derived from the prior's covariance.
    #[arg(long, value_parser = parse_triple)]
    pub window: Option<[f64; 3]>,
    /// Configuration: the file `echofield run --config` reads (this
    /// command uses [dead_reckoning], [rotation], [segmentation], [image],
    /// [matcher] and [loops.gate]); defaults otherwise.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Where to write the result (JSON).
    #[arg(long)]
    pub json: PathBuf,
    /// Also draw the score surface over x, y at the best heading (PNG).
    #[arg(long)]
    pub surface: Option<PathBuf>,
    /// Also draw the image with the scan placed at the estimate (PNG).
    #[arg(long)]
    pub overlay: Option<PathBuf>,
}

fn parse_triple(text: &str) -> Result<[f64; 3], String> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>().map_err(|e| format!("`{v}`: {e}")))
        .collect::<Result<_, _>>()?;
    match values[..] {
        [a, b, c] if values.iter().all(|v| v.is_finite()) => Ok([a, b, c]),
        _ => Err(format!("expected three finite numbers a,b,c, got `{text}`")),
    }
}

pub fn run(args: Args) -> Result<()> {
    super::prepare_output_files([
        Some(&args.json),
        args.surface.as_ref(),
        args.overlay.as_ref(),
    ])?;
    let config = match &args.config {
        Some(path) => SlamConfig::from_toml_file(path)?,
        None => SlamConfig::default(),
    };
    let mission = MissionRotations::load(&args.mission, &config)?;
    let scan = mission.scan(args.scan, &config)?;
    let image = mission.image(args.image, &config)?;
    let (prior, prior_covariance, window) = prior_and_window(&args, &mission, &config)?;
    let outcome =
        match_scan(&scan.points, &image, &prior, &window, &config.matcher).context("matching")?;
    let truth = mission.ground_truth(args.scan, args.image);
    let mut report = json!({
        "mission": args.mission.display().to_string(),
        "scan": args.scan,
        "image": args.image,
        "scan_points": scan.points.len(),
        "stationary_navigation": mission.stationary,
        "prior": pose_json(&prior),
        "prior_covariance": prior_covariance.as_ref().map(matrix_json),
        "window": window,
        "ground_truth": truth.as_ref().map(pose_json),
    });
    let estimate = record_outcome(&mut report, &outcome, truth.as_ref())?;
    let text = serde_json::to_string_pretty(&report)? + "\n";
    write_bytes_atomic(&args.json, text.as_bytes())?;
    let mut markers = vec![Marker {
        pose: prior,
        colour: plots::PRIOR,
    }];
    markers.extend(truth.map(|pose| Marker {
        pose,
        colour: plots::TRUTH,
    }));
    markers.extend(estimate.map(|pose| Marker {
        pose,
        colour: plots::ESTIMATE,
    }));
    let placed = Placed {
        scan: &scan.points,
        image: &image,
        estimate,
        window: &window,
        markers: &markers,
    };
    write_pictures(&args, &placed)
}

/// The prior `image_from_scan`, its covariance (`None` when given by hand)
/// and the search window: `--prior`/`--window` when given, else the
/// dead-reckoning motion between the rotations and the loop gate's window
/// for its covariance (its largest window without one).
fn prior_and_window(
    args: &Args,
    mission: &MissionRotations,
    config: &SlamConfig,
) -> Result<(Se2, Option<Matrix3<f64>>, SearchWindow)> {
    let (prior, prior_covariance) = match args.prior {
        Some([x, y, deg]) => (Se2::new(x, y, deg.to_radians()), None),
        None => {
            let (pose, cov) = mission.prior(args.scan, args.image)?;
            (pose, Some(cov))
        }
    };
    let window = match (args.window, prior_covariance) {
        (Some([x, y, deg]), _) => SearchWindow::new(x, y, deg.to_radians()),
        (None, Some(cov)) => config.loops.gate.window(&cov),
        (None, None) => config.loops.gate.max_window,
    };
    Ok((prior, prior_covariance, window))
}

/// Adds the match's fields (or the no-match reason, also printed to
/// stderr) to `report`, with the error against `truth` when there is one;
/// returns the estimate.
fn record_outcome(
    report: &mut serde_json::Value,
    outcome: &MatchOutcome,
    truth: Option<&Se2>,
) -> Result<Option<Se2>> {
    match outcome {
        MatchOutcome::Match(m) => {
            report["matched"] = json!(true);
            report["pose"] = pose_json(&m.image_from_scan);
            report["score"] = json!(m.score);
            report["quality"] = serde_json::to_value(&m.quality)?;
            report["covariance"] = matrix_json(&m.covariance);
            report["searched_peak"] = pose_json(&m.searched_peak);
            report["coarse_pose"] = pose_json(&m.coarse);
            report["stats"] = serde_json::to_value(&m.stats)?;
            if let Some(t) = truth {
                let e = t.between(&m.image_from_scan);
                report["error"] = json!({
                    "translation_m": e.translation().norm(),
                    "rotation_rad": e.theta().abs(),
                });
            }
            Ok(Some(m.image_from_scan))
        }
        MatchOutcome::NoMatch { reason } => {
            eprintln!("no match: {reason}");
            report["matched"] = json!(false);
            report["reason"] = serde_json::to_value(reason)?;
            report["reason_text"] = json!(reason.to_string());
            Ok(None)
        }
    }
}

/// What the pictures show: the scan (scan frame), the image, the estimate
/// and the markers (image frame).
struct Placed<'a> {
    scan: &'a [nalgebra::Point2<f64>],
    image: &'a AcousticImage,
    estimate: Option<Se2>,
    window: &'a SearchWindow,
    markers: &'a [Marker],
}

/// Writes `--surface` (errors without a match: no estimate to centre it
/// on) and `--overlay` when asked for.
fn write_pictures(args: &Args, placed: &Placed) -> Result<()> {
    if let Some(path) = &args.surface {
        let Some(centre) = placed.estimate else {
            bail!("no match, so no surface to draw at the estimate");
        };
        let half_width_m = placed.window.x_m.max(placed.window.y_m).max(0.5);
        let png = plots::score_surface_png(
            placed.scan,
            placed.image,
            &centre,
            half_width_m,
            200,
            placed.markers,
        )?;
        write_bytes_atomic(path, &png)?;
    }
    if let Some(path) = &args.overlay {
        let png = plots::overlay_png(placed.image, placed.scan, placed.markers)?;
        write_bytes_atomic(path, &png)?;
    }
    Ok(())
}

fn pose_json(pose: &Se2) -> serde_json::Value {
    json!([pose.x(), pose.y(), pose.theta()])
}

fn matrix_json(m: &Matrix3<f64>) -> serde_json::Value {
    json!([
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ])
}

#[cfg(test)]
mod tests {
    use super::*;
    use echofield_datasets::mcap::write_mission;
    use echofield_datasets::sim::{Scenario, simulate_mission};

    fn args(mission: PathBuf, dir: &std::path::Path) -> Args {
        Args {
            mission,
            scan: 4,
            image: 3,
            prior: None,
            window: None,
            config: None,
            json: dir.join("out/match.json"),
            surface: Some(dir.join("out/surface.png")),
            overlay: Some(dir.join("out/overlay.png")),
        }
    }

    #[test]
    fn matches_two_rotations_of_a_simulated_mission_and_draws_them() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("tank.mcap");
        let mission = simulate_mission(&Scenario::named("tank").unwrap(), 1).unwrap();
        write_mission(&path, &mission).unwrap();
        run(args(path.clone(), dir.path())).unwrap();
        let text = std::fs::read_to_string(dir.path().join("out/match.json")).unwrap();
        let report: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(report["matched"], true);
        assert_eq!(report["pose"].as_array().unwrap().len(), 3);
        assert_eq!(report["searched_peak"].as_array().unwrap().len(), 3);
        assert!(report["score"].as_f64().unwrap() > 0.0);
        let mean = report["quality"]["mean_intensity"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&mean));
        let cov = report["covariance"].as_array().unwrap();
        assert_eq!(cov.len(), 3);
        assert!(cov.iter().all(|row| row.as_array().unwrap().len() == 3));
        // The mission has ground truth: dead-reckoning prior, error reported.
        assert!(
            report["error"]["translation_m"].as_f64().unwrap() < 0.5,
            "{text}"
        );
        for png in ["surface.png", "overlay.png"] {
            let bytes = std::fs::read(dir.path().join("out").join(png)).unwrap();
            let picture = image::load_from_memory(&bytes).unwrap();
            assert!(picture.width() > 50 && picture.height() > 50, "{png}");
        }

        // A prior far away: no match, reported in the JSON, not an error.
        let far = Args {
            prior: Some([500.0, 0.0, 0.0]),
            window: Some([1.0, 1.0, 5.0]),
            surface: None,
            ..args(path.clone(), dir.path())
        };
        run(far).unwrap();
        let text = std::fs::read_to_string(dir.path().join("out/match.json")).unwrap();
        let report: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(report["matched"], false);
        assert_eq!(report["reason"]["kind"], "no_overlap");

        // A rotation that does not exist: an error naming the range.
        let err = run(Args {
            scan: 999,
            ..args(path, dir.path())
        })
        .unwrap_err();
        assert!(
            format!("{err:#}").contains("rotation 999 does not exist"),
            "{err:#}"
        );
    }

    #[test]
    fn triples_parse_and_bad_ones_are_refused() {
        assert_eq!(parse_triple("1,-2.5, 30").unwrap(), [1.0, -2.5, 30.0]);
        assert!(parse_triple("1,2").unwrap_err().contains("three"));
        assert!(parse_triple("1,x,3").unwrap_err().contains("`x`"));
        assert!(parse_triple("1,2,NaN").is_err());
    }
}
