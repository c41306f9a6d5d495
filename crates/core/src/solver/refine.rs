//! Adaptive meshing as a solve: solve, mark where the radiance varies across elements
//! ([`crate::mesh::adaptive`]), rebuild the mesh refined there, carry the solution onto it
//! (shooting: [`Shooting::carry_to`](super::Shooting::carry_to), nothing gained or lost; other solvers start the refined
//! mesh from dark) and go on.
//!
//! One routine, [`Refinement`], serves the CLI ([`refine_adaptively`], `render --adaptive`),
//! the viewer's solver thread (`view --adaptive`, "refine adaptively": it calls
//! [`Refinement::next`] between solver steps, whenever the solve is [`Refinement::due`]) and
//! the teaching view's uniform-vs-adaptive meshing (through [`refine_adaptively`]).
//! Its stop rules, the same for all three: refinement ends
//! - after `max_passes` refinements (the CLI's `--adaptive-passes`; the viewer's
//!   `2 × max_level + 2`, enough to reach the deepest level and coarsen back where the
//!   light settled, and a bound should refining and coarsening ever alternate);
//! - when a solution asks for no change of level ([`crate::mesh::adaptive::refine_levels`]
//!   gives the levels the mesh has), or for no refinement anywhere (all levels 0: nothing
//!   is rebuilt to coarsen back to the base mesh);
//! - short, with a message, when the next mesh would have more elements than
//!   [`crate::mesh::MAX_ELEMENTS`] or than the memory budget holds beside the textures
//!   (estimated from the current mesh: each level multiplies a patch's elements by about
//!   four).
//!
//! Where the CLI's and the viewer's rules once differed, the CLI's were kept: the viewer
//! too stops when nothing is to be refined (rather than rebuilding the same mesh once
//! more) and keeps to the memory budget, not only to [`crate::mesh::MAX_ELEMENTS`]. The
//! numbers stay each caller's: the CLI allows as many levels as passes, the viewer three
//! levels in eight passes.
//!
//! A refined mesh is built from the problem's [`crate::mesh::MeshSpec`] at the sizes of
//! the mesh solved, so discontinuity meshing's cuts (the base patches the levels are
//! indexed by) are kept.

use std::sync::atomic::AtomicBool;

use super::auto::{self, RunShape};
use super::{Problem, Solver, SolverError, SolverKind, solve_to};
use crate::mesh::{Mesh, MeshSpec};
use crate::scene::Rgb;

pub mod penumbra;

/// The next refinement levels per base patch of `problem` after a solution `radiance`:
/// [`crate::mesh::adaptive::refine_levels`] with the shadow boundaries of
/// [`penumbra::penumbra_bases`].
pub fn next_levels(
    problem: &Problem,
    radiance: &[Rgb],
    current: &[u8],
    tolerance: f64,
    max_level: u8,
) -> Vec<u8> {
    let boundary = penumbra::penumbra_bases(problem, radiance, tolerance);
    crate::mesh::adaptive::refine_levels(
        &problem.mesh,
        radiance,
        current,
        &boundary,
        tolerance,
        max_level,
    )
}

/// Which solver solves each mesh of an adaptive run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Choice {
    /// This one throughout (the user named it).
    Fixed(SolverKind),
    /// [`auto::choose`] for each mesh: a refined mesh past
    /// [`auto::HIERARCHICAL_FROM_ELEMENTS`] is solved hierarchically, from dark, where
    /// carrying the shooting solution would cost a row of the new mesh per patch that
    /// shot (minutes at 300 k elements) and shooting on would cost as much again.
    Auto(RunShape),
}

impl From<SolverKind> for Choice {
    fn from(kind: SolverKind) -> Self {
        Self::Fixed(kind)
    }
}

/// The solver on the refined mesh, and why refinement stopped short of its passes where
/// it did because the next mesh would not fit.
pub struct Refined {
    pub solver: Box<dyn Solver>,
    /// "refinement stopped at N elements: the next pass would make about M, more than the
    /// memory budget holds (K)", when it did.
    pub stopped: Option<String>,
    /// Under [`Choice::Auto`], each change of solver on a refined mesh and why.
    pub switched: Vec<String>,
}

/// Refine once a solve has left this fraction of the emitted power unshot (or less): the
/// indicator needs the solution's shape, not its last digits.
pub const REFINE_UNSHOT: f64 = 1e-3;

/// An adaptive refinement in progress: the levels per base patch of the current mesh and
/// the stop rules (see the module docs). [`Refinement::next`] turns a solution on the
/// current mesh into the problem on the next one, or says refinement is over.
#[derive(Clone, Debug)]
pub struct Refinement {
    tolerance: f64,
    /// Refinement level per base patch of the current mesh (shorter: 0 past the end).
    levels: Vec<u8>,
    /// Refinements made.
    passes: u32,
    max_passes: u32,
    max_level: u8,
    /// The most elements a refined mesh may have; `None`: what the problem's memory
    /// budget holds beside its textures, at most [`crate::mesh::MAX_ELEMENTS`].
    max_elements: Option<usize>,
}

/// What [`Refinement::next`] makes of a solution.
pub enum Next {
    /// The problem on the refined mesh: carry the solution onto it ([`Shooting::carry_to`](super::Shooting::carry_to))
    /// or solve it from dark.
    Refined(Box<Problem>),
    /// Refinement is over: the solve goes on on the current mesh. `stopped` says why when
    /// it stopped short because the next mesh would not fit.
    Done { stopped: Option<String> },
}

impl Refinement {
    /// Refinement of an unrefined mesh to `tolerance`, at most `max_passes` times and
    /// `max_level` levels per base patch, within the element limit of the problem's memory
    /// budget.
    pub fn new(tolerance: f64, max_passes: u32, max_level: u8) -> Self {
        Self {
            tolerance,
            levels: Vec::new(),
            passes: 0,
            max_passes,
            max_level,
            max_elements: None,
        }
    }

    pub fn tolerance(&self) -> f64 {
        self.tolerance
    }

    /// Refinements made so far.
    pub fn passes(&self) -> u32 {
        self.passes
    }

    /// Starts the levels over: the mesh was rebuilt some other way (its base patches are
    /// new), the passes made still count.
    pub fn restart_levels(&mut self) {
        self.levels.clear();
    }

    /// Whether a solve with `residual` left is far enough for the next refinement: at
    /// [`REFINE_UNSHOT`], or at `stop` when the solve is to stop earlier.
    pub fn due(residual: f64, stop: f64) -> bool {
        residual <= REFINE_UNSHOT.max(stop)
    }

    /// The next step after a solution `radiance` (per element) on `problem`'s mesh: the
    /// problem on the mesh refined where the solution asks for it ([`next_levels`]), or
    /// [`Next::Done`] by the stop rules of the module docs.
    pub fn next(&mut self, problem: &Problem, radiance: &[Rgb]) -> Result<Next, SolverError> {
        if self.passes >= self.max_passes {
            return Ok(Next::Done { stopped: None });
        }
        let levels = next_levels(
            problem,
            radiance,
            &self.levels,
            self.tolerance,
            self.max_level,
        );
        if levels == self.levels || levels.iter().all(|&l| l == 0) {
            return Ok(Next::Done { stopped: None });
        }
        let mesh = &problem.mesh;
        let estimate = self.estimate(mesh, &levels);
        let limit = self.max_elements.unwrap_or_else(|| {
            crate::budget::elements_within(problem.config.memory_bytes, problem.scene.texture_bytes)
                .min(crate::mesh::MAX_ELEMENTS)
        });
        if estimate > limit as f64 {
            let stopped = format!(
                "adaptive refinement stopped at {} elements: the next pass would make about {:.0}, more than the limit of {} (--max-memory at {} bytes an element, at most {})",
                mesh.elements.len(),
                estimate,
                limit,
                crate::budget::ELEMENT_BYTES,
                crate::mesh::MAX_ELEMENTS
            );
            return Ok(Next::Done {
                stopped: Some(stopped),
            });
        }
        let spec = MeshSpec {
            element_size: Some(mesh.element_size),
            patch_size: Some(mesh.patch_size),
            ..problem.config.mesh
        };
        let refined = Mesh::build_refined(&problem.scene, &spec, &levels)?;
        let refined = Problem::with_mesh(problem.scene.clone(), problem.config.clone(), refined)?;
        self.levels = levels;
        self.passes += 1;
        Ok(Next::Refined(Box::new(refined)))
    }

    /// About how many elements `mesh` (at the current levels) makes at `levels`: each
    /// level more quarters a patch's elements' area.
    fn estimate(&self, mesh: &Mesh, levels: &[u8]) -> f64 {
        let level = |v: &[u8], b: u32| i32::from(v.get(b as usize).copied().unwrap_or(0));
        mesh.patches
            .iter()
            .zip(&mesh.base_patch)
            .map(|(p, &b)| {
                let more = level(levels, b) - level(&self.levels, b);
                f64::from(p.elements.end - p.elements.start) * 4f64.powi(more)
            })
            .sum()
    }
}

/// `passes` rounds of solve (to `unshot`, at most [`REFINE_UNSHOT`]), mark, refine (a
/// [`Refinement`] of at most `passes` levels); returns the solver on the last mesh, with
/// the solution carried onto it where the solver can ([`Shooting::carry_to`](super::Shooting::carry_to)) and from dark
/// where it cannot: run it on to the stop wanted. Refinement stops before a mesh of more
/// than [`crate::mesh::MAX_ELEMENTS`] elements or more than the memory budget holds beside
/// the textures, and says so. With `cancel` set it stops at the next pass (or carry) and
/// returns the solver it has.
pub fn refine_adaptively(
    problem: Problem,
    choice: Choice,
    tolerance: f64,
    passes: u8,
    unshot: f64,
    cancel: &AtomicBool,
) -> Result<Refined, SolverError> {
    let refinement = Refinement::new(tolerance, u32::from(passes), passes);
    refine_with(problem, choice, refinement, unshot, cancel)
}

/// The solver `choice` makes for `problem`, and why when `auto` chose it.
fn kind_for(problem: &Problem, choice: Choice) -> (SolverKind, Option<String>) {
    match choice {
        Choice::Fixed(kind) => (kind, None),
        Choice::Auto(run) => {
            let (kind, why) = auto::choose(problem, run);
            (kind, Some(why))
        }
    }
}

/// [`refine_adaptively`] with the refinement given.
fn refine_with(
    problem: Problem,
    choice: Choice,
    mut refinement: Refinement,
    unshot: f64,
    cancel: &AtomicBool,
) -> Result<Refined, SolverError> {
    let mut switched = Vec::new();
    let (mut kind, _) = kind_for(&problem, choice);
    let mut solver = kind.build(problem)?;
    for _ in 0..refinement.max_passes {
        if cancel.load(std::sync::atomic::Ordering::Relaxed) {
            break;
        }
        solve_to(solver.as_mut(), unshot.max(REFINE_UNSHOT));
        let refined = match refinement.next(solver.problem(), solver.radiosity())? {
            Next::Refined(refined) => *refined,
            Next::Done { stopped } => {
                return Ok(Refined {
                    solver,
                    stopped,
                    switched,
                });
            }
        };
        let (next, why) = kind_for(&refined, choice);
        solver = if next == kind {
            match super::carry_solution(solver.as_mut(), refined, cancel) {
                Ok(carried) => carried,
                Err(refined) => kind.build(*refined)?,
            }
        } else {
            drop(solver);
            switched.push(format!(
                "refined mesh of {} elements: {}",
                refined.mesh.elements.len(),
                why.unwrap_or_default()
            ));
            next.build(refined)?
        };
        kind = next;
    }
    Ok(Refined {
        solver,
        stopped: None,
        switched,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{LoadOptions, Scene};
    use crate::solver::SolverConfig;

    fn cornell() -> Problem {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let config = SolverConfig {
            mesh: MeshSpec::sized(60.0, 120.0),
            ..Default::default()
        };
        Problem::new(scene, config).expect("problem")
    }

    #[test]
    fn refinement_adds_elements_and_stops_at_the_element_limit() {
        let first = cornell().mesh.elements.len();
        let patches = cornell().mesh.patches.len();
        let refined = refine_adaptively(
            cornell(),
            SolverKind::Shooting.into(),
            0.1,
            1,
            1e-3,
            &AtomicBool::new(false),
        )
        .expect("refined");
        assert!(refined.stopped.is_none());
        let refined = refined.solver;
        assert!(
            refined.problem().mesh.elements.len() > first,
            "nothing refined"
        );
        assert!(refined.problem().mesh.patches.len() > patches);
        // Carried, not restarted: the light's shots are already on the refined mesh.
        assert!(refined.steps() > 0 && refined.residual() < 1.0);
        // A limit below what one level would make: the first mesh comes back.
        let problem = cornell();
        let refinement = Refinement {
            max_elements: Some(first + 1),
            ..Refinement::new(0.1, 1, 1)
        };
        let limited = refine_with(
            problem,
            SolverKind::Shooting.into(),
            refinement,
            1e-3,
            &AtomicBool::new(false),
        )
        .expect("limited");
        assert!(limited.stopped.is_some_and(|s| s.contains("stopped at")));
        assert_eq!(limited.solver.problem().mesh.elements.len(), first);
    }

    #[test]
    fn a_solver_that_cannot_carry_starts_the_refined_mesh_from_dark() {
        let refined = refine_adaptively(
            cornell(),
            SolverKind::Jacobi.into(),
            0.1,
            1,
            1e-3,
            &AtomicBool::new(false),
        )
        .expect("refined")
        .solver;
        assert!(refined.problem().mesh.elements.len() > cornell().mesh.elements.len());
        assert_eq!(refined.steps(), 0);
    }

    /// With discontinuity meshing the base patches are the faces cut along the shadow
    /// outlines; refining them must keep the cuts (the same base patches, so the levels land
    /// on the patches they were computed for) and carry the solution, not restart from dark.
    #[test]
    fn discontinuity_cuts_survive_adaptive_refinement() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let config = SolverConfig {
            mesh: MeshSpec {
                element_size: Some(60.0),
                patch_size: Some(120.0),
                discontinuity: true,
                ..Default::default()
            },
            ..Default::default()
        };
        let cut = Problem::new(scene, config).expect("problem");
        let plain = cornell();
        let bases = cut.mesh.base_count();
        assert!(bases > plain.mesh.base_count(), "the cuts add base patches");
        let refined = refine_adaptively(
            cut,
            SolverKind::Shooting.into(),
            0.1,
            1,
            1e-3,
            &AtomicBool::new(false),
        )
        .expect("refined")
        .solver;
        let mesh = &refined.problem().mesh;
        assert_eq!(mesh.base_count(), bases, "the cut base patches are kept");
        assert!(mesh.patches.len() > bases, "something was refined");
        assert!(
            refined.steps() > 0,
            "the solution was carried, not restarted"
        );
    }
}
