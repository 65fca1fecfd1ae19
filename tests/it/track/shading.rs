//! Looks other than bright discs on black: the same seeded views rendered
//! under the retroreflective preset (nearly flat discs), the Lambertian one
//! (white matte spheres under a ring light, darkening to nothing at their
//! limb) and the diffuse one (white spheres in front of a lit grey body, on
//! a dark or a mid-grey background), with sensor noise, and read by
//! `track`'s defaults.

use super::{clean_views, frames, pose_of, winner, CROP_MARGIN_PX};
use layout_opt::camera::Camera;
use layout_opt::pose::rotation_error_deg;
use layout_opt::render::{Appearance, Lighting};
use layout_opt::track::{analyse, Threshold, TrackConfig};
use rayon::prelude::*;

/// The lens blur of the tests' frames, σ px (`render`'s default).
const BLUR_PX: f64 = 0.5;

/// `pose` rendered with `appearance` and a Gaussian lens blur of σ
/// `blur_px` through the window round its discs ([`frames::crop`]), read
/// by the 8-bit sensor with its default noise (seeded by `seed`,
/// realisation `k`); and that window's camera.
fn noisy_frame(
    appearance: &Appearance,
    blur_px: f64,
    pose: &layout_opt::pose::Pose,
    truth: &layout_opt::render::FrameTruth,
    seed: u64,
    k: usize,
) -> (layout_opt::track::GreyFrame, Camera) {
    let camera = Camera::paper();
    let window = frames::crop(&camera, truth, CROP_MARGIN_PX, |_| true);
    let mut render = frames::noisy(window, 4);
    render.appearance = appearance.clone();
    render.optics.blur = layout_opt::render::Blur::Gaussian { sigma_px: blur_px };
    let frame = winner()
        .render_window(&render, pose, &camera, truth)
        .expose(seed, k as u64);
    (frame, window)
}

/// Per preset, over the same views: frames posed, whole spheres flagged as
/// partly hidden, and the rotation errors of the posed frames, degrees.
fn read_views(
    appearance: &Appearance,
    blur_px: f64,
    threshold: Threshold,
    views: &[(layout_opt::pose::Pose, layout_opt::render::FrameTruth)],
) -> (usize, usize, Vec<f64>) {
    let part = winner();
    let results: Vec<(bool, usize, Option<f64>)> = views
        .par_iter()
        .enumerate()
        .map(|(k, (pose, truth))| {
            let (frame, window) = noisy_frame(appearance, blur_px, pose, truth, 0x5AD, k);
            let mut config = TrackConfig::new(&part.layout, window);
            config.detector.threshold = threshold;
            let analysis = analyse(&config, &frame);
            let flagged = analysis
                .detection
                .as_ref()
                .map_or(0, |d| d.blobs.iter().filter(|b| b.hidden()).count());
            let error = analysis
                .outcome
                .as_ref()
                .ok()
                .map(|tracked| rotation_error_deg(&pose.rotation, &pose_of(tracked).rotation));
            (error.is_some(), flagged, error)
        })
        .collect();
    (
        results.iter().filter(|r| r.0).count(),
        results.iter().map(|r| r.1).sum(),
        results.iter().filter_map(|r| r.2).collect(),
    )
}

/// Six seeded views with every sphere whole at each of 350, 550 and 800
/// mm, within ±20° of head on.
fn views() -> Vec<(layout_opt::pose::Pose, layout_opt::render::FrameTruth)> {
    [350.0, 550.0, 800.0]
        .into_iter()
        .enumerate()
        .flat_map(|(i, depth)| clean_views(0x5AD + 1000 * i as u64, 6, depth, 20.0, |_| true))
        .collect()
}

fn rms(values: &[f64]) -> f64 {
    (values.iter().map(|v| v * v).sum::<f64>() / values.len().max(1) as f64).sqrt()
}

/// Views with every sphere whole, at 350, 550 and 800 mm within ±20°: under
/// the Lambertian preset no sphere is flagged as partly hidden, every frame
/// is posed, as under the retroreflective one, and the rotation RMS is at
/// most 1.5× the retroreflective frames'. (Before the detector read a
/// shaded sphere by its own level, the limb's darkening cut half of each
/// outline away as notches, and most frames had too few whole blobs.)
#[test]
fn lambertian_spheres_are_whole_and_posed_as_often_as_flat_discs() {
    let views = views();
    let (flat_posed, flat_flagged, flat_errors) = read_views(
        &Appearance::preset(Lighting::Retroreflective),
        BLUR_PX,
        Threshold::Auto,
        &views,
    );
    let (shaded_posed, shaded_flagged, shaded_errors) = read_views(
        &Appearance::preset(Lighting::Lambertian),
        BLUR_PX,
        Threshold::Auto,
        &views,
    );
    eprintln!(
        "{} views: retroreflective {flat_posed} posed, {flat_flagged} flagged, rotation RMS {:.4}°; lambertian {shaded_posed} posed, {shaded_flagged} flagged, rotation RMS {:.4}°",
        views.len(),
        rms(&flat_errors),
        rms(&shaded_errors)
    );
    assert_eq!(flat_flagged, 0);
    assert_eq!(shaded_flagged, 0);
    assert_eq!(flat_posed, views.len());
    assert_eq!(shaded_posed, views.len());
    assert!(rms(&shaded_errors) <= 1.5 * rms(&flat_errors));
}

/// The same views behind a softer lens (σ 1 px of blur, as a real lens a
/// little out of focus gives): every frame is posed and no whole sphere
/// flagged, and the rotation RMS is at most twice the sharp frames'.
/// (While every flat disc's edge was placed by the sum of six samples, the
/// blurred step reached beyond them, its edge rippled with the subpixel
/// phase, and notches were cut from whole spheres: 76 of 240 views of the
/// render grid were posed, against 170 at σ 0.5 px.)
#[test]
fn a_blurred_lens_poses_as_often_as_a_sharp_one() {
    let views = views();
    let look = Appearance::preset(Lighting::Retroreflective);
    let (sharp_posed, _, sharp_errors) = read_views(&look, BLUR_PX, Threshold::Auto, &views);
    let (posed, flagged, errors) = read_views(&look, 1.0, Threshold::Auto, &views);
    eprintln!(
        "{} views, σ 1 px of blur: {posed} posed, {flagged} flagged, rotation RMS {:.4}° (σ 0.5 px: {sharp_posed} posed, {:.4}°)",
        views.len(),
        rms(&errors),
        rms(&sharp_errors)
    );
    assert_eq!(flagged, 0);
    assert_eq!(posed, views.len());
    assert!(rms(&errors) <= 2.0 * rms(&sharp_errors));
}

/// The same views in a diffuse scene (white spheres in front of a grey
/// body lit by a lamp beside the camera, and room light).
/// * On a mid-grey background, with the default threshold (`auto`), every
///   frame is posed and no sphere flagged.
/// * On the preset's dark background, `auto` poses as many frames as the
///   level one had to set by hand before (`--threshold 0.55`, above the lit
///   body), less 2 at most (16 and 18 of 18 when written), and Otsu's level
///   alone, which makes one region of body and spheres, poses fewer (none). (A sphere seen half against the body and
///   half against the dark ground is sometimes flagged: the lamp's shading
///   and the background's step under its limb.)
#[test]
fn diffuse_scenes_are_posed_with_the_default_threshold() {
    let views = views();
    let mut grey = Appearance::preset(Lighting::Diffuse);
    grey.background_radiance = 0.45;
    let (posed, flagged, errors) = read_views(&grey, BLUR_PX, Threshold::Auto, &views);
    eprintln!(
        "diffuse on grey, auto: {posed} of {} posed, {flagged} flagged, rotation RMS {:.4}°",
        views.len(),
        rms(&errors)
    );
    assert_eq!(flagged, 0);
    assert_eq!(posed, views.len());

    let dark = Appearance::preset(Lighting::Diffuse);
    let [auto, fixed, otsu] = [Threshold::Auto, Threshold::Fixed(0.55), Threshold::Otsu].map(|t| {
        let (posed, flagged, errors) = read_views(&dark, BLUR_PX, t, &views);
        eprintln!(
            "diffuse on dark, {t}: {posed} of {} posed, {flagged} flagged, rotation RMS {:.4}°",
            views.len(),
            rms(&errors)
        );
        posed
    });
    assert!(auto + 2 >= fixed, "auto {auto}, 0.55 {fixed}");
    assert!(auto > otsu, "auto {auto}, otsu {otsu}");
    assert!(auto * 5 >= views.len() * 4, "auto {auto}");
}

/// The looks the refinement meets: its own (retroreflective), Lambertian
/// spheres, and brighter supports and background with a dimmer sphere.
fn refined_looks() -> [(&'static str, Appearance); 3] {
    let own = Appearance::preset(Lighting::Retroreflective);
    let other_levels = Appearance {
        sphere_radiance: 0.7,
        support_radiance: 0.4,
        background_radiance: 0.1,
        ..own.clone()
    };
    [
        ("retroreflective", own),
        ("lambertian", Appearance::preset(Lighting::Lambertian)),
        ("other levels", other_levels),
    ]
}

/// Rotation errors (degrees) before and after `track --refine` with the
/// retroreflective preset's look, over `views` rendered with `appearance`
/// (noisy, 8 bit), and the share of the spheres whose render matched the
/// frame ([`layout_opt::track::likeness::Likeness`]).
fn refined_errors(
    appearance: &Appearance,
    views: &[(layout_opt::pose::Pose, layout_opt::render::FrameTruth)],
    fit_levels: bool,
) -> (Vec<f64>, Vec<f64>, f64) {
    use layout_opt::track::refine::Refiner;
    let part = winner();
    let results: Vec<(f64, f64, usize, usize)> = views
        .par_iter()
        .enumerate()
        .filter_map(|(k, (pose, truth))| {
            let (frame, window) = noisy_frame(appearance, BLUR_PX, pose, truth, 0x4EF, k);
            let config = TrackConfig::new(&part.layout, window);
            let first = analyse(&config, &frame);
            let before = rotation_error_deg(&pose.rotation, &first.pose?.rotation);
            let refiner = Refiner::new(part.scene.clone(), frames::noise_free(window, 8), 1)
                .unwrap()
                .with_fitted_levels(fit_levels);
            let refined = refiner.refine(&config, &frame, first);
            let tracked = refined.outcome.as_ref().unwrap();
            let after = rotation_error_deg(&pose.rotation, &pose_of(tracked).rotation);
            let likeness = &tracked.refinement.as_ref().unwrap().likeness;
            let compared = likeness.iter().flatten().count();
            let matched = likeness.iter().flatten().filter(|l| l.matches()).count();
            Some((before, after, compared, matched))
        })
        .collect();
    let compared: usize = results.iter().map(|r| r.2).sum();
    let matched: usize = results.iter().map(|r| r.3).sum();
    (
        results.iter().map(|r| r.0).collect(),
        results.iter().map(|r| r.1).collect(),
        matched as f64 / compared.max(1) as f64,
    )
}

/// `--refine` renders the part with the look it is given; on frames of
/// another look it must not make the pose worse. On the views above, with
/// the retroreflective look:
/// * frames of that look: every sphere's render matches the frame, and
///   the correction lowers the rotation RMS;
/// * white matte spheres (Lambertian): no sphere's render matches (the
///   shading differs however the levels are scaled), no correction is
///   taken, and the pose is the unrefined one;
/// * brighter supports and background, a dimmer sphere (0.4, 0.1 and 0.7
///   of full scale against 0.15, 0.02 and 0.9): where a support or the
///   plate shows near a limb the render departs from the frame and that
///   sphere keeps its measured centre; the rotation RMS stays within 1.1×
///   the unrefined one. (Before the likeness test, each sphere lost the
///   bias of a look the frame did not have, and the error grew 2–5×.)
#[test]
fn refinement_takes_no_correction_where_the_render_is_not_the_frame() {
    let views = views();
    for (name, appearance) in refined_looks() {
        let (before, after, matched) = refined_errors(&appearance, &views, false);
        eprintln!(
            "{name}: {} posed, rotation RMS {:.4}° unrefined, {:.4}° refined; {:.0}% of spheres matched",
            before.len(),
            rms(&before),
            rms(&after),
            100.0 * matched
        );
        assert_eq!(before.len(), views.len(), "{name}");
        match name {
            "retroreflective" => {
                assert_eq!(matched, 1.0);
                assert!(rms(&after) < rms(&before));
            }
            "lambertian" => {
                assert_eq!(matched, 0.0);
                assert_eq!(before, after);
            }
            _ => assert!(rms(&after) <= 1.1 * rms(&before)),
        }
    }
}

/// The normalised squared error `eᵀ Σ⁻¹ e` of a tracked pose against the
/// truth, by the covariance `track` reports: `e` is the rotation error in
/// rvec's coordinates (the left perturbation ω through the inverse left
/// Jacobian at rvec, as the covariance is written) and the translation
/// error, mm. χ² with 6 degrees of freedom for an honest covariance.
fn normalised_squared_error(
    tracked: &layout_opt::track::TrackedFrame,
    truth: &layout_opt::pose::Pose,
) -> f64 {
    use layout_opt::track::uncertainty::inverse_left_jacobian;
    use nalgebra::{SMatrix, SVector, Vector3};
    let estimate = pose_of(tracked);
    let omega = (estimate.rotation * truth.rotation.inverse()).scaled_axis();
    let mut e = SVector::<f64, 6>::zeros();
    e.fixed_rows_mut::<3>(0)
        .copy_from(&(inverse_left_jacobian(&Vector3::from(tracked.figures.rvec)) * omega));
    e.fixed_rows_mut::<3>(3)
        .copy_from(&(estimate.translation - truth.translation));
    let covariance = SMatrix::<f64, 6, 6>::from_fn(|i, j| tracked.figures.covariance[i][j]);
    let inverse = covariance.try_inverse().expect("a covariance of full rank");
    (e.transpose() * inverse * e)[0]
}

/// The covariance `track` reports is honest in every look: over the views
/// of [`views`], each read 3 times under seeded sensor noise, the mean
/// normalised squared pose error lies within 0.4–1.5 of its ideal 6 (χ²
/// of 6 degrees of freedom; over 54 frames its sampling σ is about 0.5),
/// for the ellipse centre and the windowed centroid, in the
/// retroreflective, Lambertian and diffuse presets; the windowed centroid
/// of Lambertian spheres within 2. Each frame's σ came from its blobs. σ
/// from the residuals alone, as before, gave 11–12 on `render`'s own flat
/// discs and 20–75 in the diffuse scene (docs/commands.md, "An honest
/// covariance").
#[test]
fn the_covariance_is_honest_in_every_look() {
    use layout_opt::track::{uncertainty::SigmaSource, CentreMethod};
    let views = views();
    let part = winner();
    for lighting in [
        Lighting::Retroreflective,
        Lighting::Lambertian,
        Lighting::Diffuse,
    ] {
        let appearance = Appearance::preset(lighting);
        let frames: Vec<_> = (0..views.len() * 3)
            .into_par_iter()
            .map(|k| {
                let (pose, truth) = &views[k % views.len()];
                let (frame, window) = noisy_frame(&appearance, BLUR_PX, pose, truth, 0x5E5, k);
                (*pose, frame, window)
            })
            .collect();
        for centre in [CentreMethod::Ellipse, CentreMethod::Window] {
            let errors: Vec<f64> = frames
                .par_iter()
                .filter_map(|(pose, frame, window)| {
                    let mut config = TrackConfig::new(&part.layout, *window);
                    config.centre = centre;
                    let analysis = analyse(&config, frame);
                    let tracked = analysis.outcome.ok()?;
                    assert_eq!(tracked.figures.sigma_source, SigmaSource::Blobs);
                    Some(normalised_squared_error(&tracked, pose))
                })
                .collect();
            let mean = errors.iter().sum::<f64>() / errors.len() as f64;
            eprintln!(
                "{lighting:?}, {} centres: {} of {} frames posed, mean normalised squared error {mean:.2} (6 if honest)",
                centre.name(),
                errors.len(),
                frames.len()
            );
            assert!(errors.len() * 5 >= frames.len() * 4, "{}", errors.len());
            // The windowed centroid of a shaded sphere is pulled by its
            // shading in a way the evidence sees only in part: the one
            // case above 1.5× (9.3 when written).
            let most = if (lighting, centre) == (Lighting::Lambertian, CentreMethod::Window) {
                12.0
            } else {
                9.0
            };
            assert!(
                (2.4..=most).contains(&mean),
                "{lighting:?} {centre:?}: {mean}"
            );
        }
    }
}

/// With the levels fitted to each frame before it renders (`track
/// --refine`'s default), the refinement works on the looks whose given
/// levels it had to refuse: on Lambertian spheres (drawn shaded where most
/// blobs are) and on other levels, most spheres' renders match their frame
/// and the rotation RMS falls; on the look it was given it does as well
/// as with the given levels (within 10%).
#[test]
fn fitted_levels_make_the_refinement_work_on_other_looks() {
    let views = views();
    let (_, given, _) = refined_errors(
        &Appearance::preset(Lighting::Retroreflective),
        &views,
        false,
    );
    for (name, appearance) in refined_looks() {
        let (before, after, matched) = refined_errors(&appearance, &views, true);
        eprintln!(
            "{name}, fitted levels: {} posed, rotation RMS {:.4}° unrefined, {:.4}° refined; {:.0}% of spheres matched",
            before.len(),
            rms(&before),
            rms(&after),
            100.0 * matched
        );
        assert_eq!(before.len(), views.len(), "{name}");
        assert!(matched >= 0.8, "{name}: {matched}");
        assert!(rms(&after) < rms(&before), "{name}");
        if name == "retroreflective" {
            assert!(rms(&after) <= 1.1 * rms(&given));
        }
    }
}
