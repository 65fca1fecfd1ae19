//! `layout-opt render SET.json --poses SCENES.json`, or `render SET.json`
//! with the scenario flags, `--moving` and `--fixed`: frames of several
//! markers of a set, each at its own pose, hiding one another
//! ([`layout_opt::render::scenes`]).

use super::common::{naming_file, StructureArgs};
use super::{progress, GlobalOptions};
use anyhow::Context;
use layout_opt::mesh::routed_as_recorded;
use layout_opt::render::scenes::{run_scenes, scenario_frames, FixedMarker, ScenesJob};
use layout_opt::render::{scenes_from_json, RenderConfig, RenderError};
use layout_opt::scenario::Scenario;
use std::path::{Path, PathBuf};

/// How the frames place the set's markers.
pub enum Placing {
    /// A scenes file (`--poses`).
    File(PathBuf),
    /// The scenario flags move one marker (index from 0); the others stand
    /// still.
    Grid {
        moving: usize,
        scenarios: Vec<Scenario>,
        fixed: Vec<FixedMarker>,
    },
}

/// Renders the frames `placing` places the set's markers in, into `out`.
pub fn run(
    set_path: &Path,
    placing: Placing,
    out: &Path,
    structure: &StructureArgs,
    config: RenderConfig,
    global: &GlobalOptions,
) -> anyhow::Result<()> {
    let set = super::export_set::load(set_path)?;
    let mut sources = vec![("SET".to_string(), set_path.to_path_buf())];
    let (frames, scenarios) = match placing {
        Placing::File(poses) => {
            let text = naming_file(std::fs::read_to_string(&poses), "scenes file", &poses)?;
            let frames = naming_file(
                scenes_from_json(&text, set.members.len()),
                "scenes file",
                &poses,
            )?;
            sources.push(("--poses".to_string(), poses));
            (frames, Vec::new())
        }
        Placing::Grid {
            moving,
            scenarios,
            fixed,
        } => (
            scenario_frames(set.members.len(), moving, &scenarios, &fixed)?,
            scenarios,
        ),
    };
    let markers = set
        .members
        .iter()
        .map(|m| {
            // The part export prints (supports routed as it routes them).
            let options = routed_as_recorded(&m.layout, structure.marker_options())?;
            Ok((m.layout.clone(), options))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let job = ScenesJob {
        name: set.name.clone(),
        markers,
        frames,
        scenarios,
        config,
        out_dir: out.to_path_buf(),
        sources,
    };
    let mut bars = progress::Bars::new(global.quiet);
    let result = run_scenes(&job, &mut bars);
    bars.finish();
    if let Err(RenderError::Interrupted) = result {
        let kept = "interrupted: none of the render's files were written";
        return Err(layout_opt::kernel::Interrupted::keeping(kept).into());
    }
    let report = result.with_context(|| format!("cannot render the set {}", set.name))?;
    for frame in &report.frames {
        let mut hidden = Vec::new();
        for marker in &frame.markers {
            for sphere in &marker.truth.spheres {
                for by in &sphere.hidden_by_markers {
                    hidden.push(format!(
                        "marker {} hides {:.0} % of {}'s {}",
                        by.marker,
                        100.0 * by.fraction,
                        marker.marker,
                        sphere.name
                    ));
                }
            }
        }
        let shown: Vec<String> = frame
            .markers
            .iter()
            .map(|m| {
                let t = m.truth.translation;
                format!("{} at ({:.0}, {:.0}, {:.0}) mm", m.marker, t[0], t[1], t[2])
            })
            .collect();
        let hidden = match hidden.is_empty() {
            true => "no marker hides another".to_string(),
            false => hidden.join(", "),
        };
        println!(
            "frame {:3}: markers {}; {hidden}; wrote {}",
            frame.frame,
            shown.join(", "),
            frame.record.display()
        );
    }
    println!(
        "{} frames of the set {} in {:.2} s",
        report.frames.len(),
        report.name,
        report.seconds
    );
    Ok(())
}
