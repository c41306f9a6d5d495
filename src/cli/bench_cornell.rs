//! `nusselt bench --only cornell-image`: the Cornell box against the path-traced reference
//! (see `bench_images.rs` for the measure and the clocks).

use std::io::Write;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use anyhow::{Context, Result};

use nusselt_core::formfactor::FormFactorMethod;
use nusselt_core::mesh::MeshSpec;
use nusselt_core::render::{self, Image, RenderSettings};
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::{Problem, SolverConfig, SolverKind, StopCriteria, run_solver};

use super::bench_images::{Recorder, first_time_below, render_elements};
use super::plot::{self, Plot, Series};

/// The Cornell box against the path-traced reference; writes `cornell_image.csv` and plots.
pub fn cornell(out: &Path, reference_path: &Path, seconds: f64) -> Result<()> {
    let reference = match Image::load_pfm(reference_path) {
        Ok(r) => r,
        Err(e) => {
            println!(
                "\ncornell image: no reference ({e}); run from the repository root or pass --cornell-reference"
            );
            return Ok(());
        }
    };
    let scene = Scene::builtin("cornell", &LoadOptions::default())?;
    let camera = render::view::default_camera(&scene);
    let mask = render::error_mask(&scene, &camera, reference.width, reference.height);
    let never = AtomicBool::new(false);
    let mut rows: Vec<(String, String, usize, usize, f64, f64)> = Vec::new();

    // Each solver over time, default mesh.
    let mut curves = Vec::new();
    for (label, kind) in [
        ("shooting", SolverKind::Shooting),
        ("gauss-seidel", SolverKind::GaussSeidel),
        ("sor", SolverKind::Sor(None)),
        ("cg", SolverKind::Cg),
    ] {
        eprintln!("cornell image: {label}…");
        let start = Instant::now();
        let mut s = kind.build(Problem::new(scene.clone(), SolverConfig::default())?)?;
        let bvh = render::display_bvh(&scene, &s.problem().mesh);
        let setup = start.elapsed().as_secs_f64();
        let mut rec = Recorder {
            reference: &reference,
            mask: &mask,
            paused: 0.0,
            next: 16,
        };
        let stop = StopCriteria {
            residual: 1e-4,
            // The clock here includes the benchmark's renders (about 0.3 s each, at
            // log-spaced steps), which the recorded times leave out.
            max_seconds: Some(3.0 * seconds),
            ..Default::default()
        };
        let mut points = Vec::new();
        let elements = s.problem().mesh.elements.len();
        run_solver(s.as_mut(), &stop, &never, &mut |r, s| {
            if rec.due(r.step) || r.residual <= stop.residual {
                let t0 = Instant::now();
                let e = rec.error(&render_elements(
                    s.problem(),
                    &s.display_radiance(),
                    &bvh,
                    16,
                ));
                points.push((setup + r.seconds - rec.paused, e));
                rows.push((
                    "solver".into(),
                    label.into(),
                    elements,
                    r.step,
                    setup + r.seconds - rec.paused,
                    e,
                ));
                rec.paused += t0.elapsed().as_secs_f64();
            }
        });
        curves.push(Series {
            label: format!("{label} ({elements} elements)"),
            points,
            markers: false,
        });
    }

    // Whole runs to --unshot 1e-4: element budgets (contour rows), then form-factor methods.
    let mut run_to_end = |label: String,
                          config: SolverConfig,
                          adaptive: Option<f64>,
                          group: &str|
     -> Result<((f64, f64), (f64, f64))> {
        eprintln!("cornell image: {label}…");
        let start = Instant::now();
        let mut s = super::bench_images::meshed(&scene, config, adaptive)?;
        let stop = StopCriteria {
            residual: 1e-4,
            // The finest meshes need longer than one solver's share.
            max_seconds: Some(4.0 * seconds),
            ..Default::default()
        };
        run_solver(s.as_mut(), &stop, &never, &mut |_, _| {});
        let solved = start.elapsed().as_secs_f64();
        let bvh = render::display_bvh(&scene, &s.problem().mesh);
        let e = render::relative_rms(
            &render_elements(s.problem(), &s.display_radiance(), &bvh, 16),
            &reference,
            &mask,
        )?;
        // Whole time to each image: start, mesh, solve, render.
        let t = start.elapsed().as_secs_f64();
        let t_direct = Instant::now();
        let settings = RenderSettings {
            width: 256,
            height: 256,
            spp: 16,
            camera,
            seed: 1,
            edge_spp: nusselt_core::render::DEFAULT_EDGE_SPP,
        };
        let direct = render::direct::render_solution(s.problem(), &s.display_radiance(), &settings);
        let e_direct = render::relative_rms(&direct, &reference, &mask)?;
        let t_direct = solved + t_direct.elapsed().as_secs_f64();
        let n = s.problem().mesh.elements.len();
        rows.push((
            format!("{group}, direct pass"),
            label.clone(),
            n,
            s.steps(),
            t_direct,
            e_direct,
        ));
        rows.push((group.into(), label, n, s.steps(), t, e));
        Ok(((t, e), (t_direct, e_direct)))
    };
    let (mut density, mut density_direct) = (Vec::new(), Vec::new());
    for budget in [1_250, 2_500, 5_000, 10_000, 20_000, 40_000] {
        let config = SolverConfig {
            mesh: MeshSpec {
                max_elements: Some(budget),
                ..Default::default()
            },
            ..Default::default()
        };
        let (vertex, direct) = run_to_end(format!("budget {budget}"), config, None, "density")?;
        density.push(vertex);
        density_direct.push(direct);
    }
    // Adaptive meshing from coarse starts (render --adaptive TOL: two refinement passes).
    for (budget, tolerance) in [
        (1_250, 0.1),
        (2_500, 0.1),
        (5_000, 0.1),
        (2_500, 0.05),
        (5_000, 0.05),
    ] {
        let config = SolverConfig {
            mesh: MeshSpec {
                max_elements: Some(budget),
                ..Default::default()
            },
            ..Default::default()
        };
        run_to_end(
            format!("budget {budget}, --adaptive {tolerance}"),
            config,
            Some(tolerance),
            "adaptive",
        )?;
    }
    let mut methods = Vec::new();
    for method in [
        FormFactorMethod::Contour,
        FormFactorMethod::Exact,
        FormFactorMethod::Hemicube,
        FormFactorMethod::Hybrid,
        FormFactorMethod::Raycast,
        FormFactorMethod::Montecarlo,
    ] {
        let config = SolverConfig {
            mesh: MeshSpec {
                max_elements: Some(5_000),
                ..Default::default()
            },
            formfactor: nusselt_core::solver::FormFactorConfig {
                method,
                ..Default::default()
            },
            ..Default::default()
        };
        let (point, _) = run_to_end(format!("{method}"), config, None, "method")?;
        methods.push(Series {
            label: format!("{method}, 5,000 elements"),
            points: vec![point],
            markers: true,
        });
    }

    // The path tracer at doubling sample counts, until a render takes 2 × `seconds`.
    let mut traced = Vec::new();
    let mut spp = 1;
    loop {
        eprintln!("cornell image: path tracer {spp} spp…");
        let start = Instant::now();
        let settings = RenderSettings {
            width: reference.width,
            height: reference.height,
            spp,
            camera,
            seed: 7,
            edge_spp: 0,
        };
        let image = nusselt_core::render::pathtrace::reference(&scene, &settings, &|_| {});
        let t = start.elapsed().as_secs_f64();
        let e = render::relative_rms(&image, &reference, &mask)?;
        rows.push((
            "pathtracer".into(),
            format!("{spp} spp"),
            0,
            spp as usize,
            t,
            e,
        ));
        traced.push((t, e));
        if t > seconds || spp >= 1 << 16 {
            break;
        }
        spp *= 2;
    }

    let path = out.join("cornell_image.csv");
    let mut csv =
        std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?;
    writeln!(csv, "group,label,elements,steps,seconds,image_error")?;
    for (g, l, n, k, t, e) in &rows {
        writeln!(csv, "{g},{l},{n},{k},{t:.4},{e:.5e}")?;
    }
    print!("\n{}", super::bench_doc::cornell_end_points(&rows));
    // Beyond the last measured count the path tracer's error falls as 1/√spp, so its time
    // to an error e is t_last · (e_last / e)² (labelled as extrapolated).
    let last = traced.last().copied();
    println!();
    for limit in [0.05, 0.02, 0.015, 0.01] {
        let pt = match first_time_below(traced.iter().copied(), limit) {
            Some(t) => format!("{t:.2} s"),
            None => last
                .map(|(t, e)| format!("{:.0} s (extrapolated)", t * (e / limit).powi(2)))
                .unwrap_or("–".into()),
        };
        let rad = curves
            .first()
            .and_then(|c| first_time_below(c.points.iter().copied(), limit));
        println!(
            "- time to {:.1} %: radiosity (shooting, default mesh) {}; path tracer {pt}",
            limit * 100.0,
            rad.map(|t| format!("{t:.2} s"))
                .unwrap_or("not reached".into()),
        );
    }
    curves.push(Series {
        label: "path tracer (doubling spp)".into(),
        points: traced,
        markers: false,
    });
    curves.push(Series {
        label: "shooting, element budgets 1,250-40,000".into(),
        points: density,
        markers: true,
    });
    curves.push(Series {
        label: "shooting + direct pass (render --pass direct), same budgets".into(),
        points: density_direct,
        markers: true,
    });
    curves.extend(methods);
    let by_elements = |group: &str| -> Vec<(f64, f64)> {
        rows.iter()
            .filter(|r| r.0 == group)
            .map(|r| (r.2 as f64, r.5))
            .collect()
    };
    plot::write(
        &out.join("cornell_elements"),
        &Plot {
            title: "Cornell box: image error against element count",
            x_label: "elements",
            y_label: "relative RMS image error",
            series: vec![
                Series {
                    label: "uniform".into(),
                    points: by_elements("density"),
                    markers: false,
                },
                Series {
                    label: "uniform + direct pass".into(),
                    points: by_elements("density, direct pass"),
                    markers: false,
                },
                Series {
                    label: "adaptive (--adaptive 0.1 / 0.05)".into(),
                    points: by_elements("adaptive"),
                    markers: true,
                },
                Series {
                    label: "adaptive + direct pass".into(),
                    points: by_elements("adaptive, direct pass"),
                    markers: true,
                },
            ],
        },
    )?;
    plot::write(
        &out.join("cornell_image"),
        &Plot {
            title: "Cornell box: image error against the path-traced reference",
            x_label: "seconds",
            y_label: "relative RMS image error",
            series: curves,
        },
    )?;
    Ok(())
}
