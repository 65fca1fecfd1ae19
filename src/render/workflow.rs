//! The run of `render`, as phases over one job: [`check`] every input and
//! every pose before any file exists, stage the output directory, render
//! and write the frames in parallel (progress and interruption through the
//! [`Observer`]), then rename the whole set into place. A run that fails
//! or is interrupted part-way leaves none of its files (and removes the
//! output directory if it made it).

use super::analysis::{blur_at, render_radiance};
use super::config::RenderConfig;
use super::scene::Scene;
use super::sensor::{expose, Digital};
use super::truth::{frame_truth, FrameTruth};
use super::RenderError;
use crate::camera::Camera;
use crate::kernel::{OutputPlan, Outputs};
use crate::layout::Layout;
use crate::mesh::{file_stem, Marker, MarkerOptions};
use crate::observer::{watch, Observer};
use crate::pose::Pose;
use crate::scenario::Scenario;
use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

/// Progress phase: every frame's pose checked and its truth computed.
pub const PHASE_CHECK: &str = "check poses";
/// Progress phase: frames rendered and written.
pub const PHASE_RENDER: &str = "render";
/// The part must stay this far in front of the camera's plane, mm.
pub const MIN_DEPTH_MM: f64 = 1.0;

/// One frame to render: its pose and, when it came from a scenario grid,
/// the scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct FramePose {
    /// Marker → camera.
    pub pose: Pose,
    /// The grid scenario it came from, if any.
    pub scenario: Option<Scenario>,
}

/// Everything a render run needs.
#[derive(Debug, Clone)]
pub struct RenderJob {
    /// The layout whose part is rendered.
    pub layout: Layout,
    /// How `export` would build the part.
    pub marker: MarkerOptions,
    /// The frames.
    pub poses: Vec<FramePose>,
    /// Appearance, optics, sensor, seed.
    pub config: RenderConfig,
    /// Directory the images go into (created if missing).
    pub out_dir: PathBuf,
    /// The files the job was read from, each with the argument that named
    /// it (the layout, the poses): no output may be one of them.
    pub sources: Vec<(String, PathBuf)>,
}

/// The files of one frame.
#[derive(Debug, Clone, Serialize)]
pub struct FrameFiles {
    /// Frame index.
    pub frame: usize,
    /// Its PNG images, one per noise realisation.
    pub images: Vec<PathBuf>,
    /// Its JSON record.
    pub record: PathBuf,
    /// Its ground truth.
    pub truth: FrameTruth,
    /// The Gaussian blur applied, px.
    pub blur_sigma_px: f64,
}

/// What a run wrote.
#[derive(Debug, Clone, Serialize)]
pub struct RenderReport {
    /// The layout's name.
    pub name: String,
    /// Every frame, in order.
    pub frames: Vec<FrameFiles>,
    /// Wall time of the run, seconds.
    pub seconds: f64,
}

/// The per-frame JSON record (docs/formats.md, "Render frame record").
#[derive(Serialize)]
struct FrameRecord<'a> {
    frame: usize,
    layout: &'a str,
    images: Vec<String>,
    width: u32,
    height: u32,
    bit_depth: u8,
    #[serde(flatten)]
    truth: &'a FrameTruth,
    scenario: Option<&'a Scenario>,
    blur_sigma_px: f64,
    seed: u64,
    camera: &'a Camera,
    appearance: &'a super::config::Appearance,
    optics: &'a super::config::Optics,
    sensor: &'a super::config::Sensor,
}

/// A job checked: the scene and every frame's truth.
pub struct Checked {
    /// The part.
    pub scene: Scene,
    /// Each frame's ground truth.
    pub truths: Vec<FrameTruth>,
}

/// Checks the configuration, builds the part and the truth of every
/// frame: a pose behind the camera or a part outside the image is an
/// error here, before any file is written. The frames' truths are
/// reported as [`PHASE_CHECK`] through `observer`, which may ask to stop.
pub fn check(job: &RenderJob, observer: &mut impl Observer) -> Result<Checked, RenderError> {
    job.config.validate()?;
    if job.poses.is_empty() {
        return Err(RenderError::NoPoses);
    }
    let scene = Scene::from_marker(Marker::design(&job.layout, &job.marker)?);
    let names: Vec<String> = job.layout.points.iter().map(|p| p.name.clone()).collect();
    let camera = &job.config.camera;
    let stop = AtomicBool::new(false);
    let done = AtomicU64::new(0);
    let total = job.poses.len() as u64;
    let check_frame = |frame: usize, frame_pose: &FramePose| {
        if stop.load(Ordering::Relaxed) {
            return Err(RenderError::Interrupted);
        }
        let pose = &frame_pose.pose;
        check_in_front(&scene, pose, frame)?;
        blur_at(&job.config, pose, frame)?;
        let truth = frame_truth(&scene, &names, pose, camera).map_err(|e| e.in_frame(frame))?;
        if truth.spheres.iter().all(|s| s.hidden.outside_image >= 1.0) {
            let t = pose.translation;
            return Err(RenderError::OutsideImage {
                frame,
                x: t.x,
                y: t.y,
                z: t.z,
            });
        }
        done.fetch_add(1, Ordering::Relaxed);
        Ok(truth)
    };
    let truths = watch(
        observer,
        PHASE_CHECK,
        total,
        || done.load(Ordering::Relaxed),
        Some(&stop),
        || {
            job.poses
                .par_iter()
                .enumerate()
                .map(|(frame, frame_pose)| check_frame(frame, frame_pose))
                .collect::<Result<Vec<_>, _>>()
        },
    )?;
    Ok(Checked { scene, truths })
}

/// Refuses frame `frame` when the part at `pose` reaches within
/// [`MIN_DEPTH_MM`] of the camera's plane (its bounding box's nearest
/// corner).
pub(super) fn check_in_front(scene: &Scene, pose: &Pose, frame: usize) -> Result<(), RenderError> {
    let nearest = scene
        .bounding_corners()
        .iter()
        .map(|p| pose.transform(p).z)
        .fold(f64::INFINITY, f64::min);
    if nearest.is_nan() || nearest <= MIN_DEPTH_MM {
        return Err(RenderError::PartBehindCamera {
            frame,
            depth_mm: nearest,
        });
    }
    Ok(())
}

/// Runs the job (module docs). An observer that asks to stop gets
/// [`RenderError::Interrupted`], and no file of the run is left.
pub fn run(job: &RenderJob, observer: &mut impl Observer) -> Result<RenderReport, RenderError> {
    let start = Instant::now();
    if observer.interrupted() {
        return Err(RenderError::Interrupted);
    }
    let checked = check(job, observer)?;
    let stem = file_stem(&job.layout.name);
    let files = open_frame_outputs(
        &job.sources,
        &job.out_dir,
        &stem,
        job.poses.len(),
        job.config.realisations,
    )?;
    let frames = write_frames(observer, files, job.poses.len(), |frame, files| {
        write_frame(job, &checked, files, &stem, frame)
    })?;
    Ok(RenderReport {
        name: job.layout.name.clone(),
        frames,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Writes frames `0..count` with `write` in parallel, each staging its
/// files in `files` (progress as [`PHASE_RENDER`] through `observer`, a
/// stop answered between frames with [`RenderError::Interrupted`]), then
/// commits them all.
pub(super) fn write_frames<T: Send>(
    observer: &mut impl Observer,
    files: Outputs,
    count: usize,
    write: impl Fn(usize, &Outputs) -> Result<T, RenderError> + Sync,
) -> Result<Vec<T>, RenderError> {
    let stop = AtomicBool::new(false);
    let done = AtomicU64::new(0);
    let frames = watch(
        observer,
        PHASE_RENDER,
        count as u64,
        || done.load(Ordering::Relaxed),
        Some(&stop),
        || {
            (0..count)
                .into_par_iter()
                .map(|frame| {
                    if stop.load(Ordering::SeqCst) {
                        return Err(RenderError::Interrupted);
                    }
                    let written = write(frame, &files)?;
                    done.fetch_add(1, Ordering::Relaxed);
                    Ok(written)
                })
                .collect::<Result<Vec<_>, _>>()
        },
    )?;
    if stop.load(Ordering::SeqCst) || observer.interrupted() {
        return Err(RenderError::Interrupted);
    }
    files.commit()?;
    Ok(frames)
}

/// The names of frame `frame`'s images (one per realisation) and of its
/// record.
pub(super) fn frame_names(stem: &str, frame: usize, realisations: u32) -> (Vec<String>, String) {
    let images = (0..realisations)
        .map(|realisation| match realisations {
            1 => format!("{stem}-{frame:03}.png"),
            _ => format!("{stem}-{frame:03}-{realisation:02}.png"),
        })
        .collect();
    (images, format!("{stem}-{frame:03}.json"))
}

/// The run's outputs, checked against its sources and locked before any
/// frame is rendered ([`crate::kernel::outputs`]): the images and record
/// of each of `frames` frames in `out_dir`.
pub(super) fn open_frame_outputs(
    sources: &[(String, PathBuf)],
    out_dir: &Path,
    stem: &str,
    frames: usize,
    realisations: u32,
) -> Result<Outputs, RenderError> {
    let mut plan = OutputPlan::new();
    for (what, path) in sources {
        plan.input(what.as_str(), path);
    }
    plan.dir("--out", out_dir);
    for frame in 0..frames {
        let (images, record) = frame_names(stem, frame, realisations);
        for name in images.iter().chain([&record]) {
            plan.file_in_dir("--out", out_dir.join(name));
        }
    }
    Ok(plan.open()?)
}

/// Renders frame `frame` once, exposes every realisation, and stages its
/// PNGs and record in the output directory.
fn write_frame(
    job: &RenderJob,
    checked: &Checked,
    files: &Outputs,
    stem: &str,
    frame: usize,
) -> Result<FrameFiles, RenderError> {
    let dir = &job.out_dir;
    let (names, record_name) = frame_names(stem, frame, job.config.realisations);
    let config = &job.config;
    let pose = &job.poses[frame].pose;
    let radiance = render_radiance(&checked.scene, pose, config).map_err(|e| e.in_frame(frame))?;
    let images = stage_images(&radiance, config, files, dir, names, frame)?;
    let truth = &checked.truths[frame];
    let blur_sigma_px = config
        .optics
        .blur
        .sigma_px(config.camera.fx(), pose.translation.z);
    let record = FrameRecord {
        frame,
        layout: &job.layout.name,
        images: file_names(&images),
        width: config.camera.width(),
        height: config.camera.height(),
        bit_depth: config.sensor.bit_depth,
        truth,
        scenario: job.poses[frame].scenario.as_ref(),
        blur_sigma_px,
        seed: config.seed,
        camera: &config.camera,
        appearance: &config.appearance,
        optics: &config.optics,
        sensor: &config.sensor,
    };
    let record_path = dir.join(record_name);
    let text = serde_json::to_string_pretty(&record).expect("a record serialises") + "\n";
    files.stage(&record_path, text.as_bytes())?;
    Ok(FrameFiles {
        frame,
        images,
        record: record_path,
        truth: truth.clone(),
        blur_sigma_px,
    })
}

/// Exposes `radiance` once per realisation of frame `frame` and stages
/// each image in `dir` under its name of `names`.
pub(super) fn stage_images(
    radiance: &super::Radiance,
    config: &RenderConfig,
    files: &Outputs,
    dir: &Path,
    names: Vec<String>,
    frame: usize,
) -> Result<Vec<PathBuf>, RenderError> {
    let mut images = Vec::new();
    for (realisation, name) in (0..config.realisations).zip(names) {
        let digital = expose(
            radiance,
            &config.sensor,
            config.seed,
            frame as u64,
            u64::from(realisation),
        );
        let path = dir.join(name);
        files.stage(&path, &encode_png(&path, &digital)?)?;
        images.push(path);
    }
    Ok(images)
}

/// The file names of `paths`, for a record beside them.
pub(super) fn file_names(paths: &[PathBuf]) -> Vec<String> {
    paths
        .iter()
        .map(|p| {
            p.file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned()
        })
        .collect()
}

/// Encodes a grey PNG of the image's bit depth.
pub fn encode_png(path: &Path, image: &Digital) -> Result<Vec<u8>, RenderError> {
    let (w, h) = (image.width as u32, image.height as u32);
    let png = |source| RenderError::Png {
        path: path.to_path_buf(),
        source,
    };
    let mut bytes = std::io::Cursor::new(Vec::new());
    if image.bit_depth == 8 {
        let raw: Vec<u8> = image.values.iter().map(|&v| v.min(255) as u8).collect();
        image::GrayImage::from_raw(w, h, raw)
            .expect("the buffer matches the size")
            .write_to(&mut bytes, image::ImageFormat::Png)
            .map_err(png)?;
    } else {
        image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(w, h, image.values.clone())
            .expect("the buffer matches the size")
            .write_to(&mut bytes, image::ImageFormat::Png)
            .map_err(png)?;
    }
    Ok(bytes.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::observer::Silent;

    struct Stop;
    impl Observer for Stop {
        fn interrupted(&self) -> bool {
            true
        }
    }

    fn job(out_dir: PathBuf, depth_mm: f64) -> RenderJob {
        RenderJob {
            sources: Vec::new(),
            layout: Layout::paper_biprism(),
            marker: MarkerOptions::default(),
            poses: vec![FramePose {
                pose: Pose::new(
                    nalgebra::Rotation3::identity(),
                    nalgebra::Vector3::new(0.0, 0.0, depth_mm),
                ),
                scenario: None,
            }],
            config: RenderConfig::new(Camera::paper()),
            out_dir,
        }
    }

    #[test]
    fn an_interrupted_or_failing_run_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("frames");
        assert!(matches!(
            run(&job(out.clone(), 600.0), &mut Stop),
            Err(RenderError::Interrupted)
        ));
        assert!(!out.exists());
        let behind = run(&job(out.clone(), -600.0), &mut Silent).unwrap_err();
        assert!(behind.to_string().contains("behind the camera"), "{behind}");
        assert!(!out.exists());
        let report = run(&job(out.clone(), 600.0), &mut Silent).unwrap();
        assert_eq!(report.frames.len(), 1);
        let names: Vec<_> = std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        assert_eq!(names.len(), 2, "{names:?}");
    }
}
