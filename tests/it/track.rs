//! `track` on frames from the test rasteriser ([`raster`]): labels, centres
//! and poses on noise-free frames; the predicted 1σ against the actual error
//! on noisy frames; the partly-hidden flag against the ground truth; and bad
//! frames, each an error record that stops no other frame.

mod raster;

use layout_opt::camera::Camera;
use layout_opt::identifiability::predict;
use layout_opt::layout::Layout;
use layout_opt::pose::{rotation_error_deg, Pose};
use layout_opt::scenario::Scenario;
use layout_opt::sphere_image::Observation;
use layout_opt::track::{analyse, TrackConfig, TrackedFrame};
use nalgebra::{Rotation3, Vector2, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use raster::{render, Bar, Scene, SphereTruth};
use rayon::prelude::*;
use std::sync::OnceLock;

fn winner() -> &'static Layout {
    static LAYOUT: OnceLock<Layout> = OnceLock::new();
    LAYOUT.get_or_init(|| {
        Layout::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("layouts/biprism-search.json"),
        )
        .unwrap()
    })
}

/// The pose of a scenario with the marker's origin on the image centre's
/// ray (the paper camera's principal point is low in the frame).
fn centred(camera: &Camera, depth_mm: f64, tilt_deg: f64, pan_deg: f64, roll_deg: f64) -> Pose {
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

/// Whether every disc is inside the frame with a margin and no two discs
/// come within a few pixels of each other.
fn clean_view(truths: &[SphereTruth], camera: &Camera) -> bool {
    truths.iter().enumerate().all(|(i, a)| {
        let e = a.ellipse_centre_px;
        let r = a.semi_major_px + 4.0;
        e.x > r
            && e.y > r
            && e.x < camera.width() as f64 - r
            && e.y < camera.height() as f64 - r
            && truths.iter().enumerate().all(|(j, b)| {
                i == j
                    || (a.ellipse_centre_px - b.ellipse_centre_px).norm()
                        > a.semi_major_px + b.semi_major_px + 4.0
            })
    })
}

/// The blob nearest each sphere's true ellipse centre (within its radius).
fn blob_of_sphere(
    tracked_blobs: &[layout_opt::track::detect::Blob],
    truth: &SphereTruth,
) -> Option<usize> {
    tracked_blobs
        .iter()
        .enumerate()
        .map(|(i, b)| {
            (
                i,
                (Vector2::new(b.ellipse_centre_px[0], b.ellipse_centre_px[1])
                    - truth.ellipse_centre_px)
                    .norm(),
            )
        })
        .filter(|(_, d)| *d < truth.semi_major_px)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

fn pose_of(tracked: &TrackedFrame) -> Pose {
    let r = nalgebra::Matrix3::from_fn(|i, j| tracked.rotation[i][j]);
    Pose::new(
        Rotation3::from_matrix_unchecked(r),
        Vector3::from(tracked.t),
    )
}

/// Depth, worst centre error (ellipse fit, centroid), rotation error and
/// whether the labels were right, of one noise-free view.
type ViewResult = (f64, [f64; 2], f64, bool);

/// Noise-free frames of the search winner at 200, 600 and 1000 mm, head on
/// to ±60° of tilt (and pan): every blob found, ellipse centres within
/// 0.05 px, correct labels wherever the identifiability model calls the
/// view identifiable, and the pose within 0.01°.
#[test]
fn noise_free_frames_give_exact_labels_centres_and_poses() {
    let camera = Camera::paper();
    let layout = winner();
    let object = layout.positions();
    let radius = layout.sphere_radius_mm();
    let config = TrackConfig::new(layout, camera);
    config.validate().unwrap();
    let mut views = Vec::new();
    for depth in [200.0, 600.0, 1000.0] {
        for tilt in [-60.0, -40.0, -20.0, 0.0, 20.0, 40.0, 60.0] {
            for pan in [-30.0, 0.0, 30.0] {
                views.push((depth, tilt, pan));
            }
        }
    }
    let results: Vec<Option<ViewResult>> = views
        .par_iter()
        .map(|&(depth, tilt, pan)| {
            let truth = centred(&camera, depth, tilt, pan, 10.0);
            let scene = Scene::clean(&camera, &object, radius, truth);
            let (frame, truths) = render(&scene);
            let analysis = analyse(&config, &frame);
            if !clean_view(&truths, &camera) {
                // At 200 mm the marker overflows the frame: measure the
                // centres of the whole, unflagged discs only.
                let blobs = &analysis.detection.as_ref()?.blobs;
                let mut worst = [0.0f64; 2];
                for t in truths.iter().filter(|t| t.hidden_fraction == 0.0) {
                    let Some(b) = blob_of_sphere(blobs, t).map(|i| &blobs[i]) else {
                        continue;
                    };
                    if b.hidden() {
                        continue;
                    }
                    let ellipse = (Vector2::from(b.ellipse_centre_px) - t.ellipse_centre_px).norm();
                    let centroid = (Vector2::from(b.centroid_px) - t.ellipse_centre_px).norm();
                    worst = [worst[0].max(ellipse), worst[1].max(centroid)];
                }
                return Some((depth, worst, f64::NAN, false));
            }
            let tracked = analysis
                .outcome
                .as_ref()
                .unwrap_or_else(|e| panic!("{depth} mm, tilt {tilt}, pan {pan}: {e}"));
            let blobs = &analysis.detection.as_ref().unwrap().blobs;
            assert_eq!(blobs.len(), object.len(), "{depth} mm tilt {tilt}");
            // Centre errors of both methods, px.
            let mut worst = [0.0f64; 2];
            for (k, t) in truths.iter().enumerate() {
                let b = &blobs
                    [blob_of_sphere(blobs, t).unwrap_or_else(|| panic!("sphere {k} not found"))];
                assert!(
                    !b.hidden(),
                    "{depth} mm tilt {tilt}: sphere {k} flagged {:?}",
                    b.hidden_because
                );
                let ellipse = (Vector2::from(b.ellipse_centre_px) - t.ellipse_centre_px).norm();
                let centroid = (Vector2::from(b.centroid_px) - t.ellipse_centre_px).norm();
                worst = [worst[0].max(ellipse), worst[1].max(centroid)];
                let centre = (Vector2::from(b.centre_px) - t.centre_px).norm();
                assert!(centre < 0.05, "projected centre off by {centre} px");
            }
            let normalised: Vec<Vector2<f64>> = object
                .iter()
                .map(|p| {
                    Observation::EllipseCentre
                        .normalised(&truth.transform(p), radius)
                        .unwrap()
                })
                .collect();
            let identifiable = predict(&camera, &truth, &object, &normalised, &[0.5; 7], 7.5)
                .unwrap()
                .wrong_probability
                <= 1e-3;
            let mut correct = true;
            for (k, t) in truths.iter().enumerate() {
                let b = blob_of_sphere(blobs, t).unwrap();
                correct &= tracked.labels[b] == Some(k);
            }
            if identifiable {
                assert!(
                    correct,
                    "{depth} mm tilt {tilt} pan {pan}: labels {:?}",
                    tracked.labels
                );
            }
            let rotation = rotation_error_deg(&truth.rotation, &pose_of(tracked).rotation);
            // 0.01° near and middle; at 1000 mm (13 px discs) the few
            // hundredths of a pixel left by the edge interpolation move the
            // pose by up to 0.02°.
            let bound = if depth <= 600.0 { 0.01 } else { 0.025 };
            if correct {
                assert!(
                    rotation < bound,
                    "{depth} mm tilt {tilt} pan {pan}: {rotation}°"
                );
            }
            Some((depth, worst, rotation, correct))
        })
        .collect();
    let seen: Vec<_> = results.iter().flatten().collect();
    let tracked = seen.iter().filter(|r| r.2.is_finite()).count();
    for depth in [200.0, 600.0, 1000.0] {
        let at: Vec<_> = seen.iter().filter(|r| r.0 == depth).collect();
        let ellipse = at.iter().map(|r| r.1[0]).fold(0.0, f64::max);
        let centroid = at.iter().map(|r| r.1[1]).fold(0.0, f64::max);
        let rotation = at
            .iter()
            .map(|r| r.2)
            .filter(|r| r.is_finite())
            .fold(0.0, f64::max);
        eprintln!("noise-free {depth} mm: {} views, worst centre error: ellipse fit {ellipse:.4} px, centroid {centroid:.4} px; worst rotation {rotation:.4}°", at.len());
        assert!(
            ellipse <= 0.05,
            "{depth} mm: ellipse centres off by {ellipse} px"
        );
    }
    assert!(tracked >= 30, "only {tracked} clean views");
}

/// A seeded random view of the winner around `depth_mm`, within ±40° of
/// head on.
fn random_pose(camera: &Camera, rng: &mut ChaCha8Rng, depth_mm: f64) -> Pose {
    centred(
        camera,
        depth_mm * rng.random_range(0.9..1.1),
        rng.random_range(-40.0..40.0),
        rng.random_range(-40.0..40.0),
        rng.random_range(-180.0..180.0),
    )
}

/// Noisy, blurred 8-bit frames at 400 mm, σ estimated from each frame's
/// residuals: each of the six pose components lies within its predicted 1σ
/// in about 68% of the frames (±5 points; with σ estimated on 2n − 6 = 8
/// degrees of freedom the Student-t expectation is 65%).
#[test]
fn predicted_one_sigma_brackets_the_actual_error() {
    let camera = Camera::paper();
    let layout = winner();
    let object = layout.positions();
    let config = TrackConfig::new(layout, camera);
    const FRAMES: u64 = 240;
    let outcomes: Vec<Option<[bool; 6]>> = (0..FRAMES)
        .into_par_iter()
        .map(|k| {
            let mut rng = ChaCha8Rng::seed_from_u64(0x7AC0 + k);
            let truth = random_pose(&camera, &mut rng, 400.0);
            let mut scene = Scene::clean(&camera, &object, layout.sphere_radius_mm(), truth);
            scene.bit_depth = 8;
            scene.blur_px = 0.7;
            scene.noise = 0.03;
            scene.seed = k;
            scene.supersampling = 4;
            let (frame, truths) = render(&scene);
            if !clean_view(&truths, &camera) {
                return None;
            }
            let analysis = analyse(&config, &frame);
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
    let tracked: Vec<[bool; 6]> = outcomes.into_iter().flatten().collect();
    assert!(
        tracked.len() as u64 >= FRAMES * 3 / 4,
        "only {} frames tracked",
        tracked.len()
    );
    let inside = tracked.iter().flatten().filter(|b| **b).count();
    let share = inside as f64 / (6 * tracked.len()) as f64;
    eprintln!(
        "noisy frames: {} tracked; {:.1}% of pose components within the predicted 1σ",
        tracked.len(),
        100.0 * share
    );
    assert!((0.63..=0.73).contains(&share), "{share}");
}

/// Frames with a dark bar across a random sphere: the partly-hidden flag
/// against the rasteriser's hidden fractions. Precision ≥ 95% (flagged
/// blobs are hidden), recall ≥ 90% for blobs with ≥ 10% hidden.
#[test]
fn hidden_flags_match_the_ground_truth() {
    let camera = Camera::paper();
    let layout = winner();
    let object = layout.positions();
    let config = TrackConfig::new(layout, camera);
    const FRAMES: u64 = 320;
    let counts: Vec<[usize; 3]> = (0..FRAMES)
        .into_par_iter()
        .filter_map(|k| {
            let mut rng = ChaCha8Rng::seed_from_u64(0xB1D + k);
            let depth = [250.0, 500.0, 800.0][k as usize % 3];
            let truth = random_pose(&camera, &mut rng, depth);
            let mut scene = Scene::clean(&camera, &object, layout.sphere_radius_mm(), truth);
            scene.bit_depth = 8;
            scene.blur_px = 0.6;
            scene.noise = 0.02;
            scene.seed = k;
            scene.supersampling = 4;
            let (_, clean) = render(&scene);
            if !clean_view(&clean, &camera) {
                return None;
            }
            // A bar whose edge cuts sphere `target` at a random depth into it.
            let target = rng.random_range(0..object.len());
            let angle: f64 = rng.random_range(0.0..std::f64::consts::PI);
            let normal = Vector2::new(-angle.sin(), angle.cos());
            let half_width = 6.0;
            let cut = rng.random_range(-0.8..0.6) * clean[target].semi_major_px;
            let centre = clean[target].ellipse_centre_px - normal * (cut + half_width);
            scene.bars.push(Bar {
                centre: [centre.x, centre.y],
                angle,
                half_width,
                half_length: 1.5 * clean[target].semi_major_px,
            });
            let (frame, truths) = render(&scene);
            let analysis = analyse(&config, &frame);
            let blobs = &analysis.detection.as_ref()?.blobs;
            let mut c = [0usize; 3]; // [flagged & hidden, flagged & whole, ≥10% hidden & unflagged]
            for t in &truths {
                let Some(b) = blob_of_sphere(blobs, t).map(|i| &blobs[i]) else {
                    continue;
                };
                match (b.hidden(), t.hidden_fraction > 0.0) {
                    (true, true) => c[0] += 1,
                    (true, false) => c[1] += 1,
                    (false, _) if t.hidden_fraction >= 0.1 => c[2] += 1,
                    _ => {}
                }
            }
            Some(c)
        })
        .collect();
    let total = counts
        .iter()
        .fold([0; 3], |a, c| [a[0] + c[0], a[1] + c[1], a[2] + c[2]]);
    let precision = total[0] as f64 / (total[0] + total[1]) as f64;
    let recall = total[0] as f64 / (total[0] + total[2]) as f64;
    eprintln!("hidden flags over {} frames: {} flagged hidden, {} flagged whole, {} missed (≥10% hidden): precision {precision:.3}, recall {recall:.3}", counts.len(), total[0], total[1], total[2]);
    assert!(total[0] >= 50, "{total:?}");
    assert!(precision >= 0.95, "{total:?}");
    assert!(recall >= 0.90, "{total:?}");
}

/// Malformed frames: each is one error record naming what is wrong, and the
/// good frame among them is still tracked.
#[test]
fn malformed_frames_are_error_records_and_the_run_goes_on() {
    use layout_opt::observer::Silent;
    use layout_opt::track::workflow::{run, TrackOutputs};
    let camera = Camera::paper();
    let layout = winner();
    let object = layout.positions();
    let config = TrackConfig::new(layout, camera);
    let dir = tempfile::tempdir().unwrap();
    let truth = centred(&camera, 500.0, 20.0, 10.0, 0.0);
    let (good, _) = render(&Scene {
        bit_depth: 8,
        ..Scene::clean(&camera, &object, layout.sphere_radius_mm(), truth)
    });
    let good_png = good.to_png();
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
    let out = dir.path().join("out.jsonl");
    let outputs = TrackOutputs {
        json_lines: Some(out.clone()),
        csv: Some(dir.path().join("out.csv")),
        overlay_dir: Some(dir.path().join("overlay")),
    };
    let result = run(&config, &[dir.path().to_path_buf()], &outputs, &mut Silent).unwrap();
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 7);
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
    assert_eq!(csv.lines().count(), 8);
}

/// Writes example frames (200, 600 and 1000 mm, head on and tilted 40°, one
/// with a bar across a sphere) into `$TRACK_FRAMES_DIR` for trying the
/// command by hand (the README's example): `TRACK_FRAMES_DIR=/tmp/frames
/// cargo test --release --test it track::write_example_frames -- --ignored`.
#[test]
#[ignore = "writes example frames for the README where told"]
fn write_example_frames() {
    let dir =
        std::path::PathBuf::from(std::env::var("TRACK_FRAMES_DIR").expect("set TRACK_FRAMES_DIR"));
    std::fs::create_dir_all(&dir).unwrap();
    let camera = Camera::paper();
    let layout = winner();
    let object = layout.positions();
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
        let mut scene = Scene::clean(&camera, &object, layout.sphere_radius_mm(), truth);
        scene.bit_depth = 8;
        scene.blur_px = 0.7;
        scene.noise = 0.02;
        scene.seed = k as u64;
        if k == 3 {
            let (_, clean) = render(&scene);
            let e = clean[6].ellipse_centre_px;
            scene.bars.push(Bar {
                centre: [e.x + 0.5 * clean[6].semi_major_px + 5.0, e.y],
                angle: 1.5,
                half_width: 5.0,
                half_length: 40.0,
            });
        }
        let (frame, _) = render(&scene);
        std::fs::write(
            dir.join(format!("frame-{depth:.0}mm-tilt{tilt:.0}.png")),
            frame.to_png(),
        )
        .unwrap();
    }
}
