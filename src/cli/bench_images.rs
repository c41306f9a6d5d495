//! The image side of `nusselt bench`: image error (relative RMS over surface pixels, the
//! measure of `render --reference`) against wall-clock time.
//!
//! - `tworooms`: the display correction mid-solve, in the unlit room of two rooms joined by
//!   a gap: no ambient term, the classic global one, the regional one, and Gauss-Seidel
//!   (which shows only what it has gathered), against the same mesh converged.
//! - `cornell-image` (`bench_cornell.rs`): the Cornell box against the independent path-traced reference
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

use anyhow::Result;

use nusselt_core::render::{self, Image, RenderSettings, SolutionView};
use nusselt_core::scene::{LoadOptions, Rgb, Scene};
use nusselt_core::solver::{
    Problem, ProgressiveSolver, Solver, SolverConfig, SolverKind, StopCriteria, run_solver,
};

use super::plot::{self, Plot, Series};

/// Renders per-element radiance of `problem` at the scene's camera, 256², `spp` samples per
/// pixel (16 against the path-traced reference: what `render` does, so edges are filtered
/// alike; 4 against a render of the same mesh, whose edges are filtered the same way).
pub(super) fn render_elements(
    problem: &Problem,
    radiance: &[Rgb],
    bvh: &nusselt_core::geometry::Bvh,
    spp: u32,
) -> Image {
    let vertex = problem.mesh.vertex_values(radiance);
    let view = SolutionView {
        scene: &problem.scene,
        mesh: &problem.mesh,
        vertex_radiance: &vertex,
        bvh,
        texture: &[],
    };
    let settings = RenderSettings {
        width: 256,
        height: 256,
        spp,
        camera: render::view::default_camera(&problem.scene),
        seed: 1,
        edge_spp: nusselt_core::render::DEFAULT_EDGE_SPP,
    };
    render::render_solution(&view, &settings)
}

/// Image errors of a run at log-spaced steps: `(solve seconds, error)` per label.
pub(super) struct Recorder<'a> {
    pub reference: &'a Image,
    pub mask: &'a [bool],
    /// Time spent rendering, subtracted from the run's clock.
    pub paused: f64,
    pub next: usize,
}

impl Recorder<'_> {
    pub fn due(&mut self, step: usize) -> bool {
        if step >= self.next {
            self.next = (self.next * 3 / 2).max(self.next + 1);
            true
        } else {
            false
        }
    }

    pub fn error(&self, image: &Image) -> f64 {
        render::relative_rms(image, self.reference, self.mask).unwrap_or(f64::NAN)
    }
}

/// The Cornell benchmarks' solver: `scene` meshed by `config`, then refined adaptively
/// (`render --adaptive TOL`: two passes, each solved to 1e-3, the solution carried onto the
/// refined mesh) when `adaptive` is given.
pub fn meshed(
    scene: &Scene,
    config: SolverConfig,
    adaptive: Option<f64>,
) -> Result<Box<dyn Solver>> {
    let problem = Problem::new(scene.clone(), config)?;
    Ok(match adaptive {
        Some(tolerance) => {
            nusselt_core::solver::refine::refine_adaptively(
                problem,
                SolverKind::Shooting.into(),
                tolerance,
                2,
                1e-4,
                &std::sync::atomic::AtomicBool::new(false),
            )?
            .solver
        }
        None => SolverKind::Shooting.build(problem)?,
    })
}

/// One row of `ambient.csv`: variant, step, seconds, residual, image error.
type AmbientRow = (String, usize, f64, f64, f64);

/// What the display-correction runs are judged against: the same mesh converged.
struct Converged<'a> {
    bvh: &'a nusselt_core::geometry::Bvh,
    reference: &'a Image,
    mask: &'a [bool],
    seconds: f64,
}

/// The display-correction benchmark on `tworooms`; writes `ambient.csv` and the plot.
pub fn ambient(out: &Path, seconds: f64) -> Result<()> {
    let scene = Scene::builtin("tworooms", &LoadOptions::default())?;
    eprintln!("tworooms: converged reference…");
    let mut reference_solver = ProgressiveSolver::new(scene.clone(), SolverConfig::default())?;
    let converge = StopCriteria {
        residual: 1e-6,
        ..Default::default()
    };
    reference_solver.run(&converge, &AtomicBool::new(false), &mut |_| {});
    let bvh = render::display_bvh(&scene, reference_solver.mesh());
    let reference = render_elements(
        reference_solver.problem(),
        reference_solver.radiosity(),
        &bvh,
        4,
    );
    let camera = render::view::default_camera(&scene);
    let mask = render::error_mask(&scene, &camera, 256, 256);
    let converged = Converged {
        bvh: &bvh,
        reference: &reference,
        mask: &mask,
        seconds,
    };
    let mut rows = shooting_rows(&scene, &converged)?;
    rows.extend(gauss_seidel_rows(&scene, &converged)?);
    write_ambient_csv(out, &rows)?;
    let elements = reference_solver.mesh().elements.len();
    let series = print_ambient_table(&rows, elements);
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

/// Shooting from dark, stepped by hand, the image error of each display correction (none,
/// global, regional) at log-spaced shot counts and at the end.
fn shooting_rows(scene: &Scene, converged: &Converged) -> Result<Vec<AmbientRow>> {
    let never = AtomicBool::new(false);
    let mut rows = Vec::new();
    let start = Instant::now();
    let mut shooting = ProgressiveSolver::new(scene.clone(), SolverConfig::default())?;
    let setup = start.elapsed().as_secs_f64();
    let mut rec = Recorder {
        reference: converged.reference,
        mask: converged.mask,
        paused: 0.0,
        next: 1,
    };
    let stop = StopCriteria {
        residual: 1e-4,
        max_seconds: Some(converged.seconds),
        ..Default::default()
    };
    let bvh = converged.bvh;
    // Step by hand: `run`'s callback cannot borrow the solver to render it.
    let run_start = Instant::now();
    loop {
        let shots = shooting.shots();
        if rec.due(shots) || shooting.unshot_fraction() <= stop.residual {
            let t0 = Instant::now();
            let t = setup + run_start.elapsed().as_secs_f64() - rec.paused;
            let unshot = shooting.unshot_fraction();
            let global = rec.error(&render_elements(
                shooting.problem(),
                &shooting.element_radiance_global_ambient(),
                bvh,
                4,
            ));
            let none = rec.error(&render_elements(
                shooting.problem(),
                shooting.radiosity(),
                bvh,
                4,
            ));
            let regional = rec.error(&render_elements(
                shooting.problem(),
                &shooting.display_radiance(),
                bvh,
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
        if shooting.unshot_fraction() <= stop.residual
            || run_start.elapsed().as_secs_f64() - rec.paused > converged.seconds
            || shooting.shoot(&never).is_none()
        {
            break;
        }
    }
    Ok(rows)
}

/// Gauss-Seidel on the same mesh: nothing but the light until its matrix is complete.
fn gauss_seidel_rows(scene: &Scene, converged: &Converged) -> Result<Vec<AmbientRow>> {
    let start = Instant::now();
    let mut gs =
        SolverKind::GaussSeidel.build(Problem::new(scene.clone(), SolverConfig::default())?)?;
    let setup = start.elapsed().as_secs_f64();
    let mut rec = Recorder {
        reference: converged.reference,
        mask: converged.mask,
        paused: 0.0,
        next: 1,
    };
    let gs_stop = StopCriteria {
        residual: 1e-4,
        max_seconds: Some(converged.seconds),
        ..Default::default()
    };
    let mut gs_rows = Vec::new();
    run_solver(
        gs.as_mut(),
        &gs_stop,
        &AtomicBool::new(false),
        &mut |r, s| {
            if rec.due(r.step) || r.residual <= gs_stop.residual {
                let t0 = Instant::now();
                let e = rec.error(&render_elements(
                    s.problem(),
                    &s.display_radiance(),
                    converged.bvh,
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
        },
    );
    Ok(gs_rows)
}

fn write_ambient_csv(out: &Path, rows: &[AmbientRow]) -> Result<()> {
    let path = out.join("ambient.csv");
    let mut csv = super::bench::csv_file(&path, "variant,step,seconds,residual,image_error")?;
    for (label, step, t, residual, e) in rows {
        writeln!(csv, "{label},{step},{t:.5},{residual:.5e},{e:.5e}")?;
    }
    Ok(())
}

/// The table on stdout (residual and error after 1 s and 2 s, time to 10 %), and the plot's
/// curve of each variant.
fn print_ambient_table(rows: &[AmbientRow], elements: usize) -> Vec<Series> {
    println!(
        "\n| tworooms (unlit room, {elements} elements) | after 1 s: residual | image error | after 2 s: image error | s to 10 % |"
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
        let fmt = |r: Option<&&AmbientRow>, k: usize| {
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
    series
}

/// The time from which the error stays at or below `limit`.
pub(super) fn first_time_below(
    points: impl Iterator<Item = (f64, f64)>,
    limit: f64,
) -> Option<f64> {
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
