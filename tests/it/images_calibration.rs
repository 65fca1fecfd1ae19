//! The noise calibration files shipped under `calibration/`: every one
//! loads, its law falls (never rises) with the blob's radius, it records
//! the command that made it, and `docs/calibration.md` lists it with that
//! command.

use layout_opt::noise::calibrated::CalibrationFile;
use std::path::Path;

fn shipped() -> Vec<std::path::PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("calibration");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.extension().is_some_and(|e| e == "json"))
        .collect();
    files.sort();
    files
}

#[test]
fn every_shipped_calibration_loads_falls_with_radius_and_is_documented() {
    let files = shipped();
    let names: Vec<String> = files
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    // The paper's camera is the default preset; its file must ship.
    assert!(names.contains(&"paper.json".to_string()), "{names:?}");
    let docs =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/calibration.md"))
            .unwrap();
    for (path, name) in files.iter().zip(&names) {
        let file = CalibrationFile::load(path).unwrap_or_else(|e| panic!("{name}: {e}"));
        let law = file.sigma().unwrap();
        let [low, high] = file.radius_px;
        assert!(0.0 < low && low < high, "{name}: {:?}", file.radius_px);
        let sigmas: Vec<f64> = (0..=20)
            .map(|k| law.sigma(low + (high - low) * k as f64 / 20.0))
            .collect();
        assert!(
            sigmas.windows(2).all(|w| w[1] <= w[0]) && sigmas[20] > 0.0,
            "{name}: σ over {low}–{high} px: {sigmas:?}"
        );
        let target = format!("--write-noise-model calibration/{name}");
        assert!(file.source.contains(&target), "{name}: {}", file.source);
        let command = file.source.split(" (seed").next().unwrap();
        assert!(
            docs.contains(command),
            "docs/calibration.md does not give {name}'s command: {command}"
        );
    }
}
