//! Line plots split into panels stacked under one title, for figures with
//! more series than a reader can tell apart in one picture.
//!
//! Every panel shares the x axis and the logarithmic y axis, so heights
//! compare across panels. The y range comes from the measurements (and
//! their bands) alone: a model line that leaves it is clipped at the frame
//! and a note says so, so that a model's pole never squeezes the data.
//! A series may carry a 95% band, drawn as a pale area of its colour.

use super::{
    draw_axes, draw_heading, draw_legend, heading_width, legend_width, log_range, styles_for,
    widest_label, Entry, Marker, Rect, Scale, Series, Svg, LABEL_SIZE, PLOT_WIDTH, TEXT_ASCENT_EM,
    TEXT_DESCENT_EM, TICK_SIZE,
};
use crate::report::ReportError;
use std::fmt::Write as _;
use std::path::Path;

/// Height of one panel's plot area, px.
const PANEL_AREA_HEIGHT: f64 = 240.0;
/// Most series one panel may hold (the plot test checks every SVG).
pub const MAX_SERIES_PER_PANEL: usize = 8;

/// The panels a figure with too many solvers is split into, in order: the
/// paper's method and its variants, the other closed-form solvers, the
/// other iterative ones.
pub const SOLVER_GROUPS: [&str; 3] = [
    "the paper's method and its variants",
    "other closed-form solvers",
    "other iterative solvers",
];

/// Which of [`SOLVER_GROUPS`] the solver called `name` belongs to.
pub fn solver_group(name: &str) -> usize {
    match name {
        name if name.starts_with("parallel") => 0,
        "epnp-gn" | "iepnp" | "lhm" | "ml" => 2,
        _ => 1,
    }
}

/// A series with an optional 95% band: (x, low, high) at each x.
#[derive(Debug, Clone)]
pub struct BandedSeries {
    /// The line.
    pub series: Series,
    /// The band, empty for none.
    pub band: Vec<(f64, f64, f64)>,
}

/// One panel: a heading and its series.
#[derive(Debug, Clone)]
pub struct LinePanel {
    /// Shown at the panel's top left ("closed-form solvers").
    pub heading: String,
    /// At most [`MAX_SERIES_PER_PANEL`].
    pub series: Vec<BandedSeries>,
}

/// Whether a point can go on a log axis.
fn drawable(x: f64, y: f64) -> bool {
    x.is_finite() && y.is_finite() && y > 0.0
}

/// The part of segment `a`–`b` (pixels) between `top` and `bottom`, if any.
fn clip_segment(
    a: (f64, f64),
    b: (f64, f64),
    top: f64,
    bottom: f64,
) -> Option<((f64, f64), (f64, f64))> {
    let inside = |p: (f64, f64)| p.1 >= top && p.1 <= bottom;
    if inside(a) && inside(b) {
        return Some((a, b));
    }
    let at = |y: f64| {
        let t = (y - a.1) / (b.1 - a.1);
        (a.0 + t * (b.0 - a.0), y)
    };
    let (mut p, mut q) = (a, b);
    for edge in [top, bottom] {
        let outside = |r: (f64, f64)| if edge == top { r.1 < top } else { r.1 > bottom };
        match (outside(p), outside(q)) {
            (true, true) => return None,
            (true, false) => p = at(edge),
            (false, true) => q = at(edge),
            (false, false) => {}
        }
    }
    Some((p, q))
}

/// Writes a stack of panels under one title. `notes` go under the title;
/// a note on clipped model lines is added when one is clipped. With
/// `availability`, its panel goes under the last one and the x values with
/// nothing available are shaded in every panel.
pub fn panel_plot(
    path: &Path,
    title: &str,
    notes: &[String],
    x_label: &str,
    y_label: &str,
    panels: &[LinePanel],
    availability: Option<&super::Availability>,
) -> Result<(), ReportError> {
    let measured = |s: &&BandedSeries| !s.series.dashed;
    let values = panels
        .iter()
        .flat_map(|p| p.series.iter().filter(measured))
        .flat_map(|s| {
            s.series
                .points
                .iter()
                .filter(|p| drawable(p.0, p.1))
                .map(|p| p.1)
                .chain(s.band.iter().flat_map(|b| [b.1, b.2]))
        });
    let range = log_range(values).or_else(|| {
        log_range(
            panels
                .iter()
                .flat_map(|p| &p.series)
                .flat_map(|s| s.series.points.iter().map(|p| p.1)),
        )
    });
    let Some((y_lo, y_hi)) = range else {
        return Ok(());
    };
    let (mut x_lo, mut x_hi) = panels
        .iter()
        .flat_map(|p| &p.series)
        .flat_map(|s| s.series.points.iter().map(|p| p.0))
        .chain(
            availability
                .iter()
                .flat_map(|a| a.points.iter().map(|p| p.0)),
        )
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
            (lo.min(x), hi.max(x))
        });
    if !x_lo.is_finite() {
        return Ok(());
    }
    if x_lo == x_hi {
        x_lo -= 1.0;
        x_hi += 1.0;
    }
    let clipped = panels.iter().flat_map(|p| &p.series).any(|s| {
        s.series.dashed
            && s.series
                .points
                .iter()
                .any(|&(x, y)| drawable(x, y) && (y < y_lo || y > y_hi))
    });
    let mut notes = notes.to_vec();
    notes.extend(availability.and_then(super::availability::empty_note));
    if clipped {
        notes.push("model lines are clipped at the frame, whose range the measurements set".into());
    }

    let styled: Vec<Vec<(&BandedSeries, super::Style)>> = panels
        .iter()
        .map(|p| {
            let styles = styles_for(
                p.series
                    .iter()
                    .map(|s| (s.series.name.as_str(), s.series.dashed)),
            );
            p.series.iter().zip(styles).collect()
        })
        .collect();
    let entries: Vec<Vec<Entry>> = styled
        .iter()
        .map(|row| {
            row.iter()
                .filter(|(s, _)| s.series.points.iter().any(|p| drawable(p.0, p.1)))
                .map(|(s, style)| Entry {
                    name: &s.series.name,
                    style: *style,
                    line: true,
                })
                .collect()
        })
        .collect();
    let mut y_scale = Scale {
        lo: y_lo,
        hi: y_hi,
        log: true,
        pixel_lo: 0.0,
        pixel_hi: 0.0,
    };
    let left = 16.0 + LABEL_SIZE + widest_label(&y_scale, 5.0) + 12.0;
    let legend_w = entries.iter().map(|e| legend_width(e)).fold(0.0, f64::max);
    let width = (left + PLOT_WIDTH + 16.0 + legend_w + 8.0).max(heading_width(title, &notes));
    let mut svg = Svg::new();
    let mut top = draw_heading(&mut svg, title, &notes, width) + 10.0;
    let x_scale = Scale {
        lo: x_lo,
        hi: x_hi,
        log: false,
        pixel_lo: left,
        pixel_hi: left + PLOT_WIDTH,
    };
    let mut bottom = top;
    let mut first_top = top;
    for (k, (panel, row)) in panels.iter().zip(&styled).enumerate() {
        let heading_y = top + TEXT_ASCENT_EM * LABEL_SIZE;
        svg.text(
            "panel-heading",
            &panel.heading,
            left,
            heading_y,
            LABEL_SIZE,
            super::Anchor::Start,
        );
        let area = Rect {
            left,
            top: heading_y + TEXT_DESCENT_EM * LABEL_SIZE + 6.0,
            right: left + PLOT_WIDTH,
            bottom: heading_y + TEXT_DESCENT_EM * LABEL_SIZE + 6.0 + PANEL_AREA_HEIGHT,
        };
        y_scale.pixel_lo = area.bottom;
        y_scale.pixel_hi = area.top;
        if k == 0 {
            first_top = area.top;
        }
        let last = k + 1 == panels.len();
        let spans = availability.map_or(Vec::new(), |a| {
            super::availability::empty_spans(a, &x_scale, area)
        });
        super::availability::shade(&mut svg, &spans, area.top, area.bottom);
        draw_axes(
            &mut svg,
            &x_scale,
            &y_scale,
            area,
            last && availability.is_none(),
        );
        // Bands first, under every line.
        for (series, style) in row {
            let band: Vec<(f64, f64, f64)> = series
                .band
                .iter()
                .copied()
                .filter(|&(x, lo, hi)| x.is_finite() && lo > 0.0 && hi.is_finite())
                .collect();
            if band.len() < 2 {
                continue;
            }
            let mut outline = String::new();
            let clamp = |y: f64| y_scale.map(y.clamp(y_lo, y_hi));
            for &(x, _, hi) in &band {
                let _ = write!(outline, "{:.1},{:.1} ", x_scale.map(x), clamp(hi));
            }
            for &(x, lo, _) in band.iter().rev() {
                let _ = write!(outline, "{:.1},{:.1} ", x_scale.map(x), clamp(lo));
            }
            let _ = writeln!(
                svg.body,
                r#"<polygon class="band" points="{}" fill="{}" fill-opacity="0.15" stroke="none"/>"#,
                outline.trim_end(),
                style.colour
            );
        }
        for (series, style) in row {
            let pixels: Vec<(f64, f64)> = series
                .series
                .points
                .iter()
                .filter(|p| drawable(p.0, p.1))
                .map(|&(x, y)| (x_scale.map(x), y_scale.map(y)))
                .collect();
            // Clipped piecewise, so a line leaving the frame stops at it.
            let mut run: Vec<(f64, f64)> = Vec::new();
            for pair in pixels.windows(2) {
                match clip_segment(pair[0], pair[1], area.top, area.bottom) {
                    Some((a, b)) => {
                        if run.last() != Some(&a) {
                            svg.polyline(&run, style);
                            run = vec![a];
                        }
                        run.push(b);
                    }
                    None => {
                        svg.polyline(&run, style);
                        run.clear();
                    }
                }
            }
            svg.polyline(&run, style);
            let marker = match (style.marker, pixels.len()) {
                (Marker::None, 1) => Marker::Circle,
                (marker, _) => marker,
            };
            for &p in pixels
                .iter()
                .filter(|p| p.1 >= area.top && p.1 <= area.bottom)
            {
                svg.marker(marker, p, 3.0, style.colour);
            }
        }
        let legend_bottom = draw_legend(&mut svg, &entries[k], area.right + 16.0, area.top);
        bottom = area.bottom;
        if let (true, Some(a)) = (last, availability) {
            bottom = super::availability::draw_panel(&mut svg, a, &x_scale, area, &spans);
        }
        if last {
            bottom = bottom.max(legend_bottom);
        }
        top = area.bottom + if last { 0.0 } else { 14.0 };
    }
    svg.vertical_text(
        "axis-label",
        y_label,
        10.0 + TEXT_ASCENT_EM * LABEL_SIZE,
        0.5 * (first_top + bottom),
        LABEL_SIZE,
    );
    let x_label_y = bottom + 6.0 + TICK_SIZE + 8.0 + TEXT_ASCENT_EM * LABEL_SIZE;
    svg.text(
        "axis-label",
        x_label,
        left + 0.5 * PLOT_WIDTH,
        x_label_y,
        LABEL_SIZE,
        super::Anchor::Middle,
    );
    svg.write(path, width, x_label_y + TEXT_DESCENT_EM * LABEL_SIZE + 10.0)
}

#[cfg(test)]
mod tests {
    use super::clip_segment;

    #[test]
    fn a_segment_is_cut_at_the_frame() {
        assert_eq!(
            clip_segment((0.0, 5.0), (10.0, 15.0), 0.0, 10.0),
            Some(((0.0, 5.0), (5.0, 10.0)))
        );
        assert_eq!(clip_segment((0.0, -5.0), (10.0, -1.0), 0.0, 10.0), None);
        let (a, b) = clip_segment((0.0, -10.0), (10.0, 20.0), 0.0, 10.0).unwrap();
        assert!((a.0 - 10.0 / 3.0).abs() < 1e-12 && a.1 == 0.0, "{a:?}");
        assert!((b.0 - 20.0 / 3.0).abs() < 1e-12 && b.1 == 10.0, "{b:?}");
    }
}
