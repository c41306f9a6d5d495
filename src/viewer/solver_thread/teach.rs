//! Teaching mode on the solver thread (`viewer::teach`): recording single steps, one step
//! back by replaying from dark, and keeping the hemicube view up to date.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use crate::viewer::teach::TeachCommand;
use crate::viewer::teach::hemicube;
use crate::viewer::teach::matrix::MatrixWork;
use crate::viewer::teach::step::{Before, capture};

use super::Event;
use super::worker::Worker;

impl Worker {
    pub(super) fn teach(&mut self, command: TeachCommand) {
        match command {
            TeachCommand::RecordSteps(on) => {
                self.record_steps = on;
                if !on {
                    self.step_detail = None;
                }
            }
            TeachCommand::Back => self.back(),
            TeachCommand::Matrix(on) => {
                self.matrix_detail = None;
                self.matrix_published = None;
                self.matrix_work = None;
                if on && let (Some(s), Some(g)) = (&self.solver, &self.geometry) {
                    match MatrixWork::new(s.problem(), g.id) {
                        Ok(w) => self.matrix_work = Some(w),
                        Err(e) => self.send_event(Event::Error(e)),
                    }
                }
            }
            TeachCommand::Nusselt(request) => {
                self.nusselt_request = request;
                self.nusselt_key = None;
                if request.is_none() {
                    self.nusselt_detail = None;
                }
            }
            TeachCommand::Hemicube(request) => {
                self.hemicube_request = request;
                if request.is_none() {
                    self.hemicube_detail = None;
                    self.hemicube_key = None;
                }
            }
        }
    }

    /// One step back: reset, then replay to one step before the current one (rows come
    /// from the cache and every solver here is deterministic, so this is the earlier
    /// state). The last replayed step is recorded, so its numbers show again. Pauses.
    fn back(&mut self) {
        let record = self.record_steps;
        let Some(solver) = self.solver.as_mut() else {
            return;
        };
        if solver.unshot().is_none() {
            // A gathering solver keeps its matrix on reset, so replaying its steps (rows,
            // then sweeps) would not give the earlier state.
            self.send_event(Event::Error(
                "Back replays shots: it needs the shooting solver".into(),
            ));
            return;
        }
        let target = solver.steps().saturating_sub(1);
        self.playing = false;
        self.steps = 0;
        solver.reset();
        // Not the shared cancel flag: a command arriving now must not leave a half replay.
        let never = AtomicBool::new(false);
        for _ in 1..target {
            if !solver.step(&never) {
                break;
            }
        }
        self.step_detail = None;
        if target > 0 {
            let before = record.then(|| Before::take(solver.as_ref())).flatten();
            if solver.step(&never)
                && let (Some(b), Some(g)) = (before, &self.geometry)
            {
                self.step_detail = capture(b, solver.as_ref(), g).map(Arc::new);
            }
        }
        let steps = solver.steps();
        Arc::make_mut(&mut self.history).retain(|p| p.steps <= steps);
    }

    /// Whether the matrix view has rows left to compute (while nothing else runs).
    pub(super) fn teach_work_pending(&self) -> bool {
        match (&self.matrix_work, &self.solver) {
            (Some(w), Some(s)) => !w.complete(s.problem()),
            _ => false,
        }
    }

    /// One row of the matrix view, when the solver has nothing to do.
    pub(super) fn teach_work_once(&mut self) {
        if self.wants_to_step() || !self.teach_work_pending() {
            return;
        }
        let (Some(work), Some(solver)) = (self.matrix_work.as_mut(), &self.solver) else {
            return;
        };
        let first = hemicube::teaching_patch(solver.problem(), None, solver.last_shooter());
        if work.step(solver.problem(), first, &self.cancel) {
            self.dirty = true;
        }
    }

    /// Rebuilds what the matrix view shows, at most four times a second (a copy of the
    /// matrix), or at once when the shooter changed or the matrix was completed; starts it
    /// again on a new mesh.
    pub(super) fn refresh_matrix(&mut self) {
        let (Some(work), Some(solver), Some(geometry)) =
            (self.matrix_work.as_mut(), &self.solver, &self.geometry)
        else {
            return;
        };
        if work.geometry_id != geometry.id {
            match MatrixWork::new(solver.problem(), geometry.id) {
                Ok(w) => *work = w,
                Err(e) => {
                    self.matrix_work = None;
                    self.matrix_detail = None;
                    self.send_event(Event::Error(e));
                    return;
                }
            }
        }
        let shooter = hemicube::teaching_patch(solver.problem(), None, solver.last_shooter());
        let done = work.rows_done();
        let due = match self.matrix_published {
            None => true,
            Some((at, rows, s)) => {
                s != shooter
                    || (rows != done
                        && (at.elapsed() >= Duration::from_millis(250)
                            || work.complete(solver.problem())))
            }
        };
        if due {
            self.matrix_detail = Some(Arc::new(work.detail(solver.problem(), geometry, shooter)));
            self.matrix_published = Some((Instant::now(), done, shooter));
        }
    }

    /// Recomputes the Nusselt view asked for when its shooter or the mesh changed (cheap:
    /// a few thousand ray-polygon tests).
    pub(super) fn refresh_nusselt(&mut self) {
        let (Some(request), Some(solver), Some(geometry)) =
            (self.nusselt_request, &self.solver, &self.geometry)
        else {
            return;
        };
        let last = solver.last_shooter();
        let key = (request, last.map(|p| p.0), geometry.id);
        if self.nusselt_key == Some(key) {
            return;
        }
        self.nusselt_key = Some(key);
        self.nusselt_detail =
            crate::viewer::teach::nusselt::compute(solver.problem(), request, last).map(Arc::new);
    }

    /// Recomputes the hemicube asked for when its shooter or the mesh changed.
    pub(super) fn refresh_hemicube(&mut self) {
        let (Some(request), Some(solver), Some(geometry)) =
            (self.hemicube_request, &self.solver, &self.geometry)
        else {
            return;
        };
        let last = solver.last_shooter();
        let key = (request, last.map(|p| p.0), geometry.id);
        if self.hemicube_key == Some(key) {
            return;
        }
        // While the solve runs the shooter changes every shot: redraw four times a second
        // at most (a new request, from the slider, is answered at once; the publish that
        // ends a solve is not throttled, as nothing is left to step then).
        let same_request = self
            .hemicube_key
            .is_some_and(|k| k.0 == request && k.2 == geometry.id);
        if self.wants_to_step()
            && same_request
            && self
                .hemicube_drawn
                .is_some_and(|t| t.elapsed() < Duration::from_millis(250))
        {
            return;
        }
        self.hemicube_key = Some(key);
        self.hemicube_drawn = Some(Instant::now());
        self.hemicube_detail = hemicube::compute(solver.problem(), request, last).map(Arc::new);
    }
}
