//! `validate SET.json`: each marker's predicted identifiability against
//! itself, the set's cross matrix, and seeded trials of every marker
//! identified against the whole set, with the report and its JSON.

use crate::camera::Camera;
use crate::identifiability::{self, IdentifiabilitySettings};
use crate::montecarlo::Target;
use crate::scenario::Scenario;
use crate::set::dips::{find_dips, Dip, Sample};
use crate::set::{
    all_pairs, cross_matrix, cross_scenario, missing_blob_trials, set_trials, CrossMatrix,
    FoundLabelling, MarkerSet, SetTrialCounts, NEAR_SHARE,
};
use crate::volume::WorkingVolume;
use rayon::prelude::*;
use serde::Serialize;
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
    /// Per ordered pair, the dips between the volume's viewpoints
    /// ([`crate::set::dips`]) and the trials at those that fail the floor.
    pub between: Vec<PairDips>,
    /// Per ordered pair, the viewpoints near the floor whose worst case
    /// leaves a blob out, and the trials there without that blob.
    pub near: Vec<PairNear>,
    /// Scenarios of the working volume.
    pub scenarios: usize,
    /// The settings the trials ran with.
    pub settings: IdentifiabilitySettings,
    /// Wall time, s.
    pub seconds: f64,
}

/// One ordered pair's dips between the viewpoints.
#[derive(Debug, Clone, Serialize)]
pub struct PairDips {
    /// The marker whose blobs are seen.
    pub marker: usize,
    /// The marker offered as the model.
    pub rival: usize,
    /// Dips whose predicted confusion exceeds [`NEAR_SHARE`] of the
    /// criterion.
    pub near: usize,
    /// Dips that fail the floor.
    pub failing: usize,
    /// The worst dip.
    pub worst: Option<Dip>,
    /// Trials at the failing dips, each frame without the dip's blob.
    pub trials: usize,
    /// Those trials that named another marker.
    pub wrong_marker: usize,
    /// The failing dips' predicted confusion probabilities, summed over
    /// their trials (the expected count of `wrong_marker`).
    pub expected_wrong: f64,
}

/// One ordered pair's viewpoints near the floor (predicted confusion above
/// [`NEAR_SHARE`] of the criterion) whose worst case leaves a blob out:
/// the grid's trials draw every blob, so these are tried again with that
/// blob left out of every frame, identified against the whole set with
/// one missing blob allowed.
#[derive(Debug, Clone, Serialize)]
pub struct PairNear {
    /// The marker whose blobs are seen.
    pub marker: usize,
    /// The marker offered as the model.
    pub rival: usize,
    /// Viewpoints near the floor.
    pub near: usize,
    /// Those whose worst case leaves a blob out.
    pub missing: usize,
    /// Trials there, each frame without that blob.
    pub trials: usize,
    /// Those trials that named another marker.
    pub wrong_marker: usize,
    /// The predicted confusion probabilities summed over the trials (the
    /// expected count of `wrong_marker`).
    pub expected_wrong: f64,
}

/// Validates `set` seen by `camera` over `volume`'s viewpoints and
/// between them (module docs).
pub fn validate_set(
    set: &MarkerSet,
    camera: &Camera,
    volume: &WorkingVolume,
    settings: &IdentifiabilitySettings,
) -> SetValidation {
    let scenarios = &volume.scenarios(camera)[..];
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
    let samples: Vec<Sample> = scenarios
        .iter()
        .copied()
        .zip(volume.unit_points())
        .collect();
    let between = all_pairs(targets.len())
        .into_iter()
        .map(|(i, j)| {
            let found = matrix.pair(i, j).map_or(&[][..], |p| &p.found[..]);
            pair_dips(&targets, (i, j), volume, (&samples, found), settings)
        })
        .collect();
    let near = all_pairs(targets.len())
        .into_iter()
        .map(|(i, j)| near_trials(&targets, (i, j), scenarios, &matrix, settings))
        .collect();
    SetValidation {
        near,
        set: set.name.clone(),
        markers: set.names(),
        files: set.members.iter().map(|m| m.file.clone()).collect(),
        identifiable,
        matrix,
        counts,
        named,
        between,
        scenarios: scenarios.len(),
        settings: *settings,
        seconds: started.elapsed().as_secs_f64(),
    }
}

/// The dips of marker `i`'s blobs explained by marker `j` over `volume`
/// (followed from its `samples` and from the labellings `found` on them),
/// and `settings.trials` trials at each failing dip, the dip's blob left
/// out of every frame, identified against the whole set.
fn pair_dips(
    targets: &[Target],
    (i, j): (usize, usize),
    volume: &WorkingVolume,
    (samples, found): (&[Sample], &[FoundLabelling]),
    settings: &IdentifiabilitySettings,
) -> PairDips {
    let first = samples.len() + (i * targets.len() + j) * DIP_INDEX_STRIDE;
    let dips = find_dips(
        &targets[i],
        targets[j].object,
        volume,
        samples,
        found,
        settings,
        first,
    );
    let max_wrong = settings.max_wrong();
    let failing: Vec<_> = dips
        .iter()
        .filter(|d| d.confusion_probability > max_wrong)
        .collect();
    let cases: Vec<Case> = failing
        .iter()
        .map(|d| (d.scenario, d.missing, d.confusion_probability))
        .collect();
    let (trials, wrong_marker, expected_wrong) = case_trials(targets, i, &cases, settings);
    PairDips {
        marker: i,
        rival: j,
        near: dips
            .iter()
            .filter(|d| d.confusion_probability > NEAR_SHARE * max_wrong)
            .count(),
        failing: failing.len(),
        worst: dips.first().cloned(),
        trials,
        wrong_marker,
        expected_wrong,
    }
}

/// A viewpoint, the blob left out of every frame there (None: every blob
/// drawn) and the predicted confusion probability of that case.
type Case = (Scenario, Option<usize>, f64);

/// `settings.trials` trials of marker `i` at each case, identified against
/// the whole set: the trials run, those that named another marker, and
/// the expected count of those (the cases' probabilities summed over
/// their trials).
fn case_trials(
    targets: &[Target],
    i: usize,
    cases: &[Case],
    settings: &IdentifiabilitySettings,
) -> (usize, usize, f64) {
    let runs: Vec<(usize, usize, f64)> = cases
        .par_iter()
        .filter_map(|(scenario, missing, probability)| {
            let (trials, wrong) = missing_blob_trials(targets, i, scenario, *missing, settings)?;
            Some((trials, wrong, trials as f64 * probability))
        })
        .collect();
    (
        runs.iter().map(|r| r.0).sum(),
        runs.iter().map(|r| r.1).sum(),
        runs.iter().map(|r| r.2).sum(),
    )
}

/// The viewpoints near the floor of pair (`i` seen, `j` offered) in
/// `matrix` whose worst case leaves a blob out, and `settings.trials`
/// trials at each with that blob left out ([`PairNear`]).
fn near_trials(
    targets: &[Target],
    (i, j): (usize, usize),
    scenarios: &[Scenario],
    matrix: &CrossMatrix,
    settings: &IdentifiabilitySettings,
) -> PairNear {
    let near = matrix.pair(i, j).map_or(&[][..], |p| &p.near[..]);
    let cases: Vec<Case> = scenarios
        .iter()
        .filter(|s| near.contains(&s.index))
        .filter_map(|s| {
            let prediction = cross_scenario(&targets[i], targets[j].object, s, settings)?;
            let missing = prediction.missing?;
            Some((*s, Some(missing), prediction.confusion_probability))
        })
        .collect();
    let (trials, wrong_marker, expected_wrong) = case_trials(targets, i, &cases, settings);
    PairNear {
        marker: i,
        rival: j,
        near: near.len(),
        missing: cases.len(),
        trials,
        wrong_marker,
        expected_wrong,
    }
}

/// Index stride between the pairs' dips (so that every dip's trials draw
/// their own streams).
const DIP_INDEX_STRIDE: usize = 1 << 16;

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
        report.push_str(&self.near_markdown());
        report.push_str(&self.between_markdown());
        report
    }

    /// The table of the trials at the viewpoints near the floor whose
    /// worst case leaves a blob out.
    fn near_markdown(&self) -> String {
        let sig = |v: f64, digits: usize| crate::report::number::significant(Some(v), digits);
        let mut text = format!(
            "\n## A blob left out near the floor\n\nThe trials above draw every blob. At every viewpoint whose predicted confusion is above {} (near the floor) and whose worst case leaves a blob out, {} more seeded trials with that blob left out of every frame, identified against the whole set with one missing blob allowed.\n\n| seen | offered | near viewpoints | worst case with a blob left out | trials | named the offered marker or another | expected |\n|---|---|---|---|---|---|---|\n",
            sig(NEAR_SHARE * self.settings.max_wrong(), 2),
            self.settings.trials,
        );
        for p in &self.near {
            text.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} |\n",
                p.marker + 1,
                p.rival + 1,
                p.near,
                p.missing,
                p.trials,
                p.wrong_marker,
                sig(p.expected_wrong, 3)
            ));
        }
        text
    }

    /// The table of the dips between the viewpoints.
    fn between_markdown(&self) -> String {
        let sig = |v: f64, digits: usize| crate::report::number::significant(Some(v), digits);
        let mut text = format!(
            "\n## Between the viewpoints\n\nThe floors of the dips of every labelling that an affine camera nearly confuses or that the cross check found within its gate at a viewpoint (docs/formats.md, \"Between the viewpoints\"), searched over the volume from its viewpoints. Failing: predicted confusion above {}; near: above {}. At each failing dip, {} seeded trials with the dip's blob left out of every frame, identified against the whole set with one missing blob allowed.\n\n| seen | offered | near | failing | worst: confusion | margin, px | blob left out | depth, mm | tilt, pan, roll ° | X, Y mm | trials at failing dips | named the offered marker or another | expected |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
            sig(self.settings.max_wrong(), 2),
            sig(NEAR_SHARE * self.settings.max_wrong(), 2),
            self.settings.trials,
        );
        for p in &self.between {
            let worst =
                p.worst
                    .as_ref()
                    .map_or("— | — | — | — | — | —".to_string(), |w| {
                        let s = &w.scenario;
                        format!(
                            "{} | {} | {} | {:.0} | {:.1}, {:.1}, {:.1} | {:.1}, {:.1}",
                            sig(w.confusion_probability, 2),
                            sig(w.margin_px, 3),
                            w.missing
                                .map_or("none".to_string(), |k| format!("P{}", k + 1)),
                            s.depth_mm,
                            s.tilt_deg,
                            s.pan_deg,
                            s.roll_deg,
                            s.offset_x_mm,
                            s.offset_y_mm
                        )
                    });
            text.push_str(&format!(
                "| {} | {} | {} | {} | {worst} | {} | {} | {} |\n",
                p.marker + 1,
                p.rival + 1,
                p.near,
                p.failing,
                p.trials,
                p.wrong_marker,
                sig(p.expected_wrong, 3)
            ));
        }
        text
    }

    /// Dips between the viewpoints that fail the floor, over every pair.
    pub fn failing_between(&self) -> usize {
        self.between.iter().map(|p| p.failing).sum()
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
            "between": self.between,
            "near": self.near,
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
        let near_confused: usize = self.near.iter().map(|p| p.wrong_marker).sum();
        let near_trials: usize = self.near.iter().map(|p| p.trials).sum();
        let expected: f64 = self.near.iter().map(|p| p.expected_wrong).sum();
        format!(
            "set {}: {} markers over {} scenarios; smallest cross margin {}; cross floor met: {}; {confused} of {trials} trials named another marker, and {near_confused} of {near_trials} with a blob left out near the floor (expected {}); between the viewpoints {} dips fail the floor",
            self.set,
            self.markers.len(),
            self.scenarios,
            self.matrix
                .smallest_margin_px()
                .map_or("above the gate everywhere".to_string(), |m| format!("{m:.2} px")),
            if self.matrix.meets_floor() { "yes" } else { "no" },
            crate::report::number::significant(Some(expected), 3),
            self.failing_between(),
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
