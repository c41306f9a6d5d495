//! `nusselt render`.

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};

use super::method::{MethodArgs, parse_method, raster_for};
use super::pass::{PassChoice, parse_pass, render_chosen};
use super::render_report::{Report, Solved};
use super::{MAX_RAYS, MAX_VIS_RAYS, SceneArgs, ViewArgs, check_count, check_output};
use nusselt_core::formfactor::{FormFactorMethod, FormFactorParams};
use nusselt_core::mesh::MeshSpec;
use nusselt_core::render::{self, Image};
use nusselt_core::scene::Rgb;
use nusselt_core::scene::file::MeshEntry;
use nusselt_core::solver::{
    FormFactorConfig, HierarchicalOptions, HierarchicalSolver, OptionSet, Problem, ShootingOptions,
    Solver, SolverConfig, SolverKind, SolverOption, StopCriteria, run_solver,
};

#[derive(Args, Debug)]
pub struct RenderArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub view: ViewArgs,
    /// Output image: .pfm, .exr (linear) or .png (exposure + sRGB).
    #[arg(long)]
    pub out: PathBuf,
    /// Element edge length in scene units (default: a scene file's `mesh.element_size`, else
    /// from the --max-elements budget).
    #[arg(long, allow_negative_numbers = true)]
    pub element_size: Option<f64>,
    /// Patch (shooter) edge length in scene units (default: 4 element sizes).
    #[arg(long, allow_negative_numbers = true)]
    pub patch_size: Option<f64>,
    /// Element budget that sets the default element size (default 20000; faces smaller
    /// than an element count as one). Ignored with --element-size.
    #[arg(long)]
    pub max_elements: Option<usize>,
    /// Cast every shadow ray for every shooter (no 4-ray probe for non-emitters).
    #[arg(long)]
    pub full_visibility: bool,
    /// Stop when remaining unshot power / emitted power falls to this (default: a scene
    /// file's `solver.unshot`, else 1e-4).
    #[arg(long, allow_negative_numbers = true)]
    pub unshot: Option<f64>,
    /// Shoot only the unshot radiance (no overshooting by the ambient estimate).
    #[arg(long)]
    pub no_overshoot: bool,
    /// Solver: auto (shooting up to 100,000 elements or under --seconds, else
    /// hierarchical; the choice and its reason are printed), shooting (progressive
    /// refinement), jacobi, gauss-seidel, sor, cg (these four store the form-factor matrix;
    /// --unshot is their relative residual), hierarchical or wavelet. Default: a scene
    /// file's `solver.name`, else auto.
    #[arg(long)]
    pub solver: Option<String>,
    /// SOR relaxation factor in (0, 2) (default: estimated from the first sweeps).
    #[arg(long, allow_negative_numbers = true)]
    pub omega: Option<f64>,
    /// Memory budget of the whole run in MiB (default: half of the machine's RAM): the
    /// textures and the mesh (about 1 KiB an element) first, the cached rows, stored matrix
    /// or links in what is left. A mesh or a gathering/CG matrix that would not fit is
    /// refused before any work; adaptive refinement stops where the next pass would not fit.
    #[arg(long)]
    pub max_memory: Option<u64>,
    /// Stop when the estimated remaining relative error of every element falls to this
    /// (shooting: the light the regional ambient term expects, over what the element shows;
    /// gathering and cg: the residual bound max|r|/(1 - ρmax)); elements darker than 1/1000
    /// of the mean radiosity count against that. Checked every 10 % more steps.
    #[arg(long, allow_negative_numbers = true)]
    pub tolerance: Option<f64>,
    /// Display correction while unconverged (shooting): `regional` (the ambient term from
    /// where the unshot light can reach, default) or `global` (the classic uniform term).
    #[arg(long, default_value = "regional")]
    pub ambient: String,
    /// BF refinement threshold of `--solver hierarchical` and `wavelet`, relative to the scene's mean
    /// emitted radiosity: smaller gives more links, a finer answer and a longer solve.
    #[arg(long, allow_negative_numbers = true)]
    pub link_tolerance: Option<f64>,
    /// How the image is made from the solution: `vertex` (radiosity interpolated over the
    /// mesh), `direct` (the lights' direct contribution per pixel with exact form factors
    /// and shadow rays, the indirect rest from the solution; sharper shadows, about 0.5 s more
    /// at 256²), `gather` (direct per pixel plus one bounce gathered from the solution by 64
    /// cosine-weighted rays per pixel: the solution's error averaged over what each point
    /// sees, several seconds more) or `auto` (default): `direct` when its work, counted on
    /// a probe of 1/16 of the pixels, comes to at most 10 s at the reference machine's
    /// rates (the same choice on any machine and under any load), else `vertex`; with
    /// --time-budget (or --seconds) the probe is timed against what is left of it instead.
    #[arg(long, default_value = "auto")]
    pub pass: String,
    /// Seconds the whole run may take (load, mesh, solve, render) for `--pass auto` to choose
    /// the most accurate pass that fits, by the clock (at most --seconds; without either,
    /// `auto` counts work instead). The solve is not cut short by it: --seconds does that.
    #[arg(long, allow_negative_numbers = true)]
    pub time_budget: Option<f64>,
    /// A priori discontinuity meshing: cut the surfaces along the shadow outlines each
    /// light vertex casts through each blocker face before meshing, so element edges follow
    /// the umbra and penumbra boundaries (`crates/core/src/mesh/discontinuity.rs`).
    #[arg(long)]
    pub discontinuity: bool,
    /// Gather rays per pixel of `--pass gather` (shared among the pixel's samples; the
    /// gather's noise falls as 1/√N).
    #[arg(long, default_value_t = nusselt_core::render::gather::GATHER_RAYS_PER_PIXEL)]
    pub gather_rays: u32,
    /// Extra samples in pixels whose first `--spp` samples disagree by more than 10 % of
    /// their mean (silhouettes, shadow and contact edges, where 16 samples misjudge how
    /// much of the pixel each side covers); 0: none
    #[arg(long, default_value_t = nusselt_core::render::DEFAULT_EDGE_SPP)]
    pub edge_spp: u32,
    /// Adaptive meshing: solve, halve the elements of every patch where the radiance varies
    /// across an element by more than this fraction of it (`crates/core/src/mesh/adaptive.rs`), and solve
    /// again on the refined mesh; `--adaptive-passes` times (default 2), each to
    /// `--unshot` (at least 1e-3).
    #[arg(long, allow_negative_numbers = true)]
    pub adaptive: Option<f64>,
    #[arg(long, default_value_t = 2)]
    pub adaptive_passes: u8,
    /// Stop after this many shots.
    #[arg(long)]
    pub shots: Option<usize>,
    /// Seconds the whole command may take: loading, meshing, the solve and the render end
    /// within them (the solve stops at 85 % of them, less what loading and meshing took,
    /// cancelling a step still running then; `--pass auto` picks a pass that fits in the
    /// rest). What was cut is printed.
    #[arg(long, allow_negative_numbers = true)]
    pub seconds: Option<f64>,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Form-factor method: contour, exact, hemicube, raycast, montecarlo, hybrid or
    /// gpu-hemicube (default: a scene file's `solver.formfactor`, else contour).
    #[arg(long)]
    pub formfactor: Option<String>,
    /// Shadow rays per receiver-patch visibility estimate (montecarlo: point pairs per
    /// element).
    #[arg(long, default_value_t = 16)]
    pub vis_rays: u32,
    /// Rays per shot for --formfactor raycast (at most 2^26).
    #[arg(long, default_value_t = 1 << 16)]
    pub rays: u32,
    #[command(flatten)]
    pub method_args: MethodArgs,
    /// Leave out the ambient term (shown by default while unconverged).
    #[arg(long)]
    pub no_ambient: bool,
    /// PNG exposure multiplier (default 1, or, when the image is nearly black or white at 1
    /// — lights weak or strong for the scene's size — the power of √2 that shows it, printed).
    #[arg(long, allow_negative_numbers = true)]
    pub exposure: Option<f64>,
    /// Reference image (PFM) to measure the image error against.
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Convergence log: one CSV row per shot.
    #[arg(long)]
    pub log: Option<PathBuf>,
    /// One CSV row per element: patch, area, centroid, radiance.
    #[arg(long)]
    pub elements_csv: Option<PathBuf>,
    /// Also write the solved mesh, lit, as glTF 2.0: `.glb` (binary) or `.gltf` (JSON,
    /// buffer embedded). Vertex colours are the radiance at --exposure; README "Export to glTF".
    #[arg(long)]
    pub export_gltf: Option<PathBuf>,
    /// One JSON summary line on stdout.
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

pub(super) fn bar(quiet: bool, len: u64, template: &str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    if let Ok(style) = ProgressStyle::with_template(template) {
        pb.set_style(style);
    }
    pb
}

fn create(path: &PathBuf) -> Result<std::io::BufWriter<std::fs::File>> {
    let f =
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    Ok(std::io::BufWriter::new(f))
}

/// The output checks shared by `render` and `reference`, made before any work: an image
/// extension `Image::save` writes, in a folder that exists.
pub(super) fn check_image_out(out: &std::path::Path) -> Result<()> {
    render::image::check_extension(out).context("--out")?;
    check_output("--out", out)
}

/// `nusselt render`. A panic anywhere in loading, meshing, solving or rendering (a bug:
/// nothing should panic) becomes an error naming the scene instead of an abort.
pub fn run_render(args: &RenderArgs) -> Result<()> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| render(args))).unwrap_or_else(
        |panic| {
            Err(anyhow!(
                "internal error while solving {}: {} (please report it with the model)",
                args.scene.describe(),
                super::panic_message(&panic)
            ))
        },
    )
}

/// The solver options the flags set (each read by some solvers only).
fn options_given(args: &RenderArgs) -> OptionSet {
    let mut given = OptionSet::default();
    for (set, option) in [
        (args.formfactor.is_some(), SolverOption::FormFactor),
        (args.no_overshoot, SolverOption::Overshoot),
        (args.ambient != "regional", SolverOption::Ambient),
        (args.omega.is_some(), SolverOption::Omega),
        (args.link_tolerance.is_some(), SolverOption::LinkTolerance),
    ] {
        if set {
            given.insert(option);
        }
    }
    given
}

/// The whole command: flags, scene, solve, image, outputs, in that order; each phase is a
/// function below.
fn render(args: &RenderArgs) -> Result<()> {
    let process_start = Instant::now();
    let plan = check_flags(args)?;
    let scene = args.scene.load()?;
    let load_seconds = process_start.elapsed().as_secs_f64();
    if args.edge_spp > super::MAX_SPP {
        bail!(
            "--edge-spp must be at most {}, got {}",
            super::MAX_SPP,
            args.edge_spp
        );
    }
    let settings = nusselt_core::render::RenderSettings {
        edge_spp: args.edge_spp,
        ..args.view.settings(&scene, args.seed)?
    };
    // Read the reference first so a bad path fails before the work.
    let reference = match &args.reference {
        Some(p) => Some(Image::load_pfm(p)?),
        None => None,
    };
    let config = solver_config(args, &plan)?;
    let adapter = config.formfactor.raster.as_ref().map(|r| r.describe());
    let solve_start = Instant::now();
    let problem = Problem::new(scene, config)?;
    let (mut solver, auto_reason) = solver_for(args, &plan, problem)?;
    if !args.quiet && !args.json {
        print_mesh(solver.problem());
    }
    let stop = StopCriteria {
        residual: plan.unshot,
        max_steps: args.shots,
        max_seconds: args
            .seconds
            .map(|s| solve_seconds_within(s, process_start.elapsed().as_secs_f64())),
        tolerance: args.tolerance,
    };
    solve(args, solver.as_mut(), &stop)?;
    let solve_seconds = solve_start.elapsed().as_secs_f64();
    let (problem, solved) = Solved::take(solver, args.no_ambient);

    let render_start = Instant::now();
    let (chosen, image) = render_chosen(
        plan.pass_choice,
        process_start,
        &problem,
        &solved.radiance,
        &settings,
        args.gather_rays,
    );
    let render_seconds = render_start.elapsed().as_secs_f64();
    let exposure = exposure_for(args, &image);
    image.save(&args.out, exposure)?;
    let error = match &reference {
        Some(r) => {
            let mask = render::error_mask(
                &problem.scene,
                &settings.camera,
                settings.width,
                settings.height,
            );
            Some(render::relative_rms(&image, r, &mask)?)
        }
        None => None,
    };
    if let Some(p) = &args.elements_csv {
        write_elements_csv(p, &problem, &solved.radiance)?;
    }
    let report = Report {
        problem: &problem,
        solved: &solved,
        camera: &settings.camera,
        auto_reason,
        chosen: &chosen,
        method: plan.method,
        adapter,
        load_seconds,
        solve_seconds,
        render_seconds,
        exposure,
        total_seconds: process_start.elapsed().as_secs_f64(),
        error,
    };
    if args.json {
        println!("{}", report.summary());
    } else if !args.quiet {
        let before_solve = solve_start.duration_since(process_start).as_secs_f64();
        report.print(args, &stop, before_solve);
    }
    if let Some(p) = &args.export_gltf {
        super::export::export_gltf(&problem, &solved.radiance, p, exposure, args.quiet)?;
    }
    Ok(())
}

/// What the flags ask for, checked before the scene is read.
struct Plan {
    /// The residual to solve to.
    unshot: f64,
    /// `None`: auto, chosen once the mesh is known (solver::auto).
    asked: Option<SolverKind>,
    given: OptionSet,
    method: FormFactorMethod,
    pass_choice: PassChoice,
    regional_ambient: bool,
    patch_size: Option<f64>,
    max_elements: Option<usize>,
    file_mesh: MeshEntry,
}

/// Every flag, before any work: a typo must not cost a scene load or a solve. A scene
/// file's mesh and solver settings are defaults; flags given win.
fn check_flags(args: &RenderArgs) -> Result<Plan> {
    check_image_out(&args.out)?;
    if let Some(p) = &args.export_gltf {
        super::export::check_gltf_out(p)?;
    }
    for (flag, path) in [("--log", &args.log), ("--elements-csv", &args.elements_csv)] {
        if let Some(p) = path {
            check_output(flag, p)?;
        }
    }
    // A scene file's mesh and solver settings are defaults; flags given win.
    let (file_mesh, file_solver) = args.scene.file_settings()?;
    let unshot = args.unshot.or(file_solver.unshot).unwrap_or(1e-4);
    let solver_name = args.solver.as_deref().or(file_solver.name.as_deref());
    let solver_name = solver_name.unwrap_or("auto");
    let formfactor = args
        .formfactor
        .as_deref()
        .or(file_solver.formfactor.as_deref());
    let formfactor = formfactor.unwrap_or("contour");
    let patch_size = args.patch_size.or(file_mesh.patch_size);
    let max_elements = args.max_elements.or(file_mesh.max_elements);
    if !(unshot.is_finite() && unshot >= 0.0) {
        bail!("--unshot must be a number >= 0");
    }
    if args.seconds.is_some_and(|s| !(s.is_finite() && s >= 0.0)) {
        bail!("--seconds must be a number >= 0");
    }
    // Told a whole-command time, the pass must fit in it too.
    let pass_choice = parse_pass(&args.pass, args.time_budget)?.within(args.seconds);
    if args.gather_rays == 0 || args.gather_rays > 65536 {
        bail!("--gather-rays must be between 1 and 65536");
    }
    if args.adaptive.is_some_and(|t| !(t.is_finite() && t > 0.0)) {
        bail!("--adaptive must be a positive number (a fraction, e.g. 0.1)");
    }
    if args.adaptive_passes > 4 {
        bail!("--adaptive-passes must be at most 4 (each halves the elements again)");
    }
    if args.tolerance.is_some_and(|t| !(t.is_finite() && t > 0.0)) {
        bail!("--tolerance must be a positive number");
    }
    let regional_ambient = match args.ambient.as_str() {
        "regional" => true,
        "global" => false,
        other => bail!("unknown --ambient '{other}' (expected regional or global)"),
    };
    // `None`: auto, chosen once the mesh is known (solver::auto).
    let asked = match solver_name {
        "auto" => None,
        name => Some(SolverKind::parse(name, args.omega).ok_or_else(|| {
            anyhow::anyhow!(
                "unknown --solver '{name}' (expected auto or one of: {})",
                SolverKind::names_joined()
            )
        })?),
    };
    if let Some(t) = args.link_tolerance
        && !(t.is_finite() && t > 0.0)
    {
        bail!("--link-tolerance must be a positive number, got {t}");
    }
    // A setting the solver would ignore is refused (auto: chooses a solver that reads it).
    let given = options_given(args);
    match asked {
        Some(kind) => kind.refuse_unread(given),
        None => nusselt_core::solver::auto::check_given(given),
    }
    .map_err(anyhow::Error::msg)?;
    if let Some(p) = patch_size
        && !(p.is_finite() && p > 0.0)
    {
        bail!("--patch-size must be a positive number, got {p}");
    }
    check_count("--vis-rays", args.vis_rays, MAX_VIS_RAYS)?;
    if args.exposure.is_some_and(|e| !(e.is_finite() && e > 0.0)) {
        bail!("--exposure must be a positive number");
    }
    let method = parse_method("--formfactor", formfactor)?;
    check_count("--rays", args.rays, MAX_RAYS)?;
    if max_elements == Some(0) {
        bail!("--max-elements must be at least 1");
    }
    args.method_args.check()?;
    Ok(Plan {
        unshot,
        asked,
        given,
        method,
        pass_choice,
        regional_ambient,
        patch_size,
        max_elements,
        file_mesh,
    })
}

/// The solve's settings from the flags and the scene file.
fn solver_config(args: &RenderArgs, plan: &Plan) -> Result<SolverConfig> {
    let method = plan.method;
    Ok(SolverConfig {
        mesh: MeshSpec {
            element_size: args.element_size.or(plan.file_mesh.element_size),
            patch_size: plan.patch_size,
            max_elements: plan.max_elements,
            discontinuity: args.discontinuity || plan.file_mesh.discontinuity,
        },
        memory_bytes: max_memory_bytes(args.max_memory)?,
        formfactor: FormFactorConfig {
            method,
            params: FormFactorParams {
                visibility_rays: args.vis_rays,
                probe_visibility: !args.full_visibility,
                seed: args.seed,
                rays: args.rays,
                ..args.method_args.params()
            },
            raster: raster_for(method)?,
        },
        shooting: ShootingOptions {
            overshoot: !args.no_overshoot,
            regional_ambient: plan.regional_ambient,
        },
        hierarchical: HierarchicalOptions {
            link_tolerance: args
                .link_tolerance
                .unwrap_or(nusselt_core::solver::DEFAULT_LINK_TOLERANCE),
        },
    })
}

/// The solver asked for, or auto's choice (printed), on `problem`; with `--adaptive`
/// solved and refined already. The second value is auto's reason, if auto chose.
fn solver_for(
    args: &RenderArgs,
    plan: &Plan,
    problem: Problem,
) -> Result<(Box<dyn Solver>, Option<String>)> {
    let (asked, unshot) = (plan.asked, plan.unshot);
    let run = nusselt_core::solver::auto::RunShape {
        progressive_image: args.seconds.is_some(),
        given: plan.given,
    };
    let (kind, mut auto_reason) = match asked {
        Some(kind) => (kind, None),
        None => {
            let (kind, why) = nusselt_core::solver::auto::choose(&problem, run);
            if !args.quiet && !args.json {
                eprintln!("--solver auto: {why}");
            }
            (kind, Some(why))
        }
    };
    let solver = match args.adaptive {
        Some(tolerance) => {
            if !args.quiet && !args.json {
                eprintln!(
                    "--adaptive {tolerance}: {} passes, each solved to a residual of {:.0e} on {} elements and refined",
                    args.adaptive_passes,
                    unshot.max(1e-3),
                    problem.mesh.elements.len()
                );
            }
            let choice = match asked {
                Some(kind) => kind.into(),
                None => nusselt_core::solver::refine::Choice::Auto(run),
            };
            let refined = nusselt_core::solver::refine::refine_adaptively(
                problem,
                choice,
                tolerance,
                args.adaptive_passes,
                unshot,
                &std::sync::atomic::AtomicBool::new(false),
            )?;
            if let Some(why) = &refined.stopped {
                eprintln!("note: {why}");
            }
            for why in &refined.switched {
                if !args.quiet && !args.json {
                    eprintln!("--solver auto: {why}");
                }
                auto_reason = Some(why.clone());
            }
            refined.solver
        }
        // Auto's hierarchy from dark shoots a light of few patches first (its direct light
        // from rows, not links: `hierarchical::direct`).
        None if asked.is_none() && kind == SolverKind::Hierarchical => {
            Box::new(HierarchicalSolver::lights_by_rows(problem))
        }
        None => kind.build(problem)?,
    };
    Ok((solver, auto_reason))
}

/// One line on the mesh: faces, elements, patches and their sizes.
fn print_mesh(problem: &Problem) {
    let m = &problem.mesh;
    eprintln!(
        "meshed {} faces: {} elements (size {:.4}), {} patches (size {:.4}; {} surfaces merged, {} clusters)",
        problem.scene.faces.len(),
        m.elements.len(),
        m.element_size,
        m.patches.len(),
        m.patch_size,
        m.surface_count,
        m.cluster_count
    );
}

/// Runs `solver` to `stop` with a progress bar and the `--log` CSV.
fn solve(args: &RenderArgs, solver: &mut dyn Solver, stop: &StopCriteria) -> Result<()> {
    let pb = bar(
        args.quiet,
        1000,
        "solving {bar:40} unshot {msg} [{elapsed}]",
    );
    let mut log = match &args.log {
        Some(p) => {
            let mut w = create(p)?;
            writeln!(w, "shot,seconds,unshot_fraction,ambient")?;
            Some(w)
        }
        None => None,
    };
    let mut log_error: Option<std::io::Error> = None;
    let initial = solver.residual().max(1e-300);
    with_deadline(stop.max_seconds, |cancel| {
        run_solver(solver, stop, cancel, &mut |r, s| {
            if let Some(w) = log.as_mut()
                && let Err(e) = writeln!(
                    w,
                    "{},{:.6},{:.6e},{:.6e}",
                    r.step,
                    r.seconds,
                    r.residual,
                    nusselt_core::solver::ambient_mean(s)
                )
            {
                log_error.get_or_insert(e);
            }
            // Progress on a log scale from the start to the target.
            let target = stop.residual.max(1e-12);
            let frac =
                ((initial / r.residual.max(1e-300)).ln() / (initial / target).ln()).clamp(0.0, 1.0);
            pb.set_position((frac * 1000.0) as u64);
            pb.set_message(format!("{:.2e} step {}", r.residual, r.step));
        })
    });
    pb.finish_and_clear();
    if let Some(e) = log_error {
        return Err(e).context("writing the convergence log");
    }
    if let Some(mut w) = log {
        w.flush()?;
    }
    Ok(())
}

/// Exposure of the PNG and glTF colours: `--exposure`, or the power of √2 that shows an
/// image nearly black or white at 1 (said on stderr).
fn exposure_for(args: &RenderArgs, image: &Image) -> f64 {
    match args.exposure {
        Some(e) => e,
        None => {
            let stops =
                render::image::auto_exposure_stops(render::image::luminance(image)).unwrap_or(0.0);
            if stops != 0.0 && !args.quiet && !args.json {
                let (look, lights) = if stops > 0.0 {
                    ("black", "weak")
                } else {
                    ("white", "strong")
                };
                eprintln!(
                    "the image is nearly {look} at exposure 1 (lights {lights} for the scene's size): PNG and glTF colours at exposure {:.4} ({stops:+} stops; --exposure to choose)",
                    stops.exp2()
                );
            }
            stops.exp2()
        }
    }
}

/// `--elements-csv`: one row per element (patch, area, centroid, radiance).
fn write_elements_csv(path: &PathBuf, problem: &Problem, radiance: &[Rgb]) -> Result<()> {
    let mut w = create(path)?;
    writeln!(w, "patch,area,cx,cy,cz,r,g,b")?;
    for (e, b) in problem.mesh.elements.iter().zip(radiance) {
        let patch = problem.mesh.patch(e.patch);
        let c = e.centroid;
        writeln!(
            w,
            "{},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e}",
            patch.source_face, e.area, c.x, c.y, c.z, b.x, b.y, b.z
        )?;
    }
    w.flush()?;
    Ok(())
}

/// Runs `work` with a flag that is set `seconds` after the start (never without), so that
/// a solver step longer than what is left (a hierarchical refinement of the atrium takes
/// 20–30 s) is cancelled at the deadline instead of running past it; a cancelled step
/// leaves the solution of the last whole one.
fn with_deadline<T>(seconds: Option<f64>, work: impl FnOnce(&AtomicBool) -> T) -> T {
    let cancel = AtomicBool::new(false);
    let Some(seconds) = seconds else {
        return work(&cancel);
    };
    let (done, wait) = std::sync::mpsc::sync_channel::<()>(0);
    std::thread::scope(|scope| {
        let cancel = &cancel;
        scope.spawn(move || {
            let limit = std::time::Duration::from_secs_f64(seconds.clamp(0.0, 1e9));
            if let Err(std::sync::mpsc::RecvTimeoutError::Timeout) = wait.recv_timeout(limit) {
                cancel.store(true, std::sync::atomic::Ordering::Relaxed);
            }
        });
        let out = work(cancel);
        drop(done);
        out
    })
}

/// Share of `--seconds` kept for the render after the solve (the vertex pass of a
/// 263 k-triangle atrium at 256²: 2 s, 7 % of 30 s).
const RENDER_SHARE: f64 = 0.15;

/// Seconds the solve may run when the whole command has `total` and `elapsed` are gone
/// (loading and meshing): what is left less [`RENDER_SHARE`] of the total for the render.
fn solve_seconds_within(total: f64, elapsed: f64) -> f64 {
    (total * (1.0 - RENDER_SHARE) - elapsed).max(0.0)
}

/// `--max-memory` in bytes, or [`nusselt_core::budget::default_bytes`].
pub(super) fn max_memory_bytes(mib: Option<u64>) -> Result<usize> {
    match mib {
        Some(0) => bail!("--max-memory must be at least 1 (MiB)"),
        Some(m) => Ok(usize::try_from(m.saturating_mul(1 << 20)).unwrap_or(usize::MAX)),
        None => Ok(nusselt_core::budget::default_bytes()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::Ordering;

    /// The flag is set once the deadline passes (a step that waits on it ends), and never
    /// without a deadline; the work's value comes back either way.
    #[test]
    fn a_deadline_cancels_the_work_in_progress() {
        let waited = with_deadline(Some(0.05), |cancel| {
            // Bounded, so that a flag never set fails the test instead of hanging it.
            (0..20_000)
                .take_while(|_| {
                    std::thread::sleep(std::time::Duration::from_millis(1));
                    !cancel.load(Ordering::Relaxed)
                })
                .count()
        });
        assert!(waited < 20_000, "the flag was never set");
        let unset = with_deadline(None, |cancel| {
            std::thread::sleep(std::time::Duration::from_millis(20));
            cancel.load(Ordering::Relaxed)
        });
        assert!(!unset);
        // Work that ends first does not wait for the deadline.
        assert_eq!(with_deadline(Some(1e6), |_| 7), 7);
    }
}
