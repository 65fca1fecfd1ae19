//! Ellipses from edge points, and what an ellipse says about the sphere
//! that made it.
//!
//! **Fit.** The direct least-squares ellipse fit of Fitzgibbon, Pilu &
//! Fisher (*Direct least square fitting of ellipses*, IEEE PAMI 21(5),
//! 1999) in the numerically stable form of Halíř & Flusser (*Numerically
//! stable direct least squares fitting of ellipses*, WSCG 1998): the conic
//! `a x² + b xy + c y² + d x + e y + f = 0` minimising the algebraic
//! residual `Σ (aᵀ xᵢ)²` under the ellipse constraint `4ac − b² = 1`. The
//! design matrix is split into its quadratic part `D₁` and linear part `D₂`
//! (Halíř & Flusser eq. (13)–(16)); the linear coefficients are eliminated,
//! `a₂ = −S₃⁻¹ S₂ᵀ a₁`, leaving the 3×3 reduced scatter
//! `R = S₁ − S₂ S₃⁻¹ S₂ᵀ` and the generalised problem `R a₁ = λ C₁ a₁`.
//! Instead of Halíř & Flusser's non-symmetric `C₁⁻¹ R`, we whiten by the
//! Cholesky factor `R = L Lᵀ`: the ellipse is the eigenvector of the
//! *symmetric* `L⁻¹ C₁ L⁻ᵀ` with the only positive eigenvalue (C₁ has one
//! positive and two negative eigenvalues, and congruence keeps the signs),
//! so a symmetric eigensolver does the work. Points are first shifted to
//! their centroid and scaled to unit RMS radius (Hartley's normalisation).
//!
//! **Sphere inverse.** A sphere's silhouette on the undistorted normalised
//! plane has its centre `m₀ = π(C) · C_z² / (C_z² − r²)` and its minor
//! semi-axis `b = r / √(C_z² − r²)` ([`crate::sphere_image`]). Since
//! `C_z² / (C_z² − r²) = 1 + b²`, the projected sphere centre is
//! `π(C) = m₀ / (1 + b²)` exactly, whatever the radius; with the radius
//! known, the depth is `C_z = r √(1 + 1/b²)`. The axis ratio of a sphere's
//! image is fixed by its centre too, `major/minor = √(1 + |m₀|² / (1 + b²))`
//! with the major axis along `m₀`: an ellipse that breaks this is not the
//! whole silhouette of a sphere.

use nalgebra::{Matrix2, Matrix3, SymmetricEigen, Vector2, Vector3};

/// Fewest edge points [`fit_ellipse`] accepts (five determine a conic;
/// one more leaves a residual).
pub const MIN_EDGE_POINTS: usize = 6;
/// Relative ridge added to the reduced scatter before its Cholesky
/// factorisation, times its trace: noise-free points on an exact conic make
/// it singular, and this keeps the factor finite without moving the answer
/// measurably.
const SCATTER_RIDGE: f64 = 1e-13;

/// An ellipse `(p − centre)ᵀ M (p − centre) = 1`, `M` positive definite.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ellipse {
    /// Centre.
    pub centre: Vector2<f64>,
    /// The shape matrix `M` (2×2, symmetric, positive definite).
    pub shape: Matrix2<f64>,
}

impl Ellipse {
    /// Semi-axes `(major, minor)` and the major axis's angle from +x, rad.
    pub fn axes(&self) -> (f64, f64, f64) {
        let eigen = SymmetricEigen::new(self.shape);
        // Smallest eigenvalue ↔ longest axis.
        let (small, large) = if eigen.eigenvalues[0] <= eigen.eigenvalues[1] {
            (0, 1)
        } else {
            (1, 0)
        };
        let major = 1.0 / eigen.eigenvalues[small].sqrt();
        let minor = 1.0 / eigen.eigenvalues[large].sqrt();
        let direction = eigen.eigenvectors.column(small);
        (major, minor, direction[1].atan2(direction[0]))
    }

    /// Area, `π / √det M`.
    pub fn area(&self) -> f64 {
        std::f64::consts::PI / self.shape.determinant().sqrt()
    }

    /// First-order (Sampson) distance of `p` from the ellipse: the
    /// algebraic value over its gradient's length; positive outside.
    pub fn distance(&self, p: &Vector2<f64>) -> f64 {
        let d = p - self.centre;
        let value = d.dot(&(self.shape * d)) - 1.0;
        let gradient = 2.0 * self.shape * d;
        let norm = gradient.norm();
        if norm > 0.0 {
            value / norm
        } else {
            f64::INFINITY
        }
    }

    /// The same ellipse seen through the affine map `q = A p + b`, with `A`
    /// diagonal (`scale`): centre `A c + b`, shape `A⁻¹ M A⁻¹`.
    pub fn scaled(&self, scale: &Vector2<f64>, offset: &Vector2<f64>) -> Ellipse {
        let inverse = Matrix2::new(1.0 / scale.x, 0.0, 0.0, 1.0 / scale.y);
        Ellipse {
            centre: self.centre.component_mul(scale) + offset,
            shape: inverse * self.shape * inverse,
        }
    }

    /// The ellipse of a homogeneous conic matrix (`xᵀ A x = 0`, either
    /// sign), or `None` when the conic is not a real ellipse.
    pub fn from_conic(conic: &Matrix3<f64>) -> Option<Ellipse> {
        let quadratic = conic.fixed_view::<2, 2>(0, 0).into_owned();
        let linear = Vector2::new(conic[(0, 2)], conic[(1, 2)]);
        let centre = -quadratic.try_inverse()? * linear;
        let value_at_centre = conic[(2, 2)] + linear.dot(&centre);
        if value_at_centre.is_nan() || value_at_centre == 0.0 {
            return None;
        }
        let shape = quadratic / -value_at_centre;
        let shape = 0.5 * (shape + shape.transpose());
        let definite = shape[(0, 0)] > 0.0 && shape.determinant() > 0.0;
        (definite && centre.iter().all(|v| v.is_finite())).then_some(Ellipse { centre, shape })
    }
}

/// The direct least-squares ellipse through `points` (module docs), or
/// `None` with fewer than [`MIN_EDGE_POINTS`] points or when they do not
/// determine an ellipse (collinear, non-finite).
pub fn fit_ellipse(points: &[Vector2<f64>]) -> Option<Ellipse> {
    if points.len() < MIN_EDGE_POINTS {
        return None;
    }
    let count = points.len() as f64;
    let mean = points.iter().sum::<Vector2<f64>>() / count;
    let spread = (points
        .iter()
        .map(|p| (p - mean).norm_squared())
        .sum::<f64>()
        / count)
        .sqrt();
    if !(spread > 0.0 && spread.is_finite()) {
        return None;
    }
    let scale = 1.0 / spread;
    // Scatter blocks S₁ = D₁ᵀD₁, S₂ = D₁ᵀD₂, S₃ = D₂ᵀD₂.
    let mut s1 = Matrix3::<f64>::zeros();
    let mut s2 = Matrix3::<f64>::zeros();
    let mut s3 = Matrix3::<f64>::zeros();
    for p in points {
        let q = (p - mean) * scale;
        let quadratic = Vector3::new(q.x * q.x, q.x * q.y, q.y * q.y);
        let linear = Vector3::new(q.x, q.y, 1.0);
        s1 += quadratic * quadratic.transpose();
        s2 += quadratic * linear.transpose();
        s3 += linear * linear.transpose();
    }
    let t = -s3.try_inverse()? * s2.transpose();
    let mut reduced = s1 + s2 * t;
    reduced = 0.5 * (reduced + reduced.transpose());
    let ridge = SCATTER_RIDGE * reduced.trace().max(f64::MIN_POSITIVE);
    let cholesky = (reduced + Matrix3::identity() * ridge).cholesky()?;
    let l = cholesky.l();
    let l_inverse = l.try_inverse()?;
    let constraint = Matrix3::new(0.0, 0.0, 2.0, 0.0, -1.0, 0.0, 2.0, 0.0, 0.0);
    let whitened = l_inverse * constraint * l_inverse.transpose();
    let eigen = SymmetricEigen::new(0.5 * (whitened + whitened.transpose()));
    let best = eigen.eigenvalues.imax();
    if eigen.eigenvalues[best].is_nan() || eigen.eigenvalues[best] <= 0.0 {
        return None;
    }
    let b = eigen.eigenvectors.column(best).into_owned();
    let a1 = l_inverse.transpose() * b;
    let a2 = t * a1;
    let (a, bxy, c, d, e, f) = (a1[0], a1[1], a1[2], a2[0], a2[1], a2[2]);
    let normalised = Matrix3::new(
        a,
        0.5 * bxy,
        0.5 * d,
        0.5 * bxy,
        c,
        0.5 * e,
        0.5 * d,
        0.5 * e,
        f,
    );
    // Undo the normalisation: q = H p with H = [s I, −s μ; 0 1].
    let h = Matrix3::new(
        scale,
        0.0,
        -scale * mean.x,
        0.0,
        scale,
        -scale * mean.y,
        0.0,
        0.0,
        1.0,
    );
    Ellipse::from_conic(&(h.transpose() * normalised * h))
}

/// What an ellipse on the undistorted normalised plane says about the
/// sphere whose silhouette it is (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereFromEllipse {
    /// The projected sphere centre on the normalised plane, `m₀ / (1 + b²)`.
    pub centre_normalised: Vector2<f64>,
    /// The axis ratio a sphere's silhouette centred at `m₀` has.
    pub expected_axis_ratio: f64,
    /// The fitted ellipse's axis ratio, major over minor.
    pub axis_ratio: f64,
    /// Minor semi-axis on the normalised plane.
    pub minor_normalised: f64,
}

impl SphereFromEllipse {
    /// Reads the sphere from an ellipse on the normalised plane.
    pub fn of(ellipse: &Ellipse) -> SphereFromEllipse {
        let (major, minor, _) = ellipse.axes();
        let b2 = minor * minor;
        let m0 = ellipse.centre;
        SphereFromEllipse {
            centre_normalised: m0 / (1.0 + b2),
            expected_axis_ratio: (1.0 + m0.norm_squared() / (1.0 + b2)).sqrt(),
            axis_ratio: major / minor,
            minor_normalised: minor,
        }
    }

    /// Depth of the sphere centre, mm, for a sphere of radius `radius_mm`:
    /// `r √(1 + 1/b²)`.
    pub fn depth_mm(&self, radius_mm: f64) -> f64 {
        radius_mm * (1.0 + 1.0 / (self.minor_normalised * self.minor_normalised)).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;
    use crate::sphere_image::{ellipse_centre_normalised, normalised_conic, semi_axes_normalised};
    use approx::assert_relative_eq;

    fn points_on(ellipse: &Ellipse, count: usize, from: f64, to: f64) -> Vec<Vector2<f64>> {
        let eigen = SymmetricEigen::new(ellipse.shape);
        (0..count)
            .map(|i| {
                let angle = from + (to - from) * i as f64 / count as f64;
                let local = Vector2::new(
                    angle.cos() / eigen.eigenvalues[0].sqrt(),
                    angle.sin() / eigen.eigenvalues[1].sqrt(),
                );
                ellipse.centre + eigen.eigenvectors * local
            })
            .collect()
    }

    #[test]
    fn exact_points_give_the_ellipse_back() {
        let truth = Ellipse {
            centre: Vector2::new(812.25, 433.5),
            shape: Matrix2::new(1.0 / 81.0, 0.002, 0.002, 1.0 / 36.0),
        };
        // A full ring and a 200° arc: the direct fit is exact on both.
        for (from, to) in [(0.0, std::f64::consts::TAU), (0.3, 3.8)] {
            let fitted = fit_ellipse(&points_on(&truth, 40, from, to)).unwrap();
            assert_relative_eq!(fitted.centre, truth.centre, epsilon = 1e-7);
            assert_relative_eq!(fitted.shape, truth.shape, epsilon = 1e-9);
            let p = Vector2::new(820.0, 440.0);
            assert!(fitted.distance(&p).abs() < 9.0);
        }
        let (major, minor, _) = truth.axes();
        assert!(major > minor);
        assert_relative_eq!(
            truth.area(),
            std::f64::consts::PI * major * minor,
            epsilon = 1e-9
        );
    }

    #[test]
    fn degenerate_inputs_are_none() {
        assert!(fit_ellipse(&[Vector2::zeros(); 3]).is_none());
        let line: Vec<Vector2<f64>> = (0..10)
            .map(|i| Vector2::new(i as f64, 2.0 * i as f64))
            .collect();
        assert!(fit_ellipse(&line).is_none());
        let nan = vec![Vector2::new(f64::NAN, 0.0); 8];
        assert!(fit_ellipse(&nan).is_none());
    }

    /// The inverse reads the projected centre and the depth of a sphere
    /// back from its exact silhouette conic.
    #[test]
    fn sphere_inverse_is_exact_on_sphere_silhouettes() {
        let camera = Camera::paper();
        for centre in [
            Vector3::new(90.0, -60.0, 200.0),
            Vector3::new(-250.0, 100.0, 600.0),
            Vector3::new(0.0, 0.0, 1000.0),
        ] {
            let radius = 5.0;
            let ellipse = Ellipse::from_conic(&normalised_conic(&centre, radius).unwrap()).unwrap();
            assert_relative_eq!(
                ellipse.centre,
                ellipse_centre_normalised(&centre, radius).unwrap(),
                epsilon = 1e-12
            );
            let (along, across) = semi_axes_normalised(&centre, radius).unwrap();
            let sphere = SphereFromEllipse::of(&ellipse);
            assert_relative_eq!(sphere.minor_normalised, across, max_relative = 1e-9);
            assert_relative_eq!(sphere.axis_ratio, along / across, max_relative = 1e-9);
            assert_relative_eq!(
                sphere.expected_axis_ratio,
                along / across,
                max_relative = 1e-9
            );
            assert_relative_eq!(
                sphere.centre_normalised,
                Vector2::new(centre.x / centre.z, centre.y / centre.z),
                epsilon = 1e-12
            );
            assert_relative_eq!(sphere.depth_mm(radius), centre.z, max_relative = 1e-9);
            // In pixels and back through the camera's affine map.
            let scale = Vector2::new(camera.fx(), camera.fy());
            let offset = Vector2::new(camera.cx(), camera.cy());
            let pixel = ellipse.scaled(&scale, &offset);
            let back = pixel.scaled(
                &Vector2::new(1.0 / scale.x, 1.0 / scale.y),
                &Vector2::new(-offset.x / scale.x, -offset.y / scale.y),
            );
            assert_relative_eq!(back.shape, ellipse.shape, max_relative = 1e-9);
        }
    }
}
