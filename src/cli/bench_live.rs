//! `nusselt bench --only live`: what a user of the viewer sees on a large model, measured
//! without a window. The viewer's own solver thread (`nusselt_viewer::solver_thread`, the
//! same settings `nusselt view MODEL` gives it) runs on the model while this thread takes
//! its snapshots as the viewer's UI would; at fixed times it draws the snapshot as the
//! viewport shows it (radiance plus the display correction per drawn vertex, interpolated
//! across each display triangle; textures and exposure left out, as they scale both images
//! alike) from the scene's first camera, and at the end compares every such image with the
//! last one: of the converged solution, or where the run ends first (`--live-seconds`), of
//! the solution then (relative RMS, `render::image::relative_rms`; `live_summary.csv` says
//! which by its `converged_s`).
//!
//! The clock starts before the model is loaded, as `nusselt view MODEL` starts; drawing a
//! sampled snapshot (256 × 192 eye rays on the display triangles) takes this thread some
//! 20 ms beside the solver, as the viewer's UI takes its share. The window, the GPU upload
//! and the textures on the GPU are not part of it: docs/VIEWER.md has the frame log of the
//! real window. Peak memory is the process's resident high-water mark (`VmHWM`, reset
//! before each model; memory the allocator kept from an earlier model counts again, so
//! measure one model per process for its own peak).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::Parser;
use glam::DVec3;
use nusselt_core::geometry::Ray;
use nusselt_core::render::image::{Image, relative_rms};
use nusselt_core::solver::{SolverConfig, SolverKind};
use nusselt_viewer::snapshot::Snapshot;
use nusselt_viewer::solver_thread::{SolverHandle, ThreadConfig};

use super::plot::{Plot, Series};

/// Image size of the sampled views.
const WIDTH: u32 = 256;
const HEIGHT: u32 = 192;
/// Seconds since start at which the displayed image is sampled.
const TIMES: [f64; 24] = [
    0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 15.0, 20.0, 25.0, 30.0, 40.0, 50.0,
    60.0, 75.0, 90.0, 120.0, 150.0, 180.0, 240.0,
];

/// One sampled moment of a run.
struct Sample {
    seconds: f64,
    steps: usize,
    residual: f64,
    image: Image,
}

/// What one model gave.
struct Run {
    model: String,
    solver: String,
    elements: usize,
    first_snapshot: Option<f64>,
    samples: Vec<Sample>,
    converged: Option<f64>,
    /// The reference image: the converged solution, or the last one if none converged.
    reference: Option<Sample>,
    peak_mb: f64,
}

/// Only the scene flags of `nusselt view` (a model as `nusselt view MODEL` loads it).
#[derive(Parser)]
struct SceneOnly {
    #[command(flatten)]
    scene: super::SceneArgs,
}

pub fn live(out: &Path, models: &[PathBuf], solver: Option<&str>, limit: f64) -> Result<()> {
    if !(limit.is_finite() && limit > 0.0) {
        bail!("--live-seconds must be a positive number, got {limit}");
    }
    if let Some(missing) = models.iter().find(|m| !m.is_file()) {
        bail!(
            "{}: no such model (pass --live-model PATH)",
            missing.display()
        );
    }
    let kind = solver
        .filter(|s| *s != "auto")
        .map(|s| SolverKind::parse(s, None).with_context(|| format!("unknown solver {s}")))
        .transpose()?;
    let mut csv = super::bench::csv_file(
        &out.join("live.csv"),
        "model,solver,elements,seconds,steps,residual,image_error",
    )?;
    let mut summary = super::bench::csv_file(
        &out.join("live_summary.csv"),
        "model,solver,elements,first_snapshot_s,within_5pct_s,residual_1e-3_s,converged_s,error_20s,peak_mb",
    )?;
    let mut series = Vec::new();
    for model in models {
        let run = run_one(model, kind, limit)?;
        write_rows(&mut csv, &mut summary, &run)?;
        save_images(out, &run)?;
        series.push(Series {
            // The plot's font has no arrow.
            label: format!("{} ({})", run.model, run.solver.replace(" → ", ", then ")),
            points: errors(&run).into_iter().map(|(t, _, e)| (t, e)).collect(),
            markers: false,
        });
    }
    super::plot::write(
        &out.join("live"),
        &Plot {
            title: "the viewer's displayed image against its last one (converged or at the limit)",
            x_label: "seconds since start (load, mesh, solve)",
            y_label: "relative RMS image error",
            series,
        },
    )
}

/// Runs the viewer's solver thread on `model` until it converges or `limit` seconds pass.
fn run_one(model: &Path, kind: Option<SolverKind>, limit: f64) -> Result<Run> {
    reset_peak_memory();
    let start = Instant::now();
    let args = SceneOnly::try_parse_from([std::ffi::OsStr::new("view"), model.as_os_str()])?;
    let scene = args.scene.load()?;
    let config = ThreadConfig {
        solver: SolverConfig {
            memory_bytes: super::render::max_memory_bytes(None)?,
            ..Default::default()
        },
        kind: kind.unwrap_or(SolverKind::Shooting),
        // Default flags: `--solver auto`.
        handoff: kind.is_none(),
        ..Default::default()
    };
    let name = model.parent().and_then(|p| p.file_name()).map_or_else(
        || model.display().to_string(),
        |n| n.to_string_lossy().into(),
    );
    let mut handle = SolverHandle::spawn(scene, config, Box::new(|| {}))?;
    let mut run = Run {
        model: name,
        solver: String::new(),
        elements: 0,
        first_snapshot: None,
        samples: Vec::new(),
        converged: None,
        reference: None,
        peak_mb: 0.0,
    };
    let mut next = 0usize;
    let mut latest: Option<Arc<Snapshot>> = None;
    loop {
        let t = start.elapsed().as_secs_f64();
        if let Some(s) = handle.take_snapshot() {
            run.first_snapshot.get_or_insert(t);
            // A handover shows as "shooting → hierarchical".
            if run.solver.is_empty() {
                run.solver = s.stats.solver.to_string();
            } else if !run.solver.ends_with(s.stats.solver) {
                run.solver = format!("{} → {}", run.solver, s.stats.solver);
            }
            run.elements = s.stats.elements;
            if s.stats.converged && run.converged.is_none() {
                run.converged = Some(t);
            }
            latest = Some(s);
        }
        // One sample for the latest sampling time passed (those passed before the first
        // snapshot showed nothing and are left out).
        let due = TIMES[next..].iter().take_while(|&&x| x <= t).count();
        if due > 0
            && let Some(s) = &latest
        {
            run.samples.push(sample(s, t));
        }
        next += due;
        if run.converged.is_some() || t >= limit {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    run.reference = latest
        .as_ref()
        .map(|s| sample(s, start.elapsed().as_secs_f64()));
    run.peak_mb = peak_memory_mb();
    handle.shutdown(Duration::from_secs(30));
    Ok(run)
}

fn sample(s: &Snapshot, seconds: f64) -> Sample {
    Sample {
        seconds,
        steps: s.stats.steps,
        residual: s.stats.residual,
        image: draw(s),
    }
}

/// The snapshot as the viewport draws it (without textures and exposure): per drawn
/// vertex radiance plus correction, interpolated over the display triangle each eye ray
/// hits first.
fn draw(s: &Snapshot) -> Image {
    let g = &s.geometry;
    let camera = &s.scene_camera;
    let shown: Vec<DVec3> = (s.radiance.iter().zip(s.correction.iter()))
        .map(|(r, c)| {
            DVec3::new(r[0] as f64, r[1] as f64, r[2] as f64) + DVec3::from(c.map(f64::from))
        })
        .collect();
    let mut image = Image::new(WIDTH, HEIGHT);
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let d = camera.ray_dir(x as f64 + 0.5, y as f64 + 0.5, WIDTH, HEIGHT);
            let Some(hit) = g
                .bvh()
                .closest_hit(&Ray::new(camera.eye, d), 0.0, f64::INFINITY)
            else {
                continue;
            };
            let t = 3 * hit.id as usize;
            let [a, b, c] =
                [g.indices[t], g.indices[t + 1], g.indices[t + 2]].map(|i| shown[i as usize]);
            image.pixels[(y * WIDTH + x) as usize] =
                a * (1.0 - hit.u - hit.v) + b * hit.u + c * hit.v;
        }
    }
    image
}

/// `(seconds, sample index, error)` of every sample against the reference.
fn errors(run: &Run) -> Vec<(f64, usize, f64)> {
    let Some(reference) = &run.reference else {
        return Vec::new();
    };
    let mask = vec![true; (WIDTH * HEIGHT) as usize];
    run.samples
        .iter()
        .enumerate()
        .filter_map(|(k, s)| {
            Some((
                s.seconds,
                k,
                relative_rms(&s.image, &reference.image, &mask).ok()?,
            ))
        })
        .collect()
}

fn write_rows(csv: &mut dyn Write, summary: &mut dyn Write, run: &Run) -> Result<()> {
    let errors = errors(run);
    for &(t, k, e) in &errors {
        let s = &run.samples[k];
        writeln!(
            csv,
            "{},{},{},{t:.2},{},{:.3e},{e:.4}",
            run.model, run.solver, run.elements, s.steps, s.residual
        )?;
    }
    // From when on every later sample stays within 5 %.
    let within = errors
        .iter()
        .rposition(|&(_, _, e)| e > 0.05)
        .map_or(errors.first().map(|e| e.0), |k| {
            errors.get(k + 1).map(|e| e.0)
        });
    let residual = run
        .samples
        .iter()
        .find(|s| s.residual <= 1e-3)
        .map(|s| s.seconds)
        .or(run.converged);
    let at_20 = errors.iter().find(|e| e.0 >= 20.0).map(|e| e.2);
    let opt = |x: Option<f64>, p: usize| x.map_or("".to_string(), |v| format!("{v:.p$}"));
    let line = format!(
        "{},{},{},{},{},{},{},{},{:.0}",
        run.model,
        run.solver,
        run.elements,
        opt(run.first_snapshot, 2),
        opt(within, 1),
        opt(residual, 1),
        opt(run.converged, 1),
        opt(at_20, 4),
        run.peak_mb
    );
    writeln!(summary, "{line}")?;
    println!("{line}");
    Ok(())
}

/// The sampled images and the reference as `live_MODEL_SECONDS.pfm` (linear radiance,
/// for `nusselt compare` and a look).
fn save_images(out: &Path, run: &Run) -> Result<()> {
    for s in run.samples.iter().chain(&run.reference) {
        let path = out.join(format!("live_{}_{:05.1}s.pfm", run.model, s.seconds));
        s.image.save(&path, 0.0)?;
    }
    Ok(())
}

/// Resets the process's resident high-water mark (Linux: `5` to `/proc/self/clear_refs`).
fn reset_peak_memory() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// The process's resident high-water mark in MB (`VmHWM`; 0 where unknown).
fn peak_memory_mb() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        .map_or(0.0, |kb| kb / 1024.0)
}
