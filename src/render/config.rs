//! What a render needs besides the part and the poses: how the part looks
//! ([`Appearance`]), the optics ([`Optics`]) and the sensor ([`Sensor`]),
//! validated once into a [`RenderConfig`].

use crate::camera::Camera;
use crate::config::ConfigError;
use nalgebra::Vector3;
use serde::Serialize;
use std::fmt;
use std::str::FromStr;

/// Default sub-samples per pixel side.
pub const DEFAULT_SUPERSAMPLING: u32 = 4;
/// Fewest sub-samples per pixel side.
pub const MIN_SUPERSAMPLING: u32 = 4;
/// Most sub-samples per pixel side.
pub const MAX_SUPERSAMPLING: u32 = 16;
/// Default Gaussian blur of the lens, px.
pub const DEFAULT_BLUR_SIGMA_PX: f64 = 0.5;
/// Widest blur a render draws, px (σ): its kernel spans 6σ + 1 = 121 px,
/// more than the largest sphere's image at the nearest working depth, so
/// no blob is left to track beyond it, and a wider kernel only costs time
/// and memory (σ = 1e9 px asked for a 48 GB kernel).
pub const MAX_BLUR_SIGMA_PX: f64 = 20.0;
/// Default full-well capacity: electrons at full scale.
pub const DEFAULT_FULL_WELL_ELECTRONS: f64 = 10_000.0;
/// Default read noise, electrons RMS.
pub const DEFAULT_READ_NOISE_ELECTRONS: f64 = 10.0;
/// Most noise realisations per pose.
pub const MAX_REALISATIONS: u32 = 1000;
/// Darkening of a retroreflective sphere at its limb: its radiance falls
/// from 1 at the centre of the disc to 1 − this at the edge.
pub const RETROREFLECTIVE_LIMB_FALLOFF: f64 = 0.15;
/// Share of the diffuse preset's light that reaches every surface
/// regardless of its orientation (its default; `render --ambient`): room
/// light, most of it from the ceiling and the walls. At 0.15 (a lamp with
/// little fill) the shaded side of a white sphere falls below its lit grey
/// supports and no disc is whole at any threshold; `track` then reads no
/// frame of the search winner (docs/calibration.md, "diffuse").
pub const DIFFUSE_AMBIENT: f64 = 0.85;
/// Direction from the part to the diffuse preset's light, camera frame:
/// beside the camera, up and to the left, 30° off the optical axis.
pub const DIFFUSE_LIGHT_DIRECTION: [f64; 3] = [-0.3536, -0.3536, -0.8660];

/// How the part is lit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Lighting {
    /// A ring light coaxial with the lens: retroreflective spheres return
    /// nearly all of it (bright, nearly uniform discs, darkening by
    /// [`RETROREFLECTIVE_LIMB_FALLOFF`] towards the limb at most), the matte
    /// supports return `cos θ` of it (θ between the surface normal and the
    /// line of sight).
    Retroreflective,
    /// A light beside the camera ([`DIFFUSE_LIGHT_DIRECTION`]): white
    /// Lambertian spheres and grey Lambertian supports, with a share of
    /// ambient light ([`Appearance::ambient`], [`DIFFUSE_AMBIENT`] by
    /// default); no shadows.
    Diffuse,
    /// A ring light coaxial with the lens on white matte (Lambertian)
    /// spheres, as a printed sphere painted white looks: every surface
    /// returns `cos θ` of the light, so a sphere's disc darkens from its
    /// centre to nothing at its limb, and the supports are dark matte print.
    Lambertian,
}

impl Lighting {
    /// Every lighting, in CLI order.
    pub const ALL: [Lighting; 3] = [
        Lighting::Retroreflective,
        Lighting::Diffuse,
        Lighting::Lambertian,
    ];

    /// Its CLI name.
    pub fn name(self) -> &'static str {
        match self {
            Lighting::Retroreflective => "retroreflective",
            Lighting::Diffuse => "diffuse",
            Lighting::Lambertian => "lambertian",
        }
    }
}

impl fmt::Display for Lighting {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Lighting {
    type Err = ConfigError;
    fn from_str(text: &str) -> Result<Self, ConfigError> {
        Lighting::ALL
            .into_iter()
            .find(|l| l.name().eq_ignore_ascii_case(text.trim()))
            .ok_or_else(|| {
                ConfigError::new(
                    "lighting",
                    format!(
                        "unknown preset \"{text}\"; use retroreflective, diffuse or lambertian"
                    ),
                )
            })
    }
}

/// How the part looks. Radiances are fractions of the sensor's full scale
/// at exposure 1.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Appearance {
    /// The lighting model.
    pub lighting: Lighting,
    /// Radiance of a sphere facing the light.
    pub sphere_radiance: f64,
    /// Radiance of a support facing the light.
    pub support_radiance: f64,
    /// Radiance of the background.
    pub background_radiance: f64,
    /// Multiplies every radiance before the sensor.
    pub exposure: f64,
    /// Darkening of a sphere at its limb (retroreflective lighting), 0..1;
    /// 1 under the Lambertian preset (the cosine law).
    pub sphere_limb_falloff: f64,
    /// Share of the light that reaches every surface whatever its
    /// orientation (diffuse lighting), 0..1; the rest comes from the lamp.
    pub ambient: f64,
}

impl Appearance {
    /// The named preset's appearance.
    pub fn preset(lighting: Lighting) -> Appearance {
        match lighting {
            Lighting::Retroreflective => Appearance {
                lighting,
                sphere_radiance: 0.9,
                support_radiance: 0.15,
                background_radiance: 0.02,
                exposure: 1.0,
                sphere_limb_falloff: RETROREFLECTIVE_LIMB_FALLOFF,
                ambient: 0.0,
            },
            Lighting::Diffuse => Appearance {
                lighting,
                sphere_radiance: 0.85,
                support_radiance: 0.5,
                background_radiance: 0.12,
                exposure: 1.0,
                sphere_limb_falloff: 0.0,
                ambient: DIFFUSE_AMBIENT,
            },
            Lighting::Lambertian => Appearance {
                lighting,
                sphere_radiance: 0.85,
                support_radiance: 0.15,
                background_radiance: 0.02,
                exposure: 1.0,
                sphere_limb_falloff: 1.0,
                ambient: 0.0,
            },
        }
    }

    /// Direction from the part to the light, camera frame (unit).
    pub fn light_direction_camera(&self) -> Vector3<f64> {
        match self.lighting {
            Lighting::Retroreflective | Lighting::Lambertian => -Vector3::z(),
            Lighting::Diffuse => Vector3::from(DIFFUSE_LIGHT_DIRECTION).normalize(),
        }
    }
}

impl Default for Appearance {
    fn default() -> Self {
        Appearance::preset(Lighting::Retroreflective)
    }
}

/// The lens's blur.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum Blur {
    /// No blur: the supersampled box filter alone.
    None,
    /// A Gaussian point-spread function.
    Gaussian {
        /// Its standard deviation, px.
        sigma_px: f64,
    },
    /// Thin-lens defocus: the blur circle of a point at the depth of the
    /// marker origin, `aperture · fx · |1/focus − 1/depth|` px across, as
    /// the Gaussian of the same second moment (σ = diameter / 4).
    Defocus {
        /// Aperture (entrance pupil) diameter, mm.
        aperture_mm: f64,
        /// Distance in focus, mm.
        focus_mm: f64,
    },
}

impl Blur {
    /// The Gaussian σ, px, for a marker origin at `depth_mm` seen by a
    /// camera of focal length `fx_px`.
    pub fn sigma_px(&self, fx_px: f64, depth_mm: f64) -> f64 {
        match *self {
            Blur::None => 0.0,
            Blur::Gaussian { sigma_px } => sigma_px,
            Blur::Defocus {
                aperture_mm,
                focus_mm,
            } => aperture_mm * fx_px * (1.0 / focus_mm - 1.0 / depth_mm).abs() / 4.0,
        }
    }
}

/// Anti-aliasing and blur.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Optics {
    /// Sub-samples per pixel side (n × n per pixel where the pixel holds
    /// an edge).
    pub supersampling: u32,
    /// The lens's blur.
    pub blur: Blur,
}

impl Default for Optics {
    fn default() -> Self {
        Optics {
            supersampling: DEFAULT_SUPERSAMPLING,
            blur: Blur::Gaussian {
                sigma_px: DEFAULT_BLUR_SIGMA_PX,
            },
        }
    }
}

/// Sensor noise, in electrons.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Noise {
    /// Electrons at full scale; photon shot noise has variance equal to
    /// the electron count.
    pub full_well_electrons: f64,
    /// Read noise, electrons RMS.
    pub read_noise_electrons: f64,
}

impl Default for Noise {
    fn default() -> Self {
        Noise {
            full_well_electrons: DEFAULT_FULL_WELL_ELECTRONS,
            read_noise_electrons: DEFAULT_READ_NOISE_ELECTRONS,
        }
    }
}

/// The sensor: bit depth and noise.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sensor {
    /// Bits per pixel of the PNG: 8 or 16.
    pub bit_depth: u8,
    /// Shot and read noise; `None`: a noise-free image (quantised only).
    pub noise: Option<Noise>,
}

impl Default for Sensor {
    fn default() -> Self {
        Sensor {
            bit_depth: 8,
            noise: Some(Noise::default()),
        }
    }
}

/// Everything a render needs besides the part and the poses.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RenderConfig {
    /// The camera: intrinsics, image size and distortion.
    pub camera: Camera,
    /// How the part looks.
    pub appearance: Appearance,
    /// Anti-aliasing and blur.
    pub optics: Optics,
    /// Bit depth and noise.
    pub sensor: Sensor,
    /// Noisy images per pose, all from one noise-free render.
    pub realisations: u32,
    /// Seeds every noise stream.
    pub seed: u64,
}

impl RenderConfig {
    /// The defaults (retroreflective preset, 4×4 supersampling, σ 0.5 px
    /// blur, 8 bit, default noise) for `camera`.
    pub fn new(camera: Camera) -> Self {
        RenderConfig {
            camera,
            appearance: Appearance::default(),
            optics: Optics::default(),
            sensor: Sensor::default(),
            realisations: 1,
            seed: 7,
        }
    }

    /// Checks every value; the error names the field.
    ///
    /// ```
    /// use layout_opt::camera::Camera;
    /// use layout_opt::render::RenderConfig;
    /// let mut config = RenderConfig::new(Camera::paper());
    /// assert!(config.validate().is_ok());
    /// config.sensor.bit_depth = 12;
    /// assert_eq!(config.validate().unwrap_err().field, "bit_depth");
    /// ```
    pub fn validate(&self) -> Result<(), ConfigError> {
        let a = &self.appearance;
        ConfigError::within("sphere_radiance", a.sphere_radiance, 0.0, 1e6)?;
        ConfigError::within("support_radiance", a.support_radiance, 0.0, 1e6)?;
        ConfigError::within("background_radiance", a.background_radiance, 0.0, 1e6)?;
        ConfigError::positive("exposure", a.exposure)?;
        ConfigError::within("sphere_limb_falloff", a.sphere_limb_falloff, 0.0, 1.0)?;
        ConfigError::within("ambient", a.ambient, 0.0, 1.0)?;
        let s = self.optics.supersampling;
        if !(MIN_SUPERSAMPLING..=MAX_SUPERSAMPLING).contains(&s) {
            return Err(ConfigError::new(
                "supersampling",
                format!("must lie in {MIN_SUPERSAMPLING}..{MAX_SUPERSAMPLING} sub-samples per pixel side, got {s}"),
            ));
        }
        match self.optics.blur {
            Blur::None => {}
            Blur::Gaussian { sigma_px } => {
                ConfigError::within("blur_sigma_px", sigma_px, 0.0, MAX_BLUR_SIGMA_PX)?
            }
            Blur::Defocus {
                aperture_mm,
                focus_mm,
            } => {
                ConfigError::non_negative("aperture_mm", aperture_mm)?;
                ConfigError::positive("focus_mm", focus_mm)?;
            }
        }
        if !matches!(self.sensor.bit_depth, 8 | 16) {
            return Err(ConfigError::new(
                "bit_depth",
                format!("must be 8 or 16, got {}", self.sensor.bit_depth),
            ));
        }
        if let Some(noise) = &self.sensor.noise {
            ConfigError::positive("full_well_electrons", noise.full_well_electrons)?;
            ConfigError::non_negative("read_noise_electrons", noise.read_noise_electrons)?;
        }
        if !(1..=MAX_REALISATIONS).contains(&self.realisations) {
            return Err(ConfigError::new(
                "realisations",
                format!(
                    "must lie in 1..{MAX_REALISATIONS}, got {}",
                    self.realisations
                ),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_are_valid_and_every_bad_value_names_its_field() {
        let good = RenderConfig::new(Camera::paper());
        assert!(good.validate().is_ok());
        let check = |change: &dyn Fn(&mut RenderConfig), field: &str| {
            let mut config = good.clone();
            change(&mut config);
            assert_eq!(config.validate().unwrap_err().field, field);
        };
        check(&|c| c.appearance.exposure = -1.0, "exposure");
        check(
            &|c| c.appearance.sphere_radiance = f64::NAN,
            "sphere_radiance",
        );
        check(&|c| c.appearance.ambient = 1.5, "ambient");
        check(&|c| c.optics.supersampling = 3, "supersampling");
        check(
            &|c| c.optics.blur = Blur::Gaussian { sigma_px: -0.5 },
            "blur_sigma_px",
        );
        check(
            &|c| {
                c.optics.blur = Blur::Defocus {
                    aperture_mm: 2.0,
                    focus_mm: 0.0,
                }
            },
            "focus_mm",
        );
        check(&|c| c.sensor.bit_depth = 12, "bit_depth");
        check(&|c| c.realisations = 0, "realisations");
        assert_eq!(
            {
                let mut c = good.clone();
                c.sensor.bit_depth = 12;
                c.validate().unwrap_err().to_string()
            },
            "bit_depth: must be 8 or 16, got 12"
        );
        assert_eq!("Diffuse".parse::<Lighting>().unwrap(), Lighting::Diffuse);
        assert_eq!("glossy".parse::<Lighting>().unwrap_err().field, "lighting");
    }

    #[test]
    fn defocus_blurs_in_proportion_to_the_aperture_and_the_focus_error() {
        let blur = Blur::Defocus {
            aperture_mm: 4.0,
            focus_mm: 500.0,
        };
        assert_eq!(blur.sigma_px(1300.0, 500.0), 0.0);
        let sigma = blur.sigma_px(1300.0, 1000.0);
        assert!((sigma - 4.0 * 1300.0 * (1.0 / 500.0 - 1.0 / 1000.0) / 4.0).abs() < 1e-12);
    }
}
