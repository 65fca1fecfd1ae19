//! A matrix of heatmaps on one SVG page: one panel for every pair of axes
//! (the lower triangle: row `y`, column `x < y`), all coloured on one
//! scale by the viridis map (perceptually uniform, sequential, readable
//! with red–green colour blindness and in grey), with one colour bar.
//! Cells with no value are drawn in light grey with a diagonal stroke.
//! Written as plain SVG text, as [`super::plots`] is.

use super::{write_text, ReportError};
use std::fmt::Write as _;
use std::path::Path;

/// Viridis at eleven even stops (matplotlib's map, sampled at 0, 0.1, …,
/// 1); colours in between are interpolated linearly in sRGB.
pub const VIRIDIS: [[u8; 3]; 11] = [
    [68, 1, 84],
    [72, 36, 117],
    [65, 68, 135],
    [53, 95, 141],
    [42, 120, 142],
    [33, 145, 140],
    [34, 168, 132],
    [68, 191, 112],
    [122, 209, 81],
    [189, 223, 38],
    [253, 231, 37],
];

/// Fill of a cell without a value.
pub const EMPTY_FILL: &str = "#e6e6e6";

const PANEL_PX: f64 = 150.0;
const GAP_PX: f64 = 70.0;
const MARGIN_PX: f64 = 24.0;
const TITLE_PX: f64 = 48.0;
const BAR_WIDTH_PX: f64 = 18.0;
const BAR_ROOM_PX: f64 = 110.0;
const FONT_PX: f64 = 11.0;

/// One axis of the matrix.
#[derive(Debug, Clone, PartialEq)]
pub struct HeatmapAxis {
    /// Label, with its unit ("tilt (deg)").
    pub label: String,
    /// The values (bin centres), in order.
    pub values: Vec<f64>,
}

/// One panel: the values of the cells of axis `x` against axis `y`.
#[derive(Debug, Clone, PartialEq)]
pub struct HeatmapPanel {
    /// Index of the horizontal axis.
    pub x: usize,
    /// Index of the vertical axis (greater than `x`).
    pub y: usize,
    /// `cells[row][column]`: row along `y`, column along `x`.
    pub cells: Vec<Vec<Option<f64>>>,
}

/// A page of heatmaps.
#[derive(Debug, Clone, PartialEq)]
pub struct HeatmapMatrix {
    /// The page's title.
    pub title: String,
    /// What the colour means, with its unit.
    pub quantity: String,
    /// The axes.
    pub axes: Vec<HeatmapAxis>,
    /// The panels.
    pub panels: Vec<HeatmapPanel>,
}

/// The viridis colour at `t` ∈ [0, 1] (clamped), as `#rrggbb`.
pub fn viridis(t: f64) -> String {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let scaled = t * (VIRIDIS.len() - 1) as f64;
    let low = (scaled.floor() as usize).min(VIRIDIS.len() - 2);
    let f = scaled - low as f64;
    let [r, g, b] = [0, 1, 2].map(|k| {
        let (a, c) = (f64::from(VIRIDIS[low][k]), f64::from(VIRIDIS[low + 1][k]));
        (a + f * (c - a)).round() as u8
    });
    format!("#{r:02x}{g:02x}{b:02x}")
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// A tick or scale label: three significant digits.
fn short(value: f64) -> String {
    super::significant(Some(value), 3)
}

/// The page as SVG text.
pub fn heatmap_matrix_svg(matrix: &HeatmapMatrix) -> String {
    let grid = matrix.axes.len().saturating_sub(1).max(1) as f64;
    let note = format!(
        "colour: {} (one scale for every panel; grey: no visible viewpoint)",
        matrix.quantity
    );
    // Wide enough for the title and the note (0.64 font sizes a character,
    // as the plots reserve).
    let text_width = (matrix.title.chars().count() as f64 * 15.0)
        .max(note.chars().count() as f64 * FONT_PX)
        * 0.64;
    let width = (MARGIN_PX * 2.0 + grid * (PANEL_PX + GAP_PX) + BAR_ROOM_PX)
        .max(MARGIN_PX * 2.0 + text_width);
    let height = TITLE_PX + MARGIN_PX + grid * (PANEL_PX + GAP_PX);
    let values = matrix
        .panels
        .iter()
        .flat_map(|p| p.cells.iter().flatten().flatten().copied())
        .filter(|v| v.is_finite());
    let (low, high) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    let span = if high > low { high - low } else { 1.0 };
    let mut svg = String::new();
    let _ = writeln!(
        svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0}" height="{height:.0}" viewBox="0 0 {width:.0} {height:.0}" font-family="sans-serif" font-size="{FONT_PX}">"#
    );
    let _ = writeln!(
        svg,
        r#"<rect width="100%" height="100%" fill="white"/><text x="{MARGIN_PX}" y="22" font-size="15">{}</text><text x="{MARGIN_PX}" y="40" font-size="{FONT_PX}">{}</text>"#,
        escape(&matrix.title),
        escape(&note)
    );
    for panel in &matrix.panels {
        let (column, row) = (panel.x as f64, (panel.y - 1) as f64);
        let left = MARGIN_PX + GAP_PX + column * (PANEL_PX + GAP_PX);
        let top = TITLE_PX + MARGIN_PX + row * (PANEL_PX + GAP_PX);
        let rows = panel.cells.len().max(1);
        let (cell_h, cell_w) = (
            PANEL_PX / rows as f64,
            PANEL_PX / panel.cells.first().map_or(1, Vec::len).max(1) as f64,
        );
        for (r, cells) in panel.cells.iter().enumerate() {
            // Row 0 (the smallest y) at the bottom, as on a plot.
            let y = top + PANEL_PX - (r + 1) as f64 * cell_h;
            for (c, value) in cells.iter().enumerate() {
                let x = left + c as f64 * cell_w;
                match value.filter(|v| v.is_finite()) {
                    Some(v) => {
                        let _ = writeln!(
                            svg,
                            r#"<rect x="{x:.2}" y="{y:.2}" width="{cell_w:.2}" height="{cell_h:.2}" fill="{}"><title>{}</title></rect>"#,
                            viridis((v - low) / span),
                            short(v)
                        );
                    }
                    None => {
                        let _ = writeln!(
                            svg,
                            r##"<rect x="{x:.2}" y="{y:.2}" width="{cell_w:.2}" height="{cell_h:.2}" fill="{EMPTY_FILL}"/><line x1="{x:.2}" y1="{:.2}" x2="{:.2}" y2="{y:.2}" stroke="#b0b0b0" stroke-width="0.6"/>"##,
                            y + cell_h,
                            x + cell_w
                        );
                    }
                }
            }
        }
        let _ = writeln!(
            svg,
            r#"<rect x="{left:.2}" y="{top:.2}" width="{PANEL_PX}" height="{PANEL_PX}" fill="none" stroke="black" stroke-width="0.8"/>"#
        );
        let (x_axis, y_axis) = (&matrix.axes[panel.x], &matrix.axes[panel.y]);
        let ends = |axis: &HeatmapAxis| {
            (
                axis.values.first().copied().map_or(String::new(), short),
                axis.values.last().copied().map_or(String::new(), short),
            )
        };
        let (x_first, x_last) = ends(x_axis);
        let (y_first, y_last) = ends(y_axis);
        let bottom = top + PANEL_PX;
        let (label_x, label_y) = (left - 56.0, top + 0.5 * PANEL_PX);
        let _ = writeln!(
            svg,
            r#"<text x="{left:.2}" y="{:.2}" font-size="{FONT_PX}">{}</text><text x="{:.2}" y="{:.2}" font-size="{FONT_PX}" text-anchor="end">{}</text><text x="{:.2}" y="{:.2}" font-size="{FONT_PX}" text-anchor="middle">{}</text>"#,
            bottom + 13.0,
            escape(&x_first),
            left + PANEL_PX,
            bottom + 13.0,
            escape(&x_last),
            left + 0.5 * PANEL_PX,
            bottom + 27.0,
            escape(&x_axis.label)
        );
        let _ = writeln!(
            svg,
            r#"<text x="{:.2}" y="{bottom:.2}" font-size="{FONT_PX}" text-anchor="end">{}</text><text x="{:.2}" y="{:.2}" font-size="{FONT_PX}" text-anchor="end">{}</text><text x="{label_x:.2}" y="{label_y:.2}" font-size="{FONT_PX}" transform="rotate(-90 {label_x:.2} {label_y:.2})" text-anchor="middle">{}</text>"#,
            left - 3.0,
            escape(&y_first),
            left - 3.0,
            top + FONT_PX,
            escape(&y_last),
            escape(&y_axis.label)
        );
    }
    if low.is_finite() {
        let left = width - BAR_ROOM_PX + 10.0;
        let top = TITLE_PX + MARGIN_PX;
        let bar_height = (grid * (PANEL_PX + GAP_PX) - GAP_PX).max(PANEL_PX);
        let steps = 64;
        for k in 0..steps {
            let t = k as f64 / (steps - 1) as f64;
            let y = top + bar_height * (1.0 - (k + 1) as f64 / steps as f64);
            let _ = writeln!(
                svg,
                r#"<rect x="{left:.2}" y="{y:.2}" width="{BAR_WIDTH_PX}" height="{:.2}" fill="{}"/>"#,
                bar_height / steps as f64 + 0.5,
                viridis(t)
            );
        }
        for (t, value) in [(0.0, low), (0.5, 0.5 * (low + high)), (1.0, high)] {
            let _ = writeln!(
                svg,
                r#"<text x="{:.2}" y="{:.2}" font-size="{FONT_PX}">{}</text>"#,
                left + BAR_WIDTH_PX + 4.0,
                top + bar_height * (1.0 - t) + 4.0,
                escape(&short(value))
            );
        }
    }
    svg.push_str("</svg>\n");
    svg
}

/// Writes the page to `path`.
pub fn heatmap_matrix(path: &Path, matrix: &HeatmapMatrix) -> Result<(), ReportError> {
    write_text(path, &heatmap_matrix_svg(matrix))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn matrix(axes: usize) -> HeatmapMatrix {
        let axis = |k: usize| HeatmapAxis {
            label: format!("axis {k}"),
            values: vec![0.0, 1.0, 2.0],
        };
        let mut panels = Vec::new();
        for y in 0..axes {
            for x in 0..y {
                panels.push(HeatmapPanel {
                    x,
                    y,
                    cells: (0..3)
                        .map(|r| {
                            (0..3)
                                .map(|c| (r + c != 4).then_some((x + y + r + c) as f64))
                                .collect()
                        })
                        .collect(),
                });
            }
        }
        HeatmapMatrix {
            title: "t".into(),
            quantity: "q (°)".into(),
            axes: (0..axes).map(axis).collect(),
            panels,
        }
    }

    #[test]
    fn six_axes_give_fifteen_panels_on_one_viridis_scale() {
        let svg = heatmap_matrix_svg(&matrix(6));
        let outlines = svg.matches(r#"fill="none" stroke="black""#).count();
        assert_eq!(outlines, 15);
        // Every filled cell and the bar use viridis colours or the empty
        // grey; nothing red or green-only.
        let palette: Vec<String> = (0..=1000).map(|k| viridis(k as f64 / 1000.0)).collect();
        for fill in svg.split(r#"fill=""#).skip(1) {
            let colour = &fill[..fill.find('"').unwrap()];
            assert!(
                colour == "white"
                    || colour == "none"
                    || colour == EMPTY_FILL
                    || palette.iter().any(|p| p == colour),
                "{colour}"
            );
        }
        // The extremes of the one scale appear: the smallest and largest
        // cell values (0 and 5 + 4 − 1 = 8 … here 0 and 12 over all panels).
        assert!(svg.contains(&viridis(0.0)) && svg.contains(&viridis(1.0)));
        assert!(svg.contains(EMPTY_FILL));
    }

    #[test]
    fn viridis_runs_from_dark_purple_to_yellow_and_darkens_monotonically() {
        assert_eq!(viridis(0.0), "#440154");
        assert_eq!(viridis(1.0), "#fde725");
        let luminance = |hex: &str| {
            let v =
                |k: usize| f64::from(u8::from_str_radix(&hex[1 + 2 * k..3 + 2 * k], 16).unwrap());
            0.2126 * v(0) + 0.7152 * v(1) + 0.0722 * v(2)
        };
        let mut last = -1.0;
        for k in 0..=100 {
            let l = luminance(&viridis(k as f64 / 100.0));
            assert!(l > last, "{k}: {l} after {last}");
            last = l;
        }
    }
}
