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
//! ([`HierarchicalSolver::continue_from`]): the image stays the shots' until the first
//! gather, which starts from the shot light.
//!
//! The shots have already computed the lights' direct light, exactly as a row of each
//! emitting patch gives it; the hierarchy takes it as given ([`emitters_direct`] from the
//! shots' cached rows, [`HierarchicalSolver::set_direct`]) and links only reflected light
//! (`render`'s auto does the same from dark, [`HierarchicalSolver::lights_by_rows`]). From dark, its
//! first refinement links every element to the lights (on the atrium 3.2 M links of four
//! shadow rays, ill-suited to two small bright spheres that each element sees whole) and
//! its second links again by the first bounce; handed over, one refinement by the light
//! as shot does the second's work and the first's is not needed. The direct light, most of
//! the image, is then the same in the shots' image and the converged one, so the image
//! shown until the first gather is closer to the converged one too.
//!
//! Measured on the atrium (`nusselt bench --only live`, 2026-12-07, quiet machine, one run
//! each): from dark, the first gathered image at 17–20 s (12.8 % from the converged one)
//! and converged at 38.9 s; handed over at 20 % unshot (10 s) with the lights linked, 20 %
//! from 8 s, 13.4 % from 11 s, 2.0 % at 40 s and converged at 43.1 s. On a machine of the
//! same kind about half as fast (`--live-seconds 100`, one run each, same day): with the
//! lights linked, handed over at 17 s, 13.4 % at 20 s, the first gather at 35 s (12.9 %),
//! converged at 71.1 s, peak 1,775 MB; with the direct light from the rows, handed over at
//! 20 s, 6.9 % at 20 s and 6.6 % until the first gather at 50 s (0.44 %), converged at
//! 56.4 s, peak 1,625 MB.
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

/// The hierarchical solve that goes on from `solver`'s shot solution, with the emitters'
/// direct light taken from the shots' rows ([`HierarchicalSolver::set_direct`]; the rows
/// are dropped then; a light's row no longer cached is computed again); `solver` itself
/// where it is not shooting.
pub fn hand_over(solver: Box<dyn Solver>) -> Box<dyn Solver> {
    let Some(shooting) = solver.shooting() else {
        return solver;
    };
    let unshot = shooting.unshot().to_vec();
    let radiosity = solver.radiosity().to_vec();
    let (problem, rows) = solver.into_parts();
    let never = AtomicBool::new(false);
    let direct = emitters_direct(&problem, &mut rows.unwrap_or_default(), &never);
    let mut next = HierarchicalSolver::new(problem);
    next.continue_from(&radiosity, &unshot);
    if let Some(direct) = direct {
        next.set_direct(direct);
    }
    Box::new(next)
}

#[cfg(test)]
mod tests;
