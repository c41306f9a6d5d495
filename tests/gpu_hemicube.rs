//! The GPU hemicube (wgpu; lavapipe on machines without a GPU) against the CPU hemicube.
//!
//! Without an adapter these tests print why and skip, except in CI (`common::in_ci`), where
//! `.ci/run` installs lavapipe and a missing adapter is a failure.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use glam::DVec3;
use nusselt_core::cases;
use nusselt_core::formfactor::hemicube::{
    self, DeltaTable, Hemicube, HemicubeView, ItemBufferRaster, NONE,
};
use nusselt_core::formfactor::{FormFactorMethod, FormFactorParams};
use nusselt_core::mesh::{MeshSpec, PatchId};
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::{ProgressiveSolver, SolverConfig, StopCriteria};
use nusselt_gpu::GpuHemicube;

mod common;

fn gpu() -> Option<GpuHemicube> {
    common::gpu_hemicube()
}

/// The one rule for `CI` (tests/common): any value but empty, `false` or `0`.
#[test]
fn ci_is_any_value_but_empty_false_or_0() {
    for (v, ci) in [
        (None, false),
        (Some(""), false),
        (Some("false"), false),
        (Some("FALSE"), false),
        (Some("0"), false),
        (Some("true"), true),
        (Some("1"), true),
        (Some("yes"), true),
    ] {
        assert_eq!(common::ci_value(v), ci, "CI={v:?}");
    }
}

fn cornell_config(
    method: FormFactorMethod,
    raster: Option<Arc<dyn ItemBufferRaster>>,
) -> SolverConfig {
    SolverConfig {
        mesh: MeshSpec::sized(40.0, 80.0),
        formfactor: nusselt_core::solver::FormFactorConfig {
            method,
            params: FormFactorParams {
                hemicube_res: 128,
                ..Default::default()
            },
            raster,
        },
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
    let params = solver.config().formfactor.params.clone();
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
    // The exact values (Lambert on the seen part), and the hemicube's pixel bound for them.
    let exact = nusselt_core::formfactor::exact::point_to_visible_polygon(
        origin,
        normal,
        &square,
        std::slice::from_ref(&blocker),
    );
    let unblocked = nusselt_core::formfactor::contour::point_to_polygon(origin, normal, &square);
    let bound = common::hemicube_bound(256, origin, &[&square, &blocker]);
    eprintln!(
        "cpu {cpu:.9} gpu {on_gpu:.9} exact {exact:.9} (bound {bound:.1e}), unblocked {unblocked:.9}"
    );
    // The blocker hides more than the bound can blur, and the CPU hemicube sees that.
    assert!(unblocked - exact > 2.0 * bound, "{unblocked} vs {exact}");
    assert!((cpu - exact).abs() <= bound, "{cpu} vs exact {exact}");
    assert!((cpu - on_gpu).abs() <= 1e-3 * cpu, "{cpu} vs {on_gpu}");
    // Without the blocker the square is seen whole; the GPU keeps up with the change of key.
    let alone = || vec![square.clone()];
    let whole = gpu
        .form_factors(8, &alone, &view, &table, &[0], 1)
        .expect("gpu")[0];
    let bound = common::hemicube_bound(256, origin, &[&square]);
    assert!(
        (whole - unblocked).abs() <= bound,
        "{whole} vs exact {unblocked}"
    );
}

/// `gpu-hemicube` through the solver converges to what the CPU hemicube converges to, and
/// the case-file evaluation agrees with the CPU hemicube on the reference catalogue.
#[test]
fn gpu_hemicube_solves_the_cornell_box_like_the_cpu_hemicube() {
    let Some(gpu) = gpu() else { return };
    let raster: Arc<dyn ItemBufferRaster> = Arc::new(gpu);
    let stop = StopCriteria {
        residual: 1e-3,
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

/// OpenGL (here Mesa's llvmpipe through EGL, which `.ci/run` installs) is refused with a
/// message that says why, instead of rasterising empty item buffers: on it
/// `gpu_honours_occluders_like_the_cpu` read 0 for 0.338 (most likely its `2z − 1` depth
/// remap rounds the depths `near/D` to the cleared 0).
/// Run as a child process with `WGPU_BACKEND=gl`; without any OpenGL adapter the refusal is
/// "no GPU adapter", which only counts outside CI.
#[test]
fn opengl_is_refused_with_the_reason() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_nusselt"))
        .args([
            "render",
            "--builtin",
            "cornell",
            "--formfactor",
            "gpu-hemicube",
            "--shots",
            "1",
            "--width",
            "8",
            "--height",
            "8",
            "--out",
        ])
        .arg(std::env::temp_dir().join("nusselt_opengl_refused.pfm"))
        .env("WGPU_BACKEND", "gl")
        .output()
        .expect("run nusselt");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "rendered on OpenGL: {stderr}");
    if stderr.contains("no GPU adapter") && !common::in_ci() {
        eprintln!("skipped: no OpenGL adapter on this machine ({stderr})");
        return;
    }
    assert!(
        stderr.contains("OpenGL") && stderr.contains("Vulkan"),
        "{stderr}"
    );
}
