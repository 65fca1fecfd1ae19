//! `track` against the renderer's ground truth, at counts too large for the
//! test suite: the figures of the tracker's closing note.
//!
//! ```text
//! cargo run --release --features examples --example track_accuracy -- centres
//! cargo run --release --features examples --example track_accuracy -- labels [POSES] [REALISATIONS]
//! cargo run --release --features examples --example track_accuracy -- hidden [POSES]
//! cargo run --release --features examples --example track_accuracy -- speed [RUNS]
//! cargo run --release --features examples --example track_accuracy -- lost [TRIALS] [TILT_STEP]
//! cargo run --release --features examples --example track_accuracy -- bias
//! cargo run --release --features examples --example track_accuracy -- clean [DEPTH_MM [REFINE_SUPERSAMPLING [REFINE_BLUR_PX]]]
//! cargo run --release --features examples --example track_accuracy -- noisy [DEPTH_MM [REALISATIONS [REFINE_SUPERSAMPLING]]]
//! ```
//!
//! * `centres`: noise-free renders (16 bit, σ 0.5 px blur, 8×8
//!   supersampling) of the search winner at 200, 600 and 1000 mm, tilt
//!   −60…60° and pan −30…30°: for each distance, the RMS and worst error of
//!   each centre method (ellipse fit, intensity centroid, projected sphere
//!   centre) against the render's exact ellipse (projected) centres over
//!   whole spheres, and the worst rotation error of the views where no
//!   sphere is hidden.
//! * `clean`: noise-free renders (as `centres`) at `DEPTH_MM` (1000 by
//!   default) on a dense grid, tilt −40…40° and pan −30…30° in 5° steps,
//!   rolls 10° and 100°, the views with no sphere hidden: the spread of
//!   the rotation error, the views beyond 0.01°, and the six worst with
//!   each sphere's ellipse-centre error (x, y) in px. With
//!   `REFINE_SUPERSAMPLING`, each frame is refined ([`Refiner`], one
//!   round) by a render of the part at that supersampling and Gaussian blur
//!   `REFINE_BLUR_PX` (0.5 by default; the frames' own is 0.5), and the
//!   centre errors are those of the corrected centres.
//! * `noisy`: the `clean` views at `DEPTH_MM` (1000) read `REALISATIONS`
//!   (5) times each by the default noisy 8-bit sensor (4×4 supersampling):
//!   the RMS rotation error unrefined and refined by a render at
//!   `REFINE_SUPERSAMPLING` (8).
//! * `labels`: random views at 300–900 mm within ±30° of head on, those
//!   where the identifiability model predicts ≥ 99.9 % correct labels at
//!   σ = 0.5 px and no sphere is hidden, each read `REALISATIONS` times by
//!   the default noisy 8-bit
//!   sensor: the share of frames whose labels are all correct, and the
//!   spread of the ellipse centres.
//! * `hidden`: random views at 250–800 mm within ±60°: what the tracker did
//!   with the spheres the render says are partly hidden, by hidden share
//!   of the outline and by how deep the support's notch reaches into the
//!   disc ([`frames::support_reach_px`]).
//! * `lost`: `validate --images`' part (supports routed for the paper's
//!   protocol) and grid (`TILT_STEP`, 10° by default; `validate`'s own
//!   default is 2°) for the winner, each visible
//!   scenario read `TRIALS` times with seed 7: the share of frames lost by
//!   reason, and per view the first lost frame's blobs flagged as partly
//!   hidden (or missing) beside the render's hidden fractions, the
//!   visibility model's support share, the notch depth, the centre error
//!   and the parts that hide the outline.

#[path = "../tests/it/track/frames.rs"]
#[allow(dead_code)]
mod frames;

use frames::{
    area_hidden, blob_of_sphere, clean_view, ellipse_centre, hidden_fraction, support_reach_px,
    Part,
};
use layout_opt::camera::Camera;
use layout_opt::identifiability::predict;
use layout_opt::pose::{rotation_error_deg, Pose};
use layout_opt::scenario::Scenario;
use layout_opt::sphere_image::Observation;
use layout_opt::track::refine::Refiner;
use layout_opt::track::{analyse, TrackConfig, TrackedFrame};
use nalgebra::{Rotation3, Vector2, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// The scenario pose with the marker origin on the image centre's ray.
fn centred(camera: &Camera, depth_mm: f64, tilt_deg: f64, pan_deg: f64, roll_deg: f64) -> Pose {
    Scenario {
        index: 0,
        depth_mm,
        offset_x_mm: (0.5 * camera.width() as f64 - camera.cx()) / camera.fx() * depth_mm,
        offset_y_mm: (0.5 * camera.height() as f64 - camera.cy()) / camera.fy() * depth_mm,
        tilt_deg,
        pan_deg,
        roll_deg,
        sigma_px: 0.5,
    }
    .pose()
}

/// The first view at `depth_mm` with no sphere hidden, on a grid of tilts
/// and pans within ±20°.
pub fn first_clean(part: &Part, camera: &Camera, depth_mm: f64) -> Pose {
    (-4..=4)
        .flat_map(|t| (-4..=4).map(move |p| (5.0 * t as f64, 5.0 * p as f64)))
        .map(|(tilt, pan)| centred(camera, depth_mm, tilt, pan, 20.0))
        .find(|pose| {
            clean_view(
                &part.truth_over(camera, pose, layout_opt::render::truth::SILHOUETTE_RAYS),
                camera,
            )
        })
        .expect("a clean view")
}

fn pose_of(tracked: &TrackedFrame) -> Pose {
    let r = nalgebra::Matrix3::from_fn(|i, j| tracked.rotation[i][j]);
    Pose::new(
        Rotation3::from_matrix_unchecked(r),
        Vector3::from(tracked.t),
    )
}

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
    .is_ok_and(|p| p.wrong_probability <= 1e-3)
}

fn centres(part: &Part, camera: Camera) {
    let config = TrackConfig::new(&part.layout, camera);
    let render = frames::noise_free(camera, 8);
    for depth in [200.0, 600.0, 1000.0] {
        let views: Vec<(f64, f64)> = [-60.0, -40.0, -20.0, 0.0, 20.0, 40.0, 60.0]
            .into_iter()
            .flat_map(|tilt| [-30.0, 0.0, 30.0].map(|pan| (tilt, pan)))
            .collect();
        let results: Vec<([Vec<f64>; 3], Option<f64>)> = views
            .par_iter()
            .map(|&(tilt, pan)| {
                let truth = centred(&camera, depth, tilt, pan, 10.0);
                let rendered = part.render(&render, &truth);
                let analysis = analyse(&config, &rendered.frame());
                let mut errors: [Vec<f64>; 3] = Default::default();
                let Some(detection) = analysis.detection.as_ref() else {
                    return (errors, None);
                };
                for sphere in &rendered.truth.spheres {
                    if hidden_fraction(sphere) > 0.0 {
                        continue;
                    }
                    let Some(b) = blob_of_sphere(&detection.blobs, sphere) else {
                        continue;
                    };
                    let b = &detection.blobs[b];
                    if b.hidden() {
                        continue;
                    }
                    let exact = ellipse_centre(sphere);
                    errors[0].push((Vector2::from(b.ellipse_centre_px) - exact).norm());
                    errors[1].push((Vector2::from(b.centroid_px) - exact).norm());
                    errors[2].push(
                        (Vector2::from(b.centre_px) - Vector2::from(sphere.projected_centre_px))
                            .norm(),
                    );
                }
                let rotation = match &analysis.outcome {
                    Ok(tracked) if clean_view(&rendered.truth, &camera) => Some(
                        rotation_error_deg(&truth.rotation, &pose_of(tracked).rotation),
                    ),
                    _ => None,
                };
                (errors, rotation)
            })
            .collect();
        let stat = |k: usize| {
            let all: Vec<f64> = results.iter().flat_map(|r| r.0[k].clone()).collect();
            let rms = (all.iter().map(|e| e * e).sum::<f64>() / all.len() as f64).sqrt();
            (all.len(), rms, all.iter().cloned().fold(0.0, f64::max))
        };
        let rotations: Vec<f64> = results.iter().filter_map(|r| r.1).collect();
        println!(
            "{depth:.0} mm: {} views, {} clean",
            views.len(),
            rotations.len()
        );
        for (k, name) in ["ellipse fit", "centroid", "sphere centre"]
            .iter()
            .enumerate()
        {
            let (n, rms, worst) = stat(k);
            println!("  {name:>13}: {n} blobs, RMS {rms:.4} px, worst {worst:.4} px");
        }
        let worst = rotations.iter().cloned().fold(0.0, f64::max);
        let rms = (rotations.iter().map(|r| r * r).sum::<f64>() / rotations.len() as f64).sqrt();
        println!("  rotation error, clean views: RMS {rms:.4}°, worst {worst:.4}°");
    }
}

/// The `clean` grid: tilt −40…40°, pan −30…30° in 5° steps, rolls 10°
/// and 100°.
fn clean_grid() -> Vec<(f64, f64, f64)> {
    (-8..=8)
        .flat_map(|t| (-6..=6).flat_map(move |p| [10.0, 100.0].map(|r| (t, p, r))))
        .map(|(t, p, r)| (5.0 * t as f64, 5.0 * p as f64, r))
        .collect()
}

/// A one-round refiner rendering at `supersampling` with blur `blur` px.
fn refiner(part: &Part, camera: Camera, supersampling: u32, blur: f64) -> Refiner {
    let mut model = frames::noise_free(camera, supersampling);
    model.optics.blur = layout_opt::render::Blur::Gaussian { sigma_px: blur };
    Refiner::new(part.scene.clone(), model, 1).unwrap()
}

/// The `clean` grid's clean views at `depth`, each read `realisations`
/// times by the default noisy 8-bit sensor (4×4 supersampling): the RMS
/// rotation error over the frames tracked both ways, unrefined and refined
/// by a render at `supersampling`.
fn noisy(part: &Part, camera: Camera, depth: f64, realisations: u64, supersampling: u32) {
    let config = TrackConfig::new(&part.layout, camera);
    let render = frames::noisy(camera, 4);
    let refiner = refiner(part, camera, supersampling, 0.5);
    let pairs: Vec<(f64, f64)> = clean_grid()
        .par_iter()
        .enumerate()
        .flat_map_iter(|(k, &(tilt, pan, roll))| {
            let truth = centred(&camera, depth, tilt, pan, roll);
            let rendered = part.render(&render, &truth);
            let clean = clean_view(&rendered.truth, &camera);
            let error =
                |pose: Option<Pose>| pose.map(|p| rotation_error_deg(&truth.rotation, &p.rotation));
            (0..realisations)
                .filter(move |_| clean)
                .filter_map(|r| {
                    let frame = rendered.expose(k as u64, r);
                    let first = analyse(&config, &frame);
                    let before = error(first.pose)?;
                    let after = error(refiner.refine(&config, &frame, first).pose)?;
                    Some((before, after))
                })
                .collect::<Vec<_>>()
        })
        .collect();
    let rms = |v: &dyn Fn(&(f64, f64)) -> f64| {
        (pairs.iter().map(|p| v(p).powi(2)).sum::<f64>() / pairs.len().max(1) as f64).sqrt()
    };
    println!(
        "{depth:.0} mm, noisy 8-bit frames of the clean views, {} tracked both ways: rotation error RMS {:.4}° unrefined, {:.4}° refined (render {supersampling}×{supersampling})",
        pairs.len(),
        rms(&|p| p.0),
        rms(&|p| p.1)
    );
}

fn clean(part: &Part, camera: Camera, depth: f64, refine: Option<(u32, f64)>) {
    let config = TrackConfig::new(&part.layout, camera);
    let render = frames::noise_free(camera, 8);
    let refiner = refine.map(|(supersampling, blur)| refiner(part, camera, supersampling, blur));
    let views = clean_grid();
    type Row = (f64, f64, f64, f64, Vec<(usize, Vector2<f64>)>);
    let mut rows: Vec<Row> = views
        .par_iter()
        .filter_map(|&(tilt, pan, roll)| {
            let truth = centred(&camera, depth, tilt, pan, roll);
            let rendered = part.render(&render, &truth);
            if !clean_view(&rendered.truth, &camera) {
                return None;
            }
            let frame = rendered.frame();
            let mut analysis = analyse(&config, &frame);
            if let Some(refiner) = &refiner {
                analysis = refiner.refine(&config, &frame, analysis);
            }
            let detection = analysis.detection.as_ref()?;
            let bias = |b: &layout_opt::track::detect::Blob| {
                b.bias.map_or(Vector2::zeros(), |c| Vector2::from(c.px))
            };
            let errors = rendered
                .truth
                .spheres
                .iter()
                .enumerate()
                .filter_map(|(k, sphere)| {
                    let b = &detection.blobs[blob_of_sphere(&detection.blobs, sphere)?];
                    Some((
                        k,
                        Vector2::from(b.ellipse_centre_px) - bias(b) - ellipse_centre(sphere),
                    ))
                })
                .collect();
            let rotation = analysis.pose.map_or(f64::NAN, |p| {
                rotation_error_deg(&truth.rotation, &p.rotation)
            });
            Some((tilt, pan, roll, rotation, errors))
        })
        .collect();
    if rows.is_empty() {
        println!("{depth:.0} mm: no clean view of {}", views.len());
        return;
    }
    rows.sort_by(|a, b| b.3.total_cmp(&a.3));
    let rotations: Vec<f64> = rows.iter().rev().map(|r| r.3).collect();
    let centres: Vec<f64> = rows
        .iter()
        .flat_map(|r| r.4.iter().map(|e| e.1.norm()))
        .collect();
    let rms = (centres.iter().map(|e| e * e).sum::<f64>() / centres.len() as f64).sqrt();
    let refined = refine.map_or(String::new(), |(supersampling, blur)| {
        format!(", refined (render {supersampling}×{supersampling}, blur {blur} px)")
    });
    println!(
        "{depth:.0} mm{refined}: {} clean views of {}; rotation error median {:.4}°, 90th percentile {:.4}°, worst {:.4}°; {} beyond 0.01°; ellipse centres RMS {rms:.4} px, worst {:.4} px",
        rows.len(),
        views.len(),
        rotations[rotations.len() / 2],
        rotations[rotations.len() * 9 / 10],
        rotations[rotations.len() - 1],
        rotations.iter().filter(|r| **r > 0.01).count(),
        centres.iter().copied().fold(0.0, f64::max)
    );
    for (tilt, pan, roll, rotation, errors) in rows.iter().take(6) {
        let spheres: Vec<String> = errors
            .iter()
            .map(|(k, e)| {
                format!(
                    "{}: ({:+.3}, {:+.3})",
                    part.layout.points[*k].name, e.x, e.y
                )
            })
            .collect();
        println!(
            "  tilt {tilt}° pan {pan}° roll {roll}°: {rotation:.4}°; {}",
            spheres.join(", ")
        );
    }
}

fn labels(part: &Part, camera: Camera, poses: u64, realisations: u64) {
    let config = TrackConfig::new(&part.layout, camera);
    let render = frames::noisy(camera, 4);
    let outcomes: Vec<(u64, u64, u64, Vec<f64>)> = (0..poses)
        .into_par_iter()
        .filter_map(|k| {
            let mut rng = ChaCha8Rng::seed_from_u64(0x1AB + k);
            let truth = centred(
                &camera,
                rng.random_range(300.0..900.0),
                rng.random_range(-30.0..30.0),
                rng.random_range(-30.0..30.0),
                rng.random_range(-180.0..180.0),
            );
            if !identifiable(&camera, part, &truth) {
                return None;
            }
            let rendered = part.render(&render, &truth);
            if !clean_view(&rendered.truth, &camera) {
                return None;
            }
            let (mut correct, mut wrong, mut failed) = (0, 0, 0);
            let mut deviations = Vec::new();
            for realisation in 0..realisations {
                let analysis = analyse(&config, &rendered.expose(k, realisation));
                let (Ok(tracked), Some(detection)) = (&analysis.outcome, &analysis.detection)
                else {
                    failed += 1;
                    continue;
                };
                let mut right = true;
                for (index, sphere) in rendered.truth.spheres.iter().enumerate() {
                    match blob_of_sphere(&detection.blobs, sphere) {
                        Some(b) => {
                            right &= tracked.labels[b] == Some(index);
                            deviations.push(
                                (Vector2::from(detection.blobs[b].ellipse_centre_px)
                                    - ellipse_centre(sphere))
                                .norm_squared(),
                            );
                        }
                        None => right = false,
                    }
                }
                if right {
                    correct += 1;
                } else {
                    wrong += 1;
                }
            }
            Some((correct, wrong, failed, deviations))
        })
        .collect();
    let correct: u64 = outcomes.iter().map(|o| o.0).sum();
    let wrong: u64 = outcomes.iter().map(|o| o.1).sum();
    let failed: u64 = outcomes.iter().map(|o| o.2).sum();
    let deviations: Vec<f64> = outcomes.iter().flat_map(|o| o.3.clone()).collect();
    let rms = (deviations.iter().sum::<f64>() / deviations.len() as f64).sqrt();
    println!(
        "{} identifiable clean poses × {realisations} noisy frames: {correct} all labels correct, {wrong} wrong, {failed} not tracked; correct {:.3} % of tracked; ellipse-centre error RMS {rms:.4} px",
        outcomes.len(),
        100.0 * correct as f64 / (correct + wrong) as f64
    );
}

/// What the tracker did with one frame's spheres, by how much of each the
/// render says is hidden.
#[derive(Default, Clone)]
struct HiddenCounts {
    /// `[flagged, not]` for: ≥ 10 % hidden with the support reaching
    /// ≥ `REACH_PX` into the disc, ≥ 10 % with a shallower notch, 1–10 %,
    /// under 1 %, whole.
    spheres: [[u64; 2]; 5],
    /// Frames with a sphere partly hidden, and of those, tracked.
    frames: [u64; 2],
    /// Partly hidden blobs labelled after the pose, and labelled right.
    labelled: [u64; 2],
    /// Ellipse-centre errors of unflagged ≥ 10 % hidden blobs, px, by the
    /// two reach classes.
    missed: [Vec<f64>; 2],
    /// `[flagged, not]` by hidden share of the AREA ([`frames::area_hidden`]):
    /// ≥ 10 %, 1–10 %, under 1 % (outline partly hidden).
    by_area: [[u64; 2]; 3],
    /// Share of the outline cut away as a notch, unflagged blobs with
    /// ≥ 10 % of the outline hidden.
    cut: Vec<f64>,
}

/// The notch depth that separates the two ≥ 10 % classes, px: the edge
/// points' outlier tolerance ([`layout_opt::track::detect::MIN_EDGE_TOLERANCE_PX`]).
const REACH_PX: f64 = layout_opt::track::detect::MIN_EDGE_TOLERANCE_PX;

fn hidden(part: &Part, camera: Camera, poses: u64) {
    let config = TrackConfig::new(&part.layout, camera);
    let render = frames::noisy(camera, 4);
    let counts: Vec<HiddenCounts> = (0..poses)
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
            let analysis = analyse(&config, &rendered.expose(k, 0));
            let detection = analysis.detection.as_ref()?;
            let mut c = HiddenCounts::default();
            let mut any_hidden = false;
            for (index, sphere) in rendered.truth.spheres.iter().enumerate() {
                let h = hidden_fraction(sphere);
                let Some(b) = blob_of_sphere(&detection.blobs, sphere) else {
                    continue;
                };
                let blob = &detection.blobs[b];
                let deep = h >= 0.1
                    && support_reach_px(&part.scene, &truth, &camera, index, 256) >= REACH_PX;
                let class = if h >= 0.1 {
                    usize::from(!deep)
                } else if h >= 0.01 {
                    2
                } else if h > 0.0 {
                    3
                } else {
                    4
                };
                c.spheres[class][usize::from(!blob.hidden())] += 1;
                if h > 0.0 {
                    let area = area_hidden(&part.scene, &truth, &camera, sphere, index);
                    let area_class = if area >= 0.1 {
                        0
                    } else if area >= 0.01 {
                        1
                    } else {
                        2
                    };
                    c.by_area[area_class][usize::from(!blob.hidden())] += 1;
                }
                if h >= 0.1 && !blob.hidden() {
                    c.cut.push(blob.outline_dropped);
                }
                if h >= 0.1 && !blob.hidden() {
                    c.missed[class].push(
                        (Vector2::from(blob.ellipse_centre_px) - ellipse_centre(sphere)).norm(),
                    );
                }
                if h > 0.0 {
                    any_hidden = true;
                    if let Ok(tracked) = &analysis.outcome {
                        if let Some(label) = tracked.labels[b] {
                            c.labelled[0] += 1;
                            c.labelled[1] += u64::from(label == index);
                        }
                    }
                }
            }
            if any_hidden {
                c.frames = [1, u64::from(analysis.outcome.is_ok())];
            }
            Some(c)
        })
        .collect();
    let mut t = HiddenCounts::default();
    for c in &counts {
        for (a, b) in t.spheres.iter_mut().zip(&c.spheres) {
            a[0] += b[0];
            a[1] += b[1];
        }
        for (a, b) in t.by_area.iter_mut().zip(&c.by_area) {
            a[0] += b[0];
            a[1] += b[1];
        }
        t.cut.extend(&c.cut);
        for i in 0..2 {
            t.frames[i] += c.frames[i];
            t.labelled[i] += c.labelled[i];
            t.missed[i].extend(&c.missed[i]);
        }
    }
    println!(
        "{} frames, {} with a partly hidden sphere, {} of them tracked",
        counts.len(),
        t.frames[0],
        t.frames[1]
    );
    let names = [
        format!("≥ 10 % hidden, notch ≥ {REACH_PX} px"),
        format!("≥ 10 % hidden, notch < {REACH_PX} px"),
        "1–10 % hidden".to_string(),
        "< 1 % hidden".to_string(),
        "whole".to_string(),
    ];
    for (name, [flagged, not]) in names.iter().zip(&t.spheres) {
        println!(
            "  {name}: {flagged} flagged, {not} not ({:.3} flagged)",
            *flagged as f64 / (flagged + not).max(1) as f64
        );
    }
    for (name, missed) in names.iter().zip(&mut t.missed) {
        missed.sort_by(f64::total_cmp);
        if let Some(worst) = missed.last() {
            println!(
                "  ellipse-centre error of unflagged blobs {name}: median {:.3} px, 90th percentile {:.3} px, worst {worst:.3} px",
                missed[missed.len() / 2],
                missed[missed.len() * 9 / 10],
            );
        }
    }
    for (name, [flagged, not]) in ["≥ 10 %", "1–10 %", "< 1 %"].iter().zip(&t.by_area) {
        println!(
            "  AREA {name} hidden: {flagged} flagged, {not} not ({:.3} flagged)",
            *flagged as f64 / (flagged + not).max(1) as f64
        );
    }
    t.cut.sort_by(f64::total_cmp);
    if let Some(worst) = t.cut.last() {
        println!(
            "  outline cut away, unflagged blobs ≥ 10 % of the outline hidden: median {:.3}, worst {worst:.3}",
            t.cut[t.cut.len() / 2]
        );
    }
    let s = &t.spheres;
    let flagged_hidden: u64 = s[..4].iter().map(|c| c[0]).sum();
    let ten = [s[0][0] + s[1][0], s[0][1] + s[1][1]];
    println!(
        "  precision {:.3}; recall ≥ 10 % hidden {:.3}, of those with a notch ≥ {REACH_PX} px {:.3}; partly hidden blobs labelled after the pose: {}, correctly {}",
        flagged_hidden as f64 / (flagged_hidden + s[4][0]) as f64,
        ten[0] as f64 / (ten[0] + ten[1]) as f64,
        s[0][0] as f64 / (s[0][0] + s[0][1]) as f64,
        t.labelled[0],
        t.labelled[1]
    );
}

/// Median wall time of one frame's analysis (detection, identification,
/// pose) on the calling thread, over `runs` runs of a 1280×720 render.
fn speed(part: &Part, camera: Camera, runs: u64) {
    let config = TrackConfig::new(&part.layout, camera);
    let truth = first_clean(part, &camera, 500.0);
    let frame = part.render(&frames::noisy(camera, 4), &truth).expose(1, 0);
    let tracked = analyse(&config, &frame);
    assert!(tracked.outcome.is_ok());
    let mut times: Vec<f64> = (0..runs)
        .map(|_| {
            let start = std::time::Instant::now();
            std::hint::black_box(analyse(&config, std::hint::black_box(&frame)));
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    println!(
        "analyse, 1280×720, {} blobs: median {:.3} ms, fastest {:.3} ms over {runs} runs",
        tracked.detection.map_or(0, |d| d.blobs.len()),
        times[times.len() / 2],
        times[0]
    );
}

/// `validate --images`'s part and grid for the winner (the supports routed
/// for the paper's protocol at a tilt step of `tilt_step_deg`, every visible scenario read
/// `trials` times with seed 7): the share of frames lost, by reason, and
/// every blob flagged as partly hidden in a frame lost for too few blobs,
/// beside the render's hidden fractions of its sphere and the visibility
/// model's support-hidden fraction.
fn lost(part: &Part, camera: Camera, trials: u64, tilt_step_deg: f64) {
    use layout_opt::mesh::{marker_for_range, MarkerOptions};
    use layout_opt::render::{expose, frame_truth, render_radiance, RenderConfig, Scene};
    use layout_opt::scenario::{sphere_images, visibility, ScenarioGrid};
    use layout_opt::track::GreyFrame;
    use layout_opt::visibility::{support_fractions, MaxHidden, Supports, WorkingRange};
    let layout = &part.layout;
    let scenarios = ScenarioGrid::paper_protocol(tilt_step_deg).scenarios();
    let max_hidden = MaxHidden::default();
    let range = WorkingRange {
        camera,
        scenarios: scenarios.clone(),
        max_hidden,
    };
    let marker = marker_for_range(layout, &MarkerOptions::default(), &range).unwrap();
    let supports = Supports::new(marker.occluders());
    let scene = Scene::from_marker(marker);
    let mut render = RenderConfig::new(camera);
    render.seed = 7;
    let config = TrackConfig::new(layout, camera);
    let centres = layout.positions();
    let radius = layout.sphere_radius_mm();
    let visible: Vec<_> = scenarios
        .iter()
        .filter(|s| {
            let pose = s.pose();
            visibility(
                &sphere_images(&camera, &pose, &centres, layout.sphere_diameter_mm),
                &camera,
            )
            .is_visible()
                && support_fractions(&camera, &pose, &centres, radius, &supports)
                    .iter()
                    .all(|f| *f <= max_hidden.fraction())
        })
        .collect();
    let rows: Vec<(u64, Vec<String>, std::collections::BTreeMap<String, u64>)> = visible
        .par_iter()
        .map(|s| {
            let pose = s.pose();
            let truth = frame_truth(&scene, &part.names, &pose, &camera).unwrap();
            let radiance = render_radiance(&scene, &pose, &render).unwrap();
            let model = support_fractions(&camera, &pose, &centres, radius, &supports);
            let mut reasons = std::collections::BTreeMap::new();
            let mut lines = Vec::new();
            for trial in 0..trials {
                let d = expose(&radiance, &render.sensor, 7, s.index as u64, trial);
                let frame =
                    GreyFrame::new(d.width as u32, d.height as u32, d.bit_depth, d.values).unwrap();
                let analysis = analyse(&config, &frame);
                let Err(error) = &analysis.outcome else {
                    continue;
                };
                let reason: String = error.to_string().chars().take(20).collect();
                *reasons.entry(reason.clone()).or_default() += 1;
                // The blobs of the first lost frame of the view (the
                // others differ by sensor noise only).
                let Some(detection) = analysis.detection.as_ref().filter(|_| lines.is_empty())
                else {
                    continue;
                };
                for (k, sphere) in truth.spheres.iter().enumerate() {
                    let Some(b) = blob_of_sphere(&detection.blobs, sphere) else {
                        let e = ellipse_centre(sphere);
                        let gap = truth
                            .spheres
                            .iter()
                            .filter(|o| o.name != sphere.name)
                            .map(|o| {
                                (ellipse_centre(o) - e).norm()
                                    - o.semi_axes_px[0]
                                    - sphere.semi_axes_px[0]
                            })
                            .fold(f64::INFINITY, f64::min);
                        lines.push(format!(
                            "    t{trial} {}: no blob (r {:.1} px, nearest disc {gap:.2} px away; rejected {:?})",
                            sphere.name, sphere.semi_axes_px[0], detection.rejected
                        ));
                        continue;
                    };
                    let b = &detection.blobs[b];
                    if !b.hidden() {
                        continue;
                    }
                    let h = &sphere.hidden;
                    let centre_error =
                        (Vector2::from(b.centre_px) - Vector2::from(sphere.projected_centre_px)).norm();
                    let reach = support_reach_px(&scene, &pose, &camera, k, 256);
                    let hits = occluding_parts(&scene, &pose, k);
                    lines.push(format!(
                        "    t{trial} {} r {:.1} px: truth support {:.4} sphere {:.4} outside {:.4}, model {:.4}; {:?} cut {:.3} dip {:.3} fill {:.3} out {:.3} ratio {:.3}/{:.3}; centre off {:.3} px, notch {:.3} px; hidden by {hits}",
                        sphere.name,
                        sphere.semi_axes_px[0],
                        h.by_support,
                        h.by_sphere,
                        h.outside_image,
                        model[k],
                        b.hidden_because,
                        b.outline_dropped,
                        b.edge_dip_px,
                        b.filled_fraction,
                        b.outlier_fraction,
                        b.axis_ratio,
                        b.expected_axis_ratio,
                        centre_error,
                        reach
                    ));
                }
            }
            let head = format!(
                "scenario {} depth {} offset {} tilt {}",
                s.index, s.depth_mm, s.offset_x_mm, s.tilt_deg
            );
            let mut all = vec![head];
            all.extend(lines);
            (trials, all, reasons)
        })
        .collect();
    let mut total = std::collections::BTreeMap::<String, u64>::new();
    let frames: u64 = rows.iter().map(|r| r.0).sum();
    for (_, lines, reasons) in &rows {
        if reasons.is_empty() {
            continue;
        }
        println!("{} lost {reasons:?}", lines[0]);
        for line in &lines[1..] {
            println!("{line}");
        }
        for (reason, count) in reasons {
            *total.entry(reason.clone()).or_default() += count;
        }
    }
    let lost: u64 = total.values().sum();
    println!(
        "{} visible scenarios, {frames} frames, {lost} lost ({:.1}%): {total:?}",
        rows.len(),
        100.0 * lost as f64 / frames as f64
    );
}

/// Which parts of `scene` the limb rays of sphere `k` meet first at `pose`
/// (256 rays): per part, the rays and how far outside the sphere's ball the
/// farthest hit lies, mm. A sphere's shape is its ball with the cone under
/// it, blended by the fillet between them: "own cone" is that fillet and
/// cone.
fn occluding_parts(scene: &layout_opt::render::Scene, pose: &Pose, k: usize) -> String {
    use layout_opt::render::scene::Ray;
    let spheres = scene.spheres().len();
    let (centre, radius) = scene.spheres()[k];
    let c = pose.transform(&centre);
    let inverse = pose.rotation.inverse();
    let origin = -(inverse * pose.translation);
    let all = scene.all_shapes();
    let mut parts = std::collections::BTreeMap::<usize, (usize, f64)>::new();
    for limb in layout_opt::render::truth::limb_points(&c, radius, 256) {
        let aim = c + (limb - c) * (1.0 - 1e-6);
        let ray = Ray {
            origin,
            direction: inverse * aim.normalize(),
        };
        if let Some(hit) = scene.first_hit(&ray, &all).filter(|h| h.sphere.is_none()) {
            let p = origin + ray.direction * hit.t;
            let part = parts.entry(hit.shape).or_default();
            part.0 += 1;
            part.1 = part.1.max((p - centre).norm() - radius);
        }
    }
    parts
        .iter()
        .map(|(&shape, (rays, off))| {
            let name = if shape == k {
                "own cone".to_string()
            } else if shape < spheres {
                format!("sphere {shape}'s cone")
            } else if shape + 1 < scene.shape_count() {
                "a strut".to_string()
            } else {
                "the plate".to_string()
            };
            format!("{name} ({rays}/256 rays, up to {off:.3} mm off the ball)")
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Noise-free renders (16×16 supersampling) of the winner near head on at
/// 800 and 1000 mm, with its part and with the spheres alone: each whole
/// sphere's ellipse-centre error both ways, and the rotation error.
fn bias(part: &Part, camera: Camera) {
    let config = TrackConfig::new(&part.layout, camera);
    let render = frames::noise_free(camera, layout_opt::render::config::MAX_SUPERSAMPLING);
    let bare = Part {
        layout: part.layout.clone(),
        scene: layout_opt::render::Scene::spheres_only(part.scene.spheres()),
        names: part.names.clone(),
    };
    let views: Vec<(f64, f64, f64)> = [800.0, 1000.0]
        .into_iter()
        .flat_map(|d| [-10.0, 0.0, 10.0].map(move |t| (d, t, 0.0)))
        .chain([(1000.0, 0.0, 10.0), (1000.0, 0.0, -10.0)])
        .collect();
    let rows: Vec<String> = views
        .par_iter()
        .map(|&(depth, tilt, pan)| {
            let truth = centred(&camera, depth, tilt, pan, 10.0);
            let mut line = format!("{depth:.0} mm tilt {tilt:+.0} pan {pan:+.0}:");
            for (name, which) in [("part", part), ("bare", &bare)] {
                let rendered = which.render(&render, &truth);
                let analysis = analyse(&config, &rendered.frame());
                let Some(detection) = analysis.detection.as_ref() else {
                    line += &format!(" {name}: no detection");
                    continue;
                };
                let mut errors = Vec::new();
                for sphere in &rendered.truth.spheres {
                    let e = blob_of_sphere(&detection.blobs, sphere)
                        .filter(|&b| hidden_fraction(sphere) == 0.0 && !detection.blobs[b].hidden())
                        .map(|b| {
                            (Vector2::from(detection.blobs[b].ellipse_centre_px)
                                - ellipse_centre(sphere))
                            .norm()
                        });
                    errors.push(e.map_or("  -  ".to_string(), |e| format!("{e:.3}")));
                }
                let rotation = match &analysis.outcome {
                    Ok(tracked) => format!(
                        "{:.4}°",
                        rotation_error_deg(&truth.rotation, &pose_of(tracked).rotation)
                    ),
                    Err(e) => format!("lost ({e})"),
                };
                line += &format!(
                    "\n   {name}: centre errors px [{}], rotation {rotation}",
                    errors.join(" ")
                );
            }
            line
        })
        .collect();
    for row in rows {
        println!("{row}");
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let part = Part::winner();
    let camera = Camera::paper();
    let number =
        |i: usize, default: u64| args.get(i).map_or(default, |a| a.parse().expect("a count"));
    match args.first().map(String::as_str) {
        Some("centres") => centres(&part, camera),
        Some("labels") => labels(&part, camera, number(1, 1000), number(2, 10)),
        Some("hidden") => hidden(&part, camera, number(1, 600)),
        Some("speed") => speed(&part, camera, number(1, 300)),
        Some("lost") => lost(&part, camera, number(1, 20), number(2, 10) as f64),
        Some("bias") => bias(&part, camera),
        Some("noisy") => noisy(
            &part,
            camera,
            number(1, 1000) as f64,
            number(2, 5),
            number(3, 8) as u32,
        ),
        Some("clean") => {
            let refine = std::env::args().nth(3).map(|_| {
                let blur = std::env::args().nth(4).map_or(0.5, |b| b.parse().unwrap());
                (number(2, 8) as u32, blur)
            });
            clean(&part, camera, number(1, 1000) as f64, refine)
        }
        _ => eprintln!(
            "usage: track_accuracy centres | labels [POSES] [REALISATIONS] | hidden [POSES] | speed [RUNS] | lost [TRIALS] | bias | clean [DEPTH_MM [REFINE_SUPERSAMPLING [REFINE_BLUR_PX]]] | noisy [DEPTH_MM [REALISATIONS [REFINE_SUPERSAMPLING]]]"
        ),
    }
}
