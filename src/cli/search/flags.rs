//! The flags of `layout-opt search`, with their help text.

use super::super::common::{CameraArgs, GridArgs, IdentifiabilityShare};
use super::super::volume::VolumeArgs;
use clap::{Args, ValueEnum};
use layout_opt::family::Envelope;
use layout_opt::mesh::Format;
use layout_opt::noise::NoiseModel;
use layout_opt::pnp::Solver;
use layout_opt::search::{
    Aggregate, AvailabilityFloor, Objective, Optimiser, WINNER_IDENTIFY_TRIALS,
};
use layout_opt::sphere_image::Observation;
use std::path::PathBuf;

/// Layout families.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(super) enum FamilyName {
    Biprism,
    Tetrahedron,
    Custom,
}

/// Flags of `search`.
#[derive(Debug, Args)]
pub struct SearchArgs {
    /// Layout family.
    #[arg(long, value_enum, default_value = "biprism")]
    pub(super) family: FamilyName,
    /// Count every candidate's own supports (the pillars export tries first)
    /// in the optimiser's loop: a sphere they hide more than this fraction
    /// (0–1) of counts as not seen. Off by default: an evaluation costs
    /// about twice as much (`cargo bench --bench supports`).
    #[arg(long, value_name = "FRACTION")]
    pub(super) count_supports: Option<layout_opt::visibility::MaxHidden>,
    /// The winner is checked, and repaired, as printed: a sphere its routed
    /// supports hide more than this fraction (0–1) of counts as not seen
    /// (docs/commands.md, "The winner as printed").
    #[arg(long, value_name = "FRACTION", default_value = "0.01")]
    pub(super) max_hidden: layout_opt::visibility::MaxHidden,
    /// Score the winner as the spheres alone: no check as printed.
    #[arg(long)]
    pub(super) no_supports: bool,
    /// Leave out the centre point (biprism: O0; tetrahedron: the centroid point).
    #[arg(long)]
    pub(super) no_centre: bool,
    /// Keep biprism arms on their axes (only their lengths vary).
    #[arg(long)]
    pub(super) no_tilts: bool,
    /// Pin the biprism's hub at the envelope's centre (by default it may move
    /// anywhere in the envelope).
    #[arg(long, alias = "centered-hub")]
    pub(super) centred_hub: bool,
    /// Number of free points (custom family).
    #[arg(long, default_value_t = 7)]
    pub(super) points: usize,
    /// Start layout for the custom family; its points marked "fixed" stay put.
    #[arg(long, value_name = "FILE")]
    pub(super) init: Option<PathBuf>,
    /// Envelope bounding the sphere centres: one size (a cube) or X,Y,Z, mm.
    #[arg(long, default_value = "100")]
    pub(super) envelope: Envelope,
    /// Sphere diameter, mm.
    #[arg(long, default_value_t = 10.0)]
    pub(super) sphere_diameter: f64,
    /// Smallest gap between sphere surfaces, mm.
    #[arg(long, default_value_t = 2.0)]
    pub(super) min_gap: f64,
    /// Smallest difference between two pairwise centre distances, mm: the
    /// identification rule of stereo trackers, which measure 3D points
    /// (0, the default, disables it; a single camera is served by
    /// --min-identifiability).
    #[arg(long, default_value_t = 0.0)]
    pub(super) min_distance_diff: f64,
    /// Least share of the visible scenarios in which one image identifies
    /// the spheres: the unlabelled solver is predicted to label the blobs
    /// correctly with probability ≥ 99.9% (--identify-criterion). A share
    /// (0.999 or 99.9%) or `none` (for stereo trackers, which identify by
    /// --min-distance-diff).
    #[arg(long, default_value = "99.9%", value_name = "SHARE")]
    pub(super) min_identifiability: IdentifiabilityShare,
    /// Least predicted probability of a correct labelling for a scenario to
    /// count as identifiable.
    #[arg(long, default_value = "99.9%", value_name = "PROBABILITY")]
    pub(super) identify_criterion: IdentifiabilityShare,
    /// Monte-Carlo trials of the unlabelled solver per visible scenario in
    /// the winner's validation (0: the prediction alone).
    #[arg(long, default_value_t = WINNER_IDENTIFY_TRIALS)]
    pub(super) identify_trials: usize,
    #[command(flatten)]
    pub(super) grid: GridArgs,
    #[command(flatten)]
    pub(super) volume: VolumeArgs,
    #[command(flatten)]
    pub(super) camera: CameraArgs,
    /// Objective: crlb, transfer, mc:<solver>, or a blend like crlb:0.7+mc:parallel-weighted:0.3.
    #[arg(long, default_value = "crlb")]
    pub(super) objective: Objective,
    /// How scenarios are combined: mean (RMS), p95 or max.
    #[arg(long, default_value = "mean")]
    pub(super) aggregate: Aggregate,
    /// Weight of translation against rotation error in the objective.
    #[arg(long, default_value_t = 0.5)]
    pub(super) translation_weight: f64,
    /// Weighted blend: cost of losing every scenario to visibility (occlusion,
    /// leaving the image), added to the accuracy. 0 (the default) scores
    /// accuracy alone, subject to --min-availability.
    #[arg(long, default_value_t = 0.0)]
    pub(super) availability_weight: f64,
    /// Least share of the grid's scenarios in which every sphere is visible
    /// and unoccluded: a share (0.6 or 60%), `reference` (the family's
    /// reference design on the same grid: for biprism, the paper's biprism),
    /// or `none` (availability priced by --availability-weight alone).
    #[arg(long, default_value = "reference", value_name = "SHARE")]
    pub(super) min_availability: AvailabilityFloor,
    /// Monte-Carlo trials per scenario for mc: objectives.
    #[arg(long, default_value_t = 20)]
    pub(super) trials: usize,
    /// Noise model: isotropic, per-point, size[:REF_PX] or calibrated:FILE (σ from images, docs/formats.md), optionally +outliers:RATE[:PX].
    #[arg(long, default_value = "isotropic")]
    pub(super) noise_model: NoiseModel,
    /// Image point of a sphere: `ellipse-centre` (its silhouette's centre,
    /// what a blob detector measures; the crlb term then carries the pose
    /// bias) or `centre` (its projected centre). Noise is added on top.
    #[arg(long, default_value = "ellipse-centre")]
    pub(super) observation: Observation,
    /// The chain the crlb term scores: ideal (the part is the layout, read
    /// as --observation says), printed[:SIGMA_MM] (a part printed to σ per
    /// centre coordinate, default 0.1 mm, read as projected centres, as
    /// track reads it) or characterised[:SIGMA_PX] (printed, then
    /// characterised from characterise --plan's views at σ px of centre
    /// noise, default 0.02).
    #[arg(long, default_value = "ideal", value_name = "CHAIN")]
    pub(super) chain: layout_opt::search::Chain,
    /// Optimiser: nelder-mead, pso or annealing (the last two are followed by
    /// a Nelder–Mead polish).
    #[arg(long, default_value = "nelder-mead")]
    pub(super) optimiser: Optimiser,
    /// Independent starts, run in parallel.
    #[arg(long, default_value_t = 8)]
    pub(super) starts: usize,
    /// Starts beyond the first two (the family's natural start and its
    /// spread start): 0 draws them uniformly within bounds; a fraction f in
    /// (0, 1] draws them around the spread start, each parameter within ± f
    /// of its range (basin hopping around the best structured start; random
    /// starts in a 20-odd-dimensional box rarely reach the good basins).
    #[arg(long, default_value_t = 0.02, value_name = "FRACTION")]
    pub(super) start_jitter: f64,
    /// Iterations per start.
    #[arg(long, default_value_t = 3000)]
    pub(super) iterations: u64,
    /// Particles (particle swarm).
    #[arg(long, default_value_t = 32)]
    pub(super) particles: usize,
    /// Nelder–Mead polish iterations: after particle swarm or annealing; after
    /// Nelder–Mead, the final polish runs this many from the winner and from
    /// three seeded copies jittered around it (0 disables). Default: two
    /// thirds of --iterations (2000 with its default), so that a short
    /// --iterations makes a short search.
    #[arg(long)]
    pub(super) polish: Option<u64>,
    /// Solver of the Monte-Carlo comparison in the report.
    #[arg(long, default_value = "parallel-weighted")]
    pub(super) compare_solver: Solver,
    /// Trials per scenario of the Monte-Carlo comparison.
    #[arg(long, default_value_t = 200)]
    pub(super) compare_trials: usize,
    /// Solvers of the winner's full sensitivity report (`all` or a list; the
    /// polynomial solvers DLS and OPnP take 0.3–2 ms per solve).
    #[arg(
        long,
        default_value = "parallel-weighted,parallel-gn,epnp-gn,sqpnp,lhm,ml"
    )]
    pub(super) validate_solvers: String,
    /// Name of the result. Default: <family>-search.
    #[arg(long)]
    pub(super) name: Option<String>,
    /// Where to write the winning layout. Default: layouts/<name>.json.
    #[arg(long, value_name = "FILE")]
    pub(super) out: Option<PathBuf>,
    /// Report directory. Default: reports/<name>/; with --out FILE, beside
    /// it: <FILE's directory>/<FILE's stem>-report/.
    #[arg(long, value_name = "DIR")]
    pub(super) report: Option<PathBuf>,
    /// Continue an interrupted search from its checkpoints. Refused, naming
    /// the settings that changed, when the only checkpoints are those of a
    /// different configuration.
    #[arg(long)]
    pub(super) resume: bool,
    /// Where checkpoints are kept (one directory per name and configuration
    /// hash; removed when the search finishes). Default: hidden beside the
    /// layout, <FILE's directory>/.<FILE's stem>.checkpoints/, so that it
    /// follows --out.
    #[arg(long, value_name = "DIR")]
    pub(super) checkpoint_dir: Option<PathBuf>,
    /// Also export the winner as printable meshes in these formats
    /// (stl, 3mf, obj, gltf, glb; comma-separated), with `export`'s defaults.
    #[arg(long, value_delimiter = ',', value_name = "FORMATS")]
    pub(super) export: Vec<Format>,
    /// Directory of the exported meshes. Default: build/<name>/.
    #[arg(long, value_name = "DIR")]
    pub(super) export_dir: Option<PathBuf>,
    /// Also compute the Pareto front of accuracy against availability (an
    /// ε-constraint sweep): front.json, front.csv and front.svg in the report
    /// directory, a layout per member in <dir of the layout>/<name>-front/.
    #[arg(long)]
    pub(super) front: bool,
    /// Availability levels of the front's sweep above the unconstrained one.
    #[arg(long, default_value_t = 8, value_name = "N", requires = "front")]
    pub(super) front_levels: usize,
    /// `--set N` and its companions.
    #[command(flatten)]
    pub(super) set: super::set::SetArgs,
}
