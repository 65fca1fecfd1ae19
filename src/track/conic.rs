//! Ellipses from edge points, and what an ellipse says about the sphere
//! that made it.
//!
//! **Fit.** The direct least-squares conic fit is the crate's one,
//! [`crate::ellipse::fit_conic`] (Fitzgibbon, Pilu & Fisher 1999 in Halíř
//! & Flusser's stable form); this module holds the ellipse as the tracker
//! uses it, `(p − c)ᵀ M (p − c) = 1`, for distances, areas and the change
//! of coordinates between pixels and the normalised plane.
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

use nalgebra::{Matrix2, Matrix3, SymmetricEigen, Vector2};

/// Fewest edge points [`fit_ellipse`] accepts (five determine a conic;
/// one more leaves a residual).
pub const MIN_EDGE_POINTS: usize = crate::ellipse::MIN_FIT_POINTS;

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

/// The direct least-squares ellipse through `points`
/// ([`crate::ellipse::fit_conic`]), or `None` with fewer than
/// [`MIN_EDGE_POINTS`] points or when they do not determine an ellipse
/// (collinear, non-finite).
pub fn fit_ellipse(points: &[Vector2<f64>]) -> Option<Ellipse> {
    Ellipse::from_conic(&crate::ellipse::fit_conic(points).ok()?)
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
    use nalgebra::Vector3;

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
