//! Renders an [`ImageSummary`]: the `report.md` section ([`markdown`]),
//! `images.csv` ([`scenario_table`]), `images.json` (the summary without
//! its per-scenario rows) and the terminal paragraph ([`console`]).
//! Computes nothing new.

use super::image_check::{CentreBin, ImageSummary, NoiseLaw, BIAS_SIGMAS, LAW_BIN_PX};
use super::images::{INDEPENDENT_RING, INDEPENDENT_WINDOW};
use crate::noise::calibrated::CentreErrorMeasure;
use crate::report::{significant, Table};
use std::collections::BTreeMap;
use std::fmt::Write as _;

fn number(value: f64) -> String {
    significant(value.is_finite().then_some(value), 3)
}

fn percent(part: usize, whole: usize) -> String {
    if whole == 0 {
        "—".to_string()
    } else {
        format!("{:.1}%", 100.0 * part as f64 / whole as f64)
    }
}

fn counts(reasons: &BTreeMap<String, usize>) -> String {
    if reasons.is_empty() {
        return "none".to_string();
    }
    reasons
        .iter()
        .map(|(reason, count)| format!("{reason}: {count}"))
        .collect::<Vec<_>>()
        .join("; ")
}

fn bin_table(label: &str, bins: &[CentreBin], law: Option<&NoiseLaw>) -> Table {
    let mut header = vec![
        label,
        "sphere views",
        "centres",
        "bias RMS (px)",
        "σ per axis (px)",
        "independent centroid σ (px)",
    ];
    let law = match law {
        Some(NoiseLaw::Fitted { law, .. }) => Some(law),
        _ => None,
    };
    if law.is_some() {
        header.extend(["noise law at the mean radius (px)", "law / independent σ"]);
    }
    let mut table = Table::new(header);
    for bin in bins {
        let mut row = vec![
            format!("{}–{}", number(bin.from), number(bin.to)),
            bin.sphere_views.to_string(),
            bin.centres.to_string(),
            number(bin.bias_px),
            number(bin.sigma_px),
            number(bin.independent_sigma_px),
        ];
        if let Some(law) = law {
            let sigma = law.sigma(bin.mean_radius_px);
            let ratio = sigma / bin.independent_sigma_px;
            row.extend([
                number(sigma),
                if ratio.is_finite() {
                    format!("{ratio:.2}")
                } else {
                    "—".to_string()
                },
            ]);
        }
        table.row(row);
    }
    table
}

/// Today's `size` law "holds" when its RMS relative residual is at most
/// this many times the fitted law's (or than 5%, whichever is larger).
pub const SIZE_LAW_HOLDS_FACTOR: f64 = 1.5;

/// The noise law in one sentence.
pub fn law_line(law: &NoiseLaw, points: &str) -> String {
    match law {
        NoiseLaw::Fitted {
            law,
            quality,
            radius_px,
        } => format!(
            "σ = {} / r^{} + {} px over disc radii {}–{} px ({} {points}): RMS relative residual {} (worst {}); today's `size` law (σ ∝ 1/√r) fits with {}, so it {}",
            number(law.a),
            number(law.b),
            number(law.c),
            number(radius_px[0]),
            number(radius_px[1]),
            quality.points,
            number(quality.rms_relative_residual),
            number(quality.worst_relative_residual),
            number(quality.size_law_rms_relative_residual),
            if quality.size_law_rms_relative_residual
                <= SIZE_LAW_HOLDS_FACTOR * quality.rms_relative_residual.max(0.05)
            {
                "holds about as well"
            } else {
                "does not hold"
            }
        ),
        NoiseLaw::Unfitted(reason) => format!("no noise law fitted: {reason}"),
    }
}

/// The `report.md` section.
pub fn markdown(images: &ImageSummary) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "## Images\n");
    let _ = writeln!(
        out,
        "Every visible scenario rendered once ({}) and read back by `track` {} times under seeded sensor noise (seed {}, frame = scenario index); per-scenario figures in [images.csv](images.csv), pooled ones in [images.json](images.json).\n",
        images.preset, images.check.trials, images.seed
    );
    let _ = writeln!(
        out,
        "- scenarios: {} visible, {} refused by the renderer ({})",
        images.scenarios,
        images.refused.values().sum::<usize>(),
        counts(&images.refused)
    );
    let lost: usize = images.lost.values().sum();
    let _ = writeln!(
        out,
        "- frames: {} read, {} posed, {} lost ({}; {}), {} mislabelled ({}), {} missing a whole sphere ({})\n",
        images.frames,
        images.posed_frames,
        lost,
        percent(lost, images.frames),
        counts(&images.lost),
        images.mislabelled_frames,
        percent(images.mislabelled_frames, images.frames),
        images.frames_missing_a_whole_sphere,
        percent(images.frames_missing_a_whole_sphere, images.frames),
    );
    let _ = writeln!(
        out,
        "### Centre error of whole spheres against disc radius\n"
    );
    out.push_str(&bin_table("radius (px)", &images.by_radius, Some(&images.noise_law)).markdown());
    let _ = writeln!(
        out,
        "\nThe independent centroid shares nothing with `track`: on the same frames, each whole sphere's intensity-weighted centroid within {INDEPENDENT_WINDOW} disc radii of its exact centre, less the median of the ring {}–{} radii out; its window is fixed by the truth, so its σ is the sensor noise's alone. The noise law (section \"Noise law\") is the tracked centres' error about the truth, noise and bias.",
        INDEPENDENT_RING.0, INDEPENDENT_RING.1
    );
    let _ = writeln!(out, "\n### Centre error of whole spheres against depth\n");
    out.push_str(&bin_table("depth (mm)", &images.by_depth, None).markdown());
    let _ = writeln!(
        out,
        "\n### Pose from the images against the first-order model\n"
    );
    match &images.pose {
        Some(p) => {
            let mut table = Table::new(["", "rotation RMS (°)", "translation RMS (mm)"]);
            table.row([
                "images".to_string(),
                number(p.image_rotation_rms_deg),
                number(p.image_translation_rms_mm),
            ]);
            table.row([
                format!(
                    "first order at the assumed σ ({} px RMS)",
                    number(p.assumed_sigma_px)
                ),
                number(p.predicted_rotation_rms_deg),
                number(p.predicted_translation_rms_mm),
            ]);
            table.row([
                format!(
                    "first order at the measured σ ({} px)",
                    number(p.measured_sigma_px)
                ),
                number(p.predicted_at_measured_rotation_rms_deg),
                number(p.predicted_at_measured_translation_rms_mm),
            ]);
            table.row([
                "first order at the measured σ and centre bias".to_string(),
                number(p.predicted_with_bias_rotation_rms_deg),
                number(p.predicted_with_bias_translation_rms_mm),
            ]);
            out.push_str(&table.markdown());
            let _ = writeln!(
                out,
                "\nOver {} scenarios (root mean square of the per-scenario RMS). The assumed σ is the noise model's per sphere (RMS shown); the measured σ pools the whole spheres' per-axis centre variance. The prediction at the measured σ is the first-order covariance of the pose the tracker solved: the spheres in at least half of its posed frames, each at its own measured σ, for any noise model; the last row adds in quadrature the first-order pose bias that those spheres' measured mean centre errors cause (the systematic part no σ predicts).\n",
                p.scenarios
            );
        }
        None => {
            let _ = writeln!(
                out,
                "No scenario gave both an image pose and a prediction.\n"
            );
        }
    }
    let _ = writeln!(
        out,
        "### Partly hidden spheres with a biased centre\n\n{} sphere views hidden in part have a mean centre error above {BIAS_SIGMAS} × their σ.\n",
        images.biased_count
    );
    if !images.biased.is_empty() {
        let mut table = Table::new([
            "scenario",
            "sphere",
            "hidden",
            "radius (px)",
            "bias (px)",
            "σ (px)",
        ]);
        for b in &images.biased {
            table.row([
                super::summary::describe_scenario(&b.scenario),
                b.sphere.clone(),
                format!("{:.1}%", 100.0 * b.hidden),
                number(b.radius_px),
                number(b.bias_px),
                number(b.sigma_px),
            ]);
        }
        out.push_str(&table.markdown());
        out.push('\n');
    }
    let _ = writeln!(
        out,
        "### Noise law\n\nOf the centre {}, per axis, over every sphere view the pose was solved from (a sphere whose notch the tracker cut away included), as the RMS in radius bins {LAW_BIN_PX} px wide (what `--write-noise-model` writes, and what `--noise-model calibrated:FILE` then assumes): {}\n\nOf the whole spheres' {}: {}\n",
        CentreErrorMeasure::AboutTruth.describe(),
        law_line(&images.noise_law, "radius bins"),
        CentreErrorMeasure::Scatter.describe(),
        law_line(&images.scatter_law, "sphere views")
    );
    if !images.samples.is_empty() {
        let _ = writeln!(
            out,
            "### Sample frames\n\nAs `track` read them, cropped to the part (its overlay: crosses at the blobs, green whole, red flagged as partly hidden, with their labels; blue, the model's outline at the tracked pose).\n"
        );
        for sample in &images.samples {
            let _ = writeln!(
                out,
                "![{role}]({dir}/{role}.png)\n\n*{Role}*: {scenario}, noise realisation {trial}; {outcome}.\n",
                role = sample.role,
                dir = SAMPLE_DIR,
                Role = capitalised(&sample.role),
                scenario = super::summary::describe_scenario(&sample.scenario),
                trial = sample.trial,
                outcome = sample.outcome,
            );
        }
    }
    out
}

/// The report's folder of sample frames.
pub const SAMPLE_DIR: &str = "images";

fn capitalised(word: &str) -> String {
    let mut chars = word.chars();
    chars.next().map_or(String::new(), |first| {
        first.to_uppercase().chain(chars).collect()
    })
}

/// Margin around the part in a sample frame's crop, px.
pub const SAMPLE_MARGIN_PX: f64 = 40.0;

/// The sample frames as `track`'s overlay PNGs, cropped to the part (every
/// sphere's disc at the true pose and every blob, with
/// [`SAMPLE_MARGIN_PX`] around them, at the camera's resolution): (file
/// name under [`SAMPLE_DIR`], bytes).
pub fn sample_pngs(images: &ImageSummary) -> Vec<(String, Vec<u8>)> {
    images
        .samples
        .iter()
        .map(|sample| {
            let (camera, object, radius_mm) = &sample.geometry;
            let png = crate::track::report::overlay_png(
                &sample.frame,
                &sample.analysis,
                camera,
                object,
                *radius_mm,
                sample.analysis.pose.as_ref(),
            );
            (format!("{}.png", sample.role), crop(sample, png))
        })
        .collect()
}

/// `png` cropped to the part (see [`sample_pngs`]); unchanged when it
/// cannot be decoded.
fn crop(sample: &super::image_check::SampleFrame, png: Vec<u8>) -> Vec<u8> {
    let (camera, object, radius_mm) = &sample.geometry;
    let pose = sample.scenario.pose();
    let mut extent = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    let mut include = |x: f64, y: f64, r: f64| {
        extent = [
            extent[0].min(x - r),
            extent[1].min(y - r),
            extent[2].max(x + r),
            extent[3].max(y + r),
        ];
    };
    for p in object {
        let centre = pose.transform(p);
        if let Some(pixel) = camera.project(&centre) {
            include(
                pixel.x,
                pixel.y,
                camera.fx() * radius_mm / centre.z.max(1e-9),
            );
        }
    }
    if let Some(detection) = &sample.analysis.detection {
        for blob in &detection.blobs {
            let [x, y] = blob.ellipse_centre_px;
            include(x, y, blob.semi_axes_px[0]);
        }
    }
    let Ok(image) = image::load_from_memory(&png) else {
        return png;
    };
    let (width, height) = (image.width() as f64, image.height() as f64);
    let left = (extent[0] - SAMPLE_MARGIN_PX)
        .floor()
        .clamp(0.0, width - 1.0);
    let top = (extent[1] - SAMPLE_MARGIN_PX)
        .floor()
        .clamp(0.0, height - 1.0);
    let right = (extent[2] + SAMPLE_MARGIN_PX)
        .ceil()
        .clamp(left + 1.0, width);
    let bottom = (extent[3] + SAMPLE_MARGIN_PX)
        .ceil()
        .clamp(top + 1.0, height);
    if !(left.is_finite() && top.is_finite() && right.is_finite() && bottom.is_finite()) {
        return png;
    }
    let cropped = image.crop_imm(
        left as u32,
        top as u32,
        (right - left) as u32,
        (bottom - top) as u32,
    );
    let mut bytes = Vec::new();
    match cropped.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    ) {
        Ok(()) => bytes,
        Err(_) => png,
    }
}
/// `images.csv`: one row per visible scenario.
pub fn scenario_table(images: &ImageSummary) -> Table {
    let mut table = Table::new([
        "scenario",
        "depth_mm",
        "tilt_deg",
        "refused",
        "frames",
        "posed",
        "mislabelled",
        "missing_a_whole_sphere",
        "whole_spheres",
        "min_radius_px",
        "sigma_px",
        "max_bias_px",
        "rotation_rms_deg",
        "translation_rms_mm",
        "predicted_rotation_rms_deg",
    ]);
    let cell = |v: f64| {
        if v.is_finite() {
            format!("{v}")
        } else {
            String::new()
        }
    };
    for row in &images.per_scenario {
        table.row([
            row.scenario.to_string(),
            cell(row.depth_mm),
            cell(row.tilt_deg),
            row.refused.clone().unwrap_or_default(),
            row.frames.to_string(),
            row.posed.to_string(),
            row.mislabelled.to_string(),
            row.missing_a_whole_sphere.to_string(),
            row.whole_spheres.to_string(),
            cell(row.min_radius_px),
            cell(row.sigma_px),
            cell(row.max_bias_px),
            cell(row.rotation_rms_deg),
            cell(row.translation_rms_mm),
            cell(row.predicted_rotation_rms_deg),
        ]);
    }
    table
}

/// The terminal paragraph.
pub fn console(images: &ImageSummary) -> String {
    let lost: usize = images.lost.values().sum();
    let sigma = |bins: &[CentreBin], first: bool| {
        let bin = if first { bins.first() } else { bins.last() };
        bin.map_or("—".to_string(), |b| {
            format!(
                "{} px at {}–{}",
                number(b.sigma_px),
                number(b.from),
                number(b.to)
            )
        })
    };
    let pose = images.pose.as_ref().map_or(
        "no scenario gave an image pose and a prediction".to_string(),
        |p| {
            format!(
                "rotation RMS {}° from the images against {}° predicted at σ {} px and {}° at the measured σ {} px",
                number(p.image_rotation_rms_deg),
                number(p.predicted_rotation_rms_deg),
                number(p.assumed_sigma_px),
                number(p.predicted_at_measured_rotation_rms_deg),
                number(p.measured_sigma_px)
            )
        },
    );
    format!(
        "images: {} visible scenarios × {} frames ({} refused by the renderer); centre σ {} (smallest discs) to {} (largest); {pose}; {} of frames lost, {} mislabelled; {} partly hidden spheres biased beyond {BIAS_SIGMAS} σ; centre error about the truth (noise and bias): {}; noise alone: {}\n",
        images.scenarios,
        images.check.trials,
        images.refused.values().sum::<usize>(),
        sigma(&images.by_radius, true),
        sigma(&images.by_radius, false),
        percent(lost, images.frames),
        percent(images.mislabelled_frames, images.frames),
        images.biased_count,
        law_line(&images.noise_law, "radius bins"),
        law_line(&images.scatter_law, "sphere views")
    )
}
