//! The image side of `nusselt bench`: image error (relative RMS over surface pixels, the
//! measure of `render --reference`) against wall-clock time.
//!
//! - `tworooms`: the display correction mid-solve, in the unlit room of two rooms joined by
//!   a gap: no ambient term, the classic global one, the regional one, and Gauss-Seidel
//!   (which shows only what it has gathered), against the same mesh converged.
//! - `cornell-image`: the Cornell box against the independent path-traced reference
//!   (`benches/data/cornell_256_ref.pfm`): each solver over time; shooting at element
//!   budgets from 1,250 to 40,000, each rendered by interpolation and by the direct pass
//!   (`render --pass direct`, whole time to the image); each form-factor method at 5,000
//!   elements; and the project's path tracer at doubling sample counts, to compare times to
//!   the same error.
//!
//! Clocks exclude the benchmark's own renders of intermediate solutions (a solve does not
//! render); they include meshing and form factors.

use std::io::Write;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use anyhow::{Context, Result};

use crate::formfactor::FormFactorMethod;
use crate::render::{self, Image, RenderSettings, SolutionView};
use crate::scene::{LoadOptions, Rgb, Scene};
use crate::solver::{
    Problem, ProgressiveSolver, SolverConfig, SolverKind, StopCriteria, run_solver,
};

use super::plot::{self, Plot, Series};

/// Renders per-element radiance of `problem` at the scene's camera, 256², `spp` samples per
/// pixel (16 against the path-traced reference: what `render` does, so edges are filtered
/// alike; 4 against a render of the same mesh, whose edges are filtered the same way).
fn render_elements(
    problem: &Problem,
    radiance: &[Rgb],
    bvh: &crate::geometry::Bvh,
    spp: u32,
) -> Image {
    let vertex = problem.mesh.vertex_values(radiance);
    let view = SolutionView {
        scene: &problem.scene,
        mesh: &problem.mesh,
        vertex_radiance: &vertex,
        bvh,
    };
    let settings = RenderSettings {
        width: 256,
        height: 256,
        spp,
        camera: render::view::default_camera(&problem.scene),
        seed: 1,
    };
    render::render_solution(&view, &settings)
}

/// Image errors of a run at log-spaced steps: `(solve seconds, error)` per label.
struct Recorder<'a> {
    reference: &'a Image,
    mask: &'a [bool],
    /// Time spent rendering, subtracted from the run's clock.
    paused: f64,
    next: usize,
}

impl Recorder<'_> {
    fn due(&mut self, step: usize) -> bool {
        if step >= self.next {
            self.next = (self.next * 3 / 2).max(self.next + 1);
            true
        } else {
            false
        }
    }

    fn error(&self, image: &Image) -> f64 {
        render::relative_rms(image, self.reference, self.mask).unwrap_or(f64::NAN)
    }
}

/// The display-correction benchmark on `tworooms`; writes `ambient.csv` and the plot.
pub fn ambient(out: &Path, seconds: f64) -> Result<()> {
    let scene = Scene::builtin("tworooms", &LoadOptions::default())?;
    eprintln!("tworooms: converged reference…");
    let mut reference_solver = ProgressiveSolver::new(scene.clone(), SolverConfig::default())?;
    let never = AtomicBool::new(false);
    let converge = StopCriteria {
        unshot: 1e-6,
        ..Default::default()
    };
    reference_solver.run(&converge, &never, &mut |_| {});
    let bvh = render::display_bvh(&scene, reference_solver.mesh());
    let reference = render_elements(
        reference_solver.problem(),
        reference_solver.radiosity(),
        &bvh,
        4,
    );
    let camera = render::view::default_camera(&scene);
    let mask = render::error_mask(&scene, &camera, 256, 256);
    let mut rows: Vec<(String, usize, f64, f64, f64)> = Vec::new();

    let start = Instant::now();
    let mut shooting = ProgressiveSolver::new(scene.clone(), SolverConfig::default())?;
    let setup = start.elapsed().as_secs_f64();
    let mut rec = Recorder {
        reference: &reference,
        mask: &mask,
        paused: 0.0,
        next: 1,
    };
    let stop = StopCriteria {
        unshot: 1e-4,
        max_seconds: Some(seconds),
        ..Default::default()
    };
    // Step by hand: `run`'s callback cannot borrow the solver to render it.
    let run_start = Instant::now();
    loop {
        let shots = shooting.shots();
        if rec.due(shots) || shooting.unshot_fraction() <= stop.unshot {
            let t0 = Instant::now();
            let t = setup + run_start.elapsed().as_secs_f64() - rec.paused;
            let unshot = shooting.unshot_fraction();
            let global = {
                let a = shooting.ambient();
                let rho = shooting.problem().element_reflectance();
                let shown: Vec<Rgb> = shooting
                    .radiosity()
                    .iter()
                    .zip(&rho)
                    .map(|(b, r)| (*b + *r * a).max(Rgb::ZERO))
                    .collect();
                rec.error(&render_elements(shooting.problem(), &shown, &bvh, 4))
            };
            let none = rec.error(&render_elements(
                shooting.problem(),
                &shooting.element_radiance(false),
                &bvh,
                4,
            ));
            let regional = rec.error(&render_elements(
                shooting.problem(),
                &shooting.element_radiance(true),
                &bvh,
                4,
            ));
            for (label, e) in [
                ("shooting, no ambient", none),
                ("shooting, global ambient", global),
                ("shooting, regional ambient", regional),
            ] {
                rows.push((label.into(), shots, t, unshot, e));
            }
            rec.paused += t0.elapsed().as_secs_f64();
        }
        if shooting.unshot_fraction() <= stop.unshot
            || run_start.elapsed().as_secs_f64() - rec.paused > seconds
            || shooting.shoot(&never).is_none()
        {
            break;
        }
    }

    // Gauss-Seidel on the same mesh: nothing but the light until its matrix is complete.
    let start = Instant::now();
    let mut gs =
        SolverKind::GaussSeidel.build(Problem::new(scene.clone(), SolverConfig::default())?)?;
    let setup = start.elapsed().as_secs_f64();
    let mut rec = Recorder {
        reference: &reference,
        mask: &mask,
        paused: 0.0,
        next: 1,
    };
    let gs_stop = StopCriteria {
        unshot: 1e-4,
        max_seconds: Some(seconds),
        ..Default::default()
    };
    let mut gs_rows = Vec::new();
    run_solver(gs.as_mut(), &gs_stop, &never, &mut |r, s| {
        if rec.due(r.step) || r.residual <= gs_stop.unshot {
            let t0 = Instant::now();
            let e = rec.error(&render_elements(
                s.problem(),
                &s.element_radiance(true),
                &bvh,
                4,
            ));
            gs_rows.push((
                "gauss-seidel".to_string(),
                r.step,
                setup + r.seconds - rec.paused,
                r.residual,
                e,
            ));
            rec.paused += t0.elapsed().as_secs_f64();
        }
    });
    rows.extend(gs_rows);

    let path = out.join("ambient.csv");
    let mut csv =
        std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?;
    writeln!(csv, "variant,step,seconds,residual,image_error")?;
    for (label, step, t, residual, e) in &rows {
        writeln!(csv, "{label},{step},{t:.5},{residual:.5e},{e:.5e}")?;
    }
    println!(
        "\n| tworooms (unlit room, {} elements) | after 1 s: residual | image error | after 2 s: image error | s to 10 % |",
        reference_solver.mesh().elements.len()
    );
    println!("|---|---:|---:|---:|---:|");
    let labels = [
        "shooting, no ambient",
        "shooting, global ambient",
        "shooting, regional ambient",
        "gauss-seidel",
    ];
    let mut series = Vec::new();
    for label in labels {
        let run: Vec<_> = rows.iter().filter(|r| r.0 == label).collect();
        let at = |limit: f64| run.iter().rev().find(|r| r.2 <= limit);
        let to_10 = first_time_below(run.iter().map(|r| (r.2, r.4)), 0.1);
        let fmt = |r: Option<&&(String, usize, f64, f64, f64)>, k: usize| {
            r.map(|r| format!("{:.3}", if k == 3 { r.3 } else { r.4 }))
                .unwrap_or("–".into())
        };
        println!(
            "| {label} | {} | {} | {} | {} |",
            fmt(at(1.0), 3),
            fmt(at(1.0), 4),
            fmt(at(2.0), 4),
            to_10.map(|t| format!("{t:.2}")).unwrap_or("–".into())
        );
        series.push(Series {
            label: label.into(),
            points: run.iter().map(|r| (r.2, r.4)).collect(),
            markers: false,
        });
    }
    plot::write(
        &out.join("ambient"),
        &Plot {
            title: "Two rooms, unlit one seen: image error from dark",
            x_label: "seconds (mesh, form factors, solve)",
            y_label: "relative RMS image error",
            series,
        },
    )?;
    Ok(())
}

/// The time from which the error stays at or below `limit`.
fn first_time_below(points: impl Iterator<Item = (f64, f64)>, limit: f64) -> Option<f64> {
    let mut at = None;
    for (t, e) in points {
        if e > limit {
            at = None;
        } else if at.is_none() {
            at = Some(t);
        }
    }
    at
}

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
            unshot: 1e-4,
            // The clock here includes the benchmark's renders (about 0.3 s each, at
            // log-spaced steps), which the recorded times leave out.
            max_seconds: Some(3.0 * seconds),
            ..Default::default()
        };
        let mut points = Vec::new();
        let elements = s.problem().mesh.elements.len();
        run_solver(s.as_mut(), &stop, &never, &mut |r, s| {
            if rec.due(r.step) || r.residual <= stop.unshot {
                let t0 = Instant::now();
                let e = rec.error(&render_elements(
                    s.problem(),
                    &s.element_radiance(true),
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
        let mut problem = Problem::new(scene.clone(), config)?;
        if let Some(tolerance) = adaptive {
            problem = crate::solver::refine::refine_adaptively(
                problem,
                SolverKind::Shooting,
                tolerance,
                2,
                1e-4,
            )?;
        }
        let mut s = ProgressiveSolver::from_problem(problem);
        let stop = StopCriteria {
            unshot: 1e-4,
            // The finest meshes need longer than one solver's share.
            max_seconds: Some(4.0 * seconds),
            ..Default::default()
        };
        s.run(&stop, &never, &mut |_| {});
        let solved = start.elapsed().as_secs_f64();
        let bvh = render::display_bvh(&scene, s.mesh());
        let e = render::relative_rms(
            &render_elements(s.problem(), &s.element_radiance(true), &bvh, 16),
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
        };
        let direct =
            render::direct::render_solution(s.problem(), &s.element_radiance(true), &settings);
        let e_direct = render::relative_rms(&direct, &reference, &mask)?;
        let t_direct = solved + t_direct.elapsed().as_secs_f64();
        let n = s.mesh().elements.len();
        rows.push((
            format!("{group}, direct pass"),
            label.clone(),
            n,
            s.shots(),
            t_direct,
            e_direct,
        ));
        rows.push((group.into(), label, n, s.shots(), t, e));
        Ok(((t, e), (t_direct, e_direct)))
    };
    let (mut density, mut density_direct) = (Vec::new(), Vec::new());
    for budget in [1_250, 2_500, 5_000, 10_000, 20_000, 40_000] {
        let config = SolverConfig {
            max_elements: Some(budget),
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
            max_elements: Some(budget),
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
            max_elements: Some(5_000),
            method,
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
        };
        let image = crate::render::pathtrace::reference(&scene, &settings, &|_| {});
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
    println!(
        "\n| Cornell box vs path-traced reference | elements | steps / spp | seconds | image error |"
    );
    println!("|---|---:|---:|---:|---:|");
    for (g, l, n, k, t, e) in &rows {
        let last_of_run = g != "solver"
            || rows
                .iter()
                .rfind(|r| r.0 == "solver" && r.1 == *l)
                .is_some_and(|r| r.3 == *k);
        if last_of_run {
            println!("| {g}: {l} | {n} | {k} | {t:.2} | {:.2} % |", e * 100.0);
        }
    }
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
