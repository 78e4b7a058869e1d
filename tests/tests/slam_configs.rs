//! The pipeline's configuration files: every shipped config parses and
//! validates, `default.toml` is exactly the built-in default, the effective
//! config written beside the outputs reads back to the same config, and
//! unknown keys or bad values are errors naming them.

use echofield::slam::{SlamConfig, SlamError};
use echofield_backend::RobustKernel;
use std::path::PathBuf;

fn configs_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("tools")
        .join("configs")
}

#[test]
fn every_shipped_config_parses() {
    let mut count = 0;
    for entry in std::fs::read_dir(configs_dir()).unwrap() {
        let path = entry.unwrap().path();
        // `localize.toml` is the `[localize]` section of `echofield
        // localize`, not a SLAM config: its own tests (tools/src/localize.rs)
        // check it against its defaults.
        if path.file_name().is_some_and(|n| n == "localize.toml") {
            continue;
        }
        if path.extension().is_some_and(|e| e == "toml") {
            SlamConfig::from_toml_file(&path)
                .unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
            count += 1;
        }
    }
    assert!(count >= 2, "{count} configs");
}

/// One default per key: the pipeline's matcher is the matcher type's own
/// default, so the library's default path is the one the pipeline runs.
#[test]
fn the_pipelines_matcher_is_the_matchers_default() {
    assert_eq!(
        SlamConfig::default().matcher,
        echofield_frontend::matcher::MatcherConfig::default()
    );
}

#[test]
fn default_toml_is_the_built_in_default() {
    let config = SlamConfig::from_toml_file(&configs_dir().join("default.toml")).unwrap();
    assert_eq!(config, SlamConfig::default());
}

#[test]
fn the_effective_config_reads_back() {
    let config = SlamConfig::from_toml_str(
        "[loops]\nmax_candidates_per_node = 7\n[backend.solver.robust.loop]\nkind = \"dcs\"\nphi = 2.0\n",
    )
    .unwrap();
    assert_eq!(config.loops.max_candidates_per_node, 7);
    let again = SlamConfig::from_toml_str(&config.to_toml_string()).unwrap();
    assert_eq!(again, config);
}

#[test]
fn unknown_keys_are_errors_naming_their_path() {
    for (text, path) in [
        (
            "[loops]\nmin_separaton_nodes = 3\n",
            "loops.min_separaton_nodes",
        ),
        (
            "[backend.solver]\niterations = 3\n",
            "backend.solver.iterations",
        ),
        ("[image]\ncell_size = 0.1\n", "image.cell_size"),
        ("[matcher]\nmax_points = 100\nfoo = 1\n", "matcher.foo"),
        (
            "[loops.gate]\nmin_windw = [1.0, 1.0, 0.1]\n",
            "loops.gate.min_windw",
        ),
        ("colour = \"red\"\n", "colour"),
    ] {
        let err = SlamConfig::from_toml_str(text).unwrap_err();
        let message = err.to_string();
        assert!(message.contains(path), "{text:?}: {message}");
        let key = path.rsplit('.').next().unwrap();
        assert!(message.contains(key), "{text:?}: {message}");
    }
}

#[test]
fn bad_values_are_errors_naming_the_field() {
    for (text, field) in [
        (
            "[loops]\nmin_separation_nodes = 1\n",
            "loops.min_separation_nodes",
        ),
        (
            "[sequential.gate]\nn_sigma = -1.0\n",
            "sequential.gate.n_sigma",
        ),
        ("[image]\ncell_size_m = 0.0\n", "image.cell_size_m"),
        ("[backend.solver]\nthreads = 0\n", "backend.solver.threads"),
        (
            "[evaluation]\nrpe_distances_m = [10.0, -5.0]\n",
            "evaluation.rpe_distances_m[1]",
        ),
        (
            "[loops]\nmin_separation_nodes = \"ten\"\n",
            "loops.min_separation_nodes",
        ),
    ] {
        let err = SlamConfig::from_toml_str(text).unwrap_err();
        assert!(matches!(err, SlamError::Config { .. }), "{err}");
        assert!(err.to_string().contains(field), "{text:?}: {err}");
    }
}

/// A file that sets some keys of a section leaves the others at the
/// pipeline's defaults, also where those differ from the defaults of the
/// section's type (the two off-axis margins, the loop edges' robust
/// kernel): each file below gives
/// the default config with exactly one value changed.
#[test]
fn partly_set_sections_keep_the_pipelines_other_defaults() {
    let defaults = SlamConfig::default();
    let changed = |edit: &dyn Fn(&mut SlamConfig)| {
        let mut c = SlamConfig::default();
        edit(&mut c);
        c
    };
    let cases: Vec<(&str, SlamConfig)> = vec![
        (
            "[matcher]\nmax_points = 400\n",
            changed(&|c| c.matcher.max_points = 400),
        ),
        (
            "[image.off_axis]\nenabled = false\n",
            changed(&|c| c.image.off_axis.enabled = false),
        ),
        (
            "[segmentation.off_axis]\nenabled = false\n",
            changed(&|c| c.segmentation.off_axis.enabled = false),
        ),
        (
            "[backend.solver]\nmax_iterations = 7\n",
            changed(&|c| c.backend.solver.max_iterations = 7),
        ),
        (
            "[backend.solver.robust.odometry]\nkind = \"huber\"\ndelta = 1.0\n",
            changed(&|c| c.backend.solver.robust.odometry = RobustKernel::Huber { delta: 1.0 }),
        ),
    ];
    for (text, expected) in cases {
        let parsed = SlamConfig::from_toml_str(text).unwrap_or_else(|e| panic!("{text:?}: {e}"));
        assert_ne!(expected, defaults, "{text:?} changes nothing");
        assert_eq!(parsed, expected, "{text:?}");
    }
    // The pipeline's defaults these cases rely on differ from the types'.
    assert_ne!(
        defaults.image.off_axis.margin,
        defaults.segmentation.off_axis.margin
    );
    assert_ne!(
        defaults.backend.solver.robust.loop_closure,
        RobustKernel::None
    );
}
