//! The whole search as one call: checkpoints, optimisation, comparison with
//! the hand designs, validation of the winner, the report and an optional
//! mesh export. [`run`] takes a [`SearchConfig`] that names every input and
//! every output path, and reports progress through an [`Observer`]; it never
//! prints.
//!
//! ```no_run
//! use layout_opt::observer::Silent;
//! use layout_opt::search::pipeline::{self, SearchConfig};
//!
//! let dir = std::env::temp_dir().join("layout-opt-doc");
//! let mut config = SearchConfig::new("my-marker", &dir);
//! config.search.starts = 2;
//! config.search.iterations = 100;
//! let outcome = pipeline::run(&config, &mut Silent)?;
//! println!("objective {:.4}", outcome.objective);
//! # Ok::<(), pipeline::SearchError>(())
//! ```

use super::checkpoint::{CheckpointError, Checkpoints, ResumeStatus};
use super::compare::{compare, hand_designs};
use super::optimise::{self, Candidate, Optimiser, SearchObserver, SearchSettings};
use super::report::{self as search_report, verdicts, SearchHeader, SearchSummary};
use super::{Aggregate, Evaluator, ObjectiveSettings};
use crate::camera::Camera;
use crate::family::{Constraints, Envelope, Family, FamilyError, FamilyKind};
use crate::layout::{Layout, LayoutError};
use crate::mesh::{ExportError, ExportOptions, Format};
use crate::montecarlo::{MonteCarloConfig, MonteCarloError, DEFAULT_GROSS_THRESHOLD_DEG};
use crate::noise::NoiseModel;
use crate::observer::{watch, Observer};
use crate::pnp::Solver;
use crate::report::{write_text, ReportError};
use crate::scenario::{Range, ScenarioGrid};
use crate::sensitivity::{self, SensitivityError};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Progress phase of the optimisation (interruptible).
pub const PHASE_SEARCH: &str = "searching";
/// Progress phase of the comparison with the hand designs.
pub const PHASE_COMPARE: &str = "comparing designs";
/// Progress phase of the winner's sensitivity report.
pub const PHASE_VALIDATE: &str = "validating the winner";

/// The default scenario grid: depths 200…1000 mm (5 values), X offsets
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
    /// The scenarios the objective is computed over.
    pub grid: ScenarioGrid,
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
    /// Where the winning (and best-so-far) layout is written.
    pub layout_path: PathBuf,
    /// The report directory (with `winner-validation/` inside).
    pub report_dir: PathBuf,
    /// Where checkpoints are kept (one subdirectory per name and
    /// configuration hash; removed when the search finishes).
    pub checkpoint_dir: PathBuf,
    /// Meshes of the winner, if wanted.
    pub export: Option<MeshExport>,
}

impl SearchConfig {
    /// The command line's defaults for a biprism search named `name` on
    /// [`default_grid`] with seed 7, writing `<dir>/<name>.json`, the report
    /// in `<dir>/<name>-report/` and checkpoints under `<dir>/checkpoints/`.
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
                min_distance_diff_mm: 1.0,
            },
            camera: Camera::paper(),
            grid: default_grid(),
            objective: ObjectiveSettings {
                objective: "crlb".parse().expect("a valid objective"),
                aggregate: Aggregate::Mean,
                translation_weight: 0.5,
                availability_weight: 1.0,
                trials: 20,
                seed,
                noise: NoiseModel::default(),
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
            layout_path,
            checkpoint_dir: dir.join("checkpoints"),
            export: None,
        }
    }

    /// Checks what the optimiser and the family do not check themselves.
    fn check(&self) -> Result<(), SearchError> {
        let c = &self.constraints;
        let s = &self.objective;
        let problem = if !(c.sphere_diameter_mm > 0.0 && c.sphere_diameter_mm.is_finite()) {
            "the sphere diameter must be positive"
        } else if !(c.min_gap_mm >= 0.0 && c.min_distance_diff_mm >= 0.0) {
            "the smallest gap and distance difference must be non-negative"
        } else if !(s.translation_weight >= 0.0 && s.availability_weight >= 0.0) {
            "objective weights must be non-negative"
        } else if s.trials == 0 || self.compare_trials == 0 {
            "Monte-Carlo trials and comparison trials must be at least 1"
        } else if self.validate_solvers.is_empty() {
            "the winner's validation needs at least one solver"
        } else if self.export.as_ref().is_some_and(|e| e.formats.is_empty()) {
            "a mesh export needs at least one format"
        } else {
            return Ok(());
        };
        Err(SearchError::Config(problem.to_string()))
    }
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

/// What a search produced.
#[derive(Debug, Clone)]
pub struct SearchOutcome {
    /// The winning layout (the best seen, when interrupted), as written to
    /// [`SearchConfig::layout_path`].
    pub winner: Layout,
    /// The winner's objective-plus-penalty cost.
    pub objective: f64,
    /// The family and its free parameters, in words.
    pub family: String,
    /// Objective evaluations.
    pub evaluations: usize,
    /// Whether the observer stopped the search; then nothing after the
    /// optimisation ran and the checkpoints are kept in [`Self::checkpoints`].
    pub interrupted: bool,
    /// This configuration's checkpoint directory (removed unless interrupted).
    pub checkpoints: PathBuf,
    /// The comparison and verdicts written to the report (`None` when
    /// interrupted).
    pub summary: Option<SearchSummary>,
    /// Files of the mesh export.
    pub exported: Vec<PathBuf>,
    /// Seconds spent optimising.
    pub search_seconds: f64,
    /// Seconds of the whole run.
    pub total_seconds: f64,
}

/// Why a search failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SearchError {
    /// A setting is out of range.
    #[error("invalid search configuration: {0}")]
    Config(String),
    /// The family cannot be built.
    #[error(transparent)]
    Family(#[from] FamilyError),
    /// Checkpoints could not be prepared or removed.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    /// The optimisation failed.
    #[error(transparent)]
    Optimise(#[from] optimise::SearchError),
    /// A directory could not be created.
    #[error("creating {}: {source}", path.display())]
    CreateDir {
        /// The directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The best-so-far layout could not be written during the search.
    #[error("could not write the best-so-far layout: {0}")]
    BestSoFar(String),
    /// The winning layout could not be written.
    #[error(transparent)]
    Layout(#[from] LayoutError),
    /// The best layout found breaks a constraint.
    #[error("the constraints cannot all be met (best layout, kept in {}): {}", layout.display(), violations.join("; "))]
    Infeasible {
        /// Where the best layout was written.
        layout: PathBuf,
        /// Each broken constraint, in words.
        violations: Vec<String>,
    },
    /// The Monte-Carlo comparison failed.
    #[error(transparent)]
    MonteCarlo(#[from] MonteCarloError),
    /// The winner's validation failed.
    #[error(transparent)]
    Sensitivity(#[from] SensitivityError),
    /// A report file could not be written.
    #[error(transparent)]
    Report(#[from] ReportError),
    /// The mesh export failed.
    #[error("exporting the winner to {}: {source}", dir.display())]
    Export {
        /// The export directory.
        dir: PathBuf,
        /// Why.
        source: ExportError,
    },
}

/// The family and its free parameters, in words.
pub fn family_description(family: &Family) -> String {
    match family.kind() {
        FamilyKind::Biprism {
            centre,
            tilts,
            free_hub,
        } => format!(
            "biprism: 6 arm lengths{}{}{}",
            if *tilts { " + 2 tilts per arm" } else { "" },
            if *free_hub {
                " + hub position"
            } else {
                ", hub at the envelope centre"
            },
            if *centre {
                " + centre point"
            } else {
                ", no centre point"
            }
        ),
        FamilyKind::Tetrahedron { centre } => format!(
            "tetrahedron: 4 free vertices{}",
            if *centre { " + centre point" } else { "" }
        ),
        FamilyKind::Custom {
            start: Some(layout),
            ..
        } => format!(
            "custom: {} points from {}, {} fixed",
            layout.points.len(),
            layout.name,
            layout.points.iter().filter(|p| p.fixed).count()
        ),
        FamilyKind::Custom { count, .. } => format!("custom: {count} free points"),
    }
}

/// Writes the best-so-far layout at every improvement and counts iterations.
struct Tracker {
    family: Family,
    name: String,
    path: PathBuf,
    provenance: serde_json::Value,
    write_error: Mutex<Option<String>>,
    iterations: Mutex<Vec<u64>>,
}

impl Tracker {
    fn done(&self) -> u64 {
        self.iterations
            .lock()
            .expect("no panics while holding the lock")
            .iter()
            .sum()
    }
}

impl SearchObserver for Tracker {
    fn improved(&self, candidate: &Candidate) {
        let mut layout = self.family.layout(&self.name, &candidate.params);
        let mut provenance = self.provenance.clone();
        provenance["status"] = "best so far (search running or interrupted)".into();
        provenance["score"] = candidate.evaluation.cost.into();
        layout.provenance = Some(provenance);
        if let Err(e) = layout.save_atomic(&self.path) {
            *self
                .write_error
                .lock()
                .expect("no panics while holding the lock") = Some(e.to_string());
        }
    }

    fn progress(&self, start: usize, iteration: u64, _evaluations: usize, _best_cost: f64) {
        let mut iterations = self
            .iterations
            .lock()
            .expect("no panics while holding the lock");
        if let Some(slot) = iterations.get_mut(start) {
            *slot = (*slot).max(iteration);
        }
    }
}

fn create_dir(path: &Path) -> Result<(), SearchError> {
    std::fs::create_dir_all(path).map_err(|source| SearchError::CreateDir {
        path: path.to_path_buf(),
        source,
    })
}

/// Runs the whole search: optimises [`SearchConfig::family`] (resuming from
/// checkpoints when asked), writes the winner to
/// [`SearchConfig::layout_path`], compares it with its start and the hand
/// designs on the same scenarios and draws, validates it, writes the report
/// into [`SearchConfig::report_dir`] and exports its meshes when asked.
///
/// `observer` hears each phase's progress and the checkpoint decision, and
/// may stop the optimisation ([`Observer::interrupted`]); an interrupted run
/// keeps the best layout seen and its checkpoints and returns at once.
pub fn run(
    config: &SearchConfig,
    observer: &mut impl Observer,
) -> Result<SearchOutcome, SearchError> {
    config.check()?;
    let constraints = config.constraints;
    let family = Family::new(
        config.family.clone(),
        constraints.envelope,
        constraints.sphere_diameter_mm,
    )?;
    let description = family_description(&family);
    let name = &config.name;
    let seed = config.search.seed;
    if let Some(parent) = config
        .layout_path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
    {
        create_dir(parent)?;
    }

    let hand = hand_designs(&constraints.envelope, constraints.sphere_diameter_mm);
    let paper = &hand[0];
    let evaluator = Evaluator::new(
        config.camera,
        config.grid.scenarios(),
        config.objective.clone(),
        constraints,
        &paper.positions(),
    );
    // Everything that decides which layouts the search evaluates: the key of
    // its checkpoints.
    let search_config = serde_json::json!({
        "version": env!("CARGO_PKG_VERSION"),
        "family": description,
        "start_layout": match family.kind() {
            FamilyKind::Custom { start: Some(layout), .. } => serde_json::to_value(layout)
                .expect("a layout serialises"),
            _ => serde_json::Value::Null,
        },
        "sphere_diameter_mm": constraints.sphere_diameter_mm,
        "constraints": constraints,
        "camera": config.camera,
        "grid": config.grid,
        "objective": config.objective,
        "search": config.search,
    });
    let (checkpoints, resume_status) =
        Checkpoints::prepare(&config.checkpoint_dir, name, &search_config, config.resume)?;
    match resume_status {
        ResumeStatus::Resuming => observer.log(&format!(
            "resuming from the checkpoints in {}",
            checkpoints.dir().display()
        )),
        ResumeStatus::NothingToResume => observer.log(&format!(
            "no checkpoint of this configuration (hash {}); starting afresh",
            checkpoints.hash()
        )),
        ResumeStatus::Fresh => {}
    }
    let provenance = serde_json::json!({
        "command": config.command,
        "seed": seed,
        "objective": config.objective.objective.to_string(),
        "aggregate": format!("{:?}", config.objective.aggregate).to_lowercase(),
        "version": env!("CARGO_PKG_VERSION"),
    });

    let settings = &config.search;
    let total_iterations = settings.starts as u64
        * (settings.iterations
            + if settings.optimiser == Optimiser::NelderMead {
                0
            } else {
                settings.polish_iterations
            });
    let tracker = Arc::new(Tracker {
        family: family.clone(),
        name: name.clone(),
        path: config.layout_path.clone(),
        provenance: provenance.clone(),
        write_error: Mutex::new(None),
        iterations: Mutex::new(vec![0; settings.starts]),
    });
    let stop = AtomicBool::new(false);
    let started = Instant::now();
    let outcome = watch(
        observer,
        PHASE_SEARCH,
        total_iterations,
        || tracker.done(),
        Some(&stop),
        || {
            optimise::run(
                &family,
                &evaluator,
                settings,
                &stop,
                tracker.clone(),
                Some(&checkpoints),
            )
        },
    )?;
    let search_seconds = started.elapsed().as_secs_f64();
    if let Some(error) = tracker
        .write_error
        .lock()
        .expect("no panics while holding the lock")
        .take()
    {
        return Err(SearchError::BestSoFar(error));
    }

    let mut winner = family.layout(name, &outcome.best.params);
    let mut final_provenance = provenance;
    final_provenance["score"] = outcome.best.evaluation.cost.into();
    final_provenance["status"] = if outcome.interrupted {
        "interrupted: best layout seen".into()
    } else {
        "finished".into()
    };
    final_provenance["evaluations"] = outcome.evaluations.into();
    winner.provenance = Some(final_provenance);
    winner.save_atomic(&config.layout_path)?;
    let mut result = SearchOutcome {
        winner: winner.clone(),
        objective: outcome.best.evaluation.cost,
        family: description.clone(),
        evaluations: outcome.evaluations,
        interrupted: outcome.interrupted,
        checkpoints: checkpoints.dir().to_path_buf(),
        summary: None,
        exported: Vec::new(),
        search_seconds,
        total_seconds: search_seconds,
    };
    if outcome.interrupted {
        return Ok(result);
    }
    checkpoints.remove()?;
    let violations = outcome.best.evaluation.violations;
    if !violations.feasible() {
        return Err(SearchError::Infeasible {
            layout: config.layout_path.clone(),
            violations: violations.describe(&constraints),
        });
    }

    // Compare on the same scenarios and draws, on the search seed and an
    // independent validation seed.
    let validation_seed = seed.wrapping_add(1);
    let start_layout = family.layout(&format!("{name}-start"), &family.initial());
    let mut designs = vec![
        (name.clone(), winner.clone()),
        ("start".to_string(), start_layout),
    ];
    let paper_index = designs.len();
    designs.extend(hand.iter().map(|l| (l.name.clone(), l.clone())));
    let hand_range = paper_index..designs.len();
    observer.progress(PHASE_COMPARE, 0, 1);
    // Hand designs that break a constraint (the paper's biprism and the cube
    // corners repeat pairwise distances) also appear made admissible, by the
    // search's own repair, so the winner meets them like for like.
    for layout in &hand {
        if constraints.violations(&layout.positions()).feasible() {
            continue;
        }
        let free = Family::new(
            FamilyKind::Custom {
                count: layout.points.len(),
                start: Some(layout.clone()),
            },
            constraints.envelope,
            constraints.sphere_diameter_mm,
        )?;
        let params = optimise::repair(&free, &evaluator, &free.initial())?;
        let mut admissible = free.layout(&format!("{}-admissible", layout.name), &params);
        admissible.provenance = Some(serde_json::json!({
            "source": format!("{} moved to the nearest layout that meets the constraints (the search's repair)", layout.name),
        }));
        designs.push((admissible.name.clone(), admissible));
    }
    let admissible_range = hand_range.end..designs.len();
    let seeds = [seed, validation_seed];
    let rows = compare(
        &config.camera,
        &evaluator,
        &designs,
        config.compare_solver,
        config.compare_trials,
        &seeds,
        config.objective.noise,
    )?;
    observer.progress(PHASE_COMPARE, 1, 1);
    let summary = SearchSummary {
        header: SearchHeader {
            command: config.command.clone(),
            version: env!("CARGO_PKG_VERSION").to_string(),
            family: description,
            constraints,
            objective: config.objective.clone(),
            search: config.search.clone(),
            grid: config.grid.clone(),
            camera: config.camera,
            comparison_solver: config.compare_solver.name().to_string(),
            comparison_trials: config.compare_trials,
            comparison_seeds: seeds.to_vec(),
        },
        verdicts: verdicts(&rows, paper_index, hand_range, admissible_range),
        outcome,
        designs: rows,
    };
    search_report::write(&config.report_dir, &summary)?;

    let validation_config = MonteCarloConfig {
        trials: config.compare_trials,
        seed: validation_seed,
        solvers: config.validate_solvers.clone(),
        noise: config.objective.noise,
        gross_threshold_deg: DEFAULT_GROSS_THRESHOLD_DEG,
    };
    let scenarios_done = AtomicU64::new(0);
    let validation = watch(
        observer,
        PHASE_VALIDATE,
        config.grid.scenarios().len() as u64,
        || scenarios_done.load(Ordering::Relaxed),
        None,
        || {
            sensitivity::run(
                &winner,
                &config.camera,
                &config.grid,
                &validation_config,
                &config.command,
                &|_| {
                    scenarios_done.fetch_add(1, Ordering::Relaxed);
                },
            )
        },
    )?;
    sensitivity::write_report(
        &config.report_dir.join("winner-validation"),
        &winner,
        &validation,
    )?;
    let total_seconds = started.elapsed().as_secs_f64();
    let run_path = config.report_dir.join("run.json");
    let run_json = serde_json::to_string_pretty(&serde_json::json!({
        "search_seconds": search_seconds,
        "total_seconds": total_seconds,
        "evaluations": summary.outcome.evaluations,
        "threads": rayon::current_num_threads(),
    }))
    .map_err(|e| ReportError::write(&run_path, e))?;
    write_text(&run_path, &(run_json + "\n"))?;

    if let Some(export) = &config.export {
        let options = ExportOptions {
            formats: export.formats.clone(),
            ..Default::default()
        };
        let report = crate::mesh::export(&winner, &options, &export.dir).map_err(|source| {
            SearchError::Export {
                dir: export.dir.clone(),
                source,
            }
        })?;
        result.exported = report.files.into_iter().map(|f| f.path).collect();
    }
    result.summary = Some(summary);
    result.total_seconds = total_seconds;
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::observer::{Collect, Silent};

    fn small(dir: &Path) -> SearchConfig {
        let mut config = SearchConfig::new("t", dir);
        config.grid = ScenarioGrid::new(
            "300,800".parse().unwrap(),
            "0,60".parse().unwrap(),
            Range::single(0.0),
            "-40..40:20".parse().unwrap(),
            Range::single(0.0),
            Range::single(0.0),
            Range::single(0.5),
        )
        .unwrap();
        config.search.starts = 2;
        config.search.iterations = 100;
        config.compare_trials = 10;
        config.validate_solvers = vec![Solver::ParallelWeighted];
        config
    }

    #[test]
    fn a_search_writes_every_output_where_the_config_says() {
        let dir = tempfile::tempdir().unwrap();
        let mut config = small(dir.path());
        config.report_dir = dir.path().join("elsewhere/report");
        let mut observer = Collect::default();
        let outcome = run(&config, &mut observer).unwrap();
        assert!(!outcome.interrupted);
        assert!(observer.lines.is_empty(), "{:?}", observer.lines);
        assert_eq!(Layout::load(&config.layout_path).unwrap(), outcome.winner);
        assert!(config.report_dir.join("report.md").exists());
        assert!(config
            .report_dir
            .join("winner-validation/report.md")
            .exists());
        assert!(!outcome.checkpoints.exists());
        assert!(!dir.path().join("t-report").exists());
        let summary = outcome.summary.unwrap();
        assert_eq!(summary.designs[0].name, "t");
    }

    /// Interrupts as soon as the search has made progress.
    #[derive(Default)]
    struct StopEarly {
        progressed: bool,
    }

    impl Observer for StopEarly {
        fn progress(&mut self, phase: &str, done: u64, _total: u64) {
            assert_eq!(phase, PHASE_SEARCH, "no phase runs after a stop");
            self.progressed |= done > 0;
        }
        fn interrupted(&self) -> bool {
            self.progressed
        }
    }

    #[test]
    fn an_interrupted_search_keeps_its_best_layout_and_checkpoints() {
        let dir = tempfile::tempdir().unwrap();
        let mut config = small(dir.path());
        config.search.iterations = 100_000;
        let outcome = run(&config, &mut StopEarly::default()).unwrap();
        assert!(outcome.interrupted && outcome.summary.is_none());
        assert!(outcome.checkpoints.exists());
        assert!(config.layout_path.exists());
        assert!(!config.report_dir.exists());
    }

    #[test]
    fn bad_settings_are_typed_errors() {
        let dir = tempfile::tempdir().unwrap();
        let mut config = small(dir.path());
        config.compare_trials = 0;
        assert!(matches!(
            run(&config, &mut Silent),
            Err(SearchError::Config(_))
        ));
        config.compare_trials = 10;
        config.search.iterations = 0;
        assert!(matches!(
            run(&config, &mut Silent),
            Err(SearchError::Optimise(_))
        ));
    }

    #[test]
    fn the_report_goes_beside_the_layout() {
        assert_eq!(
            report_dir_beside(Path::new("out/marker.json")),
            Path::new("out/marker-report")
        );
    }
}
