//! The image-check flags of `validate` (`--images` and its companions).

use clap::Args;
use layout_opt::track::CentreMethod;
use layout_opt::validate::image_check::{
    ImageCheck, ImagePreset, ImageRefine, DEFAULT_IMAGE_TRIALS,
};
use std::path::PathBuf;

/// Flags of the image-level check.
#[derive(Debug, Args)]
pub struct ImageArgs {
    /// Also render every visible scenario once (the part with its supports,
    /// render's defaults) and read it back with `track` under seeded sensor
    /// noise: centre errors against disc radius and depth, and the pose from
    /// the images beside the first-order prediction (report section
    /// "Images", images.csv, images.json).
    #[arg(long)]
    images: bool,
    /// Noisy frames read back per visible scenario with --images.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_IMAGE_TRIALS, requires = "images")]
    image_trials: usize,
    /// Camera and lighting of --images (docs/calibration.md): paper (the
    /// paper's camera, retroreflective spheres, render's defaults),
    /// machine-vision (a 1440×1080 camera with f 1739 px, ring light,
    /// retroreflective spheres; it also becomes validate's camera, so
    /// --camera is refused) or diffuse (a white print under room light).
    #[arg(
        long,
        value_name = "PRESET",
        default_value = "paper",
        requires = "images"
    )]
    image_preset: ImagePreset,
    /// Render the spheres alone with --images, without the part's supports
    /// and plate (nothing can then cut into an outline).
    #[arg(long, requires = "images")]
    image_spheres_only: bool,
    /// Lens blur σ of --images, px (0: none); default the preset's.
    #[arg(long, value_name = "PX", requires = "images")]
    image_blur: Option<f64>,
    /// The centre --images reads each blob by (track --centre): ellipse,
    /// centroid or window.
    #[arg(
        long,
        value_name = "METHOD",
        default_value = "ellipse",
        requires = "images"
    )]
    image_centre: CentreMethod,
    /// Refine every frame of --images by render-and-compare, as `track
    /// --refine` does, the part drawn as the frames are: ROUNDS rounds
    /// (default 1) at SUPERSAMPLING sub-samples per pixel side (default 8);
    /// about 50 ms a frame more per round at 8.
    #[arg(
        long,
        value_name = "ROUNDS[:SUPERSAMPLING]",
        num_args = 0..=1,
        default_missing_value = "1",
        requires = "images"
    )]
    image_refine: Option<ImageRefine>,
    /// Fit σ = a / r^b + c to the tracked centres' RMS error about the
    /// exact centres (noise and each view's bias) from --images and write
    /// it as a noise calibration file (docs/formats.md), for
    /// `--noise-model calibrated:FILE`.
    #[arg(long, value_name = "FILE")]
    write_noise_model: Option<PathBuf>,
}

impl ImageArgs {
    /// The image check, when asked for.
    pub fn check(&self) -> Option<ImageCheck> {
        self.images.then_some(ImageCheck {
            trials: self.image_trials,
            preset: self.image_preset,
            spheres_only: self.image_spheres_only,
            blur_sigma_px: self.image_blur,
            centre: self.image_centre,
            refine: self.image_refine,
        })
    }

    /// The camera the image preset brings, if any.
    pub fn preset_camera(&self) -> Option<layout_opt::camera::Camera> {
        self.images.then(|| self.image_preset.camera()).flatten()
    }

    /// Where to write the fitted noise law.
    pub fn noise_model_out(&self) -> Option<PathBuf> {
        self.write_noise_model.clone()
    }
}

/// The flag of an image-check field, if `field` is one.
pub fn image_flag(field: &str) -> Option<&'static str> {
    match field {
        "image_trials" => Some("--image-trials"),
        "write_noise_model" => Some("--write-noise-model"),
        "images" => Some("--images"),
        "image_preset" => Some("--image-preset"),
        "image_blur" => Some("--image-blur"),
        "image_centre" => Some("--image-centre"),
        "image_refine" | "refine_rounds" => Some("--image-refine"),
        _ => None,
    }
}
