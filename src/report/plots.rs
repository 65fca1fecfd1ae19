//! SVG plots, written as plain SVG text so that every label's place and size
//! is ours to choose (no system fonts needed: text is SVG `<text>`).
//!
//! Conventions every plot follows, and which the report tests check:
//! - every solver has one fixed style ([`series_style`]): a colour from a
//!   colour-blind-safe palette plus a marker and a dash pattern, so that no two
//!   series look alike even in grey; model lines are black or grey and dashed;
//! - tick labels are "nice" (1-2-5 steps) and printed with the digits their
//!   step needs; log axes label decades and, when the span is small, the
//!   values in between;
//! - legends sit outside the plot area (to the right; the picture grows);
//! - text never leaves the view box and no two labels overlap, judged with a
//!   box [`TEXT_WIDTH_EM`] × font size per character wide and from
//!   [`TEXT_ASCENT_EM`] above to [`TEXT_DESCENT_EM`] below the baseline.

use super::ReportError;
use nalgebra::Vector3;
use std::fmt::Write as _;
use std::path::Path;

mod availability;
mod front;
mod legend;
mod panels;
pub use front::{front_plot, FrontPlot};
use legend::{draw_legend, legend_width, Entry};
pub use panels::{
    panel_plot, solver_group, BandedSeries, LinePanel, MAX_SERIES_PER_PANEL, SOLVER_GROUPS,
};

/// Estimated width of one character, in units of the font size (the layout
/// uses a little more, [`LAYOUT_WIDTH_EM`], to leave room for wide glyphs).
pub const TEXT_WIDTH_EM: f64 = 0.6;
/// Height above the baseline that a line of text takes, in font sizes.
pub const TEXT_ASCENT_EM: f64 = 0.8;
/// Depth below the baseline that a line of text takes, in font sizes.
pub const TEXT_DESCENT_EM: f64 = 0.2;
/// Character width the layout reserves, in font sizes.
const LAYOUT_WIDTH_EM: f64 = 0.64;

const TITLE_SIZE: f64 = 16.0;
const NOTE_SIZE: f64 = 12.0;
const LABEL_SIZE: f64 = 12.0;
const TICK_SIZE: f64 = 11.0;
const LEGEND_SIZE: f64 = 12.0;
const POINT_LABEL_SIZE: f64 = 11.0;

/// One line of a line plot.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend entry; a solver's name picks its fixed style.
    pub name: String,
    /// Points, in x order.
    pub points: Vec<(f64, f64)>,
    /// A model prediction rather than a measurement (drawn dashed, in black
    /// or grey, without markers).
    pub dashed: bool,
}

/// The shape drawn at each point of a series.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Marker {
    /// No marker (model lines).
    None,
    /// A filled circle.
    Circle,
    /// A filled square.
    Square,
    /// A filled triangle pointing up.
    TriangleUp,
    /// A filled triangle pointing down.
    TriangleDown,
    /// A filled diamond.
    Diamond,
    /// A plus sign.
    Plus,
    /// A diagonal cross.
    Cross,
}

/// How one series is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Style {
    /// Stroke and fill colour, `#rrggbb`.
    pub colour: &'static str,
    /// SVG `stroke-dasharray`; `None` is a solid line.
    pub dash: Option<&'static str>,
    /// Marker at each point.
    pub marker: Marker,
    /// Line width, px.
    pub width: f64,
}

const SOLID: Option<&str> = None;
const DASHED: Option<&str> = Some("7 3");
const DOTTED: Option<&str> = Some("2 3");
const DASH_DOT: Option<&str> = Some("8 3 2 3");

const fn solver_style(colour: &'static str, dash: Option<&'static str>, marker: Marker) -> Style {
    Style {
        colour,
        dash,
        marker,
        width: 1.8,
    }
}

/// Every solver's style: fourteen colours from Paul Tol's muted, bright and
/// high-contrast and the Okabe–Ito palettes (all chosen to stay apart
/// under colour-vision
/// deficiency), each with its own marker–dash pair so that even series of
/// similar hue differ in shape.
const SOLVER_STYLES: [(&str, Style); 14] = [
    (
        "parallel-weighted",
        solver_style("#332288", SOLID, Marker::Circle),
    ),
    ("parallel", solver_style("#4477AA", SOLID, Marker::Square)),
    (
        "parallel-init",
        solver_style("#6699CC", DOTTED, Marker::Circle),
    ),
    (
        "parallel-gn",
        solver_style("#44AA99", SOLID, Marker::TriangleUp),
    ),
    ("epnp", solver_style("#E69F00", SOLID, Marker::Diamond)),
    ("epnp-gn", solver_style("#117733", DASHED, Marker::Square)),
    ("iepnp", solver_style("#999933", DASHED, Marker::Circle)),
    ("dlt", solver_style("#997700", SOLID, Marker::TriangleDown)),
    ("dls", solver_style("#CC6677", DASHED, Marker::Diamond)),
    ("lhm", solver_style("#882255", SOLID, Marker::Plus)),
    ("rpnp", solver_style("#AA4499", DOTTED, Marker::TriangleUp)),
    ("sqpnp", solver_style("#0072B2", DOTTED, Marker::Square)),
    ("opnp", solver_style("#D55E00", SOLID, Marker::Cross)),
    (
        "ml",
        solver_style("#8C510A", DASH_DOT, Marker::TriangleDown),
    ),
];

/// Styles of the model lines, by the start of their names.
const MODEL_STYLES: [(&str, Style); 3] = [
    (
        "first-order",
        Style {
            colour: "#000000",
            dash: Some("10 5"),
            marker: Marker::None,
            width: 2.2,
        },
    ),
    (
        "transfer",
        Style {
            colour: "#777777",
            dash: Some("3 3"),
            marker: Marker::None,
            width: 2.2,
        },
    ),
    (
        "",
        Style {
            colour: "#555555",
            dash: Some("12 3 3 3"),
            marker: Marker::None,
            width: 2.0,
        },
    ),
];

/// Styles for series that are neither a solver nor a model, in turn.
const OTHER_STYLES: [Style; 4] = [
    solver_style("#000000", SOLID, Marker::Circle),
    solver_style("#777777", SOLID, Marker::Square),
    solver_style("#000000", DOTTED, Marker::TriangleUp),
    solver_style("#777777", DOTTED, Marker::Diamond),
];

/// The fixed style of a series: a solver's own style, a model line's style
/// (`model` true) or, for anything else, `None`.
pub fn series_style(name: &str, model: bool) -> Option<Style> {
    if let Some((_, style)) = SOLVER_STYLES.iter().find(|(n, _)| *n == name) {
        return Some(*style);
    }
    if model {
        return MODEL_STYLES
            .iter()
            .find(|(prefix, _)| name.starts_with(prefix))
            .map(|(_, style)| *style);
    }
    None
}

/// Styles for `series`, the fixed ones where known, and never the same style
/// twice in one plot.
fn styles_for<'a>(series: impl Iterator<Item = (&'a str, bool)>) -> Vec<Style> {
    let mut used: Vec<Style> = Vec::new();
    let mut others = OTHER_STYLES.iter().cycle();
    let mut extra_dash = 0usize;
    for (name, model) in series {
        let mut style = series_style(name, model).unwrap_or_else(|| *others.next().expect("cycle"));
        let dashes = ["1 2", "5 2 1 2", "14 4", "4 4 1 4 1 4"];
        while used.contains(&style) {
            style.dash = Some(dashes[extra_dash % dashes.len()]);
            extra_dash += 1;
            if extra_dash > 4 * dashes.len() {
                break;
            }
        }
        used.push(style);
    }
    used
}

// ------------------------------------------------------------------ ticks

/// One tick of an axis: its value, label and how much the label matters
/// (lower first when labels would collide).
#[derive(Debug, Clone, PartialEq)]
struct Tick {
    value: f64,
    label: String,
    priority: u8,
}

/// Decimal places that a step of `step` needs.
fn decimals_for(step: f64) -> usize {
    let exponent = step.abs().log10();
    // Tolerate the rounding of steps such as 0.1 (log10 = −0.99999…).
    (-(exponent + 1e-9).floor()).max(0.0) as usize
}

/// `value` with `decimals` places, never "-0".
fn format_fixed(value: f64, decimals: usize) -> String {
    let text = format!("{value:.decimals$}");
    if text
        .trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        text.trim_start_matches('-').to_string()
    } else {
        text
    }
}

/// A "nice" step (1, 2 or 5 × 10^k) near `span / target`.
fn nice_step(span: f64, target: f64) -> f64 {
    let raw = span / target;
    let magnitude = 10f64.powf(raw.log10().floor());
    let fraction = raw / magnitude;
    let nice = if fraction < 1.5 {
        1.0
    } else if fraction < 3.5 {
        2.0
    } else if fraction < 7.5 {
        5.0
    } else {
        10.0
    };
    nice * magnitude
}

/// Linear ticks over [lo, hi], about `target` of them.
fn linear_ticks(lo: f64, hi: f64, target: f64) -> Vec<Tick> {
    let span = hi - lo;
    if !(span > 0.0 && span.is_finite()) {
        return vec![Tick {
            value: lo,
            label: format_fixed(lo, decimals_for(lo.abs().max(1.0))),
            priority: 0,
        }];
    }
    let step = nice_step(span, target);
    let decimals = decimals_for(step);
    let first = (lo / step - 1e-9).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    (first..=last)
        .map(|k| {
            let value = k as f64 * step;
            Tick {
                value,
                label: format_fixed(value, decimals),
                // Every other tick first, so that thinning keeps a regular step.
                priority: (k.rem_euclid(2)) as u8,
            }
        })
        .collect()
}

/// The label of m × 10^k on a log axis.
fn log_label(mantissa: u32, exponent: i32) -> String {
    if !(-4..=4).contains(&exponent) {
        return format!("{mantissa}e{exponent}");
    }
    let value = mantissa as f64 * 10f64.powi(exponent);
    format_fixed(value, (-exponent).max(0) as usize)
}

/// Ticks of a log axis over [lo, hi] (both positive): decades when there are
/// at least five, else 1-2-5 when that gives four, else every integer
/// multiple of the decade when that gives three; a span too short for that
/// gets linear 1-2-5 ticks.
fn log_ticks(lo: f64, hi: f64) -> Vec<Tick> {
    // Each set with the fewest ticks it must give to be chosen.
    const SETS: [(&[u32], usize); 3] = [
        (&[1], 5),
        (&[1, 2, 5], 4),
        (&[1, 2, 3, 4, 5, 6, 7, 8, 9], 3),
    ];
    let first = lo.log10().floor() as i32;
    let last = hi.log10().ceil() as i32;
    for (set, fewest) in SETS {
        let mut ticks = Vec::new();
        for exponent in first..=last {
            for &mantissa in set {
                let value = mantissa as f64 * 10f64.powi(exponent);
                if value >= lo * (1.0 - 1e-9) && value <= hi * (1.0 + 1e-9) {
                    ticks.push(Tick {
                        value,
                        label: log_label(mantissa, exponent),
                        priority: match mantissa {
                            1 => 0,
                            5 => 1,
                            2 => 2,
                            _ => 3,
                        },
                    });
                }
            }
        }
        if ticks.len() >= fewest {
            // One notation per axis: "1e4 … 1e7", never "10000 … 1e7".
            if ticks.iter().any(|t| t.label.contains('e')) {
                for t in &mut ticks {
                    let exponent = t.value.log10().floor() as i32;
                    let mantissa = (t.value / 10f64.powi(exponent)).round() as u32;
                    t.label = format!("{mantissa}e{exponent}");
                }
            }
            return ticks;
        }
    }
    linear_ticks(lo, hi, 4.0)
}

/// Unlabelled grid values of a log axis: every integer multiple of a decade.
fn log_minor(lo: f64, hi: f64) -> Vec<f64> {
    let first = lo.log10().floor() as i32;
    let last = hi.log10().ceil() as i32;
    (first..=last)
        .flat_map(|e| (1..10).map(move |m| m as f64 * 10f64.powi(e)))
        .filter(|&v| v >= lo && v <= hi)
        .collect()
}

// ------------------------------------------------------------------ SVG text

/// A text's horizontal anchor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Anchor {
    Start,
    Middle,
    End,
}

impl Anchor {
    fn svg(self) -> &'static str {
        match self {
            Anchor::Start => "start",
            Anchor::Middle => "middle",
            Anchor::End => "end",
        }
    }
}

/// An axis-aligned box: left, top, right, bottom.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Rect {
    left: f64,
    top: f64,
    right: f64,
    bottom: f64,
}

impl Rect {
    fn overlaps(&self, other: &Rect, gap: f64) -> bool {
        self.left < other.right + gap
            && other.left < self.right + gap
            && self.top < other.bottom + gap
            && other.top < self.bottom + gap
    }

    fn inside(&self, outer: &Rect) -> bool {
        self.left >= outer.left
            && self.right <= outer.right
            && self.top >= outer.top
            && self.bottom <= outer.bottom
    }
}

fn text_width(text: &str, size: f64) -> f64 {
    LAYOUT_WIDTH_EM * size * text.chars().count() as f64
}

/// The box the layout reserves for `text` with its baseline at `y`.
fn text_box(text: &str, x: f64, y: f64, size: f64, anchor: Anchor) -> Rect {
    let width = text_width(text, size);
    let left = match anchor {
        Anchor::Start => x,
        Anchor::Middle => x - 0.5 * width,
        Anchor::End => x - width,
    };
    Rect {
        left,
        top: y - (TEXT_ASCENT_EM + 0.05) * size,
        right: left + width,
        bottom: y + (TEXT_DESCENT_EM + 0.05) * size,
    }
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// An SVG document under construction.
struct Svg {
    body: String,
}

impl Svg {
    fn new() -> Self {
        Svg {
            body: String::new(),
        }
    }

    fn text(&mut self, class: &str, text: &str, x: f64, y: f64, size: f64, anchor: Anchor) {
        let _ = writeln!(
            self.body,
            r#"<text class="{class}" x="{x:.1}" y="{y:.1}" font-size="{size}" text-anchor="{}">{}</text>"#,
            anchor.svg(),
            escape(text)
        );
    }

    /// Text rotated by −90° about its anchor (reads bottom to top).
    fn vertical_text(&mut self, class: &str, text: &str, x: f64, y: f64, size: f64) {
        let _ = writeln!(
            self.body,
            r#"<text class="{class}" x="{x:.1}" y="{y:.1}" font-size="{size}" text-anchor="middle" transform="rotate(-90 {x:.1} {y:.1})">{}</text>"#,
            escape(text)
        );
    }

    fn line(&mut self, a: (f64, f64), b: (f64, f64), colour: &str, width: f64) {
        let _ = writeln!(
            self.body,
            r#"<line x1="{:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="{colour}" stroke-width="{width}"/>"#,
            a.0, a.1, b.0, b.1
        );
    }

    fn rect(&mut self, r: Rect, fill: &str, stroke: Option<&str>) {
        let stroke = stroke.map_or(String::new(), |s| format!(r#" stroke="{s}""#));
        let _ = writeln!(
            self.body,
            r#"<rect x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="{fill}"{stroke}/>"#,
            r.left,
            r.top,
            r.right - r.left,
            r.bottom - r.top
        );
    }

    fn polyline(&mut self, points: &[(f64, f64)], style: &Style) {
        if points.len() < 2 {
            return;
        }
        let mut coordinates = String::new();
        for (x, y) in points {
            let _ = write!(coordinates, "{x:.1},{y:.1} ");
        }
        let dash = style
            .dash
            .map_or(String::new(), |d| format!(r#" stroke-dasharray="{d}""#));
        let _ = writeln!(
            self.body,
            r#"<polyline points="{}" fill="none" stroke="{}" stroke-width="{}" stroke-linejoin="round"{dash}/>"#,
            coordinates.trim_end(),
            style.colour,
            style.width
        );
    }

    fn marker(&mut self, marker: Marker, (x, y): (f64, f64), size: f64, colour: &str) {
        let s = size;
        let polygon = |body: &mut String, points: &[(f64, f64)]| {
            let mut text = String::new();
            for (px, py) in points {
                let _ = write!(text, "{:.1},{:.1} ", x + px, y + py);
            }
            let _ = writeln!(
                body,
                r#"<polygon points="{}" fill="{colour}"/>"#,
                text.trim_end()
            );
        };
        match marker {
            Marker::None => {}
            Marker::Circle => {
                let _ = writeln!(
                    self.body,
                    r#"<circle cx="{x:.1}" cy="{y:.1}" r="{:.1}" fill="{colour}"/>"#,
                    0.9 * s
                );
            }
            Marker::Square => polygon(
                &mut self.body,
                &[
                    (-0.8 * s, -0.8 * s),
                    (0.8 * s, -0.8 * s),
                    (0.8 * s, 0.8 * s),
                    (-0.8 * s, 0.8 * s),
                ],
            ),
            Marker::TriangleUp => polygon(
                &mut self.body,
                &[(0.0, -s * 1.1), (s, 0.8 * s), (-s, 0.8 * s)],
            ),
            Marker::TriangleDown => polygon(
                &mut self.body,
                &[(0.0, s * 1.1), (s, -0.8 * s), (-s, -0.8 * s)],
            ),
            Marker::Diamond => polygon(
                &mut self.body,
                &[(0.0, -1.2 * s), (s, 0.0), (0.0, 1.2 * s), (-s, 0.0)],
            ),
            Marker::Plus => {
                self.line((x - 1.2 * s, y), (x + 1.2 * s, y), colour, 1.6);
                self.line((x, y - 1.2 * s), (x, y + 1.2 * s), colour, 1.6);
            }
            Marker::Cross => {
                self.line((x - s, y - s), (x + s, y + s), colour, 1.6);
                self.line((x - s, y + s), (x + s, y - s), colour, 1.6);
            }
        }
    }

    fn write(self, path: &Path, width: f64, height: f64) -> Result<(), ReportError> {
        let (width, height) = (width.ceil(), height.ceil());
        let text = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{height}\" viewBox=\"0 0 {width} {height}\" font-family=\"sans-serif\">\n<rect x=\"0\" y=\"0\" width=\"{width}\" height=\"{height}\" fill=\"#FFFFFF\"/>\n{}</svg>\n",
            self.body
        );
        super::write_text(path, &text)
    }
}

// ------------------------------------------------------------------ axes

/// A linear or logarithmic map from data to pixels.
#[derive(Debug, Clone, Copy)]
struct Scale {
    lo: f64,
    hi: f64,
    log: bool,
    pixel_lo: f64,
    pixel_hi: f64,
}

impl Scale {
    fn map(&self, value: f64) -> f64 {
        let t = if self.log {
            (value.log10() - self.lo.log10()) / (self.hi.log10() - self.lo.log10())
        } else {
            (value - self.lo) / (self.hi - self.lo)
        };
        self.pixel_lo + t * (self.pixel_hi - self.pixel_lo)
    }

    fn ticks(&self, target: f64) -> Vec<Tick> {
        if self.log {
            log_ticks(self.lo, self.hi)
        } else {
            linear_ticks(self.lo.min(self.hi), self.lo.max(self.hi), target)
        }
    }
}

/// Chooses which tick labels to print: by priority, skipping any that would
/// overlap one already kept. Returns the kept ticks with their boxes.
fn thin_labels(ticks: &[Tick], place: impl Fn(&Tick) -> Rect, gap: f64) -> Vec<(Tick, Rect)> {
    let mut order: Vec<&Tick> = ticks.iter().collect();
    order.sort_by_key(|t| t.priority);
    let mut kept: Vec<(Tick, Rect)> = Vec::new();
    for tick in order {
        let rect = place(tick);
        if kept.iter().all(|(_, r)| !r.overlaps(&rect, gap)) {
            kept.push((tick.clone(), rect));
        }
    }
    kept
}

/// The data range of positive values on a log axis, padded a little.
fn log_range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        return None;
    }
    let pad = (0.05 * (hi / lo).log10()).max(0.04);
    Some((
        snap_log(lo / 10f64.powf(pad), f64::floor),
        snap_log(hi * 10f64.powf(pad), f64::ceil),
    ))
}

/// `value` rounded (by `round`, floor or ceil) to an integer multiple of its
/// decade, so that a log axis ends on a value it can label.
fn snap_log(value: f64, round: fn(f64) -> f64) -> f64 {
    let decade = 10f64.powf(value.log10().floor());
    let multiple = round(value / decade * (1.0 + 1e-12) - 2e-12).max(1.0);
    multiple * decade
}

/// Draws the frame, grid, ticks and tick labels of a plot area.
/// `x_labels` false draws x ticks without labels (a panel below shows them).
fn draw_axes(svg: &mut Svg, x: &Scale, y: &Scale, area: Rect, x_labels: bool) {
    // Grid.
    if y.log {
        for value in log_minor(y.lo, y.hi) {
            let py = y.map(value);
            svg.line((area.left, py), (area.right, py), "#EEEEEE", 1.0);
        }
    }
    let x_ticks = x.ticks(6.0);
    let y_ticks = y.ticks(5.0);
    for tick in &x_ticks {
        let px = x.map(tick.value);
        svg.line((px, area.top), (px, area.bottom), "#DDDDDD", 1.0);
        svg.line((px, area.bottom), (px, area.bottom + 4.0), "#000000", 1.0);
    }
    for tick in &y_ticks {
        let py = y.map(tick.value);
        svg.line((area.left, py), (area.right, py), "#DDDDDD", 1.0);
        svg.line((area.left - 4.0, py), (area.left, py), "#000000", 1.0);
    }
    svg.rect(area, "none", Some("#000000"));
    if x_labels {
        draw_x_tick_labels(svg, x, &x_ticks, area.bottom);
    }
    let right = area.left - 7.0;
    let centre = 0.5 * (TEXT_ASCENT_EM - TEXT_DESCENT_EM) * TICK_SIZE;
    let kept = thin_labels(
        &y_ticks,
        |t| {
            text_box(
                &t.label,
                right,
                y.map(t.value) + centre,
                TICK_SIZE,
                Anchor::End,
            )
        },
        1.0,
    );
    for (tick, _) in kept {
        svg.text(
            "tick-y",
            &tick.label,
            right,
            y.map(tick.value) + centre,
            TICK_SIZE,
            Anchor::End,
        );
    }
}

/// The x tick labels under an area whose bottom edge is at `bottom`,
/// thinned so that no two overlap.
fn draw_x_tick_labels(svg: &mut Svg, x: &Scale, ticks: &[Tick], bottom: f64) {
    let baseline = bottom + 6.0 + TEXT_ASCENT_EM * TICK_SIZE + 2.0;
    let place = |t: &Tick| {
        text_box(
            &t.label,
            x.map(t.value),
            baseline,
            TICK_SIZE,
            Anchor::Middle,
        )
    };
    for (tick, _) in thin_labels(ticks, place, 4.0) {
        svg.text(
            "tick-x",
            &tick.label,
            x.map(tick.value),
            baseline,
            TICK_SIZE,
            Anchor::Middle,
        );
    }
}

/// The widest tick label of a scale, px.
fn widest_label(scale: &Scale, target: f64) -> f64 {
    scale
        .ticks(target)
        .iter()
        .map(|t| text_width(&t.label, TICK_SIZE))
        .fold(0.0, f64::max)
}

/// Title and notes centred over the picture; returns the bottom of the text.
fn draw_heading(svg: &mut Svg, title: &str, notes: &[String], width: f64) -> f64 {
    let mut y = 10.0 + TEXT_ASCENT_EM * TITLE_SIZE;
    svg.text("title", title, 0.5 * width, y, TITLE_SIZE, Anchor::Middle);
    y += TEXT_DESCENT_EM * TITLE_SIZE;
    for note in notes {
        y += 4.0 + TEXT_ASCENT_EM * NOTE_SIZE;
        svg.text("note", note, 0.5 * width, y, NOTE_SIZE, Anchor::Middle);
        y += TEXT_DESCENT_EM * NOTE_SIZE;
    }
    y
}

fn heading_width(title: &str, notes: &[String]) -> f64 {
    notes
        .iter()
        .map(|n| text_width(n, NOTE_SIZE))
        .fold(text_width(title, TITLE_SIZE), f64::max)
        + 20.0
}

// ------------------------------------------------------------------ plots

/// The share of scenarios with every sphere visible at each x of a line
/// plot, drawn as a panel under it.
#[derive(Debug, Clone)]
pub struct Availability {
    /// (x, share in [0, 1]) at every value of the axis, visible or not.
    pub points: Vec<(f64, f64)>,
    /// What x is, for the note on values with nothing visible
    /// ("depth 200 mm").
    pub axis: String,
    /// The unit of x.
    pub unit: String,
    /// What the panel shows ("share of scenarios with every sphere visible").
    pub label: String,
    /// What a share of zero means, for the note ("nothing visible").
    pub empty: String,
}

/// A one-panel plot laid out: its heading drawn, the plot area, both
/// scales mapped onto it, and the page width (the y labels' width on the
/// left, the legend's on the right).
struct Panel {
    svg: Svg,
    area: Rect,
    x_scale: Scale,
    y_scale: Scale,
    width: f64,
}

/// Lays out a one-panel plot of `x` (linear) and `y` (`lo`, `hi`, log)
/// under `title` and `notes`, with room for `entries` in a legend.
fn single_panel(
    title: &str,
    notes: &[String],
    entries: &[Entry],
    (x_lo, x_hi): (f64, f64),
    (y_lo, y_hi, log): (f64, f64, bool),
) -> Panel {
    let mut y_scale = Scale {
        lo: y_lo,
        hi: y_hi,
        log,
        pixel_lo: 0.0,
        pixel_hi: 0.0,
    };
    let left = 16.0 + LABEL_SIZE + widest_label(&y_scale, 5.0) + 12.0;
    let width =
        (left + PLOT_WIDTH + 16.0 + legend_width(entries) + 8.0).max(heading_width(title, notes));
    let mut svg = Svg::new();
    let heading_bottom = draw_heading(&mut svg, title, notes, width);
    let area = Rect {
        left,
        top: heading_bottom + 14.0,
        right: left + PLOT_WIDTH,
        bottom: heading_bottom + 14.0 + PLOT_HEIGHT,
    };
    y_scale.pixel_lo = area.bottom;
    y_scale.pixel_hi = area.top;
    let x_scale = Scale {
        lo: x_lo,
        hi: x_hi,
        log: false,
        pixel_lo: area.left,
        pixel_hi: area.right,
    };
    Panel {
        svg,
        area,
        x_scale,
        y_scale,
        width,
    }
}

/// A line plot with a logarithmic y axis (errors span decades).
pub fn line_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> Result<(), ReportError> {
    line_plot_with_availability(path, title, x_label, y_label, series, None)
}

const PLOT_WIDTH: f64 = 600.0;
const PLOT_HEIGHT: f64 = 360.0;
const PANEL_HEIGHT: f64 = 70.0;

/// A line plot with a logarithmic y axis and, when given, a panel under it
/// with the availability along x; x values where nothing is visible are
/// shaded and named in a note under the title.
pub fn line_plot_with_availability(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    availability: Option<&Availability>,
) -> Result<(), ReportError> {
    let drawn: Vec<(&Series, Vec<(f64, f64)>)> = series
        .iter()
        .map(|s| {
            let points = s
                .points
                .iter()
                .copied()
                .filter(|&(x, y)| x.is_finite() && y.is_finite() && y > 0.0)
                .collect();
            (s, points)
        })
        .collect();
    let Some((y_lo, y_hi)) = log_range(drawn.iter().flat_map(|(_, p)| p.iter().map(|q| q.1)))
    else {
        return Ok(());
    };
    let xs = drawn
        .iter()
        .flat_map(|(_, p)| p.iter().map(|q| q.0))
        .chain(
            availability
                .iter()
                .flat_map(|a| a.points.iter().map(|p| p.0)),
        )
        .filter(|x| x.is_finite());
    let (mut x_lo, mut x_hi) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
        (lo.min(x), hi.max(x))
    });
    if x_lo == x_hi {
        x_lo -= 1.0;
        x_hi += 1.0;
    }
    let notes: Vec<String> = availability
        .and_then(availability::empty_note)
        .into_iter()
        .collect();
    let styles = styles_for(series.iter().map(|s| (s.name.as_str(), s.dashed)));
    let entries: Vec<Entry> = series
        .iter()
        .zip(&styles)
        .zip(&drawn)
        .filter(|(_, (_, p))| !p.is_empty())
        .map(|((s, style), (_, p))| Entry {
            name: &s.name,
            style: *style,
            // A single point has no line: its legend shows the marker only.
            line: p.len() > 1 || style.marker == Marker::None,
        })
        .collect();

    let Panel {
        mut svg,
        area,
        x_scale,
        y_scale,
        width,
    } = single_panel(title, &notes, &entries, (x_lo, x_hi), (y_lo, y_hi, true));
    let spans = availability.map_or(Vec::new(), |a| availability::empty_spans(a, &x_scale, area));
    availability::shade(&mut svg, &spans, area.top, area.bottom);
    draw_axes(&mut svg, &x_scale, &y_scale, area, availability.is_none());
    for ((_, points), style) in drawn.iter().zip(&styles) {
        let pixels: Vec<(f64, f64)> = points
            .iter()
            .map(|&(x, y)| (x_scale.map(x), y_scale.map(y)))
            .collect();
        svg.polyline(&pixels, style);
        // A model line with one point would vanish without a marker.
        let marker = match (style.marker, pixels.len()) {
            (Marker::None, 1) => Marker::Circle,
            (marker, _) => marker,
        };
        for &p in &pixels {
            svg.marker(marker, p, 3.0, style.colour);
        }
    }
    svg.vertical_text(
        "axis-label",
        y_label,
        10.0 + TEXT_ASCENT_EM * LABEL_SIZE,
        0.5 * (area.top + area.bottom),
        LABEL_SIZE,
    );
    let mut bottom = area.bottom;
    if let Some(a) = availability {
        bottom = availability::draw_panel(&mut svg, a, &x_scale, area, &spans);
    }
    let x_label_y = bottom + 6.0 + TICK_SIZE + 8.0 + TEXT_ASCENT_EM * LABEL_SIZE;
    svg.text(
        "axis-label",
        x_label,
        0.5 * (area.left + area.right),
        x_label_y,
        LABEL_SIZE,
        Anchor::Middle,
    );
    let legend_bottom = draw_legend(&mut svg, &entries, area.right + 16.0, area.top);
    let height = (x_label_y + TEXT_DESCENT_EM * LABEL_SIZE + 10.0).max(legend_bottom + 10.0);
    svg.write(path, width, height)
}

/// Predicted against measured, log–log, with the line y = x.
pub fn predicted_vs_measured(
    path: &Path,
    title: &str,
    series: &[(String, Vec<(f64, f64)>)],
) -> Result<(), ReportError> {
    let good = |&&(a, b): &&(f64, f64)| a > 0.0 && b > 0.0 && a.is_finite() && b.is_finite();
    let Some((lo, hi)) = log_range(
        series
            .iter()
            .flat_map(|(_, p)| p.iter().filter(good).flat_map(|&(a, b)| [a, b])),
    ) else {
        return Ok(());
    };
    let reference = Style {
        colour: "#999999",
        dash: None,
        marker: Marker::None,
        width: 1.2,
    };
    // One panel, or one per solver group when the series are too many to
    // tell apart in one.
    type Named = (String, Vec<(f64, f64)>);
    let groups: Vec<Vec<&Named>> = if series.len() < MAX_SERIES_PER_PANEL {
        vec![series.iter().collect()]
    } else {
        (0..SOLVER_GROUPS.len())
            .map(|g| {
                series
                    .iter()
                    .filter(|(n, _)| solver_group(n) == g)
                    .collect::<Vec<_>>()
            })
            .filter(|group| !group.is_empty())
            .collect()
    };
    let side = 420.0;
    let mut y_scale = Scale {
        lo,
        hi,
        log: true,
        pixel_lo: 0.0,
        pixel_hi: 0.0,
    };
    let left = 16.0 + LABEL_SIZE + widest_label(&y_scale, 5.0) + 12.0;
    let styled: Vec<(Vec<Style>, Vec<Entry>)> = groups
        .iter()
        .map(|group| {
            let styles = styles_for(group.iter().map(|(n, _)| (n.as_str(), false)));
            let mut entries = vec![Entry {
                name: "measured = predicted",
                style: reference,
                line: true,
            }];
            entries.extend(group.iter().zip(&styles).map(|((name, _), style)| Entry {
                name,
                style: *style,
                line: false,
            }));
            (styles, entries)
        })
        .collect();
    let panel_width = |entries: &[Entry]| left + side + 16.0 + legend_width(entries) + 8.0;
    let width = styled
        .iter()
        .map(|(_, e)| panel_width(e))
        .sum::<f64>()
        .max(heading_width(title, &[]));
    let mut svg = Svg::new();
    let top = draw_heading(&mut svg, title, &[], width) + 14.0;
    let mut panel_left = 0.0;
    let mut height: f64 = 0.0;
    for (group, (styles, entries)) in groups.iter().zip(&styled) {
        let area = Rect {
            left: panel_left + left,
            top,
            right: panel_left + left + side,
            bottom: top + side,
        };
        y_scale.pixel_lo = area.bottom;
        y_scale.pixel_hi = area.top;
        let x_scale = Scale {
            lo,
            hi,
            log: true,
            pixel_lo: area.left,
            pixel_hi: area.right,
        };
        draw_axes(&mut svg, &x_scale, &y_scale, area, true);
        svg.polyline(
            &[
                (x_scale.map(lo), y_scale.map(lo)),
                (x_scale.map(hi), y_scale.map(hi)),
            ],
            &reference,
        );
        for ((_, points), style) in group.iter().zip(styles) {
            for &(a, b) in points.iter().filter(good) {
                svg.marker(
                    style.marker,
                    (x_scale.map(a), y_scale.map(b)),
                    3.0,
                    style.colour,
                );
            }
        }
        svg.vertical_text(
            "axis-label",
            "measured RMS rotation error (°)",
            panel_left + 10.0 + TEXT_ASCENT_EM * LABEL_SIZE,
            0.5 * (area.top + area.bottom),
            LABEL_SIZE,
        );
        let x_label_y = area.bottom + 6.0 + TICK_SIZE + 8.0 + TEXT_ASCENT_EM * LABEL_SIZE;
        svg.text(
            "axis-label",
            "predicted RMS rotation error (°)",
            0.5 * (area.left + area.right),
            x_label_y,
            LABEL_SIZE,
            Anchor::Middle,
        );
        let legend_bottom = draw_legend(&mut svg, entries, area.right + 16.0, area.top);
        height = height
            .max(x_label_y + TEXT_DESCENT_EM * LABEL_SIZE + 10.0)
            .max(legend_bottom + 10.0);
        panel_left += panel_width(entries);
    }
    svg.write(path, width, height)
}

/// A leader line: from a circle's edge to its label.
type Leader = ((f64, f64), (f64, f64));

/// Places a label beside each circle (centre, radius, text), clear of the
/// other labels and, where possible, of every circle, inside `bounds`:
/// beside its own circle first, then further out with a leader line.
/// Returns, per label, its box and the end of its leader line, if any.
fn place_labels(
    circles: &[((f64, f64), f64, String)],
    bounds: Rect,
    avoid: &[Rect],
) -> Vec<(Rect, Option<Leader>)> {
    const D: f64 = std::f64::consts::FRAC_1_SQRT_2;
    const DIRECTIONS: [(f64, f64); 8] = [
        (D, -D),
        (1.0, 0.0),
        (D, D),
        (-D, -D),
        (-1.0, 0.0),
        (-D, D),
        (0.0, -1.0),
        (0.0, 1.0),
    ];
    const RINGS: [f64; 6] = [3.0, 12.0, 22.0, 34.0, 48.0, 64.0];
    let circle_hits = |rect: &Rect| -> bool {
        circles.iter().any(|&((cx, cy), r, _)| {
            let nx = cx.clamp(rect.left, rect.right);
            let ny = cy.clamp(rect.top, rect.bottom);
            (nx - cx).powi(2) + (ny - cy).powi(2) < r * r
        })
    };
    let mut placed: Vec<Rect> = Vec::new();
    let mut out = Vec::new();
    for &((cx, cy), r, ref text) in circles {
        let width = text_width(text, POINT_LABEL_SIZE);
        let height = (TEXT_ASCENT_EM + TEXT_DESCENT_EM + 0.1) * POINT_LABEL_SIZE;
        let candidate = |ring: f64, (dx, dy): (f64, f64)| -> (Rect, (f64, f64), (f64, f64)) {
            let edge = (cx + dx * r, cy + dy * r);
            let near = (cx + dx * (r + ring), cy + dy * (r + ring));
            // The box's corner or side nearest the circle sits at `near`.
            let left = near.0
                + if dx > 0.1 {
                    0.0
                } else if dx < -0.1 {
                    -width
                } else {
                    -0.5 * width
                };
            let top = near.1
                + if dy > 0.1 {
                    0.0
                } else if dy < -0.1 {
                    -height
                } else {
                    -0.5 * height
                };
            (
                Rect {
                    left,
                    top,
                    right: left + width,
                    bottom: top + height,
                },
                edge,
                near,
            )
        };
        let free = |rect: &Rect, strict: bool| {
            rect.inside(&bounds)
                && placed.iter().all(|p| !p.overlaps(rect, 1.0))
                && avoid.iter().all(|p| !p.overlaps(rect, 1.0))
                && !(strict && circle_hits(rect))
        };
        let mut choice = None;
        'search: for strict in [true, false] {
            for ring in RINGS {
                for direction in DIRECTIONS {
                    let (rect, edge, near) = candidate(ring, direction);
                    if free(&rect, strict) {
                        choice = Some((rect, (ring > RINGS[0]).then_some((edge, near))));
                        break 'search;
                    }
                }
            }
        }
        // Nowhere free: beside the circle, overlapping (never seen in practice).
        let (rect, leader) = choice.unwrap_or_else(|| (candidate(RINGS[0], DIRECTIONS[0]).0, None));
        placed.push(rect);
        out.push((rect, leader));
    }
    out
}

/// Three orthographic views of a marker (front: x–y, side: z–y, top: x–z),
/// spheres drawn to scale with their names.
pub fn orthographic_views(
    path: &Path,
    title: &str,
    points: &[(String, Vector3<f64>)],
    sphere_diameter_mm: f64,
) -> Result<(), ReportError> {
    let radius = 0.5 * sphere_diameter_mm;
    let extent = points
        .iter()
        .flat_map(|(_, p)| p.iter().map(|v| v.abs()))
        .fold(0.0f64, f64::max)
        + radius
        + 8.0;
    let views: [(&str, usize, usize); 3] = [
        ("front (x right, y down)", 0, 1),
        ("side (z right, y down)", 2, 1),
        ("top (x right, z down)", 0, 2),
    ];
    let side = 300.0;
    let probe = Scale {
        lo: -extent,
        hi: extent,
        log: false,
        pixel_lo: 0.0,
        pixel_hi: 1.0,
    };
    let left_margin = 10.0 + widest_label(&probe, 5.0) + 10.0;
    let panel_width = left_margin + side + 16.0;
    let width = (3.0 * panel_width + 10.0).max(heading_width(title, &[]));
    let mut svg = Svg::new();
    let heading_bottom = draw_heading(&mut svg, title, &[], width);
    let mut bottom: f64 = 0.0;
    for (k, (name, a, b)) in views.into_iter().enumerate() {
        let panel_left = 10.0 + k as f64 * panel_width;
        let caption_y = heading_bottom + 10.0 + TEXT_ASCENT_EM * LABEL_SIZE;
        let area = Rect {
            left: panel_left + left_margin,
            top: caption_y + 10.0,
            right: panel_left + left_margin + side,
            bottom: caption_y + 10.0 + side,
        };
        svg.text(
            "caption",
            name,
            0.5 * (area.left + area.right),
            caption_y,
            LABEL_SIZE,
            Anchor::Middle,
        );
        let x_scale = Scale {
            lo: -extent,
            hi: extent,
            log: false,
            pixel_lo: area.left,
            pixel_hi: area.right,
        };
        // y down: −extent at the top.
        let y_scale = Scale {
            lo: -extent,
            hi: extent,
            log: false,
            pixel_lo: area.top,
            pixel_hi: area.bottom,
        };
        draw_axes(&mut svg, &x_scale, &y_scale, area, true);
        let pixels_per_mm = side / (2.0 * extent);
        let r = (radius * pixels_per_mm).max(1.0);
        // Far spheres first, so nearer ones are drawn on top (looking along
        // +depth, the axis not shown).
        let depth_axis = 3 - a - b;
        let mut order: Vec<usize> = (0..points.len()).collect();
        order.sort_by(|&i, &j| points[j].1[depth_axis].total_cmp(&points[i].1[depth_axis]));
        for &index in &order {
            let p = &points[index].1;
            let _ = writeln!(
                svg.body,
                r##"<circle cx="{:.1}" cy="{:.1}" r="{r:.1}" fill="#C8C8D2" stroke="#000000" stroke-width="1"/>"##,
                x_scale.map(p[a]),
                y_scale.map(p[b])
            );
        }
        // Labels nearest the viewer first, so they get the closest places.
        let circles: Vec<((f64, f64), f64, String)> = order
            .iter()
            .rev()
            .map(|&i| {
                let p = &points[i].1;
                (
                    (x_scale.map(p[a]), y_scale.map(p[b])),
                    r,
                    points[i].0.clone(),
                )
            })
            .collect();
        let placed = place_labels(&circles, area, &[]);
        for (_, leader) in &placed {
            if let Some((from, to)) = leader {
                svg.line(*from, *to, "#555555", 0.8);
            }
        }
        for ((_, _, text), (rect, _)) in circles.iter().zip(&placed) {
            svg.text(
                "point-label",
                text,
                rect.left,
                rect.top + (TEXT_ASCENT_EM + 0.05) * POINT_LABEL_SIZE,
                POINT_LABEL_SIZE,
                Anchor::Start,
            );
        }
        let x_label_y = area.bottom + 6.0 + TICK_SIZE + 8.0 + TEXT_ASCENT_EM * LABEL_SIZE;
        // Image convention: the downward axis grows downward, so the top
        // of each view reads negative.
        svg.text(
            "axis-label",
            &format!("mm on both axes; {} grows downward", ["x", "y", "z"][b]),
            0.5 * (area.left + area.right),
            x_label_y,
            LABEL_SIZE,
            Anchor::Middle,
        );
        bottom = bottom.max(x_label_y + TEXT_DESCENT_EM * LABEL_SIZE + 10.0);
    }
    svg.write(path, width, bottom)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(ticks: &[Tick]) -> Vec<&str> {
        ticks.iter().map(|t| t.label.as_str()).collect()
    }

    #[test]
    fn linear_ticks_are_nice_and_free_of_float_noise() {
        assert_eq!(
            labels(&linear_ticks(0.0, 1.0, 5.0)),
            ["0.0", "0.2", "0.4", "0.6", "0.8", "1.0"]
        );
        assert_eq!(
            labels(&linear_ticks(0.1, 0.75, 6.0)),
            ["0.1", "0.2", "0.3", "0.4", "0.5", "0.6", "0.7"]
        );
        assert_eq!(
            labels(&linear_ticks(400.0, 1000.0, 6.0)),
            ["400", "500", "600", "700", "800", "900", "1000"]
        );
        assert_eq!(
            labels(&linear_ticks(-63.0, 63.0, 5.0)),
            ["-60", "-40", "-20", "0", "20", "40", "60"]
        );
    }

    #[test]
    fn log_ticks_label_below_one_and_fill_short_spans() {
        // Five decades: decades only.
        assert_eq!(
            labels(&log_ticks(0.002, 300.0)),
            ["0.01", "0.1", "1", "10", "100"]
        );
        // Under a decade: every multiple.
        assert_eq!(
            labels(&log_ticks(0.08, 0.55)),
            ["0.08", "0.09", "0.1", "0.2", "0.3", "0.4", "0.5"]
        );
        // Three decades: 1-2-5.
        assert_eq!(
            labels(&log_ticks(1.0, 2000.0)),
            ["1", "2", "5", "10", "20", "50", "100", "200", "500", "1000", "2000"]
        );
        // Two decades: 1-2-5.
        assert_eq!(
            labels(&log_ticks(0.3, 40.0)),
            ["0.5", "1", "2", "5", "10", "20"]
        );
        // A short span falls back to linear steps.
        assert_eq!(
            labels(&log_ticks(0.21, 0.28,)),
            ["0.22", "0.24", "0.26", "0.28"]
        );
    }

    #[test]
    fn log_ranges_end_on_a_labelled_value() {
        let (lo, hi) = log_range([0.113, 0.32].into_iter()).unwrap();
        assert!(
            (lo - 0.1).abs() < 1e-12 && (hi - 0.4).abs() < 1e-12,
            "{lo} {hi}"
        );
        let (lo, hi) = log_range([3.0, 1450.0].into_iter()).unwrap();
        assert!(
            (lo - 2.0).abs() < 1e-12 && (hi - 2000.0).abs() < 1e-9,
            "{lo} {hi}"
        );
    }

    #[test]
    fn every_solver_has_its_own_colour_and_shape() {
        for (i, (_, a)) in SOLVER_STYLES.iter().enumerate() {
            for (_, b) in &SOLVER_STYLES[i + 1..] {
                assert_ne!(a.colour, b.colour);
            }
            assert!(MODEL_STYLES.iter().all(|(_, m)| m.colour != a.colour));
        }
        let names: Vec<&str> = crate::pnp::Solver::ALL.iter().map(|s| s.name()).collect();
        for name in &names {
            assert!(series_style(name, false).is_some(), "{name} has no style");
        }
        let styles = styles_for(
            ["x", "y", "z", "w", "v", "epnp"]
                .iter()
                .map(|n| (*n, false)),
        );
        for (i, a) in styles.iter().enumerate() {
            assert!(styles[i + 1..].iter().all(|b| b != a));
        }
    }

    #[test]
    fn labels_of_spheres_on_one_line_of_sight_do_not_overlap() {
        let circles: Vec<((f64, f64), f64, String)> = (0..4)
            .map(|k| ((100.0 + 2.0 * k as f64, 100.0), 8.0, format!("P{k}")))
            .collect();
        let bounds = Rect {
            left: 0.0,
            top: 0.0,
            right: 300.0,
            bottom: 300.0,
        };
        let placed = place_labels(&circles, bounds, &[]);
        for (i, (a, _)) in placed.iter().enumerate() {
            assert!(a.inside(&bounds));
            for (b, _) in &placed[i + 1..] {
                assert!(!a.overlaps(b, 0.0), "{a:?} overlaps {b:?}");
            }
        }
    }
}
