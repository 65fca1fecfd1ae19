//! The legend of a line plot: one row per series, its line and marker
//! beside its name. Each row also carries an empty `legend-entry` group
//! with the series' dash and marker, so that a test can check that no two
//! series of one legend are told apart by colour alone.

use super::text_width;
use super::{Anchor, Marker, Rect, Style, Svg, LEGEND_SIZE, TEXT_ASCENT_EM, TEXT_DESCENT_EM};
use std::fmt::Write as _;

/// A legend entry: name and style.
pub(super) struct Entry<'a> {
    pub name: &'a str,
    pub style: Style,
    pub line: bool,
}

const LEGEND_ROW: f64 = 18.0;
const LEGEND_SWATCH: f64 = 30.0;

pub(super) fn legend_width(entries: &[Entry]) -> f64 {
    entries
        .iter()
        .map(|e| text_width(e.name, LEGEND_SIZE))
        .fold(0.0, f64::max)
        + LEGEND_SWATCH
        + 24.0
}

/// Draws the legend with its top-left corner at (`left`, `top`); returns its
/// bottom.
pub(super) fn draw_legend(svg: &mut Svg, entries: &[Entry], left: f64, top: f64) -> f64 {
    let height = LEGEND_ROW * entries.len() as f64 + 8.0;
    let frame = Rect {
        left,
        top,
        right: left + legend_width(entries) - 6.0,
        bottom: top + height,
    };
    svg.rect(frame, "#FFFFFF", Some("#999999"));
    for (row, entry) in entries.iter().enumerate() {
        let y = top + 4.0 + LEGEND_ROW * (row as f64 + 0.5);
        let (a, b) = (left + 6.0, left + 6.0 + LEGEND_SWATCH);
        if entry.line {
            svg.polyline(&[(a, y), (b, y)], &entry.style);
        }
        svg.marker(
            entry.style.marker,
            (0.5 * (a + b), y),
            3.5,
            entry.style.colour,
        );
        let _ = writeln!(
            svg.body,
            r#"<g class="legend-entry" data-legend="{left:.1} {top:.1}" data-dash="{}" data-marker="{}"/>"#,
            entry.style.dash.unwrap_or("solid"),
            marker_name(entry.style.marker)
        );
        let baseline = y + 0.5 * (TEXT_ASCENT_EM - TEXT_DESCENT_EM) * LEGEND_SIZE;
        svg.text(
            "legend",
            entry.name,
            b + 6.0,
            baseline,
            LEGEND_SIZE,
            Anchor::Start,
        );
    }
    frame.bottom
}

/// A marker's name in the SVG's `legend-entry` groups.
fn marker_name(marker: Marker) -> &'static str {
    match marker {
        Marker::None => "none",
        Marker::Circle => "circle",
        Marker::Square => "square",
        Marker::TriangleUp => "triangle-up",
        Marker::TriangleDown => "triangle-down",
        Marker::Diamond => "diamond",
        Marker::Plus => "plus",
        Marker::Cross => "cross",
    }
}
