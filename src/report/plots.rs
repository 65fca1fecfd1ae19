//! SVG plots drawn with plotters' SVG backend (no system fonts needed: text
//! is written as SVG `<text>`).

use super::ReportError;
use nalgebra::Vector3;
use plotters::prelude::*;
use std::path::Path;

/// One line of a line plot.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend entry.
    pub name: String,
    /// Points, in x order.
    pub points: Vec<(f64, f64)>,
    /// Draw dashed (used for model predictions).
    pub dashed: bool,
}

const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

fn colour(index: usize) -> RGBColor {
    PALETTE[index % PALETTE.len()]
}

fn dashes(points: &[(f64, f64)], chart_dash_fraction: f64) -> Vec<Vec<(f64, f64)>> {
    // Split each segment into short dashes (in data space, linear in x).
    let mut out = Vec::new();
    for pair in points.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let pieces = 8;
        for k in 0..pieces {
            let t0 = k as f64 / pieces as f64;
            let t1 = t0 + chart_dash_fraction / pieces as f64;
            let lerp = |t: f64| (a.0 + (b.0 - a.0) * t, a.1 * (b.1 / a.1).powf(t));
            out.push(vec![lerp(t0), lerp(t1)]);
        }
    }
    out
}

/// A line plot with a logarithmic y axis (errors span decades).
pub fn line_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> Result<(), ReportError> {
    let finite = |v: f64| v.is_finite() && v > 0.0;
    let all: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.points.iter().copied())
        .filter(|&(x, y)| x.is_finite() && finite(y))
        .collect();
    if all.is_empty() {
        return Ok(());
    }
    let (mut x_min, mut x_max) = all
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.0), hi.max(p.0))
        });
    if x_min == x_max {
        x_min -= 1.0;
        x_max += 1.0;
    }
    let (y_min, y_max) = all
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.1), hi.max(p.1))
        });
    let (y_min, y_max) = (y_min / 1.5, y_max * 1.5);
    let draw = |svg: &mut String| -> Result<(), Box<dyn std::error::Error>> {
        let root = SVGBackend::with_string(svg, (800, 500)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(x_min..x_max, (y_min..y_max).log_scale())?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .draw()?;
        for (index, s) in series.iter().enumerate() {
            let points: Vec<(f64, f64)> = s
                .points
                .iter()
                .copied()
                .filter(|&(_, y)| finite(y))
                .collect();
            let style = ShapeStyle::from(&colour(index)).stroke_width(2);
            if s.dashed {
                for dash in dashes(&points, 0.6) {
                    chart.draw_series(LineSeries::new(dash, style))?;
                }
                chart
                    .draw_series(std::iter::empty::<PathElement<(f64, f64)>>())?
                    .label(&s.name)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 8, y)], style));
            } else {
                chart
                    .draw_series(LineSeries::new(points.clone(), style))?
                    .label(&s.name)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
                chart.draw_series(points.iter().map(|&p| Circle::new(p, 2, style.filled())))?;
            }
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
        root.present()?;
        Ok(())
    };
    let mut svg = String::new();
    draw(&mut svg).map_err(|e| ReportError::write(path, e))?;
    super::write_text(path, &svg)
}

/// Predicted against measured, log–log, with the line y = x.
pub fn predicted_vs_measured(
    path: &Path,
    title: &str,
    series: &[(String, Vec<(f64, f64)>)],
) -> Result<(), ReportError> {
    let values: Vec<f64> = series
        .iter()
        .flat_map(|(_, p)| p.iter().flat_map(|&(a, b)| [a, b]))
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    if values.is_empty() {
        return Ok(());
    }
    let lo = values.iter().copied().fold(f64::INFINITY, f64::min) / 1.5;
    let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max) * 1.5;
    let draw = |svg: &mut String| -> Result<(), Box<dyn std::error::Error>> {
        let root = SVGBackend::with_string(svg, (640, 600)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d((lo..hi).log_scale(), (lo..hi).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("predicted RMS rotation error (°)")
            .y_desc("measured RMS rotation error (°)")
            .draw()?;
        chart
            .draw_series(LineSeries::new(vec![(lo, lo), (hi, hi)], BLACK.mix(0.5)))?
            .label("measured = predicted")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.mix(0.5)));
        for (index, (name, points)) in series.iter().enumerate() {
            let style = ShapeStyle::from(&colour(index)).filled();
            chart
                .draw_series(
                    points
                        .iter()
                        .filter(|&&(a, b)| a > 0.0 && b > 0.0 && a.is_finite() && b.is_finite())
                        .map(|&p| Circle::new(p, 3, style)),
                )?
                .label(name)
                .legend(move |(x, y)| Circle::new((x + 10, y), 3, style));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
        root.present()?;
        Ok(())
    };
    let mut svg = String::new();
    draw(&mut svg).map_err(|e| ReportError::write(path, e))?;
    super::write_text(path, &svg)
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
        + 5.0;
    let views: [(&str, usize, usize); 3] = [
        ("front (x right, y down)", 0, 1),
        ("side (z right, y down)", 2, 1),
        ("top (x right, z down)", 0, 2),
    ];
    let draw = |svg: &mut String| -> Result<(), Box<dyn std::error::Error>> {
        let panel = 360u32;
        let root = SVGBackend::with_string(svg, (3 * panel, panel + 40)).into_drawing_area();
        root.fill(&WHITE)?;
        let (header, body) = root.split_vertically(40);
        header.titled(title, ("sans-serif", 20))?;
        for (area, (name, a, b)) in body.split_evenly((1, 3)).iter().zip(views) {
            let mut chart = ChartBuilder::on(area)
                .caption(name, ("sans-serif", 14))
                .margin(10)
                .x_label_area_size(25)
                .y_label_area_size(35)
                .build_cartesian_2d(-extent..extent, extent..-extent)?;
            chart.configure_mesh().x_desc("mm").draw()?;
            // Scale: pixels per mm along x of this panel.
            let plotting = chart.plotting_area();
            let left = plotting.map_coordinate(&(-extent, 0.0)).0;
            let right = plotting.map_coordinate(&(extent, 0.0)).0;
            let pixels_per_mm = (right - left) as f64 / (2.0 * extent);
            // Far spheres first, so nearer ones are drawn on top (the depth
            // axis is the one not shown, looking along +depth).
            let depth_axis = 3 - a - b;
            let mut order: Vec<usize> = (0..points.len()).collect();
            order.sort_by(|&i, &j| points[j].1[depth_axis].total_cmp(&points[i].1[depth_axis]));
            for index in order {
                let (label, p) = &points[index];
                let centre = (p[a], p[b]);
                let size = (radius * pixels_per_mm).round().max(1.0) as i32;
                chart.draw_series(std::iter::once(Circle::new(
                    centre,
                    size,
                    RGBColor(200, 200, 210).filled(),
                )))?;
                chart.draw_series(std::iter::once(Circle::new(
                    centre,
                    size,
                    BLACK.stroke_width(1),
                )))?;
                chart.draw_series(std::iter::once(Text::new(
                    label.clone(),
                    (p[a] + radius, p[b] - radius),
                    ("sans-serif", 12),
                )))?;
            }
        }
        root.present()?;
        Ok(())
    };
    let mut svg = String::new();
    draw(&mut svg).map_err(|e| ReportError::write(path, e))?;
    super::write_text(path, &svg)
}
