//! Issue 35: every numeric key of `run`'s configuration, set in turn to 0,
//! -1, 1e9 and (for floats) NaN and ±infinity, either gives a clean
//! validation error that names the key or completes a short run on a tiny
//! simulated mission: never a panic, never a run far longer than the
//! default's.
//!
//! The keys come from `tools/configs/default.toml` (every key with a
//! default) plus the optional keys whose default is "none" (listed in that
//! file's header). Each run happens on its own thread so that a panic is
//! reported with the key that caused it, and a hang with the key and the
//! time it had taken when the test gave up.

use echofield::slam::{NoProgress, SlamConfig, run_mission};
use echofield_datasets::sim::{Scenario, simulate_mission};
use echofield_frontend::Mission;
use std::path::PathBuf;
use std::sync::{Arc, OnceLock, mpsc};
use std::time::{Duration, Instant};

/// The first 80 s of the simulated tank (seed 3): six rotations, enough for
/// sequential matches, loop candidates (with the baseline below) and the
/// final solve.
fn mission() -> Arc<Mission> {
    static MISSION: OnceLock<Arc<Mission>> = OnceLock::new();
    MISSION
        .get_or_init(|| {
            let mut m = simulate_mission(&Scenario::named("tank").unwrap(), 3).unwrap();
            let end_s = m.beams[0].stamp_s + 80.0;
            m.beams.retain(|b| b.stamp_s < end_s);
            m.dvl.retain(|d| d.stamp_s < end_s + 5.0);
            m.attitude.retain(|a| a.stamp_s < end_s + 5.0);
            m.ground_truth.retain(|g| g.stamp_s < end_s + 5.0);
            Arc::new(m)
        })
        .clone()
}

/// Laid under every fuzzed key: loop candidates between nodes two apart, so
/// that the loop stages run on six rotations.
const BASELINE: &[(&str, &str)] = &[("loops.min_separation_nodes", "2")];

/// Keys whose default is "none", so that default.toml does not list them.
const OPTIONAL_FLOAT_KEYS: &[&str] = &[
    "rotation.beam_period_s",
    "segmentation.max_range_m",
    "image.cell_size_m",
    "image.max_range_m",
    "matcher.angle_step_rad",
    "backend.heading_prior_sigma_rad",
    "mounting.sonar_x_m",
    "mounting.sonar_y_m",
    "mounting.sonar_yaw_deg",
    "mounting.dvl_x_m",
    "mounting.dvl_y_m",
    "mounting.dvl_yaw_deg",
    "mounting.heading_offset_deg",
];

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Integer,
    Float,
}

/// A numeric key: its dotted path and, for an array, the element.
#[derive(Clone, Debug)]
struct Key {
    path: String,
    index: Option<usize>,
    kind: Kind,
}

fn default_toml() -> toml::Table {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tools/configs/default.toml");
    std::fs::read_to_string(path).unwrap().parse().unwrap()
}

fn collect(table: &toml::Table, prefix: &str, out: &mut Vec<Key>) {
    for (name, value) in table {
        let path = if prefix.is_empty() {
            name.clone()
        } else {
            format!("{prefix}.{name}")
        };
        let kind = |v: &toml::Value| match v {
            toml::Value::Integer(_) => Some(Kind::Integer),
            toml::Value::Float(_) => Some(Kind::Float),
            _ => None,
        };
        match value {
            toml::Value::Table(t) => collect(t, &path, out),
            toml::Value::Array(items) => {
                for (i, item) in items.iter().enumerate() {
                    if let Some(kind) = kind(item) {
                        out.push(Key {
                            path: path.clone(),
                            index: Some(i),
                            kind,
                        });
                    }
                }
            }
            v => {
                if let Some(kind) = kind(v) {
                    out.push(Key {
                        path,
                        index: None,
                        kind,
                    });
                }
            }
        }
    }
}

fn numeric_keys() -> Vec<Key> {
    let mut keys = Vec::new();
    collect(&default_toml(), "", &mut keys);
    keys.extend(OPTIONAL_FLOAT_KEYS.iter().map(|p| Key {
        path: p.to_string(),
        index: None,
        kind: Kind::Float,
    }));
    keys
}

/// The config text that sets `key` to `value` over [`BASELINE`].
fn config_text(key: &Key, value: toml::Value) -> String {
    let mut table = toml::Table::new();
    let mut set = |path: &str, value: toml::Value| {
        let parts: Vec<&str> = path.split('.').collect();
        let mut t = &mut table;
        for part in &parts[..parts.len() - 1] {
            t = t
                .entry(part.to_string())
                .or_insert_with(|| toml::Value::Table(toml::Table::new()))
                .as_table_mut()
                .unwrap();
        }
        t.insert(parts[parts.len() - 1].to_string(), value);
    };
    for (path, v) in BASELINE {
        if *path != key.path {
            set(
                path,
                v.parse::<toml::Value>()
                    .unwrap_or_else(|_| toml::Value::Integer(v.parse().unwrap())),
            );
        }
    }
    let value = match key.index {
        Some(i) => {
            let mut items = lookup(&default_toml(), &key.path)
                .as_array()
                .unwrap()
                .clone();
            items[i] = value;
            toml::Value::Array(items)
        }
        None => value,
    };
    set(&key.path, value);
    toml::to_string(&table).unwrap()
}

fn lookup<'a>(table: &'a toml::Table, path: &str) -> &'a toml::Value {
    let mut parts = path.split('.');
    let mut value = &table[parts.next().unwrap()];
    for part in parts {
        value = &value[part];
    }
    value
}

fn values(kind: Kind) -> Vec<(&'static str, toml::Value)> {
    match kind {
        Kind::Integer => vec![
            ("0", toml::Value::Integer(0)),
            ("-1", toml::Value::Integer(-1)),
            ("1e9", toml::Value::Integer(1_000_000_000)),
        ],
        Kind::Float => vec![
            ("0", toml::Value::Float(0.0)),
            ("-1", toml::Value::Float(-1.0)),
            ("1e9", toml::Value::Float(1e9)),
            ("nan", toml::Value::Float(f64::NAN)),
            ("inf", toml::Value::Float(f64::INFINITY)),
            ("-inf", toml::Value::Float(f64::NEG_INFINITY)),
        ],
    }
}

enum Outcome {
    Rejected(String),
    Ran(Duration),
    Failed(String),
    Panicked,
    TimedOut,
}

/// Parses and runs `text` on its own thread, waiting at most `limit`.
fn attempt(text: String, limit: Duration) -> Outcome {
    let config = match SlamConfig::from_toml_str(&text) {
        Ok(c) => c,
        Err(e) => return Outcome::Rejected(e.to_string()),
    };
    let (tx, rx) = mpsc::channel();
    let mission = mission();
    std::thread::spawn(move || {
        let t = Instant::now();
        let result = run_mission(&mission, &config, &NoProgress);
        let _ = tx.send((t.elapsed(), result.map(|_| ()).map_err(|e| e.to_string())));
    });
    match rx.recv_timeout(limit) {
        Ok((elapsed, Ok(()))) => Outcome::Ran(elapsed),
        Ok((_, Err(e))) => Outcome::Failed(e),
        Err(mpsc::RecvTimeoutError::Disconnected) => Outcome::Panicked,
        Err(mpsc::RecvTimeoutError::Timeout) => Outcome::TimedOut,
    }
}

#[test]
fn every_numeric_key_at_0_minus_1_1e9_nan_inf_is_an_error_or_a_short_run() {
    let baseline_text = config_text(
        &Key {
            path: "loops.min_separation_nodes".into(),
            index: None,
            kind: Kind::Integer,
        },
        toml::Value::Integer(2),
    );
    let t = Instant::now();
    let Outcome::Ran(_) = attempt(baseline_text, Duration::from_secs(600)) else {
        panic!("the baseline run failed");
    };
    let baseline = t.elapsed();
    // Shared machines are noisy: twenty times the baseline, at least 5 s.
    let limit = (baseline * 20).max(Duration::from_secs(5));
    let keys = numeric_keys();
    // A guard that the enumeration found the keys (78 numeric values since
    // issue 36 cut the config to about 70 keys, window elements counted
    // one by one).
    assert!(keys.len() > 70, "{} numeric keys", keys.len());
    let (mut problems, mut rejected, mut ran, mut failed) = (Vec::new(), 0, 0, 0);
    for key in &keys {
        for (label, value) in values(key.kind) {
            let name = match key.index {
                Some(i) => format!("{}[{i}]", key.path),
                None => key.path.clone(),
            };
            match attempt(config_text(key, value), limit) {
                Outcome::Rejected(message) => {
                    rejected += 1;
                    // The full path, or for a check against another key
                    // of the section (`max_points must be >= min_points`)
                    // the section's path and the key.
                    let (section, leaf) = key.path.rsplit_once('.').unwrap_or(("", &key.path));
                    let named = message.contains(&key.path)
                        || (message.contains(&format!("{section}.")) && message.contains(leaf));
                    if !named {
                        problems.push(format!(
                            "{name} = {label}: error does not name it: {message}"
                        ));
                    }
                }
                Outcome::Ran(elapsed) => {
                    ran += 1;
                    eprintln!("{name} = {label}: ran in {elapsed:?}");
                }
                // An input the pipeline cannot use under this config (no
                // scans, no nodes) is a clean error too; it must say so.
                Outcome::Failed(message) => {
                    failed += 1;
                    eprintln!("{name} = {label}: run error: {message}");
                }
                Outcome::Panicked => {
                    eprintln!("{name} = {label}: PANIC");
                    problems.push(format!("{name} = {label}: PANIC"));
                }
                // A run that hangs holds the shared thread pool, and every
                // later run would wait for it: stop here.
                Outcome::TimedOut => {
                    problems.push(format!("{name} = {label}: still running after {limit:?}"));
                    panic!("{}", problems.join("\n"));
                }
            }
        }
    }
    eprintln!(
        "{} keys: {rejected} rejected, {ran} ran, {failed} failed cleanly; baseline {baseline:?}",
        keys.len()
    );
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}
