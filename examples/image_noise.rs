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

use layout_opt::camera::Camera;
use layout_opt::layout::Layout;
use layout_opt::mesh::{Marker, MarkerOptions};
use layout_opt::noise::calibrated::fit;
use layout_opt::render::{RenderConfig, Scene};
use layout_opt::track::TrackConfig;
use layout_opt::validate::images::{check_pose, first_whole_view, sigma_samples};
use rayon::prelude::*;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .map_or("layouts/biprism-search.json", String::as_str);
    let trials: usize = args.get(1).map_or(Ok(40), |s| s.parse())?;
    let seed: u64 = args.get(2).map_or(Ok(7), |s| s.parse())?;
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
            check_pose(&scene, &names, &render, &track, &pose, frame as u64, trials)
                .ok()
                .map(|images| (depth, images))
        })
        .collect();
    println!("{path}, {trials} noisy frames per view, seed {seed}, retroreflective preset, default sensor");
    println!("depth mm | disc radius px (whole spheres) | centre σ px | lost | mislabelled | rotation RMS °");
    let mut all = Vec::new();
    for (depth, images) in results.iter().flatten() {
        let samples = sigma_samples(std::slice::from_ref(images));
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
        all.extend(samples);
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
