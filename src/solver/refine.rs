//! Adaptive meshing as a solve: solve, mark where the radiance varies across elements
//! ([`crate::mesh::adaptive`]), rebuild the mesh refined there, and again.

use std::sync::atomic::AtomicBool;

use super::{Problem, SolverError, SolverKind, StopCriteria, run_solver};

/// `passes` rounds of solve, mark, refine (see [`crate::mesh::adaptive`]); returns the
/// problem on the last refined mesh (to be solved from dark), or the first one unchanged
/// when nothing needs refining. Refinement stops before a mesh of more than
/// [`crate::mesh::MAX_ELEMENTS`] elements (each level multiplies a patch's by about four).
pub fn refine_adaptively(
    problem: Problem,
    kind: SolverKind,
    tolerance: f64,
    passes: u8,
    unshot: f64,
) -> Result<Problem, SolverError> {
    refine_within(
        problem,
        kind,
        tolerance,
        passes,
        unshot,
        crate::mesh::MAX_ELEMENTS,
    )
}

/// [`refine_adaptively`] with the element limit given.
fn refine_within(
    mut problem: Problem,
    kind: SolverKind,
    tolerance: f64,
    passes: u8,
    unshot: f64,
    max_elements: usize,
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
        let mesh = &solved.mesh;
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
        if next == levels || next.iter().all(|&l| l == 0) || estimate > max_elements as f64 {
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
        let refined =
            refine_adaptively(cornell(), SolverKind::Shooting, 0.1, 1, 1e-3).expect("refined");
        assert!(refined.mesh.elements.len() > first, "nothing refined");
        assert!(refined.mesh.patches.len() > cornell().mesh.patches.len());
        // A limit below what one level would make: the first mesh comes back.
        let limited = refine_within(cornell(), SolverKind::Shooting, 0.1, 1, 1e-3, first + 1)
            .expect("limited");
        assert_eq!(limited.mesh.elements.len(), first);
    }
}
