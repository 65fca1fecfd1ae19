//! The gauge of a characterised shape: which similarity of the adjusted
//! shape is reported, and its covariance in that gauge.
//!
//! A single camera fixes the shape only up to a similarity
//! ([`super::bundle::similarity_generators`]). The reported shape is the
//! one that best overlays the nominal layout: the similarity minimising
//! the sum of squared distances to the nominal centres (Umeyama, "Least-
//! squares estimation of transformation parameters between two point
//! patterns", IEEE TPAMI 13(4), 1991). Its scale is then the nominal's,
//! unless measured distances between sphere centres give it
//! ([`Distance`]): the scale that fits them best in the least-squares
//! sense, their σ weighing them, and the rotation and translation that
//! best overlay the nominal.
//!
//! **Covariance.** To first order, overlaying the nominal projects a
//! perturbation of the shape orthogonally off the similarity motions; the
//! projected pseudo-inverse `P (S + G Gᵀ)⁻¹ P` of the reduced information
//! `S` is then the shape's covariance over σ². With distances, the
//! scale's own perturbation (from the shape and from the distances' σ) is
//! propagated instead of projected away.

use super::bundle::similarity_generators;
use crate::pose::{nearest_rotation, Pose};
use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, Vector3};

/// A similarity `x ↦ s R x + c`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Similarity {
    /// Scale.
    pub scale: f64,
    /// Rotation.
    pub rotation: Rotation3<f64>,
    /// Translation, mm.
    pub translation: Vector3<f64>,
}

impl Similarity {
    /// The similarity that best maps `from` onto `to` (same length, at
    /// least three non-collinear points), scale included.
    pub fn onto(from: &[Vector3<f64>], to: &[Vector3<f64>]) -> Similarity {
        Self::fit(from, to, true)
    }

    /// The rigid motion (scale 1) that best maps `from` onto `to`.
    pub fn rigid_onto(from: &[Vector3<f64>], to: &[Vector3<f64>]) -> Similarity {
        Self::fit(from, to, false)
    }

    fn fit(from: &[Vector3<f64>], to: &[Vector3<f64>], with_scale: bool) -> Similarity {
        let n = from.len() as f64;
        let mean_from = from.iter().sum::<Vector3<f64>>() / n;
        let mean_to = to.iter().sum::<Vector3<f64>>() / n;
        let mut cross = Matrix3::zeros();
        let mut spread = 0.0;
        for (a, b) in from.iter().zip(to) {
            cross += (b - mean_to) * (a - mean_from).transpose();
            spread += (a - mean_from).norm_squared();
        }
        let rotation = nearest_rotation(&cross);
        let scale = if with_scale && spread > 0.0 {
            (rotation.matrix().transpose() * cross).trace() / spread
        } else {
            1.0
        };
        Similarity {
            scale,
            rotation,
            translation: mean_to - scale * (rotation * mean_from),
        }
    }

    /// The image of one point.
    pub fn apply(&self, x: &Vector3<f64>) -> Vector3<f64> {
        self.scale * (self.rotation * x) + self.translation
    }

    /// The images of points.
    pub fn apply_all(&self, points: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        points.iter().map(|x| self.apply(x)).collect()
    }

    /// The pose under which the mapped shape images as the shape did under
    /// `pose` (the camera frame scaled alike).
    pub fn carry_pose(&self, pose: &Pose) -> Pose {
        let rotation = pose.rotation * self.rotation.inverse();
        Pose::new(
            rotation,
            self.scale * pose.translation - rotation * self.translation,
        )
    }
}

/// A measured distance between two sphere centres (a caliper's), with its
/// σ.
#[derive(Debug, Clone, PartialEq)]
pub struct Distance {
    /// The first sphere (layout index).
    pub first: usize,
    /// The second sphere.
    pub second: usize,
    /// The measured distance, mm.
    pub mm: f64,
    /// Its 1σ, mm.
    pub sigma_mm: f64,
}

impl Distance {
    /// The distance between its spheres in `shape`.
    pub fn in_shape(&self, shape: &[Vector3<f64>]) -> f64 {
        (shape[self.first] - shape[self.second]).norm()
    }

    /// Its gradient with respect to the stacked shape.
    fn gradient(&self, shape: &[Vector3<f64>]) -> DVector<f64> {
        let mut g = DVector::zeros(3 * shape.len());
        let d = shape[self.first] - shape[self.second];
        let unit = d / d.norm();
        g.fixed_rows_mut::<3>(3 * self.first).copy_from(&unit);
        g.fixed_rows_mut::<3>(3 * self.second).copy_from(&-unit);
        g
    }
}

/// The scale that fits the distances best: `Σ w m d / Σ w d²` over the
/// measured `m` and the shape's `d`, `w = 1/σ²`.
pub fn distance_scale(shape: &[Vector3<f64>], distances: &[Distance]) -> f64 {
    let (numerator, denominator) = scale_sums(shape, distances);
    numerator / denominator
}

/// `(Σ w m d, Σ w d²)` of [`distance_scale`].
fn scale_sums(shape: &[Vector3<f64>], distances: &[Distance]) -> (f64, f64) {
    distances
        .iter()
        .fold((0.0, 0.0), |(numerator, denominator), distance| {
            let (d, w) = (distance.in_shape(shape), distance.sigma_mm.powi(-2));
            (numerator + w * distance.mm * d, denominator + w * d * d)
        })
}

/// The orthogonal projector off the columns of `g`.
fn projector_off(g: &DMatrix<f64>) -> DMatrix<f64> {
    let gram = g.transpose() * g;
    let inverse = gram
        .try_inverse()
        .unwrap_or_else(|| DMatrix::zeros(g.ncols(), g.ncols()));
    DMatrix::identity(g.nrows(), g.nrows()) - g * inverse * g.transpose()
}

/// `S⁺` for the reduced information `S` of `shape`, whose null space the
/// similarity motions span: `P (S + μ G Gᵀ)⁻¹ P`; `None` when `S` is
/// singular beyond them (a direction no frame observes).
pub fn gauge_inverse(information: &DMatrix<f64>, shape: &[Vector3<f64>]) -> Option<DMatrix<f64>> {
    let g = similarity_generators(shape);
    let mu = information.diagonal().mean() / (g.norm_squared() / 7.0).max(f64::MIN_POSITIVE);
    let pinned = information + &g * g.transpose() * mu;
    let inverse = pinned.cholesky()?.inverse();
    let p = projector_off(&g);
    Some(&p * inverse * &p)
}

/// The covariance of the reported shape (stacked, mm²) from the reduced
/// information `S` (normalised units) and the σ² of a centre (normalised
/// units²): in the gauge that overlays the nominal, with the nominal's
/// scale when `distances` is empty and the distances' otherwise.
pub fn shape_covariance(
    information: &DMatrix<f64>,
    shape: &[Vector3<f64>],
    sigma_squared: f64,
    distances: &[Distance],
) -> Option<DMatrix<f64>> {
    let raw = gauge_inverse(information, shape)? * sigma_squared;
    if distances.is_empty() {
        return Some(raw);
    }
    // s' = k(s) s, then overlaid rigidly: δs' = P_r (k δs + s ∇kᵀ δs + s ∂k/∂m δm).
    let g = similarity_generators(shape);
    let rigid = projector_off(&g.columns(0, 6).into_owned());
    let stacked = DVector::from_iterator(
        3 * shape.len(),
        shape.iter().flat_map(|x| x.iter().copied()),
    );
    let (numerator, denominator) = scale_sums(shape, distances);
    let k = numerator / denominator;
    let mut k_gradient = DVector::zeros(3 * shape.len());
    let mut measured_variance = 0.0;
    for distance in distances {
        let (d, w) = (distance.in_shape(shape), distance.sigma_mm.powi(-2));
        let dk_dd = (w * distance.mm * denominator - numerator * 2.0 * w * d) / denominator.powi(2);
        k_gradient += distance.gradient(shape) * dk_dd;
        let dk_dm = w * d / denominator;
        measured_variance += (dk_dm * distance.sigma_mm).powi(2);
    }
    let a = &rigid
        * (DMatrix::identity(3 * shape.len(), 3 * shape.len()) * k
            + &stacked * k_gradient.transpose());
    let scaled = &rigid * &stacked;
    Some(&a * raw * a.transpose() + &scaled * scaled.transpose() * measured_variance)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points() -> Vec<Vector3<f64>> {
        vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(50.0, 0.0, 0.0),
            Vector3::new(0.0, 50.0, 0.0),
            Vector3::new(0.0, 0.0, 50.0),
            Vector3::new(30.0, 20.0, 10.0),
        ]
    }

    #[test]
    fn a_similarity_is_recovered_and_carries_poses_unseen() {
        let truth = Similarity {
            scale: 1.004,
            rotation: Rotation3::from_euler_angles(0.2, -0.1, 0.7),
            translation: Vector3::new(3.0, -2.0, 1.0),
        };
        let from = points();
        let to = truth.apply_all(&from);
        let found = Similarity::onto(&from, &to);
        assert!((found.scale - truth.scale).abs() < 1e-12);
        assert!(found.rotation.angle_to(&truth.rotation) < 1e-12);
        assert!((found.translation - truth.translation).norm() < 1e-10);
        let rigid = Similarity::rigid_onto(&from, &to);
        assert_eq!(rigid.scale, 1.0);
        let pose = Pose::new(
            Rotation3::from_euler_angles(0.1, 0.3, -0.2),
            Vector3::new(5.0, 10.0, 400.0),
        );
        let carried = truth.carry_pose(&pose);
        for (x, y) in from.iter().zip(&to) {
            let (a, b) = (pose.project_normalised(x), carried.project_normalised(y));
            assert!((a - b).norm() < 1e-14, "{a} vs {b}");
        }
    }

    #[test]
    fn the_distance_scale_fits_the_distances() {
        let shape = points();
        let d = Distance {
            first: 0,
            second: 1,
            mm: 50.25,
            sigma_mm: 0.01,
        };
        assert!((distance_scale(&shape, &[d]) - 1.005).abs() < 1e-12);
    }
}
