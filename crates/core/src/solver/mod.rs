//! Solvers of the radiosity system `B = E + ρ F B`, one file each behind one [`Solver`]
//! trait, on a shared [`Problem`] (scene, mesh, BVH) and cached form-factor rows
//! ([`rows`]):
//! - [`ProgressiveSolver`] (`shooting`): progressive refinement with overshooting, the
//!   default; it shows a usable image after a few shots and adapts to material edits.
//! - [`GatheringSolver`] (`jacobi`, `gauss-seidel`, `sor`): the lecture's gathering with a
//!   stored matrix, on patches, with elements gathered from the patch solution.
//! - [`CgSolver`] (`cg`): a conjugate-gradient (Krylov) method, BiCGSTAB, on the patch system.
//!
//! Every solver reports the same residual, `Σ|r_i|A_i / Σ|E_i|A_i` over patches (channel
//! sums; for shooting it is the unshot fraction), so `--unshot` means the same for all.
//! All sums are `f64`. Results depend only on the scene, the settings and the seed, not on
//! thread count or timing.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use crate::formfactor::hemicube::ItemBufferRaster;
use crate::formfactor::{FormFactorMethod, FormFactorParams};
use crate::mesh::{Mesh, MeshError, MeshSpec, PatchId};
use crate::scene::{MaterialId, Rgb};

pub mod ambient;
pub mod auto;
pub mod cg;
pub mod gathering;
pub mod hierarchical;
pub mod matrix;
pub mod problem;
pub mod progressive;
pub mod refine;
pub mod rows;

pub use cg::CgSolver;
pub use gathering::{GatherMethod, GatheringSolver};
pub use hierarchical::HierarchicalSolver;
pub use matrix::MatrixSolver;
pub use problem::Problem;
pub use progressive::ProgressiveSolver;
pub use rows::RowCache;

#[derive(Clone, Debug)]
pub struct SolverConfig {
    /// The mesh: its sizes or element budget, and discontinuity meshing.
    pub mesh: MeshSpec,
    pub method: FormFactorMethod,
    pub formfactor: FormFactorParams,
    /// The run's memory budget in bytes ([`crate::budget`]): the textures and the mesh
    /// draw on it first (a mesh that cannot fit is refused before meshing), cached rows,
    /// a stored matrix and hierarchical links get what is left
    /// ([`Problem::cache_bytes`]; gathering solvers refuse a matrix that does not fit).
    pub memory_bytes: usize,
    /// Overshooting (Feda & Purgathofer 1992): each shot also sends the light the shooter
    /// is expected to receive later, `ρ_i · ambient`, and keeps it as negative unshot
    /// radiance that the light, when it arrives, cancels.
    pub overshoot: bool,
    /// Display correction of shooting: the regional ambient term ([`ambient`]) instead of
    /// the classic global one.
    pub regional_ambient: bool,
    /// Hierarchical radiosity's BF refinement threshold, relative to the scene's area-mean
    /// emitted radiosity (`--link-tolerance`): smaller gives more links and a finer answer.
    pub link_tolerance: f64,
    /// The rasteriser of `gpu-hemicube` rows (`nusselt_gpu::GpuHemicube`); required by that
    /// method, unused by the others.
    pub raster: Option<Arc<dyn ItemBufferRaster>>,
}

impl Default for SolverConfig {
    fn default() -> Self {
        Self {
            mesh: MeshSpec::default(),
            method: FormFactorMethod::Contour,
            formfactor: FormFactorParams::default(),
            memory_bytes: crate::budget::FALLBACK_BYTES,
            overshoot: true,
            regional_ambient: true,
            link_tolerance: DEFAULT_LINK_TOLERANCE,
            raster: None,
        }
    }
}

/// Default of [`SolverConfig::link_tolerance`].
pub const DEFAULT_LINK_TOLERANCE: f64 = 0.002;

#[derive(Debug, thiserror::Error)]
pub enum SolverError {
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error("the gpu-hemicube method needs a GPU hemicube rasteriser, and none was set up")]
    NoRaster,
    #[error("material {0} does not exist")]
    NoSuchMaterial(u32),
    #[error("{what} must be finite and {range}, got {value:?}")]
    BadValue {
        what: &'static str,
        range: &'static str,
        value: [f64; 3],
    },
    #[error(
        "the {solver} solver needs {needed_mb} MB for its form-factor matrix ({patches} patches x {elements} elements), more than the {limit_mb} MB the memory budget leaves beside the mesh (--max-memory); use fewer elements, a larger --max-memory or --solver shooting"
    )]
    MatrixTooLarge {
        solver: &'static str,
        needed_mb: usize,
        limit_mb: usize,
        patches: usize,
        elements: usize,
    },
    #[error(
        "a mesh of about {elements} elements (element size {element_size:.4}) needs about {needed_mib} MiB, more than the memory budget of {budget_mib} MiB{held}: use {fitting}, or --max-memory {needed_mib} or more"
    )]
    MeshOverBudget {
        elements: usize,
        element_size: f64,
        needed_mib: usize,
        budget_mib: usize,
        /// What else holds part of the budget (", of which textures hold N MiB"), or empty.
        held: String,
        /// The mesh flag that would fit ("--element-size 2.0175 or larger").
        fitting: String,
    },
    #[error(
        "the emitted power (Σ Ke × area = {emitted:e}) is too large: with interreflection it would overflow to infinity; lower Ke or scale the model down"
    )]
    PowerOverflow { emitted: f64 },
}

/// Refuses materials whose light would overflow `f64` during a solve: the emitted power
/// `P = Σ |E| A` (channel sums), times `1/(1 − ρ_max)` for all its interreflections (the
/// most power a solve carries), over the smallest patch area (the largest unshot radiance
/// that power can become) must be finite; otherwise unshot fractions turn NaN and a solve
/// to a target never ends.
fn check_power(materials: &[crate::scene::Material], mesh: &Mesh) -> Result<(), SolverError> {
    let mut emitted = 0.0;
    let mut rho_max: f64 = 0.0;
    let mut min_area = f64::INFINITY;
    for p in &mesh.patches {
        let m = &materials[p.material.0 as usize];
        emitted += channel_sum(m.emission) * p.area;
        rho_max = rho_max.max(m.reflectance.max_element());
        if p.area > 0.0 {
            min_area = min_area.min(p.area);
        }
    }
    let carried = emitted / (1.0 - rho_max.min(crate::scene::MAX_REFLECTANCE));
    if !(carried.is_finite() && (carried / min_area.min(1.0)).is_finite()) {
        return Err(SolverError::PowerOverflow { emitted });
    }
    Ok(())
}

/// When to stop [`ProgressiveSolver::run`].
#[derive(Clone, Copy, Debug)]
pub struct StopCriteria {
    /// Remaining unshot power over emitted power.
    pub unshot: f64,
    pub max_shots: Option<usize>,
    pub max_seconds: Option<f64>,
    /// Stop when the solver's estimate of the remaining relative error of every element
    /// ([`Solver::error_estimate`]) falls to this (`--tolerance`).
    pub tolerance: Option<f64>,
}

impl Default for StopCriteria {
    fn default() -> Self {
        Self {
            unshot: 1e-4,
            max_shots: None,
            max_seconds: None,
            tolerance: None,
        }
    }
}

/// One row of the convergence log.
#[derive(Clone, Copy, Debug)]
pub struct ShotRecord {
    pub shot: usize,
    pub seconds: f64,
    pub unshot_fraction: f64,
    /// Channel mean of the ambient term.
    pub ambient: f64,
    pub shooter: PatchId,
}

pub(crate) fn channel_sum(c: Rgb) -> f64 {
    c.x.abs() + c.y.abs() + c.z.abs()
}

/// Which solver (`--solver`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SolverKind {
    Shooting,
    Jacobi,
    GaussSeidel,
    /// Successive over-relaxation; `None` = ω estimated from the first sweeps.
    Sor(Option<f64>),
    Cg,
    /// Hierarchical radiosity with clustering ([`hierarchical`]).
    Hierarchical,
    /// Wavelet radiosity with flatlets F2 ([`hierarchical::flatlet`]).
    Wavelet,
}

impl SolverKind {
    /// Names as the command line spells them.
    pub const NAMES: &'static [&'static str] = &[
        "shooting",
        "jacobi",
        "gauss-seidel",
        "sor",
        "cg",
        "hierarchical",
        "wavelet",
    ];

    /// Parses a `--solver` name; `omega` applies to `sor`.
    pub fn parse(name: &str, omega: Option<f64>) -> Option<SolverKind> {
        Some(match name {
            "shooting" => SolverKind::Shooting,
            "jacobi" => SolverKind::Jacobi,
            "gauss-seidel" | "gs" => SolverKind::GaussSeidel,
            "sor" => SolverKind::Sor(omega),
            "cg" => SolverKind::Cg,
            "hierarchical" | "hr" => SolverKind::Hierarchical,
            "wavelet" | "flatlet" => SolverKind::Wavelet,
            _ => return None,
        })
    }

    /// The name as the command line spells it.
    pub fn name(self) -> &'static str {
        match self {
            SolverKind::Shooting => "shooting",
            SolverKind::Jacobi => "jacobi",
            SolverKind::GaussSeidel => "gauss-seidel",
            SolverKind::Sor(_) => "sor",
            SolverKind::Cg => "cg",
            SolverKind::Hierarchical => "hierarchical",
            SolverKind::Wavelet => "wavelet",
        }
    }

    /// Whether [`build`](Self::build) would refuse `problem` (ω out of range, a matrix over
    /// the memory budget), without taking it.
    pub fn check(self, problem: &Problem) -> Result<(), SolverError> {
        match self {
            SolverKind::Shooting | SolverKind::Hierarchical | SolverKind::Wavelet => Ok(()),
            SolverKind::Sor(omega) => {
                gathering::check_omega(GatherMethod::Sor(omega))?;
                matrix::PatchMatrix::check(problem, self.name())
            }
            _ => matrix::PatchMatrix::check(problem, self.name()),
        }
    }

    /// A solver of this kind on `problem`, starting dark.
    pub fn build(self, problem: Problem) -> Result<Box<dyn Solver>, SolverError> {
        self.build_with_rows(problem, RowCache::default())
    }

    /// As [`build`](Self::build), reusing form-factor rows cached on the same problem (by
    /// [`Solver::into_parts`] of another solver): switching solvers keeps the mesh and the
    /// rows.
    pub fn build_with_rows(
        self,
        problem: Problem,
        rows: RowCache,
    ) -> Result<Box<dyn Solver>, SolverError> {
        Ok(match self {
            SolverKind::Shooting => Box::new(ProgressiveSolver::with_rows(problem, rows)),
            SolverKind::Jacobi => Box::new(GatheringSolver::with_rows(
                problem,
                GatherMethod::Jacobi,
                rows,
            )?),
            SolverKind::GaussSeidel => Box::new(GatheringSolver::with_rows(
                problem,
                GatherMethod::GaussSeidel,
                rows,
            )?),
            SolverKind::Sor(omega) => Box::new(GatheringSolver::with_rows(
                problem,
                GatherMethod::Sor(omega),
                rows,
            )?),
            SolverKind::Cg => Box::new(CgSolver::with_rows(problem, rows)?),
            // Links, not rows: cached rows are dropped.
            SolverKind::Hierarchical => Box::new(HierarchicalSolver::new(problem)),
            SolverKind::Wavelet => Box::new(HierarchicalSolver::with_basis(
                problem,
                hierarchical::Basis::Flatlet,
            )),
        })
    }
}

/// One solver of the radiosity system. A *step* is a solver's unit of work: a shot, a
/// form-factor row while a matrix is being built, or a sweep.
pub trait Solver: Send {
    /// `shooting`, `jacobi`, `gauss-seidel`, `sor`, `cg`, `hierarchical` or `wavelet`.
    fn name(&self) -> &'static str;
    fn problem(&self) -> &Problem;
    /// One step. `false` when there is nothing left to do or `cancel` was set.
    fn step(&mut self, cancel: &AtomicBool) -> bool;
    /// Steps taken since the last reset.
    fn steps(&self) -> usize;
    /// Radiosity per element (radiance units), without any display correction.
    fn radiosity(&self) -> &[Rgb];
    /// Relative residual `Σ|r_i|A_i / Σ|E_i|A_i` (1 before the first step).
    fn residual(&self) -> f64;
    /// Per-element radiance for display, with the solver's estimate of the light still
    /// missing when `with_ambient`.
    fn element_radiance(&self, with_ambient: bool) -> Vec<Rgb>;
    /// Changes a material; the solution continues from its current state where the solver
    /// can, or restarts.
    fn set_material(
        &mut self,
        id: MaterialId,
        reflectance: Rgb,
        emission: Rgb,
    ) -> Result<(), SolverError>;
    /// Replaces the sky, suns and point lights; the solution continues from its current
    /// state (the change in what each element receives is what is left to distribute).
    fn set_lights(&mut self, lights: Vec<crate::scene::Light>);
    /// Back to the dark start (cached form factors kept).
    fn reset(&mut self);
    /// Channel mean of [`ambient`](Self::ambient).
    fn ambient_mean(&self) -> f64 {
        let a = self.ambient();
        (a.x + a.y + a.z) / 3.0
    }
    /// The classic global ambient term per channel (shooting; zero for solvers without
    /// one). [`element_radiance`](Self::element_radiance) with `with_ambient` adds `ρ_j`
    /// times it, or times the regional estimate where that is configured.
    fn ambient(&self) -> Rgb {
        Rgb::ZERO
    }
    /// The patch the last step shot from (shooting only).
    fn last_shooter(&self) -> Option<PatchId> {
        None
    }
    /// Unshot radiance per patch (shooting only): what each patch has received and not yet
    /// shot (negative where overshot light is still to be cancelled).
    fn unshot(&self) -> Option<&[Rgb]> {
        None
    }
    /// Memory held by stored form factors, in bytes.
    fn matrix_bytes(&self) -> usize {
        0
    }
    /// An estimate of the largest remaining relative error of an element's radiosity
    /// (`--tolerance`): what is still to arrive over what the element shows, measured against
    /// at least 1/1000 of the scene's mean radiosity (so elements that stay dark do not
    /// hold a solve forever). Costs about a sweep; [`run_solver`] evaluates it at
    /// geometrically spaced steps.
    fn error_estimate(&self) -> f64;
    /// A line about solver-specific figures (ω of SOR, …), empty if none.
    fn report(&self) -> String {
        String::new()
    }
    /// The problem and the cached form-factor rows, for a solver of another kind
    /// ([`SolverKind::build_with_rows`]).
    fn into_parts(self: Box<Self>) -> (Problem, RowCache);
    /// This solution carried onto `problem`, the same scene on a refined mesh, so that the
    /// solve goes on instead of starting again (shooting:
    /// [`ProgressiveSolver::carry_to`]); `problem` back where this solver cannot, to be
    /// solved from dark.
    fn carry_to(
        &mut self,
        problem: Problem,
        cancel: &AtomicBool,
    ) -> Result<Box<dyn Solver>, Box<Problem>> {
        let _ = cancel;
        Err(Box::new(problem))
    }
}

/// One row of a generic run's log.
#[derive(Clone, Copy, Debug)]
pub struct StepRecord {
    pub step: usize,
    pub seconds: f64,
    pub residual: f64,
}

/// [`run_solver`] to a residual of `unshot`, uncancelled and unwatched: for batch runs,
/// benches and tests.
pub fn solve_to(solver: &mut dyn Solver, unshot: f64) {
    let stop = StopCriteria {
        unshot,
        ..Default::default()
    };
    run_solver(solver, &stop, &AtomicBool::new(false), &mut |_, _| {});
}

/// Steps `solver` until `stop` is met (`unshot` is the residual target; `max_shots` counts
/// steps; `tolerance` is checked after 10 % more steps each time, so a run may overshoot
/// it by that many); calls `on_step` after each step.
pub fn run_solver(
    solver: &mut dyn Solver,
    stop: &StopCriteria,
    cancel: &AtomicBool,
    on_step: &mut dyn FnMut(&StepRecord, &dyn Solver),
) {
    let start = Instant::now();
    let mut next_check = solver.steps();
    loop {
        let residual = solver.residual();
        let tolerance_met = stop.tolerance.is_some_and(|t| {
            solver.steps() >= next_check && {
                next_check = solver.steps() + solver.steps() / 10 + 1;
                solver.error_estimate() <= t
            }
        });
        if residual.is_nan()
            || tolerance_met
            || residual <= stop.unshot
            || stop.max_shots.is_some_and(|n| solver.steps() >= n)
            || stop
                .max_seconds
                .is_some_and(|s| start.elapsed().as_secs_f64() >= s)
        {
            return;
        }
        if !solver.step(cancel) {
            return;
        }
        let record = StepRecord {
            step: solver.steps(),
            seconds: start.elapsed().as_secs_f64(),
            residual: solver.residual(),
        };
        on_step(&record, solver);
    }
}

/// The Jacobi-style error estimate of the gathering solvers: with the largest residual
/// `r_max` and reflectance `ρ_max`, the error `e = (I − ρF)⁻¹ r` is at most
/// `r_max / (1 − ρ_max)` where the rows sum to at most 1; returned relative to the smallest
/// channel of each of `values` (at least [`error_floor`] of `radiosity`), the largest.
pub(crate) fn residual_error_estimate(
    problem: &Problem,
    radiosity: &[Rgb],
    values: &[Rgb],
    r_max: f64,
    rho_max: f64,
) -> f64 {
    let bound = r_max / (1.0 - rho_max.min(crate::scene::MAX_REFLECTANCE));
    let floor = error_floor(problem, radiosity);
    values
        .iter()
        .map(|b| bound / b.min_element().max(floor))
        .fold(0.0, f64::max)
}

/// The floor of relative error estimates: 1/1000 of the area-mean channel-mean radiosity.
pub(crate) fn error_floor(problem: &Problem, radiosity: &[Rgb]) -> f64 {
    let mut sum = 0.0;
    let mut area = 0.0;
    for (e, b) in problem.mesh.elements.iter().zip(radiosity) {
        sum += (b.x + b.y + b.z) / 3.0 * e.area;
        area += e.area;
    }
    (1e-3 * sum / area.max(1e-300)).max(1e-300)
}
