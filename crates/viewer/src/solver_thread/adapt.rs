//! Adaptive meshing while the viewer solves (`view --adaptive TOL`, "refine adaptively" in
//! the solver panel), by the core's one refinement routine
//! (`nusselt_core::solver::refine::Refinement`, whose module docs give the stop rules):
//! each time the solve is far enough ([`Refinement::due`]), the elements whose radiance
//! varies across them by more than the tolerance are refined one level
//! (`mesh::adaptive`, Cohen et al. 1986: their patch cut into four, elements halved), and
//! the solution is carried onto the refined mesh (`Shooting::carry_to`; solvers that cannot
//! restart from dark there), so the mesh grows on screen (wireframe) until nothing exceeds
//! the tolerance, [`MAX_LEVEL`] levels are reached, or the next mesh would not fit. Refined
//! patches where nothing varies any more (a light dimmed) are coarsened a level on the same
//! passes.

use nusselt_core::solver::refine::{Next, Refinement};

use super::Event;
use super::worker::Worker;

/// Most refinement levels per base patch (each quarters its elements' area).
pub const MAX_LEVEL: u8 = 3;

/// Most refinement passes: enough to reach [`MAX_LEVEL`] and coarsen back where the light
/// settled; a bound, should refining and coarsening ever alternate.
pub const MAX_PASSES: u32 = 2 * MAX_LEVEL as u32 + 2;

/// An adaptive refinement in progress.
pub(super) type Adapting = Refinement;

impl Worker {
    /// Starts (or, with `None`, stops) refining adaptively from the current mesh.
    pub(super) fn start_adapting(&mut self, tolerance: Option<f64>) {
        match tolerance {
            None => self.adapting = None,
            Some(t) if t.is_finite() && t > 0.0 => {
                self.adapting = Some(Refinement::new(t, MAX_PASSES, MAX_LEVEL));
                self.playing = true;
            }
            Some(t) => self.send_event(Event::Error(format!(
                "adaptive tolerance must be a positive number, got {t}"
            ))),
        }
    }

    /// One refinement, when one is due: the solve is far enough and something exceeds the
    /// tolerance. Ends the refinement when nothing does.
    pub(super) fn adapt_once(&mut self) {
        let (Some(a), Some(solver)) = (self.adapting.as_mut(), self.solver.as_ref()) else {
            return;
        };
        if !Refinement::due(solver.residual(), self.stop_unshot) && !self.exhausted {
            return;
        }
        let refined = match a.next(solver.problem(), solver.radiosity()) {
            Ok(Next::Refined(p)) => p,
            Ok(Next::Done { stopped }) => {
                // Done: the solve goes on to convergence on this mesh.
                self.adapting = None;
                self.dirty = true;
                if let Some(why) = stopped {
                    self.send_event(Event::Notice(why));
                }
                return;
            }
            Err(e) => {
                // The solve goes on, on the mesh it had.
                self.adapting = None;
                self.send_event(Event::Error(format!("adaptive refinement: {e}")));
                return;
            }
        };
        let Some(mut solver) = self.solver.take() else {
            return;
        };
        // Carried where the solver can (shooting: the light already shot and delivered is
        // kept, the lights re-aimed through the finer rows); else from dark.
        let start = std::time::Instant::now();
        match nusselt_core::solver::carry_solution(solver.as_mut(), *refined, &self.cancel) {
            Ok(carried) => {
                // The same solve going on: its clock (which counts the carry's rows) and
                // history go on too.
                self.elapsed += start.elapsed();
                self.solver = Some(carried);
                self.teach.step_detail = None;
                self.dirty = true;
            }
            Err(p) => self.build(*p, None),
        }
        self.new_geometry();
        self.playing = true;
        self.exhausted = false;
    }
}
