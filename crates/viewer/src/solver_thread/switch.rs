//! Changing what the worker solves with: re-meshing, another form-factor method, another
//! solver. Each takes the solver apart ([`nusselt_core::solver::Solver::into_parts`]), changes the
//! problem or the kind, and builds the new solver on the same problem and cached rows
//! ([`SolverKind::build_with_rows`]); each restarts from dark. A change that is refused
//! leaves the user with what they had.

use std::sync::Arc;

use nusselt_core::formfactor::FormFactorMethod;
use nusselt_core::formfactor::hemicube::ItemBufferRaster;
use nusselt_core::solver::{Problem, RowCache, SolverKind};

use super::Event;
use super::worker::Worker;

impl Worker {
    /// Builds a solver of the current kind on `problem`, reusing `rows`. A kind that
    /// refuses the problem (a matrix over the memory budget) falls back to shooting, which
    /// takes any problem, with an error event saying why.
    pub(super) fn build(&mut self, problem: Problem, rows: RowCache) {
        let kind = match self.kind.check(&problem) {
            Ok(()) => self.kind,
            Err(e) => {
                self.send_event(Event::Error(format!("{e}; solving with shooting instead")));
                SolverKind::Shooting
            }
        };
        match kind.build_with_rows(problem, rows) {
            Ok(solver) => {
                self.kind = kind;
                self.solver = Some(solver);
            }
            // `check` passed, so this is not expected; the problem is gone with the error.
            Err(e) => self.send_event(Event::Failed(format!("cannot build the solver: {e}"))),
        }
        self.restart_clock();
    }

    /// Re-meshes at `size` and restarts from dark on the new mesh. On error the old mesh
    /// (and its cached rows) stay.
    pub(super) fn remesh(&mut self, size: f64) {
        if !(size.is_finite() && size > 0.0) {
            // Refused before anything is taken apart, so the solve goes on as it was.
            self.send_event(Event::Error(format!(
                "re-mesh: the element size must be a positive number, got {size}"
            )));
            return;
        }
        let Some(solver) = self.solver.take() else {
            return;
        };
        let (mut problem, mut rows) = solver.into_parts();
        match problem.remesh(size) {
            Ok(()) => {
                rows.clear();
                self.config.element_size = Some(size);
                self.build(problem, rows);
                self.new_geometry();
            }
            Err(e) => {
                // `Problem::remesh` left the problem as it was: same mesh, rows still valid.
                self.send_event(Event::Error(format!("re-mesh: {e}")));
                self.build(problem, rows);
            }
        }
    }

    /// Switches the form-factor method (cached rows dropped) and restarts from dark. The
    /// GPU hemicube is started on first use; if it cannot be, nothing changes.
    pub(super) fn set_method(&mut self, method: FormFactorMethod) {
        if method == FormFactorMethod::GpuHemicube && self.config.raster.is_none() {
            match nusselt_gpu::GpuHemicube::new() {
                Ok(gpu) => {
                    let raster: Arc<dyn ItemBufferRaster> = Arc::new(gpu);
                    self.config.raster = Some(raster);
                }
                Err(e) => {
                    self.send_event(Event::Error(format!("gpu-hemicube: {e}")));
                    return;
                }
            }
        }
        let Some(solver) = self.solver.take() else {
            return;
        };
        let (mut problem, mut rows) = solver.into_parts();
        if problem.config.raster.is_none() {
            problem.set_raster(self.config.raster.clone());
        }
        problem.config.method = method;
        rows.clear();
        self.config.method = method;
        self.build(problem, rows);
    }

    /// Switches to a solver of `kind` on the same mesh and cached rows, from dark. Refused
    /// (the current solver goes on, an error event says why) when `kind` would refuse the
    /// problem: ω out of range, a matrix over the memory budget.
    pub(super) fn set_solver(&mut self, kind: SolverKind) {
        let Some(current) = self.solver.as_ref() else {
            // Nothing loaded (a failed solve): the next load uses it.
            self.kind = kind;
            return;
        };
        if let Err(e) = kind.check(current.problem()) {
            self.send_event(Event::Error(format!(
                "cannot switch to {}: {e}",
                kind.name()
            )));
            return;
        }
        let Some(solver) = self.solver.take() else {
            return;
        };
        let (problem, rows) = solver.into_parts();
        self.kind = kind;
        self.build(problem, rows);
    }
}
