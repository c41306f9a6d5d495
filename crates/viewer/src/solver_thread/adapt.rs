//! Adaptive meshing while the viewer solves (`view --adaptive TOL`, "refine adaptively" in
//! the solver panel): each time the solve has shot all but [`ADAPT_UNSHOT`] of the
//! emitted power, the elements whose radiance varies across them by more than the
//! tolerance are refined one level (`mesh::adaptive`, Cohen et al. 1986: their patch
//! cut into four, elements halved), and the solution is carried onto the refined mesh
//! (`Solver::carry_to`; solvers that cannot restart from dark there), so the mesh grows
//! on screen (wireframe) until nothing exceeds the tolerance, [`MAX_LEVEL`]
//! levels are reached, or the mesh would pass `mesh::MAX_ELEMENTS`. Refined patches where
//! nothing varies any more (a light dimmed) are coarsened a level on the same passes.

use nusselt_core::mesh::Mesh;
use nusselt_core::solver::Problem;
use nusselt_core::solver::refine::next_levels;

use super::Event;
use super::worker::Worker;

/// Refine when this fraction of the emitted power is left unshot (the indicator needs the
/// solution's shape, not its last digits).
pub const ADAPT_UNSHOT: f64 = 1e-3;

/// Most refinement levels per base patch (each quarters its elements' area).
pub const MAX_LEVEL: u8 = 3;

/// Most refinement passes: enough to reach [`MAX_LEVEL`] and coarsen back where the light
/// settled; a bound, should refining and coarsening ever alternate.
pub const MAX_PASSES: u32 = 2 * MAX_LEVEL as u32 + 2;

/// An adaptive refinement in progress.
#[derive(Debug, Clone)]
pub(super) struct Adapting {
    pub tolerance: f64,
    /// Refinement level per base patch of the current mesh.
    pub levels: Vec<u8>,
    pub passes: u32,
}

impl Worker {
    /// Starts (or, with `None`, stops) refining adaptively from the current mesh.
    pub(super) fn start_adapting(&mut self, tolerance: Option<f64>) {
        match tolerance {
            None => self.adapting = None,
            Some(t) if t.is_finite() && t > 0.0 => {
                self.adapting = Some(Adapting {
                    tolerance: t,
                    levels: Vec::new(),
                    passes: 0,
                });
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
        let (Some(a), Some(solver)) = (self.adapting.as_ref(), self.solver.as_ref()) else {
            return;
        };
        if solver.residual() > ADAPT_UNSHOT.max(self.stop_unshot) && !self.exhausted {
            return;
        }
        let mesh = &solver.problem().mesh;
        let radiance = solver.radiosity().to_vec();
        let next = next_levels(
            solver.problem(),
            &radiance,
            &a.levels,
            a.tolerance,
            MAX_LEVEL,
        );
        let level = |v: &[u8], b: u32| i32::from(v.get(b as usize).copied().unwrap_or(0));
        let estimate: f64 = mesh
            .patches
            .iter()
            .zip(&mesh.base_patch)
            .map(|(p, &b)| {
                f64::from(p.elements.end - p.elements.start)
                    * 4f64.powi(level(&next, b) - level(&a.levels, b))
            })
            .sum();
        if next == a.levels
            || a.passes >= MAX_PASSES
            || estimate > nusselt_core::mesh::MAX_ELEMENTS as f64
        {
            // Done: the solve goes on to convergence on this mesh.
            self.adapting = None;
            self.dirty = true;
            return;
        }
        let built = Mesh::build_refined(
            &solver.problem().scene,
            mesh.element_size,
            mesh.patch_size,
            &next,
            solver.problem().config.discontinuity,
        );
        let mesh = match built {
            Ok(m) => m,
            Err(e) => {
                self.adapting = None;
                self.send_event(Event::Error(format!("adaptive refinement: {e}")));
                return;
            }
        };
        let Some(mut solver) = self.solver.take() else {
            return;
        };
        let solved = solver.problem();
        match Problem::with_mesh(solved.scene.clone(), solved.config.clone(), mesh) {
            Ok(p) => {
                // Carried where the solver can (shooting: the light already shot and
                // delivered is kept, the lights re-aimed through the finer rows); else
                // from dark.
                let start = std::time::Instant::now();
                match nusselt_core::solver::carry_solution(solver.as_mut(), p, &self.cancel) {
                    Ok(carried) => {
                        // The same solve going on: its clock (which counts the carry's
                        // rows) and history go on too.
                        self.elapsed += start.elapsed();
                        self.solver = Some(carried);
                        self.teach.step_detail = None;
                        self.dirty = true;
                    }
                    Err(p) => self.build(*p, None),
                }
                self.new_geometry();
                if let Some(a) = self.adapting.as_mut() {
                    a.levels = next;
                    a.passes += 1;
                }
                self.playing = true;
                self.exhausted = false;
            }
            Err(e) => {
                // The solve goes on, on the mesh it had.
                self.solver = Some(solver);
                self.adapting = None;
                self.send_event(Event::Error(format!("adaptive refinement: {e}")));
            }
        }
    }
}
