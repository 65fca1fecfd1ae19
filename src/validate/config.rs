//! What a validation needs, checked once before any work starts.
//!
//! [`ValidateConfig`] names every input of the analysis; [`ValidateConfig::check`]
//! refuses a bad value with a [`ConfigError`] that names the field, so a
//! library user and the command line (which maps field names to its flags)
//! hear the same reason.

use crate::camera::Camera;
use crate::config::ConfigError;
use crate::identifiability;
use crate::layout::Layout;
use crate::mesh::MarkerOptions;
use crate::montecarlo::MonteCarloConfig;
use crate::pnp::Solver;
use crate::scenario::ScenarioGrid;
use crate::visibility::{MaxHidden, DEFAULT_MAX_HIDDEN};
use crate::volume::WorkingVolume;
use serde::Serialize;

/// Default Monte-Carlo trials of the unlabelled solver per visible scenario.
pub const DEFAULT_IDENTIFY_TRIALS: usize = 200;

/// Tilt step of the default grid, degrees (the paper's protocol).
pub const DEFAULT_TILT_STEP_DEG: f64 = 2.0;

/// Tilt step of the default grid when the solvers include a polynomial
/// solver (`dls`, `opnp`: 0.1–1 ms per solve, 15–150× the others), so that
/// every solver on the default grid at 200 trials fits in a minute on two
/// cores. A tilt range with a 2° step restores the full protocol.
pub const POLYNOMIAL_TILT_STEP_DEG: f64 = 10.0;

/// The default grid's tilt step for `solvers` ([`POLYNOMIAL_TILT_STEP_DEG`]
/// when they include `dls` or `opnp`, else [`DEFAULT_TILT_STEP_DEG`]).
pub fn default_tilt_step_deg(solvers: &[Solver]) -> f64 {
    if solvers
        .iter()
        .any(|s| matches!(s, Solver::Dls | Solver::Opnp))
    {
        POLYNOMIAL_TILT_STEP_DEG
    } else {
        DEFAULT_TILT_STEP_DEG
    }
}

/// How identifiability is checked in a validation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct IdentifiabilityCheck {
    /// A scenario is identifiable when its predicted share of correct
    /// labellings reaches this.
    pub min_correct: f64,
    /// Monte-Carlo trials of the unlabelled solver per visible scenario (0:
    /// the prediction alone).
    pub trials: usize,
}

impl Default for IdentifiabilityCheck {
    fn default() -> Self {
        IdentifiabilityCheck {
            min_correct: identifiability::DEFAULT_MIN_CORRECT,
            trials: DEFAULT_IDENTIFY_TRIALS,
        }
    }
}

/// Every input of a validation's analysis.
#[derive(Debug, Clone)]
pub struct ValidateConfig {
    /// The layout.
    pub layout: Layout,
    /// The simulated camera.
    pub camera: Camera,
    /// The working volume: the viewpoints and noise levels.
    pub volume: WorkingVolume,
    /// Trials, seed, solvers, noise and gross-failure threshold.
    pub monte_carlo: MonteCarloConfig,
    /// How identifiability is checked.
    pub identifiability: IdentifiabilityCheck,
    /// Sphere-centre fabrication error σ_fab, mm per coordinate: above 0,
    /// the error budget ([`crate::error_model::budget`]) counts a part
    /// printed to it; 0 counts the part a characterised layout's
    /// covariance describes, or none.
    pub fabrication_sigma_mm: f64,
    /// 1σ of the camera's intrinsics, px: any above 0 puts the camera in
    /// the error budget.
    pub camera_sigma: crate::error_model::budget::IntrinsicSigma,
    /// The part's structure: the supports that `export` builds with these
    /// options, routed for this grid ([`crate::mesh::supports_for_range`]),
    /// hide spheres as any occluder does; `None`: the spheres alone.
    pub structure: Option<MarkerOptions>,
    /// The largest fraction of a sphere's silhouette the supports may hide
    /// while the sphere still counts as seen, 0…1.
    pub max_hidden: f64,
    /// The command that asked for the run, for the report header.
    pub command: String,
}

impl ValidateConfig {
    /// The paper's biprism, camera and protocol grid (tilt step for
    /// `solvers` by [`default_tilt_step_deg`]) at 200 trials, seed 7, no
    /// fabrication run.
    pub fn new(layout: Layout, solvers: Vec<Solver>) -> Self {
        ValidateConfig {
            layout,
            camera: Camera::paper(),
            volume: WorkingVolume::Grid(ScenarioGrid::paper_protocol(default_tilt_step_deg(
                &solvers,
            ))),
            monte_carlo: MonteCarloConfig {
                trials: 200,
                seed: 7,
                solvers,
                noise: Default::default(),
                gross_threshold_deg: crate::montecarlo::DEFAULT_GROSS_THRESHOLD_DEG,
                observation: Default::default(),
            },
            identifiability: IdentifiabilityCheck::default(),
            fabrication_sigma_mm: 0.0,
            camera_sigma: Default::default(),
            structure: Some(MarkerOptions::default()),
            max_hidden: DEFAULT_MAX_HIDDEN,
            command: String::new(),
        }
    }

    /// The part's error for the budget: printed to `fabrication_sigma_mm`
    /// when it is above 0, else a characterised layout's own covariance,
    /// else none.
    pub fn part_error(&self) -> crate::error_model::budget::PartError {
        use crate::error_model::budget::PartError;
        if self.fabrication_sigma_mm > 0.0 {
            return PartError::Printed(self.fabrication_sigma_mm);
        }
        match self.layout.characterised_covariances() {
            Some(blocks) => PartError::Characterised(blocks),
            None => PartError::Exact,
        }
    }

    /// [`Self::max_hidden`], checked.
    pub fn max_hidden(&self) -> Result<MaxHidden, ConfigError> {
        MaxHidden::new(self.max_hidden)
    }

    /// Checks every value once, naming the first bad field: `layout` (its
    /// [`Layout::validate`] reason), `solvers`, `trials`,
    /// `gross_threshold_deg`, `min_correct`, `fabrication_sigma_mm`,
    /// `max_hidden`, then the volume's fields ([`WorkingVolume::check`]) and
    /// `volume` when no viewpoint of it sees every sphere.
    ///
    /// ```
    /// use layout_opt::layout::Layout;
    /// use layout_opt::pnp::Solver;
    /// use layout_opt::validate::ValidateConfig;
    /// let mut config = ValidateConfig::new(Layout::paper_biprism(), vec![Solver::Ml]);
    /// assert!(config.check().is_ok());
    /// config.monte_carlo.trials = 0;
    /// assert_eq!(config.check().unwrap_err().field, "trials");
    /// ```
    pub fn check(&self) -> Result<Checked<'_>, ConfigError> {
        self.layout
            .validate()
            .map_err(|e| ConfigError::new("layout", e.to_string()))?;
        let monte_carlo = &self.monte_carlo;
        if monte_carlo.solvers.is_empty() {
            return Err(ConfigError::new("solvers", "names no solver"));
        }
        if monte_carlo.trials == 0 {
            return Err(ConfigError::new("trials", "must be at least 1"));
        }
        let threshold = monte_carlo.gross_threshold_deg;
        if !(threshold > 0.0 && threshold.is_finite()) {
            return Err(ConfigError::new(
                "gross_threshold_deg",
                format!("must be a positive, finite number of degrees, got {threshold}"),
            ));
        }
        let min_correct = self.identifiability.min_correct;
        if !(min_correct > 0.0 && min_correct < 1.0) {
            return Err(ConfigError::new(
                "min_correct",
                format!("must be a probability strictly between 0 and 1, got {min_correct}"),
            ));
        }
        let sigma = self.fabrication_sigma_mm;
        if !(sigma >= 0.0 && sigma.is_finite()) {
            return Err(ConfigError::new(
                "fabrication_sigma_mm",
                format!("must be a finite number of millimetres ≥ 0, got {sigma}"),
            ));
        }
        self.max_hidden()?;
        self.volume.check()?;
        self.volume.check_seen(
            &self.camera,
            &self.layout.positions(),
            self.layout.sphere_diameter_mm,
            &format!("layout {}", self.layout.name),
        )?;
        Ok(Checked(self))
    }
}

/// A [`ValidateConfig`] that passed [`ValidateConfig::check`]: what the
/// analysis takes, so that it never sees an unchecked value.
#[derive(Debug, Clone, Copy)]
pub struct Checked<'a>(&'a ValidateConfig);

impl std::ops::Deref for Checked<'_> {
    type Target = ValidateConfig;

    fn deref(&self) -> &ValidateConfig {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config() -> ValidateConfig {
        ValidateConfig::new(Layout::paper_biprism(), vec![Solver::Ml])
    }

    #[test]
    fn defaults_pass_and_follow_the_solvers() {
        assert!(config().check().is_ok());
        assert_eq!(config().identifiability.trials, DEFAULT_IDENTIFY_TRIALS);
        assert_eq!(default_tilt_step_deg(&[Solver::Ml]), DEFAULT_TILT_STEP_DEG);
        assert_eq!(
            default_tilt_step_deg(&[Solver::Ml, Solver::Dls]),
            POLYNOMIAL_TILT_STEP_DEG
        );
    }

    #[test]
    fn every_bad_value_names_its_field() {
        type Spoil = fn(&mut ValidateConfig);
        let bad: [(&str, Spoil); 9] = [
            ("layout", |c| c.layout.points.truncate(3)),
            ("solvers", |c| c.monte_carlo.solvers.clear()),
            ("trials", |c| c.monte_carlo.trials = 0),
            ("gross_threshold_deg", |c| {
                c.monte_carlo.gross_threshold_deg = f64::INFINITY
            }),
            ("gross_threshold_deg", |c| {
                c.monte_carlo.gross_threshold_deg = 0.0
            }),
            ("min_correct", |c| c.identifiability.min_correct = 1.0),
            ("fabrication_sigma_mm", |c| c.fabrication_sigma_mm = -0.1),
            ("max_hidden", |c| c.max_hidden = 1.5),
            ("max_hidden", |c| c.max_hidden = f64::NAN),
        ];
        for (field, spoil) in bad {
            let mut config = config();
            spoil(&mut config);
            let error = config.check().unwrap_err();
            assert_eq!(error.field, field, "{error}");
        }
        let mut config = config();
        config.fabrication_sigma_mm = f64::NAN;
        assert_eq!(
            config.check().unwrap_err().to_string(),
            "fabrication_sigma_mm: must be a finite number of millimetres ≥ 0, got NaN"
        );
    }
}
