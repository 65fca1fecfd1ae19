//! The centre noise of rendered frames read back by `track`, against the
//! blob's disc radius, and the law `σ = a / r^b + c` fitted to it: the
//! figures of the image-level noise calibration.
//!
//! ```text
//! cargo run --release --features examples --example image_noise -- [LAYOUT] [TRIALS] [SEED]
//! ```
//!
//! For each depth of 200…1000 mm in 100 mm steps, the first view of the
//! layout (default `layouts/biprism-search.json`) with every sphere whole
//! (`validate::images::first_whole_view`) is rendered with the default
//! retroreflective preset and sensor (8 bit, σ 0.5 px blur, full well
//! 10,000 e⁻, read noise 10 e⁻), sub-sampled 16 × 16 as `validate
//! --images` renders, and read back `TRIALS` times (default 40).
//! It prints each whole sphere's disc radius and centre σ, the frames lost
//! or mislabelled, the pose errors, and the fitted law beside the best
//! law of today's `size` form.
//!
//! **Cross-check.** On the same noisy frames (the same seeds), an
//! independent centroid that shares nothing with `track`
//! (`validate::images::independent_centroid`: each whole sphere's
//! intensity-weighted centroid over the pixels within 1.2 disc radii of its
//! exact ellipse centre, less the median of the ring from 1.4 to 1.8
//! radii). Its per-axis σ about its mean is printed beside `track`'s
//! centre σ, and its per-axis RMS error about the exact ellipse centre (the
//! centroid of a uniform disc; noise and bias) beside `track`'s RMS error
//! about the exact projected centre; with `CALIBRATION` (a noise
//! calibration file, e.g. `calibration/paper.json`), each beside that
//! law's σ at the same radius:
//!
//! ```text
//! cargo run --release --features examples --example image_noise -- LAYOUT TRIALS SEED CALIBRATION [METHOD [refine[:ROUNDS[:SUPERSAMPLING]]]]
//! ```
//!
//! `CALIBRATION` may be `-` (none). `METHOD` is `track`'s centre method
//! (`ellipse`, the default, `centroid` or `window`), and `refine` reads
//! every frame as `track --refine` does, the part rendered as the frames
//! are (`ROUNDS` rounds, 1 by default, at `SUPERSAMPLING` × `SUPERSAMPLING`
//! sub-samples, 8 by default).

use layout_opt::camera::Camera;
use layout_opt::layout::Layout;
use layout_opt::mesh::{Marker, MarkerOptions};
use layout_opt::noise::calibrated::CalibrationFile;
use layout_opt::noise::calibrated::{fit, CentreErrorMeasure};
use layout_opt::render::{frame_truth, render_radiance};
use layout_opt::render::{RenderConfig, Scene};
use layout_opt::track::refine::{Refiner, DEFAULT_SUPERSAMPLING};
use layout_opt::track::CentreMethod;
use layout_opt::track::GreyFrame;
use layout_opt::track::TrackConfig;
use layout_opt::validate::images::{
    check_pose, first_whole_view, independent_centroid, noisy_frame, sigma_samples, Reader,
    WHOLE_SPHERE_HIDDEN,
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
        .filter(|path| *path != "-")
        .map(|path| CalibrationFile::load(std::path::Path::new(path)))
        .transpose()?;
    let centre: CentreMethod = args
        .get(4)
        .map_or(Ok(CentreMethod::Ellipse), |s| s.parse())?;
    // `refine[:ROUNDS[:SUPERSAMPLING]]`, or nothing.
    let refine: Option<(u32, u32)> = match args.get(5) {
        None => None,
        Some(text) => {
            let mut parts = text.split(':');
            if parts.next() != Some("refine") {
                return Err(
                    format!("expected refine[:ROUNDS[:SUPERSAMPLING]], got {text:?}").into(),
                );
            }
            let rounds = parts.next().map_or(Ok(1), str::parse)?;
            let supersampling = parts.next().map_or(Ok(DEFAULT_SUPERSAMPLING), str::parse)?;
            Some((rounds, supersampling))
        }
    };
    let layout = Layout::load(std::path::Path::new(path))?;
    let names: Vec<String> = layout.points.iter().map(|p| p.name.clone()).collect();
    let scene = Scene::from_marker(Marker::design(&layout, &MarkerOptions::default())?);
    let camera = Camera::paper();
    let mut render = RenderConfig::new(camera);
    render.seed = seed;
    // Sub-sampled as the image check's frames are.
    render.optics.supersampling = layout_opt::render::config::MAX_SUPERSAMPLING;
    let mut track = TrackConfig::new(&layout, camera);
    track.centre = centre;
    track.validate()?;
    let refiner = match refine {
        Some((rounds, supersampling)) => {
            let mut model = render.clone();
            model.optics.supersampling = supersampling;
            Some(Refiner::new(scene.clone(), model, rounds)?)
        }
        None => None,
    };
    let reader = Reader {
        track: &track,
        refiner: refiner.as_ref(),
    };
    let depths: Vec<f64> = (2..=10).map(|d| 100.0 * d as f64).collect();
    let results: Vec<_> = depths
        .par_iter()
        .enumerate()
        .map(|(frame, &depth)| {
            let pose = first_whole_view(&scene, &names, &camera, depth).ok()??;
            let images =
                check_pose(&scene, &names, &render, reader, &pose, frame as u64, trials).ok()?;
            let centroids = centroid_sigmas(&scene, &names, &render, &pose, frame as u64, trials);
            Some((depth, images, centroids))
        })
        .collect();
    println!(
        "{path}, {trials} noisy frames per view, seed {seed}, retroreflective preset, default sensor; track --centre {}{}",
        centre.name(),
        refine.map_or(String::new(), |(rounds, n)| format!(
            " --refine --refine-rounds {rounds} --supersampling {n}"
        ))
    );
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
    println!("\ncross-check: whole spheres in disc-radius bins 4 px wide (RMS over the bin's spheres), track's centre beside an independent centroid's (same frames){}", if calibration.is_some() { " and the calibration's σ at the bin's mean radius" } else { "" });
    println!(
        "radius px | spheres | track σ px | centroid σ px | track RMS about truth px | centroid RMS about truth px | track RMS / centroid σ{}",
        if calibration.is_some() {
            " | law σ px | law / centroid σ"
        } else {
            ""
        }
    );
    let mut bins: std::collections::BTreeMap<i64, Vec<[f64; 5]>> = Default::default();
    for &(radius, track_sigma, centroid_sigma, track_rms, centroid_rms) in &cross {
        bins.entry((radius / 4.0).floor() as i64)
            .or_default()
            .push([radius, track_sigma, centroid_sigma, track_rms, centroid_rms]);
    }
    for (bin, members) in &bins {
        let n = members.len() as f64;
        let mean = members.iter().map(|m| m[0]).sum::<f64>() / n;
        let rms = |k: usize| (members.iter().map(|m| m[k] * m[k]).sum::<f64>() / n).sqrt();
        let law = calibration.as_ref().map_or(String::new(), |file| {
            let sigma = file.sigma().expect("checked on load").sigma(mean);
            format!(" | {sigma:.5} | {:.2}", sigma / rms(2))
        });
        println!(
            "{}–{} | {} | {:.5} | {:.5} | {:.5} | {:.5} | {:.2}{law}",
            4 * bin,
            4 * (bin + 1),
            members.len(),
            rms(1),
            rms(2),
            rms(3),
            rms(4),
            rms(3) / rms(2)
        );
    }
    let rotations: Vec<f64> = results
        .iter()
        .flatten()
        .flat_map(|(_, images, _)| images.rotation_error_deg.iter().copied())
        .collect();
    println!(
        "rotation error RMS over the {} posed frames: {:.5}°",
        rotations.len(),
        (rotations.iter().map(|e| e * e).sum::<f64>() / rotations.len().max(1) as f64).sqrt()
    );
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
        .filter(|s| s.hidden.total() < WHOLE_SPHERE_HIDDEN)
        .filter_map(|s| {
            let radius = 0.5 * (s.semi_axes_px[0] + s.semi_axes_px[1]);
            let centres: Vec<[f64; 2]> = frames
                .iter()
                .filter_map(|f| independent_centroid(f, s.ellipse_centre_px, radius))
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
