//! The panel under a line plot with the share available at each x (every
//! sphere visible, or identifiable), and the shading of the x values where
//! nothing is.

use super::{
    draw_x_tick_labels, Anchor, Availability, Rect, Scale, Svg, PANEL_HEIGHT, PLOT_WIDTH,
    TEXT_ASCENT_EM, TEXT_DESCENT_EM, TICK_SIZE,
};

/// Shading of the x values with nothing available.
const EMPTY_FILL: &str = "#F2E6E6";

/// The note on the x values with nothing available, if any.
pub(super) fn empty_note(a: &Availability) -> Option<String> {
    let values: Vec<String> = a
        .points
        .iter()
        .filter(|p| p.1 <= 0.0)
        .map(|p| format!("{}", p.0))
        .collect();
    (!values.is_empty()).then(|| {
        format!(
            "{} at {} {} {} (shaded): nothing to plot there",
            a.empty,
            a.axis,
            values.join(", "),
            a.unit
        )
    })
}

/// Pixel spans (left, right) of the x values where the share is zero, each
/// reaching half-way to its neighbours.
pub(super) fn empty_spans(a: &Availability, x_scale: &Scale, area: Rect) -> Vec<(f64, f64)> {
    let all_x: Vec<f64> = a.points.iter().map(|p| p.0).collect();
    a.points
        .iter()
        .filter(|p| p.1 <= 0.0)
        .map(|&(x, _)| {
            let below = all_x
                .iter()
                .copied()
                .filter(|&v| v < x)
                .fold(f64::NAN, f64::max);
            let above = all_x
                .iter()
                .copied()
                .filter(|&v| v > x)
                .fold(f64::NAN, f64::min);
            let a = if below.is_nan() { x } else { 0.5 * (x + below) };
            let b = if above.is_nan() { x } else { 0.5 * (x + above) };
            (
                x_scale.map(a).max(area.left),
                x_scale.map(b).min(area.right),
            )
        })
        .collect()
}

/// Shades `spans` from `top` to `bottom`.
pub(super) fn shade(svg: &mut Svg, spans: &[(f64, f64)], top: f64, bottom: f64) {
    for &(a, b) in spans {
        svg.rect(
            Rect {
                left: a.min(b - 4.0),
                top,
                right: b.max(a + 4.0),
                bottom,
            },
            EMPTY_FILL,
            None,
        );
    }
}

/// Draws the availability panel under `area` (with the x tick labels);
/// returns its bottom.
pub(super) fn draw_panel(
    svg: &mut Svg,
    a: &Availability,
    x_scale: &Scale,
    area: Rect,
    spans: &[(f64, f64)],
) -> f64 {
    let caption_y = area.bottom + 8.0 + TEXT_ASCENT_EM * TICK_SIZE;
    svg.text(
        "note",
        &a.label,
        area.left,
        caption_y,
        TICK_SIZE,
        Anchor::Start,
    );
    let panel = Rect {
        left: area.left,
        top: caption_y + TEXT_DESCENT_EM * TICK_SIZE + 6.0,
        right: area.right,
        bottom: caption_y + TEXT_DESCENT_EM * TICK_SIZE + 6.0 + PANEL_HEIGHT,
    };
    let share = Scale {
        lo: 0.0,
        hi: 1.0,
        log: false,
        pixel_lo: panel.bottom,
        pixel_hi: panel.top,
    };
    shade(svg, spans, panel.top, panel.bottom);
    svg.line(
        (panel.left, share.map(0.5)),
        (panel.right, share.map(0.5)),
        "#DDDDDD",
        1.0,
    );
    let bar = (PLOT_WIDTH / (2.0 * a.points.len().max(1) as f64)).min(16.0);
    for &(x, s) in &a.points {
        let px = x_scale.map(x);
        let top = share.map(s.clamp(0.0, 1.0));
        svg.rect(
            Rect {
                left: (px - 0.5 * bar).max(panel.left),
                top,
                right: (px + 0.5 * bar).min(panel.right),
                bottom: panel.bottom,
            },
            "#88CCEE",
            Some("#336699"),
        );
    }
    svg.rect(panel, "none", Some("#000000"));
    let centre = 0.5 * (TEXT_ASCENT_EM - TEXT_DESCENT_EM) * TICK_SIZE;
    for (value, label) in [(0.0, "0%"), (1.0, "100%")] {
        let py = share.map(value);
        svg.line((panel.left - 4.0, py), (panel.left, py), "#000000", 1.0);
        svg.text(
            "tick-y",
            label,
            panel.left - 7.0,
            py + centre,
            TICK_SIZE,
            Anchor::End,
        );
    }
    let x_ticks = x_scale.ticks(6.0);
    for tick in &x_ticks {
        let px = x_scale.map(tick.value);
        svg.line((px, panel.bottom), (px, panel.bottom + 4.0), "#000000", 1.0);
    }
    draw_x_tick_labels(svg, x_scale, &x_ticks, panel.bottom);
    panel.bottom
}
