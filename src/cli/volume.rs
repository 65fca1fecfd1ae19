//! The working-volume flags of `search` and `validate`, and how they
//! combine with the grid flags (docs/commands.md, "The working volume").

use super::common::{naming_file, GridArgs};
use clap::Args;
use layout_opt::config::ConfigError;
use layout_opt::scenario::{Range, ScenarioGrid};
use layout_opt::volume::{Interval, Orientation, Placement, SampledVolume, WorkingVolume};
use std::path::PathBuf;

/// How many viewpoints: `N` scrambled Sobol samples, or `grid`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Samples {
    /// The product of the range flags (today's grid).
    Grid,
    /// This many scrambled Sobol samples.
    Sobol(usize),
}

impl std::str::FromStr for Samples {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text.trim() {
            "grid" => Ok(Samples::Grid),
            count => count
                .parse()
                .map(Samples::Sobol)
                .map_err(|_| format!("'{text}' is neither a sample count nor `grid`")),
        }
    }
}

/// The working volume beyond the grid's ranges.
#[derive(Debug, Clone, Args)]
pub struct VolumeArgs {
    /// Viewpoints: N scrambled Sobol samples of the volume (seeded by
    /// --seed; each range flag then gives an interval, its first to its last
    /// value), or `grid` (the product of the range flags). Default: the
    /// command's default volume; with range flags alone, the grid.
    #[arg(long, value_name = "N|grid")]
    pub samples: Option<Samples>,
    /// Orientation as a cone: the largest angle, degrees (0–90), between
    /// the marker's face axis (its −z) and the line of sight, uniform over
    /// the cone's solid angle, with --roll about the line of sight.
    /// Replaces --tilt and --pan; samples the volume.
    #[arg(long, value_name = "DEG", conflicts_with_all = ["tilt", "pan"])]
    pub view_cone: Option<f64>,
    /// Placement as a cone: the marker origin within this half-angle,
    /// degrees (0–90), of the optical axis. Replaces the offsets; samples
    /// the volume.
    #[arg(long, value_name = "DEG", conflicts_with_all = ["offset_x", "offset_y", "in_image"])]
    pub placement_cone: Option<f64>,
    /// Placement anywhere a ball of this radius (mm) about the marker origin
    /// is wholly in the image. Replaces the offsets; samples the volume.
    #[arg(long, value_name = "MM", conflicts_with_all = ["offset_x", "offset_y"])]
    pub in_image: Option<f64>,
    /// The working volume from a JSON or YAML file (docs/formats.md); only
    /// --samples N may change it.
    #[arg(long, value_name = "FILE", conflicts_with_all = [
        "depth", "offset_x", "offset_y", "tilt", "pan", "roll", "noise",
        "view_cone", "placement_cone", "in_image",
    ])]
    pub volume: Option<PathBuf>,
}

/// A command's defaults: the grid of range flags alone, and the volume
/// of no flags at all.
pub struct VolumeDefaults {
    /// Missing ranges of a grid come from here.
    pub grid: ScenarioGrid,
    /// The volume without flags.
    pub volume: WorkingVolume,
}

impl VolumeArgs {
    /// The volume these flags and `grid` give, with `seed` scrambling
    /// samples. Checked by the library's config check, not here.
    pub fn volume(
        &self,
        grid: &GridArgs,
        defaults: VolumeDefaults,
        seed: u64,
    ) -> anyhow::Result<WorkingVolume> {
        let shaped =
            self.view_cone.is_some() || self.placement_cone.is_some() || self.in_image.is_some();
        if let Some(path) = &self.volume {
            anyhow::ensure!(
                self.samples != Some(Samples::Grid),
                "--samples grid cannot sample --volume {}: a volume file is sampled",
                path.display()
            );
            let volume = naming_file(WorkingVolume::load(path, seed), "volume", path)?;
            return Ok(match (volume, self.samples) {
                (WorkingVolume::Sampled(v), Some(Samples::Sobol(samples))) => {
                    WorkingVolume::Sampled(SampledVolume { samples, ..v })
                }
                (volume, _) => volume,
            });
        }
        let samples = match self.samples {
            Some(Samples::Grid) => {
                anyhow::ensure!(
                    !shaped,
                    "--samples grid takes the range flags alone: --view-cone, --placement-cone and --in-image sample the volume"
                );
                return Ok(WorkingVolume::Grid(grid.grid(&defaults.grid)?));
            }
            Some(Samples::Sobol(samples)) => Some(samples),
            None if shaped => None,
            None if grid.any_given() => return Ok(WorkingVolume::Grid(grid.grid(&defaults.grid)?)),
            None => match defaults.volume {
                WorkingVolume::Sampled(volume) => {
                    return Ok(WorkingVolume::Sampled(SampledVolume { seed, ..volume }))
                }
                grid_default => return Ok(grid_default),
            },
        };
        let base = match defaults.volume {
            WorkingVolume::Sampled(volume) => volume,
            WorkingVolume::Grid(_) => sampled_extent(&defaults.grid),
        };
        let interval = |given: &Option<Range>, default: Interval| {
            given.as_ref().map_or(default, Interval::of_range)
        };
        let placement = match (self.placement_cone, self.in_image, base.placement) {
            (Some(half_angle_deg), _, _) => Placement::Cone { half_angle_deg },
            (None, Some(marker_radius_mm), _) => Placement::InImage { marker_radius_mm },
            (None, None, Placement::Offsets { x_mm, y_mm }) => Placement::Offsets {
                x_mm: interval(&grid.offset_x, x_mm),
                y_mm: interval(&grid.offset_y, y_mm),
            },
            (None, None, other) => other,
        };
        let base_roll = match base.orientation {
            Orientation::Angles { roll_deg, .. } | Orientation::ViewCone { roll_deg, .. } => {
                roll_deg
            }
        };
        let orientation = match (self.view_cone, base.orientation) {
            (Some(half_angle_deg), _) => Orientation::ViewCone {
                half_angle_deg,
                roll_deg: interval(&grid.roll, base_roll),
            },
            (
                None,
                Orientation::Angles {
                    tilt_deg, pan_deg, ..
                },
            ) => Orientation::Angles {
                tilt_deg: interval(&grid.tilt, tilt_deg),
                pan_deg: interval(&grid.pan, pan_deg),
                roll_deg: interval(&grid.roll, base_roll),
            },
            (None, Orientation::ViewCone { half_angle_deg, .. }) => Orientation::ViewCone {
                half_angle_deg,
                roll_deg: interval(&grid.roll, base_roll),
            },
        };
        Ok(WorkingVolume::Sampled(SampledVolume {
            depth_mm: interval(&grid.depth, base.depth_mm),
            placement,
            orientation,
            sigma_px: interval(&grid.noise, base.sigma_px),
            samples: samples.unwrap_or(base.samples),
            seed,
        }))
    }
}

/// The box a grid spans, as a sampled volume of the default size.
fn sampled_extent(grid: &ScenarioGrid) -> SampledVolume {
    let span = Interval::spanned;
    SampledVolume {
        depth_mm: span(&grid.depth_mm),
        placement: Placement::Offsets {
            x_mm: span(&grid.offset_x_mm),
            y_mm: span(&grid.offset_y_mm),
        },
        orientation: Orientation::Angles {
            tilt_deg: span(&grid.tilt_deg),
            pan_deg: span(&grid.pan_deg),
            roll_deg: span(&grid.roll_deg),
        },
        sigma_px: span(&grid.sigma_px),
        samples: layout_opt::volume::DEFAULT_SAMPLES,
        seed: 0,
    }
}

/// The flag of a volume field named in a [`ConfigError`], if it is one.
pub fn volume_flag(error: &ConfigError) -> Option<&'static str> {
    Some(match error.field {
        "samples" => "--samples",
        "depth" => "--depth",
        "offset_x" => "--offset-x",
        "offset_y" => "--offset-y",
        "tilt" => "--tilt",
        "pan" => "--pan",
        "roll" => "--roll",
        "sigma_px" => "--noise",
        "view_cone" => "--view-cone",
        "placement_cone" => "--placement-cone",
        "in_image" => "--in-image",
        "volume" => "the working volume:",
        _ => return None,
    })
}
