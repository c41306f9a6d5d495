//! `nusselt bench --only specular`: the hybrid (radiosity + the specular eye pass,
//! `render::specular`) against the path tracer on the built-in `cornell-specular` (a mirror
//! tall block, a glass short block), both measured against a converged path-traced reference
//! (`benches/data/cornell_specular_256_ref.pfm`): image error (relative RMS over surface
//! pixels, as `render --reference`) and whole time to the image (mesh, form factors, solve
//! and render for the hybrid). The hybrid's error has a floor: caustics (light through the
//! glass and off the mirror onto diffuse surfaces) are not in the radiosity solution.

use std::io::Write;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use anyhow::{Context, Result};

use crate::render::{self, Image, RenderSettings};
use crate::scene::{LoadOptions, Scene};
use crate::solver::{Problem, SolverConfig, SolverKind, StopCriteria, run_solver};

/// Samples per pixel of the hybrid's renders (what `render` does by default).
const HYBRID_SPP: u32 = 16;

/// Writes `specular.csv` (method, setting, seconds, error) and a table on stdout.
pub fn specular(out: &Path, reference_path: &Path, seconds: f64) -> Result<()> {
    let reference = match Image::load_pfm(reference_path) {
        Ok(r) => r,
        Err(e) => {
            println!(
                "\nspecular: no reference ({e}); run from the repository root or pass --specular-reference"
            );
            return Ok(());
        }
    };
    let scene = Scene::builtin("cornell-specular", &LoadOptions::default())?;
    let camera = render::view::default_camera(&scene);
    let (width, height) = (reference.width, reference.height);
    let mask = render::error_mask(&scene, &camera, width, height);
    let settings = |spp: u32, seed: u64| RenderSettings {
        width,
        height,
        spp,
        camera,
        seed,
    };
    let mut rows: Vec<(String, String, f64, f64)> = Vec::new();

    // The hybrid: a shooting solve to a residual of 1e-4 (default mesh), then each pass.
    eprintln!("specular: radiosity solve…");
    let start = Instant::now();
    let mut solver =
        SolverKind::Shooting.build(Problem::new(scene.clone(), SolverConfig::default())?)?;
    let stop = StopCriteria {
        unshot: 1e-4,
        ..Default::default()
    };
    run_solver(
        solver.as_mut(),
        &stop,
        &AtomicBool::new(false),
        &mut |_, _| {},
    );
    let solved = start.elapsed().as_secs_f64();
    let radiance = solver.element_radiance(true);
    let problem = solver.problem();
    for pass in ["vertex", "direct", "gather"] {
        eprintln!("specular: hybrid, {pass} pass…");
        let start = Instant::now();
        let s = settings(HYBRID_SPP, 1);
        let image = match pass {
            "direct" => render::direct::render_solution(problem, &radiance, &s),
            "gather" => render::gather::render_solution(
                problem,
                &radiance,
                &s,
                render::gather::GATHER_RAYS_PER_PIXEL,
            ),
            _ => {
                let vertex = problem.mesh.vertex_values(&radiance);
                let bvh = render::display_bvh(&problem.scene, &problem.mesh);
                let view = render::SolutionView {
                    scene: &problem.scene,
                    mesh: &problem.mesh,
                    vertex_radiance: &vertex,
                    bvh: &bvh,
                };
                render::render_solution(&view, &s)
            }
        };
        let t = solved + start.elapsed().as_secs_f64();
        let e = render::relative_rms(&image, &reference, &mask)?;
        rows.push((
            format!("hybrid, {pass} pass"),
            format!("{HYBRID_SPP} spp, {} elements", problem.mesh.elements.len()),
            t,
            e,
        ));
    }

    // The path tracer at doubling sample counts, until a render takes `seconds`.
    let mut spp = 4;
    loop {
        eprintln!("specular: path tracer {spp} spp…");
        let start = Instant::now();
        let image = render::pathtrace::reference(&scene, &settings(spp, 7), &|_| {});
        let t = start.elapsed().as_secs_f64();
        let e = render::relative_rms(&image, &reference, &mask)?;
        rows.push(("path tracer".into(), format!("{spp} spp"), t, e));
        if t > seconds || spp >= 1 << 14 {
            break;
        }
        spp *= 4;
    }

    let path = out.join("specular.csv");
    let mut w = std::io::BufWriter::new(
        std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?,
    );
    writeln!(w, "method,setting,seconds,relative_rms")?;
    println!(
        "\ncornell-specular, {width}×{height}, against {}",
        reference_path.display()
    );
    println!(
        "{:<24} {:<28} {:>9} {:>10}",
        "method", "setting", "seconds", "error"
    );
    for (method, setting, t, e) in &rows {
        writeln!(w, "{method},{setting},{t:.3},{e:.5}")?;
        println!("{method:<24} {setting:<28} {t:>9.2} {:>9.2} %", e * 100.0);
    }
    w.flush()?;
    eprintln!("wrote {}", path.display());
    Ok(())
}
