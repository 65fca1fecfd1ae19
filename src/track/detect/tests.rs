//! Tests of the parent module.

use super::*;
use crate::track::conic::fit_ellipse;
use std::f64::consts::TAU;

/// Whether `(x, y)` lies inside the disc `(cx, cy, r)`.
fn within((cx, cy, r): (f64, f64, f64), x: f64, y: f64) -> bool {
    (x - cx).powi(2) + (y - cy).powi(2) < r * r
}

/// The 8-bit level of the synthetic discs' frames: 220 on a disc, 20 off.
fn disc_level(on_disc: bool) -> f64 {
    if on_disc {
        220.0
    } else {
        20.0
    }
}

/// A frame with two area-sampled discs (8×8 subsamples) on a dark
/// background, one cut by the right image border.
fn two_discs() -> GreyFrame {
    let (width, height) = (120u32, 80u32);
    let discs = [(40.3, 37.7, 9.0), (116.0, 20.0, 7.0)];
    let pixels = area_sampled(width, height, 8, 1.0, |x, y| {
        disc_level(discs.iter().any(|&disc| within(disc, x, y)))
    });
    GreyFrame::new(width, height, 8, pixels).unwrap()
}

#[test]
fn finds_a_disc_to_a_fraction_of_a_pixel_and_flags_the_clipped_one() {
    let frame = two_discs();
    let camera = Camera::new(1000.0, 1000.0, 60.0, 40.0, 120, 80, [0.0; 5]).unwrap();
    let detection = detect(&frame, &camera, &DetectorConfig::default(), 5.0, 10).unwrap();
    assert_eq!(detection.blobs.len(), 2, "{detection:?}");
    let clipped = &detection.blobs[0];
    assert!(
        clipped.hidden_because.contains(&"touches the image border"),
        "{:?}",
        clipped.hidden_because
    );
    let whole = &detection.blobs[1];
    assert!(!whole.hidden(), "{whole:?}");
    for centre in [
        whole.ellipse_centre_px,
        whole.centroid_px,
        whole.window_centroid_px,
    ] {
        let error = ((centre[0] - 40.3).powi(2) + (centre[1] - 37.7).powi(2)).sqrt();
        assert!(error < 0.05, "{centre:?}");
    }
    assert!(
        (whole.semi_axes_px[0] - 9.0).abs() < 0.1,
        "{:?}",
        whole.semi_axes_px
    );
    assert!(
        (whole.filled_fraction - 1.0).abs() < 0.02,
        "{}",
        whole.filled_fraction
    );
    assert!(matches!(
        detect(&frame, &camera, &DetectorConfig::default(), 5.0, 1),
        Err(DetectError::TooManyBlobs { max: 1, found: 2 })
    ));
}

/// Two area-sampled discs (radius 9 px) whose edges pass 0.8 px apart,
/// blurred by a [1 2 1]/4 kernel each way: the pixels between them
/// rise above the threshold, so they form one component that no
/// ellipse fits; split at their cores, each is found with its centre
/// to a tenth of a pixel.
#[test]
fn two_discs_the_threshold_joins_are_split() {
    let (width, height) = (120u32, 80u32);
    let discs = [(40.3, 40.2, 9.0), (59.1, 40.2, 9.0)];
    let pixels = area_sampled(width, height, 8, 1.0, |x, y| {
        disc_level(discs.iter().any(|&disc| within(disc, x, y)))
    });
    let (w, h) = (width as usize, height as usize);
    let blur = |p: &[u16], step: usize, limit: usize, along: fn(usize, usize) -> usize| {
        (0..p.len())
            .map(|i| {
                let k = along(i, w);
                let a = if k > 0 { p[i - step] } else { p[i] };
                let b = if k + 1 < limit { p[i + step] } else { p[i] };
                ((u32::from(a) + 2 * u32::from(p[i]) + u32::from(b) + 2) / 4) as u16
            })
            .collect::<Vec<u16>>()
    };
    let pixels = blur(&pixels, 1, w, |i, w| i % w);
    let pixels = blur(&pixels, w, h, |i, w| i / w);
    let frame = GreyFrame::new(width, height, 8, pixels.clone()).unwrap();
    let camera = Camera::new(1000.0, 1000.0, 60.0, 40.0, 120, 80, [0.0; 5]).unwrap();
    let whole = DetectorConfig::default();
    let detection = detect(&frame, &camera, &whole, 5.0, 10).unwrap();
    assert_eq!(detection.rejected.shape, 0, "{detection:?}");
    // One component at the threshold: the row through the neck stays
    // above it from one disc's middle to the other's.
    let level = detection.threshold_level * 255.0;
    assert!(
        (40..=59).all(|x| f64::from(pixels[40 * w + x]) > level),
        "{:?}",
        &pixels[40 * w + 40..=40 * w + 59]
    );
    assert_eq!(detection.blobs.len(), 2, "{detection:?}");
    for (blob, (cx, cy, _)) in detection.blobs.iter().zip(discs) {
        let [x, y] = blob.ellipse_centre_px;
        assert!((x - cx).hypot(y - cy) < 0.1, "{blob:?}");
    }
}

/// A frame with an area-sampled bright disc (8×8 subsamples) on a dark
/// background, less whatever the dark `occluders` (discs in front of
/// it) cover.
fn occluded_disc(disc: (f64, f64, f64), occluders: &[(f64, f64, f64)]) -> GreyFrame {
    let (width, height) = (100u32, 80u32);
    let pixels = area_sampled(width, height, 8, 1.0, |x, y| {
        disc_level(within(disc, x, y) && !occluders.iter().any(|&o| within(o, x, y)))
    });
    GreyFrame::new(width, height, 8, pixels).unwrap()
}

/// A dark disc in front of a 10 px disc's rim cuts a notch 1 px deep
/// into a fifth of its outline (and 1 % of its area): the notch is cut
/// away, the blob is used, and its centre comes from the rest of the
/// outline to within 0.03 px. A notch 4 px deep flags the blob.
#[test]
fn a_notched_disc_is_measured_from_its_clean_outline() {
    let camera = Camera::new(1000.0, 1000.0, 50.0, 40.0, 100, 80, [0.0; 5]).unwrap();
    let disc = (50.3, 40.6, 10.0);
    let toward = 0.6f64;
    let occluder = |depth: f64| {
        let r = 6.0;
        let d = disc.2 + r - depth;
        (disc.0 + d * toward.cos(), disc.1 + d * toward.sin(), r)
    };
    let config = DetectorConfig::default();
    let shallow = detect(
        &occluded_disc(disc, &[occluder(1.0)]),
        &camera,
        &config,
        5.0,
        4,
    )
    .unwrap();
    assert_eq!(shallow.blobs.len(), 1, "{shallow:?}");
    let blob = &shallow.blobs[0];
    assert!(!blob.hidden(), "{blob:?}");
    assert!(
        (0.1..=0.3).contains(&blob.outline_dropped),
        "{}",
        blob.outline_dropped
    );
    let [x, y] = blob.ellipse_centre_px;
    let error = (x - disc.0).hypot(y - disc.1);
    assert!(error < 0.03, "{error} px: {blob:?}");
    // The same edge without the cut: the fit leans into the notch.
    let deep = detect(
        &occluded_disc(disc, &[occluder(4.0)]),
        &camera,
        &config,
        5.0,
        4,
    )
    .unwrap();
    assert_eq!(deep.blobs.len(), 1, "{deep:?}");
    assert!(deep.blobs[0].hidden(), "{:?}", deep.blobs[0]);
}

/// Seeded points round a circle with a tapered notch pulled 0.8 px
/// into 80° of it: the plain direct fit leans into the notch by more
/// than a tenth of a pixel, [`fit_outline`] cuts the notch away and
/// finds the centre to within 0.02 px, the same on every run; a whole
/// circle loses no arc.
#[test]
fn fit_outline_cuts_a_notch_away_and_the_plain_fit_does_not() {
    use rand::{Rng, SeedableRng};
    let centre = Vector2::new(50.3, 40.7);
    let (radius, sigma, count) = (10.0, 0.02, 120);
    let notch_at = 1.0f64;
    let half_width = 40f64.to_radians();
    let points = |notched: bool| -> Vec<Vector2<f64>> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x0C7);
        (0..count)
            .map(|i| {
                let angle = TAU * i as f64 / count as f64;
                let off = (angle - notch_at + 0.5 * TAU).rem_euclid(TAU) - 0.5 * TAU;
                let depth = if notched && off.abs() < half_width {
                    0.8 * (1.0 - (off / half_width).powi(2))
                } else {
                    0.0
                };
                let noise = sigma * (rng.random::<f64>() - 0.5) * 12f64.sqrt();
                centre + (radius - depth + noise) * Vector2::new(angle.cos(), angle.sin())
            })
            .collect()
    };
    let sigmas = vec![sigma; count];
    let tolerances = vec![MIN_EDGE_TOLERANCE_PX.max(EDGE_OUTLIER_SIGMAS * sigma); count];
    let notched = points(true);
    let plain = fit_ellipse(&notched).unwrap();
    assert!((plain.centre - centre).norm() > 0.1, "{plain:?}");
    let robust = fit_outline(&notched, &sigmas, &tolerances).unwrap();
    assert!((robust.ellipse.centre - centre).norm() < 0.02, "{robust:?}");
    let cut = robust.notch.iter().filter(|c| **c).count() as f64 / count as f64;
    assert!((0.1..=0.3).contains(&cut), "{cut}");
    assert_eq!(fit_outline(&notched, &sigmas, &tolerances), Some(robust));
    let whole = fit_outline(&points(false), &sigmas, &tolerances).unwrap();
    assert!(whole.notch.iter().all(|c| !c), "{whole:?}");
    assert!((whole.ellipse.centre - centre).norm() < 0.01, "{whole:?}");
    // Mismatched inputs are refused, not a panic.
    assert_eq!(fit_outline(&notched, &sigmas[1..], &tolerances), None);
}

#[test]
fn otsu_splits_two_modes_and_refuses_one() {
    let mut histogram = [0u64; 256];
    histogram[10] = 1000;
    histogram[200] = 10;
    let bin = otsu_bin(&histogram).unwrap();
    assert!((10..200).contains(&bin));
    let mut flat = [0u64; 256];
    flat[7] = 5;
    assert_eq!(otsu_bin(&flat), None);
}
/// A 6.5 px disc on a grey plate whose edge, a straight line, runs
/// 1.5 px beyond the disc's limb (the dark beyond it): the samples
/// three pixels out read the dark, not the plate behind the limb. The
/// ellipse centre stays within 0.02 px (0.014 px; before, when those samples
/// set the outside level, the plate's grey counted as disc: 0.084 px).
#[test]
fn a_background_step_just_outside_the_limb_does_not_pull_the_centre() {
    let (width, height) = (100u32, 80u32);
    let camera = Camera::new(1000.0, 1000.0, 50.0, 40.0, width, height, [0.0; 5]).unwrap();
    let (cx, cy, r) = (50.3, 40.6, 6.5);
    let (nx, ny) = (0.3f64.cos(), 0.3f64.sin());
    let reach = r + 1.5;
    let level = |x: f64, y: f64| {
        if within((cx, cy, r), x, y) {
            900.0
        } else if (x - cx) * nx + (y - cy) * ny < reach {
            150.0
        } else {
            20.0
        }
    };
    let pixels = area_sampled(width, height, 16, 64.0, level);
    let frame = GreyFrame::new(width, height, 16, pixels).unwrap();
    let detection = detect(&frame, &camera, &DetectorConfig::default(), 5.0, 4).unwrap();
    assert_eq!(detection.blobs.len(), 1, "{detection:?}");
    let [x, y] = detection.blobs[0].ellipse_centre_px;
    let error = (x - cx).hypot(y - cy);
    assert!(error < 0.02, "{error} px: {:?}", detection.blobs[0]);
}

/// A frame of `level(x, y)` (pixel centres at integers) averaged over
/// `n` × `n` sub-samples per pixel, times `scale`, rounded.
fn area_sampled(
    width: u32,
    height: u32,
    n: usize,
    scale: f64,
    level: impl Fn(f64, f64) -> f64,
) -> Vec<u16> {
    let mut pixels = vec![0u16; (width * height) as usize];
    for y in 0..height {
        for x in 0..width {
            let mut sum = 0.0;
            for sy in 0..n {
                for sx in 0..n {
                    let px = x as f64 - 0.5 + (sx as f64 + 0.5) / n as f64;
                    let py = y as f64 - 0.5 + (sy as f64 + 0.5) / n as f64;
                    sum += level(px, py);
                }
            }
            pixels[(y * width + x) as usize] = (scale * sum / (n * n) as f64).round() as u16;
        }
    }
    pixels
}

/// Bright discs in front of a large grey plate that Otsu's level puts in
/// the foreground with them (the plate is half the frame): the plate and
/// the discs on it make one component, which is re-segmented at its bright
/// cores. Every disc is found whole, its centre to a few hundredths of a
/// pixel, and the plate itself is no blob.
#[test]
fn discs_in_front_of_a_plate_above_the_threshold_are_found() {
    let (width, height) = (160u32, 120u32);
    let camera = Camera::new(1000.0, 1000.0, 80.0, 60.0, width, height, [0.0; 5]).unwrap();
    let discs = [
        (50.3, 50.6, 5.0),
        (101.7, 48.2, 5.5),
        (75.4, 85.9, 4.5),
        (125.2, 8.1, 5.0),
    ];
    let plate = |x: f64, y: f64| (20.0..140.0).contains(&x) && (20.0..100.0).contains(&y);
    let level = |x: f64, y: f64| {
        if discs.iter().any(|&disc| within(disc, x, y)) {
            230.0
        } else if plate(x, y) {
            70.0
        } else {
            20.0
        }
    };
    let pixels = area_sampled(width, height, 8, 1.0, level);
    let frame = GreyFrame::new(width, height, 8, pixels).unwrap();
    let detection = detect(&frame, &camera, &DetectorConfig::default(), 5.0, 10).unwrap();
    // The plate is above Otsu's level: one class is the background alone.
    assert!(detection.threshold_level < 70.0 / 255.0, "{detection:?}");
    assert_eq!(detection.blobs.len(), discs.len(), "{detection:?}");
    for (cx, cy, r) in discs {
        let blob = detection
            .blobs
            .iter()
            .find(|b| (b.ellipse_centre_px[0] - cx).hypot(b.ellipse_centre_px[1] - cy) < r)
            .unwrap_or_else(|| panic!("no blob at ({cx}, {cy}): {detection:?}"));
        assert!(!blob.hidden(), "{blob:?}");
        let [x, y] = blob.ellipse_centre_px;
        assert!((x - cx).hypot(y - cy) < 0.03, "({cx}, {cy}): {blob:?}");
    }
}

/// White matte spheres under a light at the camera (the cosine law:
/// radiance `√(1 − (r/R)²)` of the centre's, to nothing at the limb),
/// area-sampled 16×16 on a 16-bit frame, radii 5–15 px at three subpixel
/// phases: the detector reads each as shaded, places its edge at the half
/// level's crossing (an outline of the same centre, inside the limb), and
/// finds the centre within 0.05 px with no flag raised. A level read at a
/// fixed sample inside, as for a flat disc, rippled by a few tenths of a
/// pixel with the edge's phase, and cut half the outline away as notches.
#[test]
fn shaded_spheres_are_whole_and_centred() {
    let (width, height) = (80u32, 80u32);
    let camera = Camera::new(1000.0, 1000.0, 40.0, 40.0, 80, 80, [0.0; 5]).unwrap();
    for r in [5.0, 8.0, 15.0] {
        for (cx, cy) in [(40.0, 40.0), (40.3, 39.8), (40.5, 40.25)] {
            let pixels = area_sampled(width, height, 16, 256.0, |x, y| {
                let q = ((x - cx).powi(2) + (y - cy).powi(2)) / (r * r);
                20.0 + 200.0 * (1.0 - q).max(0.0).sqrt()
            });
            let frame = GreyFrame::new(width, height, 16, pixels).unwrap();
            let detection = detect(&frame, &camera, &DetectorConfig::default(), 5.0, 10).unwrap();
            assert_eq!(detection.blobs.len(), 1, "r {r}: {detection:?}");
            let blob = &detection.blobs[0];
            assert!(!blob.hidden(), "r {r} at ({cx}, {cy}): {blob:?}");
            let [x, y] = blob.ellipse_centre_px;
            let error = ((x - cx).powi(2) + (y - cy).powi(2)).sqrt();
            assert!(error < 0.05, "r {r} at ({cx}, {cy}): {error} px");
        }
    }
}

/// Three classes (a dark ground, a wide grey body, a few bright discs):
/// Otsu's two-class level parts the ground from the rest, the upper
/// three-class level parts the discs from the body. Samples in two bins
/// have no three-class split (the detector then applies Otsu's level).
#[test]
fn the_upper_three_class_level_parts_the_brightest_class() {
    let mut histogram = [0u64; 256];
    for (level, count) in [(30usize, 50_000u64), (128, 30_000), (220, 2_000)] {
        for spread in 0..5 {
            histogram[level + spread] += count / 5;
        }
    }
    let two = otsu_bin(&histogram).unwrap();
    let upper = otsu_upper_bin(&histogram).unwrap();
    assert!((34..128).contains(&two), "{two}");
    assert!((132..220).contains(&upper), "{upper}");
    let mut pair = [0u64; 256];
    pair[40] = 1000;
    pair[200] = 10;
    assert_eq!(otsu_upper_bin(&pair), None);
    assert_eq!(otsu_bin(&pair), Some(40));
}
