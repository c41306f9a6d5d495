//! `nusselt view`: the live viewer, and its scripted runs (screenshots, frame logs).

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use clap::Args;

use super::SceneArgs;
use nusselt_core::formfactor::FormFactorMethod;
use nusselt_core::solver::{OptionSet, SolverKind, SolverOption};
use nusselt_viewer::teach::TeachView;
use nusselt_viewer::{
    Automation, EditSpec, ScreenshotPlan, ScreenshotWhen, UiOptions, ViewerOptions,
};

#[derive(Args, Debug, Clone)]
pub struct ViewCmdArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Element edge length (scene units); default a scene file's `mesh.element_size`, else
    /// 1/80 of the scene's diagonal.
    #[arg(long)]
    pub element_size: Option<f64>,
    /// Teaching mode: open the Teach panel on this view: step (one shot per click with its
    /// numbers), hemicube (the hemicube at the shooter), nusselt (the Nusselt analogue),
    /// matrix (the form-factor matrix), compare (shooting vs gathering side by side), mesh
    /// (uniform vs adaptive meshing). The solver starts paused; with --after-shots N step
    /// mode takes N single steps and compare N steps of each method.
    #[arg(long)]
    pub teach: Option<String>,
    /// With --teach: projector mode (large text, light theme; a toggle in the Teach panel).
    #[arg(long, requires = "teach")]
    pub projector: bool,
    /// Form-factor method (contour, exact, hemicube, raycast, montecarlo, hybrid, gpu-hemicube).
    #[arg(long = "formfactor", alias = "method")]
    pub method: Option<String>,
    /// Solver: auto (shooting, whose image improves with every shot), shooting, jacobi,
    /// gauss-seidel, sor, cg, hierarchical or wavelet, as in `nusselt render` (default: a
    /// scene file's `solver.name`, else auto); the panel switches it later.
    #[arg(long)]
    pub solver: Option<String>,
    /// SOR relaxation factor in (0, 2) (default: estimated from the first sweeps); only
    /// with --solver sor.
    #[arg(long, allow_negative_numbers = true)]
    pub omega: Option<f64>,
    /// Window size in points, WxH.
    #[arg(long, default_value = "1280x800")]
    pub window: String,
    /// Save a screenshot of the whole window to this PNG, then exit.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Screenshot after this many steps (shots; for a gathering solver, matrix rows and
    /// then sweeps); the solver stops there.
    #[arg(long, requires = "screenshot", conflicts_with_all = ["after_seconds", "after_converged"])]
    pub after_shots: Option<usize>,
    /// Screenshot this many seconds after the window opened.
    #[arg(long, requires = "screenshot", conflicts_with = "after_converged")]
    pub after_seconds: Option<f64>,
    /// Screenshot once converged (the default).
    #[arg(long, requires = "screenshot")]
    pub after_converged: bool,
    /// Give up on the screenshot after this many seconds (exit status 1; at most 86400).
    #[arg(long, default_value_t = 600.0)]
    pub screenshot_timeout: f64,
    /// With --screenshot, also save the viewport alone as PNG (the viewport export).
    #[arg(long, requires = "screenshot")]
    pub viewport_png: Option<PathBuf>,
    /// With --screenshot, also export the solution as PLY.
    #[arg(long, requires = "screenshot")]
    pub export_ply: Option<PathBuf>,
    /// Draw the element wireframe.
    #[arg(long)]
    pub wireframe: bool,
    /// Draw patch outlines.
    #[arg(long)]
    pub patch_outlines: bool,
    /// Start with the ambient term off.
    #[arg(long)]
    pub no_ambient: bool,
    /// Start with the diffuse maps off: each element in its texture's mean colour, the
    /// solution as radiosity computes it ("textures" in the Display section).
    #[arg(long)]
    pub no_textures: bool,
    /// Don't highlight the shooting patch.
    #[arg(long)]
    pub no_highlight: bool,
    /// Start with the ray-traced view on (the second pass: direct light per pixel, the
    /// indirect rest from the solution, refined progressively; a toggle in the Display
    /// section). With --screenshot, the shot waits for 16 samples per pixel.
    #[arg(long)]
    pub ray_traced: bool,
    /// Refine the mesh adaptively while solving (as `render --adaptive`): where the radiance
    /// varies across an element by more than this fraction, refine and solve again, until
    /// nothing does (three levels at most; "Refine adaptively" in the solver panel). With
    /// --wireframe the mesh is seen growing.
    #[arg(long)]
    pub adaptive: Option<f64>,
    /// A priori discontinuity meshing (as `render --discontinuity`): the lights' shadow
    /// outlines are cut into the surfaces before meshing, so element edges follow the
    /// umbra and penumbra boundaries (see them with --wireframe).
    #[arg(long)]
    pub discontinuity: bool,
    /// Exposure in stops.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// Start paused.
    #[arg(long)]
    pub paused: bool,
    /// Present frames without waiting for vertical sync.
    #[arg(long)]
    pub no_vsync: bool,
    /// Threads computing form factors; default one per core (`available_parallelism`, at
    /// least 1), as the viewer's shot pool does (docs/VIEWER.md measured it).
    #[arg(long)]
    pub solver_threads: Option<usize>,
    /// Memory budget of the run in MiB (default: half of the machine's RAM), as for
    /// `render --max-memory`: a mesh or re-mesh that would not fit is refused (the scene on
    /// screen stays), caches get what the mesh leaves.
    #[arg(long)]
    pub max_memory: Option<u64>,
    /// Material edit, as in the edit panel: TARGET:kd=r,g,b[:ke=r,g,b], TARGET a material
    /// name or #PATCH (which is also selected). Repeatable.
    #[arg(long)]
    pub edit: Vec<String>,
    /// Send the --edit edits once this many shots are on screen.
    #[arg(long, default_value_t = 0)]
    pub edit_after_shots: usize,
    /// Select this patch at start.
    #[arg(long)]
    pub select: Option<u32>,
    /// Write per-frame timings (CSV) and the latency summary to this file at exit.
    #[arg(long)]
    pub frame_log: Option<PathBuf>,
}

impl ViewCmdArgs {
    /// The viewer's command line with no arguments: the built-in Cornell box.
    pub fn cornell() -> ViewCmdArgs {
        use clap::Parser;
        #[derive(clap::Parser)]
        struct Only {
            #[command(flatten)]
            args: ViewCmdArgs,
        }
        Only::parse_from(["nusselt", "--builtin", "cornell"]).args
    }
}

/// Longest `--screenshot-timeout` and `--after-seconds`: a day.
const MAX_WAIT_SECONDS: f64 = 86_400.0;

fn parse_window(text: &str) -> Result<[f32; 2]> {
    let (w, h) = text
        .split_once(['x', 'X'])
        .with_context(|| format!("--window '{text}': expected WxH, e.g. 1280x800"))?;
    let parse = |s: &str| -> Result<f32> {
        let v: u32 = s
            .trim()
            .parse()
            .with_context(|| format!("--window '{text}': '{s}' is not a whole number"))?;
        if !(64..=8192).contains(&v) {
            bail!("--window '{text}': sizes must be in 64..=8192");
        }
        Ok(v as f32)
    };
    Ok([parse(w)?, parse(h)?])
}

/// Why `--solver auto` is shooting in the viewer (`nusselt_core::solver::auto`), and when
/// it hands over (`nusselt_core::solver::handoff`).
fn viewer_auto_reason() -> String {
    use nusselt_core::solver::{auto, handoff};
    format!(
        "shooting: the viewer shows the solution while it converges, and shooting improves it with every shot; on a scene of more than {} elements (or {:.0e} patch × element pairs) hierarchical radiosity goes on once {:.0} % of the light is left unshot, as there each shot costs a row to every element",
        auto::HIERARCHICAL_FROM_ELEMENTS,
        auto::HIERARCHICAL_FROM_PAIRS,
        100.0 * handoff::HANDOFF_UNSHOT
    )
}

/// `--solver NAME [--omega W]`: ω only with sor, and in (0, 2); `--formfactor` (given when
/// `formfactor`) only with a solver that computes rows.
fn parse_solver(name: &str, omega: Option<f64>, formfactor: bool) -> Result<SolverKind> {
    if name == "auto" {
        // What `auto` stands for in the viewer (solver::auto): an image is wanted while
        // solving, whatever the scene's size.
        return parse_solver("shooting", omega, formfactor);
    }
    let kind = SolverKind::parse(name, omega).with_context(|| {
        format!(
            "unknown --solver '{name}' (expected auto or one of: {})",
            SolverKind::names_joined()
        )
    })?;
    let mut given = OptionSet::default();
    if omega.is_some() {
        given.insert(SolverOption::Omega);
    }
    if formfactor {
        given.insert(SolverOption::FormFactor);
    }
    kind.refuse_unread(given).map_err(anyhow::Error::msg)?;
    if let Some(w) = omega
        && !(w.is_finite() && w > 0.0 && w < 2.0)
    {
        bail!("--omega must be in (0, 2), got {w}");
    }
    Ok(kind)
}

pub fn run(args: &ViewCmdArgs) -> Result<()> {
    let mut scene_args = args.scene.clone();
    if scene_args.scene.is_none() && scene_args.builtin.is_none() {
        scene_args.builtin = Some("cornell".into());
    }
    // A scene file's mesh and solver settings are defaults; flags given win.
    let (file_mesh, file_solver) = scene_args.file_settings()?;
    let element_size = args.element_size.or(file_mesh.element_size);
    check_mesh_flags(element_size, args.adaptive)?;
    let method = match args.method.as_ref().or(file_solver.formfactor.as_ref()) {
        Some(m) => super::method::parse_method("--formfactor", m)?,
        None => FormFactorMethod::Contour,
    };
    let solver_name = args.solver.as_ref().or(file_solver.name.as_ref());
    let solver_name = solver_name.map_or("auto", String::as_str);
    let solver = parse_solver(solver_name, args.omega, args.method.is_some())?;
    let teach = args.teach.as_deref().map(parse_teach).transpose()?;
    let window = parse_window(&args.window)?;
    let automation = parse_automation(args)?;
    check_run_flags(args)?;
    let memory_bytes = super::render::max_memory_bytes(args.max_memory)?;
    // The flags are checked: now the work.
    let scene = scene_args.load()?;
    nusselt_viewer::run(ViewerOptions {
        scene,
        ui: UiOptions {
            element_size,
            patch_size: file_mesh.patch_size,
            max_elements: file_mesh.max_elements,
            stop_unshot: file_solver.unshot,
            method,
            solver,
            solver_reason: (solver_name == "auto").then(viewer_auto_reason),
            solver_auto: solver_name == "auto",
            teach,
            projector: args.projector,
            raster: super::method::raster_for(method)?,
            window,
            wireframe: args.wireframe,
            patch_outlines: args.patch_outlines,
            ambient: !args.no_ambient,
            exposure_stops: args.exposure,
            highlight_shooter: !args.no_highlight,
            ray_traced: args.ray_traced,
            textures: !args.no_textures,
            adaptive: args.adaptive,
            discontinuity: args.discontinuity || file_mesh.discontinuity,
            paused: args.paused,
            no_vsync: args.no_vsync,
            solver_threads: args.solver_threads,
            memory_bytes,
            automation,
        },
    })?;
    Ok(())
}

/// `--element-size` and `--adaptive`, when given, are positive numbers.
fn check_mesh_flags(element_size: Option<f64>, adaptive: Option<f64>) -> Result<()> {
    if let Some(s) = element_size
        && !(s.is_finite() && s > 0.0)
    {
        bail!("--element-size must be a positive number, got {s}");
    }
    if let Some(t) = adaptive
        && !(t.is_finite() && t > 0.0)
    {
        bail!("--adaptive must be a positive number (a fraction, e.g. 0.25), got {t}");
    }
    Ok(())
}

/// The teaching view `--teach` names.
fn parse_teach(name: &str) -> Result<TeachView> {
    TeachView::parse(name).with_context(|| {
        format!(
            "unknown --teach '{name}' (the views: {})",
            TeachView::NAMES.join(", ")
        )
    })
}

/// What the viewer does by itself (`--edit`, `--screenshot` and when, `--frame-log`, ...),
/// from checked flags.
fn parse_automation(args: &ViewCmdArgs) -> Result<Automation> {
    let edits = args
        .edit
        .iter()
        .map(|e| EditSpec::parse(e).map_err(|m| anyhow::anyhow!("--edit {m}")))
        .collect::<Result<Vec<_>>>()?;
    let when = match (args.after_shots, args.after_seconds) {
        (Some(n), _) => ScreenshotWhen::Shots(n),
        (None, Some(s)) => {
            if !(s.is_finite() && (0.0..=MAX_WAIT_SECONDS).contains(&s)) {
                bail!("--after-seconds must be in 0..={MAX_WAIT_SECONDS}, got {s}");
            }
            ScreenshotWhen::Seconds(s)
        }
        (None, None) => ScreenshotWhen::Converged,
    };
    let t = args.screenshot_timeout;
    // Bounded: Duration::from_secs_f64 panics on values past u64 seconds (1e20).
    let timeout = Duration::try_from_secs_f64(t)
        .ok()
        .filter(|_| t > 0.0 && t <= MAX_WAIT_SECONDS)
        .with_context(|| {
            format!("--screenshot-timeout must be a number of seconds in (0, {MAX_WAIT_SECONDS}], got {t}")
        })?;
    Ok(Automation {
        screenshot: args.screenshot.clone().map(|path| ScreenshotPlan {
            path,
            when,
            timeout,
        }),
        frame_log: args.frame_log.clone(),
        edits,
        edit_after_shots: args.edit_after_shots,
        select: args.select,
        viewport_png: args.viewport_png.clone(),
        export_ply: args.export_ply.clone(),
    })
}

/// `--solver-threads`, `--exposure` and the output paths.
fn check_run_flags(args: &ViewCmdArgs) -> Result<()> {
    if args.solver_threads == Some(0) {
        bail!("--solver-threads must be at least 1");
    }
    if !args.exposure.is_finite() {
        bail!("--exposure must be a finite number of stops");
    }
    for (flag, path) in [
        ("--screenshot", &args.screenshot),
        ("--viewport-png", &args.viewport_png),
        ("--export-ply", &args.export_ply),
        ("--frame-log", &args.frame_log),
    ] {
        if let Some(p) = path {
            super::check_output(flag, p)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_sizes() {
        assert_eq!(parse_window("800x600").expect("ok"), [800.0, 600.0]);
        assert!(parse_window("800").is_err());
        assert!(parse_window("0x600").is_err());
        assert!(parse_window("axb").is_err());
    }

    #[test]
    fn solver_names_and_omega() {
        assert_eq!(
            parse_solver("shooting", None, false).expect("ok"),
            SolverKind::Shooting
        );
        assert_eq!(
            parse_solver("gauss-seidel", None, false).expect("ok"),
            SolverKind::GaussSeidel
        );
        assert_eq!(
            parse_solver("sor", Some(1.5), false).expect("ok"),
            SolverKind::Sor(Some(1.5))
        );
        assert_eq!(
            parse_solver("sor", None, false).expect("ok"),
            SolverKind::Sor(None)
        );
        let e = parse_solver("jacobi", Some(1.5), false).expect_err("omega without sor");
        assert!(e.to_string().contains("--omega"), "{e}");
        assert!(e.to_string().contains("jacobi"), "{e}");
        for bad in [0.0, 2.0, -1.0, f64::NAN] {
            let e = parse_solver("sor", Some(bad), false).expect_err("omega out of range");
            assert!(e.to_string().contains("(0, 2)"), "{bad}: {e}");
        }
        let e = parse_solver("newton", None, false).expect_err("unknown");
        assert!(e.to_string().contains("gauss-seidel"), "{e}");
        let e = parse_solver("hierarchical", None, true).expect_err("no rows");
        assert!(e.to_string().contains("--formfactor"), "{e}");
        assert!(parse_solver("cg", None, true).is_ok());
    }

    #[test]
    fn no_arguments_is_the_cornell_box() {
        let a = ViewCmdArgs::cornell();
        assert_eq!(a.scene.builtin.as_deref(), Some("cornell"));
        assert!(a.screenshot.is_none());
    }
}
