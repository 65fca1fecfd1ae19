//! A characterised layout against the part it measured: each centre's
//! error after overlaying the true centres on the nominal (the gauge
//! `characterise` reports in: a similarity, or with `--rigid` a rigid
//! motion when distances gave the scale), and its normalised squared
//! error against the covariance the layout's provenance carries.
//!
//! ```text
//! cargo run --release --example layout_against_truth -- MEASURED.json TRUTH.json NOMINAL.json [--rigid]
//! ```

use layout_opt::characterise::gauge::Similarity;
use layout_opt::layout::Layout;
use nalgebra::Matrix3;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [measured, truth, nominal, ..] = args.as_slice() else {
        return Err(
            "usage: layout_against_truth MEASURED.json TRUTH.json NOMINAL.json [--rigid]".into(),
        );
    };
    let rigid = args.iter().any(|a| a == "--rigid");
    let (measured, truth, nominal) = (
        Layout::load(measured.as_ref())?,
        Layout::load(truth.as_ref())?,
        Layout::load(nominal.as_ref())?,
    );
    let (t, n) = (truth.positions(), nominal.positions());
    let overlay = if rigid {
        Similarity::rigid_onto(&t, &n)
    } else {
        Similarity::onto(&t, &n)
    };
    let covariances = measured
        .provenance
        .as_ref()
        .and_then(|p| p.get("characterised")?.get("covariance_mm2").cloned())
        .ok_or("MEASURED has no characterised covariance")?;
    let (mut sum_squared, mut sum_nse) = (0.0, 0.0);
    for (point, truth) in measured.points.iter().zip(overlay.apply_all(&t)) {
        let e = point.position - truth;
        let c: Vec<Vec<f64>> = serde_json::from_value(covariances[&point.name].clone())?;
        let c = Matrix3::from_fn(|r, k| c[r][k]);
        let nse = (e.transpose() * c.try_inverse().ok_or("a singular covariance")? * e)[0];
        println!("{}: error {:.4} mm, NSE {nse:.2}", point.name, e.norm());
        sum_squared += e.norm_squared();
        sum_nse += nse;
    }
    let count = measured.points.len() as f64;
    println!(
        "RMS error {:.4} mm over {} centres, mean NSE {:.2} (3 expected)",
        (sum_squared / count).sqrt(),
        measured.points.len(),
        sum_nse / count
    );
    Ok(())
}
