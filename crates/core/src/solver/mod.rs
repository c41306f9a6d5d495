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

use crate::formfactor::hemicube::ItemBufferRaster;
use crate::formfactor::{FormFactorMethod, FormFactorParams};
use crate::mesh::{Mesh, MeshError, MeshSpec, PatchId};
use crate::scene::{MaterialId, Rgb};

pub mod ambient;
pub mod auto;
pub mod cg;
pub mod gathering;
pub mod handoff;
pub mod hierarchical;
pub mod matrix;
pub mod problem;
pub mod progressive;
pub mod refine;
pub mod registry;
pub mod rows;
mod run;

pub use cg::CgSolver;
pub use gathering::{GatherMethod, GatheringSolver};
pub use hierarchical::HierarchicalSolver;
pub use matrix::MatrixSolver;
pub use problem::Problem;
pub use progressive::ProgressiveSolver;
pub use registry::{OptionSet, SolverKind, SolverOption, SolverRow};
pub use rows::RowCache;
pub use run::{StepRecord, StopCriteria, run_solver, solve_to};

/// Everything a solve is set up with: the mesh, how form factors are computed, the memory
/// budget, and the options of each solver (read only by that solver; the command line
/// refuses an option the chosen solver does not read, [`SolverKind::refuse_unread`]).
#[derive(Clone, Debug)]
pub struct SolverConfig {
    /// The mesh: its sizes or element budget, and discontinuity meshing.
    pub mesh: MeshSpec,
    /// How form-factor rows are computed.
    pub formfactor: FormFactorConfig,
    /// The run's memory budget in bytes ([`crate::budget`]): the textures and the mesh
    /// draw on it first (a mesh that cannot fit is refused before meshing), cached rows,
    /// a stored matrix and hierarchical links get what is left
    /// ([`Problem::cache_bytes`]; gathering solvers refuse a matrix that does not fit).
    pub memory_bytes: usize,
    /// Options of progressive shooting.
    pub shooting: ShootingOptions,
    /// Options of hierarchical and wavelet radiosity.
    pub hierarchical: HierarchicalOptions,
}

impl Default for SolverConfig {
    fn default() -> Self {
        Self {
            mesh: MeshSpec::default(),
            formfactor: FormFactorConfig::default(),
            memory_bytes: crate::budget::FALLBACK_BYTES,
            shooting: ShootingOptions::default(),
            hierarchical: HierarchicalOptions::default(),
        }
    }
}

/// How form-factor rows are computed (`--formfactor` and its settings), read by the solvers
/// that store rows (shooting, gathering, cg); hierarchical and wavelet radiosity estimate
/// their links themselves and read only `params.seed`.
#[derive(Clone, Debug)]
pub struct FormFactorConfig {
    pub method: FormFactorMethod,
    pub params: FormFactorParams,
    /// The rasteriser of `gpu-hemicube` rows (`nusselt_gpu::GpuHemicube`); required by that
    /// method, unused by the others.
    pub raster: Option<Arc<dyn ItemBufferRaster>>,
}

impl Default for FormFactorConfig {
    fn default() -> Self {
        Self {
            method: FormFactorMethod::Contour,
            params: FormFactorParams::default(),
            raster: None,
        }
    }
}

/// Options of progressive shooting ([`ProgressiveSolver`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShootingOptions {
    /// Overshooting (Feda & Purgathofer 1992): each shot also sends the light the shooter
    /// is expected to receive later, `ρ_i · ambient`, and keeps it as negative unshot
    /// radiance that the light, when it arrives, cancels.
    pub overshoot: bool,
    /// Display correction: the regional ambient term ([`ambient`]) instead of the classic
    /// global one.
    pub regional_ambient: bool,
}

impl Default for ShootingOptions {
    fn default() -> Self {
        Self {
            overshoot: true,
            regional_ambient: true,
        }
    }
}

/// Options of hierarchical and wavelet radiosity ([`HierarchicalSolver`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HierarchicalOptions {
    /// The BF refinement threshold, relative to the scene's area-mean emitted radiosity
    /// (`--link-tolerance`): smaller gives more links and a finer answer.
    pub link_tolerance: f64,
}

impl Default for HierarchicalOptions {
    fn default() -> Self {
        Self {
            link_tolerance: DEFAULT_LINK_TOLERANCE,
        }
    }
}

/// Default of [`HierarchicalOptions::link_tolerance`].
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

/// One row of a shooting run's log ([`ProgressiveSolver::run`]).
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

/// One solver of the radiosity system: everything a caller needs to run, show, edit and
/// switch any solver. A *step* is a solver's unit of work: a shot, a form-factor row while a
/// matrix is being built, or a sweep. What only progressive shooting has (an ambient term,
/// unshot radiance, carrying a solution onto a refined mesh) is behind
/// [`shooting`](Self::shooting).
pub trait Solver: Send {
    /// Its name in the registry ([`SolverKind::name`]).
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
    /// An estimate of the largest remaining relative error of an element's radiosity
    /// (`--tolerance`): what is still to arrive over what the element shows, measured against
    /// at least 1/1000 of the scene's mean radiosity (so elements that stay dark do not
    /// hold a solve forever). Costs about a sweep; [`run_solver`] evaluates it at
    /// geometrically spaced steps.
    fn error_estimate(&self) -> f64;
    /// Per-element radiance to show while unconverged: the radiosity plus the solver's
    /// estimate of the light still to arrive, where it has one (shooting's ambient term);
    /// the radiosity itself for solvers without such an estimate.
    fn display_radiance(&self) -> Vec<Rgb>;
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
    /// Memory held by stored form factors (rows, a matrix, links), in bytes.
    fn matrix_bytes(&self) -> usize;
    /// A line about solver-specific figures (ω of SOR, links, shots…).
    fn report(&self) -> String;
    /// The problem, and the cached form-factor rows where the solver keeps rows, for a
    /// solver of another kind ([`SolverKind::build_with_rows`]).
    fn into_parts(self: Box<Self>) -> (Problem, Option<RowCache>);
    /// What only progressive shooting has; `None` for the other solvers.
    fn shooting(&self) -> Option<&dyn Shooting> {
        None
    }
    /// [`shooting`](Self::shooting), to carry its solution onto a refined mesh.
    fn shooting_mut(&mut self) -> Option<&mut dyn Shooting> {
        None
    }
}

/// What only progressive shooting has ([`ProgressiveSolver`]), reached through
/// [`Solver::shooting`].
pub trait Shooting {
    /// The classic global ambient term per channel; [`Solver::display_radiance`] adds
    /// `ρ_j` times it, or times the regional estimate where that is configured.
    fn ambient(&self) -> Rgb;
    /// Channel mean of [`ambient`](Self::ambient).
    fn ambient_mean(&self) -> f64 {
        let a = self.ambient();
        (a.x + a.y + a.z) / 3.0
    }
    /// The patch the last shot came from.
    fn last_shooter(&self) -> Option<PatchId>;
    /// Unshot radiance per patch: what each patch has received and not yet shot (negative
    /// where overshot light is still to be cancelled).
    fn unshot(&self) -> &[Rgb];
    /// This solution carried onto `problem`, the same scene on a refined mesh, so that the
    /// solve goes on instead of starting again ([`ProgressiveSolver::carry_to`]); `problem`
    /// back when cancelled, to be solved from dark.
    fn carry_to(
        &mut self,
        problem: Problem,
        cancel: &AtomicBool,
    ) -> Result<Box<dyn Solver>, Box<Problem>>;
    /// Takes a regional ambient term built for this solver's problem
    /// ([`ambient::RegionalAmbient::build`] before the problem was moved in, e.g. on another
    /// thread while the viewer built its drawing arrays), instead of building one on first
    /// display. One built for another mesh (a different patch count) is ignored.
    fn use_regional_ambient(&mut self, regional: ambient::RegionalAmbient);
}

/// `solver`'s solution carried onto `problem`, the same scene on a refined mesh, where the
/// solver can carry one ([`Shooting::carry_to`]); `problem` back otherwise, to be solved
/// from dark.
pub fn carry_solution(
    solver: &mut dyn Solver,
    problem: Problem,
    cancel: &AtomicBool,
) -> Result<Box<dyn Solver>, Box<Problem>> {
    match solver.shooting_mut() {
        Some(shooting) => shooting.carry_to(problem, cancel),
        None => Err(Box::new(problem)),
    }
}

/// The channel-mean ambient term of `solver` (0 for solvers without one), for logs and
/// panels.
pub fn ambient_mean(solver: &dyn Solver) -> f64 {
    solver.shooting().map_or(0.0, |s| s.ambient_mean())
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
