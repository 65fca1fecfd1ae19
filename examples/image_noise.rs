//! The centre noise of rendered frames read back by `track`, against the
//! blob's disc radius, and the law `σ = a / r^b + c` fitted to it: the
//! figures of the image-level noise calibration.
//!
//! ```text
//! cargo run --release --example image_noise -- [LAYOUT] [TRIALS] [SEED]
//! ```
//!
//! For each depth of 200…1000 mm in 100 mm steps, the first view of the
//! layout (default `layouts/biprism-search.json`) with every sphere whole
//! (`validate::images::first_whole_view`) is rendered with the default
//! retroreflective preset and sensor (8 bit, σ 0.5 px blur, full well
//! 10,000 e⁻, read noise 10 e⁻) and read back `TRIALS` times (default 40).
//! It prints each whole sphere's disc radius and centre σ, the frames lost
//! or mislabelled, the pose errors, and the fitted law beside the best
//! law of today's `size` form.
//!
//! **Cross-check.** On the same noisy frames (the same seeds), an
//! independent centroid that shares nothing with `track`: each whole
//! sphere's intensity-weighted centroid over the pixels within 1.2 disc
//! radii of its exact ellipse centre, less the median of the ring from 1.4
//! to 1.8 radii. Its per-axis σ about its mean is printed beside `track`'s
//! centre σ, and its per-axis RMS error about the exact ellipse centre (the
//! centroid of a uniform disc; noise and bias) beside `track`'s RMS error
//! about the exact projected centre; with `CALIBRATION` (a noise
//! calibration file, e.g. `calibration/paper.json`), each beside that
//! law's σ at the same radius:
//!
//! ```text
//! cargo run --release --example image_noise -- LAYOUT TRIALS SEED CALIBRATION
//! ```

use layout_opt::camera::Camera;
use layout_opt::layout::Layout;
use layout_opt::mesh::{Marker, MarkerOptions};
use layout_opt::noise::calibrated::CalibrationFile;
use layout_opt::noise::calibrated::{fit, CentreErrorMeasure};
use layout_opt::render::{frame_truth, render_radiance};
use layout_opt::render::{RenderConfig, Scene};
use layout_opt::track::GreyFrame;
use layout_opt::track::TrackConfig;
use layout_opt::validate::images::{
    check_pose, first_whole_view, noisy_frame, sigma_samples, WHOLE_SPHERE_HIDDEN,
};
use rayon::prelude::*;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .map_or("layouts/biprism-search.json", String::as_str);
    let trials: usize = args.get(1).map_or(Ok(40), |s| s.parse())?;
    let seed: u64 = args.get(2).map_or(Ok(7), |s| s.parse())?;
    let calibration = args
        .get(3)
        .map(|path| CalibrationFile::load(std::path::Path::new(path)))
        .transpose()?;
    let layout = Layout::load(std::path::Path::new(path))?;
    let names: Vec<String> = layout.points.iter().map(|p| p.name.clone()).collect();
    let scene = Scene::from_marker(Marker::design(&layout, &MarkerOptions::default())?);
    let camera = Camera::paper();
    let mut render = RenderConfig::new(camera);
    render.seed = seed;
    let track = TrackConfig::new(&layout, camera);
    track.validate()?;
    let depths: Vec<f64> = (2..=10).map(|d| 100.0 * d as f64).collect();
    let results: Vec<_> = depths
        .par_iter()
        .enumerate()
        .map(|(frame, &depth)| {
            let pose = first_whole_view(&scene, &names, &camera, depth).ok()??;
            let images =
                check_pose(&scene, &names, &render, &track, &pose, frame as u64, trials).ok()?;
            let centroids = centroid_sigmas(&scene, &names, &render, &pose, frame as u64, trials);
            Some((depth, images, centroids))
        })
        .collect();
    println!("{path}, {trials} noisy frames per view, seed {seed}, retroreflective preset, default sensor");
    println!("depth mm | disc radius px (whole spheres) | centre σ px | lost | mislabelled | rotation RMS °");
    let mut all = Vec::new();
    let mut cross = Vec::new();
    for (depth, images, centroids) in results.iter().flatten() {
        let samples = sigma_samples(std::slice::from_ref(images), CentreErrorMeasure::Scatter);
        let about_truth =
            sigma_samples(std::slice::from_ref(images), CentreErrorMeasure::AboutTruth);
        let radii: Vec<String> = samples
            .iter()
            .map(|s| format!("{:.1}", s.radius_px))
            .collect();
        let sigmas: Vec<String> = samples
            .iter()
            .map(|s| format!("{:.3}", s.sigma_px))
            .collect();
        let rms = (images.rotation_error_deg.iter().map(|e| e * e).sum::<f64>()
            / images.rotation_error_deg.len().max(1) as f64)
            .sqrt();
        println!(
            "{depth:.0} | {} | {} | {} | {} | {rms:.4}",
            radii.join(" "),
            sigmas.join(" "),
            images.lost.values().sum::<usize>(),
            images.mislabelled_frames
        );
        for sample in &samples {
            // The same sphere's error about the truth and its centroid:
            // matched by radius, the sphere's own exact disc radius in all.
            let same = |r: f64| (r - sample.radius_px).abs() < 1e-9;
            let truth = about_truth.iter().find(|t| same(t.radius_px));
            let centroid = centroids.iter().find(|(r, _, _)| same(*r));
            if let (Some(truth), Some(&(_, sigma, rms))) = (truth, centroid) {
                cross.push((
                    sample.radius_px,
                    sample.sigma_px,
                    sigma,
                    truth.sigma_px,
                    rms,
                ));
            }
        }
        all.extend(samples);
    }
    cross.sort_by(|a, b| a.0.total_cmp(&b.0));
    println!("\ncross-check: whole spheres, track's centre σ beside an independent centroid's σ (same frames){}", if calibration.is_some() { " and the calibration's σ(r)" } else { "" });
    println!(
        "radius px | track σ px | centroid σ px | centroid / track | track RMS about truth px | centroid RMS about truth px{}",
        if calibration.is_some() {
            " | law σ px | law / centroid σ | law / centroid RMS about truth"
        } else {
            ""
        }
    );
    for (radius, track_sigma, centroid_sigma, track_rms, centroid_rms) in &cross {
        let law = calibration.as_ref().map_or(String::new(), |file| {
            let sigma = file.sigma().expect("checked on load").sigma(*radius);
            format!(
                " | {sigma:.5} | {:.2} | {:.2}",
                sigma / centroid_sigma,
                sigma / centroid_rms
            )
        });
        println!(
            "{radius:.1} | {track_sigma:.5} | {centroid_sigma:.5} | {:.2} | {track_rms:.5} | {centroid_rms:.5}{law}",
            centroid_sigma / track_sigma
        );
    }
    let (law, quality) = fit(&all)?;
    println!(
        "fit over {} spheres: σ = {:.4} / r^{:.3} + {:.4} px; RMS relative residual {:.3} (worst {:.3}); best size law (b = 0.5, c = 0): {:.3}",
        quality.points,
        law.a,
        law.b,
        law.c,
        quality.rms_relative_residual,
        quality.worst_relative_residual,
        quality.size_law_rms_relative_residual
    );
    Ok(())
}

/// Per whole sphere: (disc radius px, per-axis σ px of its independent
/// centroid about its mean over the `trials` noisy frames of `frame`, and
/// its per-axis RMS error px about the exact ellipse centre; module docs).
fn centroid_sigmas(
    scene: &Scene,
    names: &[String],
    render: &RenderConfig,
    pose: &layout_opt::pose::Pose,
    frame: u64,
    trials: usize,
) -> Vec<(f64, f64, f64)> {
    let Ok(truth) = frame_truth(scene, names, pose, &render.camera) else {
        return Vec::new();
    };
    let Ok(radiance) = render_radiance(scene, pose, render) else {
        return Vec::new();
    };
    let frames: Vec<GreyFrame> = (0..trials as u64)
        .map(|trial| noisy_frame(&radiance, render, frame, trial))
        .collect();
    truth
        .spheres
        .iter()
        .filter(|s| {
            s.hidden.by_support + s.hidden.by_sphere + s.hidden.outside_image < WHOLE_SPHERE_HIDDEN
        })
        .filter_map(|s| {
            let radius = 0.5 * (s.semi_axes_px[0] + s.semi_axes_px[1]);
            let centres: Vec<[f64; 2]> = frames
                .iter()
                .filter_map(|f| centroid(f, s.ellipse_centre_px, radius))
                .collect();
            let n = centres.len() as f64;
            if n < 2.0 {
                return None;
            }
            let mean = centres
                .iter()
                .fold([0.0; 2], |m, c| [m[0] + c[0] / n, m[1] + c[1] / n]);
            let squares = |about: [f64; 2]| -> f64 {
                centres
                    .iter()
                    .map(|c| (c[0] - about[0]).powi(2) + (c[1] - about[1]).powi(2))
                    .sum()
            };
            Some((
                radius,
                (squares(mean) / (2.0 * (n - 1.0))).sqrt(),
                (squares(s.ellipse_centre_px) / (2.0 * n)).sqrt(),
            ))
        })
        .collect()
}

/// The background-subtracted intensity-weighted centroid of the disc of
/// radius 1.2 `radius` about `centre`, the background the median of the
/// ring from 1.4 to 1.8 `radius`; None off the image.
fn centroid(frame: &GreyFrame, centre: [f64; 2], radius: f64) -> Option<[f64; 2]> {
    let reach = (1.8 * radius).ceil() as i64 + 1;
    let (cx, cy) = (centre[0].round() as i64, centre[1].round() as i64);
    let (width, height) = (i64::from(frame.width()), i64::from(frame.height()));
    if cx - reach < 0 || cy - reach < 0 || cx + reach >= width || cy + reach >= height {
        return None;
    }
    let mut ring = Vec::new();
    let mut disc = Vec::new();
    for y in cy - reach..=cy + reach {
        for x in cx - reach..=cx + reach {
            let d = (x as f64 - centre[0]).hypot(y as f64 - centre[1]) / radius;
            let v = f64::from(frame.at(x as u32, y as u32));
            if d <= 1.2 {
                disc.push((x as f64, y as f64, v));
            } else if (1.4..=1.8).contains(&d) {
                ring.push(v);
            }
        }
    }
    ring.sort_by(f64::total_cmp);
    let background = *ring.get(ring.len() / 2)?;
    let (mut sum, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for (x, y, v) in disc {
        let w = (v - background).max(0.0);
        sum += w;
        sx += w * x;
        sy += w * y;
    }
    (sum > 0.0).then(|| [sx / sum, sy / sum])
}
