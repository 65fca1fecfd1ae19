//! `track` on frames drawn by `render` ([`frames`]: the printed part with
//! its supports, and the render's ground truth): labels, centres and poses
//! on noise-free renders; the predicted 1σ against the actual error and
//! the label rate on noisy renders; the partly-hidden flag against the
//! render's hidden fractions; uneven light and a distorted lens; and bad
//! frames, each an error record that stops no other frame. The `track`
//! command itself is tested in [`cli`].

mod cli;
pub mod frames;
mod shading;
mod stream;

use frames::{blob_of_sphere, clean_view, ellipse_centre, hidden_fraction, Part};
use layout_opt::camera::Camera;
use layout_opt::identifiability::predict;
use layout_opt::pose::{rotation_error_deg, Pose};
use layout_opt::render::config::DEFAULT_FULL_WELL_ELECTRONS;
use layout_opt::render::Noise;
use layout_opt::scenario::Scenario;
use layout_opt::sphere_image::Observation;
use layout_opt::track::{analyse, Threshold, TrackConfig, TrackedFrame};
use nalgebra::{Rotation3, Vector2, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::sync::OnceLock;

/// The search winner and its part, built once.
pub(crate) fn winner() -> &'static Part {
    static PART: OnceLock<Part> = OnceLock::new();
    PART.get_or_init(Part::winner)
}

/// The pose of a scenario with the marker's origin on the image centre's
/// ray (the paper camera's principal point is low in the frame).
pub fn centred(camera: &Camera, depth_mm: f64, tilt_deg: f64, pan_deg: f64, roll_deg: f64) -> Pose {
    let scenario = Scenario {
        index: 0,
        depth_mm,
        offset_x_mm: (0.5 * camera.width() as f64 - camera.cx()) / camera.fx() * depth_mm,
        offset_y_mm: (0.5 * camera.height() as f64 - camera.cy()) / camera.fy() * depth_mm,
        tilt_deg,
        pan_deg,
        roll_deg,
        sigma_px: 0.5,
    };
    scenario.pose()
}

pub(crate) fn pose_of(tracked: &TrackedFrame) -> Pose {
    let r = nalgebra::Matrix3::from_fn(|i, j| tracked.rotation[i][j]);
    Pose::new(
        Rotation3::from_matrix_unchecked(r),
        Vector3::from(tracked.t),
    )
}

/// Whether the identifiability model predicts labels wrong with
/// probability ≤ 10⁻³ at σ = 0.5 px.
fn identifiable(camera: &Camera, part: &Part, pose: &Pose) -> bool {
    let object = part.layout.positions();
    let radius = part.layout.sphere_radius_mm();
    let normalised: Vec<Vector2<f64>> = object
        .iter()
        .map(|p| {
            Observation::EllipseCentre
                .normalised(&pose.transform(p), radius)
                .unwrap()
        })
        .collect();
    predict(
        camera,
        pose,
        &object,
        &normalised,
        &vec![0.5; object.len()],
        7.5,
    )
    .unwrap()
    .wrong_probability
        <= 1e-3
}

/// Whether every sphere's blob carries its own label.
fn labels_correct(
    tracked: &TrackedFrame,
    blobs: &[layout_opt::track::detect::Blob],
    truth: &layout_opt::render::FrameTruth,
) -> bool {
    truth.spheres.iter().enumerate().all(|(k, sphere)| {
        blob_of_sphere(blobs, sphere).is_some_and(|b| tracked.labels[b] == Some(k))
    })
}

/// Noise-free renders (16 bit, σ 0.5 px blur, 8×8 supersampling) of the
/// search winner on its supports at 200, 600 and 1000 mm, head on to ±60°
/// of tilt. Every whole sphere's ellipse centre and projected centre within
/// 0.1 px of the render's exact ones. In views with no sphere hidden: every
/// blob found, the ellipse centres within 0.05 px RMS, correct labels
/// wherever the identifiability model calls the view identifiable, and the
/// pose within 0.01° (0.02° at 1000 mm, where a background that steps
/// behind two small discs moves their centres by up to 0.04 px).
#[test]
fn noise_free_renders_give_exact_labels_centres_and_poses() {
    let camera = Camera::paper();
    let part = winner();
    let config = TrackConfig::new(&part.layout, camera);
    config.validate().unwrap();
    let render = frames::noise_free(camera, 8);
    let mut views = Vec::new();
    for depth in [200.0, 600.0, 1000.0] {
        for tilt in [-60.0, -30.0, 0.0, 30.0, 60.0] {
            views.push((depth, tilt, 0.0));
        }
    }
    // Views near head on where the supports hide no sphere.
    let mut clean_views: Vec<Pose> = clean_poses(0xC1EA, 2, 600.0, 20.0, |_| true);
    clean_views.extend(clean_poses(0xC1EB, 2, 1000.0, 20.0, |_| true));
    let poses: Vec<(f64, f64, f64, Pose)> = views
        .iter()
        .map(|&(depth, tilt, pan)| (depth, tilt, pan, centred(&camera, depth, tilt, pan, 10.0)))
        .chain(clean_views.into_iter().map(|pose| {
            let depth = if pose.translation.norm() < 800.0 {
                600.0
            } else {
                1000.0
            };
            (depth, f64::NAN, f64::NAN, pose)
        }))
        .collect();
    let results: Vec<(f64, f64, Option<f64>, Vec<f64>)> = poses
        .par_iter()
        .map(|&(depth, tilt, pan, truth)| {
            let rendered = part.render(&render, &truth);
            let analysis = analyse(&config, &rendered.frame());
            let blobs = &analysis.detection.as_ref().unwrap().blobs;
            let clean = clean_view(&rendered.truth, &camera);
            let mut worst = 0.0f64;
            let mut squares = Vec::new();
            for (k, sphere) in rendered.truth.spheres.iter().enumerate() {
                if hidden_fraction(sphere) > 0.0 {
                    continue;
                }
                let Some(b) = blob_of_sphere(blobs, sphere) else {
                    // A whole sphere merged with a neighbour's blob.
                    assert!(!clean, "{depth} mm tilt {tilt}: sphere {k} not found");
                    continue;
                };
                let b = &blobs[b];
                if b.hidden() {
                    continue;
                }
                let ellipse = (Vector2::from(b.ellipse_centre_px) - ellipse_centre(sphere)).norm();
                let centre =
                    (Vector2::from(b.centre_px) - Vector2::from(sphere.projected_centre_px)).norm();
                // A whole sphere beside a support: the support's halo
                // reaches the edge samples (the closing note's figures).
                let bound = 0.1;
                assert!(
                    centre < bound && ellipse < bound,
                    "{depth} mm tilt {tilt}: sphere {k}'s centres off by {ellipse} px (ellipse), {centre} px (projected)"
                );
                if clean {
                    worst = worst.max(ellipse);
                    squares.push(ellipse * ellipse);
                }
            }
            if !clean {
                return (depth, worst, None, squares);
            }
            let tracked = analysis
                .outcome
                .as_ref()
                .unwrap_or_else(|e| panic!("{depth} mm, tilt {tilt}, pan {pan}: {e}"));
            assert_eq!(blobs.len(), 7, "{depth} mm tilt {tilt}");
            assert!(blobs.iter().all(|b| !b.hidden()), "{depth} mm tilt {tilt}");
            let correct = labels_correct(tracked, blobs, &rendered.truth);
            if identifiable(&camera, part, &truth) {
                assert!(
                    correct,
                    "{depth} mm tilt {tilt} pan {pan}: labels {:?}",
                    tracked.labels
                );
            }
            let rotation = rotation_error_deg(&truth.rotation, &pose_of(tracked).rotation);
            // 0.01° to 600 mm. At 1000 mm (13 px discs) spheres P1 and
            // P4 stand just in front of the base plate's edge, so the
            // background behind their limbs steps from the plate's grey to
            // the dark within the edge samples; the edge takes the level
            // next to the limb ([`layout_opt::track`]'s detection), which
            // brought the worst view from 0.0125° to 0.0099° (centres
            // within 0.04 px), but a step inside the first pixel outside
            // still leaves a few hundredths of a pixel, which only a model
            // of the part takes off (`--refine`:
            // `refinement_takes_the_parts_bias_off_the_far_pose`).
            let bound = if depth <= 600.0 { 0.01 } else { 0.02 };
            if correct {
                assert!(
                    rotation < bound,
                    "{depth} mm tilt {tilt} pan {pan}: {rotation}°"
                );
            }
            (depth, worst, correct.then_some(rotation), squares)
        })
        .collect();
    for depth in [200.0, 600.0, 1000.0] {
        let at: Vec<_> = results.iter().filter(|r| r.0 == depth).collect();
        let ellipse = at.iter().map(|r| r.1).fold(0.0, f64::max);
        let squares: Vec<f64> = at.iter().flat_map(|r| r.3.clone()).collect();
        let rms = (squares.iter().sum::<f64>() / squares.len().max(1) as f64).sqrt();
        let rotation = at.iter().filter_map(|r| r.2).fold(0.0, f64::max);
        eprintln!(
            "noise-free {depth} mm, clean views: ellipse-centre error RMS {rms:.4} px, worst {ellipse:.4} px; worst rotation {rotation:.4}° over {} views",
            at.iter().filter(|r| r.2.is_some()).count()
        );
        assert!(
            rms <= 0.05,
            "{depth} mm: ellipse centres off by {rms} px RMS"
        );
    }
    assert!(
        results.iter().filter(|r| r.2.is_some()).count() >= 4,
        "too few clean views: {results:?}"
    );
}

/// Render-and-compare at 1000 mm, where the part behind the limbs of 13 px
/// discs biases the noise-free pose most: the four worst clean views of a
/// dense grid (`track_accuracy clean 1000`, 0.016–0.019° unrefined) and two
/// random clean ones, each refined once by a render of the part at 16×16
/// supersampling (the frames' is 8×8, so the correction is not the frame's
/// own render): every corrected ellipse centre within 0.03 px of the exact
/// one, every pose within 0.01°, and the four worst views closer to the
/// truth than before.
#[test]
fn refinement_takes_the_parts_bias_off_the_far_pose() {
    use layout_opt::track::refine::Refiner;
    let camera = Camera::paper();
    let part = winner();
    let config = TrackConfig::new(&part.layout, camera);
    let render = frames::noise_free(camera, 8);
    let refiner = Refiner::new(part.scene.clone(), frames::noise_free(camera, 16), 1).unwrap();
    let worst = [
        (5.0, -20.0, 100.0),
        (-5.0, -10.0, 10.0),
        (0.0, -15.0, 10.0),
        (15.0, -10.0, 10.0),
    ];
    let poses: Vec<(bool, Pose)> = worst
        .iter()
        .map(|&(tilt, pan, roll)| (true, centred(&camera, 1000.0, tilt, pan, roll)))
        .chain(
            clean_poses(0xF4, 2, 1000.0, 20.0, |_| true)
                .into_iter()
                .map(|p| (false, p)),
        )
        .collect();
    poses.par_iter().for_each(|(was_worst, truth)| {
        let rendered = part.render(&render, truth);
        assert!(clean_view(&rendered.truth, &camera));
        let frame = rendered.frame();
        let first = analyse(&config, &frame);
        let first_pose = first.pose.unwrap();
        let before = rotation_error_deg(&truth.rotation, &first_pose.rotation);
        let refined = refiner.refine(&config, &frame, first);
        let tracked = refined.outcome.as_ref().unwrap();
        let blobs = &refined.detection.as_ref().unwrap().blobs;
        assert!(labels_correct(tracked, blobs, &rendered.truth));
        for sphere in &rendered.truth.spheres {
            let b = &blobs[blob_of_sphere(blobs, sphere).unwrap()];
            let corrected = Vector2::from(b.ellipse_centre_px) - Vector2::from(b.bias.unwrap().px);
            let error = (corrected - ellipse_centre(sphere)).norm();
            assert!(error < 0.03, "{}: {error} px", sphere.name);
        }
        let after = rotation_error_deg(&truth.rotation, &pose_of(tracked).rotation);
        eprintln!("refined at 1000 mm: {before:.4}° → {after:.4}°");
        assert!(after < 0.01, "{before}° → {after}°");
        if *was_worst {
            assert!(after < before, "{before}° → {after}°");
        }
        // The render is the frame's look: every sphere's likeness matches.
        let refinement = tracked.refinement.as_ref().unwrap();
        assert!(
            refinement
                .likeness
                .iter()
                .all(|l| l.is_some_and(|l| l.matches())),
            "{:?}",
            refinement.likeness
        );
        // The record's change is the move from the first pose.
        let change = refinement.rotation_change_deg;
        let moved = rotation_error_deg(&first_pose.rotation, &pose_of(tracked).rotation);
        assert!((change - moved).abs() < 1e-9, "{change}° against {moved}°");
    });
}

/// A seeded random view of the winner around `depth_mm`, within ±40° of
/// head on.
fn random_pose(camera: &Camera, rng: &mut ChaCha8Rng, depth_mm: f64, max_deg: f64) -> Pose {
    centred(
        camera,
        depth_mm * rng.random_range(0.9..1.1),
        rng.random_range(-max_deg..max_deg),
        rng.random_range(-max_deg..max_deg),
        rng.random_range(-180.0..180.0),
    )
}

/// The first `count` clean views (no sphere hidden, all well inside the
/// frame) among seeded random views around `depth_mm` within ±`max_deg`
/// that `keep` accepts, checked on the render's truth alone.
fn clean_poses(
    seed: u64,
    count: usize,
    depth_mm: f64,
    max_deg: f64,
    keep: impl Fn(&Pose) -> bool + Sync,
) -> Vec<Pose> {
    clean_views(seed, count, depth_mm, max_deg, keep)
        .into_iter()
        .map(|(pose, _)| pose)
        .collect()
}

/// Limb rays per sphere of the truth that finds clean views: a quarter of
/// the render's, so a support that hides less than 1/512 of an outline
/// (0.7°, a quarter pixel of a 20 px disc's) may go unseen; the tests that
/// need a count of hidden outline trace the render's own truth.
const CLEAN_RAYS: usize = 512;

/// [`clean_poses`] with each view's truth (at the paper camera), its
/// hidden fractions over [`CLEAN_RAYS`] limb rays. The candidates (at most
/// 8 per view wanted) are judged a thread's worth at a time, in seed
/// order, until `count` are found: the same views at any thread count, and
/// no truth traced beyond the batch that completes them.
pub(crate) fn clean_views(
    seed: u64,
    count: usize,
    depth_mm: f64,
    max_deg: f64,
    keep: impl Fn(&Pose) -> bool + Sync,
) -> Vec<(Pose, layout_opt::render::FrameTruth)> {
    let camera = Camera::paper();
    let part = winner();
    let limit = count as u64 * 8;
    let batch = rayon::current_num_threads().max(1) as u64;
    let mut found = Vec::new();
    let mut next = 0;
    while found.len() < count && next < limit {
        let end = (next + batch).min(limit);
        let views: Vec<_> = (next..end)
            .into_par_iter()
            .filter_map(|k| {
                let mut rng = ChaCha8Rng::seed_from_u64(seed + k);
                let pose = random_pose(&camera, &mut rng, depth_mm, max_deg);
                if !keep(&pose) {
                    return None;
                }
                let truth = part.truth_over(&camera, &pose, CLEAN_RAYS);
                clean_view(&truth, &camera).then_some((pose, truth))
            })
            .collect();
        found.extend(views);
        next = end;
    }
    assert!(found.len() >= count, "only {} clean views", found.len());
    found.truncate(count);
    found
}

/// Seeded noisy renders of random, clean views: `poses` poses, each read
/// `realisations` times by the 8-bit sensor with `full_well_electrons`,
/// each rendered through the window round the marker's discs
/// ([`frames::crop`], [`CROP_MARGIN_PX`]): the tracker sees every blob and
/// its surround, and the exposure pays for no empty background. Returns,
/// per frame, the truth pose, the analysis and whether every label is
/// right.
fn noisy_frames(
    seed: u64,
    poses: usize,
    realisations: u64,
    depth_mm: f64,
    full_well_electrons: f64,
    keep: impl Fn(&Pose) -> bool + Sync,
) -> Vec<(Pose, layout_opt::track::FrameAnalysis, usize)> {
    let camera = Camera::paper();
    let part = winner();
    let mut render = frames::noisy(camera, 4);
    render.sensor.noise = Some(Noise {
        full_well_electrons,
        ..Noise::default()
    });
    let rendered: Vec<(Pose, frames::Rendered, TrackConfig)> =
        clean_views(seed, poses, depth_mm, 30.0, keep)
            .into_par_iter()
            .map(|(pose, truth)| {
                let window = frames::crop(&camera, &truth, CROP_MARGIN_PX, |_| true);
                let mut render = render.clone();
                render.camera = window;
                (
                    pose,
                    part.render_window(&render, &pose, &camera, &truth),
                    TrackConfig::new(&part.layout, window),
                )
            })
            .collect();
    (0..poses as u64 * realisations)
        .into_par_iter()
        .map(|frame| {
            let index = (frame / realisations) as usize;
            let (truth, render, config) = &rendered[index];
            let analysis = analyse(config, &render.expose(seed, frame));
            let correct = match (&analysis.outcome, &analysis.detection) {
                (Ok(tracked), Some(detection)) => {
                    usize::from(labels_correct(tracked, &detection.blobs, &render.truth))
                }
                _ => 0,
            };
            (*truth, analysis, correct)
        })
        .collect()
}

/// Noisy 8-bit renders at 400 mm (a 1,000-electron full well: 3 % shot
/// noise at full scale, so that the noise, not the edge model's residual
/// bias, sets the error), σ from each frame's blobs: each of the six pose
/// components lies within its predicted 1σ in 66–80% of the frames
/// (68% for an exact σ; the residuals only ever grow the blobs' σ, which
/// leaves it about 10% wide where the model holds: 72% when written.
/// The 1σ share of σ estimated from the residuals alone was 65%, its
/// Student-t expectation on 2n − 6 = 8 degrees of freedom).
#[test]
fn predicted_one_sigma_brackets_the_actual_error() {
    const POSES: usize = 24;
    const REALISATIONS: u64 = 10;
    let frames = noisy_frames(0x7AC0, POSES, REALISATIONS, 400.0, 1_000.0, |_| true);
    let tracked: Vec<[bool; 6]> = frames
        .iter()
        .filter_map(|(truth, analysis, _)| {
            let tracked = analysis.outcome.as_ref().ok()?;
            if !tracked.missing.is_empty() {
                return None;
            }
            let f = &tracked.figures;
            let truth_rvec = truth.rotation.scaled_axis();
            let errors = [
                f.rvec[0] - truth_rvec.x,
                f.rvec[1] - truth_rvec.y,
                f.rvec[2] - truth_rvec.z,
                f.tvec[0] - truth.translation.x,
                f.tvec[1] - truth.translation.y,
                f.tvec[2] - truth.translation.z,
            ];
            Some(std::array::from_fn(|i| {
                errors[i].abs() <= f.covariance[i][i].sqrt()
            }))
        })
        .collect();
    assert!(
        tracked.len() as u64 >= POSES as u64 * REALISATIONS * 3 / 4,
        "only {} frames tracked",
        tracked.len()
    );
    let inside = tracked.iter().flatten().filter(|b| **b).count();
    let share = inside as f64 / (6 * tracked.len()) as f64;
    eprintln!(
        "noisy renders: {} tracked; {:.1}% of pose components within the predicted 1σ",
        tracked.len(),
        100.0 * share
    );
    assert!((0.66..=0.80).contains(&share), "{share}");
}

/// Noisy 8-bit renders of clean views the identifiability model calls
/// identifiable at σ = 0.5 px (wrong labels ≤ 10⁻³): at most one tracked
/// frame in 300 with a wrong label (with a true rate of 99.9 % that passes
/// with probability 0.96; at 99 % with probability 0.2), and at least 90 %
/// of the frames tracked (the rest refused with a reason, not mislabelled).
/// The large count is `cargo run --release --features examples --example track_accuracy --
/// labels`.
#[test]
fn identifiable_views_are_labelled_correctly() {
    let camera = Camera::paper();
    let part = winner();
    let frames = noisy_frames(0x1AB, 30, 10, 600.0, DEFAULT_FULL_WELL_ELECTRONS, |pose| {
        identifiable(&camera, part, pose)
    });
    let tracked = frames.iter().filter(|f| f.1.outcome.is_ok()).count();
    let correct: usize = frames.iter().map(|f| f.2).sum();
    let mut refused: Vec<String> = frames
        .iter()
        .filter_map(|f| f.1.outcome.as_ref().err())
        .map(|e| e.to_string().chars().take(40).collect())
        .collect();
    refused.sort();
    refused.dedup();
    eprintln!(
        "identifiable views: {} frames, {tracked} tracked, {correct} with every label right; refusals: {refused:?}",
        frames.len()
    );
    assert!(
        tracked * 10 >= frames.len() * 9,
        "{tracked} of {}",
        frames.len()
    );
    assert!(correct + 1 >= tracked, "{correct} of {tracked}");
}

/// Renders of random views, head on to ±60°, where the part's supports and
/// the spheres hide one another: a blob flagged as partly hidden is hidden
/// per the render's truth (precision ≥ 95%), and ≥ 90% of the blobs with
/// ≥ 10% of their AREA hidden ([`frames::area_hidden`]) are flagged. A
/// support that hides much of the outline but little of the area (a
/// sphere's own cone seen far off its axis cuts a notch into the limb) is
/// cut away by the detector, which measures the blob from the rest of its
/// outline: the unflagged blobs with ≥ 10% of their outline hidden have
/// ellipse centres within 0.03 px of the truth at the median and 0.1 px at
/// worst (before the cut: 0.07 px median for notches ≥ 0.3 px deep, which
/// were flagged and left out). The
/// example `track_accuracy -- hidden` gives the large counts.
#[test]
fn blobs_flagged_behind_supports_are_hidden() {
    let camera = Camera::paper();
    let part = winner();
    let config = TrackConfig::new(&part.layout, camera);
    let render = frames::noisy(camera, 4);
    // Per frame: [flagged & hidden, flagged & whole, ≥ 10% of the area
    // hidden & flagged, the same & not], and the centre errors of
    // unflagged blobs with ≥ 10% of the outline hidden.
    let reach_px = layout_opt::track::detect::MIN_EDGE_TOLERANCE_PX;
    // (error px, notch ≥ reach_px deep) per unflagged notched blob.
    type Missed = Vec<(f64, bool)>;
    let counts: Vec<([usize; 4], Missed)> = (0..30u64)
        .into_par_iter()
        .filter_map(|k| {
            let mut rng = ChaCha8Rng::seed_from_u64(0x41D + k);
            let truth = centred(
                &camera,
                rng.random_range(250.0..800.0),
                rng.random_range(-60.0..60.0),
                rng.random_range(-60.0..60.0),
                rng.random_range(-180.0..180.0),
            );
            let rendered = part.render(&render, &truth);
            let analysis = analyse(&config, &rendered.expose(0x41D, k));
            let blobs = &analysis.detection.as_ref()?.blobs;
            let mut c = [0usize; 4];
            let mut missed = Vec::new();
            for (index, sphere) in rendered.truth.spheres.iter().enumerate() {
                let Some(b) = blob_of_sphere(blobs, sphere).map(|i| &blobs[i]) else {
                    continue;
                };
                let hidden = hidden_fraction(sphere);
                if b.hidden() {
                    c[usize::from(hidden == 0.0)] += 1;
                }
                if hidden == 0.0 {
                    continue;
                }
                if frames::area_hidden(&part.scene, &truth, &camera, sphere, index) >= 0.1 {
                    c[2 + usize::from(!b.hidden())] += 1;
                }
                if hidden >= 0.1 && !b.hidden() {
                    let error =
                        (Vector2::from(b.ellipse_centre_px) - ellipse_centre(sphere)).norm();
                    let reach = frames::support_reach_px(&part.scene, &truth, &camera, index, 128);
                    missed.push((error, reach >= reach_px));
                }
            }
            Some((c, missed))
        })
        .collect();
    let total = counts
        .iter()
        .fold([0; 4], |a, (c, _)| std::array::from_fn(|i| a[i] + c[i]));
    let deep = counts.iter().flat_map(|c| &c.1).filter(|m| m.1).count();
    let mut missed: Vec<f64> = counts
        .iter()
        .flat_map(|c| c.1.iter().map(|m| m.0))
        .collect();
    missed.sort_by(f64::total_cmp);
    let median = missed.get(missed.len() / 2).copied().unwrap_or(f64::NAN);
    let worst = missed.last().copied().unwrap_or(f64::NAN);
    let precision = total[0] as f64 / (total[0] + total[1]) as f64;
    let recall = total[2] as f64 / (total[2] + total[3]) as f64;
    eprintln!("supports: {} frames: {} flagged hidden, {} flagged whole, ≥ 10% of the area hidden: {} flagged, {} not: precision {precision:.3}, recall {recall:.3}; {} unflagged blobs ≥ 10% of the outline hidden, {deep} of them with a notch ≥ {reach_px} px deep; centres off by {median:.3} px median, {worst:.3} px at worst", counts.len(), total[0], total[1], total[2], total[3], missed.len());
    assert!(total[0] >= 20 && total[2] + total[3] >= 5, "{total:?}");
    assert!(
        missed.len() >= 40,
        "{} unflagged notched blobs",
        missed.len()
    );
    assert!(precision >= 0.95, "{total:?}");
    assert!(recall >= 0.90, "{total:?}");
    assert!(median < 0.03, "{median} px");
    assert!(worst < 0.1, "{worst} px");
}

/// `[flagged & hidden, flagged & whole, ≥ 10% hidden & unflagged]` over
/// the spheres of one frame; `extra` adds to the render's hidden fractions
/// (NaN: leave the sphere out).
fn flag_counts(
    blobs: &[layout_opt::track::detect::Blob],
    truth: &layout_opt::render::FrameTruth,
    extra: &[f64],
) -> [usize; 3] {
    let mut c = [0usize; 3];
    for (sphere, more) in truth.spheres.iter().zip(extra) {
        let Some(b) = blob_of_sphere(blobs, sphere).map(|i| &blobs[i]) else {
            continue;
        };
        let hidden = hidden_fraction(sphere) + more;
        if hidden.is_nan() {
            continue;
        }
        match (b.hidden(), hidden > 0.0) {
            (true, true) => c[0] += 1,
            (true, false) => c[1] += 1,
            (false, _) if hidden >= 0.1 => c[2] += 1,
            _ => {}
        }
    }
    c
}

fn sum_counts(counts: &[[usize; 3]]) -> [usize; 3] {
    counts
        .iter()
        .fold([0; 3], |a, c| [a[0] + c[0], a[1] + c[1], a[2] + c[2]])
}

/// Bars painted on each pose of [`hidden_flags_match_the_ground_truth`].
const BARS: u64 = 8;

/// Margin round the discs of a cropped render ([`frames::crop`]), px: the
/// detector's coarse cells and measurement window, and the blur's tail,
/// with room to spare.
pub(crate) const CROP_MARGIN_PX: f64 = 12.0;

/// Clean views with a dark bar painted across a random sphere at a random
/// depth into it: the partly-hidden flag against the share of the
/// sphere's exact outline under the bar. Precision ≥ 95% (flagged blobs
/// are hidden), recall ≥ 90% for blobs with ≥ 10% hidden.
///
/// Each pose is rendered once, through the window round the marker's discs
/// ([`frames::crop`]: every blob and its surround, none of the frame's
/// empty background), and each bar is painted on a copy of it. A bar
/// through a small disc's middle can leave no blob that is the sphere's;
/// about a quarter of the bars give a flagged hidden blob (21 of 75 at 5
/// bars on 15 poses, 72 of 192 here), so at least a fifth must, or the
/// precision and recall below would rest on too few.
#[test]
fn hidden_flags_match_the_ground_truth() {
    let camera = Camera::paper();
    let part = winner();
    let views: Vec<(Pose, layout_opt::render::FrameTruth)> = [350.0, 550.0, 800.0]
        .into_iter()
        .enumerate()
        .flat_map(|(i, depth)| clean_views(0xB1D + 1000 * i as u64, 8, depth, 20.0, |_| true))
        .collect();

    let counts: Vec<[usize; 3]> = views
        .par_iter()
        .enumerate()
        .flat_map_iter(|(k, (pose, truth))| {
            let window = frames::crop(&camera, truth, CROP_MARGIN_PX, |_| true);
            let config = TrackConfig::new(&part.layout, window);
            let clean = part.render_window(&frames::noisy(window, 4), pose, &camera, truth);
            let mut rng = ChaCha8Rng::seed_from_u64(0xB1D + k as u64);
            (0..BARS)
                .map(|bar| {
                    let target = rng.random_range(0..7);
                    let sphere = &clean.truth.spheres[target];
                    let angle: f64 = rng.random_range(0.0..std::f64::consts::PI);
                    let normal = Vector2::new(-angle.sin(), angle.cos());
                    let half_width = 6.0;
                    let cut = rng.random_range(-0.8..0.6) * sphere.semi_axes_px[0];
                    let mut rendered = frames::Rendered {
                        radiance: clean.radiance.clone(),
                        truth: clean.truth.clone(),
                        config: clean.config.clone(),
                    };
                    let painted = frames::paint_bar(
                        &mut rendered,
                        &frames::Bar {
                            centre: ellipse_centre(sphere) - normal * (cut + half_width),
                            angle,
                            half_width,
                            half_length: 1.5 * sphere.semi_axes_px[0],
                        },
                        0.02,
                    );
                    // A sphere whose outline the bar misses by less than
                    // the blur's reach is neither hidden nor whole.
                    let extra: Vec<f64> = painted
                        .iter()
                        .map(|&(share, gap)| {
                            if share == 0.0 && gap < 2.0 {
                                f64::NAN
                            } else {
                                share
                            }
                        })
                        .collect();
                    let analysis = analyse(&config, &rendered.expose(0xB1D, BARS * k as u64 + bar));
                    analysis
                        .detection
                        .as_ref()
                        .map_or([0; 3], |d| flag_counts(&d.blobs, &rendered.truth, &extra))
                })
                .collect::<Vec<_>>()
        })
        .collect();
    let total = sum_counts(&counts);
    let precision = total[0] as f64 / (total[0] + total[1]) as f64;
    let recall = total[0] as f64 / (total[0] + total[2]) as f64;
    eprintln!("bars: {} frames: {} flagged hidden, {} flagged whole, {} missed (≥10% hidden): precision {precision:.3}, recall {recall:.3}", counts.len(), total[0], total[1], total[2]);
    assert!(total[0] * 5 >= counts.len(), "{total:?}");
    assert!(precision >= 0.95, "{total:?}");
    assert!(recall >= 0.90, "{total:?}");
}

/// A clean view rendered under light that falls off by a factor of three
/// across the frame (the render's radiance scaled by a smooth gradient):
/// the local threshold finds and labels every sphere with centres within
/// 0.05 px, where the global Otsu level loses the dim side's spheres or
/// merges nothing.
#[test]
fn the_local_threshold_tracks_under_uneven_light() {
    let camera = Camera::paper();
    let part = winner();
    let truth = clean_poses(0x11, 1, 500.0, 20.0, |_| true)[0];
    let mut rendered = part.render(&frames::noise_free(camera, 4), &truth);
    let width = rendered.radiance.width;
    for (i, v) in rendered.radiance.values.iter_mut().enumerate() {
        let x = (i % width) as f32 / width as f32;
        *v *= 1.0 - 0.67 * x;
    }
    let frame = rendered.frame();
    let mut config = TrackConfig::new(&part.layout, camera);
    config.detector.threshold = "local".parse::<Threshold>().unwrap();
    config.validate().unwrap();
    let analysis = analyse(&config, &frame);
    let tracked = analysis.outcome.as_ref().unwrap();
    let blobs = &analysis.detection.as_ref().unwrap().blobs;
    assert_eq!(blobs.len(), 7);
    assert!(labels_correct(tracked, blobs, &rendered.truth));
    for sphere in &rendered.truth.spheres {
        let b = &blobs[blob_of_sphere(blobs, sphere).unwrap()];
        let error = (Vector2::from(b.ellipse_centre_px) - ellipse_centre(sphere)).norm();
        assert!(error < 0.05, "{}: {error} px", sphere.name);
    }
    let rotation = rotation_error_deg(&truth.rotation, &pose_of(tracked).rotation);
    assert!(rotation < 0.02, "{rotation}°");
}

/// A clean view through the paper's distorted lens: the edge points are
/// undistorted before the fit, so the ellipse centres (in raw pixels) match
/// the render's within 0.05 px and the pose within 0.01°.
#[test]
fn a_distorted_lens_is_undone_before_the_fit() {
    let camera = Camera::paper_with_distortion();
    let part = winner();
    let truth = clean_poses(0xD1, 1, 450.0, 20.0, |_| true)[0];
    let rendered = part.render(&frames::noise_free(camera, 4), &truth);
    assert!(clean_view(&rendered.truth, &camera));
    let frame = rendered.frame();
    let config = TrackConfig::new(&part.layout, camera);
    let analysis = analyse(&config, &frame);
    let tracked = analysis.outcome.as_ref().unwrap();
    let blobs = &analysis.detection.as_ref().unwrap().blobs;
    assert!(labels_correct(tracked, blobs, &rendered.truth));
    for sphere in &rendered.truth.spheres {
        let b = &blobs[blob_of_sphere(blobs, sphere).unwrap()];
        let error = (Vector2::from(b.ellipse_centre_px) - ellipse_centre(sphere)).norm();
        assert!(error < 0.05, "{}: {error} px", sphere.name);
    }
    let rotation = rotation_error_deg(&truth.rotation, &pose_of(tracked).rotation);
    assert!(rotation < 0.01, "{rotation}°");
}

/// Malformed frames: each is one error record naming what is wrong, and the
/// good frame among them is still tracked.
#[test]
fn malformed_frames_are_error_records_and_the_run_goes_on() {
    use layout_opt::observer::Silent;
    use layout_opt::track::workflow::{run, TrackOutputs};
    let camera = Camera::paper();
    let part = winner();
    let config = TrackConfig::new(&part.layout, camera);
    let dir = tempfile::tempdir().unwrap();
    let good_png = good_frame_png();
    let write = |name: &str, bytes: &[u8]| std::fs::write(dir.path().join(name), bytes).unwrap();
    write("a-good.png", &good_png);
    write("b-empty.png", &[]);
    write("c-truncated.png", &good_png[..good_png.len() / 2]);
    let mut rgb = Vec::new();
    image::RgbImage::new(1280, 720)
        .write_to(&mut std::io::Cursor::new(&mut rgb), image::ImageFormat::Png)
        .unwrap();
    write("d-rgb.png", &rgb);
    // 10,000 small bright blobs of noise.
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut pixels = vec![10u16; 1280 * 720];
    for _ in 0..10_000 {
        let (x, y) = (
            rng.random_range(2..1277usize),
            rng.random_range(2..717usize),
        );
        for dy in 0..3 {
            for dx in 0..3 {
                pixels[(y + dy - 1) * 1280 + x + dx - 1] = 240;
            }
        }
    }
    write(
        "e-noise.png",
        &layout_opt::track::GreyFrame::new(1280, 720, 8, pixels)
            .unwrap()
            .to_png(),
    );
    write(
        "f-small.png",
        &layout_opt::track::GreyFrame::new(64, 48, 8, vec![0; 64 * 48])
            .unwrap()
            .to_png(),
    );
    write(
        "g-dark.png",
        &layout_opt::track::GreyFrame::new(1280, 720, 8, vec![12; 1280 * 720])
            .unwrap()
            .to_png(),
    );
    // The good frame with three more bright discs below the marker, near
    // the principal point (where a sphere's image is round, so they pass
    // as whole): ten whole blobs for seven spheres, one more than the two
    // extra allowed.
    let mut clutter = layout_opt::track::GreyFrame::from_png(&good_png).unwrap();
    for (cx, cy) in [(420.0, 640.0), (880.0, 640.0), (653.0, 690.0)] {
        paint_disc(&mut clutter, cx, cy, 8.0);
    }
    write("h-clutter.png", &clutter.to_png());
    let out = dir.path().join("out.jsonl");
    let outputs = TrackOutputs {
        sources: Vec::new(),
        json_lines: Some(out.clone()),
        csv: Some(dir.path().join("out.csv")),
        overlay_dir: Some(dir.path().join("overlay")),
    };
    let result = run(
        &config,
        None,
        &[dir.path().to_path_buf()],
        &outputs,
        &mut Silent,
    )
    .unwrap();
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 8);
    assert_eq!(result.tracked(), 1);
    assert!(
        lines[0]["R"].is_array() && lines[0]["covariance"].as_array().unwrap().len() == 6,
        "{}",
        lines[0]
    );
    let expect = [
        (1, "empty (0 bytes)"),
        (2, "truncated or corrupt"),
        (
            3,
            "8-bit RGB colour PNG; expected an 8- or 16-bit greyscale PNG",
        ),
        (4, "blobs"),
        (5, "the image is 64×48 px but the camera is 1280×720 px"),
        (6, "no blobs found"),
        (
            7,
            "too many blobs: 10 whole blobs for 7 spheres, more than the 2 extra allowed",
        ),
    ];
    for (index, needle) in expect {
        let error = lines[index]["error"]
            .as_str()
            .unwrap_or_else(|| panic!("{}", lines[index]));
        assert!(error.contains(needle), "{index}: {error}");
        assert!(lines[index]["frame"].as_str().unwrap().ends_with(".png"));
    }
    assert!(dir.path().join("overlay/a-good.overlay.png").exists());
    let csv = std::fs::read_to_string(dir.path().join("out.csv")).unwrap();
    assert_eq!(csv.lines().count(), 9);
}

/// The paper's biprism is symmetric: every rotation that maps its cross of
/// arms onto itself turns one labelling of its blobs into another that
/// fits as well (seen tilted about its X axis with its centre on the
/// optical axis, for one, its mirror image in the plane x = 0 is itself
/// with P2 and P4 swapped). Each such frame is an error record naming its
/// file and the ambiguity, and the run goes on to the next frame.
#[test]
fn an_ambiguous_identification_is_an_error_record_and_the_run_goes_on() {
    use layout_opt::observer::Silent;
    use layout_opt::track::workflow::{run, TrackOutputs};
    let camera = Camera::paper();
    let part = frames::Part::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("layouts/biprism-paper.json"),
    );
    let config = TrackConfig::new(&part.layout, camera);
    let dir = tempfile::tempdir().unwrap();
    let render = frames::noisy(camera, 2);
    let on_axis = Scenario {
        index: 0,
        depth_mm: 500.0,
        offset_x_mm: 0.0,
        offset_y_mm: 0.0,
        tilt_deg: 30.0,
        pan_deg: 0.0,
        roll_deg: 0.0,
        sigma_px: 0.5,
    };
    let names = ["a-mirror.png", "b-oblique.png"];
    for (name, pose) in names
        .iter()
        .zip([on_axis.pose(), centred(&camera, 400.0, 35.0, 25.0, 20.0)])
    {
        let frame = part.render(&render, &pose).expose(9, 0);
        std::fs::write(dir.path().join(name), frame.to_png()).unwrap();
    }
    let out = dir.path().join("out.jsonl");
    let outputs = TrackOutputs {
        sources: Vec::new(),
        json_lines: Some(out.clone()),
        csv: None,
        overlay_dir: None,
    };
    let result = run(
        &config,
        None,
        &[dir.path().to_path_buf()],
        &outputs,
        &mut Silent,
    )
    .unwrap();
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 2);
    for (line, name) in lines.iter().zip(names) {
        assert!(
            line["frame"].as_str().unwrap().ends_with(name),
            "{name}: {line}"
        );
        let error = line["error"]
            .as_str()
            .unwrap_or_else(|| panic!("{name}: {line}"));
        assert!(
            error.contains("ambiguous identification") && error.contains("ambiguity 1.0"),
            "{name}: {error}"
        );
        assert!(line["R"].is_null(), "{name}: {line}");
    }
    assert_eq!(result.tracked(), 0);
}

/// Paints a bright disc of radius `radius_px` centred at `(cx, cy)` over
/// `frame`, area-sampled on a 4×4 grid per pixel.
fn paint_disc(frame: &mut layout_opt::track::GreyFrame, cx: f64, cy: f64, radius_px: f64) {
    let (width, height) = (frame.width() as usize, frame.height() as usize);
    let bright = 0.9 * f64::from(frame.full_scale());
    let mut pixels = frame.pixels().to_vec();
    for y in 0..height {
        for x in 0..width {
            if (x as f64 - cx).abs() > radius_px + 1.0 || (y as f64 - cy).abs() > radius_px + 1.0 {
                continue;
            }
            let covered = (0..16u32)
                .filter(|k| {
                    let px = x as f64 - 0.5 + (f64::from(k % 4) + 0.5) / 4.0;
                    let py = y as f64 - 0.5 + (f64::from(k / 4) + 0.5) / 4.0;
                    (px - cx).hypot(py - cy) < radius_px
                })
                .count() as f64
                / 16.0;
            let v = &mut pixels[y * width + x];
            *v = (f64::from(*v) * (1.0 - covered) + bright * covered).round() as u16;
        }
    }
    *frame =
        layout_opt::track::GreyFrame::new(frame.width(), frame.height(), frame.bit_depth(), pixels)
            .unwrap();
}

/// An 8-bit noisy render of a clean view of the winner at 500 mm, as PNG.
pub fn good_frame_png() -> Vec<u8> {
    let camera = Camera::paper();
    let truth = clean_poses(0x600D, 1, 500.0, 20.0, |_| true)[0];
    let rendered = winner().render(&frames::noisy(camera, 4), &truth);
    rendered.expose(5, 0).to_png()
}

/// Writes example frames (200, 600 and 1000 mm, head on and tilted 40°)
/// rendered with the part's supports into `$TRACK_FRAMES_DIR` for trying
/// the command by hand (the README's example): `TRACK_FRAMES_DIR=/tmp/frames
/// cargo test --release --test it track::write_example_frames -- --ignored`.
#[test]
#[ignore = "writes example frames for the README where told"]
fn write_example_frames() {
    let dir =
        std::path::PathBuf::from(std::env::var("TRACK_FRAMES_DIR").expect("set TRACK_FRAMES_DIR"));
    std::fs::create_dir_all(&dir).unwrap();
    let camera = Camera::paper();
    let part = winner();
    let render = frames::noisy(camera, 4);
    for (k, (depth, tilt)) in [
        (200.0, 0.0),
        (200.0, 40.0),
        (600.0, 0.0),
        (600.0, 40.0),
        (1000.0, 0.0),
        (1000.0, 40.0),
    ]
    .into_iter()
    .enumerate()
    {
        let truth = centred(&camera, depth, tilt, 20.0, 15.0);
        let frame = part.render(&render, &truth).expose(1, k as u64);
        std::fs::write(
            dir.join(format!("frame-{depth:.0}mm-tilt{tilt:.0}.png")),
            frame.to_png(),
        )
        .unwrap();
    }
}
