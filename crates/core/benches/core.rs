//! Criterion benchmarks of the core: shadow rays through the BVH (one thread), the
//! form-factor kernels (point-to-polygon contour, exact polygon-to-polygon), one form-factor
//! row, one shot and one Gauss-Seidel sweep on cached rows, and a whole Cornell solve. Speed
//! targets live here, never in unit tests.
//!
//! `cargo bench --bench core`

use std::hint::black_box;
use std::sync::atomic::AtomicBool;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::DVec3;
use nusselt_core::geometry::{Bvh, Ray};
use nusselt_core::mesh::{Mesh, MeshSpec};
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::{ProgressiveSolver, SolverConfig, SolverKind, StopCriteria, run_solver};

mod common;
use common::segments;

fn cornell() -> Scene {
    Scene::builtin("cornell", &LoadOptions::default()).expect("cornell")
}

fn bvh_rays(c: &mut Criterion) {
    let scene = cornell();
    let mesh = Mesh::build(&scene, &MeshSpec::element(20.0)).expect("mesh");
    let bvh = Bvh::build(&mesh.blocker_triangles(&scene));
    let segs = segments(&mesh, 100_000);
    let mut g = c.benchmark_group("bvh");
    g.throughput(Throughput::Elements(segs.len() as u64));
    g.bench_function("cornell_shadow_rays_one_thread", |b| {
        b.iter(|| {
            let mut blocked = 0usize;
            for (a, p) in &segs {
                blocked += bvh.any_hit(&Ray::new(*a, *p - *a), 1e-6, 1.0 - 1e-6) as usize;
            }
            black_box(blocked)
        })
    });
    g.bench_function("cornell_closest_hit_one_thread", |b| {
        b.iter(|| {
            let mut t = 0.0;
            for (a, p) in &segs {
                if let Some(h) = bvh.closest_hit(&Ray::new(*a, *p - *a), 1e-6, f64::INFINITY) {
                    t += h.t;
                }
            }
            black_box(t)
        })
    });
    g.finish();
}

fn solve(c: &mut Criterion) {
    let mut g = c.benchmark_group("solver");
    g.sample_size(10);
    g.bench_function("cornell_row_light_default_mesh", |b| {
        let solver = ProgressiveSolver::new(cornell(), SolverConfig::default()).expect("solver");
        let light = solver.next_shooter().expect("a light");
        b.iter(|| {
            // A fresh solver per row would measure meshing; compute the row directly.
            let mut out = vec![0f32; solver.mesh().elements.len()];
            let ctx = solver.row_context();
            nusselt_core::formfactor::compute_row(
                solver.config().formfactor.method,
                &ctx,
                light,
                &mut out,
                &AtomicBool::new(false),
            );
            black_box(out)
        })
    });
    g.bench_function("cornell_solve_to_1e-3_element_24mm", |b| {
        b.iter(|| {
            let config = SolverConfig {
                mesh: MeshSpec::sized(24.0, 48.0),
                ..Default::default()
            };
            let mut s = ProgressiveSolver::new(cornell(), config).expect("solver");
            let stop = StopCriteria {
                residual: 1e-3,
                ..Default::default()
            };
            s.run(&stop, &AtomicBool::new(false), &mut |_| {});
            black_box(s.shots())
        })
    });
    g.finish();
}

/// The two analytic kernels on a unit square and a parallel one at distance 1 (Howell
/// C-11, F = 0.1998).
fn kernels(c: &mut Criterion) {
    let square = |z: f64| {
        vec![
            DVec3::new(0.0, 0.0, z),
            DVec3::new(1.0, 0.0, z),
            DVec3::new(1.0, 1.0, z),
            DVec3::new(0.0, 1.0, z),
        ]
    };
    let (bottom, mut top) = (square(0.0), square(1.0));
    top.reverse();
    let mut g = c.benchmark_group("formfactor");
    g.bench_function("point_to_polygon_contour", |b| {
        b.iter(|| {
            nusselt_core::formfactor::contour::point_to_polygon(
                black_box(DVec3::new(0.5, 0.5, 0.0)),
                DVec3::Z,
                black_box(&top),
            )
        })
    });
    g.bench_function("polygon_to_polygon_exact", |b| {
        b.iter(|| nusselt_core::formfactor::exact::polygon_to_polygon(black_box(&bottom), &top))
    });
    g.finish();
}

/// One shot and one sweep on rows already cached (the solver's inner loops without the
/// form factors): the Cornell box at its default mesh.
fn steps(c: &mut Criterion) {
    let mut g = c.benchmark_group("step");
    g.sample_size(20);
    let never = AtomicBool::new(false);
    // Shooting: 2,000 shots first, so that the rows of the patches that shoot are cached.
    let mut shooting = ProgressiveSolver::new(cornell(), SolverConfig::default()).expect("solver");
    let warm = StopCriteria {
        residual: 0.0,
        max_steps: Some(2_000),
        ..Default::default()
    };
    shooting.run(&warm, &never, &mut |_| {});
    g.bench_function("cornell_one_shot_cached_row", |b| {
        b.iter(|| {
            // Converged: back to dark (rows stay cached) and on.
            if shooting.shoot(&never).is_none() {
                shooting.reset();
            }
        })
    });
    let problem = shooting.problem();
    let problem = nusselt_core::solver::Problem::new(problem.scene.clone(), problem.config.clone())
        .expect("problem");
    let mut gs = SolverKind::GaussSeidel
        .build(problem)
        .expect("gauss-seidel");
    let rows = StopCriteria {
        residual: 0.0,
        max_steps: Some(gs.problem().mesh.patches.len()),
        ..Default::default()
    };
    run_solver(gs.as_mut(), &rows, &never, &mut |_, _| {});
    g.bench_function("cornell_one_gauss_seidel_sweep", |b| {
        b.iter(|| {
            if !gs.step(&never) {
                gs.reset();
            }
        })
    });
    g.finish();
}

criterion_group!(benches, bvh_rays, kernels, steps, solve);
criterion_main!(benches);
