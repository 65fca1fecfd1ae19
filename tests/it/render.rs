//! `render`: silhouettes against the exact sphere model, hidden fractions
//! against an independent ray march of the mesher's signed distance,
//! reproducibility across thread counts, the PNG round trip, and bad input.

use layout_opt::camera::Camera;
use layout_opt::ellipse::{fit_ellipse, Ellipse};
use layout_opt::layout::Layout;
use layout_opt::mesh::{Marker, MarkerOptions};
use layout_opt::pose::Pose;
use layout_opt::render::truth::{limb_points, on_image};
use layout_opt::render::workflow::{run, FramePose, RenderJob};
use layout_opt::render::{
    frame_truth, render_radiance, Appearance, Blur, Hidden, Lighting, RenderConfig, RenderError,
    Scene,
};
use layout_opt::sphere_image;
use nalgebra::{Rotation3, Vector2, Vector3};
use std::path::{Path, PathBuf};

fn layout(name: &str) -> Layout {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("layouts")
        .join(name);
    Layout::load(&path).unwrap()
}

fn pose(depth_mm: f64, tilt_deg: f64) -> Pose {
    Pose::new(
        Rotation3::from_axis_angle(&Vector3::x_axis(), tilt_deg.to_radians()),
        Vector3::new(0.0, 0.0, depth_mm),
    )
}

/// A flat white sphere on black, no blur, no noise, 8×8 supersampling.
fn flat_config(camera: Camera) -> RenderConfig {
    let mut config = RenderConfig::new(camera);
    config.appearance = Appearance {
        lighting: Lighting::Retroreflective,
        sphere_radiance: 1.0,
        support_radiance: 0.0,
        background_radiance: 0.0,
        exposure: 1.0,
        sphere_limb_falloff: 0.0,
        ambient: 0.0,
    };
    config.optics.supersampling = 8;
    config.optics.blur = Blur::None;
    config.sensor.noise = None;
    config
}

/// Subpixel edge points of a white-on-black blob: in each row (column)
/// strip the edge crosses steeply, the box-filtered values add up to the
/// blob's area in the strip, which places the edge at its mean position
/// over the strip.
fn edge_points(values: &[f32], width: usize, height: usize) -> Vec<Vector2<f64>> {
    let at = |x: usize, y: usize| f64::from(values[y * width + x]);
    let mut points = Vec::new();
    let mut scan = |length: usize, lines: usize, get: &dyn Fn(usize, usize) -> f64, row: bool| {
        for line in 0..lines {
            let mut k = 0;
            while k + 1 < length {
                // A run of partial pixels between a pure 0 and a pure 1.
                if get(k, line) == 0.0 && get(k + 1, line) > 0.0 {
                    let start = k + 1;
                    let mut end = start;
                    while end < length && get(end, line) < 1.0 && get(end, line) > 0.0 {
                        end += 1;
                    }
                    if end < length && get(end, line) == 1.0 && end - start <= 2 {
                        let area: f64 = (start..end).map(|i| get(i, line)).sum();
                        let edge = end as f64 - 0.5 - area;
                        points.push(if row {
                            Vector2::new(edge, line as f64)
                        } else {
                            Vector2::new(line as f64, edge)
                        });
                    }
                    k = end;
                } else if get(k, line) == 1.0 && get(k + 1, line) < 1.0 {
                    let start = k + 1;
                    let mut end = start;
                    while end < length && get(end, line) > 0.0 && get(end, line) < 1.0 {
                        end += 1;
                    }
                    if end < length && get(end, line) == 0.0 && end - start <= 2 {
                        let area: f64 = (start..end).map(|i| get(i, line)).sum();
                        let edge = start as f64 - 0.5 + area;
                        points.push(if row {
                            Vector2::new(edge, line as f64)
                        } else {
                            Vector2::new(line as f64, edge)
                        });
                    }
                    k = end;
                } else {
                    k += 1;
                }
            }
        }
    };
    scan(width, height, &|x, y| at(x, y), true);
    scan(height, width, &|y, x| at(x, y), false);
    points
}

#[test]
fn a_rendered_silhouette_fits_the_exact_ellipse() {
    let paper = Camera::paper();
    let cases = [
        ("centre", paper, Vector2::new(653.0, 508.0 - 150.0)),
        ("corner", paper, Vector2::new(70.0, 60.0)),
        (
            "centre, distorted",
            Camera::paper_with_distortion(),
            Vector2::new(653.0, 360.0),
        ),
        (
            "corner, distorted",
            Camera::paper_with_distortion(),
            Vector2::new(110.0, 90.0),
        ),
    ];
    for (name, camera, target_px) in cases {
        let depth_mm = 300.0;
        let m = Vector2::new(
            (target_px.x - camera.cx()) / camera.fx(),
            (target_px.y - camera.cy()) / camera.fy(),
        );
        let centre = Vector3::new(m.x * depth_mm, m.y * depth_mm, depth_mm);
        let radius = 5.0;
        let scene = Scene::spheres_only(&[(centre, radius)]);
        let identity = Pose::new(Rotation3::identity(), Vector3::zeros());
        let config = flat_config(camera);
        let image = render_radiance(&scene, &identity, &config).unwrap();
        let undistorted: Vec<Vector2<f64>> = edge_points(&image.values, image.width, image.height)
            .iter()
            .map(|p| {
                let n = camera.pixel_to_normalised(p).unwrap();
                Vector2::new(
                    camera.fx() * n.x + camera.cx(),
                    camera.fy() * n.y + camera.cy(),
                )
            })
            .collect();
        assert!(
            undistorted.len() > 100,
            "{name}: {} edge points",
            undistorted.len()
        );
        let fitted = fit_ellipse(&undistorted).unwrap();
        let exact =
            Ellipse::from_conic(&sphere_image::pixel_conic(&camera, &centre, radius).unwrap())
                .unwrap();
        let m0 = sphere_image::ellipse_centre_normalised(&centre, radius).unwrap();
        let exact_centre = Vector2::new(
            camera.fx() * m0.x + camera.cx(),
            camera.fy() * m0.y + camera.cy(),
        );
        let centre_error = (fitted.centre - exact_centre).norm();
        let major_error = (fitted.semi_major - exact.semi_major).abs();
        let minor_error = (fitted.semi_minor - exact.semi_minor).abs();
        println!(
            "{name}: {} edge points, centre off by {centre_error:.4} px, semi-axes {:.3}/{:.3} px off by {major_error:.4}/{minor_error:.4} px",
            undistorted.len(), exact.semi_major, exact.semi_minor
        );
        assert!(
            centre_error <= 0.05,
            "{name}: centre off by {centre_error} px"
        );
        assert!(
            major_error <= 0.05,
            "{name}: semi-major off by {major_error} px"
        );
        assert!(
            minor_error <= 0.05,
            "{name}: semi-minor off by {minor_error} px"
        );
    }
}

/// The hidden fractions of one sphere by an independent count: rays
/// marched on the mesher's own signed distance ([`Marker::signed_distance`])
/// towards the limb, a different number of them. They aim 2e-5 radii
/// inside the limb: where the cone under a sphere leaves the ball, its
/// flank parts from the ball only to second order, so a ray aimed deeper
/// would see the ball over a wider arc than the silhouette itself shows.
fn marched_fractions(marker: &Marker, pose: &Pose, camera: &Camera, index: usize) -> Hidden {
    const RAYS: usize = 500;
    let sphere = &marker.spheres[index];
    let c = pose.transform(&sphere.centre);
    let inverse = pose.rotation.inverse();
    let origin = -(inverse * pose.translation);
    let mut counts = [0usize; 3];
    for limb in limb_points(&c, sphere.radius, RAYS) {
        if !camera.project(&limb).is_some_and(|p| on_image(camera, &p)) {
            counts[2] += 1;
            continue;
        }
        let aim = c + (limb - c) * (1.0 - 2e-5);
        let direction = inverse * aim.normalize();
        let mut t = 0.0;
        let hit = loop {
            let p = origin + direction * t;
            let d = marker.signed_distance(&p);
            if d < 1e-5 {
                break p;
            }
            t += d;
            assert!(t < 1e5, "the march left the scene");
        };
        let owner = marker
            .spheres
            .iter()
            .position(|s| (hit - s.centre).norm() <= s.radius + 5e-5);
        match owner {
            Some(j) if j == index => {}
            Some(_) => counts[1] += 1,
            None => counts[0] += 1,
        }
    }
    let n = RAYS as f64;
    Hidden {
        by_support: counts[0] as f64 / n,
        by_sphere: counts[1] as f64 / n,
        outside_image: counts[2] as f64 / n,
        by_other_marker: 0.0,
    }
}

#[test]
fn hidden_fractions_agree_with_an_independent_ray_march() {
    let camera = Camera::paper();
    let cases = [
        ("biprism-search.json", pose(600.0, 0.0)),
        ("biprism-search.json", pose(600.0, 40.0)),
        ("biprism-paper.json", pose(400.0, 0.0)),
        ("biprism-paper.json", pose(300.0, 40.0)),
    ];
    let mut pillar_covers = false;
    let mut sphere_covers = false;
    let mut worst: f64 = 0.0;
    for (file, pose) in cases {
        let layout = layout(file);
        let marker = Marker::design(&layout, &MarkerOptions::default()).unwrap();
        let scene = Scene::from_marker(marker.clone());
        let names: Vec<String> = layout.points.iter().map(|p| p.name.clone()).collect();
        let truth = frame_truth(&scene, &names, &pose, &camera).unwrap();
        for (index, sphere) in truth.spheres.iter().enumerate() {
            let marched = marched_fractions(&marker, &pose, &camera, index);
            let h = sphere.hidden;
            println!(
                "{file} t={:?} {}: support {:.4}/{:.4} sphere {:.4}/{:.4} outside {:.4}/{:.4}",
                pose.translation.z,
                sphere.name,
                h.by_support,
                marched.by_support,
                h.by_sphere,
                marched.by_sphere,
                h.outside_image,
                marched.outside_image
            );
            for (a, b) in [
                (h.by_support, marched.by_support),
                (h.by_sphere, marched.by_sphere),
                (h.outside_image, marched.outside_image),
            ] {
                worst = worst.max((a - b).abs());
                assert!((a - b).abs() <= 0.01, "{file} {}: {a} vs {b}", sphere.name);
            }
            pillar_covers |= h.by_support > 0.05;
            sphere_covers |= h.by_sphere > 0.05;
        }
    }
    println!("largest difference {:.2} points", 100.0 * worst);
    assert!(
        pillar_covers,
        "some case must have a pillar covering a sphere"
    );
    assert!(
        sphere_covers,
        "some case must have a sphere covering a sphere"
    );
}

fn job(out_dir: PathBuf, poses: &[Pose]) -> RenderJob {
    let mut config = RenderConfig::new(Camera::paper());
    config.realisations = 2;
    RenderJob {
        sources: Vec::new(),
        layout: layout("biprism-search.json"),
        marker: MarkerOptions::default(),
        poses: poses
            .iter()
            .map(|&pose| FramePose {
                pose,
                scenario: None,
            })
            .collect(),
        config,
        out_dir,
    }
}

fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let path = e.unwrap().path();
            (
                path.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&path).unwrap(),
            )
        })
        .collect();
    files.sort();
    files
}

#[test]
fn the_same_seed_gives_the_same_pngs_on_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let poses = [pose(1000.0, 0.0), pose(800.0, 40.0), pose(900.0, -30.0)];
    let mut sets = Vec::new();
    for threads in [1, 2] {
        let out = dir.path().join(format!("threads-{threads}"));
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| run(&job(out.clone(), &poses), &mut layout_opt::observer::Silent))
            .unwrap();
        sets.push(files(&out));
    }
    assert_eq!(sets[0].len(), 3 * 3, "3 frames × (2 PNGs + 1 JSON)");
    assert_eq!(sets[0], sets[1]);
    // Another seed gives other noise.
    let other = dir.path().join("seed-8");
    let mut reseeded = job(other.clone(), &poses);
    reseeded.config.seed = 8;
    run(&reseeded, &mut layout_opt::observer::Silent).unwrap();
    assert_ne!(files(&other)[0].1, sets[0][0].1);
}

#[test]
fn a_png_reads_back_with_its_size_and_bit_depth() {
    let dir = tempfile::tempdir().unwrap();
    for bits in [8u8, 16] {
        let out = dir.path().join(format!("bits-{bits}"));
        let mut job = job(out.clone(), &[pose(1000.0, 0.0)]);
        job.config.sensor.bit_depth = bits;
        job.config.realisations = 1;
        let report = run(&job, &mut layout_opt::observer::Silent).unwrap();
        let image = image::open(&report.frames[0].images[0]).unwrap();
        assert_eq!((image.width(), image.height()), (1280, 720));
        let expected = if bits == 8 {
            image::ColorType::L8
        } else {
            image::ColorType::L16
        };
        assert_eq!(image.color(), expected);
        let record: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report.frames[0].record).unwrap())
                .unwrap();
        assert_eq!(record["bit_depth"], bits);
        assert_eq!(record["spheres"].as_array().unwrap().len(), 7);
        assert_eq!(record["t"][2], 1000.0);
        // The brightest pixels are the spheres, near full scale.
        let luma = image.to_luma16();
        let brightest = luma.pixels().map(|p| p.0[0]).max().unwrap();
        assert!(brightest > 50_000, "brightest {brightest}");
    }
}

#[test]
fn bad_input_is_a_clear_error_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("frames");
    let expect = |job: RenderJob, words: &str| {
        let error = run(&job, &mut layout_opt::observer::Silent).unwrap_err();
        assert!(error.to_string().contains(words), "{error}");
        assert!(
            !job.out_dir.exists(),
            "{} was written",
            job.out_dir.display()
        );
        error
    };
    let behind = Pose::new(Rotation3::identity(), Vector3::new(0.0, 0.0, -500.0));
    expect(job(out.clone(), &[behind]), "behind the camera");
    let aside = Pose::new(Rotation3::identity(), Vector3::new(5000.0, 0.0, 500.0));
    let error = expect(job(out.clone(), &[aside]), "outside the image");
    assert!(matches!(error, RenderError::OutsideImage { frame: 0, .. }));
    let mut twelve = job(out.clone(), &[pose(600.0, 0.0)]);
    twelve.config.sensor.bit_depth = 12;
    expect(twelve, "bit_depth: must be 8 or 16, got 12");
    let mut blurred = job(out.clone(), &[pose(600.0, 0.0)]);
    blurred.config.optics.blur = Blur::Gaussian { sigma_px: -1.0 };
    expect(blurred, "blur_sigma_px");
    let mut dark = job(out.clone(), &[pose(600.0, 0.0)]);
    dark.config.appearance.exposure = -1.0;
    expect(dark, "exposure");
    // An output directory below a file cannot be made.
    let file = dir.path().join("a-file");
    std::fs::write(&file, "x").unwrap();
    let error = run(
        &job(file.join("frames"), &[pose(600.0, 0.0)]),
        &mut layout_opt::observer::Silent,
    )
    .unwrap_err();
    assert!(matches!(error, RenderError::Output(_)), "{error}");
    assert!(error.to_string().contains("is a file, not a directory"));
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
}

#[cfg(feature = "cli")]
#[test]
fn the_command_names_the_flag_of_a_bad_value() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("frames");
    assert_cmd::Command::cargo_bin("layout-opt")
        .unwrap()
        .args(["render", "--bit-depth", "12", "--out"])
        .arg(&out)
        .assert()
        .failure()
        .stderr(predicates::str::contains(
            "--bit-depth: must be 8 or 16, got 12",
        ));
    assert!(!out.exists());
}

/// With no structure flags, `render` draws the part `export` prints: for a
/// layout that records its search's range, the supports routed for that
/// range (not for the view cone), so that its ground truth is that part's.
#[test]
fn the_command_renders_the_part_export_prints() {
    let layout = layout("biprism-search.json");
    let dir = tempfile::tempdir().unwrap();
    let output = assert_cmd::Command::cargo_bin("layout-opt")
        .unwrap()
        .args(["render", "layouts/biprism-search.json", "--depth", "600"])
        .args(["--tilt=-60..60:20", "--pan=-20,20", "--no-noise", "--quiet"])
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let grid = layout_opt::visibility::RangeAxes::default()
        .grid_for(&layout)
        .unwrap()
        .expect("the winner records its search's range");
    let range = layout_opt::visibility::WorkingRange {
        camera: Camera::paper(),
        scenarios: grid.scenarios(),
        max_hidden: layout_opt::visibility::MaxHidden::default(),
    };
    let printed = Scene::from_marker(
        layout_opt::mesh::marker_for_range(&layout, &MarkerOptions::default(), &range).unwrap(),
    );
    let coned = Scene::from_marker(Marker::design(&layout, &MarkerOptions::default()).unwrap());
    let names: Vec<String> = layout.points.iter().map(|p| p.name.clone()).collect();
    let camera = Camera::paper();
    let (mut frames, mut differ) = (0, 0);
    for entry in std::fs::read_dir(dir.path()).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "json") {
            continue;
        }
        let record: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let rows: Vec<Vec<f64>> = serde_json::from_value(record["R"].clone()).unwrap();
        let t: Vec<f64> = serde_json::from_value(record["t"].clone()).unwrap();
        let rotation = nalgebra::Matrix3::from_fn(|i, j| rows[i][j]);
        let pose = Pose::new(
            Rotation3::from_matrix_unchecked(rotation),
            Vector3::new(t[0], t[1], t[2]),
        );
        let of = |scene: &Scene| frame_truth(scene, &names, &pose, &camera).unwrap();
        let (printed, coned) = (of(&printed), of(&coned));
        let mut differs = false;
        for (k, sphere) in record["spheres"].as_array().unwrap().iter().enumerate() {
            let drawn = sphere["hidden"]["by_support"].as_f64().unwrap();
            assert!(
                (drawn - printed.spheres[k].hidden.by_support).abs() < 1e-9,
                "{}: {drawn} drawn, {} on the printed part",
                path.display(),
                printed.spheres[k].hidden.by_support
            );
            differs |= (printed.spheres[k].hidden.by_support - coned.spheres[k].hidden.by_support)
                .abs()
                > 0.01;
        }
        frames += 1;
        differ += usize::from(differs);
    }
    assert_eq!(frames, 14);
    assert!(differ > 0, "some frame must tell the two parts apart");
}
