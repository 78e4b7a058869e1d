//! Warnings about the input that a reader or a stage repaired instead of
//! failing on: stamps re-sorted, partial rotations dropped, a mounting
//! assumed, implausible samples dropped.
//!
//! A [`Warning`] has a [`WarningKind`], a `count` of the occurrences it
//! stands for, the `message` of the first occurrence and where that was
//! (`first_record`: "DVL message 1234", "beam 17"). [`Warnings`] keeps one
//! entry per kind: a second warning of a kind adds its count to the first
//! (except [`WarningKind::Other`], whose messages stay apart), so that a
//! report lists each kind of problem once with how often it happened.

use serde::{Deserialize, Serialize};

/// What a warning is about (`snake_case` in JSON).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum WarningKind {
    /// Records whose stamps went backwards in the file, re-sorted by time.
    StampsResorted,
    /// The mission records no verified sensor mounting; one was assumed.
    MountingAssumed,
    /// Beams that formed no complete rotation or sector sweep (cut by a
    /// gap, a change of settings, a reversal or the end of the data) and
    /// were dropped.
    RotationsDropped,
    /// Complete rotations that got no node (no navigation, no scan).
    RotationsSkipped,
    /// Sensor samples with physically implausible values, dropped.
    ImplausibleValues,
    /// Time without DVL or sonar data, bridged by dead reckoning.
    TimeGap,
    /// The yaw rates disagree with the headings; a larger noise was used.
    YawRateNoise,
    /// The DVL's distances disagree with the optimised motion.
    OdometryScale,
    /// A solver or search stopped early or failed and was worked around.
    Solver,
    /// Anything else (never merged with another warning).
    Other,
}

impl WarningKind {
    /// The kind as in JSON.
    pub fn name(self) -> &'static str {
        match self {
            Self::StampsResorted => "stamps_resorted",
            Self::MountingAssumed => "mounting_assumed",
            Self::RotationsDropped => "rotations_dropped",
            Self::RotationsSkipped => "rotations_skipped",
            Self::ImplausibleValues => "implausible_values",
            Self::TimeGap => "time_gap",
            Self::YawRateNoise => "yaw_rate_noise",
            Self::OdometryScale => "odometry_scale",
            Self::Solver => "solver",
            Self::Other => "other",
        }
    }
}

/// One kind of repaired problem (see the module doc).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Warning {
    pub kind: WarningKind,
    /// Occurrences: records, rotations, gaps, ... (at least 1).
    pub count: usize,
    /// What happened, what was done, and what to do about it (of the first
    /// occurrence).
    pub message: String,
    /// Where the first occurrence was (file record, beam, time), when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub first_record: Option<String>,
}

impl Warning {
    pub fn new(kind: WarningKind, count: usize, message: impl Into<String>) -> Self {
        Self {
            kind,
            count: count.max(1),
            message: message.into(),
            first_record: None,
        }
    }

    /// With the place of the first occurrence.
    pub fn at(mut self, first_record: impl Into<String>) -> Self {
        self.first_record = Some(first_record.into());
        self
    }

    /// The message contains `text`.
    pub fn contains(&self, text: &str) -> bool {
        self.message.contains(text)
    }
}

impl From<String> for Warning {
    /// A free-form warning ([`WarningKind::Other`]).
    fn from(message: String) -> Self {
        Self::new(WarningKind::Other, 1, message)
    }
}

impl std::fmt::Display for Warning {
    /// `message` (`count` × kind, first at `first_record`).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.message)?;
        if self.count > 1 || self.first_record.is_some() {
            write!(f, " [{}: {}", self.kind.name(), self.count)?;
            if let Some(at) = &self.first_record {
                write!(f, ", first at {at}")?;
            }
            write!(f, "]")?;
        }
        Ok(())
    }
}

/// Warnings, one entry per kind (see the module doc); serialises as a list.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Warnings(Vec<Warning>);

impl Warnings {
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds `warning`, merged into the entry of its kind when there is one.
    pub fn push(&mut self, warning: impl Into<Warning>) {
        let warning = warning.into();
        if warning.kind != WarningKind::Other
            && let Some(entry) = self.0.iter_mut().find(|w| w.kind == warning.kind)
        {
            entry.count += warning.count;
            if entry.first_record.is_none() {
                entry.first_record = warning.first_record;
            }
            return;
        }
        self.0.push(warning);
    }

    /// Adds every warning of `other` (see [`Warnings::push`]).
    pub fn extend<W: Into<Warning>>(&mut self, other: impl IntoIterator<Item = W>) {
        for w in other {
            self.push(w);
        }
    }

    pub fn iter(&self) -> std::slice::Iter<'_, Warning> {
        self.0.iter()
    }

    pub fn len(&self) -> usize {
        self.0.len()
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The entry of `kind`, if any.
    pub fn of(&self, kind: WarningKind) -> Option<&Warning> {
        self.0.iter().find(|w| w.kind == kind)
    }
}

impl<'a> IntoIterator for &'a Warnings {
    type Item = &'a Warning;
    type IntoIter = std::slice::Iter<'a, Warning>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}

impl<W: Into<Warning>> FromIterator<W> for Warnings {
    fn from_iter<I: IntoIterator<Item = W>>(iter: I) -> Self {
        let mut out = Self::new();
        out.extend(iter);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_entry_per_kind_with_the_counts_added_and_the_first_place_kept() {
        let mut w = Warnings::new();
        w.push(
            Warning::new(WarningKind::StampsResorted, 3, "DVL stamps re-sorted")
                .at("DVL message 7"),
        );
        w.push(
            Warning::new(WarningKind::StampsResorted, 2, "beam stamps re-sorted")
                .at("beam message 9"),
        );
        w.push("something".to_string());
        w.push("something else".to_string());
        assert_eq!(w.len(), 3);
        let resorted = w.of(WarningKind::StampsResorted).unwrap();
        assert_eq!(resorted.count, 5);
        assert_eq!(resorted.message, "DVL stamps re-sorted");
        assert_eq!(resorted.first_record.as_deref(), Some("DVL message 7"));
        let json = serde_json::to_value(&w).unwrap();
        for kind in [
            WarningKind::StampsResorted,
            WarningKind::ImplausibleValues,
            WarningKind::Other,
        ] {
            assert_eq!(serde_json::to_value(kind).unwrap(), kind.name());
        }
        assert_eq!(json[0]["kind"], "stamps_resorted");
        assert_eq!(json[0]["count"], 5);
        assert_eq!(json[0]["first_record"], "DVL message 7");
        assert_eq!(json[1]["kind"], "other");
        assert!(json[1].get("first_record").is_none());
        let back: Warnings = serde_json::from_value(json).unwrap();
        assert_eq!(back, w);
        assert!(
            resorted
                .to_string()
                .contains("[stamps_resorted: 5, first at DVL message 7]")
        );
    }
}
