//! Seeded synthetic PnP problems: the paper's biprism, random point clouds,
//! random poses, and noisy projections. Every random stream comes from a
//! [`ChaCha8Rng`] seeded by (seed, stream, case), so any case can be replayed
//! on its own and results do not depend on thread count.

use crate::camera::Camera;
use crate::pose::Pose;
use nalgebra::{Rotation3, UnitQuaternion, Vector2, Vector3, Vector4};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// A seeded random stream for case `case` of stream `stream` under `seed`:
/// ChaCha8 keyed by `seed`, on ChaCha stream `stream`, starting at word
/// `case · 2³²`, so every (stream, case) gets its own non-overlapping block
/// of 2³² words.
pub fn stream_rng(seed: u64, stream: u64, case: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    rng.set_word_pos(u128::from(case) << 32);
    rng
}

/// The paper's biprism (Fig. 6): the centre O0 and six vertices at distance
/// `arm_mm` on ±x, ±y, ±z, named and ordered as the paper does
/// (O0P1 = +z, O0P2 = +x, O0P5 = +y).
pub fn biprism(arm_mm: f64) -> Vec<(String, Vector3<f64>)> {
    let l = arm_mm;
    [
        ("O0", Vector3::new(0.0, 0.0, 0.0)),
        ("P1", Vector3::new(0.0, 0.0, l)),
        ("P2", Vector3::new(l, 0.0, 0.0)),
        ("P3", Vector3::new(0.0, 0.0, -l)),
        ("P4", Vector3::new(-l, 0.0, 0.0)),
        ("P5", Vector3::new(0.0, l, 0.0)),
        ("P6", Vector3::new(0.0, -l, 0.0)),
    ]
    .into_iter()
    .map(|(name, p)| (name.to_string(), p))
    .collect()
}

/// The biprism's points without names.
pub fn biprism_points(arm_mm: f64) -> Vec<Vector3<f64>> {
    biprism(arm_mm).into_iter().map(|(_, p)| p).collect()
}

/// A rotation drawn uniformly from SO(3) (normalised Gaussian quaternion).
pub fn uniform_rotation(rng: &mut impl Rng) -> Rotation3<f64> {
    let q = Vector4::from_fn(|_, _| rng.sample::<f64, _>(StandardNormal));
    UnitQuaternion::from_quaternion(nalgebra::Quaternion::from(q)).to_rotation_matrix()
}

/// `count` points uniform in a cube of side `size_mm` centred on the origin.
pub fn random_points(rng: &mut impl Rng, count: usize, size_mm: f64) -> Vec<Vector3<f64>> {
    (0..count)
        .map(|_| Vector3::from_fn(|_, _| (rng.random::<f64>() - 0.5) * size_mm))
        .collect()
}

/// A PnP problem with known answer.
#[derive(Debug, Clone)]
pub struct Problem {
    /// Object points, mm.
    pub object: Vec<Vector3<f64>>,
    /// Noisy pixel measurements.
    pub pixels: Vec<Vector2<f64>>,
    /// Undistorted normalised image points (what solvers take).
    pub normalised: Vec<Vector2<f64>>,
    /// The pose that generated the measurements.
    pub truth: Pose,
}

/// Projects `object` under `truth` through `camera`, adds isotropic Gaussian
/// pixel noise of `sigma_px`, and undistorts back to normalised coordinates.
/// Returns `None` if a point is not in front of the camera.
pub fn project_with_noise(
    rng: &mut impl Rng,
    camera: &Camera,
    object: Vec<Vector3<f64>>,
    truth: Pose,
    sigma_px: f64,
) -> Option<Problem> {
    let mut pixels = Vec::with_capacity(object.len());
    let mut normalised = Vec::with_capacity(object.len());
    for p in &object {
        let clean = camera.project(&truth.transform(p))?;
        let noise = Vector2::new(
            rng.sample::<f64, _>(StandardNormal),
            rng.sample::<f64, _>(StandardNormal),
        ) * sigma_px;
        let pixel = clean + noise;
        normalised.push(camera.pixel_to_normalised(&pixel).ok()?);
        pixels.push(pixel);
    }
    Some(Problem {
        object,
        pixels,
        normalised,
        truth,
    })
}

/// A pose with a uniformly random attitude that places the object origin at
/// depth `depth_mm`, shifted off the optical axis by up to
/// `max_off_axis_fraction · depth` in x and y.
pub fn random_pose(rng: &mut impl Rng, depth_mm: f64, max_off_axis_fraction: f64) -> Pose {
    let rotation = uniform_rotation(rng);
    let offset = |rng: &mut dyn rand::RngCore| {
        (rng.random::<f64>() * 2.0 - 1.0) * max_off_axis_fraction * depth_mm
    };
    let x = offset(rng);
    let y = offset(rng);
    Pose::new(rotation, Vector3::new(x, y, depth_mm))
}

/// A standard normal sample (re-exported for callers that draw noise).
pub fn standard_normal(rng: &mut impl Rng) -> f64 {
    StandardNormal.sample(rng)
}
