//! Malformed pose-graph files give an error naming file, line and field, and
//! never a panic.

use echofield_graph::io::{IoError, parse_pose_graph, read_pose_graph};
use proptest::prelude::*;
use std::path::Path;

const GOOD: &str = "\
VERTEX_SE2 0 0 0 0
VERTEX_SE2 1 1 0 0.1
VERTEX_SE2 2 2 0 0.2
EDGE_SE2 0 1 1 0 0.1 100 0 0 100 0 1000
EDGE_SE2 1 2 1 0 0.1 100 0 0 100 0 1000
";

/// Parses `text` as file `bad.g2o` and returns the error message, checking
/// it names the file and the expected line and field.
fn error_for(text: &str, line: usize, field: &str) -> String {
    let err = parse_pose_graph(text, Path::new("bad.g2o")).expect_err("must be rejected");
    let message = err.to_string();
    assert!(message.contains("bad.g2o"), "no file name in `{message}`");
    assert_eq!(err.line(), Some(line), "wrong line in `{message}`");
    assert!(
        message.contains(field),
        "field `{field}` missing in `{message}`"
    );
    message
}

#[test]
fn good_file_parses() {
    let graph = parse_pose_graph(GOOD, Path::new("good.g2o")).unwrap();
    assert_eq!((graph.node_count(), graph.edge_count()), (3, 2));
}

#[test]
fn wrong_token_count() {
    let text = GOOD.replace("VERTEX_SE2 1 1 0 0.1", "VERTEX_SE2 1 1 0 0.1 7");
    error_for(&text, 2, "found 5");
    let text = GOOD.replace(
        "EDGE_SE2 0 1 1 0 0.1 100 0 0 100 0 1000",
        "EDGE_SE2 0 1 1 0 0.1 100 0 0 100 0",
    );
    error_for(&text, 4, "I33");
}

#[test]
fn non_numeric_value() {
    let text = GOOD.replace("VERTEX_SE2 2 2 0 0.2", "VERTEX_SE2 2 2 zero 0.2");
    let message = error_for(&text, 3, "`y`");
    assert!(message.contains("not a number"), "{message}");
    let text = GOOD.replace("VERTEX_SE2 2 2", "VERTEX_SE2 -2 2");
    error_for(&text, 3, "`id`");
}

#[test]
fn nan_and_infinite_values() {
    let text = GOOD.replace("EDGE_SE2 1 2 1 0 0.1", "EDGE_SE2 1 2 1 NaN 0.1");
    let message = error_for(&text, 5, "`dy`");
    assert!(message.contains("not finite"), "{message}");
    let text = GOOD.replace("0 1000\nEDGE_SE2 1 2", "0 inf\nEDGE_SE2 1 2");
    error_for(&text, 4, "`I33`");
}

#[test]
fn unknown_tag() {
    let text = GOOD.replace("VERTEX_SE2 1 1 0 0.1", "VERTEX_SE3:QUAT 1 1 0 0.1");
    error_for(&text, 2, "VERTEX_SE3:QUAT");
    // An unknown first record names it too.
    error_for("HELLO 1 2 3\n", 1, "HELLO");
}

#[test]
fn edge_to_missing_vertex() {
    let text = GOOD.replace("EDGE_SE2 1 2", "EDGE_SE2 1 9");
    let message = error_for(&text, 5, "missing node 9");
    assert!(message.contains("1 -> 9"), "{message}");
}

#[test]
fn duplicate_vertex() {
    let text = GOOD.replace("VERTEX_SE2 2 2 0 0.2", "VERTEX_SE2 1 2 0 0.2");
    error_for(&text, 3, "duplicate node id 1");
}

#[test]
fn information_not_positive_definite() {
    let text = GOOD.replace(
        "100 0 0 100 0 1000\nEDGE_SE2 1 2",
        "100 0 0 -100 0 1000\nEDGE_SE2 1 2",
    );
    error_for(&text, 4, "positive definite");
    let text = GOOD.replace(
        "100 0 0 100 0 1000\nEDGE_SE2 1 2",
        "1 5 0 1 0 1\nEDGE_SE2 1 2",
    );
    error_for(&text, 4, "positive definite");
}

#[test]
fn empty_file() {
    for text in ["", "\n\n", "# only a comment\n"] {
        let err = parse_pose_graph(text, Path::new("empty.g2o")).unwrap_err();
        assert!(matches!(err, IoError::Empty { .. }), "{err}");
        assert!(err.to_string().contains("empty.g2o"));
    }
}

#[test]
fn truncated_last_line() {
    let text = &GOOD[..GOOD.len() - 12];
    let message = error_for(text, 5, "truncated");
    assert!(message.contains("EDGE_SE2"), "{message}");
}

#[test]
fn missing_file_names_the_path() {
    let err = read_pose_graph(Path::new("/nonexistent/graph.g2o")).unwrap_err();
    assert!(err.to_string().contains("/nonexistent/graph.g2o"), "{err}");
}

#[test]
fn toro_errors_name_line_and_field() {
    let text = "VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0\nEDGE2 0 1 1 0 0 10 1 20 30 2\n";
    let err = parse_pose_graph(text, Path::new("bad.graph")).unwrap_err();
    assert_eq!(err.line(), Some(3));
    assert!(err.to_string().contains("Iyt"), "{err}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// Any prefix of a valid file, and any single-byte corruption of it,
    /// parses or fails cleanly.
    #[test]
    fn prefixes_and_corruptions_never_panic(cut in 0usize..GOOD.len(), at in 0usize..GOOD.len(), byte in any::<u8>()) {
        let _ = parse_pose_graph(&GOOD[..cut], Path::new("p.g2o"));
        let mut bytes = GOOD.as_bytes().to_vec();
        bytes[at] = byte;
        if let Ok(text) = std::str::from_utf8(&bytes) {
            let _ = parse_pose_graph(text, Path::new("p.g2o"));
        }
    }
}

// Issue 35: the text-input findings of the bad-input audit, each with its
// minimal input.

#[test]
fn invalid_utf8_names_file_line_and_byte_offset() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("latin1.g2o");
    // Line 2 holds a Latin-1 `é` (0xE9) where the id should be.
    let mut bytes = b"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 ".to_vec();
    bytes.push(0xE9);
    bytes.extend_from_slice(b" 1 0 0\n");
    std::fs::write(&path, bytes).unwrap();
    let err = read_pose_graph(&path).unwrap_err();
    let message = err.to_string();
    assert_eq!(err.line(), Some(2), "{message}");
    assert!(
        message.contains("latin1.g2o:2")
            && message.contains("UTF-8")
            && message.contains("byte 30")
            && message.contains("column 12"),
        "{message}"
    );
}

#[test]
fn a_leading_byte_order_mark_is_skipped() {
    let text = format!("\u{feff}{GOOD}");
    let graph = parse_pose_graph(&text, Path::new("bom.g2o")).unwrap();
    assert_eq!((graph.node_count(), graph.edge_count()), (3, 2));
    let toro = "\u{feff}VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0\nEDGE2 0 1 1 0 0 10 1 20 30 2 3\n";
    assert_eq!(
        parse_pose_graph(toro, Path::new("bom.graph"))
            .unwrap()
            .edge_count(),
        1
    );
}

#[test]
fn a_last_number_cut_off_is_an_error_naming_line_and_field() {
    // The file was cut inside its last number: `1000` became `10`, and the
    // line end is gone. Every field is there, so only the missing line end
    // tells.
    let cut = GOOD.trim_end().strip_suffix("00").unwrap();
    let message = error_for(cut, 5, "`I33`");
    assert!(message.contains("cut off"), "{message}");
    // A FIX line cut the same way.
    let fix = format!("{GOOD}FIX 1");
    let message = error_for(&fix, 6, "`id`");
    assert!(message.contains("cut off"), "{message}");
    // The same file with its line end is fine.
    assert!(parse_pose_graph(&format!("{cut}\n"), Path::new("ok.g2o")).is_ok());
}

#[test]
fn absurd_values_are_errors_naming_the_field() {
    let text = GOOD.replace("VERTEX_SE2 1 1 0 0.1", "VERTEX_SE2 1 1e308 0 0.1");
    let message = error_for(&text, 2, "`x`");
    assert!(message.contains("out of range"), "{message}");
    let text = GOOD.replace("VERTEX_SE2 2 2 0 0.2", "VERTEX_SE2 2 2 0 1e300");
    error_for(&text, 3, "`theta`");
    let text = GOOD.replace("0 1000\nEDGE_SE2 1 2", "0 1e300\nEDGE_SE2 1 2");
    error_for(&text, 4, "`I33`");
}

#[test]
fn graph_errors_print_their_message_once() {
    let text = GOOD.replace("VERTEX_SE2 2 2 0 0.2", "VERTEX_SE2 1 2 0 0.2");
    let err = parse_pose_graph(&text, Path::new("dup.g2o")).unwrap_err();
    // The whole chain, as the CLI prints it with `{:#}`.
    let mut chain = err.to_string();
    let mut source = std::error::Error::source(&err);
    while let Some(s) = source {
        chain.push_str(&format!(": {s}"));
        source = s.source();
    }
    assert_eq!(chain.matches("duplicate node id 1").count(), 1, "{chain}");
    assert!(chain.starts_with("dup.g2o:3:"), "{chain}");
}
