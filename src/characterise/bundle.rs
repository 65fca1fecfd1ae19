//! Bundle adjustment of a rigid marker seen by one calibrated camera: the
//! sphere centres of the part and the pose of every frame, estimated
//! jointly from the spheres' projected centres.
//!
//! **Model.** Frame `f` sees sphere `i` at the normalised point
//! `π(R_f X_i + t_f)`, `π(x, y, z) = (x/z, y/z)` (undistorted; the tracker
//! undistorts its centres). The unknowns are the 3N centres `X_i` and the
//! 6F pose perturbations `(ω, δt)` of [`normalised_projection_jacobian`].
//!
//! **Solver.** Levenberg–Marquardt on the weighted normal equations, with
//! every frame's six pose unknowns eliminated by a Schur complement
//! (Triggs, McLauchlan, Hartley and Fitzgibbon, "Bundle adjustment — a
//! modern synthesis", 2000, §6.1): the reduced system in the 3N shape
//! unknowns is dense and small (N ≤ a few hundred), the eliminated blocks
//! are 6×6. A robust Huber weight (IRLS, scale from the residuals' median)
//! keeps a stray centre from pulling the shape.
//!
//! **Gauge.** A single camera sees the shape only up to a similarity: a
//! rotation, a translation and a scale of the part, compensated by the
//! poses, leave every image unchanged. The reduced information matrix
//! therefore has the seven-dimensional null space spanned by
//! [`similarity_generators`]. Steps are taken with that null space pinned
//! (a multiple of `G Gᵀ` added, which moves nothing the images see), and
//! [`super::gauge`] fixes the gauge afterwards.

use crate::pose::{normalised_projection_jacobian, perturb, Pose};
use nalgebra::{DMatrix, DVector, Matrix3, SMatrix, Vector2, Vector3};

/// One measured centre: sphere `sphere` in frame `frame`, on the
/// undistorted normalised plane, with its σ relative to the others
/// (1 for all centres alike).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// Index of the frame (into the poses).
    pub frame: usize,
    /// Index of the sphere (into the shape).
    pub sphere: usize,
    /// The measured projected centre, normalised.
    pub normalised: Vector2<f64>,
}

/// Fewest frames a characterisation adjusts (and a capture plan offers).
pub const MIN_FRAMES: usize = 6;

/// Tolerances of the adjustment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BundleOptions {
    /// Most Levenberg–Marquardt iterations per robust round.
    pub max_iterations: usize,
    /// Robust rounds (weights recomputed from the residuals).
    pub robust_rounds: usize,
    /// Huber threshold, in units of the residuals' robust σ.
    pub huber_k: f64,
}

/// Levenberg–Marquardt stops when a step lowers the cost by less than
/// this fraction of it.
pub const RELATIVE_COST_TOLERANCE: f64 = 1e-14;

/// The starting damping, relative to the mean diagonal of the system.
const INITIAL_DAMPING: f64 = 1e-4;

/// The damping beyond which no step is found (the cost is at a minimum to
/// rounding).
const MAX_DAMPING: f64 = 1e12;

impl Default for BundleOptions {
    fn default() -> Self {
        BundleOptions {
            max_iterations: 100,
            robust_rounds: 3,
            huber_k: 3.0,
        }
    }
}

/// Why an adjustment could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum BundleError {
    /// An observation names a frame or sphere that does not exist.
    #[error("observation {index} names frame {frame} and sphere {sphere}, but there are {frames} frames and {spheres} spheres")]
    OutOfRange {
        /// The observation.
        index: usize,
        /// Its frame.
        frame: usize,
        /// Its sphere.
        sphere: usize,
        /// Frames.
        frames: usize,
        /// Spheres.
        spheres: usize,
    },
    /// A value is not finite.
    #[error("{0} is not finite")]
    NotFinite(String),
    /// Fewer equations than unknowns.
    #[error("{observations} centres cannot determine {spheres} sphere centres and {frames} poses ({unknowns} unknowns up to a similarity); add frames")]
    TooFewObservations {
        /// Centres measured.
        observations: usize,
        /// Spheres.
        spheres: usize,
        /// Frames.
        frames: usize,
        /// Unknowns less the gauge's seven.
        unknowns: usize,
    },
    /// A sphere went behind a frame's camera during the adjustment.
    #[error("sphere {sphere} is behind the camera of frame {frame}")]
    Behind {
        /// The frame.
        frame: usize,
        /// The sphere.
        sphere: usize,
    },
}

/// The adjusted shape and poses.
#[derive(Debug, Clone, PartialEq)]
pub struct Bundle {
    /// Sphere centres, in the gauge the steps left them in.
    pub shape: Vec<Vector3<f64>>,
    /// Each frame's pose, object → camera.
    pub poses: Vec<Pose>,
    /// Each observation's residual, model minus measured, normalised.
    pub residuals: Vec<Vector2<f64>>,
    /// Each observation's robust weight in (0, 1].
    pub weights: Vec<f64>,
    /// Levenberg–Marquardt iterations over all robust rounds.
    pub iterations: usize,
}

/// The seven motions of a shape (stacked `[X_0; X_1; …]`) that a single
/// camera cannot see: three rotations about the origin, three
/// translations and a scaling about the origin, as the columns of a
/// 3N × 7 matrix.
pub fn similarity_generators(shape: &[Vector3<f64>]) -> DMatrix<f64> {
    let mut g = DMatrix::zeros(3 * shape.len(), 7);
    for (i, x) in shape.iter().enumerate() {
        let rotation = -x.cross_matrix();
        for r in 0..3 {
            for c in 0..3 {
                g[(3 * i + r, c)] = rotation[(r, c)];
            }
            g[(3 * i + r, 3 + r)] = 1.0;
            g[(3 * i + r, 6)] = x[r];
        }
    }
    g
}

/// The camera-frame point, its normalised image and the Jacobians of the
/// image with respect to the pose `(ω, δt)` and the object point.
fn project(
    pose: &Pose,
    point: &Vector3<f64>,
) -> Option<(Vector2<f64>, SMatrix<f64, 2, 6>, SMatrix<f64, 2, 3>)> {
    let camera = pose.transform(point);
    if camera.z.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let image = Vector2::new(camera.x / camera.z, camera.y / camera.z);
    let pose_jacobian = normalised_projection_jacobian(pose, point);
    let point_jacobian = pose_jacobian.fixed_view::<2, 3>(0, 3) * pose.rotation.matrix();
    Some((image, pose_jacobian, point_jacobian))
}

/// Residuals of every observation at `shape` and `poses` (model minus
/// measured), or the first sphere behind its camera.
fn residuals(
    shape: &[Vector3<f64>],
    poses: &[Pose],
    observations: &[Observation],
) -> Result<Vec<Vector2<f64>>, BundleError> {
    observations
        .iter()
        .map(|o| {
            let camera = poses[o.frame].transform(&shape[o.sphere]);
            if camera.z.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                return Err(BundleError::Behind {
                    frame: o.frame,
                    sphere: o.sphere,
                });
            }
            Ok(Vector2::new(camera.x / camera.z, camera.y / camera.z) - o.normalised)
        })
        .collect()
}

fn weighted_cost(residuals: &[Vector2<f64>], weights: &[f64]) -> f64 {
    residuals
        .iter()
        .zip(weights)
        .map(|(r, w)| w * r.norm_squared())
        .sum()
}

/// The normal equations of one linearisation, poses not yet eliminated.
struct Normal {
    /// Per frame: the 6×6 pose block and the pose gradient.
    pose_blocks: Vec<(SMatrix<f64, 6, 6>, SMatrix<f64, 6, 1>)>,
    /// Per observation: the 6×3 pose–point block.
    cross: Vec<SMatrix<f64, 6, 3>>,
    /// Per sphere: the 3×3 point block and the point gradient.
    point_blocks: Vec<(Matrix3<f64>, Vector3<f64>)>,
}

fn normal_equations(
    shape: &[Vector3<f64>],
    poses: &[Pose],
    observations: &[Observation],
    weights: &[f64],
) -> Result<Normal, BundleError> {
    let mut normal = Normal {
        pose_blocks: vec![(SMatrix::zeros(), SMatrix::zeros()); poses.len()],
        cross: Vec::with_capacity(observations.len()),
        point_blocks: vec![(Matrix3::zeros(), Vector3::zeros()); shape.len()],
    };
    for (o, w) in observations.iter().zip(weights) {
        let (image, jp, jx) =
            project(&poses[o.frame], &shape[o.sphere]).ok_or(BundleError::Behind {
                frame: o.frame,
                sphere: o.sphere,
            })?;
        let r = image - o.normalised;
        let (u, gp) = &mut normal.pose_blocks[o.frame];
        *u += jp.transpose() * jp * *w;
        *gp += jp.transpose() * r * *w;
        let (v, gx) = &mut normal.point_blocks[o.sphere];
        *v += jx.transpose() * jx * *w;
        *gx += jx.transpose() * r * *w;
        normal.cross.push(jp.transpose() * jx * *w);
    }
    Ok(normal)
}

/// The reduced system and what back-substitution needs.
struct Reduced {
    /// S, 3N × 3N.
    system: DMatrix<f64>,
    /// The right-hand side.
    rhs: DVector<f64>,
    /// Each frame's damped pose block, inverted.
    pose_inverses: Vec<SMatrix<f64, 6, 6>>,
}

/// The reduced (Schur) system in the shape: `S δX = −g`, with every pose
/// block damped by `1 + damping` on its diagonal (and the point blocks
/// likewise). Returns S and the right-hand side.
fn reduced_system(
    normal: &Normal,
    observations: &[Observation],
    spheres: usize,
    damping: f64,
) -> Option<Reduced> {
    let mut s = DMatrix::zeros(3 * spheres, 3 * spheres);
    let mut rhs = DVector::zeros(3 * spheres);
    for (i, (v, g)) in normal.point_blocks.iter().enumerate() {
        let mut damped = *v;
        for k in 0..3 {
            damped[(k, k)] *= 1.0 + damping;
        }
        s.fixed_view_mut::<3, 3>(3 * i, 3 * i).copy_from(&damped);
        rhs.fixed_rows_mut::<3>(3 * i).copy_from(&-g);
    }
    // Observations are grouped by frame when eliminated.
    let mut by_frame: Vec<Vec<usize>> = vec![Vec::new(); normal.pose_blocks.len()];
    for (k, o) in observations.iter().enumerate() {
        by_frame[o.frame].push(k);
    }
    let mut inverses = Vec::with_capacity(normal.pose_blocks.len());
    for (frame, (u, gp)) in normal.pose_blocks.iter().enumerate() {
        let mut damped = *u;
        for k in 0..6 {
            damped[(k, k)] *= 1.0 + damping;
        }
        let inverse = damped.cholesky()?.inverse();
        inverses.push(inverse);
        let members = &by_frame[frame];
        for &a in members {
            let wa = inverse * normal.cross[a];
            let ia = observations[a].sphere;
            // rhs_i −= Wᵢᵀ U⁻¹ (−g_p)
            let correction = normal.cross[a].transpose() * (inverse * gp);
            let mut block = rhs.fixed_rows_mut::<3>(3 * ia);
            block += correction;
            for &b in members {
                let ib = observations[b].sphere;
                let product = normal.cross[b].transpose() * wa;
                let mut target = s.fixed_view_mut::<3, 3>(3 * ib, 3 * ia);
                target -= product;
            }
        }
    }
    Some(Reduced {
        system: s,
        rhs,
        pose_inverses: inverses,
    })
}

/// The information matrix of the shape with the poses eliminated (the
/// reduced system undamped), at `shape` and `poses` with the weights
/// given, in normalised units: the shape's covariance is σ² times its
/// pseudo-inverse.
pub fn shape_information(
    shape: &[Vector3<f64>],
    poses: &[Pose],
    observations: &[Observation],
    weights: &[f64],
) -> Result<DMatrix<f64>, BundleError> {
    let normal = normal_equations(shape, poses, observations, weights)?;
    // A frame whose pose block is singular sees too little to eliminate;
    // its information is left out (ridge of rounding size).
    match reduced_system(&normal, observations, shape.len(), 0.0) {
        Some(reduced) => Ok(reduced.system),
        None => reduced_system(&normal, observations, shape.len(), 1e-12)
            .map(|reduced| reduced.system)
            .ok_or(BundleError::NotFinite("the information matrix".into())),
    }
}

/// Checks the inputs of [`adjust`].
fn check(
    shape: &[Vector3<f64>],
    poses: &[Pose],
    observations: &[Observation],
) -> Result<(), BundleError> {
    for (index, o) in observations.iter().enumerate() {
        if o.frame >= poses.len() || o.sphere >= shape.len() {
            return Err(BundleError::OutOfRange {
                index,
                frame: o.frame,
                sphere: o.sphere,
                frames: poses.len(),
                spheres: shape.len(),
            });
        }
        if !(o.normalised.x.is_finite() && o.normalised.y.is_finite()) {
            return Err(BundleError::NotFinite(format!("observation {index}")));
        }
    }
    if shape.iter().any(|x| !x.iter().all(|v| v.is_finite())) {
        return Err(BundleError::NotFinite("the starting shape".into()));
    }
    if poses.iter().any(|p| !p.is_finite()) {
        return Err(BundleError::NotFinite("a starting pose".into()));
    }
    let unknowns = (3 * shape.len() + 6 * poses.len()).saturating_sub(7);
    if 2 * observations.len() < unknowns + 1 {
        return Err(BundleError::TooFewObservations {
            observations: observations.len(),
            spheres: shape.len(),
            frames: poses.len(),
            unknowns,
        });
    }
    Ok(())
}

/// The robust σ of residuals (normalised): the median residual length
/// over its value for a unit 2-D Gaussian, `√(2 ln 2)`.
pub fn robust_sigma(residuals: &[Vector2<f64>]) -> f64 {
    let mut lengths: Vec<f64> = residuals.iter().map(|r| r.norm()).collect();
    crate::statistics::median(&mut lengths).unwrap_or(0.0) / (2.0 * std::f64::consts::LN_2).sqrt()
}

/// Adjusts `shape` and `poses` to the observations (module docs).
pub fn adjust(
    shape: &[Vector3<f64>],
    poses: &[Pose],
    observations: &[Observation],
    options: &BundleOptions,
) -> Result<Bundle, BundleError> {
    check(shape, poses, observations)?;
    let mut shape = shape.to_vec();
    let mut poses = poses.to_vec();
    let mut weights = vec![1.0; observations.len()];
    let mut iterations = 0;
    for round in 0..options.robust_rounds.max(1) {
        if round > 0 {
            let residuals = residuals(&shape, &poses, observations)?;
            let sigma = robust_sigma(&residuals);
            let threshold = options.huber_k * sigma;
            for (w, r) in weights.iter_mut().zip(&residuals) {
                let length = r.norm();
                *w = if length <= threshold || threshold <= 0.0 {
                    1.0
                } else {
                    threshold / length
                };
            }
        }
        iterations += levenberg_marquardt(
            &mut shape,
            &mut poses,
            observations,
            &weights,
            options.max_iterations,
        )?;
    }
    let residuals = residuals(&shape, &poses, observations)?;
    Ok(Bundle {
        shape,
        poses,
        residuals,
        weights,
        iterations,
    })
}

/// Levenberg–Marquardt with fixed weights; returns the iterations taken.
fn levenberg_marquardt(
    shape: &mut [Vector3<f64>],
    poses: &mut [Pose],
    observations: &[Observation],
    weights: &[f64],
    max_iterations: usize,
) -> Result<usize, BundleError> {
    let mut cost = weighted_cost(&residuals(shape, poses, observations)?, weights);
    let mut damping = INITIAL_DAMPING;
    for iteration in 0..max_iterations {
        let normal = normal_equations(shape, poses, observations, weights)?;
        let mut stepped = false;
        while damping <= MAX_DAMPING {
            let Some(Reduced {
                system: mut s,
                rhs,
                pose_inverses: inverses,
            }) = reduced_system(&normal, observations, shape.len(), damping)
            else {
                damping *= 10.0;
                continue;
            };
            // Pin the gauge: G Gᵀ scaled to the system's diagonal.
            let g = similarity_generators(shape);
            let scale = s.diagonal().mean() / (g.norm_squared() / 7.0).max(f64::MIN_POSITIVE);
            s += &g * g.transpose() * scale;
            let Some(cholesky) = s.cholesky() else {
                damping *= 10.0;
                continue;
            };
            let step_shape = cholesky.solve(&rhs);
            let trial_shape: Vec<Vector3<f64>> = shape
                .iter()
                .enumerate()
                .map(|(i, x)| x + step_shape.fixed_rows::<3>(3 * i))
                .collect();
            // Back-substitution: δp_f = U_f⁻¹ (−g_f − Σ W δX).
            let mut pose_rhs: Vec<SMatrix<f64, 6, 1>> =
                normal.pose_blocks.iter().map(|(_, gp)| -gp).collect();
            for (k, o) in observations.iter().enumerate() {
                pose_rhs[o.frame] -= normal.cross[k] * step_shape.fixed_rows::<3>(3 * o.sphere);
            }
            let trial_poses: Vec<Pose> = poses
                .iter()
                .zip(inverses.iter().zip(&pose_rhs))
                .map(|(pose, (inverse, b))| perturb(pose, &(inverse * b)))
                .collect();
            let trial_cost = match residuals(&trial_shape, &trial_poses, observations) {
                Ok(r) => weighted_cost(&r, weights),
                Err(_) => f64::INFINITY,
            };
            if trial_cost.is_finite() && trial_cost <= cost {
                let decrease = cost - trial_cost;
                shape.copy_from_slice(&trial_shape);
                poses.copy_from_slice(&trial_poses);
                cost = trial_cost;
                damping = (damping / 3.0).max(1e-12);
                stepped = true;
                if decrease <= RELATIVE_COST_TOLERANCE * cost.max(f64::MIN_POSITIVE) {
                    return Ok(iteration + 1);
                }
                break;
            }
            damping *= 4.0;
        }
        if !stepped {
            return Ok(iteration);
        }
    }
    Ok(max_iterations)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    pub(crate) fn shape() -> Vec<Vector3<f64>> {
        vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(50.0, 0.0, 0.0),
            Vector3::new(0.0, 50.0, 0.0),
            Vector3::new(0.0, 0.0, 50.0),
            Vector3::new(40.0, 35.0, 10.0),
            Vector3::new(-30.0, 20.0, 25.0),
            Vector3::new(20.0, -30.0, 30.0),
        ]
    }

    fn views(count: usize) -> Vec<Pose> {
        (0..count)
            .map(|k| {
                let a = k as f64 / count as f64 * std::f64::consts::TAU;
                let rotation = Rotation3::from_euler_angles(0.5 * a.cos(), 0.5 * a.sin(), a);
                Pose::new(
                    rotation,
                    Vector3::new(10.0 * a.sin(), -5.0, 400.0 + 30.0 * a.cos()),
                )
            })
            .collect()
    }

    fn observe(
        shape: &[Vector3<f64>],
        poses: &[Pose],
        sigma: f64,
        rng: &mut ChaCha8Rng,
    ) -> Vec<Observation> {
        let mut out = Vec::new();
        for (f, pose) in poses.iter().enumerate() {
            for (i, x) in shape.iter().enumerate() {
                let noise = Vector2::new(rng.sample(StandardNormal), rng.sample(StandardNormal));
                out.push(Observation {
                    frame: f,
                    sphere: i,
                    normalised: pose.project_normalised(x) + noise * sigma,
                });
            }
        }
        out
    }

    #[test]
    fn similarity_generators_leave_the_images_unchanged() {
        let shape = shape();
        let poses = views(3);
        let g = similarity_generators(&shape);
        let information = shape_information(
            &shape,
            &poses,
            &observe(&shape, &poses, 0.0, &mut ChaCha8Rng::seed_from_u64(1)),
            &[1.0; 21],
        )
        .unwrap();
        let leak = (&information * &g).norm() / information.norm();
        assert!(leak < 1e-9, "{leak}");
        // And nothing else is unseen: exactly seven null directions.
        let eigen = information.symmetric_eigen();
        let mut values: Vec<f64> = eigen.eigenvalues.iter().copied().collect();
        values.sort_by(f64::total_cmp);
        assert!(values[6] < 1e-9 * values[20], "{values:?}");
        assert!(values[7] > 1e-6 * values[20], "{values:?}");
    }

    #[test]
    fn noise_free_images_give_the_shape_back_up_to_a_similarity() {
        let truth = shape();
        let poses = views(12);
        let observations = observe(&truth, &poses, 0.0, &mut ChaCha8Rng::seed_from_u64(2));
        // Start 0.3 mm off per coordinate, poses 1° and 2 mm off.
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let start: Vec<Vector3<f64>> = truth
            .iter()
            .map(|x| x + Vector3::from_fn(|_, _| rng.random_range(-0.3..0.3)))
            .collect();
        let start_poses: Vec<Pose> = poses
            .iter()
            .map(|p| {
                perturb(
                    p,
                    &SMatrix::<f64, 6, 1>::new(0.01, -0.01, 0.005, 2.0, -1.0, 2.0),
                )
            })
            .collect();
        let bundle = adjust(
            &start,
            &start_poses,
            &observations,
            &BundleOptions::default(),
        )
        .unwrap();
        let worst = bundle
            .residuals
            .iter()
            .map(|r| r.norm())
            .fold(0.0, f64::max);
        assert!(worst < 1e-12, "{worst}");
        let aligned =
            super::super::gauge::Similarity::onto(&bundle.shape, &truth).apply_all(&bundle.shape);
        for (a, t) in aligned.iter().zip(&truth) {
            assert!((a - t).norm() < 1e-9, "{a} vs {t}");
        }
    }

    #[test]
    fn errors_name_their_input() {
        let shape = shape();
        let poses = views(2);
        let bad = [Observation {
            frame: 5,
            sphere: 0,
            normalised: Vector2::zeros(),
        }];
        let error = adjust(&shape, &poses, &bad, &BundleOptions::default()).unwrap_err();
        assert_eq!(
            error.to_string(),
            "observation 0 names frame 5 and sphere 0, but there are 2 frames and 7 spheres"
        );
        let few = observe(&shape, &poses[..1], 0.0, &mut ChaCha8Rng::seed_from_u64(4));
        let error = adjust(&shape, &poses[..1], &few, &BundleOptions::default()).unwrap_err();
        assert!(
            matches!(error, BundleError::TooFewObservations { .. }),
            "{error}"
        );
        let nan = [Observation {
            frame: 0,
            sphere: 0,
            normalised: Vector2::new(f64::NAN, 0.0),
        }];
        let error = adjust(&shape, &poses, &nan, &BundleOptions::default()).unwrap_err();
        assert_eq!(error.to_string(), "observation 0 is not finite");
    }
}
