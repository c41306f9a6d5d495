//! Teaching mode on the solver thread (`viewer::teach`): recording single steps, one step
//! back by replaying from dark, and keeping the hemicube view up to date.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use crate::teach::TeachCommand;
use crate::teach::compare::{CompareCommand, CompareWork};
use crate::teach::hemicube;
use crate::teach::matrix::MatrixWork;
use crate::teach::meshing::MeshJob;
use crate::teach::step::{Before, capture};

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
            TeachCommand::Compare(c) => self.compare_command(c),
            TeachCommand::Mesh(tolerance) => {
                self.mesh_job = None;
                self.mesh_detail = None;
                if let Some(t) = tolerance {
                    self.start_mesh_job(t);
                }
                self.dirty = true;
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
        if solver.shooting().is_none() {
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

    fn compare_command(&mut self, command: CompareCommand) {
        match command {
            CompareCommand::On { steps } => {
                self.compare_work = None;
                self.compare_detail = None;
                if let (Some(s), Some(g)) = (&self.solver, &self.geometry) {
                    match CompareWork::new(s.problem(), g, &self.scene_camera, steps) {
                        Ok(w) => self.compare_work = Some(w),
                        Err(e) => self.send_event(Event::Error(e)),
                    }
                }
            }
            CompareCommand::Off => {
                self.compare_work = None;
                self.compare_detail = None;
            }
            other => {
                if let Some(w) = self.compare_work.as_mut() {
                    w.apply(other);
                }
            }
        }
        self.dirty = true;
    }

    fn start_mesh_job(&mut self, tolerance: f64) {
        let (Some(solver), Some(geometry)) = (&self.solver, &self.geometry) else {
            return;
        };
        match MeshJob::start(
            solver.problem().scene.clone(),
            self.config.clone(),
            self.scene_camera,
            geometry.id,
            tolerance,
        ) {
            Ok(job) => self.mesh_job = Some(job),
            Err(e) => self.send_event(Event::Error(e)),
        }
    }

    /// How long the thread may wait for a command before teaching work is due (a
    /// comparison playing at its rate, a meshing job to poll).
    pub(super) fn teach_wait(&self) -> Option<Duration> {
        let compare = self
            .compare_work
            .as_ref()
            .and_then(|w| w.wait(Instant::now()));
        let mesh = self.mesh_job.as_ref().map(|_| Duration::from_millis(100));
        match (compare, mesh) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// Whether a teaching view has work to do now: matrix rows (while nothing else runs),
    /// comparison rows or steps that are due, a finished meshing job to collect.
    pub(super) fn teach_work_pending(&self) -> bool {
        let matrix = match (&self.matrix_work, &self.solver) {
            (Some(w), Some(s)) => !w.complete(s.problem()),
            _ => false,
        };
        let compare = self.solver.is_some()
            && self
                .compare_work
                .as_ref()
                .is_some_and(|w| w.pending(Instant::now()));
        let mesh = self.mesh_job.as_ref().is_some_and(MeshJob::finished);
        matrix || compare || mesh
    }

    /// Collects a finished meshing job, advances the comparison, then (when the solver has
    /// nothing to do) one row of the matrix view.
    pub(super) fn teach_work_once(&mut self) {
        if self.mesh_job.as_ref().is_some_and(MeshJob::finished)
            && let Some(job) = self.mesh_job.take()
        {
            match job.join() {
                Ok(d) => self.mesh_detail = Some(Arc::new(d)),
                Err(e) => self.send_event(Event::Error(e)),
            }
            self.dirty = true;
        }
        if let (Some(w), Some(s)) = (self.compare_work.as_mut(), &self.solver)
            && w.pending(Instant::now())
        {
            w.work(s.problem(), &self.cancel);
            self.dirty = true;
        }
        if self.wants_to_step() || !self.teach_work_pending() {
            return;
        }
        let (Some(work), Some(solver)) = (self.matrix_work.as_mut(), &self.solver) else {
            return;
        };
        let first = hemicube::teaching_patch(
            solver.problem(),
            None,
            solver.shooting().and_then(|s| s.last_shooter()),
        );
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
        let shooter = hemicube::teaching_patch(
            solver.problem(),
            None,
            solver.shooting().and_then(|s| s.last_shooter()),
        );
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

    /// Publishes the comparison when it changed; starts it again on a new mesh.
    pub(super) fn refresh_compare(&mut self) {
        let (Some(work), Some(solver), Some(geometry)) =
            (self.compare_work.as_mut(), &self.solver, &self.geometry)
        else {
            return;
        };
        if work.geometry_id != geometry.id {
            match CompareWork::new(solver.problem(), geometry, &self.scene_camera, 0) {
                Ok(w) => *work = w,
                Err(e) => {
                    self.compare_work = None;
                    self.compare_detail = None;
                    self.send_event(Event::Error(e));
                    return;
                }
            }
        }
        if work.changed {
            self.compare_detail = Some(Arc::new(work.detail()));
        }
    }

    /// Starts the meshing view again when the viewer's mesh changed under it.
    pub(super) fn refresh_mesh_view(&mut self) {
        let Some(geometry) = &self.geometry else {
            return;
        };
        let id = geometry.id;
        let stale_job = self.mesh_job.as_ref().filter(|j| j.geometry_id != id);
        let stale_detail = self.mesh_detail.as_ref().filter(|d| d.geometry_id != id);
        let tolerance = stale_job
            .map(|j| j.tolerance)
            .or(stale_detail.map(|d| d.tolerance));
        if let Some(t) = tolerance {
            self.mesh_job = None;
            self.mesh_detail = None;
            self.start_mesh_job(t);
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
        let last = solver.shooting().and_then(|s| s.last_shooter());
        let key = (request, last.map(|p| p.0), geometry.id);
        if self.nusselt_key == Some(key) {
            return;
        }
        self.nusselt_key = Some(key);
        self.nusselt_detail =
            crate::teach::nusselt::compute(solver.problem(), request, last).map(Arc::new);
    }

    /// Recomputes the hemicube asked for when its shooter or the mesh changed.
    pub(super) fn refresh_hemicube(&mut self) {
        let (Some(request), Some(solver), Some(geometry)) =
            (self.hemicube_request, &self.solver, &self.geometry)
        else {
            return;
        };
        let last = solver.shooting().and_then(|s| s.last_shooter());
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
