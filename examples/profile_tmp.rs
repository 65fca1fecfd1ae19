use layout_opt::camera::Camera;
use layout_opt::pnp::{epnp, ml, Solver};
use layout_opt::synthetic::*;
use nalgebra::*;
use std::time::Instant;
fn main() {
    let camera = Camera::paper();
    let mut rng = stream_rng(1, 1, 1);
    let truth = random_pose(&mut rng, 500.0, 0.1);
    let p = project_with_noise(&mut rng, &camera, biprism_points(50.0), truth, 0.5).unwrap();
    let n = 20000;
    let m = SMatrix::<f64, 12, 12>::from_fn(|i, j| {
        ((i * 7 + j * 3) % 11) as f64 + if i == j { 20.0 } else { 0.0 }
    });
    let m = m + m.transpose();
    let t = Instant::now();
    for _ in 0..n {
        std::hint::black_box(SymmetricEigen::new(std::hint::black_box(m)));
    }
    println!(
        "symeig12 {:.2} us",
        t.elapsed().as_secs_f64() * 1e6 / n as f64
    );
    let m3 = Matrix3::new(1.0, 0.2, 0.3, 0.1, 0.9, 0.2, 0.0, 0.1, 1.1);
    let t = Instant::now();
    for _ in 0..n {
        std::hint::black_box(SVD::new(std::hint::black_box(m3), true, true));
    }
    println!("svd3 {:.3} us", t.elapsed().as_secs_f64() * 1e6 / n as f64);
    let ctrl = epnp::principal_control_points(&p.object);
    let t = Instant::now();
    for _ in 0..n {
        std::hint::black_box(epnp::EpnpSystem::new(ctrl, &p.object, &p.normalised).unwrap());
    }
    println!(
        "system {:.2} us",
        t.elapsed().as_secs_f64() * 1e6 / n as f64
    );
    let t = Instant::now();
    for _ in 0..n {
        std::hint::black_box(epnp::principal_control_points(&p.object));
    }
    println!("ctrl {:.2} us", t.elapsed().as_secs_f64() * 1e6 / n as f64);
    let start = Solver::ParallelWeighted
        .solve_best(&p.object, &p.normalised)
        .unwrap();
    let t = Instant::now();
    for _ in 0..n {
        std::hint::black_box(ml::refine(&start, &p.object, &p.normalised));
    }
    println!("lm {:.2} us", t.elapsed().as_secs_f64() * 1e6 / n as f64);
    for s in Solver::ALL {
        let t = Instant::now();
        for _ in 0..n {
            std::hint::black_box(s.solve_best(&p.object, &p.normalised).unwrap());
        }
        println!("{s} {:.2} us", t.elapsed().as_secs_f64() * 1e6 / n as f64);
    }
}
#[allow(dead_code)]
fn unused() {}
