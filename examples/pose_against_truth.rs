//! `track`'s poses against `render`'s ground truth: the RMS rotation error
//! over the tracked frames of a JSON-lines file, raw and after the one
//! rotation common to every frame (the choice of the part's frame: a
//! characterised layout's frame overlays the nominal's, not the printed
//! part's own, which no image can show), and the RMS of the σ `track`
//! reported.
//!
//! ```text
//! cargo run --release --example pose_against_truth -- poses.jsonl
//! ```
//!
//! Each record's frame `X.png` must have its render record `X.json`
//! beside it.

use nalgebra::{Matrix3, Rotation3, Vector3};

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
    for line in std::fs::read_to_string(&path)?.lines() {
        let record: serde_json::Value = serde_json::from_str(line)?;
        if record.get("error").is_some() {
            continue;
        }
        let frame = record["frame"].as_str().ok_or("a record without a frame")?;
        let truth_path = std::path::Path::new(frame).with_extension("json");
        let truth: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&truth_path)?)?;
        let (Some(estimate), Some(truth)) = (rotation(&record["R"]), rotation(&truth["R"])) else {
            return Err(format!("{frame}: no rotation").into());
        };
        // The error in the part's frame: truthᵀ · estimate.
        offsets.push(truth.inverse() * estimate);
        sigmas.push(record["sigma_rot_deg"].as_f64().unwrap_or(f64::NAN));
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
    Ok(())
}
