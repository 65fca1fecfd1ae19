//! `layout-opt render SET.json --poses SCENES.json`: frames of several
//! markers of a set, each at its own pose, hiding one another
//! ([`layout_opt::render::scenes`]).

use super::common::{naming_file, StructureArgs};
use super::{progress, GlobalOptions};
use anyhow::Context;
use layout_opt::mesh::routed_as_recorded;
use layout_opt::render::scenes::{run_scenes, ScenesJob};
use layout_opt::render::{scenes_from_json, RenderConfig, RenderError};
use std::path::Path;

/// Renders the frames `poses` places the set's markers in, into `out`.
pub fn run(
    set_path: &Path,
    poses: &Path,
    out: &Path,
    structure: &StructureArgs,
    config: RenderConfig,
    global: &GlobalOptions,
) -> anyhow::Result<()> {
    let set = super::export_set::load(set_path)?;
    let text = naming_file(std::fs::read_to_string(poses), "scenes file", poses)?;
    let frames = naming_file(
        scenes_from_json(&text, set.members.len()),
        "scenes file",
        poses,
    )?;
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
        config,
        out_dir: out.to_path_buf(),
        sources: vec![
            ("SET".to_string(), set_path.to_path_buf()),
            ("--poses".to_string(), poses.to_path_buf()),
        ],
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
