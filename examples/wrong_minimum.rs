//! Why `parallel-weighted` sometimes lands in a wrong minimum where the
//! unweighted `parallel-gn` from the same start does not (issue: the eq. 30
//! weights, or their floor?).
//!
//! Fig. 8's setting (n = 10 points uniform in [−500, 500]² × [500, 1500] mm,
//! random attitude, f = 80 px, σ = 1.5–2.5 px): every problem is solved from
//! the one paraperspective start with Gauss–Newton under several weightings,
//! and gross failures (geodesic error > 5°) are counted per weighting.
//!
//! `cargo run --release --features examples --example wrong_minimum [problems] [seed]`

use layout_opt::pnp::epnp::{EpnpSystem, PAIRS};
use layout_opt::pnp::gauss_newton::refine_betas;
use layout_opt::pnp::parallel::{reference_index, single_step, M_O_FLOOR_FRACTION};
use layout_opt::pnp::{best_candidate, Candidates};
use layout_opt::pose::{rotation_error_deg, Pose};
use layout_opt::synthetic::{standard_normal, stream_rng, uniform_rotation};
use nalgebra::{Vector2, Vector3};
use rand::Rng;

const FOCAL_PX: f64 = 80.0;
const GROSS_DEG: f64 = 5.0;

/// How the six pair weights are made from (d, tz, m_o, m, mean m).
#[derive(Clone, Copy)]
enum Weighting {
    Unit,
    /// Eq. 30 with m_o floored at `fraction` × the mean projected length.
    Eq30 {
        fraction: f64,
    },
    /// Eq. 30 without the m_o factor: d² / (tz² m).
    LengthOnly,
    /// Eq. 30 without the m factor: d² / (tz² m_o), floored as ours.
    AnchorOnly,
}

impl Weighting {
    fn name(self) -> String {
        match self {
            Weighting::Unit => "unit (parallel-gn)".into(),
            Weighting::Eq30 { fraction } => format!("eq. 30, m_o floor {fraction} × mean m"),
            Weighting::LengthOnly => "eq. 30 without m_o".into(),
            Weighting::AnchorOnly => "eq. 30 without m (floored m_o)".into(),
        }
    }

    fn weights(
        self,
        control_world: &[Vector3<f64>; 4],
        control_camera: &[Vector3<f64>; 4],
    ) -> [f64; 6] {
        let project = |p: &Vector3<f64>| Vector2::new(p.x / p.z, p.y / p.z);
        let m: [f64; 6] = std::array::from_fn(|k| {
            let (a, b) = PAIRS[k];
            (project(&control_camera[a]) - project(&control_camera[b])).norm()
        });
        let mean = m.iter().sum::<f64>() / 6.0;
        let tz = control_camera[0].z;
        std::array::from_fn(|k| {
            let (a, b) = PAIRS[k];
            let d2 = (control_world[a] - control_world[b]).norm_squared();
            let anchor = if a == 0 {
                control_camera[0]
            } else {
                (control_camera[a] + control_camera[b]) * 0.5
            };
            let m_o = |fraction: f64| {
                project(&anchor)
                    .norm()
                    .max(fraction * mean)
                    .max(f64::MIN_POSITIVE)
            };
            let m_k = m[k].max(f64::MIN_POSITIVE);
            match self {
                Weighting::Unit => 1.0,
                Weighting::Eq30 { fraction } => d2 / (tz * tz * m_o(fraction) * m_k),
                Weighting::LengthOnly => d2 / (tz * tz * m_k),
                Weighting::AnchorOnly => d2 / (tz * tz * m_o(M_O_FLOOR_FRACTION)),
            }
        })
    }
}

/// The paper's pipeline from the single paraperspective start with `weighting`.
fn solve(object: &[Vector3<f64>], image: &[Vector2<f64>], weighting: Weighting) -> Option<Pose> {
    let start = single_step(object, image).ok()?;
    let shift = object[reference_index(object)];
    let s = object
        .iter()
        .map(|p| (p - shift).norm())
        .fold(0.0, f64::max);
    let control_world = [
        shift,
        shift + Vector3::new(s, 0.0, 0.0),
        shift + Vector3::new(0.0, s, 0.0),
        shift + Vector3::new(0.0, 0.0, s),
    ];
    let control_camera = control_world.map(|c| start.transform(&c));
    let weights = weighting.weights(&control_world, &control_camera);
    let system = EpnpSystem::new(control_world, object, image).ok()?;
    let betas = system.betas_from_control_camera(&control_camera);
    let mut candidates = Candidates::new();
    system.push_candidates(
        &betas,
        |b| refine_betas(&system, b, &weights),
        &mut candidates,
    );
    best_candidate("probe", &candidates, object, image).ok()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let problems: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(2000);
    let seed: u64 = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(7);
    let weightings = [
        Weighting::Unit,
        Weighting::Eq30 {
            fraction: M_O_FLOOR_FRACTION,
        },
        Weighting::Eq30 { fraction: 0.0 },
        Weighting::Eq30 { fraction: 2.0 },
        Weighting::LengthOnly,
        Weighting::AnchorOnly,
    ];
    for sigma_px in [1.5, 2.0, 2.5] {
        let mut gross = vec![0usize; weightings.len()];
        let mut only_weighted = 0;
        for case in 0..problems as u64 {
            let mut rng = stream_rng(seed, (sigma_px * 10.0) as u64, case);
            let rotation = uniform_rotation(&mut rng);
            let camera_points: Vec<Vector3<f64>> = (0..10)
                .map(|_| {
                    Vector3::new(
                        rng.random_range(-500.0..500.0),
                        rng.random_range(-500.0..500.0),
                        rng.random_range(500.0..1500.0),
                    )
                })
                .collect();
            let centroid = camera_points.iter().sum::<Vector3<f64>>() / 10.0;
            let object: Vec<Vector3<f64>> = camera_points
                .iter()
                .map(|p| rotation.inverse() * (p - centroid))
                .collect();
            let truth = Pose::new(rotation, centroid);
            let image: Vec<Vector2<f64>> = camera_points
                .iter()
                .map(|p| {
                    let noise = Vector2::new(standard_normal(&mut rng), standard_normal(&mut rng));
                    Vector2::new(p.x / p.z, p.y / p.z) + noise * (sigma_px / FOCAL_PX)
                })
                .collect();
            let failed: Vec<bool> = weightings
                .iter()
                .map(|&w| {
                    solve(&object, &image, w).is_none_or(|pose| {
                        rotation_error_deg(&truth.rotation, &pose.rotation) > GROSS_DEG
                    })
                })
                .collect();
            for (g, &f) in gross.iter_mut().zip(&failed) {
                *g += usize::from(f);
            }
            only_weighted += usize::from(failed[1] && !failed[0]);
        }
        println!("σ = {sigma_px} px, {problems} problems (f = {FOCAL_PX} px, n = 10):");
        for (w, g) in weightings.iter().zip(&gross) {
            println!("  {:<40} gross failures {g}", w.name());
        }
        println!("  eq. 30 (ours) fails where unit weights do not: {only_weighted}");
    }
}
