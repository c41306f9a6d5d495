//! The solver thread's side: a [`Worker`] owns the solver (a `Box<dyn Solver>` of the
//! chosen [`SolverKind`]), applies [`Command`]s, steps it while there is something to do,
//! and publishes [`Snapshot`]s. Changing the mesh, the form-factor method or the solver
//! goes through [`Solver::into_parts`] (in `switch.rs`).

use std::panic::AssertUnwindSafe;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TryRecvError, TrySendError};
use std::time::{Duration, Instant};

use nusselt_core::mesh::MeshSpec;
use nusselt_core::scene::{AreaLight, LoadOptions, Material, MaterialId, Rgb, Scene};
use nusselt_core::solver::ambient::RegionalAmbient;
use nusselt_core::solver::{Problem, Solver, SolverConfig, SolverKind};

use super::super::snapshot::{Geometry, HistoryPoint, Snapshot, vertex_reflectance};
use super::super::teach::step::Before;
use super::publish::Published;
use super::ray_input::RayInput;
use super::teach::Teaching;
use super::texture_job::TextureJob;
use super::{Command, Event, HISTORY_CAPACITY, Latest, ThreadConfig, Waker};

/// The solver thread's state. The solve's own state is here; the teaching views'
/// ([`Teaching`]), the ray-traced view's input ([`RayInput`]) and what was published when
/// ([`Published`]) are grouped in their own structs.
pub(super) struct Worker {
    pub(super) rx: Receiver<Command>,
    pub(super) events: SyncSender<Event>,
    pub(super) cancel: Arc<AtomicBool>,
    pub(super) latest: Arc<Latest<Arc<Snapshot>>>,
    pub(super) waker: Waker,
    pub(super) solver: Option<Box<dyn Solver>>,
    /// The kind of `solver` (and of the next one built, on a load).
    pub(super) kind: SolverKind,
    /// The solver's last step found nothing to do (not cancelled): stepping stops until a
    /// command changes something.
    pub(super) exhausted: bool,
    pub(super) loaded_materials: Arc<Vec<Material>>,
    pub(super) geometry: Option<Arc<Geometry>>,
    pub(super) reflectance: Arc<Vec<[f32; 3]>>,
    pub(super) reflectance_rev: u64,
    /// The current scene's diffuse maps as texture-array layers (built once per scene).
    pub(super) textures: Option<Arc<crate::textures::TextureLayers>>,
    /// The texture array being built for the current scene (`texture_job.rs`).
    pub(super) texture_job: Option<TextureJob>,
    /// The texture array is to be started once the current scene's first image is out.
    pub(super) texture_job_due: bool,
    pub(super) next_id: u64,
    pub(super) scene_rev: u64,
    /// The first view of the current scene (`render::view::default_camera`), chosen once
    /// per load.
    pub(super) scene_camera: nusselt_core::scene::Camera,
    pub(super) playing: bool,
    /// Single steps still to take.
    pub(super) steps: usize,
    pub(super) stop_unshot: f64,
    pub(super) max_shots: Option<usize>,
    /// The solver is `auto`'s: a large scene's shooting is handed over (`handoff.rs`).
    pub(super) handoff: bool,
    pub(super) config: SolverConfig,
    pub(super) history: Arc<Vec<HistoryPoint>>,
    /// Solve time since the last (re)start, pauses excluded.
    pub(super) elapsed: Duration,
    /// Something changed since the last publish (set by every concern: solving, edits,
    /// teaching views, adaptive refinement).
    pub(super) dirty: bool,
    /// What was published when (`publish.rs`).
    pub(super) published: Published,
    /// Set by [`Command::PanicOnNextShot`].
    pub(super) panic_on_next_shot: Option<String>,
    /// Teaching mode's views (`teach.rs`).
    pub(super) teach: Teaching,
    /// The ray-traced view's input (`ray_input.rs`).
    pub(super) ray: RayInput,
    /// Adaptive refinement in progress (`adapt.rs`).
    pub(super) adapting: Option<super::adapt::Adapting>,
    /// The scene's area lights, read for this (mesh id, reflectance revision).
    pub(super) area_lights: ((u64, u64), Arc<Vec<AreaLight>>),
}

enum Flow {
    Continue,
    Quit,
}

impl Worker {
    pub(super) fn new(
        rx: Receiver<Command>,
        events: SyncSender<Event>,
        cancel: Arc<AtomicBool>,
        latest: Arc<Latest<Arc<Snapshot>>>,
        waker: Waker,
        config: ThreadConfig,
    ) -> Worker {
        Worker {
            rx,
            events,
            cancel,
            latest,
            waker,
            solver: None,
            kind: config.kind,
            exhausted: false,
            loaded_materials: Arc::new(Vec::new()),
            geometry: None,
            reflectance: Arc::new(Vec::new()),
            reflectance_rev: 0,
            textures: None,
            texture_job: None,
            texture_job_due: false,
            next_id: 1,
            scene_rev: 0,
            scene_camera: nusselt_core::scene::Camera::cornell(),
            playing: config.play,
            steps: 0,
            stop_unshot: config.stop_unshot,
            max_shots: config.max_shots,
            handoff: config.handoff,
            config: config.solver,
            history: Arc::new(Vec::new()),
            elapsed: Duration::ZERO,
            dirty: false,
            published: Published::default(),
            panic_on_next_shot: None,
            teach: Teaching::default(),
            ray: RayInput::default(),
            adapting: None,
            area_lights: ((0, 0), Arc::new(Vec::new())),
        }
    }

    pub(super) fn run(mut self, scene: Scene) {
        let config = self.config.clone();
        self.guarded(Some(scene.name.clone()), true, |w| w.install(scene, config));
        loop {
            self.cancel.store(false, Ordering::Relaxed);
            self.poll_textures();
            // Drain what is queued; block only when there is nothing to shoot.
            loop {
                let command = if self.wants_to_shoot() || self.teach_work_pending() {
                    match self.rx.try_recv() {
                        Ok(c) => c,
                        Err(TryRecvError::Empty) => break,
                        Err(TryRecvError::Disconnected) => return,
                    }
                } else {
                    if self.dirty {
                        self.guarded(None, false, Self::publish);
                    }
                    // Wake up now and then even if idle so a lost waker cannot stall
                    // anything; no work is done on these wake-ups.
                    let mut wait = self.teach.wait().unwrap_or(Duration::from_millis(500));
                    if self.texture_job.is_some() {
                        wait = wait.min(Duration::from_millis(20));
                    }
                    match self.rx.recv_timeout(wait) {
                        Ok(c) => c,
                        Err(RecvTimeoutError::Timeout) => {
                            // The meshing view's job reports its stage.
                            self.dirty |= self.teach.meshing();
                            self.poll_textures();
                            continue;
                        }
                        Err(RecvTimeoutError::Disconnected) => return,
                    }
                };
                let (scene, loads) = match &command {
                    Command::LoadPath(p) => (Some(p.display().to_string()), true),
                    Command::LoadScene(s) => (Some(s.name.clone()), true),
                    _ => (None, false),
                };
                if let Some(Flow::Quit) = self.guarded(scene, loads, |w| w.apply(command)) {
                    return;
                }
            }
            if self.dirty && self.due() {
                self.guarded(None, false, Self::publish);
            }
            self.guarded(None, false, Self::shoot_once);
            self.guarded(None, false, Self::handoff_once);
            self.guarded(None, false, Self::adapt_once);
            self.guarded(None, false, Self::teach_work_once);
        }
    }

    /// Runs `work` (shooting, re-meshing, loading, publishing: everything that calls into
    /// the solver) and turns a panic in it into [`Event::Failed`] naming `scene` (default:
    /// the current one). The solver is dropped, since its state after a panic is unknown,
    /// unless `loads` and the panic came before the new scene was installed (the current
    /// one is then untouched and stays, as for a load error). Nothing is published after a
    /// drop, so the UI keeps the last snapshot; the thread lives on for new commands.
    fn guarded<T>(
        &mut self,
        scene: Option<String>,
        loads: bool,
        work: impl FnOnce(&mut Self) -> T,
    ) -> Option<T> {
        let scene_rev = self.scene_rev;
        let scene = scene.unwrap_or_else(|| {
            self.solver.as_ref().map_or_else(
                || "no scene".to_string(),
                |s| s.problem().scene.name.clone(),
            )
        });
        match std::panic::catch_unwind(AssertUnwindSafe(|| work(self))) {
            Ok(v) => Some(v),
            Err(payload) => {
                let message = payload
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| payload.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "(no message)".to_string());
                if !(loads && self.scene_rev == scene_rev) {
                    self.solver = None;
                    self.geometry = None;
                    self.playing = false;
                    self.steps = 0;
                    self.dirty = false;
                }
                self.send_event(Event::Failed(format!(
                    "solver failed on {scene}: {message}"
                )));
                None
            }
        }
    }

    fn wants_to_shoot(&self) -> bool {
        let Some(solver) = &self.solver else {
            return false;
        };
        (self.playing || self.steps > 0)
            && !self.exhausted
            && solver.residual() > self.stop_unshot
            && self.max_shots.is_none_or(|m| solver.steps() < m)
    }

    fn due(&self) -> bool {
        self.published.due()
    }

    fn shoot_once(&mut self) {
        if !self.wants_to_shoot() {
            return;
        }
        if let Some(message) = self.panic_on_next_shot.take() {
            panic!("{message}");
        }
        let Some(solver) = self.solver.as_mut() else {
            return;
        };
        // Teaching mode records single steps (not a running solve: it costs a copy of the
        // state and a row).
        let before = (self.teach.record_steps && !self.playing)
            .then(|| Before::take(solver.as_ref()))
            .flatten();
        let start = Instant::now();
        let stepped = solver.step(&self.cancel);
        self.elapsed += start.elapsed();
        if stepped {
            self.teach.step_detail = match (before, &self.geometry) {
                (Some(b), Some(g)) => {
                    crate::teach::step::capture(b, solver.as_ref(), g).map(Arc::new)
                }
                _ => None,
            };
        }
        if !stepped {
            // Cancelled (a command is waiting: nothing changed), or nothing left to do.
            if !self.cancel.load(Ordering::Relaxed) {
                self.exhausted = true;
                self.dirty = true;
            }
            return;
        }
        self.steps = self.steps.saturating_sub(1);
        let point = HistoryPoint {
            seconds: self.elapsed.as_secs_f64(),
            steps: solver.steps(),
            residual: solver.residual(),
            ambient: nusselt_core::solver::ambient_mean(solver.as_ref()),
        };
        let history = Arc::make_mut(&mut self.history);
        if history.len() >= HISTORY_CAPACITY {
            // Keep every other point: the plot is log-scaled in time anyway.
            let mut keep = false;
            history.retain(|_| {
                keep = !keep;
                keep
            });
        }
        history.push(point);
        self.dirty = true;
        // The first steps and single steps show at once; later ones when due
        // (`Published::due`), or when the solve just ended.
        if point.steps <= 3 || self.due() || !self.wants_to_shoot() {
            self.publish();
        }
    }

    pub(super) fn wants_to_step(&self) -> bool {
        self.wants_to_shoot()
    }

    pub(super) fn send_event(&self, event: Event) {
        if let Err(TrySendError::Full(e)) = self.events.try_send(event) {
            eprintln!("viewer: dropped a notice, the UI is not reading them: {e:?}");
        }
    }

    /// Replaces the solver with one of the current kind for `scene`; on error the old one
    /// stays. A kind that refuses the new problem (its matrix over the memory budget)
    /// falls back to shooting, with an error event saying why.
    fn install(&mut self, scene: Scene, config: SolverConfig) {
        if self.handoff {
            // Auto starts every scene shooting (a handed-over one was hierarchical).
            self.kind = SolverKind::Shooting;
        }
        let name = scene.name.clone();
        let source = scene.source.clone();
        let first_view = |s: &Scene| nusselt_core::render::view::default_camera(s);
        match Problem::new_alongside(scene, config.clone(), first_view) {
            Ok((problem, camera)) => {
                self.loaded_materials = Arc::new(problem.scene.materials.clone());
                self.config = config;
                self.solver = None;
                self.textures = None;
                self.scene_rev += 1;
                self.texture_job = None;
                self.texture_job_due = true;
                let (geometry, regional) = self.prepare_view(&problem);
                self.scene_camera = camera;
                self.build(problem, Default::default());
                if let (Some(r), Some(s)) = (
                    regional,
                    self.solver.as_mut().and_then(|s| s.shooting_mut()),
                ) {
                    s.use_regional_ambient(r);
                }
                self.install_geometry(geometry);
                self.send_event(Event::Loaded { name, source });
            }
            Err(e) => self.send_event(Event::Error(format!("{name}: {e}"))),
        }
        self.dirty = true;
    }

    /// The drawing arrays and (for shooting with the regional ambient term) the regional
    /// transport of a new problem, built side by side: on a 200 k-triangle model each takes
    /// a few tenths of a second, and the first lit frame waits for both.
    fn prepare_view(&mut self, problem: &Problem) -> (Geometry, Option<RegionalAmbient>) {
        let id = self.next_id;
        self.next_id += 1;
        let regional =
            matches!(self.kind, SolverKind::Shooting) && problem.config.shooting.regional_ambient;
        rayon::join(
            || Geometry::from_problem(id, problem),
            || regional.then(|| RegionalAmbient::build(problem)),
        )
    }

    pub(super) fn new_geometry(&mut self) {
        let Some(solver) = &self.solver else { return };
        let g = Geometry::from_problem(self.next_id, solver.problem());
        self.next_id += 1;
        self.install_geometry(g);
    }

    /// Makes `g` (built for the current solver's mesh) the drawn geometry.
    fn install_geometry(&mut self, g: Geometry) {
        let Some(solver) = &self.solver else { return };
        self.reflectance = Arc::new(vertex_reflectance(&g, &solver.problem().scene.materials));
        self.reflectance_rev += 1;
        self.geometry = Some(Arc::new(g));
    }

    pub(super) fn restart_clock(&mut self) {
        self.teach.step_detail = None;
        self.elapsed = Duration::ZERO;
        self.history = Arc::new(Vec::new());
        self.dirty = true;
    }

    fn apply(&mut self, command: Command) -> Flow {
        // Whatever the command, the solver may have something to do again.
        self.exhausted = false;
        match command {
            Command::Quit => return Flow::Quit,
            Command::PanicOnNextShot(message) => self.panic_on_next_shot = Some(message),
            Command::Play => self.playing = true,
            Command::Pause => {
                self.playing = false;
                self.steps = 0;
            }
            Command::Step => {
                self.playing = false;
                self.steps += 1;
            }
            Command::Reset => {
                if let Some(s) = self.solver.as_mut() {
                    s.reset();
                    self.restart_clock();
                }
            }
            Command::Remesh(size) => self.remesh(size),
            Command::SetMaterial {
                material,
                reflectance,
                emission,
            } => self.set_material(material, Rgb::from(reflectance), Rgb::from(emission)),
            Command::SaveScene { path, camera } => {
                if let Some(s) = self.solver.as_ref() {
                    let file = self.scene_file(s.as_ref(), camera, &path);
                    match file.save(&path) {
                        Ok(()) => {
                            self.send_event(Event::Notice(format!("saved {}", path.display())))
                        }
                        Err(e) => self.send_event(Event::Error(format!("save scene: {e}"))),
                    }
                }
            }
            Command::SetAreaLights(lights) => self.set_area_lights(lights),
            Command::SetLights(lights) => {
                if let Some(s) = self.solver.as_mut() {
                    s.set_lights(lights);
                    self.published.edit_unpublished = true;
                    self.dirty = true;
                }
            }
            Command::ResetMaterials => {
                let loaded = self.loaded_materials.clone();
                for (i, m) in loaded.iter().enumerate() {
                    let current = self
                        .solver
                        .as_ref()
                        .and_then(|s| s.problem().scene.materials.get(i).cloned());
                    if current.is_some_and(|c| c != *m) {
                        self.set_material(MaterialId(i as u32), m.reflectance, m.emission);
                    }
                }
            }
            Command::SetMethod(method) => self.set_method(method),
            Command::SetSolver(kind) => self.set_solver(kind),
            Command::Teach(t) => self.teach(t),
            Command::Adapt(t) => self.start_adapting(t),
            Command::RayTraced(on) => self.ray.set_on(on),
            Command::LoadPath(path) => match load_path(&path) {
                Ok((scene, None)) => self.load(scene),
                Ok((scene, Some(file))) => self.load_scene_file(scene, &file),
                Err(e) => self.send_event(Event::Error(e.to_string())),
            },
            Command::LoadScene(scene) => self.load(*scene),
            Command::SetStopThreshold(t) => {
                if t.is_finite() && t >= 0.0 {
                    self.stop_unshot = t;
                    self.dirty = true;
                } else {
                    self.send_event(Event::Error(format!(
                        "stop threshold must be a finite number >= 0, got {t}"
                    )));
                }
            }
        }
        self.dirty = true;
        Flow::Continue
    }

    /// What "Save scene" writes: the scene as it is now, with the mesh's element size and
    /// the solver settings in use.
    fn scene_file(
        &self,
        solver: &dyn Solver,
        camera: Option<nusselt_core::scene::Camera>,
        path: &std::path::Path,
    ) -> nusselt_core::scene::SceneFile {
        use nusselt_core::scene::file::{MeshEntry, SolverEntry};
        let problem = solver.problem();
        let mut file = nusselt_core::scene::SceneFile::describe(&problem.scene, camera, path);
        file.mesh = Some(MeshEntry {
            element_size: Some(problem.mesh.element_size),
            patch_size: problem.config.mesh.patch_size,
            max_elements: problem.config.mesh.max_elements,
            discontinuity: problem.config.mesh.discontinuity,
        });
        file.solver = Some(SolverEntry {
            name: Some(self.kind.name().into()),
            formfactor: Some(problem.config.formfactor.method.name().into()),
            unshot: Some(self.stop_unshot),
        });
        file
    }

    fn load(&mut self, scene: Scene) {
        // A new scene gets its own default element size, the other settings stay.
        let config = SolverConfig {
            mesh: MeshSpec {
                element_size: None,
                patch_size: None,
                ..self.config.mesh
            },
            ..self.config.clone()
        };
        self.install_lit(scene, config);
    }

    /// [`Worker::install`] after default lights are added to a scene without any (and
    /// the user told so).
    fn install_lit(&mut self, mut scene: Scene, config: SolverConfig) {
        if let Some(message) = scene.add_default_lights() {
            self.send_event(Event::Notice(format!("{}: {message}", scene.name)));
        }
        self.install(scene, config);
    }

    /// A scene file opened from the viewer: its mesh and solver settings apply as they do
    /// to `nusselt view FILE` (the file's `mesh` replaces the mesh settings, unset fields
    /// at their defaults; `solver.name` "auto" is shooting here, as in `view`). The
    /// file's values were checked when it was read.
    fn load_scene_file(&mut self, scene: Scene, file: &nusselt_core::scene::SceneFile) {
        if let Some(solver) = &file.solver {
            let kind = match solver.name.as_deref() {
                None => None,
                Some("auto") => Some(SolverKind::Shooting),
                Some(name) => SolverKind::parse(name, None),
            };
            if let Some(kind) = kind {
                self.kind = kind;
                self.handoff = solver.name.as_deref() == Some("auto");
            }
            if let Some(method) = solver.formfactor.as_deref().and_then(|m| m.parse().ok()) {
                self.config.formfactor.method = match self.start_raster_for(method) {
                    Ok(()) => method,
                    Err(e) => {
                        self.send_event(Event::Error(format!("{e}; using contour")));
                        nusselt_core::formfactor::FormFactorMethod::Contour
                    }
                };
            }
            if let Some(unshot) = solver.unshot {
                self.stop_unshot = unshot;
            }
        }
        let Some(mesh) = file.mesh else {
            self.load(scene);
            return;
        };
        let config = SolverConfig {
            mesh: MeshSpec {
                element_size: mesh.element_size,
                patch_size: mesh.patch_size,
                max_elements: mesh.max_elements,
                discontinuity: mesh.discontinuity,
            },
            ..self.config.clone()
        };
        self.install_lit(scene, config);
    }

    pub(super) fn set_material(&mut self, id: MaterialId, reflectance: Rgb, emission: Rgb) {
        let Some(s) = self.solver.as_mut() else {
            return;
        };
        match s.set_material(id, reflectance, emission) {
            Ok(()) => {
                self.published.edit_unpublished = true;
                if let Some(g) = &self.geometry {
                    self.reflectance =
                        Arc::new(vertex_reflectance(g, &s.problem().scene.materials));
                    self.reflectance_rev += 1;
                }
            }
            Err(e) => self.send_event(Event::Error(format!("edit: {e}"))),
        }
    }
}

/// A model, or a scene file and the scene it describes, by extension.
fn load_path(
    path: &std::path::Path,
) -> Result<(Scene, Option<nusselt_core::scene::SceneFile>), nusselt_core::scene::SceneError> {
    if nusselt_core::scene::is_scene_file(path) {
        let file = nusselt_core::scene::SceneFile::read(path)?;
        let scene = file.load(path)?;
        Ok((scene, Some(file)))
    } else {
        Ok((Scene::load(path, &LoadOptions::default())?, None))
    }
}
