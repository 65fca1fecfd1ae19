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
//! beside it.

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
    for line in std::fs::read_to_string(&path)?.lines() {
        let record: serde_json::Value = serde_json::from_str(line)?;
        if record.get("error").is_some() {
            continue;
        }
        let frame = record["frame"].as_str().ok_or("a record without a frame")?;
        let truth_path = std::path::Path::new(frame).with_extension("json");
        let truth_record: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&truth_path)?)?;
        let (Some(estimate), Some(truth)) = (rotation(&record["R"]), rotation(&truth_record["R"]))
        else {
            return Err(format!("{frame}: no rotation").into());
        };
        // The error in the part's frame: truthᵀ · estimate.
        offsets.push(truth.inverse() * estimate);
        sigmas.push(record["sigma_rot_deg"].as_f64().unwrap_or(f64::NAN));
        if let Some(nse) = normalised_squared_error(&record, &truth_record, estimate) {
            normalised.push(nse);
        }
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
