//! Teaching mode on the solver thread (`viewer::teach`): recording single steps, one step
//! back by replaying from dark, and keeping the teaching views (hemicube, Nusselt analog,
//! matrix, shooting vs gathering, meshing) up to date. Their state is a [`Teaching`], kept
//! apart from the solve's so a reader of [`Worker`] sees the two concerns separately.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use nusselt_core::solver::Solver;

use crate::snapshot::Geometry;
use crate::teach::TeachCommand;
use crate::teach::compare::{CompareCommand, CompareDetail, CompareWork};
use crate::teach::hemicube::{self, HemicubeDetail, HemicubeRequest};
use crate::teach::matrix::{MatrixDetail, MatrixWork};
use crate::teach::meshing::{MeshDetail, MeshJob};
use crate::teach::nusselt::{NusseltDetail, NusseltRequest};
use crate::teach::step::{Before, StepDetail, capture};

use super::Event;
use super::worker::Worker;

/// The teaching views' state: what each asked for, the work computing it, what was last
/// computed (published in every snapshot) and for what.
#[derive(Default)]
pub(super) struct Teaching {
    /// Record single steps, and the last one recorded.
    pub(super) record_steps: bool,
    pub(super) step_detail: Option<Arc<StepDetail>>,
    /// The hemicube asked for and the one computed.
    hemicube_request: Option<HemicubeRequest>,
    hemicube_detail: Option<Arc<HemicubeDetail>>,
    /// What `hemicube_detail` was computed for: request, last shooter, mesh.
    hemicube_key: Option<(HemicubeRequest, Option<u32>, u64)>,
    hemicube_drawn: Option<Instant>,
    /// The Nusselt view asked for, the one computed, and for what (request, shooter, mesh).
    nusselt_request: Option<NusseltRequest>,
    nusselt_detail: Option<Arc<NusseltDetail>>,
    nusselt_key: Option<(NusseltRequest, Option<u32>, u64)>,
    /// The matrix view's rows, filled while idle, and what was last published of it.
    matrix_work: Option<MatrixWork>,
    matrix_detail: Option<Arc<MatrixDetail>>,
    matrix_published: Option<(Instant, usize, Option<u32>)>,
    /// Shooting vs gathering: the comparison run, and what was last published of it.
    compare_work: Option<CompareWork>,
    compare_detail: Option<Arc<CompareDetail>>,
    /// Uniform vs adaptive meshing: the job computing it, and its result.
    mesh_job: Option<MeshJob>,
    mesh_detail: Option<Arc<MeshDetail>>,
}

/// What a snapshot carries of teaching mode.
pub(super) struct TeachingView {
    pub(super) step: Option<Arc<StepDetail>>,
    pub(super) hemicube: Option<Arc<HemicubeDetail>>,
    pub(super) matrix: Option<Arc<MatrixDetail>>,
    pub(super) nusselt: Option<Arc<NusseltDetail>>,
    pub(super) compare: Option<Arc<CompareDetail>>,
    pub(super) mesh: Option<Arc<MeshDetail>>,
    pub(super) mesh_stage: Option<&'static str>,
}

impl Teaching {
    /// What the next snapshot shows of the teaching views.
    pub(super) fn view(&self) -> TeachingView {
        TeachingView {
            step: self.step_detail.clone(),
            hemicube: self.hemicube_detail.clone(),
            matrix: self.matrix_detail.clone(),
            nusselt: self.nusselt_detail.clone(),
            compare: self.compare_detail.clone(),
            mesh: self.mesh_detail.clone(),
            mesh_stage: self.mesh_job.as_ref().map(|j| j.stage()),
        }
    }

    /// Whether the meshing view's job runs (its stage is reported while it does).
    pub(super) fn meshing(&self) -> bool {
        self.mesh_job.is_some()
    }

    /// How long the thread may wait for a command before teaching work is due (a
    /// comparison playing at its rate, a meshing job to poll).
    pub(super) fn wait(&self) -> Option<Duration> {
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
    pub(super) fn work_pending(&self, solver: Option<&dyn Solver>) -> bool {
        let matrix = match (&self.matrix_work, solver) {
            (Some(w), Some(s)) => !w.complete(s.problem()),
            _ => false,
        };
        let compare = solver.is_some()
            && self
                .compare_work
                .as_ref()
                .is_some_and(|w| w.pending(Instant::now()));
        let mesh = self.mesh_job.as_ref().is_some_and(MeshJob::finished);
        matrix || compare || mesh
    }

    /// The meshing view's job's result once it finished: `None` while it runs or when
    /// there is none; the result is kept for the view, an error returned.
    fn collect_mesh_job(&mut self) -> Option<Result<(), String>> {
        if !self.mesh_job.as_ref().is_some_and(MeshJob::finished) {
            return None;
        }
        let job = self.mesh_job.take()?;
        Some(match job.join() {
            Ok(d) => {
                self.mesh_detail = Some(Arc::new(d));
                Ok(())
            }
            Err(e) => Err(e),
        })
    }

    /// Rebuilds what the matrix view shows, at most four times a second (a copy of the
    /// matrix), or at once when the shooter changed or the matrix was completed; starts it
    /// again on a new mesh (an error there turns the view off).
    fn refresh_matrix(&mut self, solver: &dyn Solver, geometry: &Geometry) -> Result<(), String> {
        let Some(work) = self.matrix_work.as_mut() else {
            return Ok(());
        };
        if work.geometry_id != geometry.id {
            match MatrixWork::new(solver.problem(), geometry.id) {
                Ok(w) => *work = w,
                Err(e) => {
                    self.matrix_work = None;
                    self.matrix_detail = None;
                    return Err(e);
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
        Ok(())
    }

    /// Publishes the comparison when it changed; starts it again on a new mesh (an error
    /// there turns the view off).
    fn refresh_compare(
        &mut self,
        solver: &dyn Solver,
        geometry: &Geometry,
        camera: &nusselt_core::scene::Camera,
    ) -> Result<(), String> {
        let Some(work) = self.compare_work.as_mut() else {
            return Ok(());
        };
        if work.geometry_id != geometry.id {
            match CompareWork::new(solver.problem(), geometry, camera, 0) {
                Ok(w) => *work = w,
                Err(e) => {
                    self.compare_work = None;
                    self.compare_detail = None;
                    return Err(e);
                }
            }
        }
        if work.changed {
            self.compare_detail = Some(Arc::new(work.detail()));
        }
        Ok(())
    }

    /// The tolerance of a meshing view made for another mesh than `geometry_id` (dropped
    /// here), to start it again on this one.
    fn take_stale_mesh_view(&mut self, geometry_id: u64) -> Option<f64> {
        let stale_job = self
            .mesh_job
            .as_ref()
            .filter(|j| j.geometry_id != geometry_id);
        let stale_detail = self
            .mesh_detail
            .as_ref()
            .filter(|d| d.geometry_id != geometry_id);
        let tolerance = stale_job
            .map(|j| j.tolerance)
            .or(stale_detail.map(|d| d.tolerance))?;
        self.mesh_job = None;
        self.mesh_detail = None;
        Some(tolerance)
    }

    /// Recomputes the Nusselt view asked for when its shooter or the mesh changed (cheap:
    /// a few thousand ray-polygon tests).
    fn refresh_nusselt(&mut self, solver: &dyn Solver, geometry: &Geometry) {
        let Some(request) = self.nusselt_request else {
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
}

impl Worker {
    pub(super) fn teach(&mut self, command: TeachCommand) {
        let teach = &mut self.teach;
        match command {
            TeachCommand::RecordSteps(on) => {
                teach.record_steps = on;
                if !on {
                    teach.step_detail = None;
                }
            }
            TeachCommand::Back => self.back(),
            TeachCommand::Matrix(on) => {
                teach.matrix_detail = None;
                teach.matrix_published = None;
                teach.matrix_work = None;
                if on && let (Some(s), Some(g)) = (&self.solver, &self.geometry) {
                    match MatrixWork::new(s.problem(), g.id) {
                        Ok(w) => teach.matrix_work = Some(w),
                        Err(e) => self.send_event(Event::Error(e)),
                    }
                }
            }
            TeachCommand::Nusselt(request) => {
                teach.nusselt_request = request;
                teach.nusselt_key = None;
                if request.is_none() {
                    teach.nusselt_detail = None;
                }
            }
            TeachCommand::Compare(c) => self.compare_command(c),
            TeachCommand::Mesh(tolerance) => {
                teach.mesh_job = None;
                teach.mesh_detail = None;
                if let Some(t) = tolerance {
                    self.start_mesh_job(t);
                }
                self.dirty = true;
            }
            TeachCommand::Hemicube(request) => {
                teach.hemicube_request = request;
                if request.is_none() {
                    teach.hemicube_detail = None;
                    teach.hemicube_key = None;
                }
            }
        }
    }

    /// One step back: reset, then replay to one step before the current one (rows come
    /// from the cache and every solver here is deterministic, so this is the earlier
    /// state). The last replayed step is recorded, so its numbers show again. Pauses.
    fn back(&mut self) {
        let record = self.teach.record_steps;
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
        self.teach.step_detail = None;
        if target > 0 {
            let before = record.then(|| Before::take(solver.as_ref())).flatten();
            if solver.step(&never)
                && let (Some(b), Some(g)) = (before, &self.geometry)
            {
                self.teach.step_detail = capture(b, solver.as_ref(), g).map(Arc::new);
            }
        }
        let steps = solver.steps();
        Arc::make_mut(&mut self.history).retain(|p| p.steps <= steps);
    }

    fn compare_command(&mut self, command: CompareCommand) {
        let teach = &mut self.teach;
        match command {
            CompareCommand::On { steps } => {
                teach.compare_work = None;
                teach.compare_detail = None;
                if let (Some(s), Some(g)) = (&self.solver, &self.geometry) {
                    match CompareWork::new(s.problem(), g, &self.scene_camera, steps) {
                        Ok(w) => teach.compare_work = Some(w),
                        Err(e) => self.send_event(Event::Error(e)),
                    }
                }
            }
            CompareCommand::Off => {
                teach.compare_work = None;
                teach.compare_detail = None;
            }
            other => {
                if let Some(w) = teach.compare_work.as_mut() {
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
            Ok(job) => self.teach.mesh_job = Some(job),
            Err(e) => self.send_event(Event::Error(e)),
        }
    }

    /// Whether a teaching view has work to do now (see [`Teaching::work_pending`]).
    pub(super) fn teach_work_pending(&self) -> bool {
        self.teach.work_pending(self.solver.as_deref())
    }

    /// Collects a finished meshing job, advances the comparison, then (when the solver has
    /// nothing to do) one row of the matrix view.
    pub(super) fn teach_work_once(&mut self) {
        if let Some(collected) = self.teach.collect_mesh_job() {
            if let Err(e) = collected {
                self.send_event(Event::Error(e));
            }
            self.dirty = true;
        }
        if let (Some(w), Some(s)) = (self.teach.compare_work.as_mut(), &self.solver)
            && w.pending(Instant::now())
        {
            w.work(s.problem(), &self.cancel);
            self.dirty = true;
        }
        if self.wants_to_step() || !self.teach_work_pending() {
            return;
        }
        let (Some(work), Some(solver)) = (self.teach.matrix_work.as_mut(), &self.solver) else {
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

    /// Brings every teaching view up to date before a publish, in this order: hemicube,
    /// matrix, Nusselt, comparison, meshing.
    pub(super) fn refresh_teaching(&mut self) {
        self.refresh_hemicube();
        if let (Some(solver), Some(geometry)) = (&self.solver, &self.geometry)
            && let Err(e) = self.teach.refresh_matrix(solver.as_ref(), geometry)
        {
            self.send_event(Event::Error(e));
        }
        if let (Some(solver), Some(geometry)) = (&self.solver, &self.geometry) {
            self.teach.refresh_nusselt(solver.as_ref(), geometry);
        }
        if let (Some(solver), Some(geometry)) = (&self.solver, &self.geometry)
            && let Err(e) =
                self.teach
                    .refresh_compare(solver.as_ref(), geometry, &self.scene_camera)
        {
            self.send_event(Event::Error(e));
        }
        self.refresh_mesh_view();
    }

    /// Starts the meshing view again when the viewer's mesh changed under it.
    fn refresh_mesh_view(&mut self) {
        let Some(geometry) = &self.geometry else {
            return;
        };
        if let Some(t) = self.teach.take_stale_mesh_view(geometry.id) {
            self.start_mesh_job(t);
        }
    }

    /// Recomputes the hemicube asked for when its shooter or the mesh changed.
    fn refresh_hemicube(&mut self) {
        let (Some(request), Some(solver), Some(geometry)) =
            (self.teach.hemicube_request, &self.solver, &self.geometry)
        else {
            return;
        };
        let last = solver.shooting().and_then(|s| s.last_shooter());
        let key = (request, last.map(|p| p.0), geometry.id);
        if self.teach.hemicube_key == Some(key) {
            return;
        }
        // While the solve runs the shooter changes every shot: redraw four times a second
        // at most (a new request, from the slider, is answered at once; the publish that
        // ends a solve is not throttled, as nothing is left to step then).
        let same_request = self
            .teach
            .hemicube_key
            .is_some_and(|k| k.0 == request && k.2 == geometry.id);
        if self.wants_to_step()
            && same_request
            && self
                .teach
                .hemicube_drawn
                .is_some_and(|t| t.elapsed() < Duration::from_millis(250))
        {
            return;
        }
        let teach = &mut self.teach;
        teach.hemicube_key = Some(key);
        teach.hemicube_drawn = Some(Instant::now());
        teach.hemicube_detail = hemicube::compute(solver.problem(), request, last).map(Arc::new);
    }
}
