//! How long a search's optimisation will take, told before it starts: for
//! objectives with a Monte-Carlo term (the slow ones), the fastest of
//! [`TIMED_EVALUATIONS`] evaluations of the paper's biprism, times the
//! evaluations the optimiser will make (a cost model,
//! [`SIMPLEX_EVALUATIONS_PER_START`]).

use super::config::SearchConfig;
use super::optimise::{Optimiser, FINAL_POLISH_STARTS};
use super::{hand_designs, Evaluator, Term};
use std::time::Instant;

/// Nelder–Mead's evaluations per start, `SIMPLEX_EVALUATIONS_PER_START +
/// SIMPLEX_EVALUATIONS_PER_ITERATION × iterations`: a line through two
/// measured biprism searches (`search --depth 200..1000`): 8 starts × 3000
/// iterations made 38,423 evaluations, 2 starts × 150 iterations 985. The
/// fixed part is the restarted rounds' initial simplices and the start's
/// repair. The final polish's runs follow the same line: with four runs of
/// 2000 iterations it predicts 51,500 evaluations for the default search
/// (52,818 measured) and 14,120 for 2 starts × 150 iterations (14,019).
pub const SIMPLEX_EVALUATIONS_PER_START: f64 = 265.0;
/// See [`SIMPLEX_EVALUATIONS_PER_START`].
pub const SIMPLEX_EVALUATIONS_PER_ITERATION: f64 = 1.51;
/// Objective evaluations timed for the estimate; the fastest counts (the
/// others may be slowed by the machine's other work).
pub const TIMED_EVALUATIONS: usize = 3;

/// The estimate of an optimisation's time.
#[derive(Debug, Clone, PartialEq)]
pub struct SearchEstimate {
    /// Estimated seconds of the optimisation.
    pub seconds: f64,
    /// The fastest timed evaluation, seconds.
    pub per_evaluation_seconds: f64,
    /// Evaluations the optimiser will make, by the cost model.
    pub evaluations: f64,
    /// The objective, in words.
    pub objective: String,
    /// Scenarios of the grid.
    pub scenarios: usize,
    /// Starts of the optimisation.
    pub starts: usize,
    /// Worker threads each evaluation runs on.
    pub threads: usize,
}

impl SearchEstimate {
    /// How the estimate was made, in words (after "about <duration>").
    pub fn basis(&self) -> String {
        format!(
            "{:.3} s per evaluation of {} on the paper's biprism over {} scenarios, the fastest of {TIMED_EVALUATIONS} timed now; × about {:.0} evaluations for {} starts and the final polish (cost model from two measured searches); each evaluation runs on all {} threads",
            self.per_evaluation_seconds,
            self.objective,
            self.scenarios,
            self.evaluations,
            self.starts,
            self.threads,
        )
    }
}

/// Estimates the optimisation's time of a checked `config`; `None` when its
/// objective has no Monte-Carlo term (then a search is quick). Times
/// [`TIMED_EVALUATIONS`] evaluations now.
pub fn estimate(config: &SearchConfig) -> Option<SearchEstimate> {
    let settings = &config.objective;
    if !settings
        .objective
        .terms
        .iter()
        .any(|(term, _)| matches!(term, Term::MonteCarlo(_)))
    {
        return None;
    }
    let constraints = config.constraints;
    let paper = hand_designs(&constraints.envelope, constraints.sphere_diameter_mm).swap_remove(0);
    let (positions, sigmas) = (paper.positions(), paper.point_sigmas());
    // Building the evaluator scores its reference layout once: that is the
    // first timed evaluation.
    let started = Instant::now();
    let evaluator = Evaluator::new(
        config.camera,
        config.volume.scenarios(&config.camera),
        settings.clone(),
        constraints,
        &positions,
    );
    let mut per_evaluation = started.elapsed().as_secs_f64();
    for _ in 1..TIMED_EVALUATIONS {
        let started = Instant::now();
        let _ = evaluator.evaluate(&positions, &sigmas);
        per_evaluation = per_evaluation.min(started.elapsed().as_secs_f64());
    }
    let evaluations = evaluations(config);
    // A Monte-Carlo evaluation runs its scenarios on every thread, so the
    // timed one already used the whole machine, as the starts do together:
    // the time is evaluations × that time, not divided by the threads
    // again (checked: 14,019 evaluations of 2 starts × 150 iterations took
    // 182.8 s; two estimates before such runs said 184 s and 212 s).
    Some(SearchEstimate {
        seconds: per_evaluation * evaluations,
        per_evaluation_seconds: per_evaluation,
        evaluations,
        objective: settings.objective.to_string(),
        scenarios: config.volume.len(),
        starts: config.search.starts,
        threads: rayon::current_num_threads(),
    })
}

/// The evaluations the optimiser will make, by the cost model: every start,
/// then (after Nelder–Mead) the final polish's [`FINAL_POLISH_STARTS`] runs.
pub fn evaluations(config: &SearchConfig) -> f64 {
    let search = &config.search;
    let simplex = |iterations: u64| {
        SIMPLEX_EVALUATIONS_PER_START + SIMPLEX_EVALUATIONS_PER_ITERATION * iterations as f64
    };
    let per_start = match search.optimiser {
        Optimiser::NelderMead => simplex(search.iterations),
        Optimiser::ParticleSwarm => {
            search.iterations as f64 * search.particles as f64 + simplex(search.polish_iterations)
        }
        Optimiser::Annealing => search.iterations as f64 + simplex(search.polish_iterations),
    };
    let polish_runs = match search.optimiser {
        Optimiser::NelderMead if search.polish_iterations > 0 => FINAL_POLISH_STARTS,
        _ => 0,
    };
    per_start * search.starts as f64 + polish_runs as f64 * simplex(search.polish_iterations)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cost_model_counts_starts_and_the_final_polish() {
        let mut config = SearchConfig::new("t", std::path::Path::new("unused"));
        config.search.starts = 2;
        config.search.iterations = 150;
        config.search.polish_iterations = 100;
        let simplex =
            |i: f64| SIMPLEX_EVALUATIONS_PER_START + SIMPLEX_EVALUATIONS_PER_ITERATION * i;
        let expected = 2.0 * simplex(150.0) + FINAL_POLISH_STARTS as f64 * simplex(100.0);
        assert!((evaluations(&config) - expected).abs() < 1e-9);
        assert!(estimate(&config).is_none(), "crlb needs no estimate");
    }
}
