//! Adaptive meshing as a solve: solve, mark where the radiance varies across elements
//! ([`crate::mesh::adaptive`]), rebuild the mesh refined there, and again.

use std::sync::atomic::AtomicBool;

use super::{Problem, SolverError, SolverKind, StopCriteria, run_solver};

/// `passes` rounds of solve, mark, refine (see [`crate::mesh::adaptive`]); returns the
/// problem on the last refined mesh (to be solved from dark), or the first one unchanged
/// when nothing needs refining.
pub fn refine_adaptively(
    mut problem: Problem,
    kind: SolverKind,
    tolerance: f64,
    passes: u8,
    unshot: f64,
) -> Result<Problem, SolverError> {
    let mut levels: Vec<u8> = Vec::new();
    let never = AtomicBool::new(false);
    for _ in 0..passes {
        let mut solver = kind.build(problem)?;
        let stop = StopCriteria {
            unshot: unshot.max(1e-3),
            ..Default::default()
        };
        run_solver(solver.as_mut(), &stop, &never, &mut |_, _| {});
        let radiance = solver.element_radiance(false);
        let next = crate::mesh::adaptive::refine_levels(
            &solver.problem().mesh,
            &radiance,
            &levels,
            tolerance,
            passes,
        );
        let (solved, _) = solver.into_parts();
        if next == levels || next.iter().all(|&l| l == 0) {
            return Ok(solved);
        }
        levels = next;
        let mesh = crate::mesh::Mesh::build_refined(
            &solved.scene,
            solved.mesh.element_size,
            solved.mesh.patch_size,
            &levels,
        )?;
        problem = Problem::with_mesh(solved.scene, solved.config, mesh)?;
    }
    Ok(problem)
}
