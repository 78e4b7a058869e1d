//! The configuration of a SLAM run: one TOML section per stage.
//!
//! A file is laid over [`SlamConfig::default`]
//! ([`crate::config_file::from_toml_over`]): every key it leaves out keeps
//! the pipeline's default, also inside a section it partly sets (an
//! `[image.off_axis]` with one key keeps the image's margin 25, not the
//! suppression type's 20). Every section is `deny_unknown_fields`:
//! an unknown key at any depth is an error that names its full path
//! (`loops.min_separaton_nodes`). The frontend and
//! backend sections are those crates' own config structs; the sections
//! that belong to the pipeline itself (sequential matching, loop closures,
//! incremental optimisation, evaluation) are defined here and in
//! [`super::loops`].
//!
//! ```toml
//! [image]
//! cell_size_m = 0.2
//! [loops]
//! max_candidates_per_node = 4
//! [backend.solver.robust.loop]
//! kind = "cauchy"
//! c = 2.796
//! ```

use super::SlamError;
use echofield_backend::{Initialisation, OutlierConfig, RobustConfig, RobustKernel, SolverConfig};
use echofield_frontend::config_check;
use echofield_frontend::dead_reckoning::DeadReckoningConfig;
use echofield_frontend::image::ImageConfig;
use echofield_frontend::loops::LoopConfig;
use echofield_frontend::matcher::{MatchGate, MatcherConfig};
use echofield_frontend::mounting::MountingConfig;
use echofield_frontend::rotation::RotationConfig;
use echofield_frontend::segmentation::SegmentationConfig;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Everything `echofield run` can be told.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SlamConfig {
    /// Overrides of the mission's sensor mounting (every key optional).
    pub mounting: MountingConfig,
    /// The dead-reckoning EKF (noise, heading offset, extrapolation).
    pub dead_reckoning: DeadReckoningConfig,
    /// Cutting the beam stream into rotations.
    pub rotation: RotationConfig,
    /// Range extraction for the scans `S_k`.
    pub segmentation: SegmentationConfig,
    /// The acoustic images `I_k`.
    pub image: ImageConfig,
    /// The scan matcher (eq. 5-6), shared by sequential and loop matches.
    pub matcher: MatcherConfig,
    /// Sequential matches `S_k` vs `I_{k-1}`.
    pub sequential: SequentialConfig,
    /// Loop-closure candidates, checks and mutual consistency.
    pub loops: LoopConfig,
    /// The pose-graph optimisation.
    pub backend: BackendConfig,
    /// Evaluation against ground truth (only when the mission has it).
    pub evaluation: EvaluationConfig,
}

impl Default for SlamConfig {
    /// The frontend's and backend's own defaults (`tools/configs/default.toml`
    /// lists them all, documented).
    fn default() -> Self {
        Self {
            mounting: MountingConfig::default(),
            dead_reckoning: DeadReckoningConfig::default(),
            rotation: RotationConfig::default(),
            segmentation: SegmentationConfig::default(),
            image: ImageConfig::default(),
            matcher: MatcherConfig::default(),
            sequential: SequentialConfig::default(),
            loops: LoopConfig::default(),
            backend: BackendConfig::default(),
            evaluation: EvaluationConfig::default(),
        }
    }
}

impl SlamConfig {
    /// Parses TOML laid over the defaults (see the module doc); an unknown
    /// key is an error naming its path, an invalid value an error naming
    /// its field.
    pub fn from_toml_str(text: &str) -> Result<Self, SlamError> {
        crate::config_file::check_removed_keys(text)
            .map_err(|e| SlamError::config(e.path, e.message))?;
        let config = crate::config_file::from_toml_over(text, &Self::default())
            .map_err(|e| SlamError::config(e.path, e.message))?
            .derive();
        config.validate()?;
        Ok(config)
    }

    /// The values derived from other sections, in this one place: the
    /// image's range smoothing and blind zone are the segmentation's
    /// (`segmentation.smoothing_bins`, `segmentation.blind_zone_m`), so that
    /// the image `I_k` peaks at the ranges of the scan `S_k` and clears the
    /// same ringing; the heading term of the loop closer's drift model
    /// (`LoopConfig::drift_heading_sigma_rad`) is the dead reckoning's
    /// wandering heading error (`dead_reckoning.heading_bias_sigma_rad`).
    /// Each derived value that differs from the library default is logged.
    pub fn derive(mut self) -> Self {
        let image = &mut self.image;
        let segmentation = &self.segmentation;
        if image.range_smoothing_bins != segmentation.smoothing_bins {
            tracing::info!(
                "image range smoothing: {} bins (segmentation.smoothing_bins)",
                segmentation.smoothing_bins
            );
            image.range_smoothing_bins = segmentation.smoothing_bins;
        }
        if image.blind_zone_m != segmentation.blind_zone_m {
            tracing::info!(
                "image blind zone: {} m (segmentation.blind_zone_m)",
                segmentation.blind_zone_m
            );
            image.blind_zone_m = segmentation.blind_zone_m;
        }
        let heading = self.dead_reckoning.heading_bias_sigma_rad;
        if self.loops.drift_heading_sigma_rad != heading {
            tracing::info!(
                "loop drift heading sigma: {heading} rad (dead_reckoning.heading_bias_sigma_rad)"
            );
            self.loops.drift_heading_sigma_rad = heading;
        }
        self
    }

    /// Reads a TOML file (see [`SlamConfig::from_toml_str`]).
    pub fn from_toml_file(path: &Path) -> anyhow::Result<Self> {
        use anyhow::Context;
        let text = crate::config_file::read_config_text(path)?;
        Self::from_toml_str(&text).with_context(|| format!("in config {}", path.display()))
    }

    /// The configuration of `path` when given, else the defaults (the
    /// `--config` option of the commands that run the pipeline).
    pub fn from_optional_toml_file(path: Option<&Path>) -> anyhow::Result<Self> {
        path.map_or_else(|| Ok(Self::default()), Self::from_toml_file)
    }

    /// The effective configuration as TOML (for `config.toml` beside the
    /// outputs).
    pub fn to_toml_string(&self) -> String {
        toml::to_string_pretty(self).expect("the config serialises to TOML")
    }

    /// Checks every section; the error names the first bad field by its
    /// TOML path. Never changes a value.
    pub fn validate(&self) -> Result<(), SlamError> {
        let section = |name: &str, r: Result<(), echofield_frontend::FrontendError>| {
            r.map_err(|e| match e {
                echofield_frontend::FrontendError::InvalidConfig { field, message } => {
                    SlamError::config(format!("{name}.{field}"), message)
                }
                other => SlamError::config(name, other.to_string()),
            })
        };
        section("mounting", self.mounting.validate())?;
        section("dead_reckoning", self.dead_reckoning.validate())?;
        section("rotation", self.rotation.validate())?;
        section("segmentation", self.segmentation.validate())?;
        section("image", self.image.validate())?;
        section("matcher", self.matcher.validate())?;
        self.sequential.validate()?;
        self.loops.validate().map_err(SlamError::from_config)?;
        self.backend.validate()?;
        self.evaluation.validate()?;
        Ok(())
    }
}

/// [`echofield_frontend::config_check::check_range`] as a [`SlamError`].
pub(crate) fn check_range(field: &str, value: f64, lo: f64, hi: f64) -> Result<(), SlamError> {
    config_check::check_range(field, value, lo, hi).map_err(SlamError::from_config)
}

/// Sequential matching: `S_k` against `I_{k-1}` with the dead-reckoning
/// motion as prior.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SequentialConfig {
    /// Match consecutive rotations at all (false: dead reckoning only
    /// between consecutive nodes). Default true.
    pub enabled: bool,
    /// Also match `S_{k-1}` against `I_k` (module `symmetric`): the edge
    /// then carries the mean of both matches, and is not added when they
    /// disagree beyond `gate.reverse_max_translation_m` or 2°. Doubles the
    /// cost of sequential matching. Default true.
    pub symmetric: bool,
    /// The search window and acceptance gate of a sequential match
    /// ([`MatchGate`], `[sequential.gate]`, defaults
    /// [`MatchGate::sequential`]); the prior is the dead-reckoning motion.
    pub gate: MatchGate,
    /// Earlier rotations whose images join `I_{k-1}` in the submap that
    /// `S_k` is matched against (0: `I_{k-1}` alone). Not a key: derived
    /// from the data, [`SUBMAP_ROTATIONS_SCAN_ONLY`] for binary
    /// (thresholded) intensities, 0 otherwise (`sequential.rs`).
    #[serde(skip)]
    pub submap_rotations: usize,
}

/// The submap depth of scan-only data (`SequentialConfig::submap_rotations`):
/// a thresholded log keeps a wall's echo in one rotation and drops it in
/// the next, so `I_{k-1}` alone can lack walls that `S_k` holds and the
/// match slides along the walls it has; the images of the three rotations
/// before it (about a minute of travel at survey speed) bring them back.
/// Chosen on simulated thresholded missions (EXPERIMENTS.md § The
/// sequential match against a submap).
pub const SUBMAP_ROTATIONS_SCAN_ONLY: usize = 3;

/// Largest squared Mahalanobis distance between a submap match and the
/// inverse of its reverse match, with both (floored) covariances: 11.34,
/// the 99% quantile of χ² with 3 degrees of freedom. The reverse match
/// reads `I_k` alone, which lacks the walls its rotation dropped, so a
/// fixed tolerance would reject the matches the submap made right; its
/// covariance says along which directions it cannot tell.
pub const SUBMAP_REVERSE_MAX_CHI2: f64 = 11.34;

/// Largest squared Mahalanobis distance between a sequential match and
/// the dead-reckoning motion, with both covariances: 16.3, the 99.9%
/// quantile of χ² with 3 degrees of freedom. Larger: the match is not
/// used. A test level rather than a tuning value (both covariances are
/// the models' own), so not a config key.
pub const SEQUENTIAL_MAX_PRIOR_CHI2: f64 = 16.3;

impl Default for SequentialConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            symmetric: true,
            gate: MatchGate::sequential(),
            submap_rotations: 0,
        }
    }
}

impl SequentialConfig {
    /// Checks the gate; errors name the key (`sequential.gate.n_sigma`).
    pub fn validate(&self) -> Result<(), SlamError> {
        self.gate
            .validate("sequential")
            .map_err(SlamError::from_config)
    }
}

/// The pose-graph optimisation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BackendConfig {
    /// Re-optimise during the mission after loops are accepted (warm
    /// started from the current estimate), so that later loop candidates
    /// get corrected priors and small search windows. Default true.
    pub incremental: bool,
    /// Iteration limit of an incremental solve. Default 10.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): the incremental solves are warm started and only have to follow the newest loops; the final solve's `solver.max_iterations` is the one a user sets.
    #[serde(skip)]
    pub incremental_max_iterations: usize,
    /// Standard deviation of a heading prior on every node, rad: the
    /// dead-reckoning heading, which a compass bounds in absolute terms,
    /// while relative edges alone would let the heading random-walk along
    /// the chain. A constant heading bias only rotates the whole map. 0
    /// adds no priors.
    ///
    /// `None` (the default) derives it per node from the heading unit's
    /// slowly wandering error of the dead reckoning
    /// (`dead_reckoning.heading_bias_sigma_rad` `σ`, a Gauss-Markov
    /// process of correlation time `τ`): such an error is the same at
    /// nearby nodes, so independent priors of `σ` would count it once per
    /// node and hold a whole stretch of the track to it. The joint
    /// information of that process over nodes `Δt` apart is tridiagonal;
    /// it splits into a relative heading term between consecutive nodes,
    /// which the odometry edges already carry (their heading variance
    /// includes the change of the error over `Δt`), and a prior of
    /// standard deviation `σ·√((1 + φ)/(1 − φ))` on each node, `φ =
    /// exp(−Δt/τ)`, `Δt` the time since the previous node. With the
    /// defaults (2°, 120 s) and 13.6 s rotations that is 8.4°. Without a
    /// wandering error (`σ` or `τ` 0) the prior is the heading's white
    /// noise, `dead_reckoning.heading_noise_rad`.
    ///
    /// Derived priors against a fixed one, measured: EXPERIMENTS.md § Heading
    /// priors.
    pub heading_prior_sigma_rad: Option<f64>,
    /// The final batch solve (and, with `initialisation = "current"`
    /// forced, the incremental ones). Default: Levenberg-Marquardt from the
    /// chordal initialisation, Cauchy kernel (c = 2.796) on loop edges.
    pub solver: SolverConfig,
    /// How the final solve finds and switches off false loop closures
    /// (`echofield_backend::optimize_robust`): the loop edges are the
    /// suspects, judged with `solver`'s loop kernel.
    pub outliers: OutlierConfig,
}

impl Default for BackendConfig {
    fn default() -> Self {
        Self {
            incremental: true,
            incremental_max_iterations: 10,
            heading_prior_sigma_rad: None,
            solver: SolverConfig {
                robust: RobustConfig::loops_only(RobustKernel::CAUCHY_DEFAULT),
                ..SolverConfig::default()
            },
            // The kernel stays on the loops that are kept: scan-matched
            // loops can be slightly off without being false.
            outliers: OutlierConfig {
                final_kernel: true,
                ..OutlierConfig::default()
            },
        }
    }
}

impl BackendConfig {
    /// The heading prior's standard deviation for a node `dt_s` after the
    /// previous one (see `heading_prior_sigma_rad`); `None` for no prior.
    pub fn heading_prior_sigma(
        &self,
        dead_reckoning: &DeadReckoningConfig,
        dt_s: f64,
    ) -> Option<f64> {
        match self.heading_prior_sigma_rad {
            Some(sigma) => (sigma > 0.0).then_some(sigma),
            None => {
                let sigma = dead_reckoning.heading_bias_sigma_rad;
                let tau = dead_reckoning.heading_bias_time_constant_s;
                if sigma > 0.0 && tau > 0.0 {
                    let phi = (-dt_s.abs() / tau).exp();
                    let derived = sigma * ((1.0 + phi) / (1.0 - phi)).sqrt();
                    // Nodes at one instant (phi = 1) get no information.
                    Some(if derived.is_finite() {
                        derived.min(std::f64::consts::PI)
                    } else {
                        std::f64::consts::PI
                    })
                } else {
                    (dead_reckoning.heading_noise_rad > 0.0)
                        .then_some(dead_reckoning.heading_noise_rad)
                }
            }
        }
    }

    pub fn validate(&self) -> Result<(), SlamError> {
        if self.incremental_max_iterations == 0 {
            return Err(SlamError::config(
                "backend.incremental_max_iterations",
                "must be at least 1",
            ));
        }
        if let Some(sigma) = self.heading_prior_sigma_rad
            && sigma != 0.0
        {
            check_range(
                "backend.heading_prior_sigma_rad",
                sigma,
                1e-6,
                std::f64::consts::PI,
            )?;
        }
        for (field, value) in [
            (
                "incremental_max_iterations",
                self.incremental_max_iterations,
            ),
            ("solver.max_iterations", self.solver.max_iterations),
        ] {
            if value > MAX_ITERATIONS {
                return Err(SlamError::config(
                    format!("backend.{field}"),
                    format!("must be at most {MAX_ITERATIONS}, got {value}"),
                ));
            }
        }
        if self.solver.threads > MAX_THREADS {
            return Err(SlamError::config(
                "backend.solver.threads",
                format!("must be at most {MAX_THREADS}, got {}", self.solver.threads),
            ));
        }
        self.solver.validate().map_err(|e| match &e {
            echofield_backend::ConfigError::OutOfRange { field, .. } => {
                let field = format!("backend.solver.{field}");
                SlamError::config(robust_parameter(&field, &self.solver), e.to_string())
            }
            _ => SlamError::config("backend.solver", e.to_string()),
        })?;
        self.outliers.validate().map_err(|e| match &e {
            echofield_backend::ConfigError::OutOfRange { field, .. } => {
                SlamError::config(format!("backend.outliers.{field}"), e.to_string())
            }
            _ => SlamError::config("backend.outliers", e.to_string()),
        })
    }

    /// The solver configuration of the incremental solves.
    pub fn incremental_solver(&self) -> SolverConfig {
        SolverConfig {
            initialisation: Initialisation::Current,
            max_iterations: self.incremental_max_iterations,
            ..self.solver.clone()
        }
    }
}

/// The most iterations a solve may be given: a solve that has not
/// converged after that many will not, and a larger cap only hides it.
const MAX_ITERATIONS: usize = 10_000;

/// The most threads of a solve's factorisation (more only cost memory).
const MAX_THREADS: usize = 1024;

/// `field` (`backend.solver.robust.loop`) with the kernel parameter that
/// is not finite and positive appended (`backend.solver.robust.loop.c`),
/// read from the kernel's TOML form so that every kernel's parameters are
/// named; `field` itself when it is not a kernel's or none is bad.
fn robust_parameter(field: &str, solver: &SolverConfig) -> String {
    let Some(kind) = field.strip_prefix("backend.solver.robust.") else {
        return field.to_string();
    };
    let Ok(toml::Value::Table(robust)) = toml::Value::try_from(solver.robust) else {
        return field.to_string();
    };
    let Some(toml::Value::Table(kernel)) = robust.get(kind) else {
        return field.to_string();
    };
    kernel
        .iter()
        .find(|(_, v)| v.as_float().is_some_and(|x| !(x.is_finite() && x > 0.0)))
        .map_or_else(|| field.to_string(), |(name, _)| format!("{field}.{name}"))
}

/// Evaluation against ground truth. Ground truth is read only here, after
/// the estimation: nothing of it reaches the pipeline.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EvaluationConfig {
    /// A loop edge is a true positive when its relative pose is within this
    /// distance of the ground-truth relative pose, metres. Default 0.5.
    pub true_positive_translation_m: f64,
    /// ... and within this angle, degrees. Default 3.
    pub true_positive_rotation_deg: f64,
    /// Cell side of the ground-truth scan overlap of a node pair
    /// ([`echofield_frontend::scan::overlap`]: the fraction of the points
    /// of `S_k`, placed in node `j`'s frame with the ground-truth relative
    /// pose, that land on the cells holding a point of `S_j` or touching
    /// one), metres. Default 0.5.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): fixed so that recall figures stay
    /// comparable between runs.
    #[serde(skip)]
    pub overlap_distance_m: f64,
    /// Node pairs with at least this ground-truth scan overlap (and at
    /// least `loops.min_separation_nodes` apart) form the recall set.
    /// Default 0.4: the lowest overlap at which a correctly registered
    /// pair can pass the loop quality gate. The matcher's mean intensity
    /// at the true relative pose is about the overlap (EXPERIMENTS.md §
    /// Evaluation), and `loops.gate.min_mean_intensity` was 0.35 when this was
    /// set (0.30 now), so pairs that overlap less can hardly be closed by
    /// any pose the matcher finds; they are not misses of the loop closer.
    /// Lower it together with `loops.gate.min_mean_intensity`.
    pub recall_min_overlap: f64,
    /// Distances of the relative pose error, metres. Default 10, 50, 100.
    pub rpe_distances_m: Vec<f64>,
}

impl Default for EvaluationConfig {
    fn default() -> Self {
        Self {
            true_positive_translation_m: 0.5,
            true_positive_rotation_deg: 3.0,
            overlap_distance_m: 0.5,
            recall_min_overlap: 0.4,
            rpe_distances_m: vec![10.0, 50.0, 100.0],
        }
    }
}

impl EvaluationConfig {
    pub fn validate(&self) -> Result<(), SlamError> {
        check_range(
            "evaluation.true_positive_translation_m",
            self.true_positive_translation_m,
            0.0,
            1e6,
        )?;
        check_range(
            "evaluation.true_positive_rotation_deg",
            self.true_positive_rotation_deg,
            0.0,
            180.0,
        )?;
        check_range(
            "evaluation.overlap_distance_m",
            self.overlap_distance_m,
            1e-3,
            100.0,
        )?;
        check_range(
            "evaluation.recall_min_overlap",
            self.recall_min_overlap,
            0.0,
            1.0,
        )?;
        for (i, d) in self.rpe_distances_m.iter().enumerate() {
            check_range(&format!("evaluation.rpe_distances_m[{i}]"), *d, 1e-3, 1e7)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use echofield_frontend::matcher::SearchWindow;

    #[test]
    fn a_window_is_one_key_and_its_old_table_form_says_what_replaces_it() {
        let config =
            SlamConfig::from_toml_str("[loops.gate]\nmax_window = [8, 8.5, 0.15]\n").unwrap();
        assert_eq!(
            config.loops.gate.max_window,
            SearchWindow::new(8.0, 8.5, 0.15)
        );
        assert_eq!(
            config.loops.gate.min_window,
            LoopConfig::default().gate.min_window
        );

        let old = "[sequential.gate.min_window]\nx_m = 0.4\ny_m = 0.4\ntheta_rad = 0.05\n";
        let message = format!("{:#}", SlamConfig::from_toml_str(old).unwrap_err());
        assert!(message.contains("sequential.gate.min_window"), "{message}");
        assert!(message.contains("[x_m, y_m, theta_rad]"), "{message}");
        assert_eq!(
            message.matches("sequential.gate.min_window").count(),
            1,
            "{message}"
        );

        let bad = "[loops.gate]\nmin_window = [0.5, 0.5, 4.0]\n";
        let message = SlamConfig::from_toml_str(bad).unwrap_err().to_string();
        assert!(
            message.contains("loops.gate.min_window[2] (theta_rad)"),
            "{message}"
        );
    }

    #[test]
    fn heading_priors_follow_the_dead_reckonings_wandering_heading_error() {
        let backend = BackendConfig::default();
        let dr = DeadReckoningConfig::default();
        // 2°, 120 s, 13.6 s apart: phi = exp(-0.11333) = 0.89285,
        // (1 + phi) / (1 - phi) = 17.666, so 2° x 4.2031 = 8.406°.
        let sigma = backend.heading_prior_sigma(&dr, 13.6).unwrap();
        assert!((sigma.to_degrees() - 8.406).abs() < 0.005, "{sigma}");
        // Nodes farther apart share less of the error: stronger priors,
        // tending to 2° (the error's own deviation) for independent nodes.
        let far = backend.heading_prior_sigma(&dr, 600.0).unwrap();
        assert!(
            far < sigma && (far.to_degrees() - 2.0).abs() < 0.05,
            "{far}"
        );
        // Two nodes at one instant: no information, capped at π.
        let same = backend.heading_prior_sigma(&dr, 0.0).unwrap();
        assert_eq!(same, std::f64::consts::PI);
        // Without a wandering error: the white heading noise.
        let white = DeadReckoningConfig {
            heading_bias_sigma_rad: 0.0,
            ..DeadReckoningConfig::default()
        };
        assert_eq!(
            backend.heading_prior_sigma(&white, 13.6),
            Some(white.heading_noise_rad)
        );
        // A fixed value wins; 0 means no priors.
        let fixed = BackendConfig {
            heading_prior_sigma_rad: Some(0.05),
            ..BackendConfig::default()
        };
        assert_eq!(fixed.heading_prior_sigma(&dr, 13.6), Some(0.05));
        let none = BackendConfig {
            heading_prior_sigma_rad: Some(0.0),
            ..BackendConfig::default()
        };
        assert_eq!(none.heading_prior_sigma(&dr, 13.6), None);
    }
}
