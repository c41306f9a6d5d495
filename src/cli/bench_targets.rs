//! `nusselt bench --only targets`: the whole-process targets of the Cornell box at 256²
//! (5 % image error in ≤ 0.15 s, 2 % in ≤ 2 s, 1 % in ≤ 18 s), stated side by side
//! with the path tracer on the same machine.
//!
//! Each configuration is the `nusselt render` command itself, run as a child process from
//! this executable (start, load, mesh, solve, render, write the PFM; no `--reference`, so
//! judging the image is not counted), timed from spawn to exit [`RUNS`] times; the median
//! is reported with the spread. The image is judged afterwards with the render's pixel
//! mask against the path-traced reference. The path tracer (`nusselt reference`) runs the
//! same way at 16, 64 and 256 samples per pixel; the time it would need for each target is
//! extrapolated from the 256-spp run by its error falling as 1/√spp (time ∝ spp). Writes
//! `targets.csv`.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{Context, Result, bail};

use nusselt_core::render::{self, Image};
use nusselt_core::scene::{LoadOptions, Scene};

/// Runs of each radiosity configuration (the median is reported).
const RUNS: usize = 5;

/// A target and the `render` flags that meet it here (on top of `--builtin cornell`).
struct Target {
    error: f64,
    seconds: f64,
    flags: &'static [&'static str],
}

const TARGETS: [Target; 3] = [
    // Coarse uniform mesh, 4 samples per pixel (16 more on edges), stopped at 1 % unshot
    // with the classic ambient term for the rest (the regional term's 200,000 transport
    // rays would cost half the budget; in one room they agree).
    Target {
        error: 0.05,
        seconds: 0.15,
        flags: &[
            "--max-elements",
            "1500",
            "--spp",
            "4",
            "--unshot",
            "1e-2",
            "--ambient",
            "global",
            "--edge-spp",
            "16",
            "--pass",
            "vertex",
        ],
    },
    // Discontinuity meshing and the direct pass.
    Target {
        error: 0.02,
        seconds: 2.0,
        flags: &[
            "--discontinuity",
            "--max-elements",
            "4000",
            "--pass",
            "direct",
            "--unshot",
            "1e-3",
        ],
    },
    Target {
        error: 0.01,
        seconds: 18.0,
        flags: &[
            "--discontinuity",
            "--max-elements",
            "25000",
            "--pass",
            "direct",
        ],
    },
];

/// Path tracer sample counts.
const PATH_SPP: [u32; 3] = [16, 64, 256];

/// One measured configuration.
struct Measured {
    seconds: Vec<f64>,
    error: f64,
}

impl Measured {
    fn median(&self) -> f64 {
        let mut s = self.seconds.clone();
        s.sort_by(f64::total_cmp);
        s[s.len() / 2]
    }
}

/// Runs `nusselt <args> --out <image>` `runs` times, timing each, and judges the image.
fn measure(
    exe: &Path,
    args: &[String],
    image: &Path,
    runs: usize,
    judge: &dyn Fn(&Image) -> Result<f64>,
) -> Result<Measured> {
    let mut seconds = Vec::with_capacity(runs);
    for _ in 0..runs {
        let start = Instant::now();
        let out = Command::new(exe)
            .args(args)
            .arg("--out")
            .arg(image)
            .output()
            .with_context(|| format!("running {}", exe.display()))?;
        seconds.push(start.elapsed().as_secs_f64());
        if !out.status.success() {
            bail!(
                "nusselt {} failed: {}",
                args.join(" "),
                String::from_utf8_lossy(&out.stderr)
            );
        }
    }
    let error = judge(&Image::load_pfm(image)?)?;
    Ok(Measured { seconds, error })
}

/// A radiosity target's measurement with its fastest and slowest run.
type TargetRun = (&'static Target, Measured, f64, f64);

/// Judges an image: its relative RMS error against the reference.
type Judge<'a> = &'a dyn Fn(&Image) -> Result<f64>;

pub fn targets(out: &Path, reference_path: &Path) -> Result<()> {
    let reference = Image::load_pfm(reference_path)
        .with_context(|| format!("targets: the reference {}", reference_path.display()))?;
    let scene = Scene::builtin("cornell", &LoadOptions::default())?;
    let camera = render::view::default_camera(&scene);
    let mask = render::error_mask(&scene, &camera, reference.width, reference.height);
    let judge = |image: &Image| Ok(render::relative_rms(image, &reference, &mask)?);
    let exe = std::env::current_exe().context("finding the nusselt executable")?;
    let image: PathBuf = out.join("targets_image.pfm");

    let mut csv = super::bench::csv_file(
        &out.join("targets.csv"),
        "kind,flags,runs,median_s,min_s,max_s,error,target_error,target_s",
    )?;
    let radiosity = radiosity_runs(&exe, &image, &judge, &mut csv)?;
    let path = path_tracer_runs(&exe, &image, &judge, &mut csv)?;
    let _ = std::fs::remove_file(&image);
    print_targets(&radiosity, &path);
    eprintln!("wrote {}", out.join("targets.csv").display());
    Ok(())
}

/// `nusselt COMMAND --builtin cornell`'s arguments.
fn base_args(command: &str) -> Vec<String> {
    [command, "--builtin", "cornell"]
        .iter()
        .map(|s| s.to_string())
        .collect()
}

/// Each target's `render` run [`RUNS`] times; a CSV row each.
fn radiosity_runs(
    exe: &Path,
    image: &Path,
    judge: Judge,
    csv: &mut dyn Write,
) -> Result<Vec<TargetRun>> {
    let mut radiosity = Vec::new();
    for t in &TARGETS {
        let mut args = base_args("render");
        args.extend(t.flags.iter().map(|s| s.to_string()));
        eprintln!("targets: render {}…", t.flags.join(" "));
        let m = measure(exe, &args, image, RUNS, judge)?;
        let (lo, hi) = m
            .seconds
            .iter()
            .fold((f64::INFINITY, 0f64), |(a, b), &s| (a.min(s), b.max(s)));
        writeln!(
            csv,
            "radiosity,{},{},{:.3},{:.3},{:.3},{:.5},{},{}",
            t.flags.join(" "),
            RUNS,
            m.median(),
            lo,
            hi,
            m.error,
            t.error,
            t.seconds
        )?;
        radiosity.push((t, m, lo, hi));
    }
    Ok(radiosity)
}

/// The path tracer (`nusselt reference`) once at each of [`PATH_SPP`]; a CSV row each.
fn path_tracer_runs(
    exe: &Path,
    image: &Path,
    judge: Judge,
    csv: &mut dyn Write,
) -> Result<Vec<(u32, Measured)>> {
    let mut path = Vec::new();
    for spp in PATH_SPP {
        let mut args = base_args("reference");
        args.extend(["--spp".to_string(), spp.to_string(), "--quiet".to_string()]);
        eprintln!("targets: path tracer {spp} spp…");
        let m = measure(exe, &args, image, 1, judge)?;
        writeln!(
            csv,
            "pathtracer,--spp {spp},1,{:.3},{:.3},{:.3},{:.5},,",
            m.median(),
            m.median(),
            m.median(),
            m.error
        )?;
        path.push((spp, m));
    }
    Ok(path)
}

/// The targets and the path tracer's runs on stdout; the path tracer's time to each target
/// measured where a run reached it, else extrapolated.
fn print_targets(radiosity: &[TargetRun], path: &[(u32, Measured)]) {
    println!("\nCornell box 256², whole process (`nusselt render`, median of {RUNS} runs):");
    println!(
        "{:>7} {:>8} | {:>9} {:>15} {:>7} {:>4} | {:>18} | flags",
        "target", "in", "median s", "min–max s", "error", "met", "path tracer s"
    );
    let last = &path.last().expect("PATH_SPP is not empty").1;
    for (t, m, lo, hi) in radiosity {
        let met = m.error <= t.error && m.median() <= t.seconds;
        // The path tracer's time to this error: measured where a run reached it, else
        // extrapolated from the largest run (error ∝ 1/√spp, time ∝ spp).
        let reached = path.iter().find(|(_, p)| p.error <= t.error);
        let path_s = match reached {
            Some((spp, p)) => format!("{:.2} ({spp} spp)", p.median()),
            None => format!(
                "~{:.0} (extrap.)",
                last.median() * (last.error / t.error).powi(2)
            ),
        };
        println!(
            "{:>6.0} % {:>6.2} s | {:>9.3} {:>7.3}–{:<7.3} {:>6.2} % {:>4} | {:>18} | {}",
            t.error * 100.0,
            t.seconds,
            m.median(),
            lo,
            hi,
            m.error * 100.0,
            if met { "yes" } else { "no" },
            path_s,
            t.flags.join(" ")
        );
    }
    println!("path tracer (`nusselt reference`, one run each):");
    for (spp, m) in path {
        println!(
            "  {spp:>4} spp: {:.2} s, {:.2} %",
            m.median(),
            m.error * 100.0
        );
    }
}
