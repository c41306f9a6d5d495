//! `nusselt bench --only hierarchical`: hierarchical and wavelet radiosity against
//! progressive shooting on the Cornell box (default mesh), whole solves to a residual of
//! 1e-4: image error against the path-traced reference, solve time, stored form factors or
//! links, and the process's peak memory. Writes `hierarchical.csv`.
//!
//! `nusselt bench --only large`: the same three on the large scenes (the generated gallery,
//! 100 k input triangles, and the Cornell box at a million elements): seconds to a residual
//! of 1 % and of 1e-4 (or the time limit), memory, and the image error against the
//! path-traced references (`benches/data/cornell_256_ref.pfm`, `gallery_256_ref.pfm`).
//! Writes `large.csv`.

use std::io::Write;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use anyhow::Result;

use nusselt_core::mesh::MeshSpec;
use nusselt_core::render::{self, Image};
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::{Problem, SolverConfig, SolverKind, StopCriteria, run_solver};

use super::bench::{peak_mb, reset_peak};
use super::bench_images::render_elements;

/// Link tolerances measured (the default is [`nusselt_core::solver::DEFAULT_LINK_TOLERANCE`]).
const TOLERANCES: [f64; 4] = [0.02, 0.005, 0.002, 0.001];
/// Those for flatlets (each block costs 16 oracle evaluations).
const WAVELET_TOLERANCES: [f64; 3] = [0.02, 0.005, 0.002];
/// Time limit of one large-scene run.
const LARGE_SECONDS: f64 = 90.0;

pub fn cornell(out: &Path, reference_path: &Path) -> Result<()> {
    let reference = match Image::load_pfm(reference_path) {
        Ok(r) => r,
        Err(e) => {
            println!("\nhierarchical: no reference ({e}); pass --cornell-reference");
            return Ok(());
        }
    };
    let scene = Scene::builtin("cornell", &LoadOptions::default())?;
    let camera = render::view::default_camera(&scene);
    let mask = render::error_mask(&scene, &camera, reference.width, reference.height);
    let path = out.join("hierarchical.csv");
    let mut csv = super::bench::csv_file(
        &path,
        "solver,link_tolerance,elements,steps,solve_seconds,image_error,stored_mb,peak_rss_mb,report",
    )?;
    println!("\nhierarchical and wavelet vs shooting, Cornell box, to residual 1e-4:");
    println!(
        "{:<14} {:>9} {:>8} {:>6} {:>8} {:>8} {:>9} {:>9}",
        "solver", "tolerance", "elements", "steps", "solve s", "error %", "stored MB", "peak MB"
    );
    let mut runs: Vec<(SolverKind, Option<f64>)> = vec![(SolverKind::Shooting, None)];
    runs.extend(
        TOLERANCES
            .iter()
            .map(|t| (SolverKind::Hierarchical, Some(*t))),
    );
    runs.extend(
        WAVELET_TOLERANCES
            .iter()
            .map(|t| (SolverKind::Wavelet, Some(*t))),
    );
    let never = AtomicBool::new(false);
    for (kind, tolerance) in runs {
        reset_peak();
        let config = SolverConfig {
            hierarchical: nusselt_core::solver::HierarchicalOptions {
                link_tolerance: tolerance.unwrap_or(nusselt_core::solver::DEFAULT_LINK_TOLERANCE),
            },
            ..SolverConfig::default()
        };
        let start = Instant::now();
        let mut s = kind.build(Problem::new(scene.clone(), config)?)?;
        let stop = StopCriteria {
            residual: 1e-4,
            ..Default::default()
        };
        run_solver(s.as_mut(), &stop, &never, &mut |_, _| {});
        let seconds = start.elapsed().as_secs_f64();
        let peak = peak_mb().unwrap_or(f64::NAN);
        let bvh = render::display_bvh(&scene, &s.problem().mesh);
        let image = render_elements(s.problem(), &s.display_radiance(), &bvh, 16);
        let error = render::relative_rms(&image, &reference, &mask).unwrap_or(f64::NAN);
        let stored = s.matrix_bytes() as f64 / (1 << 20) as f64;
        let report = s.report().replace(',', ";");
        let elements = s.problem().mesh.elements.len();
        println!(
            "{:<14} {:>9} {:>8} {:>6} {:>8.2} {:>8.2} {:>9.1} {:>9.0}",
            s.name(),
            tolerance.map(|t| t.to_string()).unwrap_or("-".into()),
            elements,
            s.steps(),
            seconds,
            100.0 * error,
            stored,
            peak
        );
        writeln!(
            csv,
            "{},{},{},{},{:.3},{:.5},{:.1},{:.0},{}",
            s.name(),
            tolerance.map(|t| t.to_string()).unwrap_or_default(),
            elements,
            s.steps(),
            seconds,
            error,
            stored,
            peak,
            report
        )?;
    }
    println!("wrote {}", path.display());
    Ok(())
}

/// The large scenes: seconds to 1 % and to 1e-4, memory, image difference.
pub fn large(out: &Path, cornell_reference: &Path, gallery_reference: &Path) -> Result<()> {
    let path = out.join("large.csv");
    let mut csv = super::bench::csv_file(
        &path,
        "scene,solver,elements,steps,seconds_to_1pc,seconds,residual,image_error,stored_mb,peak_rss_mb,report",
    )?;
    println!("\nlarge scenes (each run to residual 1e-4 or {LARGE_SECONDS} s):");
    println!(
        "{:<12} {:<13} {:>8} {:>6} {:>8} {:>8} {:>9} {:>8} {:>9} {:>8}",
        "scene",
        "solver",
        "elements",
        "steps",
        "s to 1%",
        "s",
        "residual",
        "error %",
        "stored MB",
        "peak MB"
    );
    let scenes: [(&str, &str, Option<usize>, &Path); 2] = [
        ("gallery", "gallery", None, gallery_reference),
        ("cornell-1M", "cornell", Some(1_000_000), cornell_reference),
    ];
    let never = AtomicBool::new(false);
    for (label, builtin, max_elements, reference_path) in scenes {
        let scene = Scene::builtin(builtin, &LoadOptions::default())?;
        let camera = render::view::default_camera(&scene);
        let reference = Image::load_pfm(reference_path).ok();
        if reference.is_none() {
            println!("{label}: no reference at {}", reference_path.display());
        }
        for kind in [
            SolverKind::Shooting,
            SolverKind::Hierarchical,
            SolverKind::Wavelet,
        ] {
            reset_peak();
            let config = SolverConfig {
                mesh: MeshSpec {
                    max_elements,
                    ..Default::default()
                },
                ..SolverConfig::default()
            };
            let start = Instant::now();
            let mut s = kind.build(Problem::new(scene.clone(), config)?)?;
            let stop = StopCriteria {
                residual: 1e-4,
                max_seconds: Some(LARGE_SECONDS),
                ..Default::default()
            };
            let mut to_one_percent = None;
            run_solver(s.as_mut(), &stop, &never, &mut |r, _| {
                if r.residual <= 1e-2 && to_one_percent.is_none() {
                    to_one_percent = Some(start.elapsed().as_secs_f64());
                }
            });
            let seconds = start.elapsed().as_secs_f64();
            let peak = peak_mb().unwrap_or(f64::NAN);
            let radiance = s.display_radiance();
            let (steps, residual, name) = (s.steps(), s.residual(), s.name());
            let (report, stored) = (s.report().replace(',', ";"), s.matrix_bytes());
            let (problem, rows) = s.into_parts();
            drop(rows);
            let bvh = render::display_bvh(&scene, &problem.mesh);
            let image = render_elements(&problem, &radiance, &bvh, 16);
            let error = reference
                .as_ref()
                .map(|r| {
                    let mask = render::error_mask(&scene, &camera, r.width, r.height);
                    render::relative_rms(&image, r, &mask).unwrap_or(f64::NAN)
                })
                .unwrap_or(f64::NAN);
            let stored = stored as f64 / (1 << 20) as f64;
            let elements = problem.mesh.elements.len();
            let to_1 = to_one_percent
                .map(|t| format!("{t:.2}"))
                .unwrap_or("-".into());
            println!(
                "{label:<12} {name:<13} {elements:>8} {steps:>6} {to_1:>8} {seconds:>8.2} {residual:>9.1e} {:>8.2} {stored:>9.1} {peak:>8.0}",
                100.0 * error,
            );
            writeln!(
                csv,
                "{label},{name},{elements},{steps},{to_1},{seconds:.3},{residual:.3e},{error:.5},{stored:.1},{peak:.0},{report}"
            )?;
        }
    }
    println!("wrote {}", path.display());
    Ok(())
}
