//! `validate SET.json`: each marker's predicted identifiability against
//! itself, the set's cross matrix, and seeded trials of every marker
//! identified against the whole set, with the report and its JSON.

use crate::camera::Camera;
use crate::identifiability::{self, IdentifiabilitySettings};
use crate::montecarlo::Target;
use crate::scenario::Scenario;
use crate::set::{cross_matrix, set_trials, CrossMatrix, MarkerSet, SetTrialCounts};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// What [`validate_set`] found.
#[derive(Debug, Clone)]
pub struct SetValidation {
    /// The set's name.
    pub set: String,
    /// The markers' names, in the set's order.
    pub markers: Vec<String>,
    /// Each marker's layout file, as the set file names it.
    pub files: Vec<String>,
    /// Per marker: scenarios predicted identifiable against itself, of
    /// those in which every sphere is in front.
    pub identifiable: Vec<(usize, usize)>,
    /// The cross matrix.
    pub matrix: CrossMatrix,
    /// Per marker, its trials against the whole set.
    pub counts: Vec<SetTrialCounts>,
    /// `named[i][j]`: trials of marker i that named marker j.
    pub named: Vec<Vec<usize>>,
    /// Scenarios of the working volume.
    pub scenarios: usize,
    /// The settings the trials ran with.
    pub settings: IdentifiabilitySettings,
    /// Wall time, s.
    pub seconds: f64,
}

/// Validates `set` seen by `camera` over `scenarios` (module docs).
pub fn validate_set(
    set: &MarkerSet,
    camera: &Camera,
    scenarios: &[Scenario],
    settings: &IdentifiabilitySettings,
) -> SetValidation {
    let objects = set.objects();
    let sigmas: Vec<Vec<Option<f64>>> = set
        .members
        .iter()
        .map(|m| m.layout.point_sigmas())
        .collect();
    let diameter = set.members[0].layout.sphere_diameter_mm;
    let targets: Vec<Target> = objects
        .iter()
        .zip(&sigmas)
        .map(|(object, sigmas)| Target {
            camera,
            object,
            sphere_diameter_mm: diameter,
            point_sigma_px: sigmas,
        })
        .collect();
    let started = Instant::now();
    let stop = AtomicBool::new(false);
    let prediction_only = IdentifiabilitySettings {
        trials: 0,
        ..*settings
    };
    let identifiable = targets
        .iter()
        .map(|target| {
            let results = identifiability::run_until(
                target,
                scenarios,
                &prediction_only,
                &|_| true,
                &|_| {},
                &stop,
            )
            .unwrap_or_default();
            let seen: Vec<_> = results
                .iter()
                .flatten()
                .filter(|r| r.prediction.is_some())
                .collect();
            let identifiable = seen.iter().filter(|r| r.identifiable(settings)).count();
            (identifiable, seen.len())
        })
        .collect();
    let matrix = cross_matrix(&targets, &set.names(), scenarios, settings);
    let (counts, named) = set_trials(&targets, scenarios, settings);
    SetValidation {
        set: set.name.clone(),
        markers: set.names(),
        files: set.members.iter().map(|m| m.file.clone()).collect(),
        identifiable,
        matrix,
        counts,
        named,
        scenarios: scenarios.len(),
        settings: *settings,
        seconds: started.elapsed().as_secs_f64(),
    }
}

impl SetValidation {
    /// The report, headed by `command`.
    pub fn markdown(&self, command: &str) -> String {
        let settings = &self.settings;
        let mut report = format!(
            "# Marker set {}: {} markers\n\n`{}`\n\n{} scenarios; {} seeded trials per marker and visible scenario, each identified against the whole set (seed {}); {:.1} s. Cross floor: a viewpoint counts when the predicted confusion probability is at most {:.1e}; every pair meets it in {:.1}% of its visible viewpoints: {}.\n\n## Markers\n\n| marker | file | identifiable (predicted) | trials | named another marker | wrong labels | no fit |\n|---|---|---|---|---|---|---|\n",
            self.set,
            self.markers.len(),
            command,
            self.scenarios,
            settings.trials,
            settings.seed,
            self.seconds,
            1.0 - settings.min_correct,
            100.0 * settings.min_correct,
            if self.matrix.meets_floor() { "yes" } else { "no" },
        );
        for (k, c) in self.counts.iter().enumerate() {
            report.push_str(&format!(
                "| {} ({}) | {} | {} of {} | {} | {} | {} | {} |\n",
                k + 1,
                self.markers[k],
                self.files[k],
                self.identifiable[k].0,
                self.identifiable[k].1,
                c.trials,
                c.wrong_marker,
                c.wrong_labels,
                c.failed
            ));
        }
        report.push_str(&super::matrix_markdown(&self.matrix));
        report
    }

    /// The figures as JSON (`set.json`).
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "set": self.set,
            "markers": self.markers,
            "identifiable": self
                .identifiable
                .iter()
                .map(|(i, v)| serde_json::json!({"identifiable": i, "visible": v}))
                .collect::<Vec<_>>(),
            "matrix": self.matrix,
            "trials": self.counts,
            "named": self.named,
            "seconds": self.seconds,
        })
    }

    /// Writes `set-report.md` (headed by `command`) and `set.json` into
    /// `dir`, each atomically; returns the report's path.
    pub fn write(&self, dir: &Path, command: &str) -> std::io::Result<PathBuf> {
        write_reports(dir, &self.markdown(command), &self.json())
    }

    /// One line for the console.
    pub fn summary(&self) -> String {
        let confused: usize = self.counts.iter().map(|c| c.wrong_marker).sum();
        let trials: usize = self.counts.iter().map(|c| c.trials).sum();
        format!(
            "set {}: {} markers over {} scenarios; smallest cross margin {}; cross floor met: {}; {confused} of {trials} trials named another marker",
            self.set,
            self.markers.len(),
            self.scenarios,
            self.matrix
                .smallest_margin_px()
                .map_or("above the gate everywhere".to_string(), |m| format!("{m:.2} px")),
            if self.matrix.meets_floor() { "yes" } else { "no" },
        )
    }
}

/// Writes a set's `set-report.md` and `set.json` into `dir`, each
/// atomically; returns the report's path.
pub fn write_reports(
    dir: &Path,
    markdown: &str,
    json: &serde_json::Value,
) -> std::io::Result<PathBuf> {
    let report = dir.join("set-report.md");
    crate::files::write_text_atomic(&report, markdown)?;
    crate::files::write_text_atomic(
        &dir.join("set.json"),
        &(serde_json::to_string_pretty(json)? + "\n"),
    )?;
    Ok(report)
}
