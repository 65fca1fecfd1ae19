//! `layout-opt track --set SET.json IMAGES...`: every marker of a set found
//! in each frame, named by its number and layout
//! ([`layout_opt::track::set`]).

use super::track_stream::{self, StreamArgs, StreamJob};
use super::{progress, GlobalOptions};
use anyhow::Context;
use layout_opt::kernel::Interrupted;
use layout_opt::layout::Layout;
use layout_opt::set::MarkerSet;
use layout_opt::track::refine::Refiner;
use layout_opt::track::set::SetTrackConfig;
use layout_opt::track::stream::SetTracker;
use layout_opt::track::workflow::{run_set, TrackOutputs, WorkflowError};
use layout_opt::track::TrackConfig;
use std::path::{Path, PathBuf};

/// Tracks the set's markers in `frames`; `configure` applies the flags to
/// one marker's layout, and `refiner` gives its refiner when --refine asks
/// for one.
pub fn run(
    set_path: &Path,
    frames: &[PathBuf],
    output: Option<&Path>,
    stream: &StreamArgs,
    global: &GlobalOptions,
    configure: &dyn Fn(&Layout) -> anyhow::Result<TrackConfig>,
    refiner: &dyn Fn(&Layout, &TrackConfig) -> anyhow::Result<Option<Refiner>>,
) -> anyhow::Result<()> {
    let set = MarkerSet::load(set_path)?;
    set.check_distinct()?;
    let markers = set
        .members
        .iter()
        .map(|m| Ok((m.layout.name.clone(), configure(&m.layout)?)))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let refiners = set
        .members
        .iter()
        .zip(&markers)
        .map(|(m, (_, config))| refiner(&m.layout, config))
        .collect::<anyhow::Result<Option<Vec<Refiner>>>>()?;
    let config = SetTrackConfig { markers, refiners };
    if let Some(input) = stream.input(frames)? {
        config.validate()?;
        let camera = &config.markers[0].1.camera;
        let job = StreamJob {
            sources: vec![("--set", set_path)],
            output,
            tracker: &SetTracker { config: &config },
            camera_size: (camera.width(), camera.height()),
            describe: format!("the set {} ({} markers)", set.name, set.members.len()),
        };
        return track_stream::run(stream, &input, job);
    }
    let outputs = TrackOutputs {
        sources: vec![("--set".into(), set_path.to_path_buf())],
        json_lines: output.map(Path::to_path_buf),
        ..Default::default()
    };
    let mut bars = progress::Bars::new(global.quiet);
    let result = run_set(&config, frames, &outputs, &mut bars);
    bars.finish();
    let run = match result {
        Ok(run) => run,
        Err(WorkflowError::Interrupted) => return Err(Interrupted::nothing_written().into()),
        Err(error) => return Err(error).context("track --set"),
    };
    let mut found = 0;
    for (name, analysis) in &run.frames {
        found += analysis.markers.len();
        if let Some(error) = analysis
            .error
            .as_deref()
            .filter(|_| analysis.markers.is_empty())
        {
            eprintln!("{name}: {error}");
        }
    }
    let summary = format!(
        "found {found} markers of the set {} ({} markers) in {} frames",
        set.name,
        set.members.len(),
        run.frames.len()
    );
    match output {
        Some(path) => eprintln!("{summary}; wrote {}", path.display()),
        None => {
            print!("{}", run.json_lines);
            eprintln!("{summary}");
        }
    }
    Ok(())
}
