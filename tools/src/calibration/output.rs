//! What `echofield calibrate` writes: the config file (`[mounting]` with a
//! comment on every value) and the table it prints.

use echofield_frontend::calibration::uncertainty::Vote;
use echofield_frontend::calibration::{Calibration, ContinuousEstimate, DiscreteEstimate};
use echofield_frontend::sensors::{AngleDirection, SweepTiming};
use std::fmt::Write as _;

/// Comment lines are wrapped at this width.
const COMMENT_WIDTH: usize = 88;

fn angle_name(a: AngleDirection) -> &'static str {
    match a {
        AngleDirection::CounterClockwise => "counter_clockwise",
        AngleDirection::Clockwise => "clockwise",
    }
}

fn sweep_name(s: SweepTiming) -> &'static str {
    match s {
        SweepTiming::Logged => "logged",
        SweepTiming::AngleIncreasing => "angle_increasing",
        SweepTiming::AngleDecreasing => "angle_decreasing",
    }
}

fn other_angle(a: AngleDirection) -> AngleDirection {
    match a {
        AngleDirection::CounterClockwise => AngleDirection::Clockwise,
        AngleDirection::Clockwise => AngleDirection::CounterClockwise,
    }
}

fn other_sweep(s: SweepTiming) -> SweepTiming {
    match s {
        SweepTiming::AngleIncreasing => SweepTiming::AngleDecreasing,
        SweepTiming::AngleDecreasing => SweepTiming::AngleIncreasing,
        SweepTiming::Logged => SweepTiming::Logged,
    }
}

/// The note on a discrete choice: its vote, or why the mission's value
/// stays.
fn discrete_note<T: PartialEq + Copy>(
    d: &DiscreteEstimate<T>,
    name: impl Fn(T) -> &'static str,
    other: T,
) -> String {
    let v = &d.vote;
    let evidence = format!(
        "{:.3} bits sharper than {}; {} of {} blocks prefer it (signed-rank p = {:.4})",
        v.gap_bits,
        name(other),
        v.agreeing_blocks,
        v.blocks,
        v.p_value
    );
    if v.determined {
        format!("estimated: {evidence}")
    } else {
        format!(
            "kept from the mission: the data prefer {} too weakly to tell ({evidence})",
            name(d.estimate)
        )
    }
}

/// The note on a continuous value, in `unit` after scaling by `scale`.
fn continuous_note(c: &ContinuousEstimate, scale: f64, unit: &str) -> String {
    let std = c.std.unwrap_or(f64::NAN) * scale;
    let vote = c.vote.map_or(String::new(), |v: Vote| {
        format!(
            "; it predicts the windows left out better than the mission's {:.3} {unit} \
             ({} of {} blocks, signed-rank p = {:.4})",
            c.mission * scale,
            v.agreeing_blocks,
            v.blocks,
            v.p_value
        )
    });
    match &c.reason {
        None => format!("estimated: ± {std:.3} {unit} (1 sd, block jackknife){vote}"),
        Some(reason) => format!(
            "estimate {:.3} ± {std:.3} {unit}; {reason}",
            c.estimate * scale
        ),
    }
}

/// Appends `text` as `#` comment lines wrapped at [`COMMENT_WIDTH`].
fn comment(out: &mut String, text: &str) {
    let mut line = String::from("#");
    for word in text.split_whitespace() {
        if line.len() + 1 + word.len() > COMMENT_WIDTH && line.len() > 1 {
            out.push_str(&line);
            out.push('\n');
            line = String::from("#");
        }
        line.push(' ');
        line.push_str(word);
    }
    out.push_str(&line);
    out.push('\n');
}

/// One key of `[mounting]`: its value as TOML, as shown, the mission's,
/// and the note on it.
struct KeyRow {
    key: &'static str,
    toml_value: String,
    shown: String,
    mission: String,
    note: String,
}

/// Every key the calibration writes, in order.
fn key_rows(result: &Calibration) -> Vec<KeyRow> {
    let a = &result.sonar_angle;
    let mut rows = vec![KeyRow {
        key: "sonar_angle",
        toml_value: format!("\"{}\"", angle_name(a.value)),
        shown: angle_name(a.value).into(),
        mission: angle_name(a.mission).into(),
        note: discrete_note(a, angle_name, other_angle(a.estimate)),
    }];
    if let Some(sw) = &result.sweep {
        rows.push(KeyRow {
            key: "sweep",
            toml_value: format!("\"{}\"", sweep_name(sw.value)),
            shown: sweep_name(sw.value).into(),
            mission: sweep_name(sw.mission).into(),
            note: discrete_note(sw, sweep_name, other_sweep(sw.estimate)),
        });
    }
    let deg = 180.0 / std::f64::consts::PI;
    for (key, c, scale, unit) in [
        ("sonar_yaw_deg", &result.sonar_yaw_rad, deg, "deg"),
        ("sonar_x_m", &result.sonar_x_m, 1.0, "m"),
        ("sonar_y_m", &result.sonar_y_m, 1.0, "m"),
        ("heading_offset_deg", &result.heading_offset_rad, deg, "deg"),
    ] {
        rows.push(KeyRow {
            key,
            toml_value: format!("{:.4}", c.value * scale),
            shown: format!("{:.3}", c.value * scale),
            mission: format!("{:.3}", c.mission * scale),
            // A value never estimated carries only its reason.
            note: match (&c.std, &c.reason) {
                (None, Some(reason)) => format!("{reason}; kept from the mission"),
                _ => continuous_note(c, scale, unit),
            },
        });
    }
    rows
}

/// The config file: a header, `[mounting]` with every key of the sonar
/// head (the sweep only for a reconstruction) and the heading offset, each
/// after a comment with its uncertainty or the reason it was kept; then
/// `other_sections` (the settings file's other pipeline sections).
pub fn config_toml(result: &Calibration, mission: &str, other_sections: &toml::Table) -> String {
    let s = &result.summary;
    let mut out = String::new();
    comment(
        &mut out,
        &format!(
            "The sensor mounting of `{mission}`, estimated by `echofield calibrate` from its \
             sonar, DVL and heading alone (no ground truth): {} rotations in {} windows of {}, \
             {} returns, cells of {:.3} m. Give it to `echofield run` with --config.",
            s.rotations, s.windows, s.window_rotations, s.returns, s.cell_size_m
        ),
    );
    out.push_str("\n[mounting]\n");
    for row in key_rows(result) {
        comment(&mut out, &row.note);
        let _ = writeln!(out, "{} = {}", row.key, row.toml_value);
    }
    if !other_sections.is_empty() {
        out.push('\n');
        comment(&mut out, "The other settings calibrate was given:");
        out.push_str(&toml::to_string(other_sections).unwrap_or_default());
    }
    out
}

/// The table `echofield calibrate` prints: a summary line, every
/// combination, then every key with its value, the mission's, and its
/// note.
pub fn summary_lines(result: &Calibration, mission: &str) -> Vec<String> {
    let s = &result.summary;
    let cell = if s.cell_size_derived {
        "derived"
    } else {
        "configured"
    };
    let mut lines = vec![format!(
        "{mission}: {} rotations in {} windows of {} ({} blocks), {} returns, cells {:.3} m \
         ({cell}), {} evaluations",
        s.rotations,
        s.windows,
        s.window_rotations,
        s.blocks,
        s.returns,
        s.cell_size_m,
        s.evaluations
    )];
    lines.push(format!(
        "{:<38} {:>10} {:>22}",
        "combination", "yaw (deg)", "mean entropy (bits)"
    ));
    for (k, c) in result.combinations.iter().enumerate() {
        let name = match c.sweep {
            SweepTiming::Logged => angle_name(c.sonar_angle).to_string(),
            sweep => format!("{}, {}", angle_name(c.sonar_angle), sweep_name(sweep)),
        };
        lines.push(format!(
            "{name:<38} {:>10.2} {:>22.4}{}",
            c.yaw_rad.to_degrees(),
            c.mean_entropy_bits,
            if k == 0 { "  best" } else { "" }
        ));
    }
    lines.push(format!(
        "{:<20} {:<20} {:<20} note",
        "key", "value", "mission"
    ));
    lines.extend(
        key_rows(result)
            .into_iter()
            .map(|r| format!("{:<20} {:<20} {:<20} {}", r.key, r.shown, r.mission, r.note)),
    );
    lines
}
