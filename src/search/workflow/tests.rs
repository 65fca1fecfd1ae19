//! The workflow's promises: every output where the config says, nothing
//! clobbered by an interrupted run in any phase, resumed runs that keep the
//! books, outputs checked and locked before any work, refusals before any
//! work; and the analysis alone writes nothing.

use super::*;
use crate::family::FamilyKind;
use crate::observer::{Collect, Silent};
use crate::pnp::Solver;
use crate::scenario::{Range, ScenarioGrid};
use crate::search::analysis::{
    self, PHASE_COMPARE, PHASE_FRONT, PHASE_IDENTIFY, PHASE_SEARCH, PHASE_SUPPORTS, PHASE_VALIDATE,
    STATUS_FINISHED,
};
use crate::search::config::FrontOutput;
use crate::search::identify::IDENTIFY_ROUNDS;
use crate::search::{FrontSettings, IdentifiabilityFloor};

fn small(dir: &Path) -> SearchConfig {
    let mut config = SearchConfig::new("t", dir);
    config.volume = crate::volume::WorkingVolume::Grid(
        ScenarioGrid::new(
            "300,800".parse().unwrap(),
            "0,60".parse().unwrap(),
            Range::single(0.0),
            "-40..40:20".parse().unwrap(),
            Range::single(0.0),
            Range::single(0.0),
            Range::single(0.5),
        )
        .unwrap(),
    );
    config.search.starts = 2;
    config.search.iterations = 100;
    config.compare_trials = 10;
    config.validate_solvers = vec![Solver::ParallelWeighted];
    // The winner's identifiability Monte-Carlo runs, at the fewest trials:
    // no test here asserts on its rate. The identifiability floor, which
    // costs a prediction per evaluation, only where a test needs it.
    config.identify_trials = 2;
    config.min_identifiability = None;
    config
}

/// [`small`] with the default identifiability floor.
fn small_with_floor(dir: &Path) -> SearchConfig {
    SearchConfig {
        min_identifiability: Some(IdentifiabilityFloor::DEFAULT),
        ..small(dir)
    }
}

#[test]
fn a_search_writes_every_output_where_the_config_says() {
    let dir = tempfile::tempdir().unwrap();
    let mut config = small(dir.path());
    config.report_dir = dir.path().join("elsewhere/report");
    let mut observer = Collect::default();
    let outcome = run(&config, &mut observer).unwrap();
    assert!(!outcome.interrupted);
    assert_eq!(observer.lines.len(), 2, "{:?}", observer.lines);
    assert!(observer.lines[0].starts_with("search finished"));
    assert!(
        !outcome.partial.exists(),
        "a finished run leaves no partial file"
    );
    assert!(
        !config.checkpoint_dir.exists(),
        "nor its checkpoint directory"
    );
    let provenance = outcome.winner.provenance.as_ref().unwrap();
    assert_eq!(provenance["status"], STATUS_FINISHED);
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

/// Interrupts as soon as `phase` has made progress or, with
/// `at_start`, as soon as it begins (a phase shorter than the
/// observer's polling interval could otherwise end before a stop lands).
struct StopIn {
    phase: &'static str,
    at_start: bool,
    progressed: bool,
    phases: Vec<String>,
}

impl StopIn {
    fn new(phase: &'static str) -> Self {
        Self {
            phase,
            at_start: false,
            progressed: false,
            phases: Vec::new(),
        }
    }

    fn at_start(phase: &'static str) -> Self {
        Self {
            at_start: true,
            ..Self::new(phase)
        }
    }
}

impl Observer for StopIn {
    fn progress(&mut self, phase: &str, done: u64, _total: u64) {
        assert!(
            !self.progressed || phase == self.phase,
            "no phase runs after a stop"
        );
        if self.phases.last().is_none_or(|p| p != phase) {
            self.phases.push(phase.to_string());
        }
        self.progressed |= phase == self.phase && (self.at_start || done > 0);
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
    let mut observer = StopIn::new(PHASE_SEARCH);
    let outcome = run(&config, &mut observer).unwrap();
    assert!(outcome.interrupted && outcome.summary.is_none());
    assert_eq!(outcome.interrupted_phase.as_deref(), Some(PHASE_SEARCH));
    assert!(outcome.checkpoints.exists());
    assert!(
        !config.layout_path.exists(),
        "only a finished run writes --out"
    );
    assert_eq!(Layout::load(&outcome.partial).unwrap(), outcome.winner);
    assert!(!config.report_dir.exists());
    assert!(!files::lock_path(&config.layout_path).exists());
}

#[test]
fn every_phase_can_be_interrupted_and_the_finished_result_stays() {
    let dir = tempfile::tempdir().unwrap();
    let mut config = small(dir.path());
    // Long enough phases that a stop lands inside each.
    config.compare_trials = 400;
    config.validate_solvers = vec![Solver::ParallelWeighted, Solver::Ml];
    let finished = run(&config, &mut Silent).unwrap();
    let layout_bytes = std::fs::read(&config.layout_path).unwrap();
    let report_bytes = std::fs::read(config.report_dir.join("summary.json")).unwrap();
    for phase in [PHASE_COMPARE, PHASE_VALIDATE] {
        let mut observer = StopIn::at_start(phase);
        let outcome = run(&config, &mut observer).unwrap();
        assert!(outcome.interrupted, "{phase}");
        assert_eq!(outcome.interrupted_phase.as_deref(), Some(phase));
        assert_eq!(observer.phases.last().map(String::as_str), Some(phase));
        // The search had finished: the partial file holds its winner.
        let partial = Layout::load(&outcome.partial).unwrap();
        assert_eq!(partial.points, finished.winner.points);
        let status = partial.provenance.unwrap()["status"].clone();
        assert!(status.as_str().unwrap().contains(phase), "{status}");
        assert_eq!(std::fs::read(&config.layout_path).unwrap(), layout_bytes);
        assert_eq!(
            std::fs::read(config.report_dir.join("summary.json")).unwrap(),
            report_bytes
        );
        assert!(outcome.checkpoints.exists());
    }
    // A resumed run finishes, counts every evaluation and cleans up.
    let mut resumed_config = config.clone();
    resumed_config.resume = true;
    let resumed = run(&resumed_config, &mut Silent).unwrap();
    assert_eq!(resumed.evaluations, finished.evaluations);
    assert_eq!(resumed.winner.points, finished.winner.points);
    assert!(!resumed.partial.exists() && !resumed.checkpoints.exists());
}

#[test]
fn a_front_is_written_with_its_report_and_not_before() {
    let dir = tempfile::tempdir().unwrap();
    let mut config = small(dir.path());
    config.validate_solvers = vec![Solver::ParallelWeighted, Solver::Ml];
    let layout_dir = dir.path().join("t-front");
    config.front = Some(FrontOutput {
        settings: FrontSettings {
            levels: 1,
            iterations: 40,
        },
        layout_dir: layout_dir.clone(),
    });
    // Stopped in the winner's validation, after the front's sweep: no
    // front file without its report.
    let mut observer = StopIn::at_start(PHASE_VALIDATE);
    let outcome = run(&config, &mut observer).unwrap();
    assert!(outcome.interrupted);
    assert!(observer.phases.iter().any(|p| p == PHASE_FRONT));
    assert!(!layout_dir.exists(), "front layouts before the report");
    assert!(!config.report_dir.exists());
    // A finished run writes both.
    let outcome = run(&config, &mut Silent).unwrap();
    let front = outcome.front.expect("a front");
    assert!(!front.members.is_empty());
    for member in &front.members {
        Layout::load(&member.layout).unwrap();
    }
    for file in ["front.json", "front.csv", "front.svg", "summary.json"] {
        assert!(config.report_dir.join(file).exists(), "{file}");
    }
}

#[test]
fn custom_layouts_of_twelve_points_end_identifiable_and_sixteen_are_refused_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let mut config = small_with_floor(dir.path());
    // The stereo rule (pairwise distances 1 mm apart) in the default
    // 100 mm cube.
    config.constraints.min_distance_diff_mm = 1.0;
    config.family = FamilyKind::Custom {
        count: 12,
        start: None,
    };
    config.search.iterations = 60;
    config.search.polish_iterations = 40;
    let outcome = run(&config, &mut Silent).unwrap();
    let violations = config.constraints.violations(&outcome.winner.positions());
    assert!(violations.feasible(), "{violations:?}");
    assert!(violations.smallest_distance_diff_mm >= 1.0);
    let status = Layout::load(&config.layout_path)
        .unwrap()
        .provenance
        .unwrap()["status"]
        .clone();
    assert!(status.as_str().unwrap().starts_with("finished"), "{status}");

    // Sixteen: 120 distances fit the range (capacity 162) but not the
    // cube's geometry as far as the repair finds; refused before any
    // work, with what it does reach.
    let dir = tempfile::tempdir().unwrap();
    let mut config = small(dir.path());
    config.constraints.min_distance_diff_mm = 1.0;
    config.family = FamilyKind::Custom {
        count: 16,
        start: None,
    };
    let error = run(&config, &mut Silent).unwrap_err();
    let text = error.to_string();
    assert!(matches!(error, SearchError::Unsatisfiable(_)), "{text}");
    assert!(text.contains("no layout of 16 points"), "{text}");
    assert!(text.contains("--points 1"), "{text}");
    assert!(text.contains("not a proof"), "{text}");
    assert!(!config.checkpoint_dir.exists());
    assert!(!config.layout_path.exists());
}

/// Records each phase's last progress.
#[derive(Default)]
struct Record {
    last: Vec<(String, u64, u64)>,
}

impl Observer for Record {
    fn progress(&mut self, phase: &str, done: u64, total: u64) {
        assert!(done <= total, "{phase}: {done} of {total}");
        match self.last.last_mut() {
            Some(last) if last.0 == phase => {
                assert!(
                    done >= last.1,
                    "{phase} went back from {} to {done}",
                    last.1
                );
                assert_eq!(total, last.2, "{phase} changed its total");
                *last = (phase.to_string(), done, total);
            }
            _ => self.last.push((phase.to_string(), done, total)),
        }
    }
}

#[test]
fn every_phase_has_a_bar_that_ends_at_its_total() {
    let dir = tempfile::tempdir().unwrap();
    let mut config = small_with_floor(dir.path());
    config.search.iterations = 150;
    let mut observer = Record::default();
    run(&config, &mut observer).unwrap();
    // The winner as printed: its scenarios visible as printed are those
    // its availability as printed counts, each checked for identity.
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(config.report_dir.join("summary.json")).unwrap(),
    )
    .unwrap();
    let books = &summary["supports"];
    let visible = books["identifiable_as_printed"][0].as_f64().unwrap();
    let identifiable = books["identifiable_as_printed"][1].as_f64().unwrap();
    let scenarios = books["scenarios"].as_f64().unwrap();
    assert_eq!(
        visible,
        books["winner"]["availability"].as_f64().unwrap() * scenarios
    );
    assert!(identifiable <= visible && visible > 0.0, "{books}");
    let phases: Vec<&str> = observer.last.iter().map(|p| p.0.as_str()).collect();
    assert_eq!(
        phases,
        [
            PHASE_SEARCH,
            PHASE_IDENTIFY,
            PHASE_SUPPORTS,
            PHASE_COMPARE,
            PHASE_VALIDATE
        ]
    );
    // The search's total is its real budget: starts × iterations.
    assert_eq!(observer.last[0].2, 2 * 150);
    assert_eq!(observer.last[1].2, IDENTIFY_ROUNDS as u64);
    // The check as printed: one step, then one per repair round.
    assert_eq!(observer.last[2].2, 1 + crate::search::SUPPORT_ROUNDS as u64);
    // The comparison: 5 designs (winner, start, 3 hand designs; none
    // made admissible, the stereo distance rule being off) × 2 seeds ×
    // 20 scenarios.
    assert_eq!(observer.last[3].2, 5 * 2 * 20);
    // The validation: its Monte-Carlo run, then identifiability.
    assert_eq!(observer.last[4].2, 2 * 20);
    for (phase, done, total) in &observer.last {
        assert_eq!(done, total, "{phase} ended short of its total");
    }
}

#[test]
fn a_resumed_search_keeps_the_books() {
    let longer = |dir: &Path| {
        let mut config = small(dir);
        config.search.iterations = 2000;
        config
    };
    let dir = tempfile::tempdir().unwrap();
    let straight = run(&longer(dir.path()), &mut Silent).unwrap();
    let other = tempfile::tempdir().unwrap();
    let config = longer(other.path());
    let first = run(&config, &mut StopIn::new(PHASE_SEARCH)).unwrap();
    assert!(first.interrupted);
    // A temporary left by a killed writer is removed.
    let stale = config.layout_path.with_file_name(".t.json.999999.0.tmp");
    std::fs::write(&stale, "half a layout").unwrap();
    let mut resume = config.clone();
    resume.resume = true;
    let mut observer = Collect::default();
    let resumed = run(&resume, &mut observer).unwrap();
    assert!(!stale.exists());
    assert!(observer.lines.iter().any(|l| l.contains("resuming")));
    assert_eq!(resumed.evaluations, straight.evaluations);
    let run_json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(config.report_dir.join("run.json")).unwrap())
            .unwrap();
    assert_eq!(run_json["evaluations"], straight.evaluations);
    assert_eq!(run_json["resumed"], true);
    assert!(run_json["evaluations_this_run"].as_u64().unwrap() < straight.evaluations as u64);
}

#[test]
fn outputs_are_checked_and_locked_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let mut config = small(dir.path());
    // Another run holds the layout.
    let lock = files::OutputLock::acquire(&config.layout_path).unwrap();
    let error = run(&config, &mut Silent).unwrap_err();
    assert!(matches!(error, SearchError::Lock(_)), "{error}");
    assert!(
        error.to_string().contains("in use by another run"),
        "{error}"
    );
    assert!(!config.checkpoint_dir.exists());
    drop(lock);
    // The layout's directory is a file.
    let file = dir.path().join("plain-file");
    std::fs::write(&file, "x").unwrap();
    config.layout_path = file.join("t.json");
    config.checkpoint_dir = checkpoint_dir_beside(&config.layout_path);
    let error = run(&config, &mut Silent).unwrap_err();
    assert!(matches!(error, SearchError::Unwritable { .. }), "{error}");
    // The report directory is a file.
    let mut config = small(dir.path());
    config.report_dir = file.clone();
    let error = run(&config, &mut Silent).unwrap_err();
    assert!(matches!(error, SearchError::Unwritable { .. }), "{error}");
    assert!(!config.checkpoint_dir.exists());
}

#[test]
fn impossible_constraints_are_refused_before_the_search() {
    let dir = tempfile::tempdir().unwrap();
    let mut config = small(dir.path());
    config.constraints.min_distance_diff_mm = 1.0;
    config.family = FamilyKind::Custom {
        count: 30,
        start: None,
    };
    let error = run(&config, &mut Silent).unwrap_err();
    assert!(matches!(error, SearchError::Unsatisfiable(_)), "{error}");
    assert!(
        error.to_string().contains("435 pairwise distances"),
        "{error}"
    );
    assert!(!config.checkpoint_dir.exists());
    assert!(!config.layout_path.exists());
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
    // Nothing was created for a refused configuration.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn too_many_points_for_distinct_distances_are_refused_before_the_search() {
    let dir = tempfile::tempdir().unwrap();
    let mut config = small(dir.path());
    config.constraints.min_distance_diff_mm = 1.0;
    config.family = FamilyKind::Custom {
        count: 19,
        start: None,
    };
    let error = run(&config, &mut Silent).unwrap_err();
    assert!(
        error.to_string().contains("171 pairwise distances")
            && error.to_string().contains("at most 162"),
        "{error}"
    );
    assert!(!config.layout_path.exists());
    assert!(!config.checkpoint_dir.exists());
}

#[test]
fn the_analysis_alone_writes_nothing_and_finds_what_the_workflow_reports() {
    let dir = tempfile::tempdir().unwrap();
    let config = small(dir.path());
    let Analysed::Finished(finished) = analysis::run(&config, &mut Silent).unwrap() else {
        panic!("an uninterrupted analysis finishes");
    };
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    let outcome = run(&config, &mut Silent).unwrap();
    let summary = outcome.summary.unwrap();
    assert_eq!(finished.winner, outcome.winner);
    assert_eq!(
        serde_json::to_value(&finished.summary.designs).unwrap(),
        serde_json::to_value(&summary.designs).unwrap()
    );
}
