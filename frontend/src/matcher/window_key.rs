//! A window as one config key: `min_window = [x_m, y_m, theta_rad]`
//! (metres, metres, radians, in the reference node's frame), for
//! `#[serde(with = "window_key")]` on a [`SearchWindow`] field of a config
//! section. Reports and other outputs keep the named fields of
//! [`SearchWindow`]'s own serde form.
//!
//! Failure modes: an array of other than three numbers is an error naming
//! its length; the table form of earlier versions (`[loops.min_window]`
//! with `x_m`, `y_m`, `theta_rad`) is an error that says what replaces it.
//! Serde's visitors are written out here because the two forms must give
//! different messages, which no derive gives.

use super::SearchWindow;
use serde::de::{self, MapAccess, SeqAccess, Visitor};
use serde::{Deserializer, Serialize, Serializer};
use std::fmt;

/// What replaces the table form, for its error message.
pub const TABLE_FORM_REMOVED: &str = "a window is one key since issue 36: write \
     `[x_m, y_m, theta_rad]` (metres, metres, radians), e.g. `[0.5, 0.5, 0.05]`, \
     instead of a table with `x_m`, `y_m` and `theta_rad`";

pub fn serialize<S: Serializer>(window: &SearchWindow, serializer: S) -> Result<S::Ok, S::Error> {
    [window.x_m, window.y_m, window.theta_rad].serialize(serializer)
}

pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<SearchWindow, D::Error> {
    deserializer.deserialize_any(WindowVisitor)
}

struct WindowVisitor;

impl<'de> Visitor<'de> for WindowVisitor {
    type Value = SearchWindow;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a window `[x_m, y_m, theta_rad]` of three numbers")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<SearchWindow, A::Error> {
        let mut axes = [0.0; 3];
        for (i, axis) in axes.iter_mut().enumerate() {
            *axis = seq
                .next_element::<f64>()?
                .ok_or_else(|| de::Error::invalid_length(i, &self))?;
        }
        let mut len = 3;
        while seq.next_element::<de::IgnoredAny>()?.is_some() {
            len += 1;
        }
        if len != 3 {
            return Err(de::Error::invalid_length(len, &self));
        }
        Ok(SearchWindow::new(axes[0], axes[1], axes[2]))
    }

    fn visit_map<A: MapAccess<'de>>(self, _map: A) -> Result<SearchWindow, A::Error> {
        Err(de::Error::custom(TABLE_FORM_REMOVED))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct Section {
        #[serde(with = "super")]
        w: SearchWindow,
    }

    #[test]
    fn a_window_is_three_numbers_and_round_trips() {
        let s: Section = serde_json::from_str(r#"{"w": [0.5, 2, 0.05]}"#).unwrap();
        assert_eq!(s.w, SearchWindow::new(0.5, 2.0, 0.05));
        let text = serde_json::to_string(&s).unwrap();
        assert_eq!(text, r#"{"w":[0.5,2.0,0.05]}"#);
    }

    #[test]
    fn other_lengths_and_the_table_form_are_errors_saying_why() {
        for (text, expected) in [
            (r#"{"w": [0.5, 0.5]}"#, "invalid length 2"),
            (r#"{"w": [0.5, 0.5, 0.1, 1.0]}"#, "invalid length 4"),
            (
                r#"{"w": {"x_m": 0.5, "y_m": 0.5, "theta_rad": 0.1}}"#,
                "[x_m, y_m, theta_rad]",
            ),
        ] {
            let err = serde_json::from_str::<Section>(text)
                .unwrap_err()
                .to_string();
            assert!(err.contains(expected), "{text}: {err}");
        }
    }
}
