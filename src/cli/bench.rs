//! `nusselt bench`: every solver on scenes with a known answer, error and residual against
//! wall-clock time, in the manner of Willmott & Heckbert's empirical comparison of
//! radiosity algorithms (1997). CSV under `--out` (default `bench/`), a summary table on
//! stdout.
//!
//! Scenes: the furnace at ρ = 0.5/0.9/0.99/0.999 (exact answer `1/(1 − ρ)`, every
//! element), the ceiling-lit unit cube at ρ = 0.5/0.9/0.99 (face averages against a fine
//! mesh solved by the Krylov solver to a residual of 1e-10), and the Cornell box (residual
//! only). The live-edit benchmark changes a Cornell wall's Kd and the light's Ke on a
//! converged solve and times shooting back to 1 % of the edit's power.

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;

use nusselt_core::mesh::MeshSpec;
use nusselt_core::scene::{LoadOptions, MaterialId, Rgb, Scene};

use super::plot::{self, Plot, Series};
use nusselt_core::solver::{
    Problem, ProgressiveSolver, Solver, SolverConfig, SolverKind, StopCriteria, run_solver,
};

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Folder for the CSV files.
    #[arg(long, default_value = "bench")]
    pub out: PathBuf,
    /// Wall-clock limit per solver and scene, in seconds.
    #[arg(long, default_value_t = 20.0)]
    pub seconds: f64,
    /// Only the scenes whose name contains this (e.g. `furnace`, `cube-0.99`, `cornell`,
    /// `tworooms`, `cornell-image`, `meshing` (error against elements: uniform, adaptive and
    /// discontinuity meshing), `hierarchical`, `specular` (the mirror and glass scene,
    /// hybrid against path tracer), `targets` (the Cornell box's whole-process time to 5 %,
    /// 2 % and 1 % image error, `nusselt render` run as a child process, against the path
    /// tracer), `large`: the gallery and a million-element
    /// Cornell box with shooting, hierarchical and wavelet radiosity, several minutes;
    /// `sponza`: the 263 k-triangle atrium with default flags, `nusselt render` as a child
    /// process: setup phases, shots/s, the vertex pass, peak memory, about 4 minutes;
    /// `live`: the viewer's solver thread on `--live-model` (default the Crytek atrium, the
    /// Šibenik cathedral and the Dabrović atrium): its displayed image against its last
    /// one (converged, or at `--live-seconds`) over time, `live.csv`, `live_summary.csv`
    /// and `live.svg`).
    #[arg(long)]
    pub only: Option<String>,
    /// Models for `live` (repeat the flag for several).
    #[arg(long, default_values = [
        "../shared/models/crytek_sponza/sponza.obj",
        "../shared/models/sibenik/sibenik.obj",
        "../shared/models/dabrovic_sponza/sponza.obj",
    ])]
    pub live_model: Vec<PathBuf>,
    /// The viewer's solver for `live` (`auto`, as `nusselt view` chooses, or a name).
    #[arg(long, default_value = "auto")]
    pub live_solver: String,
    /// Longest run per model for `live`, in seconds.
    #[arg(long, default_value_t = 240.0)]
    pub live_seconds: f64,
    /// The Cornell box's path-traced reference image for `cornell-image`.
    #[arg(long, default_value = "benches/data/cornell_256_ref.pfm")]
    pub cornell_reference: PathBuf,
    /// The gallery's path-traced reference image for `large` (`nusselt reference --builtin
    /// gallery --spp 4096`, about 1 % noise).
    #[arg(long, default_value = "benches/data/gallery_256_ref.pfm")]
    pub gallery_reference: PathBuf,
    /// The `cornell-specular` path-traced reference for `specular` (the hybrid eye pass
    /// against the path tracer; see docs/SPECULAR.md for how it was made).
    #[arg(long, default_value = "benches/data/cornell_specular_256_ref.pfm")]
    pub specular_reference: PathBuf,
    /// The Crytek atrium's OBJ for `sponza`.
    #[arg(long, default_value = "../shared/models/crytek_sponza/sponza.obj")]
    pub sponza: PathBuf,
    /// Runs no benchmark: rewrites the generated figure tables in README.md and docs/*.md
    /// (`<!-- bench:table NAME -->` regions) from the CSVs in `--out`. Run from the
    /// repository root.
    #[arg(long)]
    pub doc: bool,
    /// With `--doc`: writes nothing, and fails where a document differs from the CSVs.
    #[arg(long, requires = "doc")]
    pub check: bool,
}

/// Creates the bench CSV `path` with its [`provenance`] lines and `header` (the column
/// names), ready for rows.
pub(super) fn csv_file(path: &std::path::Path, header: &str) -> Result<std::fs::File> {
    let mut csv =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    provenance(&mut csv)?;
    writeln!(csv, "{header}")?;
    Ok(csv)
}

/// Writes the `# command:` and `# date:` lines every bench CSV opens with, read by
/// `nusselt bench --doc` for the line above each generated table.
pub(super) fn provenance(csv: &mut dyn Write) -> std::io::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    writeln!(csv, "# command: nusselt {}", args.join(" "))?;
    writeln!(csv, "# date: {}", utc_date(std::time::SystemTime::now()))
}

/// `time`'s UTC calendar date as `YYYY-MM-DD` (days to civil date, H. Hinnant's algorithm).
fn utc_date(time: std::time::SystemTime) -> String {
    let secs = time
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    let z = (secs / 86_400) as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1_460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}")
}

/// Resets the process's peak resident memory (Linux: `5` to `/proc/self/clear_refs`), so
/// that [`peak_mb`] after a run is that run's peak. Elsewhere a no-op.
pub(super) fn reset_peak() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// Peak resident memory since the last [`reset_peak`] (VmHWM), in MiB; `None` where the
/// system does not say.
pub(super) fn peak_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// The answer a run is measured against.
enum Truth {
    /// Every element's radiance.
    Uniform(f64),
    /// Area-weighted mean radiance per axis-aligned face of the unit cube.
    CubeFaces([f64; 6]),
    /// No answer: residual only.
    None,
}

fn cube_face(c: glam::DVec3) -> usize {
    let d = [c.x, 1.0 - c.x, c.y, 1.0 - c.y, c.z, 1.0 - c.z];
    (0..6).min_by(|&a, &b| d[a].total_cmp(&d[b])).unwrap_or(0)
}

fn cube_faces(solver: &dyn Solver) -> [f64; 6] {
    let mesh = &solver.problem().mesh;
    let mut sum = [0.0; 6];
    let mut area = [0.0; 6];
    for (e, b) in mesh.elements.iter().zip(solver.radiosity()) {
        let f = cube_face(e.centroid);
        sum[f] += b.x * e.area;
        area[f] += e.area;
    }
    std::array::from_fn(|k| if area[k] > 0.0 { sum[k] / area[k] } else { 0.0 })
}

fn error(truth: &Truth, solver: &dyn Solver) -> Option<f64> {
    match truth {
        Truth::Uniform(x) => Some(
            solver
                .radiosity()
                .iter()
                .map(|b| (b.x - x).abs() / x)
                .fold(0.0, f64::max),
        ),
        Truth::CubeFaces(reference) => {
            let faces = cube_faces(solver);
            Some(
                (0..6)
                    .map(|k| (faces[k] - reference[k]).abs() / reference[k])
                    .fold(0.0, f64::max),
            )
        }
        Truth::None => None,
    }
}

fn builtin(name: &str, rho: Option<f64>) -> Result<Scene> {
    Ok(Scene::builtin(
        name,
        &LoadOptions {
            rho,
            ..Default::default()
        },
    )?)
}

/// The cube's face averages from a fine mesh (contour rows, 9,600 elements), solved to a
/// residual of 1e-10 by the Krylov solver.
fn cube_reference(rho: f64) -> Result<[f64; 6]> {
    let config = SolverConfig {
        mesh: MeshSpec::sized(0.025, 0.1),
        ..Default::default()
    };
    let mut s = SolverKind::Cg.build(Problem::new(builtin("cube", Some(rho))?, config)?)?;
    let stop = StopCriteria {
        residual: 1e-10,
        max_steps: None,
        max_seconds: Some(600.0),
        tolerance: None,
    };
    run_solver(s.as_mut(), &stop, &AtomicBool::new(false), &mut |_, _| {});
    Ok(cube_faces(s.as_ref()))
}

struct Case {
    name: String,
    scene: Scene,
    truth: Truth,
}

const SOLVERS: [(&str, SolverKind, bool); 8] = [
    ("shooting", SolverKind::Shooting, true),
    ("shooting-plain", SolverKind::Shooting, false),
    ("jacobi", SolverKind::Jacobi, false),
    ("gauss-seidel", SolverKind::GaussSeidel, false),
    ("sor", SolverKind::Sor(None), false),
    ("cg", SolverKind::Cg, false),
    ("hierarchical", SolverKind::Hierarchical, false),
    ("wavelet", SolverKind::Wavelet, false),
];

pub fn run(args: &BenchArgs) -> Result<()> {
    if args.doc {
        return super::bench_doc::run(&args.out, std::path::Path::new("."), args.check);
    }
    if !(args.seconds.is_finite() && args.seconds > 0.0) {
        anyhow::bail!("--seconds must be a positive number");
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let wanted = |name: &str| args.only.as_ref().is_none_or(|o| name.contains(o.as_str()));
    let cases = convergence_cases(&wanted)?;
    let path = args.out.join("convergence.csv");
    let mut csv = convergence_csv(&path, !cases.is_empty())?;
    let mut plots: Vec<(String, Vec<Series>)> = Vec::new();
    for case in &cases {
        let mut case_series = Vec::new();
        for (label, kind, overshoot) in SOLVERS {
            if let Some(series) = convergence_run(case, label, kind, overshoot, args, &mut csv)? {
                case_series.push(series);
            }
        }
        plots.push((case.name.clone(), case_series));
    }
    csv.flush()?;
    convergence_plots(&args.out, plots)?;
    image_benches(args, &wanted)?;
    if !cases.is_empty() {
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// The scenes with a known answer that `--only` selects: the furnace, the cube (each with
/// its fine reference solve) and the Cornell box.
fn convergence_cases(wanted: &dyn Fn(&str) -> bool) -> Result<Vec<Case>> {
    let mut cases = Vec::new();
    for rho in [0.5, 0.9, 0.99, 0.999] {
        let name = format!("furnace-{rho}");
        if wanted(&name) {
            cases.push(Case {
                name,
                scene: builtin("furnace", Some(rho))?,
                truth: Truth::Uniform(1.0 / (1.0 - rho)),
            });
        }
    }
    for rho in [0.5, 0.9, 0.99] {
        let name = format!("cube-{rho}");
        if wanted(&name) {
            eprintln!("{name}: fine reference solve…");
            cases.push(Case {
                name,
                scene: builtin("cube", Some(rho))?,
                truth: Truth::CubeFaces(cube_reference(rho)?),
            });
        }
    }
    if wanted("cornell") {
        cases.push(Case {
            name: "cornell".into(),
            scene: builtin("cornell", None)?,
            truth: Truth::None,
        });
    }
    Ok(cases)
}

/// `convergence.csv` with its header, and the summary table's header on stdout; with no
/// case selected (only the image benchmarks), a sink that leaves an earlier file alone.
fn convergence_csv(path: &std::path::Path, any: bool) -> Result<Box<dyn Write>> {
    if !any {
        return Ok(Box::new(std::io::sink()));
    }
    let mut csv: Box<dyn Write> = Box::new(std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
    ));
    provenance(&mut csv)?;
    writeln!(
        csv,
        "scene,solver,step,seconds,residual,error,elements,patches,matrix_mb"
    )?;
    println!(
        "| scene | solver | elements | patches | steps | seconds | residual | error | s to 1 % | s to 0.1 % | matrix MB | peak RSS MB |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    Ok(csv)
}

/// What one solver's run on one case logged: the CSV rows (one each time the residual
/// falls by 20 %, and the last), the plot's points, and the times from which the error
/// stays below 1 % and 0.1 %.
struct Logged {
    rows: Vec<String>,
    points: Vec<(f64, f64)>,
    to_1: Option<f64>,
    to_01: Option<f64>,
}

/// One solver on one case: its CSV rows, its summary row on stdout, and its plot series;
/// `None` (after a line saying why) where the solver refuses the scene.
fn convergence_run(
    case: &Case,
    label: &str,
    kind: SolverKind,
    overshoot: bool,
    args: &BenchArgs,
    csv: &mut dyn Write,
) -> Result<Option<Series>> {
    let config = SolverConfig {
        shooting: nusselt_core::solver::ShootingOptions {
            overshoot,
            ..Default::default()
        },
        ..Default::default()
    };
    reset_peak();
    let start = Instant::now();
    let problem = Problem::new(case.scene.clone(), config)?;
    let mut solver = match kind.build(problem) {
        Ok(s) => s,
        Err(e) => {
            println!("| {} | {label} | refused: {e} |", case.name);
            return Ok(None);
        }
    };
    let setup = start.elapsed().as_secs_f64();
    let logged = solve_logged(case, label, solver.as_mut(), setup, args.seconds);
    for row in &logged.rows {
        writeln!(csv, "{row}")?;
    }
    print_convergence_row(case, label, solver.as_ref(), start, &logged);
    Ok(Some(Series {
        label: label.to_string(),
        points: logged.points,
        markers: false,
    }))
}

/// Runs `solver` to a residual of 1e-6 or `seconds`, logging as [`Logged`] says; times
/// count from the start of setup (`setup` seconds before the solve).
fn solve_logged(
    case: &Case,
    label: &str,
    solver: &mut dyn Solver,
    setup: f64,
    seconds: f64,
) -> Logged {
    let (mut to_1, mut to_01) = (None, None);
    let stop = StopCriteria {
        residual: 1e-6,
        max_steps: None,
        max_seconds: Some(seconds),
        tolerance: None,
    };
    let mut rows: Vec<String> = Vec::new();
    let (elements, patches) = (
        solver.problem().mesh.elements.len(),
        solver.problem().mesh.patches.len(),
    );
    // Log-spaced rows: one each time the residual falls by 20 %, and the last.
    let mut logged = f64::INFINITY;
    let mut last_row = String::new();
    let mut points = Vec::new();
    let never = AtomicBool::new(false);
    run_solver(solver, &stop, &never, &mut |r, s| {
        let t = setup + r.seconds;
        let err = error(&case.truth, s);
        if r.residual <= 0.8 * logged || r.residual <= stop.residual {
            points.push((t, err.unwrap_or(r.residual)));
        }
        // The time from which the error stays below 1 % (0.1 %): a later step
        // above it (the error crossing zero on its way) resets the time.
        if let Some(e) = err {
            for (limit, at) in [(1e-2, &mut to_1), (1e-3, &mut to_01)] {
                if e > limit {
                    *at = None;
                } else if at.is_none() {
                    *at = Some(t);
                }
            }
        }
        let row = format!(
            "{},{label},{},{t:.6},{:.6e},{},{elements},{patches},{:.3}",
            case.name,
            r.step,
            r.residual,
            err.map(|e| format!("{e:.6e}")).unwrap_or_default(),
            s.matrix_bytes() as f64 / (1 << 20) as f64
        );
        if r.residual <= 0.8 * logged {
            logged = r.residual;
            rows.push(row);
            last_row.clear();
        } else {
            last_row = row;
        }
    });
    if !last_row.is_empty() {
        rows.push(last_row);
    }
    Logged {
        rows,
        points,
        to_1,
        to_01,
    }
}

/// One row of the summary table on stdout.
fn print_convergence_row(
    case: &Case,
    label: &str,
    solver: &dyn Solver,
    start: Instant,
    logged: &Logged,
) {
    let fmt = |x: Option<f64>| x.map(|v| format!("{v:.3}")).unwrap_or("–".into());
    println!(
        "| {} | {label} | {} | {} | {} | {:.3} | {:.1e} | {} | {} | {} | {:.1} | {} |",
        case.name,
        solver.problem().mesh.elements.len(),
        solver.problem().mesh.patches.len(),
        solver.steps(),
        start.elapsed().as_secs_f64(),
        solver.residual(),
        error(&case.truth, solver)
            .map(|e| format!("{e:.1e}"))
            .unwrap_or("–".into()),
        fmt(logged.to_1),
        fmt(logged.to_01),
        solver.matrix_bytes() as f64 / (1 << 20) as f64,
        peak_mb().map(|m| format!("{m:.0}")).unwrap_or("–".into()),
    );
}

/// `convergence-NAME.{svg,png}`: error (residual for the Cornell box) against time.
fn convergence_plots(out: &std::path::Path, plots: Vec<(String, Vec<Series>)>) -> Result<()> {
    for (name, series) in plots {
        let measure = if name.starts_with("cornell") {
            "residual"
        } else {
            "largest relative error"
        };
        plot::write(
            &out.join(format!("convergence-{name}")),
            &Plot {
                title: &format!("{name}: {measure} against time"),
                x_label: "seconds (mesh, form factors, solve)",
                y_label: measure,
                series,
            },
        )?;
    }
    Ok(())
}

/// The benchmarks with their own files (`bench_*.rs`) that `--only` selects, in order.
fn image_benches(args: &BenchArgs, wanted: &dyn Fn(&str) -> bool) -> Result<()> {
    if wanted("tworooms") {
        super::bench_images::ambient(&args.out, args.seconds)?;
    }
    if wanted("hierarchical") {
        super::bench_hierarchical::cornell(&args.out, &args.cornell_reference)?;
    }
    if wanted("large") {
        super::bench_hierarchical::large(
            &args.out,
            &args.cornell_reference,
            &args.gallery_reference,
        )?;
    }
    // Needs a model that is not part of the program: only when asked for.
    if args.only.as_deref().is_some_and(|o| "sponza".contains(o)) {
        super::bench_sponza::sponza(&args.out, &args.sponza)?;
    }
    if args.only.as_deref() == Some("live") {
        super::bench_live::live(
            &args.out,
            &args.live_model,
            Some(args.live_solver.as_str()),
            args.live_seconds,
        )?;
    }
    if wanted("cornell-image") {
        super::bench_cornell::cornell(&args.out, &args.cornell_reference, args.seconds)?;
    }
    if wanted("meshing") {
        super::bench_meshing::meshing(&args.out, &args.cornell_reference)?;
    }
    if wanted("specular") {
        super::bench_specular::specular(&args.out, &args.specular_reference, args.seconds)?;
    }
    if wanted("targets") {
        super::bench_targets::targets(&args.out, &args.cornell_reference)?;
    }
    if wanted("edit") || wanted("cornell") {
        live_edits(&args.out)?;
    }
    Ok(())
}

/// Material edits on a converged Cornell solve (default mesh, shooting with cached rows):
/// seconds until at most 1 % of the edit's power is left unshot.
fn live_edits(out: &std::path::Path) -> Result<()> {
    let scene = builtin("cornell", None)?;
    let find = |name: &str| {
        scene
            .materials
            .iter()
            .position(|m| m.name == name)
            .map(|i| MaterialId(i as u32))
    };
    let (Some(wall), Some(light)) = (find("leftWall").or(find("red")), find("light")) else {
        println!("live edits: the Cornell materials were not found");
        return Ok(());
    };
    let mut s = ProgressiveSolver::new(scene.clone(), SolverConfig::default())?;
    let never = AtomicBool::new(false);
    let converge = StopCriteria {
        residual: 1e-4,
        ..Default::default()
    };
    s.run(&converge, &never, &mut |_| {});
    let path = out.join("live_edits.csv");
    let mut csv = std::fs::File::create(&path)?;
    provenance(&mut csv)?;
    writeln!(csv, "edit,edit_power_fraction,shots,seconds")?;
    println!(
        "\n| live edit (Cornell, default mesh) | edit's power / emitted | shots | seconds to 1 % of it |"
    );
    println!("|---|---:|---:|---:|");
    let edits: [(&str, MaterialId, Option<Rgb>, Option<Rgb>); 2] = [
        (
            "red wall Kd -> 0.2 0.6 0.2",
            wall,
            Some(Rgb::new(0.2, 0.6, 0.2)),
            None,
        ),
        (
            "light Ke x2",
            light,
            None,
            Some(scene.materials[light.0 as usize].emission * 2.0),
        ),
    ];
    for (label, id, kd, ke) in edits {
        let m = &s.scene().materials[id.0 as usize];
        let (kd, ke) = (kd.unwrap_or(m.reflectance), ke.unwrap_or(m.emission));
        let before = s.unshot_fraction();
        s.set_material(id, kd, ke)?;
        let edit = (s.unshot_fraction() - before).abs().max(1e-12);
        let shots0 = s.shots();
        let start = Instant::now();
        let stop = StopCriteria {
            residual: 0.01 * edit,
            ..Default::default()
        };
        s.run(&stop, &never, &mut |_| {});
        let secs = start.elapsed().as_secs_f64();
        writeln!(csv, "{label},{edit:.6e},{},{secs:.4}", s.shots() - shots0)?;
        println!(
            "| {label} | {edit:.3} | {} | {secs:.3} |",
            s.shots() - shots0
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::utc_date;
    use std::time::{Duration, UNIX_EPOCH};

    #[test]
    fn utc_dates() {
        assert_eq!(utc_date(UNIX_EPOCH), "1970-01-01");
        let day = |d: u64| utc_date(UNIX_EPOCH + Duration::from_secs(d * 86_400 + 3_600));
        assert_eq!(day(20_792), "2026-12-05");
        assert_eq!(day(11_016), "2000-02-29");
        assert_eq!(day(11_017), "2000-03-01");
    }
}
