//! `nusselt bench --only specular`: the hybrid (radiosity + the specular eye pass,
//! `render::specular`) against the path tracer on the built-in `cornell-specular` (a mirror
//! tall block, a glass short block), both measured against a converged path-traced reference
//! (`benches/data/cornell_specular_256_ref.pfm`): image error (relative RMS over surface
//! pixels, as `render --reference`) and whole time to the image (mesh, form factors, solve
//! and render for the hybrid). The hybrid's error has a floor: caustics (light through the
//! glass and off the mirror onto diffuse surfaces) are not in the radiosity solution. So its
//! error is also measured against the path tracer without caustics
//! ([`PathTracer::without_caustics`], the hybrid's own light transport; two renders of
//! [`NO_CAUSTICS_SPP`] with different seeds, averaged, their difference giving its noise):
//! what is left there is the pass's own error. The same hybrid rows for `cornell-glossy` (the
//! tall block a glossy metal), against its caustic-free path tracer only.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use anyhow::Result;

use nusselt_core::render::pathtrace::PathTracer;
use nusselt_core::render::{self, Image, RenderSettings};
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::{Problem, SolverConfig, SolverKind, solve_to};

/// Samples per pixel of the hybrid's renders (what `render` does by default).
const HYBRID_SPP: u32 = 16;
/// Paths per pixel of each of the two caustic-free references.
const NO_CAUSTICS_SPP: u32 = 512;

/// One row of the table: method, setting, seconds, error against the path-traced reference
/// (none for a scene without one), error against the caustic-free path tracer.
type Row = (String, String, f64, Option<f64>, Option<f64>);

/// Writes `specular.csv` (method, setting, seconds, errors) and a table on stdout.
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
        edge_spp: 0,
    };
    let (mut rows, noise) = hybrid_rows(&scene, "", &settings, &mask, Some(&reference))?;

    // The path tracer at doubling sample counts, until a render takes `seconds`.
    let mut spp = 4;
    loop {
        eprintln!("specular: path tracer {spp} spp…");
        let start = Instant::now();
        let image = render::pathtrace::reference(&scene, &settings(spp, 7), &|_| {});
        let t = start.elapsed().as_secs_f64();
        let e = render::relative_rms(&image, &reference, &mask)?;
        rows.push(("path tracer".into(), format!("{spp} spp"), t, Some(e), None));
        if t > seconds || spp >= 1 << 14 {
            break;
        }
        spp *= 4;
    }
    // The glossy variant: no converged path-traced reference with caustics was made for it
    // (cornell-specular's took 8,192 spp); the hybrid against its own transport only.
    let glossy = Scene::builtin("cornell-glossy", &LoadOptions::default())?;
    let (glossy_rows, glossy_noise) = hybrid_rows(&glossy, "glossy: ", &settings, &mask, None)?;
    rows.extend(glossy_rows);

    let path = out.join("specular.csv");
    let mut w = std::io::BufWriter::new(super::bench::csv_file(
        &path,
        "method,setting,seconds,relative_rms,relative_rms_without_caustics",
    )?);
    println!(
        "\ncornell-specular, {width}×{height}, against {} (error) and the path tracer without \
         caustics, 2 × {NO_CAUSTICS_SPP} spp, noise {:.2} % (own error)",
        reference_path.display(),
        noise * 100.0
    );
    println!(
        "(cornell-glossy: the tall block a glossy metal, Ns 60; its caustic-free reference's \
         noise {:.2} %)",
        glossy_noise * 100.0
    );
    println!(
        "{:<32} {:<28} {:>9} {:>10} {:>10}",
        "method", "setting", "seconds", "error", "own error"
    );
    for (method, setting, t, e, own) in &rows {
        let csv = |x: &Option<f64>| x.map(|x| format!("{x:.5}")).unwrap_or_default();
        writeln!(w, "{method},{setting},{t:.3},{},{}", csv(e), csv(own))?;
        let pct = |x: &Option<f64>| {
            x.map(|x| format!("{:.2} %", x * 100.0))
                .unwrap_or("–".into())
        };
        println!(
            "{method:<32} {setting:<28} {t:>9.2} {:>10} {:>10}",
            pct(e),
            pct(own)
        );
    }
    w.flush()?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

/// The hybrid on `scene`: a caustic-free path-traced reference (two renders of
/// [`NO_CAUSTICS_SPP`], averaged; their difference gives its noise), a shooting solve to a
/// residual of 1e-4 at the default mesh, then each pass, timed (solve included) and judged
/// against `reference` (if any) and the caustic-free one. Returns the rows and that noise.
fn hybrid_rows(
    scene: &Scene,
    label: &str,
    settings: &dyn Fn(u32, u64) -> RenderSettings,
    mask: &[bool],
    reference: Option<&Image>,
) -> Result<(Vec<Row>, f64)> {
    let name = &scene.name;
    eprintln!("specular: {name}: caustic-free reference, 2 × {NO_CAUSTICS_SPP} spp…");
    let tracer = PathTracer::new(scene).without_caustics();
    let a = tracer.render(&settings(NO_CAUSTICS_SPP, 11), &|_| {});
    let b = tracer.render(&settings(NO_CAUSTICS_SPP, 12), &|_| {});
    let mut no_caustics = a.clone();
    for (p, q) in no_caustics.pixels.iter_mut().zip(&b.pixels) {
        *p = (*p + *q) * 0.5;
    }
    // Each half is σ from the truth, their mean σ/√2; |a − b| is σ√2.
    let noise = render::relative_rms(&a, &b, mask)? / 2.0;

    eprintln!("specular: {name}: radiosity solve…");
    let start = Instant::now();
    let mut solver =
        SolverKind::Shooting.build(Problem::new(scene.clone(), SolverConfig::default())?)?;
    solve_to(solver.as_mut(), 1e-4);
    let solved = start.elapsed().as_secs_f64();
    let radiance = solver.display_radiance();
    let problem = solver.problem();
    let mut rows = Vec::new();
    for pass in render::Pass::ALL {
        eprintln!("specular: {name}: hybrid, {} pass…", pass.name());
        let start = Instant::now();
        let image = pass.render(
            problem,
            &radiance,
            &settings(HYBRID_SPP, 1),
            render::gather::GATHER_RAYS_PER_PIXEL,
        );
        let t = solved + start.elapsed().as_secs_f64();
        let e = match reference {
            Some(r) => Some(render::relative_rms(&image, r, mask)?),
            None => None,
        };
        let own = render::relative_rms(&image, &no_caustics, mask)?;
        rows.push((
            format!("{label}hybrid, {} pass", pass.name()),
            format!("{HYBRID_SPP} spp, {} elements", problem.mesh.elements.len()),
            t,
            e,
            Some(own),
        ));
    }
    Ok((rows, noise))
}
