//! Perspective-n-Point solvers behind one interface.
//!
//! **Convention (all solvers).** Inputs are object points `X_i` (mm, marker
//! frame) and *undistorted normalised* image points `m_i = (x_i, y_i)` on the
//! plane `z = 1`, related by `λ_i [m_i; 1] = R X_i + t` with `λ_i > 0`
//! (paper eqs. 2–3, OpenCV). Pixels are turned into normalised points by
//! [`crate::camera::Camera::pixel_to_normalised`] before any solver runs.
//!
//! Every solver returns all its candidate poses ([`Solver::solve`]); the
//! single best pose ([`Solver::solve_best`]) is the candidate with the lowest
//! reprojection error among those that put every point in front of the
//! camera. No solver falls back to another: a method either runs itself or
//! returns a [`PnpError`] that says why.
//!
//! ```
//! use layout_opt_solvers::pnp::{PnpError, Solver};
//! use layout_opt_solvers::pose::{rotation_error_deg, Pose};
//! use layout_opt_solvers::synthetic::biprism_points;
//! use nalgebra::{Rotation3, Vector2, Vector3};
//!
//! // The paper's biprism (L = 50 mm).
//! let object = biprism_points(50.0);
//! let truth = Pose::new(
//!     Rotation3::from_euler_angles(0.2, -0.1, 0.05),
//!     Vector3::new(20.0, -10.0, 600.0),
//! );
//! let image: Vec<Vector2<f64>> = object.iter().map(|p| truth.project_normalised(p)).collect();
//! // Noise-free data: every solver recovers the pose.
//! for solver in [Solver::Epnp, Solver::ParallelWeighted, Solver::Sqpnp, Solver::Ml] {
//!     let pose = solver.solve_best(&object, &image)?;
//!     assert!(rotation_error_deg(&truth.rotation, &pose.rotation) < 1e-6);
//! }
//! // Bad input is an error, never a panic.
//! assert!(matches!(
//!     Solver::Epnp.solve_best(&object[..3], &image[..3]),
//!     Err(PnpError::TooFewPoints { .. })
//! ));
//! # Ok::<(), PnpError>(())
//! ```

use crate::pose::Pose;
use crate::spread::{Spread, DUPLICATE_TOLERANCE, PLANARITY_TOLERANCE};
use nalgebra::{Vector2, Vector3};
use smallvec::SmallVec;

pub mod dls;
pub mod dlt;
pub mod epnp;
pub mod epnp_gn;
pub mod gauss_newton;
pub mod iepnp;
pub mod lhm;
pub mod ml;
pub mod ml_sphere;
pub mod opnp;
pub mod p3p;
pub mod parallel;
pub mod parallel_init;
pub mod polynomial;
pub mod rpnp;
pub mod sqpnp;
pub mod three_cubics;
pub mod unlabelled;

/// Candidate poses returned by a solver. Six fit inline, so the common
/// solvers allocate nothing (EPnP returns four or five closed forms; a mirror
/// candidate, rare, may spill).
pub type Candidates = SmallVec<[Pose; 6]>;

/// Object coordinates (about their centroid) and normalised image
/// coordinates must lie within `MIN_COORDINATE_SCALE..MAX_COORDINATE_SCALE`
/// in size: the solvers form squared distances and, in DLS and OPnP, fourth
/// and higher powers of them, which must neither overflow nor underflow.
pub const MAX_COORDINATE_SCALE: f64 = 1e60;
/// See [`MAX_COORDINATE_SCALE`].
pub const MIN_COORDINATE_SCALE: f64 = 1e-60;

/// Why a solver could not return a pose.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum PnpError {
    /// Fewer correspondences than the method needs.
    TooFewPoints {
        /// Human name of the method.
        solver: &'static str,
        /// Minimum number of correspondences.
        needed: usize,
        /// Number given.
        got: usize,
    },
    /// Object and image point lists differ in length.
    MismatchedLengths {
        /// Number of object points.
        object: usize,
        /// Number of image points.
        image: usize,
    },
    /// A coordinate was NaN or infinite.
    NonFinite {
        /// "object" or "image".
        kind: &'static str,
        /// Index of the offending point.
        index: usize,
    },
    /// Two object points coincide.
    DuplicatePoints {
        /// Index of the first point.
        first: usize,
        /// Index of the second point.
        second: usize,
    },
    /// Object coordinates too large or too small to square in double
    /// precision (the methods work with squared distances and higher
    /// powers).
    BadScale {
        /// "object" or "image".
        kind: &'static str,
        /// The largest absolute coordinate (object: about the centroid).
        magnitude: f64,
    },
    /// Every image point is the same point: the image says nothing about
    /// rotation or distance.
    CoincidentImagePoints,
    /// The image points lie on one line, which a noncoplanar object cannot
    /// project to (and a planar one only seen edge-on, where the pose is
    /// undetermined).
    CollinearImagePoints,
    /// All object points lie on one line: no method can recover the roll about it.
    Collinear,
    /// The object points are coplanar and the method needs a 3D spread.
    Coplanar {
        /// Human name of the method.
        solver: &'static str,
    },
    /// Every candidate puts some point behind the camera: the image points
    /// cannot come from these object points under a perspective camera.
    BehindCamera {
        /// Human name of the method.
        solver: &'static str,
    },
    /// The method's polynomial system solver failed (e.g. a singular
    /// elimination template) on every formulation it tries.
    PolynomialSolver {
        /// Human name of the method.
        solver: &'static str,
        /// What went wrong.
        source: three_cubics::CubicSystemError,
    },
    /// More object points than the method can track.
    TooManyPoints {
        /// Human name of the method.
        solver: &'static str,
        /// Most points accepted.
        max: usize,
        /// Number given.
        got: usize,
    },
    /// The method's numerics broke down on this input.
    Degenerate {
        /// Human name of the method.
        solver: &'static str,
        /// What went wrong.
        reason: &'static str,
    },
}

impl std::fmt::Display for PnpError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PnpError::TooFewPoints {
                solver,
                needed,
                got,
            } => write!(f, "{solver} needs at least {needed} points, got {got}"),
            PnpError::MismatchedLengths { object, image } => write!(
                f,
                "mismatched lengths: {object} object points but {image} image points"
            ),
            PnpError::NonFinite { kind, index } => {
                write!(f, "{kind} point {index} has a non-finite coordinate")
            }
            PnpError::DuplicatePoints { first, second } => {
                write!(f, "object points {first} and {second} coincide")
            }
            PnpError::BadScale { kind, magnitude } => write!(
                f,
                "{kind} point coordinates of size {magnitude:e} are outside the range {MIN_COORDINATE_SCALE:e}..{MAX_COORDINATE_SCALE:e} that PnP can work in; rescale the units"
            ),
            PnpError::CoincidentImagePoints => f.write_str(
                "all image points coincide; no PnP method can recover a pose from one image point",
            ),
            PnpError::CollinearImagePoints => f.write_str(
                "the image points are collinear; no PnP method can recover the pose",
            ),
            PnpError::Collinear => {
                f.write_str("object points are collinear; no PnP method can recover the pose")
            }
            PnpError::Coplanar { solver } => {
                write!(f, "object points are coplanar; {solver} needs noncoplanar points")
            }
            PnpError::BehindCamera { solver } => write!(
                f,
                "{solver} found no pose that puts every point in front of the camera (points behind the camera)"
            ),
            PnpError::PolynomialSolver { solver, source } => {
                write!(f, "{solver}: the polynomial solver failed: {source}")
            }
            PnpError::TooManyPoints { solver, max, got } => {
                write!(f, "{solver} handles at most {max} points, got {got}")
            }
            PnpError::Degenerate { solver, reason } => write!(f, "{solver} failed: {reason}"),
        }
    }
}

impl std::error::Error for PnpError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            PnpError::PolynomialSolver { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// What one solver is and how it runs: its stable CLI name, the names
/// reports show, the fewest points it takes, whether it takes coplanar
/// points, the solver it refines (if any), and the function that runs it.
/// Every solver file declares its own (`epnp::EPNP`,
/// `parallel::PARALLEL_WEIGHTED`, …); [`Solver`] lists them.
#[derive(Debug)]
pub struct Method {
    /// The stable CLI name (docs/formats.md, "Solver names").
    pub name: &'static str,
    /// The name used in messages and reports.
    pub display_name: &'static str,
    /// One line on the method and where it comes from (`solve --list`).
    pub description: &'static str,
    /// The fewest correspondences the method accepts.
    pub min_points: usize,
    /// Whether the method runs on coplanar object points.
    pub accepts_coplanar: bool,
    /// Whether it recovers the pose of noise-free pinhole data exactly
    /// (false for an approximation, such as a single paraperspective
    /// step, which keeps its model's bias).
    pub exact: bool,
    /// The solver whose best pose the method refines; `None` for methods
    /// that start from their own closed forms.
    pub start: Option<Solver>,
    /// Runs the method on object points and normalised image points that
    /// [`validate_input`] has accepted, and returns every candidate pose.
    pub solve: SolveFn,
}

/// The one signature every solver has: object points (marker frame) and
/// normalised image points in, every candidate pose out.
pub type SolveFn = fn(&[Vector3<f64>], &[Vector2<f64>]) -> Result<Candidates, PnpError>;

/// Declares [`Solver`], one variant per solver, each bound to the
/// [`Method`] its file declares, in the order reports list them. Adding a
/// solver is one line in the list below (and its `pub mod`).
macro_rules! solvers {
    ($($variant:ident => $module:ident :: $method:ident,)*) => {
        /// Every solver, by stable CLI name (docs/formats.md, "Solver
        /// names"). Each variant's [`Method`] (names, description, minimum
        /// points, coplanarity, start, solve function) lives in its file.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[non_exhaustive]
        pub enum Solver {
            $(
                #[doc = concat!("[`", stringify!($module), "::", stringify!($method), "`].")]
                $variant,
            )*
        }

        impl Solver {
            /// Every solver, in the order reports list them.
            pub const ALL: &'static [Solver] = &[$(Solver::$variant),*];

            /// What the solver is and how it runs, from its file.
            pub fn method(self) -> &'static Method {
                match self {
                    $(Solver::$variant => &$module::$method,)*
                }
            }
        }
    };
}

solvers! {
    Dlt => dlt::DLT,
    Epnp => epnp::EPNP,
    EpnpGn => epnp_gn::EPNP_GN,
    Iepnp => iepnp::IEPNP,
    ParallelInit => parallel_init::PARALLEL_INIT,
    Parallel => parallel::PARALLEL,
    ParallelGn => parallel::PARALLEL_GN,
    ParallelWeighted => parallel::PARALLEL_WEIGHTED,
    Dls => dls::DLS,
    Lhm => lhm::LHM,
    Rpnp => rpnp::RPNP,
    Sqpnp => sqpnp::SQPNP,
    Opnp => opnp::OPNP,
    Ml => ml::ML,
}

impl Solver {
    /// The stable CLI name.
    pub fn name(self) -> &'static str {
        self.method().name
    }

    /// The name used in messages and reports.
    pub fn display_name(self) -> &'static str {
        self.method().display_name
    }

    /// One line on the method and where it comes from.
    pub fn description(self) -> &'static str {
        self.method().description
    }

    /// The solver whose pose a refining method starts from, where the
    /// method is a refinement of another's result (`ml` refines SQPnP's
    /// best candidate); `None` for the methods that start from their own
    /// closed forms. Reports and `solve`'s output name it, so no start is
    /// hidden.
    pub fn start(self) -> Option<Solver> {
        self.method().start
    }

    /// Looks a solver up by its stable CLI name.
    pub fn from_name(name: &str) -> Option<Solver> {
        Solver::ALL.iter().copied().find(|s| s.name() == name)
    }

    /// The fewest correspondences the method accepts.
    pub fn min_points(self) -> usize {
        self.method().min_points
    }

    /// Whether the method needs noncoplanar object points.
    pub fn needs_noncoplanar(self) -> bool {
        !self.method().accepts_coplanar
    }

    /// Whether the method recovers noise-free poses exactly
    /// ([`Method::exact`]).
    pub fn is_exact(self) -> bool {
        self.method().exact
    }

    /// Runs the method and returns every candidate pose it produces.
    pub fn solve(
        self,
        object: &[Vector3<f64>],
        image: &[Vector2<f64>],
    ) -> Result<Candidates, PnpError> {
        validate_input(self, object, image)?;
        (self.method().solve)(object, image)
    }

    /// Runs the method and returns its best candidate: the lowest
    /// reprojection error among the poses that put every point in front of
    /// the camera.
    pub fn solve_best(
        self,
        object: &[Vector3<f64>],
        image: &[Vector2<f64>],
    ) -> Result<Pose, PnpError> {
        let candidates = self.solve(object, image)?;
        best_candidate(self.display_name(), &candidates, object, image)
    }
}

impl std::fmt::Display for Solver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(feature = "serde")]
impl serde::Serialize for Solver {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}

impl std::str::FromStr for Solver {
    type Err = String;
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        Solver::from_name(name).ok_or_else(|| {
            let names: Vec<&str> = Solver::ALL.iter().map(|s| s.name()).collect();
            format!("unknown solver '{name}'; known: {}", names.join(", "))
        })
    }
}

/// Picks the candidate with the lowest reprojection error among those that
/// put every object point in front of the camera.
pub fn best_candidate(
    solver: &'static str,
    candidates: &[Pose],
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
) -> Result<Pose, PnpError> {
    // One pass per candidate: each point is transformed once, both for the
    // in-front test and for its reprojection error. Comparing sums of
    // squares ranks the candidates as their RMS errors do.
    let mut best: Option<(f64, &Pose)> = None;
    for pose in candidates {
        if !pose.is_finite() {
            continue;
        }
        let Some(error_sq) = reprojection_error_sq_in_front(pose, object, image) else {
            continue;
        };
        if error_sq.is_finite() && best.is_none_or(|(lowest, _)| error_sq < lowest) {
            best = Some((error_sq, pose));
        }
    }
    best.map(|(_, pose)| *pose)
        .ok_or(PnpError::BehindCamera { solver })
}

/// The sum of squared reprojection errors on the normalised image plane,
/// or `None` if some point is not strictly in front of the camera.
pub(crate) fn reprojection_error_sq_in_front(
    pose: &Pose,
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
) -> Option<f64> {
    let mut sum = 0.0;
    for (p, m) in object.iter().zip(image) {
        let c = pose.transform(p);
        // NaN depth counts as not in front.
        let in_front = c.z > 0.0;
        if !in_front {
            return None;
        }
        let inverse_z = 1.0 / c.z;
        sum += (Vector2::new(c.x * inverse_z, c.y * inverse_z) - m).norm_squared();
    }
    Some(sum)
}

/// Centroid of a non-empty point set and the RMS distance of the points
/// from it (the scale several solvers normalise by).
pub fn centroid_and_rms_radius(points: &[Vector3<f64>]) -> (Vector3<f64>, f64) {
    let count = points.len() as f64;
    let centroid = points.iter().sum::<Vector3<f64>>() / count;
    let rms = (points
        .iter()
        .map(|p| (p - centroid).norm_squared())
        .sum::<f64>()
        / count)
        .sqrt();
    (centroid, rms)
}

/// Checks the inputs every method shares: matching lengths, enough points,
/// finite values, no duplicate object points, not collinear, and (for the
/// methods that need it) not coplanar.
pub fn validate_input(
    solver: Solver,
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
) -> Result<(), PnpError> {
    if object.len() != image.len() {
        return Err(PnpError::MismatchedLengths {
            object: object.len(),
            image: image.len(),
        });
    }
    if object.len() < solver.min_points() {
        return Err(PnpError::TooFewPoints {
            solver: solver.display_name(),
            needed: solver.min_points(),
            got: object.len(),
        });
    }
    check_finite(object, image)?;
    let centroid = object.iter().sum::<Vector3<f64>>() / object.len() as f64;
    let object_magnitude = object
        .iter()
        .map(|p| (p - centroid).amax())
        .fold(0.0, f64::max);
    if object_magnitude == 0.0 {
        return Err(PnpError::DuplicatePoints {
            first: 0,
            second: 1,
        });
    }
    check_scale("object", object_magnitude)?;
    let spread = Spread::of(object);
    let scale = spread.extents[0];
    let duplicate_distance = DUPLICATE_TOLERANCE * scale;
    let duplicate_distance_sq = duplicate_distance * duplicate_distance;
    for (i, a) in object.iter().enumerate() {
        for (j, b) in object.iter().enumerate().skip(i + 1) {
            if (a - b).norm_squared() <= duplicate_distance_sq {
                return Err(PnpError::DuplicatePoints {
                    first: i,
                    second: j,
                });
            }
        }
    }
    if spread.extents[1] <= PLANARITY_TOLERANCE * scale {
        return Err(PnpError::Collinear);
    }
    if solver.needs_noncoplanar() && spread.extents[2] <= PLANARITY_TOLERANCE * scale {
        return Err(PnpError::Coplanar {
            solver: solver.display_name(),
        });
    }
    let image_magnitude = image.iter().map(|m| m.amax()).fold(0.0, f64::max);
    if image_magnitude > MAX_COORDINATE_SCALE {
        return Err(PnpError::BadScale {
            kind: "image",
            magnitude: image_magnitude,
        });
    }
    check_image_spread(image)?;
    Ok(())
}

/// Refuses object coordinates whose size (about the centroid) cannot be
/// squared and raised to the fourth power in double precision.
/// The first object or image point with a NaN or infinite coordinate, as
/// [`PnpError::NonFinite`].
pub(crate) fn check_finite(
    object: &[Vector3<f64>],
    image: &[Vector2<f64>],
) -> Result<(), PnpError> {
    if let Some(index) = object.iter().position(|p| !p.iter().all(|v| v.is_finite())) {
        return Err(PnpError::NonFinite {
            kind: "object",
            index,
        });
    }
    if let Some(index) = image.iter().position(|m| !m.iter().all(|v| v.is_finite())) {
        return Err(PnpError::NonFinite {
            kind: "image",
            index,
        });
    }
    Ok(())
}

fn check_scale(kind: &'static str, magnitude: f64) -> Result<(), PnpError> {
    if (MIN_COORDINATE_SCALE..=MAX_COORDINATE_SCALE).contains(&magnitude) {
        Ok(())
    } else {
        Err(PnpError::BadScale { kind, magnitude })
    }
}

/// Refuses image points that all coincide or all lie on one line: their
/// 2×2 scatter about the centroid has a zero (or, relative to the largest,
/// below [`PLANARITY_TOLERANCE`]²) eigenvalue.
fn check_image_spread(image: &[Vector2<f64>]) -> Result<(), PnpError> {
    if image.iter().all(|m| *m == image[0]) {
        return Err(PnpError::CoincidentImagePoints);
    }
    let count = image.len() as f64;
    let centroid = image.iter().sum::<Vector2<f64>>() / count;
    // Scale by the largest offset first, so that the scatter neither
    // overflows nor underflows.
    let largest = image
        .iter()
        .map(|m| (m - centroid).amax())
        .fold(0.0, f64::max);
    let (mut xx, mut xy, mut yy) = (0.0, 0.0, 0.0);
    for m in image {
        let d = (m - centroid) / largest;
        xx += d.x * d.x;
        xy += d.x * d.y;
        yy += d.y * d.y;
    }
    // Eigenvalues of [[xx, xy], [xy, yy]]: the smaller is the determinant
    // over the larger.
    let half_trace = 0.5 * (xx + yy);
    let larger = half_trace + (0.25 * (xx - yy).powi(2) + xy * xy).sqrt();
    let smaller = (xx * yy - xy * xy) / larger;
    if smaller <= PLANARITY_TOLERANCE * PLANARITY_TOLERANCE * larger {
        return Err(PnpError::CollinearImagePoints);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube() -> Vec<Vector3<f64>> {
        vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 1.0, 0.0),
            Vector3::new(0.0, 0.0, 1.0),
            Vector3::new(1.0, 1.0, 0.0),
            Vector3::new(1.0, 0.0, 1.0),
        ]
    }

    #[test]
    fn names_round_trip_and_are_unique() {
        for &solver in Solver::ALL {
            assert_eq!(Solver::from_name(solver.name()), Some(solver));
            assert_eq!(solver.name().parse::<Solver>(), Ok(solver));
        }
        let err = "nope".parse::<Solver>().unwrap_err();
        assert!(err.contains("unknown solver 'nope'") && err.contains("parallel-weighted"));
    }

    #[test]
    fn validation_messages() {
        let image = vec![Vector2::new(0.0, 0.0); 6];
        let object = cube();
        let err = validate_input(Solver::Epnp, &object[..3], &image[..3]).unwrap_err();
        assert_eq!(err.to_string(), "EPnP needs at least 4 points, got 3");
        let err = validate_input(Solver::Epnp, &object, &image[..5]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "mismatched lengths: 6 object points but 5 image points"
        );
        let mut bad = object.clone();
        bad[2].y = f64::NAN;
        let err = validate_input(Solver::Epnp, &bad, &image).unwrap_err();
        assert_eq!(
            err.to_string(),
            "object point 2 has a non-finite coordinate"
        );
        let mut bad_image = image.clone();
        bad_image[4].x = f64::INFINITY;
        let err = validate_input(Solver::Epnp, &object, &bad_image).unwrap_err();
        assert_eq!(err.to_string(), "image point 4 has a non-finite coordinate");
        let mut dup = object.clone();
        dup[5] = dup[1];
        let err = validate_input(Solver::Epnp, &dup, &image).unwrap_err();
        assert_eq!(err.to_string(), "object points 1 and 5 coincide");
        let line: Vec<_> = (0..6)
            .map(|i| Vector3::new(i as f64, 2.0 * i as f64, 0.5))
            .collect();
        let err = validate_input(Solver::Epnp, &line, &image).unwrap_err();
        assert_eq!(err, PnpError::Collinear);
        let plane: Vec<_> = (0..6)
            .map(|i| Vector3::new(i as f64, (i * i) as f64, 3.0))
            .collect();
        let err = validate_input(Solver::Dlt, &plane, &image).unwrap_err();
        assert_eq!(
            err.to_string(),
            "object points are coplanar; DLT needs noncoplanar points"
        );
    }

    /// Degenerate images and coordinates that cannot be squared are refused
    /// with errors that say so, for every solver, before any method runs.
    #[test]
    fn degenerate_images_and_scales_are_refused() {
        let object = cube();
        let spread_image: Vec<_> = (0..6)
            .map(|i| Vector2::new(0.01 * i as f64, 0.02 * ((i * i) % 5) as f64))
            .collect();
        for &solver in Solver::ALL {
            if object.len() < solver.min_points() {
                continue;
            }
            assert_eq!(validate_input(solver, &object, &spread_image), Ok(()));
            let same_pixel = vec![Vector2::new(0.1, -0.2); 6];
            assert_eq!(
                solver.solve(&object, &same_pixel).unwrap_err(),
                PnpError::CoincidentImagePoints,
                "{solver}"
            );
            let on_a_line: Vec<_> = (0..6)
                .map(|i| Vector2::new(0.01 * i as f64, 0.5 - 0.03 * i as f64))
                .collect();
            assert_eq!(
                solver.solve(&object, &on_a_line).unwrap_err(),
                PnpError::CollinearImagePoints,
                "{solver}"
            );
            for factor in [1e200, 1e-200, 1e70, 1e-70] {
                let scaled: Vec<_> = object.iter().map(|p| p * factor).collect();
                let err = solver.solve(&scaled, &spread_image).unwrap_err();
                assert!(
                    matches!(err, PnpError::BadScale { kind: "object", .. }),
                    "{solver} at scale {factor:e}: {err}"
                );
                assert!(err.to_string().contains("rescale the units"), "{err}");
            }
            let far: Vec<_> = spread_image.iter().map(|m| m * 1e70).collect();
            assert!(matches!(
                solver.solve(&object, &far).unwrap_err(),
                PnpError::BadScale { kind: "image", .. }
            ));
        }
    }
}
