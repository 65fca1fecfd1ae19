//! Ellipses in the image: the direct least-squares conic fit to edge points,
//! and the centre, semi-axes and orientation of an ellipse given as a conic
//! matrix (such as [`crate::sphere_image::pixel_conic`]).
//!
//! A conic is the symmetric 3×3 matrix `Q` with `(x, y, 1) Q (x, y, 1)ᵀ = 0`
//! on the curve, i.e. `a x² + b x y + c y² + d x + e y + f = 0` with
//! `Q = [[a, b/2, d/2], [b/2, c, e/2], [d/2, e/2, f]]`.
//!
//! Reference: A. Fitzgibbon, M. Pilu, R. B. Fisher, "Direct least square
//! fitting of ellipses", IEEE TPAMI 21(5), 1999 (the constraint
//! `4ac − b² = 1`, eq. (8)); R. Halíř, J. Flusser, "Numerically stable
//! direct least squares fitting of ellipses", WSCG 1998 (the reduced 3×3
//! eigenproblem, eqs. (9)–(11), used here).

use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

/// Fewest points a conic fit takes (five determine a conic; six leave one
/// residual).
pub const MIN_FIT_POINTS: usize = 6;

/// Why no ellipse came out.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum EllipseError {
    /// Too few points for a fit.
    #[error("an ellipse fit needs at least {MIN_FIT_POINTS} points, got {0}")]
    TooFewPoints(usize),
    /// A point is NaN or infinite.
    #[error("edge point {0} is not finite")]
    NotFinite(usize),
    /// The points do not determine an ellipse (collinear, or a degenerate
    /// scatter).
    #[error("the points determine no ellipse (collinear or degenerate)")]
    Degenerate,
    /// The conic is a hyperbola, parabola or empty: no real ellipse.
    #[error("the conic is not a real ellipse")]
    NotAnEllipse,
}

/// An ellipse: centre, semi-axes and the direction of the major axis.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Ellipse {
    /// Centre (same units as the conic's coordinates, e.g. px).
    pub centre: Vector2<f64>,
    /// Semi-major axis.
    pub semi_major: f64,
    /// Semi-minor axis.
    pub semi_minor: f64,
    /// Angle of the major axis from +x, radians, in (−π/2, π/2].
    pub angle_rad: f64,
}

impl Ellipse {
    /// The ellipse a conic matrix describes (any overall sign and scale).
    ///
    /// ```
    /// use layout_opt::ellipse::Ellipse;
    /// use nalgebra::Matrix3;
    /// // (x − 3)²/4 + (y − 1)² = 1
    /// let q = Matrix3::new(0.25, 0.0, -0.75, 0.0, 1.0, -1.0, -0.75, -1.0, 2.25 + 1.0 - 1.0);
    /// let e = Ellipse::from_conic(&q).unwrap();
    /// assert!((e.centre.x - 3.0).abs() < 1e-12 && (e.semi_major - 2.0).abs() < 1e-12);
    /// ```
    pub fn from_conic(conic: &Matrix3<f64>) -> Result<Ellipse, EllipseError> {
        let a = Matrix2::new(conic[(0, 0)], conic[(0, 1)], conic[(1, 0)], conic[(1, 1)]);
        let b = Vector2::new(conic[(0, 2)], conic[(1, 2)]);
        let determinant = a.determinant();
        if determinant.is_nan() || determinant <= 0.0 || !conic.iter().all(|v| v.is_finite()) {
            return Err(EllipseError::NotAnEllipse);
        }
        let inverse = a.try_inverse().ok_or(EllipseError::NotAnEllipse)?;
        let centre = -(inverse * b);
        // The conic's value at the centre: (x − c)ᵀ A (x − c) = −k.
        let k = conic[(2, 2)] + b.dot(&centre);
        let eigen = a.symmetric_eigen();
        let (l0, l1) = (eigen.eigenvalues[0], eigen.eigenvalues[1]);
        let (s0, s1) = (-k / l0, -k / l1);
        if !(s0 > 0.0 && s1 > 0.0) {
            return Err(EllipseError::NotAnEllipse);
        }
        // The major axis belongs to the smaller |eigenvalue|.
        let (major, minor, axis) = if s0 >= s1 {
            (
                s0.sqrt(),
                s1.sqrt(),
                eigen.eigenvectors.column(0).into_owned(),
            )
        } else {
            (
                s1.sqrt(),
                s0.sqrt(),
                eigen.eigenvectors.column(1).into_owned(),
            )
        };
        let mut angle_rad = axis.y.atan2(axis.x);
        if angle_rad <= -std::f64::consts::FRAC_PI_2 {
            angle_rad += std::f64::consts::PI;
        } else if angle_rad > std::f64::consts::FRAC_PI_2 {
            angle_rad -= std::f64::consts::PI;
        }
        Ok(Ellipse {
            centre,
            semi_major: major,
            semi_minor: minor,
            angle_rad,
        })
    }
}

/// The direct least-squares ellipse through `points` (Fitzgibbon et al.,
/// in Halíř and Flusser's stable form), as a conic matrix normalised to
/// `4ac − b² = 1`. The points are centred and scaled before the fit, so
/// pixel coordinates of any size fit equally well.
pub fn fit_conic(points: &[Vector2<f64>]) -> Result<Matrix3<f64>, EllipseError> {
    if points.len() < MIN_FIT_POINTS {
        return Err(EllipseError::TooFewPoints(points.len()));
    }
    if let Some(bad) = points
        .iter()
        .position(|p| !(p.x.is_finite() && p.y.is_finite()))
    {
        return Err(EllipseError::NotFinite(bad));
    }
    let n = points.len() as f64;
    let mean = points.iter().sum::<Vector2<f64>>() / n;
    let scale = (points
        .iter()
        .map(|p| (p - mean).norm_squared())
        .sum::<f64>()
        / n)
        .sqrt();
    if scale.is_nan() || scale <= 0.0 {
        return Err(EllipseError::Degenerate);
    }
    // Scatter matrices of the quadratic part D1 = [x², xy, y²] and the
    // linear part D2 = [x, y, 1] (Halíř–Flusser eq. (9)).
    let mut s1 = Matrix3::zeros();
    let mut s2 = Matrix3::zeros();
    let mut s3 = Matrix3::zeros();
    for p in points {
        let q = (p - mean) / scale;
        let d1 = Vector3::new(q.x * q.x, q.x * q.y, q.y * q.y);
        let d2 = Vector3::new(q.x, q.y, 1.0);
        s1 += d1 * d1.transpose();
        s2 += d1 * d2.transpose();
        s3 += d2 * d2.transpose();
    }
    let s3_inverse = s3.try_inverse().ok_or(EllipseError::Degenerate)?;
    let t = -(s3_inverse * s2.transpose());
    let m = s1 + s2 * t;
    // C1⁻¹ M with C1 = [[0, 0, 2], [0, −1, 0], [2, 0, 0]] (eq. (11)).
    let reduced = Matrix3::from_rows(&[
        (m.row(2) / 2.0).into_owned(),
        (-m.row(1)).into_owned(),
        (m.row(0) / 2.0).into_owned(),
    ]);
    let eigenvalues = reduced.complex_eigenvalues();
    let mut best: Option<Vector3<f64>> = None;
    for lambda in eigenvalues.iter() {
        if lambda.im.abs() > 1e-9 * (1.0 + lambda.re.abs()) {
            continue;
        }
        let shifted = reduced - Matrix3::identity() * lambda.re;
        // The eigenvector spans the null space: the largest cross product
        // of two rows of the shifted matrix.
        let rows = [
            shifted.row(0).transpose(),
            shifted.row(1).transpose(),
            shifted.row(2).transpose(),
        ];
        let v = [
            rows[0].cross(&rows[1]),
            rows[1].cross(&rows[2]),
            rows[0].cross(&rows[2]),
        ]
        .into_iter()
        .max_by(|a, b| a.norm_squared().total_cmp(&b.norm_squared()))
        .expect("three candidates");
        if v.norm_squared() == 0.0 {
            continue;
        }
        let constraint = 4.0 * v[0] * v[2] - v[1] * v[1];
        if constraint > 0.0 {
            best = Some(v / constraint.sqrt());
        }
    }
    let a1 = best.ok_or(EllipseError::NotAnEllipse)?;
    let a2 = t * a1;
    let normalised = Matrix3::new(
        a1[0],
        a1[1] / 2.0,
        a2[0] / 2.0,
        a1[1] / 2.0,
        a1[2],
        a2[1] / 2.0,
        a2[0] / 2.0,
        a2[1] / 2.0,
        a2[2],
    );
    // Back to the input coordinates: q = N p with N = [I/s, −mean/s; 0, 1].
    let back = Matrix3::new(
        1.0 / scale,
        0.0,
        -mean.x / scale,
        0.0,
        1.0 / scale,
        -mean.y / scale,
        0.0,
        0.0,
        1.0,
    );
    let conic = back.transpose() * normalised * back;
    let (a, b, c) = (conic[(0, 0)], 2.0 * conic[(0, 1)], conic[(1, 1)]);
    let norm = (4.0 * a * c - b * b).sqrt();
    if !(norm > 0.0 && norm.is_finite()) {
        return Err(EllipseError::NotAnEllipse);
    }
    Ok(conic / norm)
}

/// [`fit_conic`] and [`Ellipse::from_conic`] in one step.
pub fn fit_ellipse(points: &[Vector2<f64>]) -> Result<Ellipse, EllipseError> {
    Ellipse::from_conic(&fit_conic(points)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ellipse_points(e: &Ellipse, count: usize, offset: f64) -> Vec<Vector2<f64>> {
        let (s, c) = e.angle_rad.sin_cos();
        (0..count)
            .map(|k| {
                let phi = offset + std::f64::consts::TAU * k as f64 / count as f64;
                let (x, y) = (e.semi_major * phi.cos(), e.semi_minor * phi.sin());
                e.centre + Vector2::new(c * x - s * y, s * x + c * y)
            })
            .collect()
    }

    #[test]
    fn fits_exact_points_of_an_ellipse_back_to_it() {
        let truth = Ellipse {
            centre: Vector2::new(640.3, 355.7),
            semi_major: 31.2,
            semi_minor: 18.4,
            angle_rad: 0.6,
        };
        let fitted = fit_ellipse(&ellipse_points(&truth, 40, 0.1)).unwrap();
        assert!((fitted.centre - truth.centre).norm() < 1e-8);
        assert!((fitted.semi_major - truth.semi_major).abs() < 1e-8);
        assert!((fitted.semi_minor - truth.semi_minor).abs() < 1e-8);
        assert!((fitted.angle_rad - truth.angle_rad).abs() < 1e-8);
    }

    #[test]
    fn rejects_too_few_collinear_and_non_finite_points() {
        let line: Vec<_> = (0..10)
            .map(|k| Vector2::new(k as f64, 2.0 * k as f64))
            .collect();
        assert_eq!(fit_conic(&line[..3]), Err(EllipseError::TooFewPoints(3)));
        assert!(fit_conic(&line).is_err());
        let mut bad = ellipse_points(
            &Ellipse {
                centre: Vector2::zeros(),
                semi_major: 2.0,
                semi_minor: 1.0,
                angle_rad: 0.0,
            },
            8,
            0.0,
        );
        bad[3].x = f64::NAN;
        assert_eq!(fit_conic(&bad), Err(EllipseError::NotFinite(3)));
        assert_eq!(
            EllipseError::TooFewPoints(3).to_string(),
            "an ellipse fit needs at least 6 points, got 3"
        );
    }

    #[test]
    fn a_hyperbola_is_not_an_ellipse() {
        let q = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0);
        assert_eq!(Ellipse::from_conic(&q), Err(EllipseError::NotAnEllipse));
    }
}
