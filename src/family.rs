//! Layout families: parameterisations that map a parameter vector to marker
//! points, with bounds, a natural start, and fabrication constraints.
//!
//! * `biprism`: the paper's bipyramid (Fig. 6) generalised. Six arms from the
//!   centre along ±z, ±x, −z... in the paper's order (P1 = +z, P2 = +x,
//!   P3 = −z, P4 = −x, P5 = +y, P6 = −y), each with its own length and,
//!   optionally, a tilt of its direction by two angles (about the two axes
//!   perpendicular to its nominal axis, each within ±[`MAX_ARM_TILT_DEG`]);
//!   the centre point O0 is optional. By default the *hub* (where the arms
//!   meet, and O0 when it is used) may also move anywhere in the envelope:
//!   the envelope is a size limit, not a statement of where the hub sits, and
//!   a hub pinned at the envelope's centre spends a sphere on the position
//!   that tells the least about rotation (a hub in a corner with arms to the
//!   other corners has ~14% more spread). `free_hub: false` pins it at the
//!   centre. With the hub at the centre, all arms at L = 50 mm and no tilt it
//!   is the paper's biprism, the family's natural start.
//! * `tetrahedron`: four free vertices, plus optionally a centre point at
//!   their centroid.
//! * `custom`: N free points, or a layout file whose points marked `fixed`
//!   stay where they are while the others move.
//!
//! The **envelope** is a box centred on the layout's origin that bounds the
//! sphere *centres* (as the paper's "100 mm" biprism has centres at ±50 mm).

use crate::layout::{Layout, LayoutPoint};
use nalgebra::{Rotation3, Vector3};
use rand::Rng;
use serde::Serialize;

/// Largest tilt of a biprism arm from its nominal axis, per angle, degrees.
/// Two tilts of up to 90° reach the whole half-space around the nominal axis
/// (the first tilts the arm towards one perpendicular axis, the second swings
/// it about that axis), so the six arms together can reach any direction;
/// the margin beyond 90° keeps optima off the bounds.
pub const MAX_ARM_TILT_DEG: f64 = 120.0;

/// Directions (in units of the envelope's half sizes) for spread-out starts:
/// four alternating corners (a regular tetrahedron inscribed in the box), the
/// other four corners, then the six face centres.
pub const SPREAD_DIRECTIONS: [[f64; 3]; 14] = [
    [1.0, 1.0, 1.0],
    [1.0, -1.0, -1.0],
    [-1.0, 1.0, -1.0],
    [-1.0, -1.0, 1.0],
    [-1.0, -1.0, -1.0],
    [-1.0, 1.0, 1.0],
    [1.0, -1.0, 1.0],
    [1.0, 1.0, -1.0],
    [1.0, 0.0, 0.0],
    [-1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, -1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.0, 0.0, -1.0],
];

/// Biprism arms of the spread start differ in length by this much, mm.
pub const SPREAD_STAGGER_MM: f64 = 1.5;

/// Widths of the distance repulsion in [`Constraints::spread_distances`],
/// in units of the wanted spacing, widest first (a continuation: wide
/// repulsion moves whole crowds of distances towards empty stretches of the
/// range, narrow repulsion then separates neighbours).
pub const SPREAD_WIDTHS: [f64; 6] = [4.0, 3.0, 2.0, 1.5, 1.2, 1.0];
/// Gradient steps of each phase of [`Constraints::spread_distances`].
pub const SPREAD_STEPS: usize = 300;
/// The finishing phase of [`Constraints::spread_distances`] asks sorted
/// neighbouring distances for this multiple of the wanted spacing, so that
/// it ends inside the constraint rather than on its edge.
pub const SPREAD_FINISH_SPACING: f64 = 1.05;
/// Free points are first moved by up to this much in each axis (seeded), mm:
/// a symmetric layout repeats distances exactly, and the repulsion between
/// equal distances has no direction.
pub const SPREAD_JITTER_MM: f64 = 0.5;
/// Weight of the gap shortfall (squared, mm²) in the spreading energies.
const SPREAD_GAP_WEIGHT: f64 = 10.0;

/// Why a family or constraint set cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FamilyError {
    /// The envelope is not a usable box.
    #[error("the envelope must be positive and finite in every axis, got {0:?} mm")]
    BadEnvelope([f64; 3]),
    /// The envelope cannot hold even one sphere.
    #[error("the envelope {envelope:?} mm is smaller than one sphere of {diameter_mm} mm")]
    EnvelopeTooSmall {
        /// Envelope, mm.
        envelope: [f64; 3],
        /// Sphere diameter, mm.
        diameter_mm: f64,
    },
    /// Too few points for PnP.
    #[error("a layout needs at least 4 points, got {0}")]
    TooFewPoints(usize),
    /// A custom family's start file has no free point.
    #[error("every point of the start layout is fixed: nothing to optimise")]
    NothingFree,
    /// The envelope string could not be parsed.
    #[error("cannot parse envelope '{0}': give one size (a cube) or X,Y,Z in mm")]
    ParseEnvelope(String),
}

/// The box that bounds the sphere centres, centred on the marker origin.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Envelope {
    /// Full size along x, y, z, mm.
    pub size_mm: [f64; 3],
}

impl Envelope {
    /// A box of the given size (mm), checked to be positive and finite.
    pub fn new(size_mm: [f64; 3]) -> Result<Self, FamilyError> {
        if size_mm.iter().all(|s| s.is_finite() && *s > 0.0) {
            Ok(Self { size_mm })
        } else {
            Err(FamilyError::BadEnvelope(size_mm))
        }
    }

    /// Half sizes, mm.
    pub fn half(&self) -> Vector3<f64> {
        Vector3::new(self.size_mm[0], self.size_mm[1], self.size_mm[2]) * 0.5
    }

    /// How far `p` lies outside the box, mm (0 inside).
    pub fn excess_mm(&self, p: &Vector3<f64>) -> f64 {
        let half = self.half();
        (0..3).map(|k| (p[k].abs() - half[k]).max(0.0)).sum()
    }
}

impl std::str::FromStr for Envelope {
    type Err = FamilyError;
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let values: Vec<f64> = text
            .split(',')
            .map(|v| v.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| FamilyError::ParseEnvelope(text.to_string()))?;
        match values.as_slice() {
            [cube] => Envelope::new([*cube; 3]),
            [x, y, z] => Envelope::new([*x, *y, *z]),
            _ => Err(FamilyError::ParseEnvelope(text.to_string())),
        }
    }
}

/// Which family, with its options.
#[derive(Debug, Clone, PartialEq)]
pub enum FamilyKind {
    /// Six arms (optionally tilted) and an optional centre point.
    Biprism {
        /// Include the centre point O0 (a sphere at the hub).
        centre: bool,
        /// Let each arm tilt off its axis.
        tilts: bool,
        /// Let the hub move within the envelope (three more parameters).
        free_hub: bool,
    },
    /// Four free vertices and an optional centre point.
    Tetrahedron {
        /// Include a point at the vertices' centroid.
        centre: bool,
    },
    /// Free points: `count` of them, or the points of a start layout with
    /// some fixed.
    Custom {
        /// Number of points (ignored when `start` is given).
        count: usize,
        /// A start layout whose `fixed` points stay put.
        start: Option<Layout>,
    },
}

/// A family in an envelope: the map from parameters to points.
#[derive(Debug, Clone, PartialEq)]
pub struct Family {
    kind: FamilyKind,
    envelope: Envelope,
    sphere_diameter_mm: f64,
}

/// The paper's arm directions, in its point order P1…P6.
const ARM_AXES: [[f64; 3]; 6] = [
    [0.0, 0.0, 1.0],
    [1.0, 0.0, 0.0],
    [0.0, 0.0, -1.0],
    [-1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, -1.0, 0.0],
];

impl Family {
    /// A family of `kind` within `envelope`, for spheres of `sphere_diameter_mm`.
    pub fn new(
        kind: FamilyKind,
        envelope: Envelope,
        sphere_diameter_mm: f64,
    ) -> Result<Self, FamilyError> {
        let smallest = envelope
            .size_mm
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        if smallest < sphere_diameter_mm {
            return Err(FamilyError::EnvelopeTooSmall {
                envelope: envelope.size_mm,
                diameter_mm: sphere_diameter_mm,
            });
        }
        if let FamilyKind::Custom { count, start } = &kind {
            match start {
                Some(layout) => {
                    if layout.points.len() < 4 {
                        return Err(FamilyError::TooFewPoints(layout.points.len()));
                    }
                    if layout.points.iter().all(|p| p.fixed) {
                        return Err(FamilyError::NothingFree);
                    }
                }
                None if *count < 4 => return Err(FamilyError::TooFewPoints(*count)),
                None => {}
            }
        }
        Ok(Self {
            kind,
            envelope,
            sphere_diameter_mm,
        })
    }

    /// The family's kind.
    pub fn kind(&self) -> &FamilyKind {
        &self.kind
    }

    /// The envelope.
    pub fn envelope(&self) -> Envelope {
        self.envelope
    }

    /// Short name: biprism, tetrahedron or custom.
    pub fn name(&self) -> &'static str {
        match self.kind {
            FamilyKind::Biprism { .. } => "biprism",
            FamilyKind::Tetrahedron { .. } => "tetrahedron",
            FamilyKind::Custom { .. } => "custom",
        }
    }

    /// Number of parameters.
    pub fn dimension(&self) -> usize {
        match &self.kind {
            FamilyKind::Biprism {
                tilts, free_hub, ..
            } => 6 + if *tilts { 12 } else { 0 } + if *free_hub { 3 } else { 0 },
            FamilyKind::Tetrahedron { .. } => 12,
            FamilyKind::Custom {
                start: Some(layout),
                ..
            } => 3 * layout.points.iter().filter(|p| !p.fixed).count(),
            FamilyKind::Custom { count, .. } => 3 * count,
        }
    }

    /// Number of points a parameter vector maps to.
    pub fn point_count(&self) -> usize {
        match &self.kind {
            FamilyKind::Biprism { centre, .. } => 6 + usize::from(*centre),
            FamilyKind::Tetrahedron { centre } => 4 + usize::from(*centre),
            FamilyKind::Custom {
                start: Some(layout),
                ..
            } => layout.points.len(),
            FamilyKind::Custom { count, .. } => *count,
        }
    }

    /// Lower and upper bounds of every parameter (arm lengths in mm, tilts in
    /// degrees, coordinates in mm).
    pub fn bounds(&self) -> (Vec<f64>, Vec<f64>) {
        let half = self.envelope.half();
        let mut lower = Vec::with_capacity(self.dimension());
        let mut upper = Vec::with_capacity(self.dimension());
        match &self.kind {
            FamilyKind::Biprism {
                tilts, free_hub, ..
            } => {
                // An arm reaches at most the envelope's corner (the opposite
                // corner when the hub moves); the box itself is enforced as a
                // constraint.
                let longest = if *free_hub { 2.0 } else { 1.0 } * half.norm();
                for _ in 0..6 {
                    lower.push(self.sphere_diameter_mm);
                    upper.push(longest);
                }
                if *tilts {
                    for _ in 0..12 {
                        lower.push(-MAX_ARM_TILT_DEG);
                        upper.push(MAX_ARM_TILT_DEG);
                    }
                }
                if *free_hub {
                    for k in 0..3 {
                        lower.push(-half[k]);
                        upper.push(half[k]);
                    }
                }
            }
            FamilyKind::Tetrahedron { .. } | FamilyKind::Custom { .. } => {
                for _ in 0..self.dimension() / 3 {
                    for k in 0..3 {
                        lower.push(-half[k]);
                        upper.push(half[k]);
                    }
                }
            }
        }
        (lower, upper)
    }

    /// Clamps a parameter vector into the bounds.
    pub fn clamp(&self, params: &[f64]) -> Vec<f64> {
        let (lower, upper) = self.bounds();
        params
            .iter()
            .zip(lower.iter().zip(&upper))
            .map(|(p, (lo, hi))| {
                if p.is_finite() {
                    p.clamp(*lo, *hi)
                } else {
                    0.5 * (lo + hi)
                }
            })
            .collect()
    }

    /// The natural start: the paper's biprism scaled to the envelope
    /// (biprism), a regular tetrahedron inscribed in it (tetrahedron), the
    /// start file's free points or points spread on the envelope's corners
    /// and face centres (custom).
    pub fn initial(&self) -> Vec<f64> {
        let half = self.envelope.half();
        match &self.kind {
            FamilyKind::Biprism {
                tilts, free_hub, ..
            } => {
                let mut params: Vec<f64> = ARM_AXES
                    .iter()
                    .map(|axis| {
                        let axis = Vector3::new(axis[0], axis[1], axis[2]);
                        (0..3)
                            .filter(|&k| axis[k] != 0.0)
                            .map(|k| half[k])
                            .fold(f64::INFINITY, f64::min)
                    })
                    .collect();
                if *tilts {
                    params.extend([0.0; 12]);
                }
                if *free_hub {
                    params.extend([0.0; 3]);
                }
                params
            }
            FamilyKind::Tetrahedron { .. } => SPREAD_DIRECTIONS[..4]
                .iter()
                .flat_map(|s| (0..3).map(move |k| s[k] * half[k]))
                .collect(),
            FamilyKind::Custom {
                start: Some(layout),
                ..
            } => layout
                .points
                .iter()
                .filter(|p| !p.fixed)
                .flat_map(|p| [p.position.x, p.position.y, p.position.z])
                .collect(),
            FamilyKind::Custom { count, .. } => {
                // Corners first, then face centres: well spread and
                // noncoplanar; further rounds shrink by 10%.
                let corners = SPREAD_DIRECTIONS;
                (0..*count)
                    .flat_map(|i| {
                        let c = corners[i % corners.len()];
                        let shrink = 0.9f64.powi((i / corners.len()) as i32 + 1);
                        (0..3)
                            .map(move |k| c[k] * half[k] * shrink)
                            .collect::<Vec<_>>()
                    })
                    .collect()
            }
        }
    }

    /// A second, maximum-spread start: biprism arms pointed at alternating
    /// corners of the envelope (each arm at the corner nearest its own axis,
    /// alternating so that no two arms share a corner), custom points on the
    /// corners at full size; the natural start for the other families (a
    /// regular tetrahedron already spans the box).
    pub fn spread(&self) -> Vec<f64> {
        match &self.kind {
            FamilyKind::Biprism {
                tilts: true,
                free_hub,
                ..
            } => {
                let half = self.envelope.half();
                // Corner targets for P1..P6 (nominal axes +z, +x, −z, −x, +y,
                // −y), each in its arm's reach. Centred hub: six of the eight
                // corners, two per axis pair. Free hub: the hub in the
                // (−,−,−) corner and the arms to six of the other seven
                // (the far corner included), so hub and arms occupy seven
                // corners.
                let (hub, corners) = if *free_hub {
                    (
                        [-1.0, -1.0, -1.0],
                        [
                            [1.0, 1.0, 1.0],
                            [1.0, -1.0, -1.0],
                            [1.0, 1.0, -1.0],
                            [-1.0, -1.0, 1.0],
                            [-1.0, 1.0, -1.0],
                            [1.0, -1.0, 1.0],
                        ],
                    )
                } else {
                    (
                        [0.0; 3],
                        [
                            [1.0, 1.0, 1.0],
                            [1.0, -1.0, -1.0],
                            [-1.0, 1.0, -1.0],
                            [-1.0, -1.0, 1.0],
                            [1.0, 1.0, -1.0],
                            [-1.0, -1.0, -1.0],
                        ],
                    )
                };
                let scale = |c: [f64; 3]| Vector3::new(c[0] * half.x, c[1] * half.y, c[2] * half.z);
                let hub = scale(hub);
                let mut params = vec![0.0; 6];
                let limit = MAX_ARM_TILT_DEG as i32;
                for (arm, corner) in corners.iter().enumerate() {
                    let target = scale(*corner) - hub;
                    let axis = Vector3::new(ARM_AXES[arm][0], ARM_AXES[arm][1], ARM_AXES[arm][2]);
                    let (a, b) = perpendicular_axes(&axis);
                    // The two tilt angles that point the arm at the corner, to
                    // the nearest degree (a start point: the search refines it).
                    let direction = target.normalize();
                    let mut best = (f64::INFINITY, 0.0, 0.0);
                    for i in -limit..=limit {
                        for j in -limit..=limit {
                            let (first, second) = (i as f64, j as f64);
                            let d = Rotation3::from_scaled_axis(b * second.to_radians())
                                * Rotation3::from_scaled_axis(a * first.to_radians())
                                * axis;
                            let error = (d - direction).norm();
                            if error < best.0 {
                                best = (error, first, second);
                            }
                        }
                    }
                    // Staggered lengths keep the pairwise distances apart
                    // (identifiable spheres); the search's repair phase
                    // finishes the job.
                    params[arm] = target.norm() - SPREAD_STAGGER_MM * arm as f64;
                    params.extend([best.1, best.2]);
                }
                if *free_hub {
                    params.extend([hub.x, hub.y, hub.z]);
                }
                params
            }
            FamilyKind::Custom { count, start: None } => {
                let half = self.envelope.half();
                let corners = &SPREAD_DIRECTIONS[..8];
                let mut params = self.initial();
                for (i, corner) in corners.iter().enumerate().take(*count) {
                    for k in 0..3 {
                        params[3 * i + k] = corner[k] * half[k];
                    }
                }
                params
            }
            _ => self.initial(),
        }
    }

    /// Point names, in point order.
    pub fn names(&self) -> Vec<String> {
        match &self.kind {
            FamilyKind::Biprism { centre, .. } => {
                let mut names: Vec<String> = Vec::new();
                if *centre {
                    names.push("O0".into());
                }
                names.extend((1..=6).map(|i| format!("P{i}")));
                names
            }
            FamilyKind::Tetrahedron { centre } => {
                let mut names: Vec<String> = (1..=4).map(|i| format!("V{i}")).collect();
                if *centre {
                    names.push("C".into());
                }
                names
            }
            FamilyKind::Custom {
                start: Some(layout),
                ..
            } => layout.points.iter().map(|p| p.name.clone()).collect(),
            FamilyKind::Custom { count, .. } => (1..=*count).map(|i| format!("Q{i}")).collect(),
        }
    }

    /// The points of a parameter vector (clamped into bounds first).
    pub fn points(&self, params: &[f64]) -> Vec<Vector3<f64>> {
        let params = self.clamp(params);
        match &self.kind {
            FamilyKind::Biprism {
                centre,
                tilts,
                free_hub,
            } => {
                let hub = if *free_hub {
                    let h = self.dimension() - 3;
                    Vector3::new(params[h], params[h + 1], params[h + 2])
                } else {
                    Vector3::zeros()
                };
                let mut points = Vec::with_capacity(7);
                if *centre {
                    points.push(hub);
                }
                for (arm, axis) in ARM_AXES.iter().enumerate() {
                    let axis = Vector3::new(axis[0], axis[1], axis[2]);
                    let direction = if *tilts {
                        let (a, b) = perpendicular_axes(&axis);
                        let first = params[6 + 2 * arm].to_radians();
                        let second = params[7 + 2 * arm].to_radians();
                        Rotation3::from_scaled_axis(b * second)
                            * Rotation3::from_scaled_axis(a * first)
                            * axis
                    } else {
                        axis
                    };
                    points.push(hub + direction * params[arm]);
                }
                points
            }
            FamilyKind::Tetrahedron { centre } => {
                let mut points: Vec<Vector3<f64>> = params
                    .chunks(3)
                    .map(|c| Vector3::new(c[0], c[1], c[2]))
                    .collect();
                if *centre {
                    points.push(points.iter().sum::<Vector3<f64>>() / 4.0);
                }
                points
            }
            FamilyKind::Custom {
                start: Some(layout),
                ..
            } => {
                let mut free = params.chunks(3);
                layout
                    .points
                    .iter()
                    .map(|p| {
                        if p.fixed {
                            p.position
                        } else {
                            let c = free.next().expect("one chunk per free point");
                            Vector3::new(c[0], c[1], c[2])
                        }
                    })
                    .collect()
            }
            FamilyKind::Custom { .. } => params
                .chunks(3)
                .map(|c| Vector3::new(c[0], c[1], c[2]))
                .collect(),
        }
    }

    /// The family record stored in a layout file.
    pub fn record(&self, params: &[f64]) -> serde_json::Value {
        let params = self.clamp(params);
        match &self.kind {
            FamilyKind::Biprism {
                centre,
                tilts,
                free_hub,
            } => serde_json::json!({
                "kind": "biprism",
                "parameters": {
                    "arm_mm": &params[..6],
                    "arm_tilt_deg": if *tilts { serde_json::json!(params[6..18].chunks(2).collect::<Vec<_>>()) } else { serde_json::Value::Null },
                    "hub_mm": if *free_hub { serde_json::json!(&params[params.len() - 3..]) } else { serde_json::json!([0.0, 0.0, 0.0]) },
                    "centre": centre,
                },
                "envelope_mm": self.envelope.size_mm,
            }),
            FamilyKind::Tetrahedron { centre } => serde_json::json!({
                "kind": "tetrahedron",
                "parameters": {"vertices_mm": params.chunks(3).collect::<Vec<_>>(), "centre": centre},
                "envelope_mm": self.envelope.size_mm,
            }),
            FamilyKind::Custom { .. } => serde_json::json!({
                "kind": "custom",
                "parameters": {"free_points_mm": params.chunks(3).collect::<Vec<_>>()},
                "envelope_mm": self.envelope.size_mm,
            }),
        }
    }

    /// Which points stay where they are (a custom family's start file's
    /// `fixed` points; none for the other families), in point order.
    pub fn fixed_points(&self) -> Vec<bool> {
        match &self.kind {
            FamilyKind::Custom {
                start: Some(layout),
                ..
            } => layout.points.iter().map(|p| p.fixed).collect(),
            _ => vec![false; self.point_count()],
        }
    }

    /// A custom family's parameters that put its free points at `points`
    /// (the inverse of [`Family::points`]); None for the other families,
    /// whose parameters are not coordinates, or for the wrong point count.
    pub fn custom_params(&self, points: &[Vector3<f64>]) -> Option<Vec<f64>> {
        if !matches!(self.kind, FamilyKind::Custom { .. }) || points.len() != self.point_count() {
            return None;
        }
        Some(
            points
                .iter()
                .zip(self.fixed_points())
                .filter(|(_, fixed)| !fixed)
                .flat_map(|(p, _)| [p.x, p.y, p.z])
                .collect(),
        )
    }

    /// The layout of a parameter vector.
    pub fn layout(&self, name: &str, params: &[f64]) -> Layout {
        let fixed = self.fixed_points();
        let sigmas: Vec<Option<f64>> = match &self.kind {
            FamilyKind::Custom {
                start: Some(layout),
                ..
            } => layout.point_sigmas(),
            _ => vec![None; self.point_count()],
        };
        Layout {
            name: name.to_string(),
            points: self
                .names()
                .into_iter()
                .zip(self.points(params))
                .zip(fixed.into_iter().zip(sigmas))
                .map(|((name, position), (fixed, sigma_px))| LayoutPoint {
                    name,
                    position,
                    sigma_px,
                    fixed,
                })
                .collect(),
            sphere_diameter_mm: self.sphere_diameter_mm,
            family: Some(self.record(params)),
            provenance: None,
        }
    }
}

/// Two unit axes perpendicular to a coordinate axis, in a fixed order.
fn perpendicular_axes(axis: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    if axis.x != 0.0 {
        (Vector3::y(), Vector3::z())
    } else if axis.y != 0.0 {
        (Vector3::z(), Vector3::x())
    } else {
        (Vector3::x(), Vector3::y())
    }
}

/// Fabrication constraints on a layout.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Constraints {
    /// The box bounding the sphere centres.
    pub envelope: Envelope,
    /// Sphere diameter, mm.
    pub sphere_diameter_mm: f64,
    /// Smallest gap between two sphere surfaces, mm.
    pub min_gap_mm: f64,
    /// Smallest difference between any two pairwise centre distances, mm, so
    /// that spheres can be told apart without labels (0 disables).
    pub min_distance_diff_mm: f64,
}

/// How far a layout is from meeting each constraint (0 = met), mm.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Violations {
    /// Total distance of sphere centres outside the envelope, mm.
    pub envelope_mm: f64,
    /// Total shortfall of sphere-surface gaps below the minimum, mm.
    pub gap_mm: f64,
    /// Total shortfall of distance differences below the minimum, mm.
    pub distance_diff_mm: f64,
    /// Smallest sphere-surface gap, mm.
    pub smallest_gap_mm: f64,
    /// Smallest difference between two pairwise distances, mm.
    pub smallest_distance_diff_mm: f64,
}

impl Violations {
    /// Every constraint is met.
    pub fn feasible(&self) -> bool {
        self.total() <= 1e-9
    }

    /// Sum of all violations, mm.
    pub fn total(&self) -> f64 {
        self.envelope_mm + self.gap_mm + self.distance_diff_mm
    }

    /// The unmet constraints, in words.
    pub fn describe(&self, constraints: &Constraints) -> Vec<String> {
        // Two decimals, or two significant digits below 0.01 mm, so that a
        // violation never reads as "0.00 mm".
        let mm = |value: f64| {
            if value.abs() >= 0.01 || value == 0.0 {
                format!("{value:.2}")
            } else {
                format!("{value:.1e}")
            }
        };
        let mut out = Vec::new();
        if self.envelope_mm > 1e-9 {
            out.push(format!(
                "sphere centres outside the {:?} mm envelope by {} mm in total",
                constraints.envelope.size_mm,
                mm(self.envelope_mm)
            ));
        }
        if self.gap_mm > 1e-9 {
            out.push(format!(
                "smallest gap between spheres {} mm < {} mm",
                mm(self.smallest_gap_mm),
                constraints.min_gap_mm
            ));
        }
        if self.distance_diff_mm > 1e-9 {
            out.push(format!(
                "pairwise distances differ by as little as {} mm < {} mm (spheres not identifiable)",
                mm(self.smallest_distance_diff_mm),
                constraints.min_distance_diff_mm
            ));
        }
        out
    }
}

impl Constraints {
    /// How many pairwise distances, each at least a sphere diameter plus
    /// the gap and at most the envelope's diagonal, can differ pairwise by
    /// `min_distance_diff_mm` (None when identifiability is off): a layout of
    /// n points needs n(n − 1)/2 of them. A necessary condition only.
    pub fn distinct_distance_capacity(&self) -> Option<usize> {
        if self.min_distance_diff_mm <= 0.0 {
            return None;
        }
        let closest = self.sphere_diameter_mm + self.min_gap_mm;
        let farthest = self.envelope.half().norm() * 2.0;
        if farthest < closest {
            return Some(0);
        }
        Some(((farthest - closest) / self.min_distance_diff_mm).floor() as usize + 1)
    }

    /// These constraints with the gap and the distance difference raised by
    /// `fraction` of themselves plus `margin_mm` (a difference of 0 stays
    /// off); the envelope is kept.
    pub fn tightened(&self, fraction: f64, margin_mm: f64) -> Constraints {
        let tighten = |value: f64| value * (1.0 + fraction) + margin_mm;
        Constraints {
            min_gap_mm: tighten(self.min_gap_mm),
            min_distance_diff_mm: if self.min_distance_diff_mm > 0.0 {
                tighten(self.min_distance_diff_mm)
            } else {
                0.0
            },
            ..*self
        }
    }

    /// Moves the free points (`fixed[i]` false) of `points` until their
    /// pairwise distances differ by at least `min_distance_diff_mm`, the
    /// spheres keep their gap and every centre stays in the envelope, and
    /// says whether that was reached (`points` then holds the layout; else
    /// the closest it got).
    ///
    /// A dedicated repair for the identifiability constraint, which a
    /// general-purpose repair cannot meet beyond about ten points: the
    /// n(n − 1)/2 distances must then fill most of the range the envelope
    /// allows at nearly even spacing, and the constraint (a sum of kinks
    /// over sorted neighbours) only ever sees the neighbours of a crowd,
    /// never the empty stretches elsewhere. Here each sorted pair of
    /// distances repels the other with a Gaussian energy
    /// exp(−Δ²/(2w²)), with w shrinking over [`SPREAD_WIDTHS`] (times the
    /// wanted spacing): wide repulsion spreads the crowds over the whole
    /// range, narrow repulsion separates neighbours. A final phase minimises
    /// the squared shortfall of sorted neighbours below
    /// [`SPREAD_FINISH_SPACING`] times the spacing. Every phase is projected
    /// gradient descent (the projection is the envelope; the gap is a
    /// squared penalty) with a backtracking step, [`SPREAD_STEPS`] steps at
    /// most, and the whole ends as soon as the constraints are met. The free
    /// points are first jittered by up to [`SPREAD_JITTER_MM`] from `rng`.
    ///
    /// On the default constraints (100 mm cube, 10 mm spheres, 2 mm gap,
    /// 1 mm difference, tightened by the search's margin) it reaches them for
    /// 12 and 13 points from the custom family's start; for 16 it gets the
    /// distances 0.46 mm apart at best (three seeded tries), and the search
    /// refuses it up front.
    pub fn spread_distances(
        &self,
        points: &mut [Vector3<f64>],
        fixed: &[bool],
        rng: &mut impl Rng,
    ) -> bool {
        let half = self.envelope.half();
        let is_free = |i: usize| !fixed.get(i).copied().unwrap_or(false);
        if self.violations(points).feasible() {
            return true;
        }
        for (i, p) in points.iter_mut().enumerate() {
            if is_free(i) {
                for k in 0..3 {
                    p[k] = (p[k] + SPREAD_JITTER_MM * rng.random_range(-1.0..=1.0))
                        .clamp(-half[k], half[k]);
                }
            }
        }
        let spacing = self.min_distance_diff_mm;
        let mut work = SpreadWork::new(points.len());
        let phases = SPREAD_WIDTHS
            .iter()
            .map(|w| SpreadEnergy::Repulsion {
                width_mm: w * spacing,
            })
            .chain(std::iter::once(SpreadEnergy::Neighbours {
                spacing_mm: SPREAD_FINISH_SPACING * spacing,
            }));
        for energy in phases {
            if self.descend(points, fixed, energy, &mut work) {
                return true;
            }
        }
        self.violations(points).feasible()
    }

    /// One phase of [`Constraints::spread_distances`]: projected gradient
    /// descent on `energy`; true once the constraints are met.
    fn descend(
        &self,
        points: &mut [Vector3<f64>],
        fixed: &[bool],
        energy: SpreadEnergy,
        work: &mut SpreadWork,
    ) -> bool {
        let half = self.envelope.half();
        let closest = self.sphere_diameter_mm + self.min_gap_mm;
        let mut value = work.energy(points, closest, energy);
        let mut gradient = work.gradient.clone();
        let mut step = 1.0;
        for _ in 0..SPREAD_STEPS {
            if self.violations(points).feasible() {
                return true;
            }
            loop {
                work.trial.clear();
                work.trial
                    .extend(points.iter().zip(&gradient).enumerate().map(|(i, (p, g))| {
                        if fixed.get(i).copied().unwrap_or(false) {
                            *p
                        } else {
                            let moved = p - step * g;
                            Vector3::new(
                                moved.x.clamp(-half.x, half.x),
                                moved.y.clamp(-half.y, half.y),
                                moved.z.clamp(-half.z, half.z),
                            )
                        }
                    }));
                let trial = std::mem::take(&mut work.trial);
                let trial_value = work.energy(&trial, closest, energy);
                if trial_value < value || step < 1e-12 {
                    points.copy_from_slice(&trial);
                    value = trial_value;
                    gradient.copy_from_slice(&work.gradient);
                    work.trial = trial;
                    break;
                }
                work.trial = trial;
                step *= 0.5;
            }
            step *= 1.5;
        }
        self.violations(points).feasible()
    }

    /// Measures the violations of `points`.
    pub fn violations(&self, points: &[Vector3<f64>]) -> Violations {
        let mut v = Violations {
            smallest_gap_mm: f64::INFINITY,
            smallest_distance_diff_mm: f64::INFINITY,
            ..Violations::default()
        };
        v.envelope_mm = points.iter().map(|p| self.envelope.excess_mm(p)).sum();
        let mut distances = Vec::with_capacity(points.len() * (points.len() - 1) / 2);
        for (i, a) in points.iter().enumerate() {
            for b in &points[i + 1..] {
                let d = (a - b).norm();
                distances.push(d);
                let gap = d - self.sphere_diameter_mm;
                v.smallest_gap_mm = v.smallest_gap_mm.min(gap);
                v.gap_mm += (self.min_gap_mm - gap).max(0.0);
            }
        }
        distances.sort_by(f64::total_cmp);
        for pair in distances.windows(2) {
            let diff = pair[1] - pair[0];
            v.smallest_distance_diff_mm = v.smallest_distance_diff_mm.min(diff);
            if self.min_distance_diff_mm > 0.0 {
                v.distance_diff_mm += (self.min_distance_diff_mm - diff).max(0.0);
            }
        }
        v
    }
}

/// The energies [`Constraints::spread_distances`] descends.
#[derive(Debug, Clone, Copy)]
enum SpreadEnergy {
    /// Gaussian repulsion of width `width_mm` between every two distances.
    Repulsion { width_mm: f64 },
    /// Squared shortfall of sorted neighbouring distances below `spacing_mm`.
    Neighbours { spacing_mm: f64 },
}

/// Buffers of [`Constraints::spread_distances`], allocated once per call.
struct SpreadWork {
    /// Pairwise distances with their point indices, sorted.
    pairs: Vec<(f64, usize, usize)>,
    /// Derivative of the energy by each sorted distance.
    by_distance: Vec<f64>,
    /// Gradient of the last energy evaluated by each point.
    gradient: Vec<Vector3<f64>>,
    /// A trial step's points.
    trial: Vec<Vector3<f64>>,
}

impl SpreadWork {
    fn new(points: usize) -> Self {
        let pairs = points * points.saturating_sub(1) / 2;
        Self {
            pairs: Vec::with_capacity(pairs),
            by_distance: Vec::with_capacity(pairs),
            gradient: vec![Vector3::zeros(); points],
            trial: Vec::with_capacity(points),
        }
    }

    /// The energy of `points` (with the gap below `closest` as a squared
    /// penalty), leaving its gradient in `self.gradient`.
    fn energy(&mut self, points: &[Vector3<f64>], closest: f64, energy: SpreadEnergy) -> f64 {
        self.pairs.clear();
        for (i, a) in points.iter().enumerate() {
            for (j, b) in points.iter().enumerate().skip(i + 1) {
                self.pairs.push(((a - b).norm(), i, j));
            }
        }
        self.pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let m = self.pairs.len();
        self.by_distance.clear();
        self.by_distance.resize(m, 0.0);
        let mut value = 0.0;
        for k in 0..m {
            let d = self.pairs[k].0;
            match energy {
                SpreadEnergy::Repulsion { width_mm } => {
                    // Beyond four widths the terms are below 3.4e-4: cut.
                    for l in k + 1..m {
                        let apart = self.pairs[l].0 - d;
                        if apart > 4.0 * width_mm {
                            break;
                        }
                        let term = (-apart * apart / (2.0 * width_mm * width_mm)).exp();
                        value += term;
                        let slope = -apart / (width_mm * width_mm) * term;
                        self.by_distance[l] += slope;
                        self.by_distance[k] -= slope;
                    }
                }
                SpreadEnergy::Neighbours { spacing_mm } => {
                    if k + 1 < m {
                        let short = spacing_mm - (self.pairs[k + 1].0 - d);
                        if short > 0.0 {
                            value += short * short;
                            self.by_distance[k + 1] -= 2.0 * short;
                            self.by_distance[k] += 2.0 * short;
                        }
                    }
                }
            }
            let short = closest - d;
            if short > 0.0 {
                value += SPREAD_GAP_WEIGHT * short * short;
                self.by_distance[k] -= 2.0 * SPREAD_GAP_WEIGHT * short;
            }
        }
        self.gradient.iter_mut().for_each(|g| *g = Vector3::zeros());
        for (&(d, i, j), slope) in self.pairs.iter().zip(&self.by_distance) {
            if *slope != 0.0 && d > 0.0 {
                let along = (points[i] - points[j]) * (slope / d);
                self.gradient[i] += along;
                self.gradient[j] -= along;
            }
        }
        value
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn cube(size: f64) -> Envelope {
        Envelope::new([size; 3]).unwrap()
    }

    #[test]
    fn biprism_start_is_the_papers_biprism() {
        for (free_hub, dimension) in [(false, 18), (true, 21)] {
            let family = Family::new(
                FamilyKind::Biprism {
                    centre: true,
                    tilts: true,
                    free_hub,
                },
                cube(100.0),
                10.0,
            )
            .unwrap();
            let points = family.points(&family.initial());
            let paper = crate::synthetic::biprism_points(50.0);
            for (a, b) in points.iter().zip(&paper) {
                assert_relative_eq!(a, b, epsilon = 1e-12);
            }
            assert_eq!(family.names()[0], "O0");
            assert_eq!(family.dimension(), dimension);
        }
    }

    #[test]
    fn a_free_hub_moves_every_point_and_its_spread_start_fills_seven_corners() {
        let family = Family::new(
            FamilyKind::Biprism {
                centre: true,
                tilts: true,
                free_hub: true,
            },
            cube(100.0),
            10.0,
        )
        .unwrap();
        let mut params = family.initial();
        let shifted = {
            let n = params.len();
            params[n - 3..].copy_from_slice(&[5.0, -7.0, 11.0]);
            family.points(&params)
        };
        let offset = Vector3::new(5.0, -7.0, 11.0);
        for (a, b) in shifted.iter().zip(crate::synthetic::biprism_points(50.0)) {
            assert_relative_eq!(*a, b + offset, epsilon = 1e-12);
        }
        let points = family.points(&family.spread());
        assert_relative_eq!(points[0], Vector3::new(-50.0, -50.0, -50.0));
        let mut corners: Vec<[i32; 3]> = points
            .iter()
            .map(|p| {
                for k in 0..3 {
                    // Staggered lengths: within a few mm of the corner.
                    assert!((p[k].abs() - 50.0).abs() < 10.0, "{p:?}");
                }
                [
                    p.x.signum() as i32,
                    p.y.signum() as i32,
                    p.z.signum() as i32,
                ]
            })
            .collect();
        corners.sort();
        corners.dedup();
        assert_eq!(corners.len(), 7, "seven distinct corners: {points:?}");
        assert_eq!(family.record(&params)["parameters"]["hub_mm"][2], 11.0);
    }

    #[test]
    fn spread_start_points_arms_at_corners() {
        let family = Family::new(
            FamilyKind::Biprism {
                centre: true,
                tilts: true,
                free_hub: false,
            },
            cube(100.0),
            10.0,
        )
        .unwrap();
        let points = family.points(&family.spread());
        for p in &points[1..] {
            for k in 0..3 {
                assert!((p[k].abs() - 50.0).abs() < 6.0, "{p:?}");
            }
        }
        let custom = Family::new(
            FamilyKind::Custom {
                count: 7,
                start: None,
            },
            cube(100.0),
            10.0,
        )
        .unwrap();
        assert!(custom
            .points(&custom.spread())
            .iter()
            .all(|p| p.abs() == Vector3::new(50.0, 50.0, 50.0)));
    }

    #[test]
    fn tilts_move_arms_off_their_axes() {
        let family = Family::new(
            FamilyKind::Biprism {
                centre: false,
                tilts: true,
                free_hub: false,
            },
            cube(100.0),
            10.0,
        )
        .unwrap();
        let mut params = family.initial();
        params[6] = 30.0;
        let points = family.points(&params);
        assert_relative_eq!(points[0].norm(), 50.0, epsilon = 1e-12);
        assert!((points[0].z - 50.0 * 30f64.to_radians().cos()).abs() < 1e-9);
    }

    #[test]
    fn tetrahedron_and_custom_starts_fit_the_envelope() {
        let constraints = Constraints {
            envelope: cube(100.0),
            sphere_diameter_mm: 10.0,
            min_gap_mm: 2.0,
            min_distance_diff_mm: 0.0,
        };
        let tetra =
            Family::new(FamilyKind::Tetrahedron { centre: true }, cube(100.0), 10.0).unwrap();
        let v = constraints.violations(&tetra.points(&tetra.initial()));
        assert!(v.feasible(), "{v:?}");
        for count in 4..=14 {
            let custom =
                Family::new(FamilyKind::Custom { count, start: None }, cube(100.0), 10.0).unwrap();
            let points = custom.points(&custom.initial());
            assert_eq!(points.len(), count);
            assert!(constraints.violations(&points).envelope_mm == 0.0);
        }
    }

    #[test]
    fn violations_are_measured() {
        let constraints = Constraints {
            envelope: cube(100.0),
            sphere_diameter_mm: 10.0,
            min_gap_mm: 2.0,
            min_distance_diff_mm: 1.0,
        };
        let paper = crate::synthetic::biprism_points(50.0);
        let v = constraints.violations(&paper);
        assert_eq!(v.envelope_mm, 0.0);
        assert_eq!(v.gap_mm, 0.0);
        // The paper's biprism repeats its distances: not identifiable.
        assert!(v.distance_diff_mm > 0.0);
        assert_eq!(v.smallest_distance_diff_mm, 0.0);
        let mut crowded = paper.clone();
        crowded[1] = Vector3::new(0.0, 0.0, 11.0);
        crowded[2] = Vector3::new(0.0, 0.0, 60.0);
        let v = constraints.violations(&crowded);
        assert!((v.smallest_gap_mm - 1.0).abs() < 1e-12);
        assert!(v.gap_mm >= 1.0 && v.envelope_mm >= 10.0);
        assert!(!v.describe(&constraints).is_empty());
    }

    #[test]
    fn distinct_distance_capacity_counts_the_envelopes_room() {
        let mut constraints = Constraints {
            envelope: cube(100.0),
            sphere_diameter_mm: 10.0,
            min_gap_mm: 2.0,
            min_distance_diff_mm: 1.0,
        };
        // Distances from 12 mm to the 173.2 mm diagonal, 1 mm apart: 162.
        assert_eq!(constraints.distinct_distance_capacity(), Some(162));
        constraints.min_distance_diff_mm = 0.0;
        assert_eq!(constraints.distinct_distance_capacity(), None);
    }

    #[test]
    fn spreading_makes_twelve_points_identifiable_and_keeps_fixed_points() {
        let constraints = Constraints {
            envelope: cube(100.0),
            sphere_diameter_mm: 10.0,
            min_gap_mm: 2.0,
            min_distance_diff_mm: 1.0,
        }
        // As the search's penalty tightens them.
        .tightened(0.02, 0.01);
        let family = Family::new(
            FamilyKind::Custom {
                count: 12,
                start: None,
            },
            cube(100.0),
            10.0,
        )
        .unwrap();
        // The corners-and-faces start repeats its distances exactly.
        let start = family.points(&family.initial());
        assert_eq!(
            constraints.violations(&start).smallest_distance_diff_mm,
            0.0
        );
        let mut fixed = vec![false; 12];
        fixed[0] = true;
        fixed[5] = true;
        let mut points = start.clone();
        let mut rng = crate::synthetic::stream_rng(3, 1, 0);
        assert!(constraints.spread_distances(&mut points, &fixed, &mut rng));
        let v = constraints.violations(&points);
        assert!(v.feasible() && v.smallest_distance_diff_mm >= 1.03, "{v:?}");
        assert_eq!((points[0], points[5]), (start[0], start[5]));
        // Round trip through the family's parameters.
        let params = family.custom_params(&points).unwrap();
        assert_eq!(family.points(&params), points);
        // A layout that already meets them is left alone.
        let mut again = points.clone();
        assert!(constraints.spread_distances(&mut again, &fixed, &mut rng));
        assert_eq!(again, points);
        let biprism =
            Family::new(FamilyKind::Tetrahedron { centre: false }, cube(100.0), 10.0).unwrap();
        assert_eq!(biprism.custom_params(&points[..4]), None);
    }

    #[test]
    fn tightening_raises_gap_and_difference_but_keeps_zero_off() {
        let constraints = Constraints {
            envelope: cube(100.0),
            sphere_diameter_mm: 10.0,
            min_gap_mm: 2.0,
            min_distance_diff_mm: 1.0,
        };
        let tight = constraints.tightened(0.02, 0.01);
        assert_relative_eq!(tight.min_gap_mm, 2.05, epsilon = 1e-12);
        assert_relative_eq!(tight.min_distance_diff_mm, 1.03, epsilon = 1e-12);
        assert_eq!(tight.envelope, constraints.envelope);
        let off = Constraints {
            min_distance_diff_mm: 0.0,
            ..constraints
        };
        assert_eq!(off.tightened(0.02, 0.01).min_distance_diff_mm, 0.0);
    }

    #[test]
    fn bad_families_are_rejected() {
        assert!(matches!(
            Family::new(FamilyKind::Tetrahedron { centre: false }, cube(5.0), 10.0),
            Err(FamilyError::EnvelopeTooSmall { .. })
        ));
        assert_eq!(
            Family::new(
                FamilyKind::Custom {
                    count: 3,
                    start: None
                },
                cube(100.0),
                10.0
            )
            .unwrap_err(),
            FamilyError::TooFewPoints(3)
        );
        assert!("100,80".parse::<Envelope>().is_err());
        assert!("0".parse::<Envelope>().is_err());
        assert_eq!("120".parse::<Envelope>().unwrap().size_mm, [120.0; 3]);
    }
}
