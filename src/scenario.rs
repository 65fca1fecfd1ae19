//! Scenarios: one camera pose of the marker plus one noise level, built as a
//! grid from CLI ranges (docs/formats.md, "Ranges on the command line"), and
//! the visibility rules every scenario is checked against.
//!
//! **Scenario pose (contract).** The marker origin sits at
//! `(offset_x, offset_y, depth)` in the camera frame; its attitude is
//! `R = Rz(roll) · Ry(pan) · Rx(tilt)` applied to the base attitude, in which
//! the marker axes are parallel to the camera axes (the paper's real-image
//! protocol tilts the marker about X from −90° to 90°).
//!
//! ```
//! use layout_opt::scenario::{Range, ScenarioGrid};
//!
//! let grid = ScenarioGrid::new(
//!     "200..1000:200".parse()?, // depth, mm: 200, 400, …, 1000
//!     "0,50".parse()?,          // X offset, mm
//!     Range::single(0.0),       // Y offset
//!     "-60..60:30".parse()?,    // tilt about X, degrees
//!     Range::single(0.0),       // pan
//!     Range::single(0.0),       // roll
//!     Range::single(0.5),       // σ, px
//! )?;
//! assert_eq!(grid.len(), 5 * 2 * 5);
//! let first = &grid.scenarios()[0];
//! assert_eq!(first.pose().translation.z, 200.0);
//! // Malformed ranges are errors.
//! assert!("200 to 1000".parse::<Range>().is_err());
//! # Ok::<(), layout_opt::scenario::ScenarioError>(())
//! ```

use crate::camera::Camera;
use crate::pose::Pose;
use nalgebra::{Rotation3, Vector2, Vector3};
use serde::Serialize;
use std::str::FromStr;

/// Farthest depth a scenario may have, mm: 100 m, a hundred times the
/// farthest working range of a close-range marker. Beyond it a sphere's
/// image is far below a pixel, and depths such as 1e308 mm overflow the
/// projection.
pub const MAX_DEPTH_MM: f64 = 1e5;
/// [`MAX_DEPTH_MM`] as a requirement, for errors.
pub const MAX_DEPTH_TEXT: &str = "at most 100000 mm (100 m)";

/// Values a range `A..B` without a step expands to.
pub const DEFAULT_STEP_COUNT: usize = 5;
/// Largest number of values one range may expand to.
pub const MAX_RANGE_VALUES: usize = 100_000;
/// Largest tilt, pan or roll, degrees: angles are taken in −180…180° so
/// that every attitude appears once.
pub const MAX_ANGLE_DEG: f64 = 180.0;
/// Margin (px) a sphere's image disc must keep from the image border.
pub const VISIBILITY_MARGIN_PX: f64 = 5.0;

/// Bad scenario ranges.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ScenarioError {
    /// A range string could not be parsed.
    #[error("cannot parse range '{text}': {reason}")]
    Parse {
        /// The text given.
        text: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A quantity is outside what it can physically be.
    #[error("{quantity} must be {requirement}, got {}", short_number(*value))]
    OutOfDomain {
        /// Which quantity.
        quantity: &'static str,
        /// What it must be.
        requirement: &'static str,
        /// The offending value.
        value: f64,
    },
}

/// `value` as written, or in exponent form when that is shorter (1e308
/// rather than its 309 digits).
fn short_number(value: f64) -> String {
    let plain = value.to_string();
    let exponent = format!("{value:e}");
    if exponent.len() < plain.len() {
        exponent
    } else {
        plain
    }
}

/// A list of values from a CLI range: `A..B` ([`DEFAULT_STEP_COUNT`] values),
/// `A..B:STEP`, a single value, or a comma-separated list of values.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Range {
    /// The values, in order.
    pub values: Vec<f64>,
}

impl Range {
    /// A range of one value.
    pub fn single(value: f64) -> Self {
        Self {
            values: vec![value],
        }
    }

    /// A range of the given values.
    pub fn list(values: &[f64]) -> Self {
        Self {
            values: values.to_vec(),
        }
    }

    /// `start..=end` in steps of `step` (the end is included when the steps
    /// land on it within rounding).
    pub fn stepped(start: f64, end: f64, step: f64) -> Result<Self, ScenarioError> {
        parse_range(&format!("{start}..{end}:{step}"))
    }
}

fn parse_number(text: &str, whole: &str) -> Result<f64, ScenarioError> {
    let value: f64 = text.trim().parse().map_err(|_| ScenarioError::Parse {
        text: whole.to_string(),
        reason: format!("'{}' is not a number", text.trim()),
    })?;
    if !value.is_finite() {
        return Err(ScenarioError::Parse {
            text: whole.to_string(),
            reason: format!("'{}' is not finite", text.trim()),
        });
    }
    Ok(value)
}

fn parse_range(text: &str) -> Result<Range, ScenarioError> {
    let error = |reason: String| ScenarioError::Parse {
        text: text.to_string(),
        reason,
    };
    let trimmed = text.trim();
    if trimmed.is_empty() {
        return Err(error("the range is empty".into()));
    }
    if let Some((start, rest)) = trimmed.split_once("..") {
        let (end, step) = match rest.split_once(':') {
            Some((end, step)) => (end, Some(step)),
            None => (rest, None),
        };
        let start = parse_number(start, text)?;
        let end = parse_number(end, text)?;
        let values = match step {
            None => {
                if start == end {
                    vec![start]
                } else {
                    (0..DEFAULT_STEP_COUNT)
                        .map(|k| start + (end - start) * k as f64 / (DEFAULT_STEP_COUNT - 1) as f64)
                        .collect()
                }
            }
            Some(step) => {
                let step = parse_number(step, text)?;
                if step <= 0.0 {
                    return Err(error(format!("the step must be positive, got {step}")));
                }
                // A descending range runs from A down to B, as `A..B`
                // without a step does; the step is always a magnitude.
                let direction = if end < start { -1.0 } else { 1.0 };
                let count = ((end - start).abs() / step + 1e-9).floor();
                if count >= MAX_RANGE_VALUES as f64 {
                    return Err(error(format!(
                        "{} values is more than {MAX_RANGE_VALUES}",
                        count + 1.0
                    )));
                }
                (0..count as usize + 1)
                    .map(|k| start + direction * step * k as f64)
                    .collect()
            }
        };
        return Ok(Range { values });
    }
    let values = trimmed
        .split(',')
        .map(|part| parse_number(part, text))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Range { values })
}

impl FromStr for Range {
    type Err = ScenarioError;
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        parse_range(text)
    }
}

/// One scenario: a marker pose and a pixel noise level.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Scenario {
    /// Position in the grid; seeds the scenario's random streams.
    pub index: usize,
    /// Depth of the marker origin, mm.
    pub depth_mm: f64,
    /// X offset of the marker origin, mm.
    pub offset_x_mm: f64,
    /// Y offset of the marker origin, mm.
    pub offset_y_mm: f64,
    /// Rotation about X, degrees.
    pub tilt_deg: f64,
    /// Rotation about Y, degrees.
    pub pan_deg: f64,
    /// Rotation about Z, degrees.
    pub roll_deg: f64,
    /// Pixel noise σ, px.
    pub sigma_px: f64,
}

impl Scenario {
    /// The marker pose of this scenario (module docs give the convention).
    pub fn pose(&self) -> Pose {
        let rotation = Rotation3::from_axis_angle(&Vector3::z_axis(), self.roll_deg.to_radians())
            * Rotation3::from_axis_angle(&Vector3::y_axis(), self.pan_deg.to_radians())
            * Rotation3::from_axis_angle(&Vector3::x_axis(), self.tilt_deg.to_radians());
        Pose::new(
            rotation,
            Vector3::new(self.offset_x_mm, self.offset_y_mm, self.depth_mm),
        )
    }
}

/// A grid of scenarios: the Cartesian product of its ranges.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScenarioGrid {
    /// Depths, mm (all positive).
    pub depth_mm: Range,
    /// X offsets, mm.
    pub offset_x_mm: Range,
    /// Y offsets, mm.
    pub offset_y_mm: Range,
    /// Tilts about X, degrees.
    pub tilt_deg: Range,
    /// Pans about Y, degrees.
    pub pan_deg: Range,
    /// Rolls about Z, degrees.
    pub roll_deg: Range,
    /// Pixel noise levels σ, px (all non-negative).
    pub sigma_px: Range,
}

impl ScenarioGrid {
    /// Builds a grid, checking every range is non-empty, depths are positive
    /// and at most [`MAX_DEPTH_MM`],
    /// angles lie within ±[`MAX_ANGLE_DEG`] and noise levels are
    /// non-negative.
    pub fn new(
        depth_mm: Range,
        offset_x_mm: Range,
        offset_y_mm: Range,
        tilt_deg: Range,
        pan_deg: Range,
        roll_deg: Range,
        sigma_px: Range,
    ) -> Result<Self, ScenarioError> {
        let grid = Self {
            depth_mm,
            offset_x_mm,
            offset_y_mm,
            tilt_deg,
            pan_deg,
            roll_deg,
            sigma_px,
        };
        for (name, range) in grid.named_ranges() {
            if range.values.is_empty() {
                return Err(ScenarioError::Parse {
                    text: name.to_string(),
                    reason: "the range is empty".into(),
                });
            }
        }
        if let Some(&depth) = grid.depth_mm.values.iter().find(|&&d| d <= 0.0) {
            return Err(ScenarioError::OutOfDomain {
                quantity: "depth",
                requirement: "positive (mm in front of the camera)",
                value: depth,
            });
        }
        if let Some(&depth) = grid.depth_mm.values.iter().find(|&&d| d > MAX_DEPTH_MM) {
            return Err(ScenarioError::OutOfDomain {
                quantity: "depth",
                requirement: MAX_DEPTH_TEXT,
                value: depth,
            });
        }
        for (quantity, range) in [
            ("tilt", &grid.tilt_deg),
            ("pan", &grid.pan_deg),
            ("roll", &grid.roll_deg),
        ] {
            if let Some(&angle) = range.values.iter().find(|a| a.abs() > MAX_ANGLE_DEG) {
                return Err(ScenarioError::OutOfDomain {
                    quantity,
                    requirement: "within −180…180° (each attitude once)",
                    value: angle,
                });
            }
        }
        if let Some(&sigma) = grid.sigma_px.values.iter().find(|&&s| s < 0.0) {
            return Err(ScenarioError::OutOfDomain {
                quantity: "noise σ",
                requirement: "non-negative (px)",
                value: sigma,
            });
        }
        let count = grid.len();
        if count > 10_000_000 {
            return Err(ScenarioError::Parse {
                text: "scenario grid".into(),
                reason: format!("{count} scenarios is more than 10,000,000"),
            });
        }
        Ok(grid)
    }

    /// The paper's real-image protocol, simulated (validate's default): depths
    /// 200…1000 mm in steps of 200, X offsets 0, 50 and 100 mm, tilt about X
    /// −90°…90° in steps of `tilt_step_deg`, σ = 0.5 px.
    pub fn paper_protocol(tilt_step_deg: f64) -> Self {
        Self::new(
            Range::list(&[200.0, 400.0, 600.0, 800.0, 1000.0]),
            Range::list(&[0.0, 50.0, 100.0]),
            Range::single(0.0),
            Range::stepped(-90.0, 90.0, tilt_step_deg).expect("a positive step"),
            Range::single(0.0),
            Range::single(0.0),
            Range::single(0.5),
        )
        .expect("the paper's protocol is a valid grid")
    }

    /// The ranges with their names, in grid order.
    pub fn named_ranges(&self) -> [(&'static str, &Range); 7] {
        [
            ("depth", &self.depth_mm),
            ("offset-x", &self.offset_x_mm),
            ("offset-y", &self.offset_y_mm),
            ("tilt", &self.tilt_deg),
            ("pan", &self.pan_deg),
            ("roll", &self.roll_deg),
            ("noise", &self.sigma_px),
        ]
    }

    /// Number of scenarios.
    pub fn len(&self) -> usize {
        self.named_ranges()
            .iter()
            .map(|(_, r)| r.values.len())
            .product()
    }

    /// Whether the grid is empty (never, for a validated grid).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Every scenario, in a fixed order (depth outermost, noise innermost).
    pub fn scenarios(&self) -> Vec<Scenario> {
        let mut out = Vec::with_capacity(self.len());
        for &depth_mm in &self.depth_mm.values {
            for &offset_x_mm in &self.offset_x_mm.values {
                for &offset_y_mm in &self.offset_y_mm.values {
                    for &tilt_deg in &self.tilt_deg.values {
                        for &pan_deg in &self.pan_deg.values {
                            for &roll_deg in &self.roll_deg.values {
                                for &sigma_px in &self.sigma_px.values {
                                    out.push(Scenario {
                                        index: out.len(),
                                        depth_mm,
                                        offset_x_mm,
                                        offset_y_mm,
                                        tilt_deg,
                                        pan_deg,
                                        roll_deg,
                                        sigma_px,
                                    });
                                }
                            }
                        }
                    }
                }
            }
        }
        out
    }
}

/// The image of one sphere: centre and disc radius, px.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SphereImage {
    /// Projected centre, px (distortion applied).
    pub centre_px: [f64; 2],
    /// Radius of the image disc, px.
    pub radius_px: f64,
    /// Distance of the sphere centre from the camera centre, mm.
    pub distance_mm: f64,
}

/// Which visibility rules a scenario breaks, per feature (indices into the
/// layout's points).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Visibility {
    /// Features not in front of the camera.
    pub behind: Vec<usize>,
    /// Features whose image disc leaves the image (with the margin).
    pub outside: Vec<usize>,
    /// `(hidden, by)`: the disc of `hidden` overlaps the disc of the nearer
    /// sphere `by`, so its centre cannot be measured cleanly.
    pub occluded: Vec<(usize, usize)>,
    /// Features whose silhouette the part's own supports hide beyond the
    /// allowed fraction (see [`crate::visibility`]); always empty when the
    /// supports are not counted.
    pub hidden_by_support: Vec<usize>,
}

impl Visibility {
    /// Every feature is in front, inside the image and unoccluded.
    pub fn is_visible(&self) -> bool {
        self.behind.is_empty()
            && self.outside.is_empty()
            && self.occluded.is_empty()
            && self.hidden_by_support.is_empty()
    }

    /// Every feature is in front of the camera (so it has an image at all).
    pub fn all_in_front(&self) -> bool {
        self.behind.is_empty()
    }
}

/// Images of the spheres of `object` under `pose`, or `None` for a sphere
/// whose centre is not in front of the camera. The disc radius is that of the
/// sphere's silhouette cone, `f · ρ / √(D² − ρ²)` (exact on the optical axis).
pub fn sphere_images(
    camera: &Camera,
    pose: &Pose,
    object: &[Vector3<f64>],
    sphere_diameter_mm: f64,
) -> Vec<Option<SphereImage>> {
    let radius_mm = 0.5 * sphere_diameter_mm;
    let focal = 0.5 * (camera.fx() + camera.fy());
    object
        .iter()
        .map(|p| {
            let c = pose.transform(p);
            let centre = camera.project(&c)?;
            let distance_mm = c.norm();
            let radius_px = if distance_mm > radius_mm {
                focal * radius_mm / (distance_mm * distance_mm - radius_mm * radius_mm).sqrt()
            } else {
                f64::INFINITY
            };
            Some(SphereImage {
                centre_px: [centre.x, centre.y],
                radius_px,
                distance_mm,
            })
        })
        .collect()
}

/// Checks the visibility rules: every feature in front of the camera, its
/// image disc inside the image with [`VISIBILITY_MARGIN_PX`], and no disc
/// overlapping the disc of a nearer sphere.
pub fn visibility(images: &[Option<SphereImage>], camera: &Camera) -> Visibility {
    let mut result = Visibility::default();
    for (index, image) in images.iter().enumerate() {
        let Some(image) = image else {
            result.behind.push(index);
            continue;
        };
        let centre = Vector2::new(image.centre_px[0], image.centre_px[1]);
        if !camera.contains(&centre, VISIBILITY_MARGIN_PX + image.radius_px) {
            result.outside.push(index);
        }
    }
    for (i, a) in images.iter().enumerate() {
        let Some(a) = a else { continue };
        for (j, b) in images.iter().enumerate() {
            let Some(b) = b else { continue };
            if i == j || b.distance_mm >= a.distance_mm {
                continue;
            }
            let gap = ((a.centre_px[0] - b.centre_px[0]).powi(2)
                + (a.centre_px[1] - b.centre_px[1]).powi(2))
            .sqrt();
            if gap < a.radius_px + b.radius_px {
                result.occluded.push((i, j));
            }
        }
    }
    result
}

/// The smallest visibility margin of a scenario, px: the least distance by
/// which a sphere's disc stays inside the image (with
/// [`VISIBILITY_MARGIN_PX`]) or two discs stay apart. Non-negative exactly
/// when [`visibility`] finds nothing wrong (up to ties at zero);
/// `−∞` when a sphere is behind the camera.
pub fn visibility_margin_px(images: &[Option<SphereImage>], camera: &Camera) -> f64 {
    let mut margin = f64::INFINITY;
    let (width, height) = (camera.width() as f64, camera.height() as f64);
    for (i, image) in images.iter().enumerate() {
        let Some(a) = image else {
            return f64::NEG_INFINITY;
        };
        let [x, y] = a.centre_px;
        let edge = VISIBILITY_MARGIN_PX + a.radius_px;
        margin = margin
            .min(x - edge)
            .min(y - edge)
            .min(width - edge - x)
            .min(height - edge - y);
        for b in images[i + 1..].iter().flatten() {
            let gap = ((x - b.centre_px[0]).powi(2) + (y - b.centre_px[1]).powi(2)).sqrt();
            margin = margin.min(gap - a.radius_px - b.radius_px);
        }
    }
    margin
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn margin_agrees_with_the_rules() {
        let camera = Camera::paper();
        let object = crate::synthetic::biprism_points(50.0);
        for tilt in (-90..=90).step_by(5) {
            for (depth, offset) in [(200.0, 0.0), (500.0, 60.0), (900.0, 0.0), (400.0, 150.0)] {
                let s = Scenario {
                    index: 0,
                    depth_mm: depth,
                    offset_x_mm: offset,
                    offset_y_mm: 0.0,
                    tilt_deg: tilt as f64,
                    pan_deg: 10.0,
                    roll_deg: 0.0,
                    sigma_px: 0.5,
                };
                let images = sphere_images(&camera, &s.pose(), &object, 10.0);
                let margin = visibility_margin_px(&images, &camera);
                assert_eq!(
                    margin >= 0.0,
                    visibility(&images, &camera).is_visible(),
                    "tilt {tilt} depth {depth}: {margin}"
                );
            }
        }
    }

    #[test]
    fn ranges_parse() {
        assert_eq!(
            "200..1000:200".parse::<Range>().unwrap().values,
            vec![200.0, 400.0, 600.0, 800.0, 1000.0]
        );
        assert_eq!(
            "-90..90:45".parse::<Range>().unwrap().values,
            vec![-90.0, -45.0, 0.0, 45.0, 90.0]
        );
        assert_eq!("0.5".parse::<Range>().unwrap().values, vec![0.5]);
        assert_eq!(
            "0,50,100".parse::<Range>().unwrap().values,
            vec![0.0, 50.0, 100.0]
        );
        assert_eq!(
            "0..1".parse::<Range>().unwrap().values.len(),
            DEFAULT_STEP_COUNT
        );
        assert_eq!("0..1:0.3".parse::<Range>().unwrap().values.len(), 4);
        // Descending ranges run from A down to B in both forms.
        assert_eq!(
            "1000..200:200".parse::<Range>().unwrap().values,
            vec![1000.0, 800.0, 600.0, 400.0, 200.0]
        );
        assert_eq!(
            "1000..200".parse::<Range>().unwrap().values,
            vec![1000.0, 800.0, 600.0, 400.0, 200.0]
        );
        assert_eq!(
            "10..0:4".parse::<Range>().unwrap().values,
            vec![10.0, 6.0, 2.0]
        );
        let err = "1..2:0".parse::<Range>().unwrap_err();
        assert!(err.to_string().contains("step must be positive"), "{err}");
        let err = "a..2".parse::<Range>().unwrap_err();
        assert!(err.to_string().contains("'a' is not a number"), "{err}");
        assert!("".parse::<Range>().is_err());
        assert!("nan".parse::<Range>().is_err());
    }

    #[test]
    fn grid_rejects_impossible_values() {
        let ok = |text: &str| text.parse::<Range>().unwrap();
        let err = ScenarioGrid::new(
            ok("0..100:50"),
            ok("0"),
            ok("0"),
            ok("0"),
            ok("0"),
            ok("0"),
            ok("0.5"),
        )
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "depth must be positive (mm in front of the camera), got 0"
        );
        let err = ScenarioGrid::new(
            ok("100"),
            ok("0"),
            ok("0"),
            ok("0"),
            ok("0"),
            ok("0"),
            ok("-1"),
        )
        .unwrap_err();
        assert!(
            err.to_string().contains("noise σ must be non-negative"),
            "{err}"
        );
        let err = ScenarioGrid::new(
            ok("100"),
            ok("0"),
            ok("0"),
            ok("-200..200:10"),
            ok("0"),
            ok("0"),
            ok("0.5"),
        )
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "tilt must be within −180…180° (each attitude once), got -200"
        );
        assert!(ScenarioGrid::new(
            ok("100"),
            ok("0"),
            ok("0"),
            ok("-180..180:90"),
            ok("180"),
            ok("-180"),
            ok("0.5"),
        )
        .is_ok());
    }

    #[test]
    fn paper_protocol_size_and_order() {
        let grid = ScenarioGrid::paper_protocol(2.0);
        assert_eq!(grid.len(), 5 * 3 * 91);
        let scenarios = grid.scenarios();
        assert_eq!(scenarios[0].depth_mm, 200.0);
        assert_eq!(scenarios[0].tilt_deg, -90.0);
        assert_eq!(scenarios[1].tilt_deg, -88.0);
        assert!(scenarios.iter().enumerate().all(|(i, s)| s.index == i));
    }

    #[test]
    fn scenario_pose_convention() {
        let s = Scenario {
            index: 0,
            depth_mm: 500.0,
            offset_x_mm: 10.0,
            offset_y_mm: -5.0,
            tilt_deg: 90.0,
            pan_deg: 0.0,
            roll_deg: 0.0,
            sigma_px: 0.5,
        };
        let pose = s.pose();
        assert_relative_eq!(pose.translation, Vector3::new(10.0, -5.0, 500.0));
        // Tilting +90° about X takes the marker's +y axis to the camera's +z.
        assert_relative_eq!(pose.rotation * Vector3::y(), Vector3::z(), epsilon = 1e-12);
    }

    #[test]
    fn head_on_biprism_hides_p3_and_o0_behind_p1() {
        let camera = Camera::paper();
        let object = crate::synthetic::biprism_points(50.0);
        let s = Scenario {
            index: 0,
            depth_mm: 500.0,
            offset_x_mm: 0.0,
            offset_y_mm: 0.0,
            tilt_deg: 0.0,
            pan_deg: 0.0,
            roll_deg: 0.0,
            sigma_px: 0.5,
        };
        // Base attitude: the marker's z axis (O0→P1) points away from the
        // camera, so P3 (z = −50) is nearest and hides O0 and P1.
        let images = sphere_images(&camera, &s.pose(), &object, 10.0);
        let v = visibility(&images, &camera);
        assert!(!v.is_visible());
        assert!(v.occluded.contains(&(0, 3)), "{v:?}");
        assert!(v.occluded.contains(&(1, 3)), "{v:?}");
        assert!(v.occluded.contains(&(1, 0)), "{v:?}");
        // Tilted by 60°, the line of sight no longer passes through all three.
        let tilted = Scenario {
            tilt_deg: 60.0,
            ..s
        };
        let v = visibility(
            &sphere_images(&camera, &tilted.pose(), &object, 10.0),
            &camera,
        );
        assert!(v.is_visible(), "{v:?}");
    }

    #[test]
    fn behind_and_outside_are_reported() {
        let camera = Camera::paper();
        let object = crate::synthetic::biprism_points(50.0);
        let s = Scenario {
            index: 0,
            depth_mm: 30.0,
            offset_x_mm: 0.0,
            offset_y_mm: 0.0,
            tilt_deg: 30.0,
            pan_deg: 20.0,
            roll_deg: 0.0,
            sigma_px: 0.5,
        };
        let v = visibility(&sphere_images(&camera, &s.pose(), &object, 10.0), &camera);
        assert!(!v.behind.is_empty());
        let far_off = Scenario {
            depth_mm: 500.0,
            offset_x_mm: 400.0,
            tilt_deg: 30.0,
            ..s
        };
        let v = visibility(
            &sphere_images(&camera, &far_off.pose(), &object, 10.0),
            &camera,
        );
        assert!(v.behind.is_empty() && !v.outside.is_empty(), "{v:?}");
    }
}
