//! The solver thread's side: a [`Worker`] owns the [`ProgressiveSolver`], applies
//! [`Command`]s, shoots while there is something to shoot, and publishes [`Snapshot`]s.

use std::panic::AssertUnwindSafe;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TryRecvError, TrySendError};
use std::time::{Duration, Instant};

use crate::formfactor::FormFactorMethod;
use crate::formfactor::hemicube::ItemBufferRaster;
use crate::mesh::PatchId;
use crate::scene::{LoadOptions, Material, MaterialId, Rgb, Scene};
use crate::solver::{ProgressiveSolver, SolverConfig};

use super::super::snapshot::{Geometry, HistoryPoint, Snapshot, Stats, vertex_reflectance};
use super::{Command, Event, HISTORY_CAPACITY, Latest, PUBLISH_INTERVAL, ThreadConfig, Waker};

pub(super) struct Worker {
    rx: Receiver<Command>,
    events: SyncSender<Event>,
    cancel: Arc<AtomicBool>,
    latest: Arc<Latest<Arc<Snapshot>>>,
    waker: Waker,
    solver: Option<ProgressiveSolver>,
    loaded_materials: Arc<Vec<Material>>,
    geometry: Option<Arc<Geometry>>,
    reflectance: Arc<Vec<[f32; 3]>>,
    reflectance_rev: u64,
    next_id: u64,
    scene_rev: u64,
    seq: u64,
    playing: bool,
    steps: usize,
    stop_unshot: f64,
    max_shots: Option<usize>,
    config: SolverConfig,
    history: Arc<Vec<HistoryPoint>>,
    /// Solve time since the last (re)start, pauses excluded.
    elapsed: Duration,
    last_publish: Option<Instant>,
    /// Something changed since the last publish.
    dirty: bool,
    /// A material edit was applied and not yet published.
    edit_unpublished: bool,
    edit_published: Option<Instant>,
    /// Set by [`Command::PanicOnNextShot`].
    panic_on_next_shot: Option<String>,
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
            loaded_materials: Arc::new(Vec::new()),
            geometry: None,
            reflectance: Arc::new(Vec::new()),
            reflectance_rev: 0,
            next_id: 1,
            scene_rev: 0,
            seq: 0,
            playing: config.play,
            steps: 0,
            stop_unshot: config.stop_unshot,
            max_shots: config.max_shots,
            config: config.solver,
            history: Arc::new(Vec::new()),
            elapsed: Duration::ZERO,
            last_publish: None,
            dirty: false,
            edit_unpublished: false,
            edit_published: None,
            panic_on_next_shot: None,
        }
    }

    pub(super) fn run(mut self, scene: Scene) {
        let config = self.config.clone();
        self.guarded(Some(scene.name.clone()), true, |w| w.install(scene, config));
        loop {
            self.cancel.store(false, Ordering::Relaxed);
            // Drain what is queued; block only when there is nothing to shoot.
            loop {
                let command = if self.wants_to_shoot() {
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
                    match self.rx.recv_timeout(Duration::from_millis(500)) {
                        Ok(c) => c,
                        Err(RecvTimeoutError::Timeout) => continue,
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
            self.solver
                .as_ref()
                .map_or_else(|| "no scene".to_string(), |s| s.scene().name.clone())
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
            && solver.unshot_fraction() > self.stop_unshot
            && self.max_shots.is_none_or(|m| solver.shots() < m)
            && solver.next_shooter().is_some()
    }

    fn due(&self) -> bool {
        self.last_publish
            .is_none_or(|t| t.elapsed() >= PUBLISH_INTERVAL)
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
        let start = Instant::now();
        let shot = solver.shoot(&self.cancel);
        self.elapsed += start.elapsed();
        if shot.is_none() {
            // Cancelled (a command is waiting) or nothing left: nothing changed.
            return;
        }
        self.steps = self.steps.saturating_sub(1);
        let ambient = solver.ambient();
        let point = HistoryPoint {
            seconds: self.elapsed.as_secs_f64(),
            shots: solver.shots(),
            unshot_fraction: solver.unshot_fraction(),
            ambient: (ambient.x + ambient.y + ambient.z) / 3.0,
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
        // The first shots and single steps show at once; later ones at most every
        // PUBLISH_INTERVAL, or when the solve just ended.
        if point.shots <= 3 || self.due() || !self.wants_to_shoot() {
            self.publish();
        }
    }

    fn send_event(&self, event: Event) {
        if let Err(TrySendError::Full(e)) = self.events.try_send(event) {
            eprintln!("viewer: dropped a notice, the UI is not reading them: {e:?}");
        }
    }

    /// Replaces the solver with one for `scene`; on error the old one stays.
    fn install(&mut self, scene: Scene, config: SolverConfig) {
        let name = scene.name.clone();
        let source = scene.source.clone();
        match ProgressiveSolver::new(scene, config.clone()) {
            Ok(solver) => {
                self.loaded_materials = Arc::new(solver.scene().materials.clone());
                self.config = config;
                self.solver = Some(solver);
                self.scene_rev += 1;
                self.new_geometry();
                self.restart_clock();
                self.send_event(Event::Loaded { name, source });
            }
            Err(e) => self.send_event(Event::Error(format!("{name}: {e}"))),
        }
        self.dirty = true;
    }

    fn new_geometry(&mut self) {
        let Some(solver) = &self.solver else { return };
        let g = Geometry::from_mesh(self.next_id, solver.mesh());
        self.next_id += 1;
        self.reflectance = Arc::new(vertex_reflectance(&g, solver));
        self.reflectance_rev += 1;
        self.geometry = Some(Arc::new(g));
    }

    fn restart_clock(&mut self) {
        self.elapsed = Duration::ZERO;
        self.history = Arc::new(Vec::new());
        self.dirty = true;
    }

    fn apply(&mut self, command: Command) -> Flow {
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
            Command::Remesh(size) => {
                if let Some(s) = self.solver.as_mut() {
                    match s.remesh(size) {
                        Ok(()) => {
                            self.config.element_size = Some(size);
                            self.new_geometry();
                            self.restart_clock();
                        }
                        Err(e) => self.send_event(Event::Error(format!("re-mesh: {e}"))),
                    }
                }
            }
            Command::SetMaterial {
                material,
                reflectance,
                emission,
            } => self.set_material(material, Rgb::from(reflectance), Rgb::from(emission)),
            Command::ResetMaterials => {
                let loaded = self.loaded_materials.clone();
                for (i, m) in loaded.iter().enumerate() {
                    let current = self
                        .solver
                        .as_ref()
                        .and_then(|s| s.scene().materials.get(i).cloned());
                    if current.is_some_and(|c| c != *m) {
                        self.set_material(MaterialId(i as u32), m.reflectance, m.emission);
                    }
                }
            }
            Command::SetMethod(method) => {
                if method == FormFactorMethod::GpuHemicube && self.config.raster.is_none() {
                    // Started on first use: creating a device takes a moment.
                    match crate::gpu::GpuHemicube::new() {
                        Ok(gpu) => {
                            let raster: Arc<dyn ItemBufferRaster> = Arc::new(gpu);
                            self.config.raster = Some(raster.clone());
                            if let Some(s) = self.solver.as_mut() {
                                s.set_raster(Some(raster));
                            }
                        }
                        Err(e) => self.send_event(Event::Error(format!("gpu-hemicube: {e}"))),
                    }
                }
                if let Some(s) = self.solver.as_mut() {
                    match s.set_method(method) {
                        Ok(()) => {
                            self.config.method = method;
                            self.restart_clock();
                        }
                        Err(e) => self.send_event(Event::Error(e.to_string())),
                    }
                }
            }
            Command::LoadPath(path) => match Scene::load_obj(&path, &LoadOptions::default()) {
                Ok(scene) => self.load(scene),
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

    fn load(&mut self, scene: Scene) {
        // A new scene gets its own default element size, the other settings stay.
        let config = SolverConfig {
            element_size: None,
            patch_size: None,
            ..self.config.clone()
        };
        self.install(scene, config);
    }

    fn set_material(&mut self, id: MaterialId, reflectance: Rgb, emission: Rgb) {
        let Some(s) = self.solver.as_mut() else {
            return;
        };
        match s.set_material(id, reflectance, emission) {
            Ok(()) => {
                self.edit_unpublished = true;
                if let Some(g) = &self.geometry {
                    self.reflectance = Arc::new(vertex_reflectance(g, s));
                    self.reflectance_rev += 1;
                }
            }
            Err(e) => self.send_event(Event::Error(format!("edit: {e}"))),
        }
    }

    fn publish(&mut self) {
        let (Some(solver), Some(geometry)) = (&self.solver, &self.geometry) else {
            return;
        };
        let per_vertex = solver.mesh().vertex_values(&solver.element_radiance(false));
        let radiance = geometry.expand(&per_vertex);
        debug_assert!(radiance.iter().flatten().all(|x| x.is_finite()));
        let ambient = solver.ambient();
        debug_assert!(ambient.is_finite());
        let shots_per_second = {
            let h = &self.history;
            match (
                h.last(),
                h.iter()
                    .rev()
                    .find(|p| h.last().is_some_and(|l| l.seconds - p.seconds >= 1.0)),
            ) {
                (Some(l), Some(p)) => (l.shots - p.shots) as f64 / (l.seconds - p.seconds),
                (Some(l), None) if l.seconds > 0.0 => l.shots as f64 / l.seconds,
                _ => 0.0,
            }
        };
        let unshot_fraction = solver.unshot_fraction();
        let stats = Stats {
            elements: geometry.elements,
            patches: geometry.patches,
            shots: solver.shots(),
            shots_per_second,
            unshot_fraction,
            elapsed_seconds: self.elapsed.as_secs_f64(),
            playing: self.playing,
            converged: unshot_fraction <= self.stop_unshot || solver.next_shooter().is_none(),
            limit_reached: self.max_shots.is_some_and(|m| solver.shots() >= m),
            last_shooter: solver.last_shooter().map(|p: PatchId| p.0),
            next_shooter: solver.next_shooter().map(|p| p.0),
        };
        self.seq += 1;
        let now = Instant::now();
        if self.edit_unpublished {
            self.edit_unpublished = false;
            self.edit_published = Some(now);
        }
        let snapshot = Snapshot {
            seq: self.seq,
            published: now,
            edit_published: self.edit_published,
            geometry: geometry.clone(),
            radiance: Arc::new(radiance),
            reflectance: self.reflectance.clone(),
            reflectance_rev: self.reflectance_rev,
            ambient: ambient.as_vec3().to_array(),
            stats,
            materials: Arc::new(solver.scene().materials.clone()),
            loaded_materials: self.loaded_materials.clone(),
            history: self.history.clone(),
            scene_name: solver.scene().name.clone(),
            scene_source: solver.scene().source.clone(),
            scene_rev: self.scene_rev,
            scene_camera: solver.scene().default_camera(),
            two_sided: solver.scene().two_sided,
            method: solver.config().method,
        };
        self.latest.publish(Arc::new(snapshot));
        self.last_publish = Some(now);
        self.dirty = false;
        (self.waker)();
    }
}
