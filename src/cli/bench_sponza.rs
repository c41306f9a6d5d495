//! `nusselt bench --only sponza`: the Crytek atrium (263 k triangles, two emitting
//! spheres, 23 textures; `../shared/models/crytek_sponza`, or `--sponza PATH`) with default
//! flags, each row one `nusselt render` child process as a user runs it: where the time of
//! the whole command goes (load, meshing, textures, solve, render), shots per second, the
//! unshot fraction reached, the vertex pass at 256², and the process's peak memory.
//! Writes `sponza.csv`. Rows: `--seconds 10/30/60` with shooting, `--shots 0` (setup and
//! render alone: what a slow pass or a slow meshing would show first), the hierarchical
//! solver to convergence, and the hierarchical solver under `--seconds 45/100`, whose
//! refinement steps take 20–30 s each and whose direct-pass probe alone once took 150 s.
//! A run with `--seconds S` whose whole command takes more than S + 10 % fails the bench.

use std::io::Write;
use std::path::Path;
use std::process::Command;

use anyhow::{Context, Result, bail};

/// One measured configuration: a label and the `render` flags after the model.
const RUNS: [(&str, &[&str]); 7] = [
    ("setup + render only", &["--shots", "0", "--pass", "vertex"]),
    ("shooting --seconds 10", &["--seconds", "10"]),
    ("shooting --seconds 30", &["--seconds", "30"]),
    ("shooting --seconds 60", &["--seconds", "60"]),
    ("hierarchical, converged", &["--solver", "hierarchical"]),
    (
        "hierarchical --seconds 45",
        &["--solver", "hierarchical", "--seconds", "45"],
    ),
    (
        "hierarchical --seconds 100",
        &["--solver", "hierarchical", "--seconds", "100"],
    ),
];

/// A `--seconds` run may end this much past its limit.
const SECONDS_SLACK: f64 = 1.1;

pub fn sponza(out: &Path, model: &Path) -> Result<()> {
    if !model.is_file() {
        bail!(
            "the atrium model {} is missing (pass --sponza PATH to crytek_sponza/sponza.obj)",
            model.display()
        );
    }
    let exe = std::env::current_exe().context("finding the nusselt executable")?;
    let path = out.join("sponza.csv");
    let mut csv = super::bench::csv_file(
        &path,
        "run,elements,load_s,mesh_s,textures_s,solve_s,steps,shots_per_s,unshot,render_s,total_s,peak_mb",
    )?;
    println!(
        "\n| atrium (default flags) | elements | load s | mesh s | textures s | solve s | steps | steps/s | unshot | render s | whole s | peak MB |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let image = out.join("sponza.png");
    let mut late = Vec::new();
    for (label, flags) in RUNS {
        let started = std::time::Instant::now();
        let output = Command::new("/usr/bin/time")
            .args(["-f", "PEAK_KB %M"])
            .arg(&exe)
            .arg("render")
            .arg(model)
            .args(flags)
            .arg("--out")
            .arg(&image)
            .arg("--json")
            .output()
            .with_context(|| format!("running {} render (needs /usr/bin/time)", exe.display()))?;
        let stdout = String::from_utf8_lossy(&output.stdout);
        let stderr = String::from_utf8_lossy(&output.stderr);
        if !output.status.success() {
            bail!("{label}: render failed: {stderr}");
        }
        let summary: serde_json::Value = stdout
            .lines()
            .find(|l| l.starts_with('{'))
            .context("no JSON summary")
            .and_then(|l| Ok(serde_json::from_str(l)?))?;
        let peak_mb = stderr
            .lines()
            .find_map(|l| l.strip_prefix("PEAK_KB "))
            .and_then(|k| k.trim().parse::<f64>().ok())
            .map(|k| k / 1024.0);
        let f = |k: &str| summary[k].as_f64().unwrap_or(f64::NAN);
        let setup = |k: &str| summary["setup_seconds"][k].as_f64().unwrap_or(0.0);
        let (mesh, textures) = (setup("mesh"), setup("textures"));
        let solve = f("solve_seconds") - mesh - textures - setup("bvh") - setup("lights");
        let steps = f("shots");
        let rate = if solve > 0.0 { steps / solve } else { 0.0 };
        let peak = peak_mb.unwrap_or(f64::NAN);
        writeln!(
            csv,
            "{label},{},{:.2},{mesh:.2},{textures:.2},{solve:.2},{steps},{rate:.2},{:.3e},{:.2},{:.2},{peak:.0}",
            f("elements"),
            f("load_seconds"),
            f("unshot_fraction"),
            f("render_seconds"),
            f("total_seconds"),
        )?;
        println!(
            "| {label} | {} | {:.1} | {mesh:.1} | {textures:.1} | {solve:.1} | {steps} | {rate:.1} | {:.2e} | {:.2} | {:.1} | {peak:.0} |",
            f("elements"),
            f("load_seconds"),
            f("unshot_fraction"),
            f("render_seconds"),
            f("total_seconds"),
        );
        let whole = started.elapsed().as_secs_f64();
        if let Some(limit) = seconds_flag(flags)
            && whole > limit * SECONDS_SLACK
        {
            late.push(format!("{label}: {whole:.1} s"));
        }
    }
    eprintln!("wrote {}", path.display());
    if !late.is_empty() {
        bail!(
            "past their --seconds limit (+{:.0} %): {}",
            (SECONDS_SLACK - 1.0) * 100.0,
            late.join(", ")
        );
    }
    Ok(())
}

/// The value of `--seconds` among `flags`.
fn seconds_flag(flags: &[&str]) -> Option<f64> {
    let at = flags.iter().position(|f| *f == "--seconds")?;
    flags.get(at + 1)?.parse().ok()
}
