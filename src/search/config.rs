//! The search's configuration: every input and every output path of one
//! search ([`SearchConfig`]), its command-line defaults, and the one check of
//! its values ([`SearchConfig::check`]), which names the bad field in a
//! [`ConfigError`] before any work starts.

use super::front::FrontSettings;
use super::optimise::{Optimiser, SearchSettings};
use super::{Aggregate, AvailabilityFloor, IdentifiabilityFloor, ObjectiveSettings};
use crate::camera::Camera;
use crate::config::ConfigError;
use crate::family::{Constraints, Envelope, FamilyKind};
use crate::mesh::Format;
use crate::noise::NoiseModel;
use crate::pnp::Solver;
use crate::scenario::{Range, ScenarioGrid};
use crate::validate;
use crate::volume::{Interval, Orientation, Placement, SampledVolume, WorkingVolume};
use std::path::{Path, PathBuf};

/// Default Monte-Carlo trials of the unlabelled solver per visible scenario
/// in the search winner's validation (`validate` runs more by default).
/// The search's identifiability floor is met on the prediction and its
/// repair rounds; these trials confirm it on the solver itself. At 20 per
/// scenario, the 512-viewpoint default volume gets some 6,500 trials, and
/// they are the largest share of the time after the search: at 50 a whole
/// default run took 32.5 s, over the 30 s it is allowed.
pub const WINNER_IDENTIFY_TRIALS: usize = 20;

/// The polish budget when none is given: two thirds of `iterations` (2000
/// with the default 3000), so that the polish shrinks with a quick search
/// instead of dominating it.
pub fn default_polish_iterations(iterations: u64) -> u64 {
    (u128::from(iterations) * 2 / 3) as u64
}

/// The default working volume, scrambled with `seed` (the search's seed):
/// [`crate::volume::DEFAULT_SAMPLES`] Sobol viewpoints over depths
/// 200…1000 mm, X offsets 0…100 mm and tilts −60°…60° (what
/// [`default_grid`] spans), plus Y offsets −50…50 mm, pans −20°…20° and
/// rolls −20°…20°, at σ 0.5 px. Fewer viewpoints than the grid's 325, so
/// the default search costs no more than it did on the grid.
pub fn default_volume(seed: u64) -> WorkingVolume {
    WorkingVolume::Sampled(SampledVolume {
        depth_mm: Interval::new(200.0, 1000.0),
        placement: Placement::Offsets {
            x_mm: Interval::new(0.0, 100.0),
            y_mm: Interval::new(-50.0, 50.0),
        },
        orientation: Orientation::Angles {
            tilt_deg: Interval::new(-60.0, 60.0),
            pan_deg: Interval::new(-20.0, 20.0),
            roll_deg: Interval::new(-20.0, 20.0),
        },
        sigma_px: Interval::point(0.5),
        samples: crate::volume::DEFAULT_SAMPLES,
        seed,
    })
}

/// The scenario grid of `--samples grid`: depths 200…1000 mm (5 values), X offsets
/// 0…100 mm, tilt −60°…60° in 10° steps, σ 0.5 px.
pub fn default_grid() -> ScenarioGrid {
    ScenarioGrid::new(
        "200..1000".parse().expect("valid"),
        "0..100".parse().expect("valid"),
        Range::single(0.0),
        "-60..60:10".parse().expect("valid"),
        Range::single(0.0),
        Range::single(0.0),
        Range::single(0.5),
    )
    .expect("the default grid is valid")
}

/// A held-out grid beside `grid`: every range of two or more values is
/// replaced by the midpoints of its neighbouring values, so no scenario is
/// shared with `grid` (`200..1000` in 5 → 300, 500, 700, 900).
pub fn held_out_grid(grid: &ScenarioGrid) -> ScenarioGrid {
    let shift = |range: &Range| {
        if range.values.len() < 2 {
            range.clone()
        } else {
            let mids: Vec<f64> = range
                .values
                .windows(2)
                .map(|w| 0.5 * (w[0] + w[1]))
                .collect();
            Range::list(&mids)
        }
    };
    ScenarioGrid::new(
        shift(&grid.depth_mm),
        shift(&grid.offset_x_mm),
        shift(&grid.offset_y_mm),
        shift(&grid.tilt_deg),
        shift(&grid.pan_deg),
        shift(&grid.roll_deg),
        grid.sigma_px.clone(),
    )
    .expect("midpoints of a valid grid form a valid grid")
}

/// The Pareto front of a search (`search --front`).
#[derive(Debug, Clone)]
pub struct FrontOutput {
    /// How the front is swept.
    pub settings: FrontSettings,
    /// Directory of the members' layout files (beside the winner's:
    /// `<dir of the layout>/<name>-front/`).
    pub layout_dir: PathBuf,
}

/// The winner's meshes, written with `export`'s defaults.
#[derive(Debug, Clone)]
pub struct MeshExport {
    /// Formats to write (at least one).
    pub formats: Vec<Format>,
    /// Directory of the meshes and fabrication sheet.
    pub dir: PathBuf,
}

/// Every input and every output path of a search.
#[derive(Debug, Clone)]
pub struct SearchConfig {
    /// Name of the result (the winning layout's name).
    pub name: String,
    /// The layout family and its options.
    pub family: FamilyKind,
    /// Envelope, sphere diameter, gaps and identifiability.
    pub constraints: Constraints,
    /// The simulated camera.
    pub camera: Camera,
    /// The working volume the objective is computed over.
    pub volume: WorkingVolume,
    /// The objective (its seed is the seed of its common random numbers).
    pub objective: ObjectiveSettings,
    /// Optimiser and budget. `search.seed` is also the run's seed: the
    /// comparison uses it and `seed + 1`, the winner's validation `seed + 1`.
    pub search: SearchSettings,
    /// Solver of the Monte-Carlo comparison with the hand designs.
    pub compare_solver: Solver,
    /// Trials per scenario of the comparison and of the winner's validation.
    pub compare_trials: usize,
    /// Solvers of the winner's sensitivity report (at least one).
    pub validate_solvers: Vec<Solver>,
    /// Continue from this configuration's checkpoints, if any.
    pub resume: bool,
    /// The command that asked for the run, recorded in the layout's
    /// provenance and the report headers.
    pub command: String,
    /// Where the winning layout is written when the run finishes (the best
    /// so far goes to [`partial_path`] of it while the run lasts).
    pub layout_path: PathBuf,
    /// The report directory (with `winner-validation/` inside).
    pub report_dir: PathBuf,
    /// Where checkpoints are kept (one subdirectory per name and
    /// configuration hash; removed when the search finishes). The command
    /// line's default is [`checkpoint_dir_beside`] the layout, so that runs
    /// with different outputs never share checkpoints.
    pub checkpoint_dir: PathBuf,
    /// Meshes of the winner, if wanted.
    pub export: Option<MeshExport>,
    /// The Pareto front of accuracy against availability, if wanted.
    pub front: Option<FrontOutput>,
    /// The identifiability floor (None: no floor; monocular trackers need
    /// one, stereo trackers use `constraints.min_distance_diff_mm`).
    pub min_identifiability: Option<IdentifiabilityFloor>,
    /// Monte-Carlo trials of the unlabelled solver per visible scenario in
    /// the winner's validation (0: the prediction alone).
    pub identify_trials: usize,
    /// Count every candidate's own supports as occluders in the optimiser's
    /// loop, with this largest hidden fraction
    /// ([`crate::search::Evaluator::with_candidate_supports`]); `None`
    /// (the default): the spheres alone. It multiplies an evaluation's
    /// cost many times over (see docs/commands.md).
    pub count_supports: Option<crate::visibility::MaxHidden>,
    /// Check the winner as printed, its routed supports counted (a sphere
    /// hidden more than this fraction counts as not seen), and repair it
    /// to the availability floor as printed (`crate::search` supports
    /// phase); `None`: the spheres alone.
    pub supports: Option<crate::visibility::MaxHidden>,
}

impl SearchConfig {
    /// The command line's defaults for a biprism search named `name` on
    /// [`default_volume`] with seed 7, writing `<dir>/<name>.json`, the report
    /// in `<dir>/<name>-report/` and checkpoints in `<dir>/.<name>.checkpoints/`.
    pub fn new(name: &str, dir: &Path) -> Self {
        let seed = 7;
        let layout_path = dir.join(format!("{name}.json"));
        SearchConfig {
            name: name.to_string(),
            family: FamilyKind::Biprism {
                centre: true,
                tilts: true,
                free_hub: true,
            },
            constraints: Constraints {
                envelope: Envelope::new([100.0; 3]).expect("a valid envelope"),
                sphere_diameter_mm: 10.0,
                min_gap_mm: 2.0,
                min_distance_diff_mm: 0.0,
            },
            camera: Camera::paper(),
            volume: default_volume(seed),
            objective: ObjectiveSettings {
                objective: "crlb".parse().expect("a valid objective"),
                aggregate: Aggregate::Mean,
                translation_weight: 0.5,
                availability_weight: 0.0,
                min_availability: AvailabilityFloor::Reference,
                trials: 20,
                seed,
                noise: NoiseModel::default(),
                observation: crate::sphere_image::Observation::default(),
                chain: Default::default(),
            },
            search: SearchSettings {
                optimiser: Optimiser::NelderMead,
                starts: 8,
                start_jitter: 0.02,
                iterations: 3000,
                particles: 32,
                polish_iterations: 2000,
                seed,
            },
            compare_solver: Solver::ParallelWeighted,
            compare_trials: 200,
            validate_solvers: vec![
                Solver::ParallelWeighted,
                Solver::ParallelGn,
                Solver::EpnpGn,
                Solver::Sqpnp,
                Solver::Lhm,
                Solver::Ml,
            ],
            resume: false,
            command: "layout-opt (library)".to_string(),
            report_dir: report_dir_beside(&layout_path),
            checkpoint_dir: checkpoint_dir_beside(&layout_path),
            layout_path,
            export: None,
            front: None,
            min_identifiability: Some(IdentifiabilityFloor::DEFAULT),
            identify_trials: WINNER_IDENTIFY_TRIALS,
            count_supports: None,
            supports: Some(crate::visibility::MaxHidden::default()),
        }
    }

    /// How the winner's validation checks identifiability.
    pub fn identifiability_check(&self) -> validate::IdentifiabilityCheck {
        validate::IdentifiabilityCheck {
            min_correct: self
                .min_identifiability
                .map_or(crate::identifiability::DEFAULT_MIN_CORRECT, |f| {
                    f.min_correct
                }),
            trials: self.identify_trials,
        }
    }

    /// Checks every value the optimiser and the family do not check
    /// themselves, once, before anything is built or written: the first bad
    /// one is named by its field.
    pub fn check(&self) -> Result<(), ConfigError> {
        self.volume.check()?;
        if let Some(&sigma) = self.volume.sigma_values_px().iter().find(|&&s| s <= 0.0) {
            return Err(ConfigError::new(
                "sigma_px",
                format!("must be > 0 px, got {sigma}: search needs σ > 0 px; without noise every layout's error is zero, so the objective cannot tell layouts apart (and its ratio to the paper's biprism is 0/0)"),
            ));
        }
        let s = &self.objective;
        for (field, weight) in [
            ("translation_weight", s.translation_weight),
            ("availability_weight", s.availability_weight),
        ] {
            if !weight.is_finite() {
                return Err(ConfigError::new(field, format!("must be finite, got {weight}: an infinite or undefined weight makes every layout's objective infinite or undefined, so none can be ranked")));
            }
            if weight < 0.0 {
                return Err(ConfigError::new(field, format!("must be non-negative, got {weight}: a negative weight would reward the error it should price")));
            }
        }
        let c = &self.constraints;
        ConfigError::positive("sphere_diameter_mm", c.sphere_diameter_mm)?;
        ConfigError::non_negative("min_gap_mm", c.min_gap_mm)?;
        ConfigError::non_negative("min_distance_diff_mm", c.min_distance_diff_mm)?;
        at_least_one("trials", s.trials)?;
        at_least_one("compare_trials", self.compare_trials)?;
        if let AvailabilityFloor::Share(share) = s.min_availability {
            ConfigError::within("min_availability", share, 0.0, 1.0)?;
        }
        if let Some(floor) = self.min_identifiability {
            ConfigError::within("min_identifiability", floor.min_share, 0.0, 1.0)?;
            if !(floor.min_correct > 0.0 && floor.min_correct < 1.0) {
                return Err(ConfigError::new(
                    "identify_criterion",
                    format!(
                        "must be a probability strictly between 0 and 1, got {}",
                        floor.min_correct
                    ),
                ));
            }
        }
        if self.validate_solvers.is_empty() {
            return Err(ConfigError::new(
                "validate_solvers",
                "names no solver: the winner's validation needs at least one",
            ));
        }
        if self.export.as_ref().is_some_and(|e| e.formats.is_empty()) {
            return Err(ConfigError::new(
                "export",
                "names no format: a mesh export needs at least one",
            ));
        }
        if let Some(front) = &self.front {
            at_least_one("front_levels", front.settings.levels)?;
        }
        let reference =
            super::compare::hand_designs(&c.envelope, c.sphere_diameter_mm).swap_remove(0);
        self.volume.check_seen(
            &self.camera,
            &reference.positions(),
            c.sphere_diameter_mm,
            "the paper's biprism scaled to the envelope",
        )?;
        Ok(())
    }
}

/// Checks that a count is at least 1.
fn at_least_one(field: &'static str, count: usize) -> Result<(), ConfigError> {
    if count == 0 {
        return Err(ConfigError::new(field, "must be at least 1"));
    }
    Ok(())
}

/// Where the report goes when only the layout file is chosen: beside it, as
/// `<dir>/<stem>-report/` (`out/marker.json` → `out/marker-report/`).
pub fn report_dir_beside(layout_path: &Path) -> PathBuf {
    let stem = layout_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "layout".into());
    layout_path.with_file_name(format!("{stem}-report"))
}

/// Where the best layout so far goes while a search for `layout_path` runs,
/// and where an interrupted run leaves it: `<stem>.partial.json` beside it
/// (`out/marker.json` → `out/marker.partial.json`).
pub fn partial_path(layout_path: &Path) -> PathBuf {
    let stem = layout_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "layout".into());
    layout_path.with_file_name(format!("{stem}.partial.json"))
}

/// The default checkpoint directory of a search writing `layout_path`:
/// hidden beside it, `<dir>/.<stem>.checkpoints/`, so that it follows
/// `--out` and two searches with different outputs never share it.
pub fn checkpoint_dir_beside(layout_path: &Path) -> PathBuf {
    let stem = layout_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "layout".into());
    layout_path.with_file_name(format!(".{stem}.checkpoints"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_report_goes_beside_the_layout() {
        assert_eq!(
            report_dir_beside(Path::new("out/marker.json")),
            Path::new("out/marker-report")
        );
    }

    #[test]
    fn each_bad_value_is_named_by_its_field() {
        let dir = Path::new("unused");
        let base = SearchConfig::new("t", dir);
        assert_eq!(base.check(), Ok(()));
        type Spoil = fn(&mut SearchConfig);
        let cases: [(&str, Spoil); 8] = [
            ("sphere_diameter_mm", |c| {
                c.constraints.sphere_diameter_mm = -1.0
            }),
            ("min_gap_mm", |c| c.constraints.min_gap_mm = f64::NAN),
            ("min_distance_diff_mm", |c| {
                c.constraints.min_distance_diff_mm = -0.5
            }),
            ("translation_weight", |c| {
                c.objective.translation_weight = -2.0
            }),
            ("availability_weight", |c| {
                c.objective.availability_weight = f64::INFINITY
            }),
            ("trials", |c| c.objective.trials = 0),
            ("compare_trials", |c| c.compare_trials = 0),
            ("sigma_px", |c| {
                c.volume = WorkingVolume::Grid(ScenarioGrid {
                    sigma_px: Range::single(0.0),
                    ..default_grid()
                })
            }),
        ];
        for (field, spoil) in cases {
            let mut config = base.clone();
            spoil(&mut config);
            let error = config.check().unwrap_err();
            assert_eq!(error.field, field, "{error}");
        }
        let mut config = base.clone();
        config.objective.translation_weight = -2.0;
        assert_eq!(
            config.check().unwrap_err().to_string(),
            "translation_weight: must be non-negative, got -2: a negative weight would reward the error it should price"
        );
    }

    #[test]
    fn the_polish_follows_the_iterations() {
        assert_eq!(default_polish_iterations(3000), 2000);
        assert_eq!(default_polish_iterations(60), 40);
        assert_eq!(default_polish_iterations(0), 0);
    }
}
