//! `characterise`'s report: Markdown and JSON of a [`Characterisation`],
//! and the terminal text of a [`CapturePlan`]. Computes nothing new.

use super::plan::CapturePlan;
use super::Characterisation;
use std::fmt::Write;

/// Figures as fixed-point text.
fn triple(v: &[f64; 3], digits: usize) -> String {
    format!("{:.digits$}, {:.digits$}, {:.digits$}", v[0], v[1], v[2])
}

/// The report (Markdown).
pub fn markdown(c: &Characterisation, command: &str, layout_file: &str) -> String {
    let mut out = String::new();
    let (worst, worst_sigma) = c.worst_sigma();
    let _ = writeln!(
        out,
        "# {} as printed, characterised from {} frames\n",
        c.nominal,
        c.frames.len()
    );
    let _ = writeln!(out, "`{command}`\n");
    let _ = writeln!(
        out,
        "The sphere centres and every frame's pose were adjusted together (bundle adjustment, Levenberg–Marquardt with the poses eliminated, a robust Huber loss), from the nominal layout and the poses tracked with it. The centres are given in the frame that best overlays the nominal ({}). Each σ is first order, at the centres' noise estimated from the residuals: **{:.4} px** per axis (residual RMS {:.4} px over {} centres).\n",
        match c.scale.source {
            "distances" => format!("its scale from the measured distances, ×{:.5} the nominal's", c.scale.factor),
            _ => "at the nominal's scale: one camera cannot see a uniform shrink; give --distance to measure it".to_string(),
        },
        c.sigma_px,
        c.residual_rms_px,
        c.centres
    );
    let _ = writeln!(out, "Characterised layout: `{layout_file}`. Largest 1σ: {worst_sigma:.4} mm ({}), against the bar of {} mm.\n", c.names[worst], c.max_sigma_mm);
    let _ = writeln!(out, "## Spheres\n");
    let _ = writeln!(out, "| sphere | nominal (mm) | correction (mm) | \\|correction\\| (mm) | 1σ axes (mm) | weakest direction |");
    let _ = writeln!(out, "|---|---|---|---|---|---|");
    for i in 0..c.names.len() {
        let d = c.correction_mm[i];
        let _ = writeln!(
            out,
            "| {} | {} | {} | {:.4} | {} | {} |",
            c.names[i],
            triple(&c.nominal_mm[i], 3),
            triple(&d, 4),
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt(),
            triple(&c.sigma_axes_mm[i], 4),
            triple(&c.weakest_direction[i], 2)
        );
    }
    let _ = writeln!(out, "\nThe 1σ ellipsoid of each centre has the axes given, the largest along the weakest direction: the direction the frames observed worst. Views turned to look across it shrink it.\n");
    if !c.scale.distances.is_empty() {
        let _ = writeln!(out, "## Measured distances\n");
        let _ = writeln!(
            out,
            "| pair | measured (mm) | σ (mm) | characterised (mm) | nominal (mm) |"
        );
        let _ = writeln!(out, "|---|---|---|---|---|");
        for d in &c.scale.distances {
            let _ = writeln!(
                out,
                "| {}:{} | {} | {} | {:.4} | {:.4} |",
                d.measured.first,
                d.measured.second,
                d.measured.mm,
                d.measured.sigma_mm,
                d.characterised_mm,
                d.nominal_mm
            );
        }
        out.push('\n');
    }
    let _ = writeln!(out, "## Frames\n");
    let _ = writeln!(
        out,
        "| frame | centres | residual RMS (px) | distance (mm) |"
    );
    let _ = writeln!(out, "|---|---|---|---|");
    for f in &c.frames {
        let distance = (f.tvec[0].powi(2) + f.tvec[1].powi(2) + f.tvec[2].powi(2)).sqrt();
        let _ = writeln!(
            out,
            "| {} | {} | {:.4} | {:.0} |",
            f.frame, f.centres, f.rms_px, distance
        );
    }
    if !c.dropped.is_empty() {
        let _ = writeln!(out, "\n## Frames not used\n");
        for d in &c.dropped {
            let _ = writeln!(out, "* `{}`: {}", d.frame, d.reason);
        }
    }
    out
}

/// The summary as JSON.
pub fn json(c: &Characterisation, command: &str) -> String {
    let mut value = serde_json::to_value(c).unwrap_or_default();
    if let Some(map) = value.as_object_mut() {
        map.insert("command".into(), serde_json::json!(command));
        map.insert(
            "version".into(),
            serde_json::json!(env!("CARGO_PKG_VERSION")),
        );
    }
    serde_json::to_string_pretty(&value).unwrap_or_default() + "\n"
}

/// The capture plan as terminal text.
pub fn plan_text(plan: &CapturePlan) -> String {
    let mut out = String::new();
    let depth = plan.views.first().map_or(0.0, |v| v.depth_mm);
    let _ = writeln!(
        out,
        "capture plan for {}: {} views, the part's centroid on the optical axis at {depth:.0} mm, turned as listed (tilt about the camera's x axis, then pan about its y axis):",
        plan.layout,
        plan.views.len()
    );
    for (k, v) in plan.views.iter().enumerate() {
        let _ = writeln!(
            out,
            "  {:>2}. {} ({} spheres clear)",
            k + 1,
            v.describe(),
            v.spheres.len()
        );
    }
    let _ = writeln!(
        out,
        "predicted 1σ of each characterised centre (largest axis, first order, {} px centre noise per axis, nominal scale):",
        plan.sigma_px
    );
    for (name, sigma) in plan.names.iter().zip(&plan.sphere_sigma_mm) {
        let _ = writeln!(out, "  {name}: {sigma:.4} mm");
    }
    out
}
