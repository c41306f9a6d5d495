//! Shooting, then hierarchical: what `auto` does in the viewer on a large scene.
//!
//! Each solver is fast at one half of the job. Progressive shooting spreads the lights'
//! power first (Cohen et al. 1988), so with the ambient term its image is close early, but
//! every shot costs a row of form factors to every element: on the 263 k-triangle Crytek
//! atrium (227 k elements) it leaves about 1.3 % unshot after three minutes. Hierarchical
//! radiosity (Hanrahan et al. 1991) converges there in about 35 s, but from the emission
//! alone its first refinement links by the lights' radiosity only, and shows nothing for
//! its first 14 s. So the viewer shoots until [`HANDOFF_UNSHOT`] of the power is left, which
//! takes the lights and the brightest surfaces a few seconds, then goes on hierarchically
//! from the shot solution ([`HierarchicalSolver::continue_from`]): its first refinement
//! then links by the light already spread.
//!
//! Only scenes that `auto` would solve hierarchically without an image to show
//! ([`super::auto::choose`]) are handed over; smaller ones shoot to the end.

use super::auto::{self, RunShape};
use super::{HierarchicalSolver, Problem, Solver, SolverKind};

/// The unshot fraction at which a large scene's shooting hands over. Measured on the
/// Crytek atrium (`render sponza.obj --solver shooting --shots 80 --log shots.csv`,
/// 2026-12-07): the emitting spheres' own shots take it from 1 to 0.30 in 2.7 s, then
/// each shot takes off about 0.4 %. In the viewer (`nusselt bench --only live`), handing
/// over at 0.2 (after 8 s of shooting) converged at 50 s, at 0.1 (after 17 s) at 57 s: the
/// hierarchy's refinement costs the same from either, so shooting longer only delays it,
/// and the displayed image was 13.6 % and 12.5 % from the converged one meanwhile.
pub const HANDOFF_UNSHOT: f64 = 0.2;

/// Whether `solver` is shooting on a scene `auto` would solve hierarchically, and has
/// spread all but [`HANDOFF_UNSHOT`] of the power.
pub fn due(solver: &dyn Solver) -> bool {
    solver.shooting().is_some() && ready(solver.problem(), solver.residual())
}

/// Whether a shooting solve of `problem` with `unshot` of its power left would be handed
/// over: the scene is one `auto` solves hierarchically and `unshot` is at most
/// [`HANDOFF_UNSHOT`].
pub fn ready(problem: &Problem, unshot: f64) -> bool {
    unshot <= HANDOFF_UNSHOT
        && auto::choose(problem, RunShape::default()).0 == SolverKind::Hierarchical
}

/// The hierarchical solve that goes on from `solver`'s shot solution (its cached rows are
/// dropped); `solver` itself where it is not shooting.
pub fn hand_over(solver: Box<dyn Solver>) -> Box<dyn Solver> {
    let Some(shooting) = solver.shooting() else {
        return solver;
    };
    let unshot = shooting.unshot().to_vec();
    let radiosity = solver.radiosity().to_vec();
    let (problem, rows) = solver.into_parts();
    drop(rows);
    let mut next = HierarchicalSolver::new(problem);
    next.continue_from(&radiosity, &unshot);
    Box::new(next)
}

#[cfg(test)]
mod tests;
