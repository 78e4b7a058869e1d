//! Keys that config files no longer take (issue 36 cut the user-facing
//! keys from 124 to about 70), each with what replaces it, so that an old
//! file fails with an error that says what to write instead rather than
//! with serde's bare "unknown field".
//!
//! A key listed here is either *moved* (the gate keys of `[sequential]`
//! and `[loops]` went into their `gate` tables), *derived* from another
//! key, or now a *constant*: a library parameter that config files leave
//! at its default (the field's doc comment, or the named constant's, says
//! why it is fixed). Every constant keeps the default the key had, so a
//! run without these keys is the run it was.

use super::ConfigFileError;

/// `(path, what replaces it)` of every removed key.
pub const REMOVED_KEYS: &[(&str, &str)] = &[
    // [sequential] and [loops]: the shared gate.
    ("sequential.n_sigma", "moved to `sequential.gate.n_sigma`"),
    (
        "sequential.min_window",
        "moved to `sequential.gate.min_window`",
    ),
    (
        "sequential.max_window",
        "moved to `sequential.gate.max_window`",
    ),
    (
        "sequential.min_mean_intensity",
        "moved to `sequential.gate.min_mean_intensity`",
    ),
    (
        "sequential.min_sigma",
        "moved to `sequential.gate.min_sigma`",
    ),
    (
        "sequential.reverse_max_translation_m",
        "moved to `sequential.gate.reverse_max_translation_m`",
    ),
    (
        "sequential.reverse_window",
        "derived: the reverse match searches `sequential.gate.min_window`",
    ),
    (
        "sequential.reverse_max_rotation_rad",
        "now the constant 2° (`echofield_frontend::matcher::gate::REVERSE_MAX_ROTATION_RAD`)",
    ),
    (
        "sequential.max_prior_chi2",
        "now the constant 16.3 (`echofield::slam::config::SEQUENTIAL_MAX_PRIOR_CHI2`)",
    ),
    ("loops.n_sigma", "moved to `loops.gate.n_sigma`"),
    ("loops.min_window", "moved to `loops.gate.min_window`"),
    ("loops.max_window", "moved to `loops.gate.max_window`"),
    (
        "loops.min_mean_intensity",
        "moved to `loops.gate.min_mean_intensity`",
    ),
    ("loops.min_sigma", "moved to `loops.gate.min_sigma`"),
    (
        "loops.reverse_max_translation_m",
        "moved to `loops.gate.reverse_max_translation_m`",
    ),
    (
        "loops.reverse_window",
        "derived: the reverse match climbs within `loops.gate.min_window`",
    ),
    (
        "loops.reverse_max_rotation_rad",
        "now the constant 2° (`echofield_frontend::matcher::gate::REVERSE_MAX_ROTATION_RAD`)",
    ),
    (
        "loops.drift_heading_sigma_rad",
        "derived: `dead_reckoning.heading_bias_sigma_rad`",
    ),
    (
        "loops.wide_searches_per_node",
        "now the constant 1 (`echofield_frontend::loops::config::WIDE_SEARCHES_PER_NODE`)",
    ),
    (
        "loops.escalate_min_predicted_overlap",
        "now the constant 0.8 (`echofield_frontend::loops::config::ESCALATE_MIN_PREDICTED_OVERLAP`)",
    ),
    (
        "loops.window_edge_fraction",
        "now the constant 0.05 (`echofield_frontend::loops::config::WINDOW_EDGE_FRACTION`)",
    ),
    (
        "loops.consistency_max_chi2",
        "now the constant 11.34 (`echofield_frontend::loops::config::CONSISTENCY_MAX_CHI2`)",
    ),
    (
        "loops.densify_correlation",
        "now the constant 1 (`echofield_frontend::loops::config::DENSIFY_CORRELATION`)",
    ),
    (
        "loops.densify_max_window",
        "now the constant [2 m, 2 m, 6°] (`echofield_frontend::loops::config::densify_max_window`)",
    ),
    (
        "loops.densify_min_predicted_overlap",
        "now the constant 0.4 (`echofield_frontend::loops::config::DENSIFY_MIN_PREDICTED_OVERLAP`)",
    ),
    // [dead_reckoning]
    (
        "dead_reckoning.dvl_gate_chi2",
        "now fixed at 20 (`DeadReckoningConfig::dvl_gate_chi2`, a library parameter)",
    ),
    (
        "dead_reckoning.dvl_gate_max_consecutive",
        "now fixed at 3 (`DeadReckoningConfig::dvl_gate_max_consecutive`, a library parameter)",
    ),
    (
        "dead_reckoning.dvl_noise_adaptation_samples",
        "now fixed at 30 (`DeadReckoningConfig::dvl_noise_adaptation_samples`, a library parameter); `dvl_velocity_noise_mps` stays its floor",
    ),
    (
        "dead_reckoning.yaw_rate_check_window_s",
        "now fixed at 1 s (`DeadReckoningConfig::yaw_rate_check_window_s`, a library parameter); `yaw_rate_noise_radps` stays its floor",
    ),
    (
        "dead_reckoning.yaw_rate_random_walk_radps_per_sqrt_s",
        "now fixed at 0.02 (`DeadReckoningConfig::yaw_rate_random_walk_radps_per_sqrt_s`, a library parameter)",
    ),
    (
        "dead_reckoning.heading_random_walk_rad_per_sqrt_s",
        "now fixed at 0; a wandering heading error is `heading_bias_sigma_rad` with `heading_bias_time_constant_s`",
    ),
    (
        "dead_reckoning.max_dvl_gap_s",
        "now fixed at 5 s (`DeadReckoningConfig::max_dvl_gap_s`, a library parameter)",
    ),
    (
        "dead_reckoning.max_extrapolation_s",
        "now fixed at 2 s (`DeadReckoningConfig::max_extrapolation_s`, a library parameter)",
    ),
    // [rotation], [segmentation]
    (
        "rotation.max_gap_beam_periods",
        "now fixed at 3 (`RotationConfig::max_gap_beam_periods`, a library parameter)",
    ),
    (
        "rotation.min_partial_coverage_rad",
        "now fixed at π (`RotationConfig::min_partial_coverage_rad`, a library parameter)",
    ),
    (
        "segmentation.min_peak_separation_m",
        "now fixed at 1 m (`SegmentationConfig::min_peak_separation_m`, a library parameter)",
    ),
    (
        "segmentation.min_scan_points",
        "now fixed at 10 (`SegmentationConfig::min_scan_points`, a library parameter); `matcher.min_points` is the key",
    ),
    (
        "segmentation.beam_width.backscatter_exponent",
        "now fixed at 2, Lambert's law (`BeamWidthCorrection::backscatter_exponent`, a library parameter)",
    ),
    (
        "segmentation.beam_width.max_incidence_rad",
        "now fixed at 75° (`BeamWidthCorrection::max_incidence_rad`, a library parameter)",
    ),
    (
        "segmentation.beam_width.max_bend_rad",
        "now fixed at 20° (`BeamWidthCorrection::max_bend_rad`, a library parameter)",
    ),
    (
        "segmentation.off_axis.max_angle_rad",
        "now fixed at 3° (`OffAxisSuppression::max_angle_rad`, a library parameter)",
    ),
    (
        "segmentation.off_axis.max_range_difference_m",
        "now fixed at 0.3 m (`OffAxisSuppression::max_range_difference_m`, a library parameter)",
    ),
    // [image], [matcher]
    (
        "image.angular_half_width_rad",
        "now fixed at 1.5° (`ImageConfig::angular_half_width_rad`, a library parameter)",
    ),
    (
        "image.max_wedge_rad",
        "now fixed at 6° (`ImageConfig::max_wedge_rad`, a library parameter)",
    ),
    (
        "image.range_smoothing_bins",
        "derived: `segmentation.smoothing_bins`",
    ),
    ("image.blind_zone_m", "derived: `segmentation.blind_zone_m`"),
    (
        "image.normalisation_quantile",
        "now fixed at 0.999 (`ImageConfig::normalisation_quantile`, a library parameter)",
    ),
    (
        "image.intensity_exponent",
        "now fixed at 1 (`ImageConfig::intensity_exponent`, a library parameter)",
    ),
    (
        "image.smoothing_sigma_m",
        "now fixed at 0 (`ImageConfig::smoothing_sigma_m`, a library parameter)",
    ),
    (
        "image.pyramid_levels",
        "now fixed at 7 (`ImageConfig::pyramid_levels`, a library parameter)",
    ),
    (
        "image.off_axis.max_angle_rad",
        "now fixed at 3° (`OffAxisSuppression::max_angle_rad`, a library parameter)",
    ),
    (
        "image.off_axis.max_range_difference_m",
        "now fixed at 0.3 m (`OffAxisSuppression::max_range_difference_m`, a library parameter)",
    ),
    (
        "image.pose_fit.off_axis_margin",
        "now fixed at 10 (`PoseFitRaster::off_axis_margin`, a library parameter)",
    ),
    (
        "image.pose_fit.range_smoothing_bins",
        "now fixed at 1 (`PoseFitRaster::range_smoothing_bins`, a library parameter)",
    ),
    (
        "matcher.covariance_scale",
        "now fixed at 1 (`MatcherConfig::covariance_scale`, a library parameter)",
    ),
    // [backend], [evaluation]
    (
        "backend.incremental_max_iterations",
        "now fixed at 10 (`BackendConfig::incremental_max_iterations`, a library parameter)",
    ),
    (
        "backend.solver.relative_cost_tolerance",
        "now fixed at 1e-10 (`SolverConfig::relative_cost_tolerance`, a library parameter)",
    ),
    (
        "backend.solver.step_tolerance",
        "now fixed at 1e-10 (`SolverConfig::step_tolerance`, a library parameter)",
    ),
    (
        "backend.solver.initial_lambda",
        "now fixed at 1e-10 (`SolverConfig::initial_lambda`, a library parameter)",
    ),
    (
        "backend.outliers.growth_step_nodes",
        "now fixed at 100 (`OutlierConfig::growth_step_nodes`, a library parameter)",
    ),
    (
        "backend.outliers.growth_iterations",
        "now fixed at 10 (`OutlierConfig::growth_iterations`, a library parameter)",
    ),
    (
        "backend.outliers.max_rounds",
        "now fixed at 10 (`OutlierConfig::max_rounds`, a library parameter)",
    ),
    (
        "backend.outliers.support_window_nodes",
        "now fixed at 10 (`OutlierConfig::support_window_nodes`, a library parameter)",
    ),
    (
        "backend.outliers.support_chi2",
        "now fixed at 11.34 (`OutlierConfig::support_chi2`, a library parameter)",
    ),
    (
        "backend.outliers.min_support",
        "now fixed at 3 (`OutlierConfig::min_support`, a library parameter)",
    ),
    (
        "evaluation.overlap_distance_m",
        "now fixed at 0.5 m (`EvaluationConfig::overlap_distance_m`, a library parameter)",
    ),
];

/// The first key of the TOML `text`, in [`REMOVED_KEYS`] order, that
/// config files no longer take, as an error naming its path and what
/// replaces it. Text that is not TOML passes (the reader that follows
/// reports the syntax error with its position).
pub fn check_removed_keys(text: &str) -> Result<(), ConfigFileError> {
    let Ok(table) = text.parse::<toml::Table>() else {
        return Ok(());
    };
    for (path, replacement) in REMOVED_KEYS {
        if lookup(&table, path) {
            return Err(ConfigFileError {
                path: (*path).to_string(),
                message: format!("no longer a config key (issue 36): {replacement}"),
            });
        }
    }
    Ok(())
}

/// `path` (`loops.gate.n_sigma`) names a key or table of `table`.
fn lookup(table: &toml::Table, path: &str) -> bool {
    let mut current = table;
    let mut parts = path.split('.').peekable();
    while let Some(part) = parts.next() {
        match (current.get(part), parts.peek()) {
            (Some(_), None) => return true,
            (Some(toml::Value::Table(inner)), Some(_)) => current = inner,
            _ => return false,
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_removed_key_is_named_with_what_replaces_it() {
        let e = check_removed_keys("[loops]\nmin_window = [1, 1, 0.1]\n").unwrap_err();
        assert_eq!(e.path, "loops.min_window");
        assert!(e.message.contains("`loops.gate.min_window`"), "{e}");
        let e = check_removed_keys("[backend.outliers]\nmin_support = 2\n").unwrap_err();
        assert_eq!(e.path, "backend.outliers.min_support");
        assert!(e.message.contains("fixed at 3"), "{e}");
        // The old table form of a moved window is caught as well.
        let old = "[sequential.min_window]\nx_m = 0.4\n";
        assert_eq!(
            check_removed_keys(old).unwrap_err().path,
            "sequential.min_window"
        );
    }

    #[test]
    fn current_keys_and_bad_toml_pass() {
        assert!(check_removed_keys("[loops.gate]\nmin_window = [1, 1, 0.1]\n").is_ok());
        assert!(check_removed_keys("[image]\nbackground_quantile = 0.4\n").is_ok());
        assert!(check_removed_keys("[loops").is_ok());
    }
}
