//! The documented default configuration that `echofield config` prints.
//!
//! [`DOCUMENTED_DEFAULTS`] is `tools/configs/default.toml`: every key of
//! [`SlamConfig::default`](crate::slam::SlamConfig::default) with its
//! value, each key and each table header preceded by its documentation as
//! `#` comments (the first paragraph of the field's doc comment). The tests
//! below hold the file to that: its keys and values are exactly those of
//! the built-in default, and no key or header goes undocumented. The
//! documentation lives in the file rather than being read from the doc
//! comments at run time because Rust keeps no doc comments in a binary.
//!
//! [`section`] cuts one table (with its sub-tables) out of the text, so
//! `echofield config --section loops > loops.toml` is a file that
//! `echofield run --config` accepts as it is.

/// `tools/configs/default.toml`: the default configuration, documented.
pub const DOCUMENTED_DEFAULTS: &str = include_str!("../configs/default.toml");

/// A `--section` that names no table of the configuration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("no config section `{name}`; the sections are: {}", known.join(", "))]
pub struct UnknownSection {
    pub name: String,
    /// The top-level sections of the text, in file order.
    pub known: Vec<String>,
}

/// One table of the text: its name (`loops.gate`) and its lines,
/// from the comment block just above the header to the line before the
/// next table's comment block.
struct Table<'a> {
    name: &'a str,
    lines: Vec<&'a str>,
}

/// The text before the first table (the file's own header comment), and
/// the tables in order.
fn split(text: &str) -> (Vec<&str>, Vec<Table<'_>>) {
    let mut preamble: Vec<&str> = Vec::new();
    let mut tables: Vec<Table> = Vec::new();
    // Comment lines seen since the last blank line: they belong to the
    // next header if one follows directly.
    let mut pending: Vec<&str> = Vec::new();
    for line in text.lines() {
        let trimmed = line.trim();
        if let Some(name) = header(trimmed) {
            tables.push(Table {
                name,
                lines: std::mem::take(&mut pending),
            });
            if let Some(table) = tables.last_mut() {
                table.lines.push(line);
            }
            continue;
        }
        let target = match tables.last_mut() {
            Some(table) => &mut table.lines,
            None => &mut preamble,
        };
        if trimmed.is_empty() {
            target.append(&mut pending);
            target.push(line);
        } else if trimmed.starts_with('#') {
            pending.push(line);
        } else {
            target.append(&mut pending);
            target.push(line);
        }
    }
    match tables.last_mut() {
        Some(table) => table.lines.append(&mut pending),
        None => preamble.append(&mut pending),
    }
    (preamble, tables)
}

/// The name of a table header line (`[loops.gate]`), if it is one.
fn header(line: &str) -> Option<&str> {
    let name = line.strip_prefix('[')?.strip_suffix(']')?;
    (!name.starts_with('[') && !name.is_empty()).then_some(name.trim())
}

/// The top-level sections of `text` (`dead_reckoning`, `loops`, ...), in
/// file order.
pub fn section_names(text: &str) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for table in split(text).1 {
        let top = table.name.split('.').next().unwrap_or(table.name);
        if !names.iter().any(|n| n == top) {
            names.push(top.to_string());
        }
    }
    names
}

/// The table `name` of `text` and its sub-tables (`loops` gives `[loops]`
/// and `[loops.gate]` ...; `loops.gate` only that one), each
/// with its documentation. Errors: no table has that name or lies under it.
pub fn section(text: &str, name: &str) -> Result<String, UnknownSection> {
    let name = name.trim().trim_start_matches('[').trim_end_matches(']');
    let prefix = format!("{name}.");
    let mut out = String::new();
    for table in split(text).1 {
        if table.name == name || table.name.starts_with(&prefix) {
            for line in &table.lines {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    if out.is_empty() {
        return Err(UnknownSection {
            name: name.to_string(),
            known: section_names(text),
        });
    }
    Ok(out.trim_end().to_string() + "\n")
}

/// The full path of every key of the TOML `text` (`loops.gate.min_window`),
/// each table's keys in alphabetical order; an array is one key. Errors:
/// `text` is not TOML.
pub fn key_paths(text: &str) -> Result<Vec<String>, toml::de::Error> {
    fn walk(table: &toml::Table, prefix: &str, out: &mut Vec<String>) {
        for (key, value) in table {
            let path = format!("{prefix}{key}");
            match value {
                toml::Value::Table(inner) => walk(inner, &format!("{path}."), out),
                _ => out.push(path),
            }
        }
    }
    let table: toml::Table = text.parse()?;
    let mut out = Vec::new();
    walk(&table, "", &mut out);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::slam::SlamConfig;

    /// The key of a `key = value` line, if it is one.
    fn key_of(line: &str) -> Option<&str> {
        let (key, _) = line.split_once(" = ")?;
        let key = key.trim();
        key.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_')
            .then_some(key)
    }

    #[test]
    fn the_documented_defaults_are_exactly_the_built_in_defaults() {
        // Compared as TOML tables, not through the parser that lays a file
        // over the defaults (which would fill in a key the file forgot).
        // The built-in side is the TOML a run writes as its effective
        // config, which leaves out keys without a value (`[mounting]`).
        let file: toml::Table = DOCUMENTED_DEFAULTS.parse().unwrap();
        let built_in: toml::Table = SlamConfig::default().to_toml_string().parse().unwrap();
        assert_eq!(file, built_in);
    }

    #[test]
    fn every_key_and_every_header_is_documented() {
        let lines: Vec<&str> = DOCUMENTED_DEFAULTS.lines().collect();
        let mut keys = 0;
        for (i, line) in lines.iter().enumerate() {
            let documented = i > 0 && lines[i - 1].trim_start().starts_with('#');
            if header(line.trim()).is_some() {
                assert!(documented, "line {}: header {line} has no comment", i + 1);
            } else if let Some(key) = key_of(line) {
                assert!(documented, "line {}: key `{key}` has no comment", i + 1);
                keys += 1;
            }
        }
        assert!(keys > 50, "{keys} keys");
    }

    #[test]
    fn every_section_is_a_config_file_of_the_defaults() {
        let names = section_names(DOCUMENTED_DEFAULTS);
        assert!(names.len() >= 10, "{names:?}");
        let mut all = String::new();
        for name in &names {
            let text = section(DOCUMENTED_DEFAULTS, name).unwrap();
            assert!(text.contains(&format!("[{name}]")), "{name}: {text}");
            let parsed = SlamConfig::from_toml_str(&text)
                .unwrap_or_else(|e| panic!("section {name}: {e}\n{text}"));
            assert_eq!(parsed, SlamConfig::default(), "section {name}");
            all.push_str(&text);
        }
        // Together the sections hold every key of the file.
        let all: toml::Table = all.parse().unwrap();
        let file: toml::Table = DOCUMENTED_DEFAULTS.parse().unwrap();
        assert_eq!(all, file);
    }

    #[test]
    fn a_sub_table_alone_and_a_section_with_its_sub_tables() {
        let pose_fit = section(DOCUMENTED_DEFAULTS, "image.pose_fit").unwrap();
        let table: toml::Table = pose_fit.parse().unwrap();
        let image = table["image"].as_table().unwrap();
        assert_eq!(image.keys().collect::<Vec<_>>(), ["pose_fit"]);
        assert!(pose_fit.starts_with('#'), "{pose_fit}");

        let image = section(DOCUMENTED_DEFAULTS, "[image]").unwrap();
        assert!(image.contains("[image.pose_fit]"), "{image}");
        assert!(image.contains("background_quantile = "), "{image}");
        assert!(!image.contains("[matcher"), "{image}");
    }

    #[test]
    fn an_unknown_section_names_itself_and_the_sections() {
        let err = section(DOCUMENTED_DEFAULTS, "loop").unwrap_err();
        let message = err.to_string();
        assert!(message.contains("`loop`"), "{message}");
        assert!(message.contains("loops, backend"), "{message}");
    }

    #[test]
    fn key_paths_are_full_paths_of_the_leaves() {
        let text = "[a]\nx = 1\n[a.w]\nx_m = 0.5\n[b]\nl = [1, 2]\n";
        assert_eq!(key_paths(text).unwrap(), ["a.w.x_m", "a.x", "b.l"]);
        let all = key_paths(DOCUMENTED_DEFAULTS).unwrap();
        assert!(all.iter().any(|k| k == "loops.gate.min_window"), "{all:?}");
        assert!(key_paths("[a").is_err());
    }

    #[test]
    fn no_removed_key_is_a_key_of_the_defaults_and_each_names_its_replacement() {
        let defaults = key_paths(DOCUMENTED_DEFAULTS).unwrap();
        for (path, replacement) in crate::config_file::REMOVED_KEYS {
            assert!(
                !defaults
                    .iter()
                    .any(|k| k == path || k.starts_with(&format!("{path}."))),
                "{path}"
            );
            let text = format!(
                "[{}]\n{} = 1\n",
                path.rsplit_once('.').unwrap().0,
                path.rsplit_once('.').unwrap().1
            );
            let message = format!("{:#}", SlamConfig::from_toml_str(&text).unwrap_err());
            assert!(message.contains(path), "{message}");
            assert!(message.contains(replacement), "{message}");
        }
    }

    #[test]
    fn at_most_seventy_keys_have_a_default() {
        let keys = key_paths(DOCUMENTED_DEFAULTS).unwrap();
        assert!(keys.len() <= 70, "{} keys: {keys:?}", keys.len());
    }

    #[test]
    fn comments_go_with_the_header_below_them() {
        let text = "# file\n\n[a]\n# key x\nx = 1\n\n# table b\n[b]\n# key y\ny = 2\n";
        assert_eq!(section(text, "a").unwrap(), "[a]\n# key x\nx = 1\n");
        assert_eq!(
            section(text, "b").unwrap(),
            "# table b\n[b]\n# key y\ny = 2\n"
        );
        assert_eq!(section_names(text), ["a", "b"]);
    }
}
