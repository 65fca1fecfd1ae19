//! `track`'s poses against `render`'s ground truth: the RMS rotation error
//! over the tracked frames of a JSON-lines file, raw and after the one
//! rotation common to every frame (the choice of the part's frame: a
//! characterised layout's frame overlays the nominal's, not the printed
//! part's own, which no image can show), and the RMS of the σ `track`
//! reported. With the covariance `track` wrote, the mean normalised
//! squared pose error `eᵀ Σ⁻¹ e` of `e = (rvec − rvec_true, t − t_true)`:
//! 6 for an honest covariance of known σ (`track`'s default, σ from the
//! blobs), 8 for one whose σ is estimated from the 8 residual degrees of
//! freedom of 7 spheres (`solve`'s); and its rotation and translation
//! parts alone (3 each, or 4).
//!
//! ```text
//! cargo run --release --example pose_against_truth -- poses.jsonl
//! ```
//!
//! Each record's frame `X.png` must have its render record `X.json`
//! beside it. On `track --set` records of frames of several markers
//! (`render SET.json --poses SCENES.json`), each record is judged against
//! its marker's truth in the frame, and the run also counts the markers
//! named wrong (a marker the frame does not show, or a pose 20 mm or more
//! from its truth), the poses within the 3σ ellipsoid of their covariance
//! (`eᵀΣ⁻¹e` ≤ 20.06, the 99.73% point of χ² with 6 degrees of freedom),
//! and the markers the frames show whole (every sphere unhidden and its
//! disc clear of every other by 2 px) that were not found.

use nalgebra::{Matrix3, Rotation3, SMatrix, SVector, Vector3};

fn rotation(value: &serde_json::Value) -> Option<Rotation3<f64>> {
    let rows = value.as_array()?;
    let mut m = Matrix3::zeros();
    for (i, row) in rows.iter().enumerate().take(3) {
        for (j, v) in row.as_array()?.iter().enumerate().take(3) {
            m[(i, j)] = v.as_f64()?;
        }
    }
    Some(Rotation3::from_matrix(&m))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .ok_or("usage: pose_against_truth POSES.jsonl")?;
    let mut offsets = Vec::new();
    let mut sigmas = Vec::new();
    let mut normalised = Vec::new();
    let mut scenes = Scenes::default();
    for line in std::fs::read_to_string(&path)?.lines() {
        let record: serde_json::Value = serde_json::from_str(line)?;
        let frame = record["frame"].as_str().ok_or("a record without a frame")?;
        let truth_path = std::path::Path::new(frame).with_extension("json");
        let frame_truth: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&truth_path)?)?;
        if frame_truth.get("markers").is_some() {
            scenes.frame(frame, &frame_truth);
        }
        if record.get("error").is_some() {
            continue;
        }
        let truth_record = match record["marker"].as_u64() {
            None => frame_truth,
            Some(marker) => match scenes.judge(frame, marker, &record, &frame_truth) {
                Some(truth) => truth,
                None => continue,
            },
        };
        let (Some(estimate), Some(truth)) = (rotation(&record["R"]), rotation(&truth_record["R"]))
        else {
            return Err(format!("{frame}: no rotation").into());
        };
        // The error in the part's frame: truthᵀ · estimate.
        offsets.push(truth.inverse() * estimate);
        sigmas.push(record["sigma_rot_deg"].as_f64().unwrap_or(f64::NAN));
        if let Some(nse) = normalised_squared_error(&record, &truth_record, estimate) {
            normalised.push(nse);
            scenes.within_3_sigma += usize::from(nse[0] <= CHI2_6_3SIGMA);
        }
    }
    if !scenes.frames.is_empty() {
        scenes.print();
    }
    if offsets.is_empty() {
        return Err("no tracked frames".into());
    }
    let n = offsets.len() as f64;
    let mean: Vector3<f64> = offsets
        .iter()
        .map(|r| r.scaled_axis())
        .sum::<Vector3<f64>>()
        / n;
    let common = Rotation3::new(mean);
    let rms =
        |errors: &mut dyn Iterator<Item = f64>| (errors.map(|e| e * e).sum::<f64>() / n).sqrt();
    let raw = rms(&mut offsets.iter().map(|r| r.angle().to_degrees()));
    let relative = rms(&mut offsets
        .iter()
        .map(|r| (r * common.inverse()).angle().to_degrees()));
    let sigma = rms(&mut sigmas.iter().copied());
    println!(
        "{} frames: rotation RMS {relative:.4}° after the common rotation of {:.4}° (raw {raw:.4}°); track's σ RMS {sigma:.4}°",
        offsets.len(),
        common.angle().to_degrees()
    );
    if !normalised.is_empty() {
        let m = normalised.len() as f64;
        let mean = |part: usize| normalised.iter().map(|e| e[part]).sum::<f64>() / m;
        println!(
            "mean normalised squared error over {} frames: pose {:.2} (6 if honest), rotation {:.2} (3), translation {:.2} (3)",
            normalised.len(),
            mean(0),
            mean(1),
            mean(2)
        );
    }
    Ok(())
}

/// `[pose, rotation, translation]` normalised squared errors of one
/// record against its truth, by the record's covariance of (rvec, tvec).
fn normalised_squared_error(
    record: &serde_json::Value,
    truth: &serde_json::Value,
    estimate: Rotation3<f64>,
) -> Option<[f64; 3]> {
    let truth_rotation = rotation(&truth["R"])?;
    let rows = record["covariance"].as_array()?;
    let mut covariance = SMatrix::<f64, 6, 6>::zeros();
    for (i, row) in rows.iter().enumerate().take(6) {
        for (j, v) in row.as_array()?.iter().enumerate().take(6) {
            covariance[(i, j)] = v.as_f64()?;
        }
    }
    let mut error = SVector::<f64, 6>::zeros();
    let rvec = Vector3::new(
        record["rvec"][0].as_f64()?,
        record["rvec"][1].as_f64()?,
        record["rvec"][2].as_f64()?,
    );
    // The left perturbation ω (estimate = exp([ω]×) truth) in rvec's
    // coordinates, as track's covariance is written.
    let omega = (estimate * truth_rotation.inverse()).scaled_axis();
    let rotation_error = layout_opt::track::uncertainty::inverse_left_jacobian(&rvec) * omega;
    error.fixed_rows_mut::<3>(0).copy_from(&rotation_error);
    for k in 0..3 {
        error[3 + k] = record["t"][k].as_f64()? - truth["t"][k].as_f64()?;
    }
    let quadratic = |c: SMatrix<f64, 3, 3>, e: Vector3<f64>| Some(e.dot(&(c.try_inverse()? * e)));
    Some([
        error.dot(&(covariance.try_inverse()? * error)),
        quadratic(
            covariance.fixed_view::<3, 3>(0, 0).into(),
            error.fixed_rows::<3>(0).into(),
        )?,
        quadratic(
            covariance.fixed_view::<3, 3>(3, 3).into(),
            error.fixed_rows::<3>(3).into(),
        )?,
    ])
}

/// The 99.73% point of χ² with 6 degrees of freedom: a pose error within
/// the 3σ ellipsoid of its covariance.
const CHI2_6_3SIGMA: f64 = 20.06;

/// A translation error that names the wrong marker, mm.
const WRONG_MARKER_MM: f64 = 20.0;

/// Counts over frames of several markers.
#[derive(Default)]
struct Scenes {
    /// Frames seen.
    frames: std::collections::BTreeSet<String>,
    /// (frame, marker) shown whole.
    whole: std::collections::BTreeSet<(String, u64)>,
    /// (frame, marker) found right.
    found: std::collections::BTreeSet<(String, u64)>,
    /// Markers shown: all, and partly hidden by another marker.
    shown: usize,
    hidden_by_other: usize,
    /// Records naming a marker wrong.
    wrong: usize,
    /// Records posed within their 3σ ellipsoid.
    within_3_sigma: usize,
}

impl Scenes {
    /// Counts the markers `truth` shows, once per frame.
    fn frame(&mut self, frame: &str, truth: &serde_json::Value) {
        if !self.frames.insert(frame.to_string()) {
            return;
        }
        let markers = truth["markers"].as_array().cloned().unwrap_or_default();
        let discs: Vec<(u64, [f64; 2], f64)> = markers
            .iter()
            .flat_map(|m| {
                let number = m["marker"].as_u64().unwrap_or(0);
                m["spheres"]
                    .as_array()
                    .cloned()
                    .unwrap_or_default()
                    .into_iter()
                    .map(move |s| {
                        let c = &s["ellipse_centre_px"];
                        (
                            number,
                            [
                                c[0].as_f64().unwrap_or(f64::NAN),
                                c[1].as_f64().unwrap_or(f64::NAN),
                            ],
                            s["semi_axes_px"][0].as_f64().unwrap_or(f64::NAN),
                        )
                    })
            })
            .collect();
        for m in &markers {
            let number = m["marker"].as_u64().unwrap_or(0);
            self.shown += 1;
            let spheres = m["spheres"].as_array().cloned().unwrap_or_default();
            let hidden =
                |s: &serde_json::Value, key: &str| s["hidden"][key].as_f64().unwrap_or(1.0);
            self.hidden_by_other +=
                usize::from(spheres.iter().any(|s| hidden(s, "by_other_marker") > 0.0));
            let unhidden = spheres.iter().all(|s| {
                [
                    "by_support",
                    "by_sphere",
                    "outside_image",
                    "by_other_marker",
                ]
                .iter()
                .all(|key| hidden(s, key) == 0.0)
            });
            let clear = discs.iter().enumerate().all(|(a, (_, ca, ra))| {
                discs[a + 1..].iter().all(|(_, cb, rb)| {
                    ((ca[0] - cb[0]).powi(2) + (ca[1] - cb[1]).powi(2)).sqrt() > ra + rb + 2.0
                })
            });
            if unhidden && clear && discs.iter().any(|d| d.0 == number) {
                self.whole.insert((frame.to_string(), number));
            }
        }
    }

    /// The truth of the marker `record` names, or None (counted as wrong)
    /// when the frame does not show it or the pose is far from it.
    fn judge(
        &mut self,
        frame: &str,
        marker: u64,
        record: &serde_json::Value,
        truth: &serde_json::Value,
    ) -> Option<serde_json::Value> {
        let shown = truth["markers"]
            .as_array()?
            .iter()
            .find(|m| m["marker"].as_u64() == Some(marker))
            .cloned();
        let near = shown.as_ref().is_some_and(|m| {
            (0..3)
                .map(|k| {
                    (record["t"][k].as_f64().unwrap_or(f64::NAN)
                        - m["t"][k].as_f64().unwrap_or(f64::NAN))
                    .powi(2)
                })
                .sum::<f64>()
                .sqrt()
                < WRONG_MARKER_MM
        });
        if !near {
            self.wrong += 1;
            return None;
        }
        self.found.insert((frame.to_string(), marker));
        shown
    }

    fn print(&self) {
        let missed = self.whole.difference(&self.found).count();
        println!(
            "{} frames showing {} markers ({} partly hidden by another marker, {} whole and clear): {} found right, {} records naming a marker wrong, {} of the {} whole markers not found; {} poses within their 3σ ellipsoid",
            self.frames.len(),
            self.shown,
            self.hidden_by_other,
            self.whole.len(),
            self.found.len(),
            self.wrong,
            missed,
            self.whole.len(),
            self.within_3_sigma
        );
    }
}
