//! The GPU hemicube (wgpu; lavapipe on machines without a GPU) against the CPU hemicube.
//!
//! Skipped when no adapter can be opened, unless `CI` is set: CI installs lavapipe, so there
//! a missing adapter is a failure.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use glam::DVec3;
use nusselt::cli::cases;
use nusselt::formfactor::hemicube::{
    self, DeltaTable, Hemicube, HemicubeView, ItemBufferRaster, NONE,
};
use nusselt::formfactor::{FormFactorMethod, FormFactorParams};
use nusselt::gpu::GpuHemicube;
use nusselt::mesh::PatchId;
use nusselt::scene::{LoadOptions, Scene};
use nusselt::solver::{ProgressiveSolver, SolverConfig, StopCriteria};

fn gpu() -> Option<GpuHemicube> {
    match GpuHemicube::new() {
        Ok(g) => {
            eprintln!("adapter: {}", g.adapter());
            Some(g)
        }
        Err(e) if std::env::var_os("CI").is_none() => {
            eprintln!("skipped: {e}");
            None
        }
        Err(e) => panic!("CI has lavapipe, yet: {e}"),
    }
}

fn cornell_config(
    method: FormFactorMethod,
    raster: Option<Arc<dyn ItemBufferRaster>>,
) -> SolverConfig {
    SolverConfig {
        element_size: Some(40.0),
        patch_size: Some(80.0),
        method,
        formfactor: FormFactorParams {
            hemicube_res: 128,
            ..Default::default()
        },
        raster,
        ..Default::default()
    }
}

fn cornell() -> Scene {
    Scene::builtin("cornell", &LoadOptions::default()).expect("cornell")
}

/// The item buffers of both rasterisers for every patch of a coarse Cornell box: the same
/// id in all but a few pixels, which lie on polygon edges (pixel centres on an edge, f32 vs
/// f64), and per-element form factors equal to float precision elsewhere.
#[test]
fn gpu_item_buffer_matches_the_cpu_hemicube() {
    let Some(gpu) = gpu() else { return };
    let solver =
        ProgressiveSolver::new(cornell(), cornell_config(FormFactorMethod::Hemicube, None))
            .expect("solver");
    let mesh = solver.mesh();
    let params = solver.config().formfactor.clone();
    let ctx = solver.row_context();
    let table = DeltaTable::new(params.hemicube_res);
    let never = AtomicBool::new(false);
    let (mut pixels, mut differing) = (0usize, 0usize);
    let (mut elements, mut identical) = (0usize, 0usize);
    let mut worst_row: f64 = 0.0;
    for (k, patch) in mesh.patches.iter().enumerate() {
        let shooter = PatchId(k as u32);
        // Item buffers, pixel for pixel.
        let angle = hemicube::shot_angle(&ctx, shooter);
        let ids = hemicube::element_ids(&ctx, shooter);
        let mut cube = Hemicube::new(&table, patch.centroid, patch.normal, angle, ctx.epsilon);
        for (id, e) in ids.iter().zip(&mesh.elements) {
            if *id != hemicube::SKIP {
                cube.draw(e.corners(), *id);
            }
        }
        let cpu_ids = cube.item_buffer();
        let view = HemicubeView {
            origin: patch.centroid,
            axes: hemicube::hemicube_axes(patch.normal, angle),
            near: ctx.epsilon,
        };
        let polygons = || mesh.elements.iter().map(|e| e.corners().to_vec()).collect();
        let gpu_ids = gpu
            .item_buffer(mesh.id, &polygons, &view, table.res() as u32, &ids)
            .expect("gpu item buffer");
        assert_eq!(gpu_ids.len(), cpu_ids.len());
        pixels += cpu_ids.len();
        differing += cpu_ids.iter().zip(&gpu_ids).filter(|(a, b)| a != b).count();
        // Per-element form factors.
        let cpu = hemicube::element_values(&ctx, shooter, &table, &never).expect("cpu");
        let on_gpu = hemicube::raster_element_values(&ctx, &gpu, shooter, &table).expect("gpu");
        let total: f64 = cpu.iter().sum();
        let diff: f64 = cpu.iter().zip(&on_gpu).map(|(a, b)| (a - b).abs()).sum();
        worst_row = worst_row.max(diff / total.max(1e-12));
        for (a, b) in cpu.iter().zip(&on_gpu) {
            if *a > 0.0 || *b > 0.0 {
                elements += 1;
                identical += usize::from(a == b);
            }
        }
    }
    let pixel_share = differing as f64 / pixels as f64;
    let identical_share = identical as f64 / elements as f64;
    eprintln!(
        "{} patches: {differing} of {pixels} pixels differ ({pixel_share:.2e}); \
         {identical} of {elements} element form factors bit-identical ({identical_share:.4}); \
         worst row Σ|ΔF|/ΣF {worst_row:.2e}",
        mesh.patches.len()
    );
    assert!(pixel_share < 2e-3, "{pixel_share}");
    assert!(identical_share > 0.9, "{identical_share}");
    assert!(worst_row < 1e-2, "{worst_row}");
}

/// A blocker half-way: both rasterisers see the same square through the same hole.
#[test]
fn gpu_honours_occluders_like_the_cpu() {
    let Some(gpu) = gpu() else { return };
    let table = DeltaTable::new(256);
    let square = vec![
        DVec3::new(-1.0, -1.0, 1.0),
        DVec3::new(-1.0, 1.0, 1.0),
        DVec3::new(1.0, 1.0, 1.0),
        DVec3::new(1.0, -1.0, 1.0),
    ];
    let blocker = vec![
        DVec3::new(-2.0, -2.0, 0.5),
        DVec3::new(0.0, -2.0, 0.5),
        DVec3::new(0.0, 2.0, 0.5),
        DVec3::new(-2.0, 2.0, 0.5),
    ];
    let (origin, normal) = (DVec3::new(0.1, 0.2, 0.0), DVec3::Z);
    let angle = 0.7;
    let mut cube = Hemicube::new(&table, origin, normal, angle, 1e-9);
    cube.draw(&square, 0);
    cube.draw(&blocker, NONE);
    let cpu = cube.form_factor(0);
    let view = HemicubeView {
        origin,
        axes: hemicube::hemicube_axes(normal, angle),
        near: 1e-9,
    };
    let polygons = || vec![square.clone(), blocker.clone()];
    let on_gpu = gpu
        .form_factors(7, &polygons, &view, &table, &[0, NONE], 1)
        .expect("gpu")[0];
    eprintln!("cpu {cpu:.9} gpu {on_gpu:.9}");
    assert!(cpu > 0.1 && cpu < 0.5, "{cpu}");
    assert!((cpu - on_gpu).abs() <= 1e-3 * cpu, "{cpu} vs {on_gpu}");
    // Without the blocker the square is seen whole; the GPU keeps up with the change of key.
    let alone = || vec![square.clone()];
    let whole = gpu
        .form_factors(8, &alone, &view, &table, &[0], 1)
        .expect("gpu")[0];
    assert!(whole > 1.5 * on_gpu, "{whole} vs {on_gpu}");
}

/// `gpu-hemicube` through the solver converges to what the CPU hemicube converges to, and
/// the case-file evaluation agrees with the CPU hemicube on the reference catalogue.
#[test]
fn gpu_hemicube_solves_the_cornell_box_like_the_cpu_hemicube() {
    let Some(gpu) = gpu() else { return };
    let raster: Arc<dyn ItemBufferRaster> = Arc::new(gpu);
    let stop = StopCriteria {
        unshot: 1e-3,
        ..Default::default()
    };
    let never = AtomicBool::new(false);
    let mut cpu =
        ProgressiveSolver::new(cornell(), cornell_config(FormFactorMethod::Hemicube, None))
            .expect("cpu");
    cpu.run(&stop, &never, &mut |_| {});
    let mut on_gpu = ProgressiveSolver::new(
        cornell(),
        cornell_config(FormFactorMethod::GpuHemicube, Some(raster.clone())),
    )
    .expect("gpu");
    on_gpu.run(&stop, &never, &mut |_| {});
    let (a, b) = (cpu.radiosity(), on_gpu.radiosity());
    let num: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length_squared())
        .sum();
    let den: f64 = a.iter().map(|x| x.length_squared()).sum();
    let rel = (num / den).sqrt();
    eprintln!(
        "cpu {} shots, gpu {} shots, element RMS difference {rel:.2e}",
        cpu.shots(),
        on_gpu.shots()
    );
    assert!(rel < 2e-3, "{rel}");

    // Without a rasteriser the method is refused, not silently replaced.
    assert!(
        ProgressiveSolver::new(
            cornell(),
            cornell_config(FormFactorMethod::GpuHemicube, None)
        )
        .is_err()
    );

    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/formfactors.json");
    let params = FormFactorParams {
        hemicube_res: 128,
        ..Default::default()
    };
    for case in cases::load(&path).expect("cases") {
        if case.name.contains("disk") {
            continue; // 128-gons: slow on a software rasteriser, nothing new.
        }
        let c = cases::evaluate(&case, FormFactorMethod::Hemicube, &params);
        let g = cases::evaluate_with(
            &case,
            FormFactorMethod::GpuHemicube,
            &params,
            Some(&*raster),
        )
        .expect("gpu case");
        // One edge pixel differing in one of the 36 hemicubes per triangle of A1 moves the
        // mean by up to a pixel's delta form factor / 72.
        let pixel = (2.0 / 128.0f64).powi(2) / std::f64::consts::PI;
        let tol = 2e-3 * c.abs() + pixel / 72.0;
        eprintln!("{:32} cpu {c:.6e} gpu {g:.6e} (tol {tol:.1e})", case.name);
        assert!((c - g).abs() <= tol, "{}: {c} vs {g}", case.name);
    }
}
