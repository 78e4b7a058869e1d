//! `loops.png`: every loop-closure candidate as a segment between the
//! optimised positions of its two nodes, over the optimised trajectory.
//!
//! Colours: accepted and true against ground truth in green, accepted and
//! false in red, accepted without ground truth in blue; rejected candidates
//! thin and pale, in a fixed colour per check that rejected them. Rejected
//! ones are drawn first, then the accepted true ones, and the accepted
//! false ones last and wider, so that a few false loops among hundreds of
//! true ones stay visible. The legend counts each class and, when the
//! tolerances of the verdict are given, names them: against a reference
//! whose own error is near them (GPS fixes and a compass), "false" is the
//! reference's verdict as much as the loop's.

use super::trajectory::OPTIMISED;
use super::{
    draw_grid, draw_legend, equal_aspect_ranges, legend_corner, legend_line, map_chart_builder,
    map_plot_area_px, plot_error, render_png,
};
use anyhow::Result;
use plotters::prelude::*;
use std::collections::BTreeMap;

pub const ACCEPTED_TRUE: RGBColor = RGBColor(0, 160, 60);
pub const ACCEPTED_FALSE: RGBColor = RGBColor(220, 20, 20);
pub const ACCEPTED_UNKNOWN: RGBColor = RGBColor(20, 60, 220);
/// Colours of rejected candidates by the check that rejected them (the
/// pipeline's `RejectReason` names), so a check keeps its colour from one
/// run to the next; other names are grey.
const REJECTED: [(&str, RGBColor); 10] = [
    ("quality", RGBColor(190, 140, 220)),
    ("covariance", RGBColor(230, 170, 90)),
    ("window_edge", RGBColor(110, 190, 210)),
    ("reverse_mismatch", RGBColor(200, 190, 80)),
    ("inconsistent", RGBColor(230, 130, 170)),
    ("robust_kernel", RGBColor(140, 110, 90)),
    ("prior", RGBColor(120, 200, 150)),
    ("no_match", RGBColor(170, 170, 200)),
    ("no_data", RGBColor(200, 200, 200)),
    ("deferred", RGBColor(215, 215, 185)),
];
const REJECTED_OTHER: RGBColor = RGBColor(150, 150, 150);

fn rejected_colour(check: &str) -> RGBColor {
    REJECTED
        .iter()
        .find(|(name, _)| *name == check)
        .map_or(REJECTED_OTHER, |(_, c)| *c)
}

/// What happened to a candidate.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LoopClass {
    /// Accepted; `Some(true)` when ground truth says the match is right,
    /// `Some(false)` when wrong, `None` without ground truth.
    Accepted(Option<bool>),
    /// Rejected by the named check.
    Rejected(String),
}

/// One candidate drawn as a segment.
#[derive(Clone, Debug)]
pub struct LoopSegment {
    /// Positions of the two nodes, metres.
    pub from: (f64, f64),
    pub to: (f64, f64),
    pub class: LoopClass,
}

/// Draws the trajectory and the candidates as a PNG of `size_px`.
/// `tolerance`: the true-positive tolerances (metres, degrees) the
/// verdicts of [`LoopClass::Accepted`] were judged with, for the legend.
pub fn loops_png(
    trajectory: &[(f64, f64)],
    loops: &[LoopSegment],
    tolerance: Option<(f64, f64)>,
    caption: &str,
    size_px: (u32, u32),
) -> Result<Vec<u8>> {
    let (rejected, accepted) = by_class(loops);
    render_png(size_px.0, size_px.1, |root| {
        let area_px = map_plot_area_px(root, caption)?;
        let (xs, ys) = equal_aspect_ranges(
            trajectory
                .iter()
                .copied()
                .chain(loops.iter().flat_map(|l| [l.from, l.to])),
            area_px,
            0.04,
        );
        let corner = legend_corner(
            trajectory
                .iter()
                .copied()
                .chain(loops.iter().flat_map(|l| [l.from, l.to])),
            &xs,
            &ys,
        );
        let mut chart = map_chart_builder(root, caption)
            .build_cartesian_2d(xs, ys)
            .map_err(plot_error)?;
        draw_grid(&mut chart, "x (m)", "y (m)")?;
        let track = OPTIMISED.mix(0.6);
        chart
            .draw_series(LineSeries::new(
                trajectory.iter().copied(),
                track.stroke_width(2),
            ))
            .map_err(plot_error)?
            .label("optimised trajectory")
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], track.stroke_width(3)));
        for (check, segments) in &rejected {
            let colour = rejected_colour(check);
            draw_segments(&mut chart, segments, colour.mix(0.55).stroke_width(1))?
                .label(format!("rejected: {check} ({})", segments.len()))
                .legend(legend_line(colour));
        }
        draw_accepted(&mut chart, &accepted, tolerance)?;
        draw_legend(&mut chart, corner)?;
        Ok(())
    })
}

type MapChart<'a, 'b> = super::Chart<'a, 'b>;

/// The rejected candidates by check name (for stable colours and legend
/// order) and the accepted ones: without ground truth, true, false.
#[allow(clippy::type_complexity)]
fn by_class(loops: &[LoopSegment]) -> (BTreeMap<&str, Vec<&LoopSegment>>, [Vec<&LoopSegment>; 3]) {
    let mut rejected: BTreeMap<&str, Vec<&LoopSegment>> = BTreeMap::new();
    let mut accepted: [Vec<&LoopSegment>; 3] = Default::default();
    for l in loops {
        match &l.class {
            LoopClass::Rejected(check) => rejected.entry(check.as_str()).or_default().push(l),
            LoopClass::Accepted(None) => accepted[0].push(l),
            LoopClass::Accepted(Some(true)) => accepted[1].push(l),
            LoopClass::Accepted(Some(false)) => accepted[2].push(l),
        }
    }
    (rejected, accepted)
}

/// The accepted candidates of [`by_class`], each class (not empty) with its
/// legend entry.
fn draw_accepted(
    chart: &mut MapChart,
    accepted: &[Vec<&LoopSegment>; 3],
    tolerance: Option<(f64, f64)>,
) -> Result<()> {
    let names = accepted_names(tolerance);
    let colours = [ACCEPTED_UNKNOWN, ACCEPTED_TRUE, ACCEPTED_FALSE];
    let widths = [2, 2, 3];
    for (((segments, name), colour), width) in accepted.iter().zip(names).zip(colours).zip(widths) {
        if segments.is_empty() {
            continue;
        }
        draw_segments(chart, segments, colour.stroke_width(width))?
            .label(format!("{name} ({})", segments.len()))
            .legend(legend_line(colour));
    }
    Ok(())
}

/// The legend names of the accepted classes (no ground truth, true,
/// false), with the tolerances when known.
fn accepted_names(tolerance: Option<(f64, f64)>) -> [String; 3] {
    let (t, f) = match tolerance {
        Some((m, deg)) => (
            format!("accepted, within {m} m and {deg}° of ground truth"),
            format!("accepted, farther than {m} m or {deg}° from it"),
        ),
        None => ("accepted, true".into(), "accepted, false".into()),
    };
    ["accepted (no ground truth)".into(), t, f]
}

fn draw_segments<'c, 'a, 'b>(
    chart: &'c mut MapChart<'a, 'b>,
    segments: &[&LoopSegment],
    style: ShapeStyle,
) -> Result<&'c mut plotters::chart::SeriesAnno<'a, BitMapBackend<'b>>> {
    chart
        .draw_series(
            segments
                .iter()
                .map(|l| PathElement::new([l.from, l.to], style)),
        )
        .map_err(plot_error)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepted_segments_are_drawn_in_their_verdict_colour() {
        let trajectory: Vec<(f64, f64)> = (0..50).map(|i| (f64::from(i), 0.0)).collect();
        let loops = vec![
            LoopSegment {
                from: (0.0, 0.0),
                to: (10.0, 20.0),
                class: LoopClass::Accepted(Some(true)),
            },
            LoopSegment {
                from: (40.0, 0.0),
                to: (30.0, 20.0),
                class: LoopClass::Accepted(Some(false)),
            },
            LoopSegment {
                from: (20.0, 0.0),
                to: (20.0, 20.0),
                class: LoopClass::Rejected("quality".into()),
            },
        ];
        let png = loops_png(&trajectory, &loops, None, "loops", (500, 400)).unwrap();
        let rgb = image::load_from_memory(&png).unwrap().to_rgb8();
        assert_eq!(rgb.dimensions(), (500, 400));
        for c in [ACCEPTED_TRUE, ACCEPTED_FALSE] {
            assert!(
                rgb.pixels().any(|p| p.0 == [c.0, c.1, c.2]),
                "{c:?} missing"
            );
        }
        assert!(
            !rgb.pixels()
                .any(|p| p.0 == [ACCEPTED_UNKNOWN.0, ACCEPTED_UNKNOWN.1, ACCEPTED_UNKNOWN.2])
        );
    }

    #[test]
    fn the_legend_names_the_tolerances_of_the_verdict() {
        let [none, t, f] = accepted_names(Some((0.5, 3.0)));
        assert_eq!(none, "accepted (no ground truth)");
        assert_eq!(t, "accepted, within 0.5 m and 3° of ground truth");
        assert_eq!(f, "accepted, farther than 0.5 m or 3° from it");
        assert_eq!(accepted_names(None)[1], "accepted, true");
    }

    /// A false loop under many true ones that cover it stays visible: the
    /// false ones are drawn last.
    #[test]
    fn false_loops_are_drawn_over_true_ones() {
        let trajectory: Vec<(f64, f64)> = (0..50).map(|i| (f64::from(i), 0.0)).collect();
        let mut loops: Vec<LoopSegment> = vec![LoopSegment {
            from: (0.0, 10.0),
            to: (40.0, 10.0),
            class: LoopClass::Accepted(Some(false)),
        }];
        for k in 0..20 {
            loops.push(LoopSegment {
                from: (0.0, 10.0 + 0.01 * f64::from(k)),
                to: (40.0, 10.0 + 0.01 * f64::from(k)),
                class: LoopClass::Accepted(Some(true)),
            });
        }
        let png = loops_png(&trajectory, &loops, None, "loops", (500, 400)).unwrap();
        let rgb = image::load_from_memory(&png).unwrap().to_rgb8();
        let red = [ACCEPTED_FALSE.0, ACCEPTED_FALSE.1, ACCEPTED_FALSE.2];
        // More red than the legend's short sample line alone could give.
        let count = rgb.pixels().filter(|p| p.0 == red).count();
        assert!(count > 200, "{count} red pixels");
    }
}
