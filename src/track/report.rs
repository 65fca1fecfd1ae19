//! `track`'s output, rendered from the analyses: one JSON line per frame
//! (docs/formats.md, "`track` output", contract), a CSV table on request,
//! and annotated overlay PNGs. Nothing here computes anything new.

use super::analysis::{FrameAnalysis, TrackedFrame};
use super::detect::{Blob, Detection, Rejected};
use super::frame::GreyFrame;
use crate::camera::Camera;
use crate::pose::Pose;
use crate::sphere_image::SphereSilhouette;
use image::{ImageFormat, Rgb, RgbImage};
use imageproc::drawing::{draw_cross_mut, draw_line_segment_mut};
use nalgebra::Vector2;
use serde::Serialize;

/// One JSON line: a tracked frame or an error record.
#[derive(Debug, Clone, Serialize)]
#[serde(untagged)]
pub enum FrameRecord<'a> {
    /// A frame with a pose.
    Tracked {
        /// The frame's name (its path as given).
        frame: &'a str,
        /// The pose fields.
        #[serde(flatten)]
        tracked: &'a TrackedFrame,
        /// The detector's figures per blob.
        blobs: &'a [Blob],
        /// Components rejected, by reason.
        rejected: &'a Rejected,
        /// The threshold the detector applied.
        threshold: AppliedThreshold,
    },
    /// A frame without one.
    Failed {
        /// The frame's name.
        frame: &'a str,
        /// Why, in one line.
        error: String,
        /// The detector's figures, when it got that far.
        #[serde(skip_serializing_if = "Option::is_none")]
        blobs: Option<&'a [Blob]>,
        /// The threshold the detector applied, when it got that far.
        #[serde(skip_serializing_if = "Option::is_none")]
        threshold: Option<AppliedThreshold>,
    },
}

/// The threshold the detector applied to a frame: under `--threshold
/// auto`, the one it chose.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AppliedThreshold {
    /// As `--threshold` names it: `otsu`, `otsu3`, `local:R:OFFSET` or the
    /// fixed level.
    pub applied: String,
    /// The global level, or the local offset, fraction of full scale.
    pub level: f64,
}

impl AppliedThreshold {
    fn of(detection: &Detection) -> AppliedThreshold {
        AppliedThreshold {
            applied: detection.threshold.to_string(),
            level: detection.threshold_level,
        }
    }
}

/// The record of `analysis` of frame `name`.
pub fn record<'a>(name: &'a str, analysis: &'a FrameAnalysis) -> FrameRecord<'a> {
    match (&analysis.outcome, &analysis.detection) {
        (Ok(tracked), Some(detection)) => FrameRecord::Tracked {
            frame: name,
            tracked,
            blobs: &detection.blobs,
            rejected: &detection.rejected,
            threshold: AppliedThreshold::of(detection),
        },
        (Ok(_), None) => unreachable!("a tracked frame has a detection"),
        (Err(error), detection) => FrameRecord::Failed {
            frame: name,
            error: error.to_string(),
            blobs: detection.as_ref().map(|d| d.blobs.as_slice()),
            threshold: detection.as_ref().map(AppliedThreshold::of),
        },
    }
}

/// The JSON-lines document of every frame, in input order.
pub fn json_lines(frames: &[(String, FrameAnalysis)]) -> String {
    let mut out = String::new();
    for (name, analysis) in frames {
        out.push_str(&serde_json::to_string(&record(name, analysis)).expect("records serialise"));
        out.push('\n');
    }
    out
}

/// The CSV table: one row per frame, the pose and its 1σ figures.
pub fn csv(frames: &[(String, FrameAnalysis)]) -> String {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let header = [
        "frame",
        "status",
        "error",
        "blobs",
        "labels",
        "ambiguity",
        "wrong_label_probability",
        "rvec_x",
        "rvec_y",
        "rvec_z",
        "tvec_x",
        "tvec_y",
        "tvec_z",
        "sigma_px",
        "sigma_rot_deg",
        "sigma_trans_mm",
        "reprojection_rms_px",
    ];
    writer.write_record(header).expect("writing to memory");
    for (name, analysis) in frames {
        let blobs = analysis
            .detection
            .as_ref()
            .map_or(String::new(), |d| d.blobs.len().to_string());
        let row: Vec<String> = match &analysis.outcome {
            Ok(t) => {
                let labels: Vec<String> = t
                    .labels
                    .iter()
                    .map(|l| l.map_or("-".to_string(), |l| l.to_string()))
                    .collect();
                let f = &t.figures;
                let mut row = vec![
                    name.clone(),
                    "tracked".into(),
                    String::new(),
                    blobs,
                    labels.join(" "),
                    t.ambiguity.map_or(String::new(), |a| a.to_string()),
                    t.wrong_label_probability.to_string(),
                ];
                row.extend(f.rvec.iter().chain(&f.tvec).map(|v| v.to_string()));
                row.extend(
                    [
                        f.sigma_px,
                        f.sigma_rot_deg,
                        f.sigma_trans_mm,
                        t.reprojection_rms_px,
                    ]
                    .iter()
                    .map(|v| v.to_string()),
                );
                row
            }
            Err(error) => {
                let mut row = vec![name.clone(), "error".into(), error.to_string(), blobs];
                row.resize(header.len(), String::new());
                row
            }
        };
        writer.write_record(&row).expect("writing to memory");
    }
    String::from_utf8(writer.into_inner().expect("flushing to memory")).expect("CSV is UTF-8")
}

/// 3×5 bitmaps of the digits 0–9, one row per `u8` (3 low bits, left = 4).
const DIGITS: [[u8; 5]; 10] = [
    [7, 5, 5, 5, 7],
    [2, 6, 2, 2, 7],
    [7, 1, 7, 4, 7],
    [7, 1, 7, 1, 7],
    [5, 5, 7, 1, 1],
    [7, 4, 7, 1, 7],
    [7, 4, 7, 5, 7],
    [7, 1, 1, 1, 1],
    [7, 5, 7, 5, 7],
    [7, 5, 7, 1, 7],
];
/// Pixels per bitmap cell of the overlay's digits.
const DIGIT_SCALE: i64 = 3;

fn draw_number(image: &mut RgbImage, number: usize, x: i64, y: i64, colour: Rgb<u8>) {
    for (position, digit) in number.to_string().bytes().enumerate() {
        let bitmap = DIGITS[usize::from(digit - b'0')];
        let left = x + position as i64 * 4 * DIGIT_SCALE;
        for (row, bits) in bitmap.iter().enumerate() {
            for column in 0..3 {
                if bits & (4 >> column) == 0 {
                    continue;
                }
                for dy in 0..DIGIT_SCALE {
                    for dx in 0..DIGIT_SCALE {
                        let px = left + column * DIGIT_SCALE + dx;
                        let py = y + row as i64 * DIGIT_SCALE + dy;
                        if px >= 0
                            && py >= 0
                            && (px as u32) < image.width()
                            && (py as u32) < image.height()
                        {
                            image.put_pixel(px as u32, py as u32, colour);
                        }
                    }
                }
            }
        }
    }
}

/// Overlay colours: whole blobs, hidden blobs, the reprojected model.
const WHOLE: Rgb<u8> = Rgb([40, 220, 40]);
const HIDDEN: Rgb<u8> = Rgb([240, 40, 40]);
const MODEL: Rgb<u8> = Rgb([60, 140, 255]);

/// An annotated PNG of `frame`: each blob's centre as a cross (green whole,
/// red flagged as partly hidden) with its label, and with a pose the model
/// silhouette of every sphere (blue outline).
pub fn overlay_png(
    frame: &GreyFrame,
    analysis: &FrameAnalysis,
    camera: &Camera,
    object: &[nalgebra::Vector3<f64>],
    radius_mm: f64,
    pose: Option<&Pose>,
) -> Vec<u8> {
    let shift = frame.bit_depth() - 8;
    let mut image = RgbImage::from_fn(frame.width(), frame.height(), |x, y| {
        let v = (frame.at(x, y) >> shift) as u8;
        Rgb([v, v, v])
    });
    if let Some(pose) = pose {
        for p in object {
            let Ok(silhouette) = SphereSilhouette::new(camera, &pose.transform(p), radius_mm)
            else {
                continue;
            };
            let Some(ellipse) = super::conic::Ellipse::from_conic(&silhouette.conic_px) else {
                continue;
            };
            let eigen = nalgebra::SymmetricEigen::new(ellipse.shape);
            const STEPS: usize = 72;
            let point = |k: usize| {
                let angle = std::f64::consts::TAU * k as f64 / STEPS as f64;
                let local = Vector2::new(
                    angle.cos() / eigen.eigenvalues[0].sqrt(),
                    angle.sin() / eigen.eigenvalues[1].sqrt(),
                );
                // Undistorted pixels back through the lens.
                let ideal = ellipse.centre + eigen.eigenvectors * local;
                let m = Vector2::new(
                    (ideal.x - camera.cx()) / camera.fx(),
                    (ideal.y - camera.cy()) / camera.fy(),
                );
                let raw = camera.normalised_to_pixel(&m);
                (raw.x as f32, raw.y as f32)
            };
            for k in 0..STEPS {
                draw_line_segment_mut(&mut image, point(k), point(k + 1), MODEL);
            }
        }
    }
    if let Some(detection) = &analysis.detection {
        for blob in &detection.blobs {
            let colour = if blob.hidden() { HIDDEN } else { WHOLE };
            let [x, y] = blob.ellipse_centre_px;
            draw_cross_mut(&mut image, colour, x.round() as i32, y.round() as i32);
            if let Some(label) = blob.label {
                let offset = blob.semi_axes_px[0] + 4.0;
                draw_number(
                    &mut image,
                    label,
                    (x + offset) as i64,
                    (y - offset) as i64,
                    colour,
                );
            }
        }
    }
    let mut bytes = Vec::new();
    image
        .write_to(&mut std::io::Cursor::new(&mut bytes), ImageFormat::Png)
        .expect("encoding a PNG into memory cannot fail");
    bytes
}
