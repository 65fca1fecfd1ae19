//! The validated configuration of `track`.

use crate::camera::Camera;
use crate::config::ConfigError;
use crate::layout::Layout;
use crate::pnp::Solver;
use nalgebra::Vector3;
use serde::Serialize;
use std::fmt;
use std::str::FromStr;

/// How bright pixels are told from the background.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Threshold {
    /// Otsu's level; where it leaves a frame a blob flagged, or rejected
    /// for its shape or size, the upper of Otsu's three-class levels too, and of
    /// the two the detection with more whole blobs ([`ThresholdUsed`] says
    /// which). A frame of bright spheres on a dark ground reads at Otsu's
    /// level; a diffuse scene, white spheres in front of a lit grey body
    /// on a darker ground, at the upper level, where Otsu's puts body and
    /// spheres in one region.
    Auto,
    /// Otsu's level over the whole frame (Otsu, *A threshold selection
    /// method from gray-level histograms*, IEEE SMC 9(1), 1979).
    Otsu,
    /// The upper of Otsu's two levels that split the frame's histogram
    /// into three classes (Liao, Chen and Chung, *A fast algorithm for
    /// multilevel thresholding*, J. Inf. Sci. Eng. 17, 2001): the
    /// spheres above a lit body and the ground below it.
    OtsuUpper,
    /// A fixed level, as a fraction of full scale (0..1).
    Fixed(f64),
    /// Local: a pixel is bright when it exceeds the mean of the square of
    /// half-width `radius_px` around it by `offset` (fraction of full
    /// scale). For frames whose illumination is uneven.
    Local {
        /// Half-width of the averaging square, px.
        radius_px: u32,
        /// Margin above the local mean, fraction of full scale.
        offset: f64,
    },
}

/// Default half-width of the local threshold's window, px: several disc
/// radii at the near end (a 10 mm sphere is a 65 px disc at 200 mm), so a
/// disc raises its own local mean by little.
pub const DEFAULT_LOCAL_RADIUS_PX: u32 = 96;
/// Default margin of the local threshold, fraction of full scale.
pub const DEFAULT_LOCAL_OFFSET: f64 = 0.1;

impl FromStr for Threshold {
    type Err = String;

    /// `auto`, `otsu`, `otsu3`, `local`, `local:RADIUS_PX:OFFSET` or a
    /// fixed level in 0..1.
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let text = text.trim();
        match text {
            "auto" => return Ok(Threshold::Auto),
            "otsu" => return Ok(Threshold::Otsu),
            "otsu3" => return Ok(Threshold::OtsuUpper),
            "local" => {
                return Ok(Threshold::Local {
                    radius_px: DEFAULT_LOCAL_RADIUS_PX,
                    offset: DEFAULT_LOCAL_OFFSET,
                })
            }
            _ => {}
        }
        if let Some(rest) = text.strip_prefix("local:") {
            let (radius, offset) = rest
                .split_once(':')
                .ok_or_else(|| format!("expected local:RADIUS_PX:OFFSET, got {text:?}"))?;
            return Ok(Threshold::Local {
                radius_px: radius
                    .parse()
                    .map_err(|_| format!("bad local radius {radius:?} (px, a whole number)"))?,
                offset: offset
                    .parse()
                    .map_err(|_| format!("bad local offset {offset:?} (fraction of full scale)"))?,
            });
        }
        text.parse::<f64>().map(Threshold::Fixed).map_err(|_| {
            format!("unknown threshold {text:?}: expected auto, otsu, otsu3, local, local:RADIUS_PX:OFFSET or a level in 0..1")
        })
    }
}

impl fmt::Display for Threshold {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Threshold::Auto => f.write_str("auto"),
            Threshold::Otsu => f.write_str("otsu"),
            Threshold::OtsuUpper => f.write_str("otsu3"),
            Threshold::Fixed(level) => write!(f, "{level}"),
            Threshold::Local { radius_px, offset } => write!(f, "local:{radius_px}:{offset}"),
        }
    }
}

/// Which subpixel centre of a blob feeds identification and pose.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum CentreMethod {
    /// The centre of the ellipse fitted to the blob's subpixel edge.
    #[default]
    Ellipse,
    /// The intensity-weighted centroid of the blob.
    Centroid,
    /// The background-subtracted intensity centroid over the fitted
    /// ellipse grown by [`super::detect::WINDOW_MARGIN_PX`]: linear in the
    /// pixels, so the least noisy of the three, but pulled by whatever lies
    /// behind the limb (plate, supports) unless `--refine` takes that off.
    Window,
}

impl CentreMethod {
    /// Stable CLI name.
    pub fn name(self) -> &'static str {
        match self {
            CentreMethod::Ellipse => "ellipse",
            CentreMethod::Centroid => "centroid",
            CentreMethod::Window => "window",
        }
    }
}

impl FromStr for CentreMethod {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text.trim() {
            "ellipse" => Ok(CentreMethod::Ellipse),
            "centroid" => Ok(CentreMethod::Centroid),
            "window" => Ok(CentreMethod::Window),
            other => Err(format!(
                "unknown centre method {other:?}: expected ellipse, centroid or window"
            )),
        }
    }
}

/// How blobs are found and judged.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DetectorConfig {
    /// The threshold.
    pub threshold: Threshold,
    /// Smallest blob kept, px (thresholded pixels).
    pub min_area_px: usize,
    /// Largest blob kept, px.
    pub max_area_px: usize,
    /// Smallest contrast kept, blob plateau minus local background, as a
    /// fraction of full scale.
    pub min_contrast: f64,
    /// A blob whose area above the half level is below this fraction of
    /// its fitted ellipse's area is flagged as partly hidden.
    pub min_filled_fraction: f64,
    /// A blob with more than this share of its edge points off the fitted
    /// ellipse is flagged as partly hidden.
    pub max_outlier_fraction: f64,
    /// A blob whose edge dips inside its fitted ellipse by more than this
    /// along some arc, beyond the noise of its edge points, is flagged as
    /// partly hidden ([`super::detect::edge_dip`]), px.
    pub max_edge_dip_px: f64,
    /// A blob with more than this share of its edge points cut away as a
    /// notch ([`super::detect::notch_arcs`]) is flagged as partly hidden:
    /// below it, the rest of the outline fixes the ellipse and the blob is
    /// measured from it.
    pub max_outline_dropped: f64,
}

/// Default smallest blob, px: below this an ellipse fit has too few edge
/// points to be worth its centre.
pub const DEFAULT_MIN_AREA_PX: usize = 12;
/// Default largest blob, px: a 10 mm sphere at 100 mm on a 1300 px lens is
/// about 130 px across (13,000 px²).
pub const DEFAULT_MAX_AREA_PX: usize = 40_000;
/// Default least contrast, fraction of full scale.
pub const DEFAULT_MIN_CONTRAST: f64 = 0.08;
/// Default least filled fraction of an unhidden blob: a whole disc fills
/// its ellipse to within the pixels its outline cuts (about 1–2% for a
/// 13 px disc), so 0.95 leaves a margin and still catches a blob with a
/// tenth hidden.
pub const DEFAULT_MIN_FILLED_FRACTION: f64 = 0.95;
/// Default largest share of edge points off the ellipse of an unhidden blob.
pub const DEFAULT_MAX_OUTLIER_FRACTION: f64 = 0.08;
/// Default largest dip of a whole blob's edge inside its ellipse, px: the
/// edge model's own errors on a whole disc reach a few hundredths of a
/// pixel along an arc, and a plate edge passing just behind a 15 px disc
/// bends its edge by up to a tenth; a support's notch a third of a pixel
/// deep goes well beyond this (`track_accuracy -- hidden`).
pub const DEFAULT_MAX_EDGE_DIP_PX: f64 = 0.1;
/// Default largest share of a used blob's outline cut away as a notch: a
/// sphere's own support cone, seen 50–60° off its axis, hides a fifth to
/// a quarter of the outline and a fraction of a percent of the area
/// (`track_accuracy -- lost`); the rest, two thirds of the outline or
/// more, still fixes the ellipse.
pub const DEFAULT_MAX_OUTLINE_DROPPED: f64 = 0.35;

impl Default for DetectorConfig {
    fn default() -> Self {
        Self {
            threshold: Threshold::Auto,
            min_area_px: DEFAULT_MIN_AREA_PX,
            max_area_px: DEFAULT_MAX_AREA_PX,
            min_contrast: DEFAULT_MIN_CONTRAST,
            min_filled_fraction: DEFAULT_MIN_FILLED_FRACTION,
            max_outlier_fraction: DEFAULT_MAX_OUTLIER_FRACTION,
            max_edge_dip_px: DEFAULT_MAX_EDGE_DIP_PX,
            max_outline_dropped: DEFAULT_MAX_OUTLINE_DROPPED,
        }
    }
}

impl DetectorConfig {
    /// Checks every field.
    pub fn validate(&self) -> Result<(), ConfigError> {
        match self.threshold {
            Threshold::Auto | Threshold::Otsu | Threshold::OtsuUpper => {}
            Threshold::Fixed(level) => {
                if !(level > 0.0 && level < 1.0) {
                    return Err(ConfigError::new(
                        "threshold",
                        format!("a fixed level must lie strictly between 0 and 1 (fraction of full scale), got {level}"),
                    ));
                }
            }
            Threshold::Local { radius_px, offset } => {
                if radius_px == 0 || radius_px > 4096 {
                    return Err(ConfigError::new(
                        "threshold",
                        format!("the local radius must be 1..4096 px, got {radius_px}"),
                    ));
                }
                ConfigError::within("threshold", offset, 0.0, 1.0)?;
            }
        }
        if self.min_area_px < 5 {
            return Err(ConfigError::new(
                "min_area_px",
                format!(
                    "must be at least 5 px (an ellipse needs edge points), got {}",
                    self.min_area_px
                ),
            ));
        }
        if self.max_area_px < self.min_area_px {
            return Err(ConfigError::new(
                "max_area_px",
                format!(
                    "must be at least min_area_px ({}), got {}",
                    self.min_area_px, self.max_area_px
                ),
            ));
        }
        ConfigError::within("min_contrast", self.min_contrast, 0.0, 1.0)?;
        ConfigError::within("min_filled_fraction", self.min_filled_fraction, 0.0, 1.0)?;
        ConfigError::within("max_outlier_fraction", self.max_outlier_fraction, 0.0, 1.0)?;
        ConfigError::within("max_edge_dip_px", self.max_edge_dip_px, 0.0, 1e3)?;
        ConfigError::within("max_outline_dropped", self.max_outline_dropped, 0.0, 1.0)?;
        Ok(())
    }
}

/// Most clutter blobs `max_extra_blobs` accepts: each extra blob multiplies
/// the subsets tried (C(n + k, n) for n spheres).
pub const MAX_EXTRA_BLOBS: usize = 4;
/// Default largest predicted probability that the labels are wrong before a
/// frame is refused as ambiguous: the identifiability model's default bar
/// ([`crate::identifiability::DEFAULT_MIN_CORRECT`]).
pub const DEFAULT_MAX_WRONG_LABELS: f64 = 1.0 - crate::identifiability::DEFAULT_MIN_CORRECT;

/// Everything `track` needs to turn a frame into a pose.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrackConfig {
    /// The camera (its size must match every frame's).
    pub camera: Camera,
    /// The marker's sphere centres, mm, in layout order.
    pub object: Vec<Vector3<f64>>,
    /// The spheres' names, in layout order.
    pub names: Vec<String>,
    /// Sphere diameter, mm (default: the layout's).
    pub sphere_diameter_mm: f64,
    /// The blob detector.
    pub detector: DetectorConfig,
    /// Which blob centre feeds the pose.
    pub centre: CentreMethod,
    /// The solver of the final pose (`ml` fits the sphere model).
    pub solver: Solver,
    /// Pixel noise σ of the blob centres, px, one for all; `None`: each
    /// centre's own from its blob ([`super::uncertainty`]).
    pub sigma_px: Option<f64>,
    /// Identification gate, px.
    pub gate_px: f64,
    /// How many blobs beyond the spheres are tolerated as clutter.
    pub max_extra_blobs: usize,
    /// A frame whose labels are wrong with a larger predicted probability
    /// is refused as ambiguous.
    pub max_wrong_labels: f64,
}

impl TrackConfig {
    /// The defaults for `layout` seen by `camera`.
    pub fn new(layout: &Layout, camera: Camera) -> Self {
        TrackConfig {
            camera,
            object: layout.positions(),
            names: layout.points.iter().map(|p| p.name.clone()).collect(),
            sphere_diameter_mm: layout.sphere_diameter_mm,
            detector: DetectorConfig::default(),
            centre: CentreMethod::default(),
            solver: Solver::Ml,
            sigma_px: None,
            gate_px: crate::batch::DEFAULT_GATE_PX,
            max_extra_blobs: 2,
            max_wrong_labels: DEFAULT_MAX_WRONG_LABELS,
        }
    }

    /// Checks every field once, before any frame is read.
    pub fn validate(&self) -> Result<(), ConfigError> {
        use crate::pnp::unlabelled::{MAX_POINTS, MIN_POINTS};
        if !(MIN_POINTS..=MAX_POINTS).contains(&self.object.len()) {
            return Err(ConfigError::new(
                "object",
                format!(
                    "the layout must have {MIN_POINTS}..{MAX_POINTS} spheres to be identified, got {}",
                    self.object.len()
                ),
            ));
        }
        if self.names.len() != self.object.len() {
            return Err(ConfigError::new(
                "names",
                format!(
                    "{} names for {} spheres",
                    self.names.len(),
                    self.object.len()
                ),
            ));
        }
        ConfigError::positive("sphere_diameter_mm", self.sphere_diameter_mm)?;
        self.detector.validate()?;
        if let Some(sigma) = self.sigma_px {
            ConfigError::positive("sigma_px", sigma)?;
        }
        ConfigError::positive("gate_px", self.gate_px)?;
        if self.max_extra_blobs > MAX_EXTRA_BLOBS {
            return Err(ConfigError::new(
                "max_extra_blobs",
                format!(
                    "must be at most {MAX_EXTRA_BLOBS} (each extra blob multiplies the labellings tried), got {}",
                    self.max_extra_blobs
                ),
            ));
        }
        ConfigError::within("max_wrong_labels", self.max_wrong_labels, 0.0, 1.0)?;
        Ok(())
    }

    /// Sphere radius, mm.
    pub fn radius_mm(&self) -> f64 {
        0.5 * self.sphere_diameter_mm
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_validate_and_every_field_is_checked() {
        let layout = Layout::paper_biprism();
        let config = TrackConfig::new(&layout, Camera::paper());
        config.validate().unwrap();
        assert_eq!(config.sphere_diameter_mm, 10.0);
        let cases: Vec<(TrackConfig, &str)> = vec![
            (
                TrackConfig {
                    sphere_diameter_mm: -1.0,
                    ..config.clone()
                },
                "sphere_diameter_mm",
            ),
            (
                TrackConfig {
                    sigma_px: Some(0.0),
                    ..config.clone()
                },
                "sigma_px",
            ),
            (
                TrackConfig {
                    gate_px: f64::NAN,
                    ..config.clone()
                },
                "gate_px",
            ),
            (
                TrackConfig {
                    max_extra_blobs: 9,
                    ..config.clone()
                },
                "max_extra_blobs",
            ),
            (
                TrackConfig {
                    max_wrong_labels: 2.0,
                    ..config.clone()
                },
                "max_wrong_labels",
            ),
            (
                TrackConfig {
                    object: config.object[..3].to_vec(),
                    ..config.clone()
                },
                "object",
            ),
            (
                TrackConfig {
                    detector: DetectorConfig {
                        threshold: Threshold::Fixed(1.5),
                        ..config.detector
                    },
                    ..config.clone()
                },
                "threshold",
            ),
            (
                TrackConfig {
                    detector: DetectorConfig {
                        max_area_px: 3,
                        ..config.detector
                    },
                    ..config.clone()
                },
                "max_area_px",
            ),
            (
                TrackConfig {
                    detector: DetectorConfig {
                        min_contrast: -0.1,
                        ..config.detector
                    },
                    ..config.clone()
                },
                "min_contrast",
            ),
            (
                TrackConfig {
                    detector: DetectorConfig {
                        max_edge_dip_px: f64::NAN,
                        ..config.detector
                    },
                    ..config.clone()
                },
                "max_edge_dip_px",
            ),
        ];
        for (bad, field) in cases {
            let error = bad.validate().unwrap_err();
            assert_eq!(error.field, field, "{error}");
        }
    }

    #[test]
    fn thresholds_and_methods_parse() {
        assert_eq!("otsu".parse::<Threshold>().unwrap(), Threshold::Otsu);
        assert_eq!("0.4".parse::<Threshold>().unwrap(), Threshold::Fixed(0.4));
        assert_eq!(
            "local:50:0.2".parse::<Threshold>().unwrap(),
            Threshold::Local {
                radius_px: 50,
                offset: 0.2
            }
        );
        for t in [
            Threshold::Auto,
            Threshold::Otsu,
            Threshold::OtsuUpper,
            Threshold::Fixed(0.25),
            Threshold::Local {
                radius_px: 9,
                offset: 0.05,
            },
        ] {
            assert_eq!(t.to_string().parse::<Threshold>().unwrap(), t);
        }
        assert!("bright".parse::<Threshold>().unwrap_err().contains("otsu"));
        assert_eq!(
            "centroid".parse::<CentreMethod>().unwrap(),
            CentreMethod::Centroid
        );
        assert_eq!(
            "window".parse::<CentreMethod>().unwrap(),
            CentreMethod::Window
        );
        assert!("middle".parse::<CentreMethod>().is_err());
    }
}
