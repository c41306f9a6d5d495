//! `nusselt bench --only hierarchical`: hierarchical radiosity against progressive shooting
//! on the Cornell box (default mesh), whole solves to a residual of 1e-4: image error
//! against the path-traced reference, solve time, stored form factors or links, and the
//! process's peak memory. Writes `hierarchical.csv`.

use std::io::Write;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use anyhow::{Context, Result};

use crate::render::{self, Image};
use crate::scene::{LoadOptions, Scene};
use crate::solver::{Problem, SolverConfig, SolverKind, StopCriteria, run_solver};

use super::bench::{peak_mb, reset_peak};
use super::bench_images::render_elements;

/// Link tolerances measured (the default is [`crate::solver::DEFAULT_LINK_TOLERANCE`]).
const TOLERANCES: [f64; 4] = [0.02, 0.005, 0.002, 0.001];

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
    let mut csv =
        std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?;
    writeln!(
        csv,
        "solver,link_tolerance,elements,steps,solve_seconds,image_error,stored_mb,peak_rss_mb,report"
    )?;
    println!("\nhierarchical vs shooting, Cornell box, to residual 1e-4:");
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
    let never = AtomicBool::new(false);
    for (kind, tolerance) in runs {
        reset_peak();
        let config = SolverConfig {
            link_tolerance: tolerance.unwrap_or(crate::solver::DEFAULT_LINK_TOLERANCE),
            ..SolverConfig::default()
        };
        let start = Instant::now();
        let mut s = kind.build(Problem::new(scene.clone(), config)?)?;
        let stop = StopCriteria {
            unshot: 1e-4,
            ..Default::default()
        };
        run_solver(s.as_mut(), &stop, &never, &mut |_, _| {});
        let seconds = start.elapsed().as_secs_f64();
        let peak = peak_mb().unwrap_or(f64::NAN);
        let bvh = render::display_bvh(&scene, &s.problem().mesh);
        let image = render_elements(s.problem(), &s.element_radiance(true), &bvh, 16);
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
