//! Configuration files laid over the built-in defaults.
//!
//! Deserialising a TOML file straight into a config struct fills each
//! missing key from the `Default` of the struct that holds it. That is
//! wrong wherever a section's default is not its type's default:
//! `[image.off_axis]` has margin 25 and `[segmentation.off_axis]` 15
//! (their type says 20), and `[backend.solver]` puts a Cauchy kernel on
//! loop edges (the solver's own default has none). A file that sets one key of such a section
//! silently reset its other keys to the type's values.
//!
//! [`from_toml_over`] instead serialises the defaults to a TOML table,
//! lays the file over it key by key and deserialises the result, so every
//! key the file leaves out keeps the value of the defaults given:
//! - a table in the file merges into the default's table of the same key,
//!   recursively;
//! - a table with a `kind` key is one variant of a tagged enum (the robust
//!   kernels: `kind = "dcs"` with `phi`); it replaces the default's table
//!   whole, whose fields belong to another variant;
//! - any other value (numbers, strings, arrays) replaces the default's.
//!
//! Unknown keys stay errors: they are carried into the merged table, and
//! every config struct denies unknown fields. Errors name the key by its
//! path (`loops.min_separaton_nodes`).

mod removed;

pub use removed::{REMOVED_KEYS, check_removed_keys};
use serde::Serialize;
use serde::de::DeserializeOwned;

/// A key of a tagged enum's table: its variant.
const ENUM_TAG: &str = "kind";

/// Why a config file could not be read, and where.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{path}: {message}")]
pub struct ConfigFileError {
    /// The TOML path of the offending key (`loops.gate.n_sigma`), or
    /// `(document)` for a syntax error.
    pub path: String,
    pub message: String,
}

/// Reads a config file as text: an I/O error names the file, invalid
/// UTF-8 names the file, line, column and byte offset
/// ([`echofield_graph::io::read_text`]), and a leading byte-order mark is
/// dropped.
pub fn read_config_text(path: &std::path::Path) -> Result<String, echofield_graph::io::IoError> {
    let text = echofield_graph::io::read_text(path)?;
    Ok(match text.strip_prefix('\u{feff}') {
        Some(rest) => rest.to_string(),
        None => text,
    })
}

/// `text` (TOML) laid over `defaults` (see the module doc).
pub fn from_toml_over<T: Serialize + DeserializeOwned>(
    text: &str,
    defaults: &T,
) -> Result<T, ConfigFileError> {
    let user: toml::Table = text.parse().map_err(|e: toml::de::Error| ConfigFileError {
        path: "(document)".into(),
        message: e.to_string().trim_end().to_string(),
    })?;
    let mut merged = toml::Table::try_from(defaults).map_err(|e| ConfigFileError {
        path: "(defaults)".into(),
        message: e.to_string(),
    })?;
    lay_over(&mut merged, user);
    serde_path_to_error::deserialize(toml::Value::Table(merged)).map_err(|e| {
        let path = e.path().to_string();
        let message = e.into_inner().to_string();
        // toml ends some messages with a line naming the key again
        // (`in `loops.gate.min_window``); the path is already given, once.
        let message = message.trim_end();
        let message = match message.rsplit_once('\n') {
            Some((head, tail)) if tail.trim_start().starts_with("in `") => head.trim_end(),
            _ => message,
        };
        ConfigFileError {
            path,
            message: message.to_string(),
        }
    })
}

/// Lays `user` over `base` in place (see the module doc).
fn lay_over(base: &mut toml::Table, user: toml::Table) {
    for (key, value) in user {
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(below)), toml::Value::Table(above))
                if !above.contains_key(ENUM_TAG) =>
            {
                lay_over(below, above);
            }
            (_, value) => {
                base.insert(key, value);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    #[serde(default, deny_unknown_fields)]
    struct Inner {
        a: f64,
        b: f64,
    }

    impl Default for Inner {
        fn default() -> Self {
            Self { a: 1.0, b: 2.0 }
        }
    }

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    #[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
    enum Kernel {
        Huber { delta: f64 },
        Dcs { phi: f64 },
    }

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    #[serde(default, deny_unknown_fields)]
    struct Outer {
        name: String,
        list: Vec<u32>,
        inner: Inner,
        kernel: Kernel,
    }

    impl Default for Outer {
        fn default() -> Self {
            Self {
                name: "x".into(),
                list: vec![1, 2],
                inner: Inner::default(),
                kernel: Kernel::Huber { delta: 3.0 },
            }
        }
    }

    /// Defaults that differ from the types' own, as the pipeline's do.
    fn defaults() -> Outer {
        Outer {
            name: "pipeline".into(),
            list: vec![7, 8, 9],
            inner: Inner { a: 10.0, b: 20.0 },
            kernel: Kernel::Huber { delta: 1.5 },
        }
    }

    #[test]
    fn keys_left_out_keep_the_given_defaults_not_the_types() {
        let c: Outer = from_toml_over("[inner]\nb = 5.0\n", &defaults()).unwrap();
        assert_eq!(c.inner, Inner { a: 10.0, b: 5.0 });
        assert_eq!(c.name, "pipeline");
        assert_eq!(c.list, vec![7, 8, 9]);
        // Plain serde, for contrast, takes the type's default for `a`.
        let plain: Outer = toml::from_str("[inner]\nb = 5.0\n").unwrap();
        assert_eq!(plain.inner, Inner { a: 1.0, b: 5.0 });
    }

    #[test]
    fn config_text_drops_a_bom_and_names_invalid_utf8() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.toml");
        std::fs::write(&path, b"\xEF\xBB\xBF[inner]\nb = 5.0\n").unwrap();
        let text = read_config_text(&path).unwrap();
        let c: Outer = from_toml_over(&text, &defaults()).unwrap();
        assert_eq!(c.inner.b, 5.0);
        std::fs::write(&path, b"[inner]\nb = \"\xC3\"\n").unwrap();
        let message = read_config_text(&path).unwrap_err().to_string();
        assert!(
            message.contains("c.toml:2") && message.contains("byte 13"),
            "{message}"
        );
    }

    #[test]
    fn an_empty_file_gives_the_defaults() {
        assert_eq!(from_toml_over("", &defaults()).unwrap(), defaults());
    }

    #[test]
    fn arrays_and_strings_replace() {
        let c: Outer = from_toml_over("name = \"y\"\nlist = [3]\n", &defaults()).unwrap();
        assert_eq!((c.name.as_str(), c.list), ("y", vec![3]));
    }

    #[test]
    fn a_tagged_variant_replaces_the_default_variant_whole() {
        let c: Outer =
            from_toml_over("[kernel]\nkind = \"dcs\"\nphi = 1.0\n", &defaults()).unwrap();
        assert_eq!(c.kernel, Kernel::Dcs { phi: 1.0 });
        // The same variant must be given whole too: no field is merged in.
        let err = from_toml_over::<Outer>("[kernel]\nkind = \"huber\"\n", &defaults()).unwrap_err();
        assert_eq!(err.path, "kernel");
        assert!(err.message.contains("delta"), "{err}");
    }

    #[test]
    fn unknown_keys_and_bad_values_name_their_path() {
        let err = from_toml_over::<Outer>("[inner]\nc = 1.0\n", &defaults()).unwrap_err();
        assert_eq!(err.path, "inner.c");
        let err = from_toml_over::<Outer>("[inner]\na = \"no\"\n", &defaults()).unwrap_err();
        assert_eq!(err.path, "inner.a");
        // The key is named once, by the path, not again in the message.
        assert!(!err.message.contains("inner.a"), "{err}");
        let err = from_toml_over::<Outer>("[inner\n", &defaults()).unwrap_err();
        assert_eq!(err.path, "(document)");
        assert!(err.message.contains("line 1"), "{err}");
    }
}
