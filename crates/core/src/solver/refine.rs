//! Adaptive meshing as a solve: solve, mark where the radiance varies across elements
//! ([`crate::mesh::adaptive`]), rebuild the mesh refined there, carry the solution onto it
//! (shooting: [`Solver::carry_to`], nothing gained or lost) and go on.

use std::sync::atomic::AtomicBool;

use super::auto::{self, RunShape};
use super::{Problem, Solver, SolverError, SolverKind, solve_to};
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

/// `passes` rounds of solve (to `unshot`, at most 1e-3), mark, refine (see
/// [`crate::mesh::adaptive`]); returns the solver on the last mesh, with the solution
/// carried onto it where the solver can ([`Solver::carry_to`]) and from dark where it
/// cannot: run it on to the stop wanted. Refinement stops before a mesh of more than
/// [`crate::mesh::MAX_ELEMENTS`] elements or more than the memory budget holds beside the
/// textures (each level multiplies a patch's elements by about four), and says so.
pub fn refine_adaptively(
    problem: Problem,
    choice: Choice,
    tolerance: f64,
    passes: u8,
    unshot: f64,
) -> Result<Refined, SolverError> {
    let fit =
        crate::budget::elements_within(problem.config.memory_bytes, problem.scene.texture_bytes);
    let limit = fit.min(crate::mesh::MAX_ELEMENTS);
    refine_within(problem, choice, tolerance, passes, unshot, limit)
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

/// [`refine_adaptively`] with the element limit given.
fn refine_within(
    problem: Problem,
    choice: Choice,
    tolerance: f64,
    passes: u8,
    unshot: f64,
    max_elements: usize,
) -> Result<Refined, SolverError> {
    let mut levels: Vec<u8> = Vec::new();
    let never = AtomicBool::new(false);
    let mut switched = Vec::new();
    let (mut kind, _) = kind_for(&problem, choice);
    let mut solver = kind.build(problem)?;
    for _ in 0..passes {
        solve_to(solver.as_mut(), unshot.max(1e-3));
        let radiance = solver.radiosity().to_vec();
        let mesh = &solver.problem().mesh;
        let next = next_levels(solver.problem(), &radiance, &levels, tolerance, passes);
        let level = |v: &[u8], b: u32| i32::from(v.get(b as usize).copied().unwrap_or(0));
        let estimate: f64 = mesh
            .patches
            .iter()
            .zip(&mesh.base_patch)
            .map(|(p, &b)| {
                let more = level(&next, b) - level(&levels, b);
                f64::from(p.elements.end - p.elements.start) * 4f64.powi(more)
            })
            .sum();
        if next == levels || next.iter().all(|&l| l == 0) {
            break;
        }
        if estimate > max_elements as f64 {
            let stopped = format!(
                "adaptive refinement stopped at {} elements: the next pass would make about {:.0}, more than the limit of {max_elements} (--max-memory at {} bytes an element, at most {})",
                mesh.elements.len(),
                estimate,
                crate::budget::ELEMENT_BYTES,
                crate::mesh::MAX_ELEMENTS
            );
            return Ok(Refined {
                solver,
                stopped: Some(stopped),
                switched,
            });
        }
        levels = next;
        let solved = solver.problem();
        let mesh = crate::mesh::Mesh::build_refined(
            &solved.scene,
            solved.mesh.element_size,
            solved.mesh.patch_size,
            &levels,
            solved.config.discontinuity,
        )?;
        let refined = Problem::with_mesh(solved.scene.clone(), solved.config.clone(), mesh)?;
        let (next, why) = kind_for(&refined, choice);
        solver = if next == kind {
            match super::carry_solution(solver.as_mut(), refined, &never) {
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
            element_size: Some(60.0),
            patch_size: Some(120.0),
            ..Default::default()
        };
        Problem::new(scene, config).expect("problem")
    }

    #[test]
    fn refinement_adds_elements_and_stops_at_the_element_limit() {
        let first = cornell().mesh.elements.len();
        let patches = cornell().mesh.patches.len();
        let refined = refine_adaptively(cornell(), SolverKind::Shooting.into(), 0.1, 1, 1e-3)
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
        let limited = refine_within(
            cornell(),
            SolverKind::Shooting.into(),
            0.1,
            1,
            1e-3,
            first + 1,
        )
        .expect("limited");
        assert!(limited.stopped.is_some_and(|s| s.contains("stopped at")));
        assert_eq!(limited.solver.problem().mesh.elements.len(), first);
    }

    #[test]
    fn a_solver_that_cannot_carry_starts_the_refined_mesh_from_dark() {
        let refined = refine_adaptively(cornell(), SolverKind::Jacobi.into(), 0.1, 1, 1e-3)
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
            element_size: Some(60.0),
            patch_size: Some(120.0),
            discontinuity: true,
            ..Default::default()
        };
        let cut = Problem::new(scene, config).expect("problem");
        let plain = cornell();
        let bases = cut.mesh.base_count();
        assert!(bases > plain.mesh.base_count(), "the cuts add base patches");
        let refined = refine_adaptively(cut, SolverKind::Shooting.into(), 0.1, 1, 1e-3)
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
