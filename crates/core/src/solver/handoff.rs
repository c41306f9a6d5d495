//! Shooting, then hierarchical: what `auto` does in the viewer on a large scene.
//!
//! Each solver is fast at one half of the job. Progressive shooting spreads the lights'
//! power first (Cohen et al. 1988), so with the ambient term its image is close early, but
//! every shot costs a row of form factors to every element: on the 263 k-triangle Crytek
//! atrium (227 k elements) it leaves about 1.3 % unshot after three minutes. Hierarchical
//! radiosity (Hanrahan et al. 1991) converges there in about 40 s, but from dark it shows
//! only the emission and the ambient estimate (55 % from the converged image) until its
//! first refinement and gather, about 13 s. So the viewer shoots until [`HANDOFF_UNSHOT`]
//! of the power is left, which takes the lights and the brightest surfaces a few seconds,
//! then goes on hierarchically from the shot solution
//! ([`HierarchicalSolver::continue_from_shots`]): the image stays the shots' until the
//! first gather.
//!
//! The links then carry only the light not yet shot ([`super::hierarchical::remainder`]):
//! the converged answer is the shots' radiosity plus the unshot light's transport, so
//! what the shots delivered (the lights' direct light, exactly as the rows give it, and
//! the first bounces of the brightest surfaces) keeps the rows' accuracy, and the image
//! shown until the first gather is close to the converged one. Before, the hierarchy took
//! the lights' direct light from the shots' rows ([`HierarchicalSolver::set_direct`]) and
//! re-solved all the reflected light over its links: its converged image of the atrium
//! was 6.6–6.9 % from the shots' image at the handover, in broad smooth regions where a
//! coarse link spreads its estimate. The link tolerance is the same absolute bound per
//! link as from dark, so with less light to carry the links are coarser and fewer. A scene
//! with a sky, sun or point light is handed over as before (the direct light from the
//! rows, all reflected light over the links): there the unshot light alone came back too
//! dark (`remainder`'s module docs).
//!
//! Measured on the atrium (`nusselt bench --only live --live-model
//! ../shared/models/crytek_sponza/sponza.obj --live-seconds 70`, 2-core AMD EPYC,
//! 2026-12-08, one run each): with the direct light from the rows and all reflected light
//! linked, handed over at about 20 s, 6.9 % from the last image at 20 s and until the
//! first gather at 30–40 s; with only the unshot light linked, handed over at 15–20 s,
//! 4.5 % at 20 s, the first gather between 30 and 40 s (0.6 %), a residual of 1e-3 at
//! 50.0 s and converged at 51.3 s, peak 1,680 MB. On the Cornell box handed over at 10 % unshot
//! (patches of one element), the handed-over answer is 1.1 % from the element-to-element
//! solution and the hierarchy's from dark 0.7 %: the same bound per link, on less light.
//!
//! Only scenes that `auto` would solve hierarchically without an image to show
//! ([`super::auto::choose`]) are handed over; smaller ones shoot to the end.

use std::sync::atomic::AtomicBool;

use super::auto::{self, RunShape};
use super::hierarchical::direct::emitters_direct;
use super::{HierarchicalSolver, Problem, Solver, SolverKind};

/// The unshot fraction at which a large scene's shooting hands over. Measured on the
/// Crytek atrium (`render sponza.obj --solver shooting --shots 80 --log shots.csv`,
/// 2026-12-07): the emitting spheres' own shots take it from 1 to 0.30 in 2.7 s, then
/// each shot takes off about 0.4 %, so 0.2 is about 6 s of shooting. In the viewer the
/// displayed image was then 13.6 % from the converged one, no further than the
/// hierarchy's first gathered image (12.8 %): shooting on would only delay that gather.
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

/// The hierarchical solve that goes on from `solver`'s shot solution; `solver` itself
/// where it is not shooting. Its links carry only the unshot light
/// ([`HierarchicalSolver::continue_from_shots`]) where the scene has no sky, sun or point
/// light; with them, the emitters' direct light is taken from the shots' rows
/// ([`HierarchicalSolver::set_direct`]; a light's row no longer cached is computed again)
/// and the links carry all the reflected light (module docs: why).
pub fn hand_over(solver: Box<dyn Solver>) -> Box<dyn Solver> {
    let Some(shooting) = solver.shooting() else {
        return solver;
    };
    let unshot = shooting.unshot().to_vec();
    let radiosity = solver.radiosity().to_vec();
    let (problem, rows) = solver.into_parts();
    let remainder = problem.external.is_empty();
    let direct = if remainder {
        None
    } else {
        emitters_direct(
            &problem,
            &mut rows.unwrap_or_default(),
            &AtomicBool::new(false),
        )
    };
    let mut next = HierarchicalSolver::new(problem);
    if remainder {
        next.continue_from_shots(&radiosity, &unshot);
    } else {
        next.continue_from(&radiosity, &unshot);
        if let Some(direct) = direct {
            next.set_direct(direct);
        }
    }
    Box::new(next)
}

#[cfg(test)]
mod tests;
