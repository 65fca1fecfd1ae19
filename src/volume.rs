//! The working volume: every pose, in six degrees of freedom, from which a
//! marker must be seen, and the noise it is seen with. It is either a
//! [`ScenarioGrid`] (the product of today's axis ranges) or a
//! [`SampledVolume`]: scrambled Sobol points (Burley's Owen-scrambled
//! Sobol sequence, Burley 2020, "Practical Hash-based Owen Scrambling",
//! through the `sobol_burley` crate) mapped into
//!
//! - a depth range;
//! - a placement of the marker origin: lateral offsets in x and y, a cone
//!   half-angle about the optical axis, or anywhere the whole marker (a
//!   ball of a given radius) is in the image;
//! - an orientation: tilt, pan and roll ranges, or a view cone (the largest
//!   angle between the marker's face axis, its −z, and the line of sight to
//!   the camera) with a roll range about the line of sight;
//! - a pixel noise range.
//!
//! Not to be confused with [`crate::visibility::WorkingRange`], the list
//! of views the part's supports are routed for. Every sample is a
//! [`Scenario`] with the scenario pose convention (`R = Rz(roll) · Ry(pan) ·
//! Rx(tilt)`), so every engine reads a sampled volume as it reads a grid.
//!
//! **Mapping from the unit hypercube** (dimension k of sample i is
//! `u_k`, the Sobol point scrambled by the seed): depth, offsets, angles of
//! the angle form, roll and noise are uniform in their intervals (`a + u·(b
//! − a)`); a cone of half-angle α is sampled uniformly over its solid
//! angle, `cos θ = 1 − u·(1 − cos α)` and azimuth `φ = 2π·u'`; the image
//! placement is uniform over the image's pixels inset by the marker's
//! image radius at that depth. The sequence is computed serially, so the
//! scenarios never depend on the thread count.
//!
//! ```
//! use layout_opt::camera::Camera;
//! use layout_opt::volume::{Interval, Orientation, Placement, SampledVolume, WorkingVolume};
//!
//! let volume = WorkingVolume::Sampled(SampledVolume {
//!     depth_mm: Interval::new(200.0, 1000.0),
//!     placement: Placement::Offsets {
//!         x_mm: Interval::new(0.0, 100.0),
//!         y_mm: Interval::new(-50.0, 50.0),
//!     },
//!     orientation: Orientation::ViewCone {
//!         half_angle_deg: 60.0,
//!         roll_deg: Interval::new(-30.0, 30.0),
//!     },
//!     sigma_px: Interval::point(0.5),
//!     samples: 64,
//!     seed: 7,
//! });
//! volume.check()?;
//! let scenarios = volume.scenarios(&Camera::paper());
//! assert_eq!(scenarios.len(), 64);
//! assert!(scenarios.iter().all(|s| (200.0..=1000.0).contains(&s.depth_mm)));
//! # Ok::<(), layout_opt::config::ConfigError>(())
//! ```

use crate::camera::Camera;
use crate::config::ConfigError;
use crate::scenario::{Range, Scenario, ScenarioGrid, MAX_ANGLE_DEG, VISIBILITY_MARGIN_PX};
use nalgebra::{Rotation3, Unit, Vector3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Most samples a sampled volume may hold (the Sobol sequence's length).
pub const MAX_SAMPLES: usize = 1 << 16;
/// Samples of the default sampled volume (a power of two, as Sobol points
/// are best balanced in blocks of powers of two). With 256, the default
/// search's winners sat on the availability floor of their own draw and
/// fell short of the paper's biprism on independent grids; with 512 they
/// meet it (docs/formats.md, "Default volume of `search`").
pub const DEFAULT_SAMPLES: usize = 512;
/// Bins of a sampled axis in the per-axis curves and the heatmaps.
pub const AXIS_BINS: usize = 8;
/// Largest cone half-angle, degrees: beyond 90° the marker's face points
/// away from the camera (view cone) or the origin is behind it (placement).
pub const MAX_CONE_DEG: f64 = 90.0;

/// A closed interval `[min, max]`; in files a number (a point) or
/// `[min, max]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(from = "IntervalForm", into = "[f64; 2]")]
pub struct Interval {
    /// Lower end.
    pub min: f64,
    /// Upper end (≥ `min` in a checked volume).
    pub max: f64,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum IntervalForm {
    Point(f64),
    Pair([f64; 2]),
}

impl From<IntervalForm> for Interval {
    fn from(form: IntervalForm) -> Self {
        match form {
            IntervalForm::Point(value) => Interval::point(value),
            IntervalForm::Pair([min, max]) => Interval { min, max },
        }
    }
}

impl From<Interval> for [f64; 2] {
    fn from(interval: Interval) -> Self {
        [interval.min, interval.max]
    }
}

impl Interval {
    /// `[min, max]` (checked by [`WorkingVolume::check`]).
    pub fn new(min: f64, max: f64) -> Self {
        Self { min, max }
    }

    /// The interval of one value.
    pub fn point(value: f64) -> Self {
        Self::new(value, value)
    }

    /// From the first to the last value of a command-line range (so that a
    /// descending range is an inverted interval, which the check refuses).
    pub fn of_range(range: &Range) -> Self {
        let first = range.values.first().copied().unwrap_or(f64::NAN);
        let last = range.values.last().copied().unwrap_or(f64::NAN);
        Self::new(first, last)
    }

    /// From the smallest to the largest value of a range (the box a grid
    /// axis spans, whatever its order).
    pub fn spanned(range: &Range) -> Self {
        let low = range.values.iter().copied().fold(f64::INFINITY, f64::min);
        let high = range
            .values
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        Self::new(low, high)
    }

    /// The point a fraction `u` ∈ [0, 1] along it.
    pub fn at(&self, u: f64) -> f64 {
        self.min + u * (self.max - self.min)
    }

    fn check(&self, field: &'static str) -> Result<(), ConfigError> {
        if !(self.min.is_finite() && self.max.is_finite()) {
            return Err(ConfigError::new(
                field,
                format!("must be finite, got {}..{}", self.min, self.max),
            ));
        }
        if self.min > self.max {
            return Err(ConfigError::new(
                field,
                format!(
                    "is an inverted range {}..{}: a sampled volume needs min ≤ max",
                    self.min, self.max
                ),
            ));
        }
        Ok(())
    }

    fn text(&self, unit: &str) -> String {
        if self.min == self.max {
            format!("{}{unit}", self.min)
        } else {
            format!("{}…{}{unit}", self.min, self.max)
        }
    }
}

/// Where the marker origin may sit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Placement {
    /// Lateral offsets of the origin from the optical axis, mm.
    Offsets {
        /// X offset, mm.
        x_mm: Interval,
        /// Y offset, mm.
        y_mm: Interval,
    },
    /// The origin's direction within this half-angle of the optical axis,
    /// uniform over the cone's solid angle.
    Cone {
        /// Half-angle, degrees (0…90, exclusive of 90).
        half_angle_deg: f64,
    },
    /// Anywhere a ball of this radius about the origin is wholly in the
    /// image (with the visibility margin): the origin's pixel uniform over
    /// the inset image.
    InImage {
        /// Radius of the ball that holds the marker, mm.
        marker_radius_mm: f64,
    },
}

/// How the marker may be turned.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Orientation {
    /// Tilt, pan and roll in the scenario convention, each uniform in its
    /// interval.
    Angles {
        /// Tilt about X, degrees.
        tilt_deg: Interval,
        /// Pan about Y, degrees.
        pan_deg: Interval,
        /// Roll about Z, degrees.
        roll_deg: Interval,
    },
    /// The marker's face axis (its −z) within `half_angle_deg` of the line
    /// of sight to the camera, uniform over the cone's solid angle, then
    /// rolled about the line of sight.
    ViewCone {
        /// Largest angle between the face axis and the line of sight,
        /// degrees (0…90).
        half_angle_deg: f64,
        /// Roll about the line of sight, degrees.
        roll_deg: Interval,
    },
}

/// A volume sampled at scrambled Sobol points (module docs give the
/// mapping).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SampledVolume {
    /// Depth of the marker origin (its camera z), mm.
    pub depth_mm: Interval,
    /// Where the origin sits.
    pub placement: Placement,
    /// How the marker is turned.
    pub orientation: Orientation,
    /// Pixel noise σ, px.
    pub sigma_px: Interval,
    /// Number of samples (1…[`MAX_SAMPLES`]).
    #[serde(default = "default_samples")]
    pub samples: usize,
    /// Seed of the scrambling (a file leaves it out: the command's `--seed`
    /// gives it).
    #[serde(default)]
    pub seed: u64,
}

fn default_samples() -> usize {
    DEFAULT_SAMPLES
}

/// The working volume: a grid of axis values or a sampled volume.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum WorkingVolume {
    /// The product of the axis ranges (today's grid).
    Grid(ScenarioGrid),
    /// Scrambled Sobol samples.
    Sampled(SampledVolume),
}

/// One axis of a volume's per-axis curves: its values (the grid's values,
/// or the centres of [`AXIS_BINS`] equal bins of a sampled axis) and which
/// value each scenario falls under.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumeAxis {
    /// The axis's name (`depth`, `offset-x`, `offset-y`, `tilt`, `pan`,
    /// `roll`, `noise`).
    pub name: &'static str,
    /// The grid's values, or the bin centres.
    pub values: Vec<f64>,
    /// Bin edges (`values.len() + 1`), or None for a grid axis.
    edges: Option<Vec<f64>>,
}

/// The six degrees of freedom and noise, with the scenario field each
/// reads, in grid order.
pub const AXES: [&str; 7] = [
    "depth", "offset-x", "offset-y", "tilt", "pan", "roll", "noise",
];

/// A scenario's value on a named axis.
pub fn axis_value(s: &Scenario, axis: &str) -> f64 {
    match axis {
        "depth" => s.depth_mm,
        "offset-x" => s.offset_x_mm,
        "offset-y" => s.offset_y_mm,
        "tilt" => s.tilt_deg,
        "pan" => s.pan_deg,
        "roll" => s.roll_deg,
        _ => s.sigma_px,
    }
}

impl VolumeAxis {
    /// The index of the value (bin) `scenario` falls under.
    pub fn bin(&self, scenario: &Scenario) -> Option<usize> {
        let value = axis_value(scenario, self.name);
        match &self.edges {
            None => self.values.iter().position(|&v| v == value),
            Some(edges) => {
                let (low, high) = (edges[0], edges[edges.len() - 1]);
                if !(low..=high).contains(&value) {
                    return None;
                }
                let width = (high - low) / self.values.len() as f64;
                Some((((value - low) / width) as usize).min(self.values.len() - 1))
            }
        }
    }
}

impl WorkingVolume {
    /// Checks the volume once, before any work: no empty volume, no
    /// inverted range, no cone beyond 90°, positive depths, angles within
    /// ±180°, non-negative noise. The field names the quantity (`depth`,
    /// `offset_x`, `view_cone`, `samples`, …).
    pub fn check(&self) -> Result<(), ConfigError> {
        match self {
            WorkingVolume::Grid(grid) => {
                if grid.is_empty() {
                    return Err(ConfigError::new("volume", "is empty: it holds no scenario"));
                }
                Ok(())
            }
            WorkingVolume::Sampled(volume) => volume.check(),
        }
    }

    /// Number of viewpoints.
    pub fn len(&self) -> usize {
        match self {
            WorkingVolume::Grid(grid) => grid.len(),
            WorkingVolume::Sampled(volume) => volume.samples,
        }
    }

    /// Whether it holds no viewpoint (never, for a checked volume).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Every viewpoint, in a fixed order that does not depend on the thread
    /// count; `camera` places the image placement's samples.
    pub fn scenarios(&self, camera: &Camera) -> Vec<Scenario> {
        match self {
            WorkingVolume::Grid(grid) => grid.scenarios(),
            WorkingVolume::Sampled(volume) => volume.scenarios(camera),
        }
    }

    /// The viewpoint at the unit-cube point `u` (depth, placement ×2,
    /// orientation ×3, noise; each clamped to 0…1), named `index`: the
    /// sampled volume's own mapping (module docs), or for a grid each axis
    /// spanned from its smallest to its largest value. A search between the
    /// samples moves `u` continuously.
    pub fn scenario_at(&self, index: usize, camera: &Camera, u: [f64; 7]) -> Scenario {
        let u = u.map(|v| if v.is_nan() { 0.5 } else { v.clamp(0.0, 1.0) });
        match self {
            WorkingVolume::Sampled(volume) => volume.scenario(index, camera, u),
            WorkingVolume::Grid(grid) => {
                let span = |range: &Range, u: f64| Interval::spanned(range).at(u);
                Scenario {
                    index,
                    depth_mm: span(&grid.depth_mm, u[0]),
                    offset_x_mm: span(&grid.offset_x_mm, u[1]),
                    offset_y_mm: span(&grid.offset_y_mm, u[2]),
                    tilt_deg: span(&grid.tilt_deg, u[3]),
                    pan_deg: span(&grid.pan_deg, u[4]),
                    roll_deg: span(&grid.roll_deg, u[5]),
                    sigma_px: span(&grid.sigma_px, u[6]),
                }
            }
        }
    }

    /// Each viewpoint's point in the unit cube, in [`Self::scenarios`]'
    /// order: [`Self::scenario_at`] of it is the viewpoint (a grid axis of
    /// one value maps to 0).
    pub fn unit_points(&self) -> Vec<[f64; 7]> {
        match self {
            WorkingVolume::Sampled(volume) => volume.unit_points(),
            WorkingVolume::Grid(grid) => {
                let ranges = grid.named_ranges();
                let spans: [Interval; 7] =
                    std::array::from_fn(|axis| Interval::spanned(ranges[axis].1));
                grid.scenarios()
                    .iter()
                    .map(|s| {
                        std::array::from_fn(|axis| {
                            let span = spans[axis];
                            let value = axis_value(s, ranges[axis].0);
                            if span.max > span.min {
                                (value - span.min) / (span.max - span.min)
                            } else {
                                0.0
                            }
                        })
                    })
                    .collect()
            }
        }
    }

    /// A volume of the same extent that shares no viewpoint with this one:
    /// the grid's midpoints between neighbouring values, or the same
    /// sampled volume scrambled with another seed.
    pub fn held_out(&self, held_out_grid: impl Fn(&ScenarioGrid) -> ScenarioGrid) -> Self {
        match self {
            WorkingVolume::Grid(grid) => WorkingVolume::Grid(held_out_grid(grid)),
            WorkingVolume::Sampled(volume) => WorkingVolume::Sampled(SampledVolume {
                seed: volume.seed ^ HELD_OUT_SEED,
                ..*volume
            }),
        }
    }

    /// The volume in words and numbers, for report headers.
    pub fn describe(&self) -> String {
        match self {
            WorkingVolume::Grid(grid) => format!(
                "a grid of {} viewpoints: {}",
                grid.len(),
                grid.named_ranges()
                    .iter()
                    .map(|(name, range)| format!("{name} {}", range_text(range)))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            WorkingVolume::Sampled(volume) => volume.describe(),
        }
    }

    /// The axes along which the viewpoints vary, with the value (or bin)
    /// of each; an axis with one value is left out.
    pub fn axes(&self, scenarios: &[Scenario]) -> Vec<VolumeAxis> {
        match self {
            WorkingVolume::Grid(grid) => grid
                .named_ranges()
                .iter()
                .filter(|(_, range)| range.values.len() > 1)
                .map(|(name, range)| VolumeAxis {
                    name,
                    values: range.values.clone(),
                    edges: None,
                })
                .collect(),
            WorkingVolume::Sampled(_) => {
                AXES.iter()
                    .filter_map(|&name| {
                        let (low, high) = scenarios.iter().fold(
                            (f64::INFINITY, f64::NEG_INFINITY),
                            |(low, high), s| {
                                let v = axis_value(s, name);
                                (low.min(v), high.max(v))
                            },
                        );
                        (high - low > AXIS_SPREAD_TOLERANCE * (1.0 + high.abs().max(low.abs())))
                            .then(|| {
                                let width = (high - low) / AXIS_BINS as f64;
                                VolumeAxis {
                                    name,
                                    values: (0..AXIS_BINS)
                                        .map(|k| low + (k as f64 + 0.5) * width)
                                        .collect(),
                                    edges: Some(
                                        (0..=AXIS_BINS).map(|k| low + k as f64 * width).collect(),
                                    ),
                                }
                            })
                    })
                    .collect()
            }
        }
    }

    /// Each axis as a range of values, in grid order: the grid's ranges,
    /// or for a sampled volume [`crate::scenario::DEFAULT_STEP_COUNT`]
    /// values spread over the extent its samples reach on the axis (one
    /// value when they do not vary). `export` routes supports for this
    /// grid when a layout's provenance records it.
    pub fn axis_ranges(&self, camera: &Camera) -> Vec<(&'static str, Range)> {
        match self {
            WorkingVolume::Grid(grid) => grid
                .named_ranges()
                .iter()
                .map(|(name, range)| (*name, (*range).clone()))
                .collect(),
            WorkingVolume::Sampled(_) => {
                let scenarios = self.scenarios(camera);
                AXES.iter()
                    .map(|&name| {
                        let (low, high) = scenarios.iter().fold(
                            (f64::INFINITY, f64::NEG_INFINITY),
                            |(low, high), s| {
                                let v = axis_value(s, name);
                                (low.min(v), high.max(v))
                            },
                        );
                        let steps = crate::scenario::DEFAULT_STEP_COUNT;
                        let range = if high - low
                            > AXIS_SPREAD_TOLERANCE * (1.0 + high.abs().max(low.abs()))
                        {
                            let values: Vec<f64> = (0..steps)
                                .map(|k| low + (high - low) * k as f64 / (steps - 1) as f64)
                                .collect();
                            Range::list(&values)
                        } else {
                            Range::single(low)
                        };
                        (name, range)
                    })
                    .collect()
            }
        }
    }

    /// Noise levels of the volume, for the checks that need σ > 0: the
    /// grid's values, or the sampled interval's ends.
    pub fn sigma_values_px(&self) -> Vec<f64> {
        match self {
            WorkingVolume::Grid(grid) => grid.sigma_px.values.clone(),
            WorkingVolume::Sampled(volume) => vec![volume.sigma_px.min, volume.sigma_px.max],
        }
    }

    /// Reads a sampled volume from a JSON or YAML file (`.yaml`/`.yml` by
    /// YAML, anything else by JSON; docs/formats.md gives the format) and
    /// checks it. The file's seed, if any, is replaced by `seed`.
    pub fn load(path: &Path, seed: u64) -> Result<Self, VolumeFileError> {
        let text = std::fs::read_to_string(path).map_err(|source| VolumeFileError::Read {
            path: path.display().to_string(),
            source,
        })?;
        let yaml = matches!(
            path.extension().and_then(|e| e.to_str()),
            Some("yaml" | "yml")
        );
        let parsed: Result<SampledVolume, String> = if yaml {
            serde_saphyr::from_str(&text).map_err(|e| crate::config::one_line(&e.to_string()))
        } else {
            serde_json::from_str(&text).map_err(|e| e.to_string())
        };
        let volume = parsed.map_err(|reason| VolumeFileError::Malformed {
            path: path.display().to_string(),
            reason,
        })?;
        let volume = WorkingVolume::Sampled(SampledVolume { seed, ..volume });
        volume.check().map_err(|source| VolumeFileError::Invalid {
            path: path.display().to_string(),
            source,
        })?;
        Ok(volume)
    }

    /// Refuses a volume from which no viewpoint has every sphere of
    /// `object` (centres, mm; spheres of `sphere_diameter_mm`) in front of
    /// the camera and inside the image (the rules of
    /// [`crate::scenario::visibility`] but occlusion: a volume that never
    /// has the marker in view is misdrawn, while one in which its spheres
    /// hide each other is a finding about the layout, which the reports
    /// give).
    pub fn check_seen(
        &self,
        camera: &Camera,
        object: &[Vector3<f64>],
        sphere_diameter_mm: f64,
        what: &str,
    ) -> Result<(), ConfigError> {
        let seen = self.scenarios(camera).iter().any(|s| {
            let images =
                crate::scenario::sphere_images(camera, &s.pose(), object, sphere_diameter_mm);
            let visibility = crate::scenario::visibility(&images, camera);
            visibility.behind.is_empty() && visibility.outside.is_empty()
        });
        if seen {
            Ok(())
        } else {
            Err(ConfigError::new(
                "volume",
                format!(
                    "no viewpoint of it has every sphere of {what} in view (in each, one is behind the camera or leaves the image): {}",
                    self.describe()
                ),
            ))
        }
    }
}

/// Why a volume file cannot be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum VolumeFileError {
    /// The file cannot be read.
    #[error("cannot read volume file {path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not a volume.
    #[error("malformed volume file {path}: {reason}")]
    Malformed {
        /// The file.
        path: String,
        /// What the parser said.
        reason: String,
    },
    /// The volume it holds is not usable.
    #[error("volume file {path}: {source}")]
    Invalid {
        /// The file.
        path: String,
        /// What is wrong.
        source: ConfigError,
    },
}

/// Mixed into the seed of a sampled volume's held-out twin.
const HELD_OUT_SEED: u64 = 0x9e37_79b9_7f4a_7c15;
/// Relative spread below which a sampled axis counts as constant.
const AXIS_SPREAD_TOLERANCE: f64 = 1e-9;

fn range_text(range: &Range) -> String {
    let values = &range.values;
    if values.len() <= 6 {
        values
            .iter()
            .map(|v| v.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    } else {
        format!(
            "{}…{} ({} values)",
            values[0],
            values[values.len() - 1],
            values.len()
        )
    }
}

impl SampledVolume {
    fn check(&self) -> Result<(), ConfigError> {
        if self.samples == 0 {
            return Err(ConfigError::new(
                "samples",
                "is 0: the volume would hold no viewpoint",
            ));
        }
        if self.samples > MAX_SAMPLES {
            return Err(ConfigError::new(
                "samples",
                format!(
                    "must be at most {MAX_SAMPLES} (the scrambled Sobol sequence's length), got {}",
                    self.samples
                ),
            ));
        }
        self.depth_mm.check("depth")?;
        if self.depth_mm.min <= 0.0 {
            return Err(ConfigError::new(
                "depth",
                format!(
                    "must be positive (mm in front of the camera), got {}",
                    self.depth_mm.min
                ),
            ));
        }
        if self.depth_mm.max > crate::scenario::MAX_DEPTH_MM {
            return Err(ConfigError::new(
                "depth",
                format!(
                    "must be {}, got {}",
                    crate::scenario::MAX_DEPTH_TEXT,
                    self.depth_mm.max
                ),
            ));
        }
        let cone = |field: &'static str, angle: f64, largest_open: bool| {
            let too_big = if largest_open {
                angle >= MAX_CONE_DEG
            } else {
                angle > MAX_CONE_DEG
            };
            if !angle.is_finite() || angle < 0.0 || too_big {
                let bound = if largest_open { "below" } else { "at most" };
                return Err(ConfigError::new(
                    field,
                    format!(
                        "must be a half-angle from 0° to {bound} {MAX_CONE_DEG}°, got {angle}°"
                    ),
                ));
            }
            Ok(())
        };
        match self.placement {
            Placement::Offsets { x_mm, y_mm } => {
                x_mm.check("offset_x")?;
                y_mm.check("offset_y")?;
            }
            Placement::Cone { half_angle_deg } => cone("placement_cone", half_angle_deg, true)?,
            Placement::InImage { marker_radius_mm } => {
                ConfigError::positive("in_image", marker_radius_mm)?
            }
        }
        let angle = |field: &'static str, interval: Interval| {
            interval.check(field)?;
            if interval.min < -MAX_ANGLE_DEG || interval.max > MAX_ANGLE_DEG {
                return Err(ConfigError::new(
                    field,
                    format!("must lie within −180…180°, got {}", interval.text("°")),
                ));
            }
            Ok(())
        };
        match self.orientation {
            Orientation::Angles {
                tilt_deg,
                pan_deg,
                roll_deg,
            } => {
                angle("tilt", tilt_deg)?;
                angle("pan", pan_deg)?;
                angle("roll", roll_deg)?;
            }
            Orientation::ViewCone {
                half_angle_deg,
                roll_deg,
            } => {
                cone("view_cone", half_angle_deg, false)?;
                angle("roll", roll_deg)?;
            }
        }
        self.sigma_px.check("sigma_px")?;
        if self.sigma_px.min < 0.0 {
            return Err(ConfigError::new(
                "sigma_px",
                format!("must be non-negative (px), got {}", self.sigma_px.min),
            ));
        }
        Ok(())
    }

    fn describe(&self) -> String {
        let placement = match self.placement {
            Placement::Offsets { x_mm, y_mm } => format!(
                "x offset {}, y offset {}",
                x_mm.text(" mm"),
                y_mm.text(" mm")
            ),
            Placement::Cone { half_angle_deg } => {
                format!("origin within {half_angle_deg}° of the optical axis")
            }
            Placement::InImage { marker_radius_mm } => format!(
                "anywhere a {marker_radius_mm} mm ball about the origin is wholly in the image"
            ),
        };
        let orientation = match self.orientation {
            Orientation::Angles {
                tilt_deg,
                pan_deg,
                roll_deg,
            } => format!(
                "tilt {}, pan {}, roll {}",
                tilt_deg.text("°"),
                pan_deg.text("°"),
                roll_deg.text("°")
            ),
            Orientation::ViewCone {
                half_angle_deg,
                roll_deg,
            } => format!(
                "face within {half_angle_deg}° of the line of sight, roll {} about it",
                roll_deg.text("°")
            ),
        };
        format!(
            "{} scrambled Sobol viewpoints (seed {}): depth {}, {placement}, {orientation}, σ {}",
            self.samples,
            self.seed,
            self.depth_mm.text(" mm"),
            self.sigma_px.text(" px")
        )
    }

    /// The samples (module docs give the mapping).
    fn scenarios(&self, camera: &Camera) -> Vec<Scenario> {
        self.unit_points()
            .into_iter()
            .enumerate()
            .map(|(index, u)| self.scenario(index, camera, u))
            .collect()
    }

    /// The scrambled Sobol points of the samples, in the unit cube.
    fn unit_points(&self) -> Vec<[f64; 7]> {
        let seed = (self.seed as u32) ^ ((self.seed >> 32) as u32);
        (0..self.samples)
            .map(|index| {
                std::array::from_fn(|dimension| {
                    f64::from(sobol_burley::sample(index as u32, dimension as u32, seed))
                })
            })
            .collect()
    }

    /// The scenario at the unit-cube point `u` (depth, placement ×2,
    /// orientation ×3, noise).
    fn scenario(&self, index: usize, camera: &Camera, u: [f64; 7]) -> Scenario {
        let depth_mm = self.depth_mm.at(u[0]);
        let (offset_x_mm, offset_y_mm) = match self.placement {
            Placement::Offsets { x_mm, y_mm } => (x_mm.at(u[1]), y_mm.at(u[2])),
            Placement::Cone { half_angle_deg } => {
                let (theta, phi) = in_cone(half_angle_deg, u[1], u[2]);
                let radius = depth_mm * theta.tan();
                (radius * phi.cos(), radius * phi.sin())
            }
            Placement::InImage { marker_radius_mm } => {
                let focal = 0.5 * (camera.fx() + camera.fy());
                let inset = VISIBILITY_MARGIN_PX + focal * marker_radius_mm / depth_mm;
                let along = |u: f64, size: f64| {
                    let span = (size - 2.0 * inset).max(0.0);
                    0.5 * (size - span) + u * span
                };
                let column = along(u[1], f64::from(camera.width()));
                let row = along(u[2], f64::from(camera.height()));
                (
                    (column - camera.cx()) / camera.fx() * depth_mm,
                    (row - camera.cy()) / camera.fy() * depth_mm,
                )
            }
        };
        let (tilt_deg, pan_deg, roll_deg) = match self.orientation {
            Orientation::Angles {
                tilt_deg,
                pan_deg,
                roll_deg,
            } => (tilt_deg.at(u[3]), pan_deg.at(u[4]), roll_deg.at(u[5])),
            Orientation::ViewCone {
                half_angle_deg,
                roll_deg,
            } => {
                let (theta, phi) = in_cone(half_angle_deg, u[3], u[4]);
                let roll = roll_deg.at(u[5]).to_radians();
                let sight = Vector3::new(offset_x_mm, offset_y_mm, depth_mm);
                let to_sight = Rotation3::rotation_between(&Vector3::z(), &sight)
                    .unwrap_or_else(Rotation3::identity);
                let z = Vector3::z_axis();
                let azimuth = Rotation3::from_axis_angle(&z, phi);
                let rotation = to_sight
                    * Rotation3::from_axis_angle(&z, roll)
                    * azimuth
                    * Rotation3::from_axis_angle(&Unit::new_unchecked(Vector3::x()), theta)
                    * azimuth.inverse();
                // R = Rz(roll) · Ry(pan) · Rx(tilt): nalgebra's (roll,
                // pitch, yaw) are our (tilt, pan, roll).
                let (tilt, pan, roll) = rotation.euler_angles();
                (tilt.to_degrees(), pan.to_degrees(), roll.to_degrees())
            }
        };
        Scenario {
            index,
            depth_mm,
            offset_x_mm,
            offset_y_mm,
            tilt_deg,
            pan_deg,
            roll_deg,
            sigma_px: self.sigma_px.at(u[6]),
        }
    }
}

/// A direction uniform over the solid angle of a cone of half-angle
/// `half_angle_deg` about z: its polar angle and azimuth, radians.
fn in_cone(half_angle_deg: f64, u_polar: f64, u_azimuth: f64) -> (f64, f64) {
    let cos_max = half_angle_deg.to_radians().cos();
    let cos_theta = 1.0 - u_polar * (1.0 - cos_max);
    (
        cos_theta.clamp(-1.0, 1.0).acos(),
        std::f64::consts::TAU * u_azimuth,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn volume(orientation: Orientation, samples: usize) -> SampledVolume {
        SampledVolume {
            depth_mm: Interval::new(200.0, 1000.0),
            placement: Placement::Offsets {
                x_mm: Interval::new(0.0, 100.0),
                y_mm: Interval::new(-50.0, 50.0),
            },
            orientation,
            sigma_px: Interval::new(0.2, 1.0),
            samples,
            seed: 3,
        }
    }

    fn angles() -> Orientation {
        Orientation::Angles {
            tilt_deg: Interval::new(-60.0, 60.0),
            pan_deg: Interval::new(-20.0, 20.0),
            roll_deg: Interval::new(-30.0, 30.0),
        }
    }

    /// A viewpoint's unit-cube point maps back onto it, for a sampled
    /// volume (both orientation forms) and for a grid, whose axes span
    /// from their smallest to their largest value whatever their order.
    #[test]
    fn unit_points_map_back_onto_the_viewpoints() {
        let camera = Camera::paper();
        let cone = Orientation::ViewCone {
            half_angle_deg: 50.0,
            roll_deg: Interval::new(-10.0, 10.0),
        };
        let grid = ScenarioGrid::new(
            "300,900".parse().unwrap(),
            "0".parse().unwrap(),
            "40,-20".parse().unwrap(),
            "-30..30:15".parse().unwrap(),
            "5".parse().unwrap(),
            "0,10".parse().unwrap(),
            "0.5".parse().unwrap(),
        )
        .unwrap();
        for volume in [
            WorkingVolume::Sampled(volume(angles(), 64)),
            WorkingVolume::Sampled(volume(cone, 64)),
            WorkingVolume::Grid(grid),
        ] {
            let scenarios = volume.scenarios(&camera);
            let units = volume.unit_points();
            assert_eq!(units.len(), scenarios.len());
            for (s, u) in scenarios.iter().zip(&units) {
                assert!(u.iter().all(|v| (0.0..=1.0).contains(v)), "{u:?}");
                let back = volume.scenario_at(s.index, &camera, *u);
                for axis in AXES {
                    assert_relative_eq!(
                        axis_value(&back, axis),
                        axis_value(s, axis),
                        epsilon = 1e-9
                    );
                }
            }
        }
    }

    /// Uniform in a box: the means and variances of the seven coordinates
    /// match the uniform distribution's to within what 1024 Sobol points
    /// allow, and each axis's bins hold 1/8 of the points each within a
    /// few points (a stratification a pseudo-random draw would not keep).
    #[test]
    fn samples_are_uniform_in_the_box() {
        let v = volume(angles(), 1024);
        let scenarios = v.scenarios(&Camera::paper());
        let n = scenarios.len() as f64;
        let boxes = [
            ("depth", 200.0, 1000.0),
            ("offset-x", 0.0, 100.0),
            ("offset-y", -50.0, 50.0),
            ("tilt", -60.0, 60.0),
            ("pan", -20.0, 20.0),
            ("roll", -30.0, 30.0),
            ("noise", 0.2, 1.0),
        ];
        for (axis, low, high) in boxes {
            let values: Vec<f64> = scenarios.iter().map(|s| axis_value(s, axis)).collect();
            let width = high - low;
            let mean = values.iter().sum::<f64>() / n;
            let variance = values.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
            assert_relative_eq!(mean, 0.5 * (low + high), epsilon = 0.005 * width);
            assert_relative_eq!(
                variance,
                width * width / 12.0,
                epsilon = 0.005 * width * width
            );
            let bins = WorkingVolume::Sampled(v)
                .axes(&scenarios)
                .into_iter()
                .find(|a| a.name == axis)
                .unwrap();
            let mut counts = vec![0usize; AXIS_BINS];
            for s in &scenarios {
                counts[bins.bin(s).unwrap()] += 1;
            }
            for count in counts {
                assert!((count as i64 - 128).abs() <= 2, "{axis}: {count}");
            }
        }
    }

    /// Uniform over the view cone's solid angle: cos θ of the face axis
    /// against the line of sight is uniform on [cos α, 1], so its mean is
    /// (1 + cos α)/2 and no sample lies outside the cone.
    #[test]
    fn view_cone_samples_are_uniform_over_the_solid_angle() {
        let half_angle_deg: f64 = 60.0;
        let v = volume(
            Orientation::ViewCone {
                half_angle_deg,
                roll_deg: Interval::new(-180.0, 180.0),
            },
            1024,
        );
        let cosines: Vec<f64> = v
            .scenarios(&Camera::paper())
            .iter()
            .map(|s| {
                let pose = s.pose();
                let face = pose.rotation * -Vector3::z();
                let to_camera = -pose.translation.normalize();
                face.dot(&to_camera)
            })
            .collect();
        let cos_max = half_angle_deg.to_radians().cos();
        assert!(cosines.iter().all(|&c| c >= cos_max - 1e-9));
        let mean = cosines.iter().sum::<f64>() / cosines.len() as f64;
        assert_relative_eq!(mean, 0.5 * (1.0 + cos_max), epsilon = 0.002);
        // Half the solid angle lies below the median cos θ = (1 + cos α)/2.
        let below = cosines
            .iter()
            .filter(|&&c| c < 0.5 * (1.0 + cos_max))
            .count();
        assert!((below as i64 - 512).abs() <= 8, "{below}");
    }

    #[test]
    fn the_same_seed_gives_the_same_samples_and_another_seed_others() {
        let v = volume(angles(), 16);
        let camera = Camera::paper();
        assert_eq!(v.scenarios(&camera), v.scenarios(&camera));
        let held = WorkingVolume::Sampled(v).held_out(|g| g.clone());
        let other = held.scenarios(&camera);
        assert_eq!(other.len(), 16);
        assert!(v
            .scenarios(&camera)
            .iter()
            .zip(&other)
            .all(|(a, b)| a.depth_mm != b.depth_mm));
    }

    #[test]
    fn image_placement_keeps_the_ball_in_the_image() {
        let mut v = volume(angles(), 256);
        v.placement = Placement::InImage {
            marker_radius_mm: 60.0,
        };
        // From 600 mm the ball's image (≤ 130 px in radius) fits the
        // 1280 × 720 image.
        v.depth_mm = Interval::new(600.0, 1000.0);
        let camera = Camera::paper();
        for s in v.scenarios(&camera) {
            let centre = camera
                .project(&Vector3::new(s.offset_x_mm, s.offset_y_mm, s.depth_mm))
                .unwrap();
            let radius_px = 0.5 * (camera.fx() + camera.fy()) * 60.0 / s.depth_mm;
            assert!(camera.contains(&centre, radius_px + VISIBILITY_MARGIN_PX - 1e-6));
        }
    }

    #[test]
    fn each_bad_volume_is_named_by_its_field() {
        type Spoil = fn(&mut SampledVolume);
        let cases: [(&str, &str, Spoil); 7] = [
            ("samples", "is 0", |v| v.samples = 0),
            ("depth", "inverted range 1000..200", |v| {
                v.depth_mm = Interval::new(1000.0, 200.0)
            }),
            ("depth", "must be positive", |v| {
                v.depth_mm = Interval::new(0.0, 200.0)
            }),
            ("view_cone", "at most 90°, got 95°", |v| {
                v.orientation = Orientation::ViewCone {
                    half_angle_deg: 95.0,
                    roll_deg: Interval::point(0.0),
                }
            }),
            ("placement_cone", "below 90°", |v| {
                v.placement = Placement::Cone {
                    half_angle_deg: 90.0,
                }
            }),
            ("offset_y", "inverted", |v| {
                v.placement = Placement::Offsets {
                    x_mm: Interval::point(0.0),
                    y_mm: Interval::new(5.0, -5.0),
                }
            }),
            ("sigma_px", "non-negative", |v| {
                v.sigma_px = Interval::new(-1.0, 1.0)
            }),
        ];
        for (field, words, spoil) in cases {
            let mut v = volume(angles(), 16);
            spoil(&mut v);
            let error = WorkingVolume::Sampled(v).check().unwrap_err();
            assert_eq!(error.field, field, "{error}");
            assert!(error.to_string().contains(words), "{error}");
        }
        assert!(WorkingVolume::Sampled(volume(angles(), 16)).check().is_ok());
    }

    #[test]
    fn a_volume_that_never_sees_the_marker_is_refused() {
        let mut v = volume(angles(), 32);
        v.placement = Placement::Offsets {
            x_mm: Interval::new(5000.0, 6000.0),
            y_mm: Interval::point(0.0),
        };
        let object = crate::synthetic::biprism_points(50.0);
        let error = WorkingVolume::Sampled(v)
            .check_seen(&Camera::paper(), &object, 10.0, "the paper's biprism")
            .unwrap_err();
        assert_eq!(error.field, "volume");
        assert!(error.to_string().contains("no viewpoint"), "{error}");
        // Spheres that hide each other are in view: head on, the biprism's
        // P3 hides O0 and P1, and the volume stands.
        let head_on = WorkingVolume::Grid(
            ScenarioGrid::new(
                Range::single(500.0),
                Range::single(0.0),
                Range::single(0.0),
                Range::single(0.0),
                Range::single(0.0),
                Range::single(0.0),
                Range::single(0.5),
            )
            .unwrap(),
        );
        assert!(head_on
            .check_seen(&Camera::paper(), &object, 10.0, "the paper's biprism")
            .is_ok());
        assert!(WorkingVolume::Sampled(volume(angles(), 32))
            .check_seen(&Camera::paper(), &object, 10.0, "the paper's biprism")
            .is_ok());
    }
}
