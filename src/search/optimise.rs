//! argmin optimisers over a layout family: Nelder–Mead, particle swarm and
//! simulated annealing, run from several seeded starts in parallel.
//!
//! * Every random stream is seeded from (seed, start): particle swarm gets a
//!   seeded ChaCha generator (argmin's default draws from the OS), annealing
//!   perturbs with its own seeded generator, and random starts are drawn from
//!   `stream_rng(seed, START_STREAM, start)`: uniformly within bounds, or,
//!   with a start jitter, around the spread start (basin hopping from the
//!   best structured start rather than a blind sample of a 20-odd-dimensional
//!   box, where random starts rarely reach the good basins).
//! * Every run has a bounded iteration count (Nelder–Mead has no bounds and
//!   may never converge on a noisy objective). Parameters outside the
//!   family's bounds are clamped before evaluation and penalised by
//!   [`BOUND_PENALTY`] per range-width of excess, so simplices stay inside.
//! * Each start first *repairs* its start point: Nelder–Mead on the
//!   (tightened) constraint violation alone, which costs microseconds per
//!   evaluation, for up to [`REPAIR_ITERATIONS`] iterations. Starting the
//!   real search from a feasible point matters: the identifiability
//!   constraint (distinct pairwise distances) is a field of kinks that a
//!   penalty alone leaves optimisers stranded just outside. A custom family
//!   that the repair leaves infeasible then gets the distance-spreading
//!   repair ([`crate::family::Constraints::spread_distances`]): beyond ten
//!   points or so, distinct distances must fill the envelope's range.
//! * Particle swarm and annealing are followed by a Nelder–Mead polish of
//!   their best point.
//! * Starts are independent and deterministic; the winner is the best start
//!   (feasible before infeasible, then lowest cost, then lowest start index),
//!   so the result does not depend on the thread count.
//! * A shared tracker reports every improvement of the best-so-far layout to
//!   the caller (which writes it atomically), and a stop flag, checked at
//!   every evaluation, ends all starts promptly (Ctrl-C): evaluations return
//!   +∞ at once and the iteration observer then ends the executor, before
//!   that iteration could be checkpointed.
//! * With [`Checkpoints`], each start's optimiser phases are checkpointed
//!   ([`super::checkpoint`]) and resume where they stopped.

use super::checkpoint::{CheckpointError, Checkpoints, StartCheckpoint, StartState};
use super::{Evaluation, Evaluator, PENALTY_MARGIN_FRACTION, PENALTY_MARGIN_MM};
use crate::family::{Family, FamilyKind};
use crate::synthetic::stream_rng;
use argmin::core::checkpointing::Checkpoint;
use argmin::core::{observers::ObserverMode, CostFunction, Executor, Solver, State, KV};
use argmin::solver::neldermead::NelderMead;
use argmin::solver::particleswarm::{Particle, ParticleSwarm};
use argmin::solver::simulatedannealing::{Anneal, SimulatedAnnealing};
use rand::Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// Iterations of the feasibility repair of each start point.
pub const REPAIR_ITERATIONS: u64 = 1500;
/// Cost added per range-width a parameter lies outside its bounds.
pub const BOUND_PENALTY: f64 = 100.0;
/// Random stream of the random starts.
const START_STREAM: u64 = 0x5EA2C4;
/// Random stream of particle swarm.
const SWARM_STREAM: u64 = 0x5EA2C5;
/// Random stream of the final polish's jittered starts.
const POLISH_STREAM: u64 = 0x5EA2C7;
/// Starts of the final polish after Nelder–Mead (the best layout itself and
/// jittered copies), each with `polish_iterations` iterations: basin hopping
/// around the winner, which steadies it across seeds.
pub const FINAL_POLISH_STARTS: usize = 4;
/// Least jitter of the final polish's starts, fraction of each range.
pub const FINAL_POLISH_JITTER: f64 = 0.005;
/// Random stream of annealing.
const ANNEAL_STREAM: u64 = 0x5EA2C6;
/// Random stream of the distance-spreading repair's jitter.
const SPREAD_STREAM: u64 = 0x5EA2C8;
/// Seeded tries of the distance-spreading repair of one start (each from
/// its own jitter).
pub const SPREAD_TRIES: u64 = 3;
/// Nelder–Mead's initial simplex steps this fraction of each range.
pub const SIMPLEX_STEP: f64 = 0.1;
/// The repair's simplex steps this fraction of each range: small, so that
/// the repaired start stays next to the start it repairs (the
/// identifiability constraint needs moves of about a millimetre, which a
/// full-size simplex overshoots by an order of magnitude).
pub const REPAIR_STEP: f64 = 0.01;
/// Rounds of the repair (see [`REPAIR_STEP`]).
pub const REPAIR_ROUNDS: u64 = 5;
/// Restarted rounds of each Nelder–Mead run.
pub const NELDER_MEAD_ROUNDS: u64 = 4;
/// Each Nelder–Mead round's simplex is this fraction of the previous one's.
pub const ROUND_SHRINK: f64 = 0.5;
/// Initial annealing temperature (costs are ~1 for the reference layout).
pub const ANNEAL_TEMPERATURE: f64 = 0.05;
/// At the initial temperature, annealing steps have this fraction of each
/// parameter's range as standard deviation.
pub const ANNEAL_STEP: f64 = 0.1;

/// Which optimiser runs each start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Optimiser {
    /// Nelder–Mead simplex.
    NelderMead,
    /// Particle swarm, then a Nelder–Mead polish.
    ParticleSwarm,
    /// Simulated annealing, then a Nelder–Mead polish.
    Annealing,
}

impl Optimiser {
    /// Every optimiser.
    pub const ALL: [Optimiser; 3] = [
        Optimiser::NelderMead,
        Optimiser::ParticleSwarm,
        Optimiser::Annealing,
    ];
}

impl std::str::FromStr for Optimiser {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text {
            "nelder-mead" | "nm" => Ok(Optimiser::NelderMead),
            "pso" | "particle-swarm" => Ok(Optimiser::ParticleSwarm),
            "annealing" | "sa" => Ok(Optimiser::Annealing),
            other => Err(format!(
                "unknown optimiser '{other}'; use nelder-mead, pso or annealing"
            )),
        }
    }
}

/// How the search runs.
#[derive(Debug, Clone, Serialize)]
pub struct SearchSettings {
    /// The optimiser.
    pub optimiser: Optimiser,
    /// Independent starts: start 0 is the family's natural start, start 1 its
    /// maximum-spread start ([`Family::spread`]), the others random (see
    /// [`SearchSettings::start_jitter`]).
    pub starts: usize,
    /// Starts 2… : 0 draws them uniformly within bounds; a fraction f in
    /// (0, 1] draws each parameter of the spread start plus a uniform offset
    /// within ± f of that parameter's range, clamped into bounds.
    pub start_jitter: f64,
    /// Iterations of the main optimiser per start.
    pub iterations: u64,
    /// Particles (particle swarm).
    pub particles: usize,
    /// Iterations of the Nelder–Mead polish (0: none).
    pub polish_iterations: u64,
    /// Seed of every random stream.
    pub seed: u64,
}

impl SearchSettings {
    /// Checks the settings (before anything is written or run).
    pub fn check(&self) -> Result<(), OptimiseError> {
        if self.starts == 0 || self.iterations == 0 {
            return Err(OptimiseError::Settings(
                "starts and iterations must be at least 1".into(),
            ));
        }
        if !(0.0..=1.0).contains(&self.start_jitter) {
            return Err(OptimiseError::Settings(format!(
                "the start jitter must be a fraction of each parameter's range in [0, 1], got {}",
                self.start_jitter
            )));
        }
        if self.optimiser == Optimiser::ParticleSwarm && self.particles < 2 {
            return Err(OptimiseError::Settings(
                "particle swarm needs at least 2 particles".into(),
            ));
        }
        Ok(())
    }
}

/// A scored parameter vector.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    /// Family parameters (clamped into bounds).
    pub params: Vec<f64>,
    /// Its score.
    pub evaluation: Evaluation,
    /// The start that found it.
    pub start: usize,
}

impl Candidate {
    /// Admissible (constraints met, availability floor reached) before
    /// inadmissible, then lower cost, then lower start index.
    fn better_than(&self, other: &Candidate) -> bool {
        let infeasible = |c: &Candidate| !c.evaluation.admissible();
        infeasible(self)
            .cmp(&infeasible(other))
            .then(self.evaluation.cost.total_cmp(&other.evaluation.cost))
            .then(self.start.cmp(&other.start))
            .is_lt()
    }
}

/// What the caller hears while the search runs (from worker threads).
pub trait SearchObserver: Sync {
    /// The best-so-far layout improved.
    fn improved(&self, candidate: &Candidate);
    /// A start finished an iteration; `evaluations` counts all starts.
    fn progress(&self, start: usize, iteration: u64, evaluations: usize, best_cost: f64);
    /// A start ran to its end (not called for a start a stop ended).
    fn finished(&self, start: usize) {
        let _ = start;
    }
}

/// The result of a search.
#[derive(Debug, Clone, Serialize)]
pub struct OptimiseOutcome {
    /// The winner.
    pub best: Candidate,
    /// Each start's best, in start order.
    pub starts: Vec<Candidate>,
    /// Objective evaluations of the whole search, those before a resume
    /// included (restored from the checkpoints), so a resumed search counts
    /// what an uninterrupted one would.
    pub evaluations: usize,
    /// Objective evaluations this call made itself.
    pub evaluations_this_run: usize,
    /// Whether the stop flag ended the search early.
    pub interrupted: bool,
}

/// Why a search failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OptimiseError {
    /// Bad settings.
    #[error("invalid search settings: {0}")]
    Settings(String),
    /// Stopped before any layout was evaluated.
    #[error("the search was interrupted before it evaluated any layout")]
    InterruptedEmpty,
    /// Checkpoints could not be read or written.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    /// argmin reported an error.
    #[error("optimiser failed in start {start}: {message}")]
    Optimiser {
        /// The start.
        start: usize,
        /// argmin's message.
        message: String,
    },
}

struct Shared<'a> {
    best: Mutex<Option<Candidate>>,
    evaluations: Arc<AtomicUsize>,
    observer: Arc<dyn SearchObserver + Send>,
    stop: &'a AtomicBool,
    /// Set by the first evaluation that sees `stop`; iteration observers
    /// (which must own their data) end their executors on it.
    halted: Arc<AtomicBool>,
    /// Every start's state, for the books at the end (a start a stop ended
    /// returns none of its own).
    start_states: Mutex<Vec<Arc<Mutex<StartState>>>>,
}

impl Shared<'_> {
    fn offer(&self, candidate: &Candidate) {
        let mut best = self
            .best
            .lock()
            .expect("no thread panics while holding the tracker");
        if best.as_ref().is_none_or(|b| candidate.better_than(b)) {
            *best = Some(candidate.clone());
            self.observer.improved(candidate);
        }
    }
}

struct LayoutProblem<'a> {
    family: &'a Family,
    evaluator: &'a Evaluator,
    point_sigma: &'a [Option<f64>],
    lower: &'a [f64],
    upper: &'a [f64],
    start: usize,
    shared: &'a Shared<'a>,
    start_best: Mutex<Option<Candidate>>,
    /// The start's best parameters and annealing generator, shared with its
    /// checkpoints.
    start_state: Arc<Mutex<StartState>>,
    /// While repairing, the cost is the constraint violation alone.
    repairing: bool,
}

impl LayoutProblem<'_> {
    fn bound_penalty(&self, params: &[f64]) -> f64 {
        params
            .iter()
            .zip(self.lower.iter().zip(self.upper))
            .map(|(p, (lo, hi))| {
                let excess = (lo - p).max(0.0) + (p - hi).max(0.0);
                BOUND_PENALTY * excess / (hi - lo)
            })
            .sum()
    }
}

impl CostFunction for LayoutProblem<'_> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, params: &Self::Param) -> Result<Self::Output, argmin::core::Error> {
        // After a stop every evaluation returns +∞ at once, so the bounded
        // iterations drain in microseconds (argmin's Nelder–Mead unwraps
        // cost errors, so an error cannot end it).
        if self.shared.stop.load(Ordering::Relaxed) {
            self.shared.halted.store(true, Ordering::Relaxed);
            return Ok(f64::INFINITY);
        }
        let clamped = self.family.clamp(params);
        if self.repairing {
            let points = self.family.points(&clamped);
            return Ok(self.evaluator.penalty(&points) + self.bound_penalty(params));
        }
        let evaluation = self
            .evaluator
            .evaluate(&self.family.points(&clamped), self.point_sigma);
        let cost = evaluation.cost + self.bound_penalty(params);
        let candidate = Candidate {
            params: clamped,
            evaluation,
            start: self.start,
        };
        self.shared.evaluations.fetch_add(1, Ordering::Relaxed);
        self.start_state
            .lock()
            .expect("no panics while holding the lock")
            .evaluations += 1;
        {
            let mut best = self
                .start_best
                .lock()
                .expect("no panics while holding the lock");
            if best.as_ref().is_none_or(|b| candidate.better_than(b)) {
                *best = Some(candidate.clone());
                self.start_state
                    .lock()
                    .expect("no panics while holding the lock")
                    .best_params = Some(candidate.params.clone());
            }
        }
        self.shared.offer(&candidate);
        Ok(cost)
    }
}

impl Anneal for LayoutProblem<'_> {
    type Param = Vec<f64>;
    type Output = Vec<f64>;
    type Float = f64;

    /// Moves each parameter with probability 1/2 by a Gaussian step whose
    /// size shrinks with the temperature.
    fn anneal(&self, params: &Vec<f64>, temperature: f64) -> Result<Vec<f64>, argmin::core::Error> {
        let mut start_state = self
            .start_state
            .lock()
            .expect("no panics while holding the lock");
        let rng = &mut start_state.anneal_rng;
        let scale = ANNEAL_STEP * (temperature / ANNEAL_TEMPERATURE).min(1.0);
        let mut next = params.clone();
        for (k, value) in next.iter_mut().enumerate() {
            if rng.random::<bool>() {
                let step: f64 = rng.sample(StandardNormal);
                *value = (*value + step * scale * (self.upper[k] - self.lower[k]))
                    .clamp(self.lower[k], self.upper[k]);
            }
        }
        Ok(next)
    }
}

/// The argmin observer that forwards iterations to the caller's observer.
/// It also ends the executor once the search is halted, so that an iteration
/// evaluated after a stop is never checkpointed.
struct ProgressObserver {
    observer: Arc<dyn SearchObserver + Send>,
    evaluations: Arc<AtomicUsize>,
    halted: Arc<AtomicBool>,
    start: usize,
}

impl ProgressObserver {
    fn new(shared: &Shared<'_>, start: usize) -> Self {
        Self {
            observer: Arc::clone(&shared.observer),
            evaluations: Arc::clone(&shared.evaluations),
            halted: Arc::clone(&shared.halted),
            start,
        }
    }
}

/// The error an executor ends with after a stop.
#[derive(Debug, thiserror::Error)]
#[error("search stopped")]
struct Halted;

impl<I: State<Float = f64>> argmin::core::observers::Observe<I> for ProgressObserver {
    fn observe_iter(&mut self, state: &I, _kv: &KV) -> Result<(), argmin::core::Error> {
        if self.halted.load(Ordering::Relaxed) {
            return Err(Halted.into());
        }
        self.observer.progress(
            self.start,
            state.get_iter(),
            self.evaluations.load(Ordering::Relaxed),
            state.get_best_cost(),
        );
        Ok(())
    }
}

/// A simplex at `start` with one vertex per parameter, `scale` of its range
/// away (inward at a bound).
fn simplex(start: &[f64], lower: &[f64], upper: &[f64], scale: f64) -> Vec<Vec<f64>> {
    let mut vertices = vec![start.to_vec()];
    for k in 0..start.len() {
        let mut vertex = start.to_vec();
        let step = scale * (upper[k] - lower[k]);
        vertex[k] = if vertex[k] + step <= upper[k] {
            vertex[k] + step
        } else {
            vertex[k] - step
        };
        vertices.push(vertex);
    }
    vertices
}

/// Runs one optimiser phase of a start through argmin's executor, with the
/// progress observer and, when `checkpoint` names a file, checkpointing that
/// resumes from it: the start's best parameters are restored and scored
/// again, the executor reloads the solver and its state, and the phase's end
/// state is saved once more so a resumed run skips a finished phase.
fn run_phase<'a, S, I>(
    problem: LayoutProblem<'a>,
    solver: S,
    configure: impl FnOnce(I) -> I,
    checkpoint: Option<PathBuf>,
) -> Result<LayoutProblem<'a>, argmin::core::Error>
where
    S: Solver<LayoutProblem<'a>, I> + Serialize + DeserializeOwned,
    I: State<Float = f64> + Serialize + DeserializeOwned,
{
    let start_state = Arc::clone(&problem.start_state);
    let file = checkpoint
        .as_ref()
        .map(|path| StartCheckpoint::new(path.clone(), Arc::clone(&start_state)));
    if let Some(file) = &file {
        if file.restore_start_state()? {
            let best = start_state
                .lock()
                .expect("no panics while holding the lock")
                .best_params
                .clone();
            if let Some(params) = best {
                // Scoring the restored best again rebuilds the start's own
                // best and the shared best-so-far; it is not one of the
                // search's evaluations, so the restored count stands.
                let lock = || {
                    start_state
                        .lock()
                        .expect("no panics while holding the lock")
                };
                let restored = lock().evaluations;
                problem.cost(&params)?;
                lock().evaluations = restored;
            }
        }
    }
    let observer = ProgressObserver::new(problem.shared, problem.start);
    let mut executor = Executor::new(problem, solver)
        .configure(configure)
        .add_observer(observer, ObserverMode::Always);
    if let Some(file) = file {
        executor = executor.checkpointing(file);
    }
    let result = executor.run()?;
    if let Some(path) = checkpoint {
        StartCheckpoint::new(path, start_state).save(&result.solver, &result.state)?;
    }
    Ok(result
        .problem
        .problem
        .expect("the executor returns its problem"))
}

/// Nelder–Mead in [`NELDER_MEAD_ROUNDS`] rounds that share `iterations`:
/// each round restarts from the start's best point with a fresh simplex,
/// [`ROUND_SHRINK`] times the previous round's size. A simplex in 10–20
/// dimensions collapses onto a subspace (here, onto the kinks of the
/// identifiability constraint) long before its budget is spent; a fresh
/// simplex restores the lost directions. Each round is its own checkpointed
/// phase (`<phase>-<round>`).
fn run_nelder_mead<'a>(
    mut problem: LayoutProblem<'a>,
    start: &[f64],
    iterations: u64,
    checkpoints: Option<(&Checkpoints, &str)>,
) -> Result<LayoutProblem<'a>, argmin::core::Error> {
    let rounds = NELDER_MEAD_ROUNDS.min(iterations);
    let mut from = start.to_vec();
    for round in 0..rounds {
        let budget = iterations / rounds + u64::from(round < iterations % rounds);
        let scale = SIMPLEX_STEP * ROUND_SHRINK.powi(round as i32);
        let solver = NelderMead::new(simplex(&from, problem.lower, problem.upper, scale))
            .with_sd_tolerance(1e-10)?;
        let file = checkpoints.map(|(c, phase)| c.file(problem.start, &format!("{phase}-{round}")));
        problem = run_phase(problem, solver, |state| state.max_iters(budget), file)?;
        if let Some(best) = best_params(&problem) {
            from = best;
        }
    }
    Ok(problem)
}

fn best_params(problem: &LayoutProblem<'_>) -> Option<Vec<f64>> {
    problem
        .start_best
        .lock()
        .expect("no panics while holding the lock")
        .as_ref()
        .map(|c| c.params.clone())
}

/// Moves `initial` to a point that meets the (tightened) constraints:
/// Nelder–Mead on the constraint violation alone, for up to
/// [`REPAIR_ITERATIONS`] iterations in each of up to [`REPAIR_ROUNDS`]
/// rounds. Each round restarts from the best point so far with a simplex
/// twice the previous one's, from [`REPAIR_STEP`]: small first, so that the
/// repaired point stays next to `initial`, larger when a symmetric start
/// (equal distances everywhere) leaves the small simplex on a plateau of
/// kinks. A custom family whose points still break a constraint then gets
/// the distance-spreading repair ([`spread_repair`], seeded by `seed` and the
/// start), which moves them further but reaches the identifiability
/// constraint for many more points. Returns the best point found if none
/// meets them. `problem` must be in repair mode.
fn repair_start<'a>(
    mut problem: LayoutProblem<'a>,
    initial: Vec<f64>,
    seed: u64,
) -> Result<(LayoutProblem<'a>, Vec<f64>), argmin::core::Error> {
    debug_assert!(problem.repairing);
    let mut best = initial;
    let mut cost = problem.cost(&best)?;
    for round in 0..REPAIR_ROUNDS {
        if cost <= 0.0 {
            break;
        }
        let scale = REPAIR_STEP * 2f64.powi(round as i32);
        let repair = NelderMead::new(simplex(&best, problem.lower, problem.upper, scale))
            .with_sd_tolerance(0.0)?;
        let result = Executor::new(problem, repair)
            .configure(|state| state.max_iters(REPAIR_ITERATIONS).target_cost(0.0))
            .run()?;
        if result.state.best_cost < cost {
            cost = result.state.best_cost;
            if let Some(param) = &result.state.best_param {
                best = param.clone();
            }
        }
        problem = result
            .problem
            .problem
            .expect("the executor returns its problem");
    }
    if cost > 0.0 {
        if let Some(spread) = spread_repair(
            problem.family,
            problem.evaluator,
            &best,
            seed,
            problem.start,
        ) {
            let spread_cost = problem.cost(&spread)?;
            if spread_cost < cost {
                best = spread;
            }
        }
    }
    let repaired = problem.family.clamp(&best);
    Ok((problem, repaired))
}

/// The distance-spreading repair
/// ([`crate::family::Constraints::spread_distances`]) of a
/// custom family's `params` towards `evaluator`'s constraints as its
/// penalty tightens them: up to [`SPREAD_TRIES`] seeded tries, from
/// `stream_rng(seed, SPREAD_STREAM, start · SPREAD_TRIES + try)`. Returns the
/// first try's parameters that meet them, else the last try's; None for
/// families whose parameters are not point coordinates, or without the
/// identifiability constraint (the general repair meets the others).
pub fn spread_repair(
    family: &Family,
    evaluator: &Evaluator,
    params: &[f64],
    seed: u64,
    start: usize,
) -> Option<Vec<f64>> {
    let constraints = evaluator.constraints();
    if constraints.min_distance_diff_mm <= 0.0
        || !matches!(family.kind(), FamilyKind::Custom { .. })
    {
        return None;
    }
    let target = constraints.tightened(PENALTY_MARGIN_FRACTION, PENALTY_MARGIN_MM);
    let fixed = family.fixed_points();
    let mut last = None;
    for attempt in 0..SPREAD_TRIES {
        let mut points = family.points(params);
        let mut rng = stream_rng(seed, SPREAD_STREAM, start as u64 * SPREAD_TRIES + attempt);
        let met = target.spread_distances(&mut points, &fixed, &mut rng);
        last = family.custom_params(&points);
        if met || last.is_none() {
            break;
        }
    }
    last
}

/// The layout nearest `params` (by the search's own repair) that meets
/// `evaluator`'s constraints, or the closest it gets: how the report makes
/// a hand design admissible before comparing it with the winner.
pub fn repair(
    family: &Family,
    evaluator: &Evaluator,
    params: &[f64],
) -> Result<Vec<f64>, OptimiseError> {
    let never = AtomicBool::new(false);
    let shared = Shared {
        best: Mutex::new(None),
        evaluations: Arc::new(AtomicUsize::new(0)),
        observer: Arc::new(Quiet),
        stop: &never,
        halted: Arc::new(AtomicBool::new(false)),
        start_states: Mutex::new(Vec::new()),
    };
    let (lower, upper) = family.bounds();
    let problem = LayoutProblem {
        family,
        evaluator,
        point_sigma: &[],
        lower: &lower,
        upper: &upper,
        start: 0,
        shared: &shared,
        start_best: Mutex::new(None),
        start_state: Arc::new(Mutex::new(StartState {
            best_params: None,
            anneal_rng: stream_rng(0, ANNEAL_STREAM, 0),
            evaluations: 0,
        })),
        repairing: true,
    };
    repair_start(problem, family.clamp(params), 0)
        .map(|(_, repaired)| repaired)
        .map_err(|error| OptimiseError::Optimiser {
            start: 0,
            message: error.to_string(),
        })
}

/// What every start of one run shares: the family, the objective, the
/// shared best and stop, the points' σ and the parameter bounds.
struct StartContext<'a> {
    family: &'a Family,
    evaluator: &'a Evaluator,
    shared: &'a Shared<'a>,
    point_sigma: &'a [Option<f64>],
    bounds: &'a (Vec<f64>, Vec<f64>),
}

/// Runs start `start` (its point from `extra` when it is one of the warm
/// starts) under `settings`, resuming from and writing `checkpoints`.
fn run_start<'a>(
    context: &StartContext<'a>,
    settings: &SearchSettings,
    (start, extra): (usize, &[Vec<f64>]),
    checkpoints: Option<&Checkpoints>,
) -> Result<Option<Candidate>, argmin::core::Error> {
    let StartContext {
        family,
        evaluator,
        shared,
        point_sigma,
        bounds,
    } = *context;
    let (lower, upper) = (&bounds.0, &bounds.1);
    let initial = start_point(family, settings, bounds, start, extra);
    let start_state = Arc::new(Mutex::new(StartState {
        best_params: None,
        anneal_rng: stream_rng(settings.seed, ANNEAL_STREAM, start as u64),
        evaluations: 0,
    }));
    shared
        .start_states
        .lock()
        .expect("no panics while holding the lock")
        .push(Arc::clone(&start_state));
    let problem = LayoutProblem {
        family,
        evaluator,
        point_sigma,
        lower,
        upper,
        start,
        shared,
        start_best: Mutex::new(None),
        start_state,
        repairing: true,
    };
    // The repair is deterministic and cheap, so a resumed run repeats it
    // rather than checkpointing it.
    let (mut problem, initial) = repair_start(problem, initial, settings.seed)?;
    problem.repairing = false;
    let main = checkpoints.map(|c| c.file(start, "main"));
    let problem = match settings.optimiser {
        Optimiser::NelderMead => run_nelder_mead(
            problem,
            &initial,
            settings.iterations,
            checkpoints.map(|c| (c, "main")),
        )?,
        Optimiser::ParticleSwarm => {
            // The swarm starts from the start point plus random particles, so
            // start 0 always contains the family's natural start.
            let mut rng = stream_rng(settings.seed, SWARM_STREAM, start as u64);
            let mut population = Vec::with_capacity(settings.particles);
            for k in 0..settings.particles {
                let position: Vec<f64> = if k == 0 {
                    initial.clone()
                } else {
                    lower
                        .iter()
                        .zip(upper)
                        .map(|(lo, hi)| rng.random_range(*lo..=*hi))
                        .collect()
                };
                let velocity: Vec<f64> = lower
                    .iter()
                    .zip(upper)
                    .map(|(lo, hi)| rng.random_range(-(hi - lo)..=(hi - lo)))
                    .collect();
                let cost = problem.cost(&position)?;
                population.push(Particle::new(position, cost, velocity));
            }
            let solver = ParticleSwarm::new((lower.clone(), upper.clone()), settings.particles)
                .with_rng_generator(rng);
            run_phase(
                problem,
                solver,
                |state| state.population(population).max_iters(settings.iterations),
                main,
            )?
        }
        Optimiser::Annealing => {
            let solver = SimulatedAnnealing::new_with_rng(
                ANNEAL_TEMPERATURE,
                stream_rng(settings.seed, SWARM_STREAM, start as u64),
            )?;
            run_phase(
                problem,
                solver,
                |state| state.param(initial.clone()).max_iters(settings.iterations),
                main,
            )?
        }
    };
    let problem = if settings.optimiser != Optimiser::NelderMead && settings.polish_iterations > 0 {
        match best_params(&problem) {
            Some(best) => run_nelder_mead(
                problem,
                &best,
                settings.polish_iterations,
                checkpoints.map(|c| (c, "polish")),
            )?,
            None => problem,
        }
    } else {
        problem
    };
    let best = problem
        .start_best
        .lock()
        .expect("no panics while holding the lock")
        .take();
    Ok(best)
}

/// The parameters start `start` begins from (before its repair): the
/// family's natural start, its spread start, then seeded random points, as
/// [`SearchSettings`] describes.
fn start_point(
    family: &Family,
    settings: &SearchSettings,
    (lower, upper): &(Vec<f64>, Vec<f64>),
    start: usize,
    extra: &[Vec<f64>],
) -> Vec<f64> {
    if let Some(point) = start
        .checked_sub(settings.starts)
        .and_then(|k| extra.get(k))
    {
        return family.clamp(point);
    }
    match start {
        0 => family.initial(),
        1 => family.spread(),
        _ => {
            let mut rng = stream_rng(settings.seed, START_STREAM, start as u64);
            let jitter = settings.start_jitter;
            if jitter > 0.0 {
                let centre = family.spread();
                let jittered: Vec<f64> = centre
                    .iter()
                    .zip(lower.iter().zip(upper))
                    .map(|(c, (lo, hi))| c + jitter * (hi - lo) * rng.random_range(-1.0..=1.0))
                    .collect();
                family.clamp(&jittered)
            } else {
                lower
                    .iter()
                    .zip(upper)
                    .map(|(lo, hi)| rng.random_range(*lo..=*hi))
                    .collect()
            }
        }
    }
}

/// Minimises `evaluator`'s cost over `family`'s parameters, checkpointing
/// into (and resuming from) `checkpoints` when given.
pub fn run(
    family: &Family,
    evaluator: &Evaluator,
    settings: &SearchSettings,
    stop: &AtomicBool,
    observer: Arc<dyn SearchObserver + Send>,
    checkpoints: Option<&Checkpoints>,
) -> Result<OptimiseOutcome, OptimiseError> {
    run_with_starts(
        family,
        evaluator,
        settings,
        &[],
        stop,
        observer,
        checkpoints,
    )
}

/// [`run`] with further start points after the settings' own starts (warm
/// starts: an ε-constraint sweep starts each level from the previous
/// level's winner). They are starts `settings.starts…` in the outcome.
pub fn run_with_starts(
    family: &Family,
    evaluator: &Evaluator,
    settings: &SearchSettings,
    extra: &[Vec<f64>],
    stop: &AtomicBool,
    observer: Arc<dyn SearchObserver + Send>,
    checkpoints: Option<&Checkpoints>,
) -> Result<OptimiseOutcome, OptimiseError> {
    // Warm starts alone (no own starts) are a valid run.
    SearchSettings {
        starts: settings.starts.max(usize::from(!extra.is_empty())),
        ..settings.clone()
    }
    .check()?;
    let bounds = family.bounds();
    let point_sigma = family.layout("", &family.initial()).point_sigmas();
    let shared = Shared {
        best: Mutex::new(None),
        evaluations: Arc::new(AtomicUsize::new(0)),
        observer,
        stop,
        halted: Arc::new(AtomicBool::new(false)),
        start_states: Mutex::new(Vec::new()),
    };
    let context = StartContext {
        family,
        evaluator,
        shared: &shared,
        point_sigma: &point_sigma,
        bounds: &bounds,
    };
    let results: Vec<Result<Option<Candidate>, argmin::core::Error>> = (0..settings.starts
        + extra.len())
        .into_par_iter()
        .map(|start| {
            // A start that would begin after a stop does not begin at all.
            if stop.load(Ordering::Relaxed) {
                return Err(Halted.into());
            }
            let result = run_start(&context, settings, (start, extra), checkpoints);
            if result.is_ok() {
                shared.observer.finished(start);
            }
            result
        })
        .collect();
    let interrupted = stop.load(Ordering::Relaxed);
    let mut starts = collect_starts(results, interrupted, 0)?;
    // The final polish: Nelder–Mead again from the best layout and from
    // points jittered around it, each with a fresh simplex (see
    // [`FINAL_POLISH_STARTS`]).
    let first_stage = starts.len();
    let mut interrupted = interrupted;
    if !interrupted && settings.optimiser == Optimiser::NelderMead && settings.polish_iterations > 0
    {
        if let Some(best) = best_of(&starts) {
            let points = final_polish_points(family, settings, &bounds, &best.params);
            let polish = SearchSettings {
                starts: 0,
                iterations: settings.polish_iterations,
                ..settings.clone()
            };
            let offset = settings.starts + extra.len();
            let results: Vec<_> = (0..points.len())
                .into_par_iter()
                .map(|k| run_start(&context, &polish, (k, &points), None))
                .collect();
            interrupted = stop.load(Ordering::Relaxed);
            starts.extend(collect_starts(results, interrupted, offset)?);
        }
    }
    for (k, candidate) in starts.iter_mut().enumerate().skip(first_stage) {
        candidate.start = settings.starts + extra.len() + k - first_stage;
    }
    // After an interruption a start's own best may be missing; the shared
    // tracker still has the best layout seen anywhere.
    let best = if interrupted {
        shared
            .best
            .into_inner()
            .expect("no panics while holding the tracker")
    } else {
        best_of(&starts)
    }
    .ok_or(OptimiseError::InterruptedEmpty)?;
    let evaluations = shared
        .start_states
        .into_inner()
        .expect("no panics while holding the lock")
        .iter()
        .map(|state| {
            state
                .lock()
                .expect("no panics while holding the lock")
                .evaluations
        })
        .sum::<u64>() as usize;
    Ok(OptimiseOutcome {
        best,
        starts,
        evaluations,
        evaluations_this_run: shared.evaluations.load(Ordering::Relaxed),
        interrupted,
    })
}

/// A search observer that hears nothing (repairs report through their own
/// phase).
pub(crate) struct Quiet;

impl SearchObserver for Quiet {
    fn improved(&self, _: &Candidate) {}
    fn progress(&self, _: usize, _: u64, _: usize, _: f64) {}
}

/// One repair round: a quiet Nelder–Mead run of `iterations` from `from`
/// alone (no starts of its own, no final polish), under `settings`'
/// optimiser seed. The identifiability and the cross repairs run their
/// rounds through it.
pub(crate) fn repair_round(
    family: &Family,
    evaluator: &Evaluator,
    settings: &SearchSettings,
    iterations: u64,
    from: &[f64],
    stop: &AtomicBool,
) -> Result<OptimiseOutcome, OptimiseError> {
    let round = SearchSettings {
        starts: 0,
        iterations,
        polish_iterations: 0,
        ..settings.clone()
    };
    run_with_starts(
        family,
        evaluator,
        &round,
        &[from.to_vec()],
        stop,
        Arc::new(Quiet),
        None,
    )
}

/// The best of `candidates` by [`Candidate::better_than`].
fn best_of(candidates: &[Candidate]) -> Option<Candidate> {
    candidates
        .iter()
        .fold(None::<Candidate>, |best, c| match best {
            Some(b) if !c.better_than(&b) => Some(b),
            _ => Some(c.clone()),
        })
}

/// Each start's result, in start order (`offset` numbers them in errors).
fn collect_starts(
    results: Vec<Result<Option<Candidate>, argmin::core::Error>>,
    interrupted: bool,
    offset: usize,
) -> Result<Vec<Candidate>, OptimiseError> {
    let mut starts = Vec::with_capacity(results.len());
    for (start, result) in results.into_iter().enumerate() {
        match result {
            Ok(Some(candidate)) => starts.push(candidate),
            Ok(None) => {}
            // A start ended by a stop keeps no result of its own.
            Err(error) if interrupted && error.is::<Halted>() => {}
            Err(error) => {
                return Err(OptimiseError::Optimiser {
                    start: offset + start,
                    message: error.to_string(),
                })
            }
        }
    }
    Ok(starts)
}

/// The final polish's start points: the best parameters, then
/// [`FINAL_POLISH_STARTS`] − 1 seeded points within ± half the start jitter
/// (at least [`FINAL_POLISH_JITTER`]) of each parameter's range around them.
fn final_polish_points(
    family: &Family,
    settings: &SearchSettings,
    (lower, upper): &(Vec<f64>, Vec<f64>),
    best: &[f64],
) -> Vec<Vec<f64>> {
    let jitter = (0.5 * settings.start_jitter).max(FINAL_POLISH_JITTER);
    let mut points = vec![best.to_vec()];
    for k in 1..FINAL_POLISH_STARTS {
        let mut rng = stream_rng(settings.seed, POLISH_STREAM, k as u64);
        let jittered: Vec<f64> = best
            .iter()
            .zip(lower.iter().zip(upper))
            .map(|(c, (lo, hi))| c + jitter * (hi - lo) * rng.random_range(-1.0..=1.0))
            .collect();
        points.push(family.clamp(&jittered));
    }
    points
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::camera::Camera;
    use crate::family::{Constraints, Envelope, FamilyKind};
    use crate::noise::NoiseModel;
    use crate::scenario::{Range, ScenarioGrid};
    use crate::search::{Aggregate, ObjectiveSettings};

    pub(crate) fn setup() -> (Family, Evaluator) {
        let envelope = Envelope::new([100.0; 3]).unwrap();
        let family = Family::new(
            FamilyKind::Biprism {
                centre: true,
                tilts: false,
                free_hub: false,
            },
            envelope,
            10.0,
        )
        .unwrap();
        let grid = ScenarioGrid::new(
            Range::list(&[400.0, 800.0]),
            Range::single(30.0),
            Range::single(0.0),
            Range::list(&[-30.0, 30.0]),
            Range::single(0.0),
            Range::single(0.0),
            Range::single(0.5),
        )
        .unwrap();
        let evaluator = Evaluator::new(
            Camera::paper(),
            grid.scenarios(),
            ObjectiveSettings {
                objective: "crlb".parse().unwrap(),
                aggregate: Aggregate::Mean,
                translation_weight: 0.5,
                availability_weight: 2.0,
                min_availability: crate::search::AvailabilityFloor::None,
                trials: 10,
                seed: 1,
                noise: NoiseModel::default(),
                observation: crate::sphere_image::Observation::default(),
                chain: Default::default(),
            },
            Constraints {
                envelope,
                sphere_diameter_mm: 10.0,
                min_gap_mm: 1.0,
                min_distance_diff_mm: 0.0,
            },
            &crate::synthetic::biprism_points(50.0),
        );
        (family, evaluator)
    }

    /// Two starts (the natural and the spread start), no jitter.
    fn two_starts(
        optimiser: Optimiser,
        iterations: u64,
        particles: usize,
        polish_iterations: u64,
        seed: u64,
    ) -> SearchSettings {
        SearchSettings {
            optimiser,
            starts: 2,
            start_jitter: 0.0,
            iterations,
            particles,
            polish_iterations,
            seed,
        }
    }

    #[test]
    fn every_optimiser_keeps_a_near_optimal_start_and_is_deterministic() {
        let (family, evaluator) = setup();
        for optimiser in Optimiser::ALL {
            let settings = two_starts(optimiser, 40, 8, 40, 5);
            let stop = AtomicBool::new(false);
            let a = run(&family, &evaluator, &settings, &stop, Arc::new(Quiet), None).unwrap();
            let b = run(&family, &evaluator, &settings, &stop, Arc::new(Quiet), None).unwrap();
            assert_eq!(
                a.best.params, b.best.params,
                "{optimiser:?} is not deterministic"
            );
            // Without tilts the longest arms are best: the start (the paper's
            // biprism) is already near-optimal, so the search must not lose it.
            assert!(
                a.best.evaluation.cost <= 1.0 + 1e-9,
                "{optimiser:?}: {}",
                a.best.evaluation.cost
            );
            assert!(a.evaluations > 10);
        }
    }

    #[test]
    fn nelder_mead_improves_on_a_biprism_shrunk_to_30_percent_of_the_envelope() {
        let (_, evaluator) = setup();
        let envelope = Envelope::new([100.0; 3]).unwrap();
        // The paper's biprism fills the envelope with 50 mm arms: 15 mm is 30%.
        let shrunk = crate::layout::Layout {
            name: "shrunk".into(),
            points: crate::synthetic::biprism(15.0)
                .into_iter()
                .map(|(name, p)| crate::layout::LayoutPoint::new(name, p))
                .collect(),
            sphere_diameter_mm: 10.0,
            family: None,
            provenance: None,
        };
        let family = Family::new(
            FamilyKind::Custom {
                count: 0,
                start: Some(shrunk.clone()),
            },
            envelope,
            10.0,
        )
        .unwrap();
        let start = evaluator.evaluate(&shrunk.positions(), &[None; 7]);
        assert!(start.accuracy > 2.5, "not a poor start: {}", start.accuracy);
        // One start: the shrunken layout itself (the natural start).
        let settings = SearchSettings {
            starts: 1,
            ..two_starts(Optimiser::NelderMead, 800, 2, 0, 3)
        };
        let stop = AtomicBool::new(false);
        let outcome = run(&family, &evaluator, &settings, &stop, Arc::new(Quiet), None).unwrap();
        let best = &outcome.best.evaluation;
        assert!(best.admissible());
        assert!(
            best.accuracy < 0.5 * start.accuracy,
            "from {} only to {}",
            start.accuracy,
            best.accuracy
        );
    }

    #[test]
    fn jittered_starts_stay_near_the_spread_start_and_are_seeded() {
        let (family, _) = setup();
        let bounds = family.bounds();
        let spread = family.spread();
        let mut settings = SearchSettings {
            starts: 6,
            start_jitter: 0.05,
            ..two_starts(Optimiser::NelderMead, 1, 2, 0, 3)
        };
        let mut moved = false;
        for start in 2..6 {
            let point = start_point(&family, &settings, &bounds, start, &[]);
            assert_eq!(point, start_point(&family, &settings, &bounds, start, &[]));
            for (k, x) in point.iter().enumerate() {
                let range = bounds.1[k] - bounds.0[k];
                assert!((bounds.0[k]..=bounds.1[k]).contains(x));
                assert!((x - spread[k]).abs() <= 0.05 * range + 1e-12);
                moved |= (x - spread[k]).abs() > 1e-3 * range;
            }
        }
        assert!(moved, "the jitter moved nothing");
        // Without jitter the same starts are uniform draws within bounds.
        settings.start_jitter = 0.0;
        let far = (2..6).any(|start| {
            let point = start_point(&family, &settings, &bounds, start, &[]);
            point
                .iter()
                .zip(&spread)
                .enumerate()
                .any(|(k, (x, c))| (x - c).abs() > 0.05 * (bounds.1[k] - bounds.0[k]))
        });
        assert!(far);
        settings.start_jitter = 1.5;
        let stop = AtomicBool::new(false);
        let (_, evaluator) = setup();
        assert!(matches!(
            run(&family, &evaluator, &settings, &stop, Arc::new(Quiet), None),
            Err(OptimiseError::Settings(_))
        ));
    }

    #[test]
    fn a_stop_flag_ends_the_search() {
        let (family, evaluator) = setup();
        for optimiser in Optimiser::ALL {
            let settings = two_starts(optimiser, 100_000, 8, 100_000, 5);
            let stop = AtomicBool::new(true);
            let started = std::time::Instant::now();
            let result = run(&family, &evaluator, &settings, &stop, Arc::new(Quiet), None);
            assert!(
                matches!(result, Err(OptimiseError::InterruptedEmpty)),
                "{optimiser:?}"
            );
            // Not a timing assertion on speed, a liveness one: 10⁵ iterations
            // of real evaluations would take minutes.
            assert!(
                started.elapsed().as_secs() < 30,
                "{optimiser:?} did not stop"
            );
        }
    }

    /// Stops the search after a number of progress reports.
    struct StopAfter {
        remaining: AtomicUsize,
        stop: Arc<AtomicBool>,
    }
    impl SearchObserver for StopAfter {
        fn improved(&self, _: &Candidate) {}
        fn progress(&self, _: usize, _: u64, _: usize, _: f64) {
            if self.remaining.fetch_sub(1, Ordering::SeqCst) <= 1 {
                self.stop.store(true, Ordering::SeqCst);
            }
        }
    }

    #[test]
    fn an_interrupted_search_resumes_to_the_same_winner() {
        let (family, evaluator) = setup();
        for optimiser in Optimiser::ALL {
            let settings = two_starts(optimiser, 90, 6, 50, 11);
            let config = serde_json::json!({"optimiser": format!("{optimiser:?}")});
            let root = std::env::temp_dir()
                .join(format!("lo-resume-{}-{optimiser:?}", std::process::id()));
            let _ = std::fs::remove_dir_all(&root);
            let never = AtomicBool::new(false);
            let straight = run(
                &family,
                &evaluator,
                &settings,
                &never,
                Arc::new(Quiet),
                None,
            )
            .unwrap();

            let (checkpoints, _) = Checkpoints::prepare(&root, "t", &config, false).unwrap();
            let stop = Arc::new(AtomicBool::new(false));
            let observer = Arc::new(StopAfter {
                remaining: AtomicUsize::new(70),
                stop: Arc::clone(&stop),
            });
            let first = run(
                &family,
                &evaluator,
                &settings,
                &stop,
                observer,
                Some(&checkpoints),
            )
            .unwrap();
            assert!(first.interrupted, "{optimiser:?}: the stop never came");

            let (checkpoints, status) = Checkpoints::prepare(&root, "t", &config, true).unwrap();
            assert_eq!(status, crate::search::checkpoint::ResumeStatus::Resuming);
            let resumed = run(
                &family,
                &evaluator,
                &settings,
                &never,
                Arc::new(Quiet),
                Some(&checkpoints),
            )
            .unwrap();
            assert!(!resumed.interrupted);
            assert_eq!(
                resumed.best.params, straight.best.params,
                "{optimiser:?}: resuming changed the winner"
            );
            assert!(
                resumed.evaluations_this_run < straight.evaluations,
                "{optimiser:?}: the resumed run started over ({} vs {} evaluations)",
                resumed.evaluations_this_run,
                straight.evaluations
            );
            assert_eq!(
                resumed.evaluations, straight.evaluations,
                "{optimiser:?}: the resumed run lost the books of the first"
            );
            let _ = std::fs::remove_dir_all(&root);
        }
    }

    #[test]
    fn repair_makes_symmetric_hand_designs_identifiable() {
        let envelope = Envelope::new([100.0; 3]).unwrap();
        let constraints = Constraints {
            envelope,
            sphere_diameter_mm: 10.0,
            min_gap_mm: 2.0,
            min_distance_diff_mm: 1.0,
        };
        let (_, evaluator) = setup();
        let evaluator = Evaluator::new(
            Camera::paper(),
            evaluator.scenarios().to_vec(),
            evaluator.settings().clone(),
            constraints,
            &crate::synthetic::biprism_points(50.0),
        );
        for layout in crate::search::compare::hand_designs(&envelope, 10.0) {
            let family = Family::new(
                FamilyKind::Custom {
                    count: 0,
                    start: Some(layout.clone()),
                },
                envelope,
                10.0,
            )
            .unwrap();
            let start = family.initial();
            assert!(!constraints.violations(&family.points(&start)).feasible());
            let repaired = repair(&family, &evaluator, &start).unwrap();
            let points = family.points(&repaired);
            let v = constraints.violations(&points);
            assert!(v.feasible(), "{}: {v:?}", layout.name);
            // Next to the design it repairs: twelve equal distances need a
            // spread of 11 mm, so some sphere moves several millimetres.
            let moved = points
                .iter()
                .zip(&family.points(&start))
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, f64::max);
            assert!(moved < 15.0, "{}: moved {moved} mm", layout.name);
        }
    }
}
