//! `render SET.json --poses SCENES.json`: frames of several markers, each
//! part at its own pose and each hiding what lies behind it of the others,
//! supports included. Every frame's record gives, per marker, its pose and
//! per sphere the exact ellipse and what hides how much of it, naming the
//! markers ([`super::truth::part_truth`]). The run is [`super::workflow`]'s:
//! every frame checked before any file exists, frames rendered in
//! parallel, the whole set renamed into place or nothing.

use super::analysis::{render_parts, scene_blur_px, Placed};
use super::config::RenderConfig;
use super::scene::Scene;
use super::truth::{part_truth, FrameTruth};
use super::workflow::{
    check_in_front, file_names, frame_names, open_frame_outputs, stage_images, write_frames,
    PHASE_CHECK,
};
use super::RenderError;
use crate::camera::Camera;
use crate::kernel::Outputs;
use crate::layout::Layout;
use crate::mesh::{file_stem, Marker, MarkerOptions};
use crate::observer::{watch, Observer};
use crate::pose::Pose;
use crate::scenario::Scenario;
use rayon::prelude::*;
use serde::Serialize;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

/// Everything a run of scenes needs.
#[derive(Debug, Clone)]
pub struct ScenesJob {
    /// The name the files take (the set's).
    pub name: String,
    /// The markers, each with how `export` builds its part; a frame names
    /// them by their place here.
    pub markers: Vec<(Layout, MarkerOptions)>,
    /// Each frame's markers: (index into `markers`, marker → camera).
    pub frames: Vec<Vec<(usize, Pose)>>,
    /// Each frame's scenario-grid point, when the scenario flags placed its
    /// moving marker ([`scenario_frames`]); empty otherwise.
    pub scenarios: Vec<Scenario>,
    /// Appearance, optics, sensor, seed.
    pub config: RenderConfig,
    /// Directory the images go into (created if missing).
    pub out_dir: PathBuf,
    /// The files the job was read from, each with the argument that named
    /// it: no output may be one of them.
    pub sources: Vec<(String, PathBuf)>,
}

/// What a frame shows of one marker.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarkerTruth {
    /// The marker's number in the set (from 1).
    pub marker: usize,
    /// Its layout's name.
    pub layout: String,
    /// Its pose and spheres.
    #[serde(flatten)]
    pub truth: FrameTruth,
}

/// A marker held still in every frame of a scenario grid: `N:X,Y,Z` or
/// `N:X,Y,Z:TILT,PAN,ROLL` (its number in the set; its origin in the
/// camera frame, mm; its turn in degrees, as a scenario's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedMarker {
    /// Index in the set (from 0).
    pub marker: usize,
    /// Marker → camera.
    pub pose: Pose,
}

impl std::str::FromStr for FixedMarker {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        let usage = || {
            format!("{text:?}: give N:X,Y,Z or N:X,Y,Z:TILT,PAN,ROLL (the marker's number, its origin in mm, its turn in degrees)")
        };
        let mut parts = text.split(':');
        let marker: usize = parts
            .next()
            .and_then(|n| n.trim().parse().ok())
            .filter(|&n| n > 0)
            .ok_or_else(usage)?;
        let numbers = |part: Option<&str>| -> Result<Vec<f64>, String> {
            let values: Option<Vec<f64>> = part
                .ok_or_else(usage)?
                .split(',')
                .map(|v| v.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
                .collect();
            values.filter(|v| v.len() == 3).ok_or_else(usage)
        };
        let at = numbers(parts.next())?;
        let turn = match parts.next() {
            Some(turn) => numbers(Some(turn))?,
            None => vec![0.0; 3],
        };
        if parts.next().is_some() {
            return Err(usage());
        }
        let pose = Scenario {
            index: 0,
            depth_mm: at[2],
            offset_x_mm: at[0],
            offset_y_mm: at[1],
            tilt_deg: turn[0],
            pan_deg: turn[1],
            roll_deg: turn[2],
            sigma_px: 0.0,
        }
        .pose();
        Ok(FixedMarker {
            marker: marker - 1,
            pose,
        })
    }
}

/// The frames of a scenario grid for a set of `markers` markers: marker
/// `moving` (index from 0) at each scenario's pose, the `fixed` ones where
/// they stand; each marker at most once.
pub fn scenario_frames(
    markers: usize,
    moving: usize,
    scenarios: &[Scenario],
    fixed: &[FixedMarker],
) -> Result<Vec<Vec<(usize, Pose)>>, RenderError> {
    let mut placed = vec![moving];
    for f in fixed {
        if placed.contains(&f.marker) {
            return Err(RenderError::Poses(format!(
                "marker {} is placed twice (the moving marker is {})",
                f.marker + 1,
                moving + 1
            )));
        }
        placed.push(f.marker);
    }
    if let Some(&out) = placed.iter().find(|&&m| m >= markers) {
        return Err(RenderError::Poses(format!(
            "marker {}: the set's markers are numbered 1 to {markers}",
            out + 1
        )));
    }
    Ok(scenarios
        .iter()
        .map(|scenario| {
            std::iter::once((moving, scenario.pose()))
                .chain(fixed.iter().map(|f| (f.marker, f.pose)))
                .collect()
        })
        .collect())
}

/// The files of one frame.
#[derive(Debug, Clone, Serialize)]
pub struct SceneFrameFiles {
    /// Frame index.
    pub frame: usize,
    /// Its PNG images, one per noise realisation.
    pub images: Vec<PathBuf>,
    /// Its JSON record.
    pub record: PathBuf,
    /// Each marker it shows, in the scenes file's order.
    pub markers: Vec<MarkerTruth>,
}

/// What a run wrote.
#[derive(Debug, Clone, Serialize)]
pub struct ScenesReport {
    /// The set's name.
    pub name: String,
    /// Every frame, in order.
    pub frames: Vec<SceneFrameFiles>,
    /// Wall time of the run, seconds.
    pub seconds: f64,
}

/// The per-frame JSON record (docs/formats.md, "Render scene record").
#[derive(Serialize)]
struct SceneRecord<'a> {
    frame: usize,
    set: &'a str,
    images: Vec<String>,
    width: u32,
    height: u32,
    bit_depth: u8,
    markers: &'a [MarkerTruth],
    scenario: Option<&'a Scenario>,
    blur_sigma_px: f64,
    seed: u64,
    camera: &'a Camera,
    appearance: &'a super::config::Appearance,
    optics: &'a super::config::Optics,
    sensor: &'a super::config::Sensor,
}

/// A frame checked: what it shows of each marker, and its blur (px, σ).
type CheckedFrame = (Vec<MarkerTruth>, f64);

/// Checks the job and computes every frame's truth (reported as
/// [`PHASE_CHECK`]): a marker behind the camera, a frame whose markers
/// all lie outside the image, or a defocus in a frame of several markers
/// is an error here, before any file is written.
fn check(
    job: &ScenesJob,
    scenes: &[Scene],
    observer: &mut impl Observer,
) -> Result<Vec<CheckedFrame>, RenderError> {
    let camera = &job.config.camera;
    let stop = AtomicBool::new(false);
    let done = AtomicU64::new(0);
    let names: Vec<Vec<String>> = job
        .markers
        .iter()
        .map(|(layout, _)| layout.points.iter().map(|p| p.name.clone()).collect())
        .collect();
    let check_frame = |frame: usize, placed: &[(usize, Pose)]| {
        if stop.load(Ordering::Relaxed) {
            return Err(RenderError::Interrupted);
        }
        let parts: Vec<Placed> = placed
            .iter()
            .map(|(marker, pose)| Placed {
                scene: &scenes[*marker],
                pose,
            })
            .collect();
        let blur_px = scene_blur_px(&job.config, &parts).map_err(|e| e.in_frame(frame))?;
        let mut truths = Vec::with_capacity(parts.len());
        for (k, (marker, pose)) in placed.iter().enumerate() {
            check_in_front(&scenes[*marker], pose, frame)?;
            let truth =
                part_truth(&parts, k, &names[*marker], camera).map_err(|e| e.in_frame(frame))?;
            let mut truth = MarkerTruth {
                marker: marker + 1,
                layout: job.markers[*marker].0.name.clone(),
                truth,
            };
            // The truth numbers the hiding parts by their place in the
            // frame: name them by their markers' numbers.
            for sphere in &mut truth.truth.spheres {
                for by in &mut sphere.hidden_by_markers {
                    by.marker = placed[by.marker - 1].0 + 1;
                }
            }
            truths.push(truth);
        }
        let all_outside = truths
            .iter()
            .flat_map(|t| &t.truth.spheres)
            .all(|s| s.hidden.outside_image >= 1.0);
        if all_outside {
            let t = placed[0].1.translation;
            return Err(RenderError::OutsideImage {
                frame,
                x: t.x,
                y: t.y,
                z: t.z,
            });
        }
        done.fetch_add(1, Ordering::Relaxed);
        Ok((truths, blur_px))
    };
    watch(
        observer,
        PHASE_CHECK,
        job.frames.len() as u64,
        || done.load(Ordering::Relaxed),
        Some(&stop),
        || {
            job.frames
                .par_iter()
                .enumerate()
                .map(|(frame, placed)| check_frame(frame, placed))
                .collect::<Result<Vec<_>, _>>()
        },
    )
}

/// Runs the job (module docs). An observer that asks to stop gets
/// [`RenderError::Interrupted`], and no file of the run is left.
pub fn run_scenes(
    job: &ScenesJob,
    observer: &mut impl Observer,
) -> Result<ScenesReport, RenderError> {
    let start = Instant::now();
    if observer.interrupted() {
        return Err(RenderError::Interrupted);
    }
    job.config.validate()?;
    if job.frames.is_empty() {
        return Err(RenderError::NoPoses);
    }
    if let Some((frame, (marker, _))) = job.frames.iter().enumerate().find_map(|(k, f)| {
        f.iter()
            .find(|(marker, _)| *marker >= job.markers.len())
            .map(|m| (k, m))
    }) {
        return Err(RenderError::Poses(format!(
            "frame {frame}: marker {} is not one of the {} markers",
            marker + 1,
            job.markers.len()
        )));
    }
    let scenes = job
        .markers
        .iter()
        .map(|(layout, options)| Ok(Scene::from_marker(Marker::design(layout, options)?)))
        .collect::<Result<Vec<Scene>, RenderError>>()?;
    let checked = check(job, &scenes, observer)?;
    let stem = file_stem(&job.name);
    let config = &job.config;
    let files = open_frame_outputs(
        &job.sources,
        &job.out_dir,
        &stem,
        job.frames.len(),
        config.realisations,
    )?;
    let write_frame = |frame: usize, files: &Outputs| -> Result<SceneFrameFiles, RenderError> {
        let parts: Vec<Placed> = job.frames[frame]
            .iter()
            .map(|(marker, pose)| Placed {
                scene: &scenes[*marker],
                pose,
            })
            .collect();
        let (truths, blur_sigma_px) = &checked[frame];
        let radiance =
            render_parts(&parts, *blur_sigma_px, config, None).map_err(|e| e.in_frame(frame))?;
        let (names, record_name) = frame_names(&stem, frame, config.realisations);
        let images = stage_images(&radiance, config, files, &job.out_dir, names, frame)?;
        let record = SceneRecord {
            frame,
            set: &job.name,
            images: file_names(&images),
            width: config.camera.width(),
            height: config.camera.height(),
            bit_depth: config.sensor.bit_depth,
            markers: truths,
            scenario: job.scenarios.get(frame),
            blur_sigma_px: *blur_sigma_px,
            seed: config.seed,
            camera: &config.camera,
            appearance: &config.appearance,
            optics: &config.optics,
            sensor: &config.sensor,
        };
        let record_path = job.out_dir.join(record_name);
        let text = serde_json::to_string_pretty(&record).expect("a record serialises") + "\n";
        files.stage(&record_path, text.as_bytes())?;
        Ok(SceneFrameFiles {
            frame,
            images,
            record: record_path,
            markers: truths.clone(),
        })
    };
    let frames = write_frames(observer, files, job.frames.len(), write_frame)?;
    Ok(ScenesReport {
        name: job.name.clone(),
        frames,
        seconds: start.elapsed().as_secs_f64(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fixed_marker_reads_its_number_place_and_turn() {
        let fixed: FixedMarker = "2:10,-20,600:0,30,0".parse().unwrap();
        assert_eq!(fixed.marker, 1);
        assert_eq!(
            fixed.pose.translation,
            nalgebra::Vector3::new(10.0, -20.0, 600.0)
        );
        let turned = fixed.pose.rotation * nalgebra::Vector3::z();
        assert!((turned.z - 30f64.to_radians().cos()).abs() < 1e-12);
        let still: FixedMarker = "1:0,0,500".parse().unwrap();
        assert_eq!(still.pose.rotation, nalgebra::Rotation3::identity());
        for bad in [
            "0:0,0,500",
            "x:0,0,500",
            "1:0,0",
            "1:0,0,500:1,2",
            "1:0,0,inf",
            "1:0,0,1:0,0,0:9",
        ] {
            assert!(bad.parse::<FixedMarker>().is_err(), "{bad}");
        }
    }

    #[test]
    fn scenario_frames_move_one_marker_and_hold_the_others() {
        let scenarios: Vec<Scenario> = [400.0, 800.0]
            .iter()
            .enumerate()
            .map(|(index, &depth_mm)| Scenario {
                index,
                depth_mm,
                offset_x_mm: 0.0,
                offset_y_mm: 0.0,
                tilt_deg: 10.0,
                pan_deg: 0.0,
                roll_deg: 0.0,
                sigma_px: 0.5,
            })
            .collect();
        let fixed: FixedMarker = "3:100,0,700".parse().unwrap();
        let frames = scenario_frames(3, 1, &scenarios, &[fixed]).unwrap();
        assert_eq!(frames.len(), 2);
        assert_eq!(frames[1][0].0, 1);
        assert_eq!(frames[1][0].1.translation.z, 800.0);
        assert_eq!(frames[1][1], (2, fixed.pose));
        let twice = scenario_frames(3, 2, &scenarios, &[fixed]).unwrap_err();
        assert!(twice.to_string().contains("placed twice"), "{twice}");
        let beyond = scenario_frames(2, 0, &scenarios, &[fixed]).unwrap_err();
        assert!(beyond.to_string().contains("numbered 1 to 2"), "{beyond}");
    }
}
