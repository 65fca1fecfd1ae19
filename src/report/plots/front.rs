//! The accuracy–availability plot of a search's Pareto front: a linear y
//! axis (the errors of a front span far less than a decade), both axes
//! padded so that no point sits on the frame, the front as a line, the hand
//! designs as single points, the winner ringed and named, and an arrow
//! towards the better corner.

use super::{
    draw_axes, draw_legend, single_panel, styles_for, Anchor, Entry, Marker, Panel, Rect,
    ReportError, Series, Style, Svg, LABEL_SIZE, POINT_LABEL_SIZE, TEXT_ASCENT_EM, TEXT_DESCENT_EM,
    TICK_SIZE,
};
use std::fmt::Write as _;
use std::path::Path;

/// Share of a range added below and above it, so that no point sits on the
/// plot's frame.
const RANGE_PAD: f64 = 0.1;

/// The winner's style: a colour no other series of the plot uses and a
/// marker of its own.
const WINNER_STYLE: Style = Style {
    colour: "#CC3311",
    dash: None,
    marker: Marker::Cross,
    width: 1.8,
};

/// What [`front_plot`] draws.
#[derive(Debug, Clone)]
pub struct FrontPlot<'a> {
    /// The title.
    pub title: &'a str,
    /// What x is, with its unit (availability).
    pub x_label: &'a str,
    /// What y is, with its unit (an error: lower is better).
    pub y_label: &'a str,
    /// The front (several points, a line) and the designs (single points).
    pub series: &'a [Series],
    /// The winner's name and (x, y), ringed and named on the plot.
    pub winner: Option<(&'a str, (f64, f64))>,
}

/// A range that holds `values` with [`RANGE_PAD`] of its span on either
/// side (never below zero when every value is at least zero).
fn padded_range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if lo > hi {
        return None;
    }
    let span = if hi > lo { hi - lo } else { hi.abs().max(1.0) };
    let pad = RANGE_PAD * span;
    let bottom = if lo >= 0.0 {
        (lo - pad).max(0.0)
    } else {
        lo - pad
    };
    Some((bottom, hi + pad))
}

/// Writes the front plot to `path`: nothing when no point is finite.
pub fn front_plot(path: &Path, plot: &FrontPlot) -> Result<(), ReportError> {
    let winner = plot
        .winner
        .filter(|(_, (x, y))| x.is_finite() && y.is_finite());
    let drawn: Vec<Vec<(f64, f64)>> = plot
        .series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .copied()
                .filter(|&(x, y)| x.is_finite() && y.is_finite())
                .collect()
        })
        .collect();
    let all = || {
        drawn
            .iter()
            .flatten()
            .copied()
            .chain(winner.map(|(_, p)| p))
    };
    let (Some((x_lo, x_hi)), Some((y_lo, y_hi))) = (
        padded_range(all().map(|p| p.0)),
        padded_range(all().map(|p| p.1)),
    ) else {
        return Ok(());
    };
    let styles = styles_for(plot.series.iter().map(|s| (s.name.as_str(), s.dashed)));
    let winner_name = winner.map(|(name, _)| format!("winner: {name}"));
    let mut entries: Vec<Entry> = plot
        .series
        .iter()
        .zip(&styles)
        .zip(&drawn)
        .filter(|(_, p)| !p.is_empty())
        .map(|((s, style), p)| Entry {
            name: &s.name,
            style: *style,
            // A single point has no line: its legend shows the marker only.
            line: p.len() > 1 || style.marker == Marker::None,
        })
        .collect();
    if let Some(name) = &winner_name {
        entries.push(Entry {
            name,
            style: WINNER_STYLE,
            line: false,
        });
    }
    let Panel {
        mut svg,
        area,
        x_scale,
        y_scale,
        width,
    } = single_panel(plot.title, &[], &entries, (x_lo, x_hi), (y_lo, y_hi, false));
    draw_axes(&mut svg, &x_scale, &y_scale, area, true);
    draw_better(&mut svg, area);
    for (points, style) in drawn.iter().zip(&styles) {
        let pixels: Vec<(f64, f64)> = points
            .iter()
            .map(|&(x, y)| (x_scale.map(x), y_scale.map(y)))
            .collect();
        svg.polyline(&pixels, style);
        let marker = match style.marker {
            Marker::None => Marker::Circle,
            marker => marker,
        };
        for &p in &pixels {
            svg.marker(marker, p, 3.0, style.colour);
        }
    }
    if let (Some((_, (x, y))), Some(name)) = (winner, &winner_name) {
        draw_winner(&mut svg, area, (x_scale.map(x), y_scale.map(y)), name);
    }
    svg.vertical_text(
        "axis-label",
        plot.y_label,
        10.0 + TEXT_ASCENT_EM * LABEL_SIZE,
        0.5 * (area.top + area.bottom),
        LABEL_SIZE,
    );
    let x_label_y = area.bottom + 6.0 + TICK_SIZE + 8.0 + TEXT_ASCENT_EM * LABEL_SIZE;
    svg.text(
        "axis-label",
        plot.x_label,
        0.5 * (area.left + area.right),
        x_label_y,
        LABEL_SIZE,
        Anchor::Middle,
    );
    let legend_bottom = draw_legend(&mut svg, &entries, area.right + 16.0, area.top);
    let height = (x_label_y + TEXT_DESCENT_EM * LABEL_SIZE + 10.0).max(legend_bottom + 10.0);
    svg.write(path, width, height)
}

/// The winner's marker, a ring round it and its name beside it, on the
/// side with more room and inside the plot area.
fn draw_winner(svg: &mut Svg, area: Rect, (x, y): (f64, f64), name: &str) {
    svg.marker(WINNER_STYLE.marker, (x, y), 3.5, WINNER_STYLE.colour);
    let _ = writeln!(
        svg.body,
        r#"<circle class="winner" cx="{x:.1}" cy="{y:.1}" r="9.0" fill="none" stroke="{}" stroke-width="1.5"/>"#,
        WINNER_STYLE.colour
    );
    let right_half = x > 0.5 * (area.left + area.right);
    let (label_x, anchor) = if right_half {
        (x - 12.0, Anchor::End)
    } else {
        (x + 12.0, Anchor::Start)
    };
    let baseline = if y - area.top > 30.0 {
        y - 12.0
    } else {
        y + 12.0 + TEXT_ASCENT_EM * POINT_LABEL_SIZE
    };
    svg.text(
        "point-label",
        name,
        label_x,
        baseline,
        POINT_LABEL_SIZE,
        anchor,
    );
}

/// An arrow in the plot's lower right corner pointing there, the better
/// corner (more availability, less error), with the word "better".
fn draw_better(svg: &mut Svg, area: Rect) {
    let tip = (area.right - 14.0, area.bottom - 14.0);
    let tail = (tip.0 - 36.0, tip.1 - 36.0);
    svg.line(tail, tip, "#555555", 1.5);
    let _ = writeln!(
        svg.body,
        r##"<polygon class="better" points="{:.1},{:.1} {:.1},{:.1} {:.1},{:.1}" fill="#555555"/>"##,
        tip.0,
        tip.1,
        tip.0 - 9.0,
        tip.1 - 3.0,
        tip.0 - 3.0,
        tip.1 - 9.0
    );
    svg.text(
        "note",
        "better",
        tail.0 - 4.0,
        tail.1 + 4.0,
        POINT_LABEL_SIZE,
        Anchor::End,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_are_padded_and_stay_at_or_above_zero() {
        let (lo, hi) = padded_range([0.2, 0.4].into_iter()).unwrap();
        assert!((lo - 0.18).abs() < 1e-12 && (hi - 0.42).abs() < 1e-12);
        let (lo, _) = padded_range([0.0, 100.0].into_iter()).unwrap();
        assert_eq!(lo, 0.0);
        let (lo, hi) = padded_range([5.0].into_iter()).unwrap();
        assert!(lo < 5.0 && hi > 5.0);
        assert_eq!(padded_range([f64::NAN].into_iter()), None);
    }
}
