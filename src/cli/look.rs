//! How the part looks through the lens: the flags `render` draws with and
//! `track --refine` renders its correction with.

use clap::Args;
use layout_opt::render::config::{DEFAULT_BLUR_SIGMA_PX, DEFAULT_SUPERSAMPLING};
use layout_opt::render::{Appearance, Blur, Lighting, Optics};

/// Appearance and optics flags (each defaults to the preset's or the
/// renderer's value).
#[derive(Debug, Args)]
pub struct LookArgs {
    /// Appearance preset: retroreflective (bright discs under a ring light
    /// on dark supports), diffuse (white Lambertian spheres and grey
    /// supports, light beside the camera) or lambertian (white matte
    /// spheres under a ring light: discs darkening to nothing at their
    /// limb, on dark supports). Default: retroreflective.
    #[arg(long, value_name = "PRESET")]
    pub preset: Option<Lighting>,
    /// Sphere radiance, fraction of full scale (default: the preset's).
    #[arg(long, value_name = "L")]
    pub sphere_radiance: Option<f64>,
    /// Support radiance (default: the preset's).
    #[arg(long, value_name = "L")]
    pub support_radiance: Option<f64>,
    /// Background radiance (default: the preset's).
    #[arg(long, value_name = "L")]
    pub background_radiance: Option<f64>,
    /// Diffuse preset: share of the light that reaches every surface
    /// whatever its orientation, 0–1 (default: the preset's).
    #[arg(long, value_name = "SHARE")]
    pub ambient: Option<f64>,
    /// Exposure: multiplies every radiance (default 1).
    #[arg(long, value_name = "X")]
    pub exposure: Option<f64>,
    /// Sub-samples per pixel side at edges (4..16; default 4, and 8 for
    /// track --refine).
    #[arg(long, value_name = "N")]
    pub supersampling: Option<u32>,
    /// Gaussian blur of the lens, px (0: none; default 0.5).
    #[arg(long, value_name = "PX", conflicts_with = "aperture")]
    pub blur: Option<f64>,
    /// Thin-lens defocus instead of --blur: aperture diameter, mm.
    #[arg(long, value_name = "MM", requires = "focus")]
    pub aperture: Option<f64>,
    /// Distance in focus, mm (with --aperture).
    #[arg(long, value_name = "MM", requires = "aperture")]
    pub focus: Option<f64>,
}

impl LookArgs {
    /// Whether any of the flags was given.
    pub fn any_given(&self) -> bool {
        self.preset.is_some()
            || self.sphere_radiance.is_some()
            || self.support_radiance.is_some()
            || self.background_radiance.is_some()
            || self.ambient.is_some()
            || self.exposure.is_some()
            || self.supersampling.is_some()
            || self.blur.is_some()
            || self.aperture.is_some()
    }

    /// Whether a level was given: a radiance or the exposure.
    pub fn levels_given(&self) -> bool {
        self.sphere_radiance.is_some()
            || self.support_radiance.is_some()
            || self.background_radiance.is_some()
            || self.exposure.is_some()
    }

    /// The appearance: the preset with the radiances given.
    pub fn appearance(&self) -> Appearance {
        let preset = Appearance::preset(self.preset.unwrap_or(Lighting::Retroreflective));
        Appearance {
            sphere_radiance: self.sphere_radiance.unwrap_or(preset.sphere_radiance),
            support_radiance: self.support_radiance.unwrap_or(preset.support_radiance),
            background_radiance: self
                .background_radiance
                .unwrap_or(preset.background_radiance),
            exposure: self.exposure.unwrap_or(1.0),
            ambient: self.ambient.unwrap_or(preset.ambient),
            ..preset
        }
    }

    /// The optics, with `supersampling` unless --supersampling is given.
    pub fn optics(&self, supersampling: u32) -> Optics {
        let blur = match (self.aperture, self.focus) {
            (Some(aperture_mm), Some(focus_mm)) => Blur::Defocus {
                aperture_mm,
                focus_mm,
            },
            _ => {
                let sigma_px = self.blur.unwrap_or(DEFAULT_BLUR_SIGMA_PX);
                if sigma_px == 0.0 {
                    Blur::None
                } else {
                    Blur::Gaussian { sigma_px }
                }
            }
        };
        Optics {
            supersampling: self.supersampling.unwrap_or(supersampling),
            blur,
        }
    }

    /// [`LookArgs::optics`] at the renderer's default supersampling.
    pub fn render_optics(&self) -> Optics {
        self.optics(DEFAULT_SUPERSAMPLING)
    }
}

/// The flag a render configuration field comes from.
pub fn flag(field: &str) -> String {
    match field {
        "blur_sigma_px" => "--blur".into(),
        "aperture_mm" => "--aperture".into(),
        "focus_mm" => "--focus".into(),
        "full_well_electrons" => "--full-well".into(),
        "read_noise_electrons" => "--read-noise".into(),
        other => format!("--{}", other.replace('_', "-")),
    }
}
