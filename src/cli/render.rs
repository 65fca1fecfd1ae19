//! `layout-opt render`: grey PNG images of the part `export` builds, with
//! the ground truth of each frame beside it.

use super::common::{naming_file, CameraArgs, GridArgs, StructureArgs};
use super::export_set::is_set_file;
use super::look::{flag, LookArgs};
use super::render_scenes::Placing;
use super::{progress, GlobalOptions};
use anyhow::Context;
use clap::Args;
use layout_opt::layout::Layout;
use layout_opt::mesh::routed_as_recorded;
use layout_opt::render::scenes::FixedMarker;
use layout_opt::render::workflow::{self, FramePose, RenderJob};
use layout_opt::render::{poses_from_json, Noise, RenderConfig, RenderError, Sensor};
use layout_opt::scenario::{Range, ScenarioGrid};
use std::path::PathBuf;

/// Flags of `render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Layout file (JSON), or a set file (layout-opt-set) with --poses
    /// SCENES.json: frames of several markers. Without it, the paper's
    /// biprism.
    #[arg(value_name = "LAYOUT")]
    layout: Option<PathBuf>,
    /// Output directory (created if missing).
    #[arg(long, value_name = "DIR", default_value = "render")]
    out: PathBuf,
    #[command(flatten)]
    camera: CameraArgs,
    /// Scenario flags as in validate; without them and without --poses:
    /// depths 200, 600, 1000 mm, head on and tilted 40°.
    #[command(flatten)]
    grid: GridArgs,
    /// Poses file: a JSON array of {"R": [[..],[..],[..]], "t": [x, y, z]}
    /// (marker → camera, mm), instead of the scenario flags. With a set:
    /// an array of frames, each an array of {"marker": N, "R": …, "t": …},
    /// N the marker's number in the set.
    #[arg(long, value_name = "FILE")]
    poses: Option<PathBuf>,
    /// With a set and the scenario flags: the marker the scenarios move
    /// (its number in the set).
    #[arg(long, value_name = "N", default_value_t = 1)]
    moving: usize,
    /// With a set and the scenario flags: a marker held still in every
    /// frame, N:X,Y,Z (its number; its origin in the camera frame, mm) or
    /// N:X,Y,Z:TILT,PAN,ROLL (degrees, as the scenario flags turn). Repeat
    /// for more markers.
    #[arg(long, value_name = "N:X,Y,Z[:TILT,PAN,ROLL]")]
    fixed: Vec<FixedMarker>,
    #[command(flatten)]
    structure: StructureArgs,
    #[command(flatten)]
    look: LookArgs,
    /// Bits per pixel: 8 or 16.
    #[arg(long, value_name = "BITS", default_value_t = 8)]
    bit_depth: u8,
    /// Electrons at full scale (shot noise).
    #[arg(long, value_name = "E", default_value_t = 10_000.0)]
    full_well: f64,
    /// Read noise, electrons RMS.
    #[arg(long, value_name = "E", default_value_t = 10.0)]
    read_noise: f64,
    /// No sensor noise (quantisation only).
    #[arg(long)]
    no_noise: bool,
    /// Noisy images per pose (all from one noise-free render).
    #[arg(long, value_name = "N", default_value_t = 1)]
    realisations: u32,
}

pub(super) fn config(args: &RenderArgs, global: &GlobalOptions) -> anyhow::Result<RenderConfig> {
    let config = RenderConfig {
        camera: args.camera.camera()?,
        appearance: args.look.appearance(),
        optics: args.look.render_optics(),
        sensor: Sensor {
            bit_depth: args.bit_depth,
            noise: (!args.no_noise).then_some(Noise {
                full_well_electrons: args.full_well,
                read_noise_electrons: args.read_noise,
            }),
        },
        realisations: args.realisations,
        seed: global.seed,
    };
    config
        .validate()
        .map_err(|e| anyhow::anyhow!("{}: {}", flag(e.field), e.reason))?;
    Ok(config)
}

fn poses(args: &RenderArgs) -> anyhow::Result<Vec<FramePose>> {
    if let Some(path) = &args.poses {
        anyhow::ensure!(
            !args.grid.any_given(),
            "--poses replaces the scenario flags (--depth, --tilt, …); give one or the other"
        );
        let text = naming_file(std::fs::read_to_string(path), "poses file", path)?;
        let poses = naming_file(poses_from_json(&text), "poses file", path)?;
        return Ok(poses
            .into_iter()
            .map(|pose| FramePose {
                pose,
                scenario: None,
            })
            .collect());
    }
    anyhow::ensure!(
        args.grid.noise.is_none(),
        "--noise is pixel noise for validate; render takes --full-well and --read-noise"
    );
    let zero = Range::single(0.0);
    let defaults = ScenarioGrid::new(
        Range::list(&[200.0, 600.0, 1000.0]),
        zero.clone(),
        zero.clone(),
        Range::list(&[0.0, 40.0]),
        zero.clone(),
        zero.clone(),
        zero,
    )?;
    Ok(args
        .grid
        .grid(&defaults)?
        .scenarios()
        .into_iter()
        .map(|scenario| FramePose {
            pose: scenario.pose(),
            scenario: Some(scenario),
        })
        .collect())
}

pub fn run(args: RenderArgs, global: &GlobalOptions) -> anyhow::Result<()> {
    if let Some(set) = args.layout.as_deref().filter(|p| is_set_file(p)) {
        let placing = match &args.poses {
            Some(file) => {
                anyhow::ensure!(
                    !args.grid.any_given() && args.fixed.is_empty() && args.moving == 1,
                    "--poses SCENES.json places every marker; the scenario flags, --moving and --fixed place them otherwise: give one or the other"
                );
                Placing::File(file.clone())
            }
            None => {
                anyhow::ensure!(args.moving >= 1, "--moving counts the set's markers from 1");
                let scenarios = poses(&args)?
                    .into_iter()
                    .filter_map(|frame| frame.scenario)
                    .collect();
                Placing::Grid {
                    moving: args.moving - 1,
                    scenarios,
                    fixed: args.fixed.clone(),
                }
            }
        };
        let config = config(&args, global)?;
        return super::render_scenes::run(set, placing, &args.out, &args.structure, config, global);
    }
    anyhow::ensure!(
        args.fixed.is_empty() && args.moving == 1,
        "--moving and --fixed place the markers of a set: give a set file (layout-opt-set)"
    );
    let layout = match &args.layout {
        Some(path) => naming_file(Layout::load(path), "layout", path)?,
        None => Layout::paper_biprism(),
    };
    let sources = [("LAYOUT", &args.layout), ("--poses", &args.poses)]
        .into_iter()
        .filter_map(|(what, path)| Some((what.to_string(), path.clone()?)))
        .collect();
    let job = RenderJob {
        sources,
        // The part export prints (supports routed as it routes them).
        marker: routed_as_recorded(&layout, args.structure.marker_options())?,
        poses: poses(&args)?,
        config: config(&args, global)?,
        out_dir: args.out.clone(),
        layout,
    };
    let mut bars = progress::Bars::new(global.quiet);
    let result = workflow::run(&job, &mut bars);
    bars.finish();
    if let Err(RenderError::Interrupted) = result {
        let kept = "interrupted: none of the render's files were written";
        return Err(layout_opt::kernel::Interrupted::keeping(kept).into());
    }
    let report = result.with_context(|| format!("cannot render {}", job.layout.name))?;
    for frame in &report.frames {
        let names: Vec<String> = frame
            .images
            .iter()
            .map(|p| p.display().to_string())
            .collect();
        let worst = frame
            .truth
            .spheres
            .iter()
            .map(|s| (s.hidden.by_support + s.hidden.by_sphere, &s.name))
            .max_by(|a, b| a.0.total_cmp(&b.0));
        let hidden = match worst {
            Some((fraction, name)) if fraction > 0.0 => {
                format!("most hidden: {name} {:.1} %", 100.0 * fraction)
            }
            _ => "no sphere hidden".to_string(),
        };
        let t = frame.truth.translation;
        println!(
            "frame {:3}: t = ({:.0}, {:.0}, {:.0}) mm, {hidden}; wrote {} and {}",
            frame.frame,
            t[0],
            t[1],
            t[2],
            names.join(", "),
            frame.record.display()
        );
    }
    println!(
        "{} frames of {} in {:.2} s",
        report.frames.len(),
        report.name,
        report.seconds
    );
    Ok(())
}
