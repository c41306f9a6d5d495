//! The solver thread: it owns the [`ProgressiveSolver`]; the UI talks to it through a
//! bounded command channel and reads a latest-wins [`Snapshot`].
//!
//! Why this shape (after rerun's viewer and egui's custom3d demo): the UI must never wait
//! for a shot, which can take from microseconds (cached form-factor row) to a second (a new
//! row on a fine mesh). So
//! - commands go through a `sync_channel`; the UI uses `try_send` and keeps what did not
//!   fit for the next frame, so it never blocks;
//! - commands that change the problem (edits, re-mesh, reset, load, pause, quit) also raise
//!   a cancel flag that [`ProgressiveSolver::shoot`] polls, so a long shot is abandoned
//!   (leaving the solver untouched) and the command applies within milliseconds;
//! - results are published by swapping an `Arc<Snapshot>` into a slot under a mutex held
//!   only for the swap, never while shooting; the UI takes it when it draws;
//! - every publish calls the waker (`egui::Context::request_repaint` in the viewer), so the
//!   window redraws exactly when there is something new.
//!
//! Publishing is rate-limited (about 60 per second) because building a snapshot costs a
//! pass over the mesh; the first state (emitters only) and the first shots are published
//! at once so light shows up immediately.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TryRecvError, TrySendError};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::formfactor::FormFactorMethod;
use crate::formfactor::hemicube::ItemBufferRaster;
use crate::mesh::PatchId;
use crate::scene::{LoadOptions, Material, MaterialId, Rgb, Scene};
use crate::solver::{ProgressiveSolver, SolverConfig};

use super::snapshot::{Geometry, HistoryPoint, Snapshot, Stats, corner_reflectance};

/// Capacity of the command channel.
pub const COMMAND_CAPACITY: usize = 256;
/// Most history points kept (older ones are thinned out by half when full).
pub const HISTORY_CAPACITY: usize = 4096;
/// Shortest time between two published snapshots while shooting.
pub const PUBLISH_INTERVAL: Duration = Duration::from_millis(15);

/// What the UI asks of the solver thread.
#[derive(Debug)]
pub enum Command {
    Play,
    Pause,
    /// One shot, then pause.
    Step,
    /// Back to dark (materials as they are now).
    Reset,
    /// New element size; restarts from dark on the new mesh. The old snapshot stays
    /// published until the new mesh is ready.
    Remesh(f64),
    /// Incremental edit (no restart).
    SetMaterial {
        material: MaterialId,
        reflectance: [f64; 3],
        emission: [f64; 3],
    },
    /// All materials back to how they were loaded (incrementally).
    ResetMaterials,
    /// Switch the form-factor method (restarts the solve).
    SetMethod(FormFactorMethod),
    /// Load an OBJ file; on error the current scene stays.
    LoadPath(PathBuf),
    /// Replace the scene with one loaded elsewhere.
    LoadScene(Box<Scene>),
    /// Stop shooting below this unshot fraction.
    SetStopThreshold(f64),
    Quit,
}

impl Command {
    /// Whether a shot in progress should be abandoned for this command.
    fn interrupts(&self) -> bool {
        !matches!(self, Command::Play | Command::Step)
    }
}

/// Notices from the solver thread (errors, loads); these must not be lost the way stale
/// snapshots may be, so they have their own bounded channel.
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    Error(String),
    Loaded {
        name: String,
        source: Option<PathBuf>,
    },
}

/// A one-value mailbox: the writer replaces, the reader takes.
#[derive(Debug)]
pub struct Latest<T> {
    slot: Mutex<Option<T>>,
}

impl<T> Default for Latest<T> {
    fn default() -> Self {
        Self {
            slot: Mutex::new(None),
        }
    }
}

impl<T> Latest<T> {
    pub fn publish(&self, value: T) {
        // A panic elsewhere cannot leave an `Option` half-written: ignore poisoning.
        *self.slot.lock().unwrap_or_else(PoisonError::into_inner) = Some(value);
    }
    pub fn take(&self) -> Option<T> {
        self.slot
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .take()
    }
}

/// Called after each publish (the viewer passes `request_repaint`).
pub type Waker = Box<dyn Fn() + Send + 'static>;

/// Settings of the solver thread.
#[derive(Clone, Debug)]
pub struct ThreadConfig {
    pub solver: SolverConfig,
    /// Start shooting at once.
    pub play: bool,
    /// Stop shooting below this unshot fraction.
    pub stop_unshot: f64,
    /// Stop shooting after this many shots since the last (re)start (scripted runs).
    pub max_shots: Option<usize>,
    /// Threads that compute form-factor rows; `None` = one per core. (Leaving the UI a
    /// core was tried on the 2-core test machine with lavapipe: no measurable change in
    /// frame times under load, 25 % fewer shots; see docs/VIEWER.md.)
    pub shot_threads: Option<usize>,
}

impl ThreadConfig {
    pub fn shot_threads(&self) -> usize {
        self.shot_threads
            .unwrap_or_else(|| {
                std::thread::available_parallelism()
                    .map_or(1, |n| n.get())
                    .saturating_sub(1)
            })
            .max(1)
    }
}

impl Default for ThreadConfig {
    fn default() -> Self {
        Self {
            solver: SolverConfig::default(),
            play: true,
            stop_unshot: 1e-6,
            max_shots: None,
            shot_threads: None,
        }
    }
}

/// The UI's end of the solver thread.
pub struct SolverHandle {
    tx: SyncSender<Command>,
    cancel: Arc<AtomicBool>,
    latest: Arc<Latest<Arc<Snapshot>>>,
    events: Receiver<Event>,
    thread: Option<JoinHandle<()>>,
}

impl SolverHandle {
    /// Starts the thread; the solver (mesh, hierarchy) is built there, so this returns at
    /// once.
    pub fn spawn(scene: Scene, config: ThreadConfig, waker: Waker) -> std::io::Result<Self> {
        let (tx, rx) = std::sync::mpsc::sync_channel(COMMAND_CAPACITY);
        let (etx, erx) = std::sync::mpsc::sync_channel(64);
        let cancel = Arc::new(AtomicBool::new(false));
        let latest = Arc::new(Latest::default());
        let threads = config.shot_threads();
        let worker = Worker {
            rx,
            events: etx,
            cancel: cancel.clone(),
            latest: latest.clone(),
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
        };
        let thread = std::thread::Builder::new()
            .name("nusselt-solver".into())
            .spawn(move || {
                // Shots run in their own, named pool.
                match rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .thread_name(|i| format!("nusselt-shot-{i}"))
                    .build()
                {
                    Ok(pool) => pool.install(|| worker.run(scene)),
                    Err(e) => {
                        eprintln!("viewer: no thread pool for shots ({e}); using the global one");
                        worker.run(scene)
                    }
                }
            })?;
        Ok(Self {
            tx,
            cancel,
            latest,
            events: erx,
            thread: Some(thread),
        })
    }

    /// Sends without blocking; gives the command back when the channel is full (or the
    /// thread is gone).
    pub fn send(&self, command: Command) -> Result<(), Command> {
        let interrupts = command.interrupts();
        match self.tx.try_send(command) {
            Ok(()) => {
                if interrupts {
                    self.cancel.store(true, Ordering::Relaxed);
                }
                Ok(())
            }
            Err(TrySendError::Full(c) | TrySendError::Disconnected(c)) => Err(c),
        }
    }

    /// The newest snapshot since the last call, if any.
    pub fn take_snapshot(&self) -> Option<Arc<Snapshot>> {
        self.latest.take()
    }

    pub fn try_event(&self) -> Option<Event> {
        self.events.try_recv().ok()
    }

    /// Whether the thread is still running.
    pub fn is_alive(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Asks the thread to stop and waits up to `timeout` for it. Returns whether it ended.
    pub fn shutdown(&mut self, timeout: Duration) -> bool {
        let deadline = Instant::now() + timeout;
        self.cancel.store(true, Ordering::Relaxed);
        let mut quit = Some(Command::Quit);
        while let Some(c) = quit.take() {
            match self.tx.try_send(c) {
                Ok(()) | Err(TrySendError::Disconnected(_)) => {}
                Err(TrySendError::Full(c)) => {
                    if Instant::now() >= deadline {
                        break;
                    }
                    self.cancel.store(true, Ordering::Relaxed);
                    std::thread::sleep(Duration::from_millis(1));
                    quit = Some(c);
                }
            }
        }
        while self.thread.as_ref().is_some_and(|t| !t.is_finished()) {
            if Instant::now() >= deadline {
                return false;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        if let Some(t) = self.thread.take() {
            // The worker catches nothing; a panic there is reported here.
            if t.join().is_err() {
                eprintln!("error: the solver thread panicked");
                return false;
            }
        }
        true
    }
}

impl Drop for SolverHandle {
    fn drop(&mut self) {
        if self.thread.is_some() {
            self.shutdown(Duration::from_secs(5));
        }
    }
}

struct Worker {
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
}

enum Flow {
    Continue,
    Quit,
}

impl Worker {
    fn run(mut self, scene: Scene) {
        self.install(scene, self.config.clone());
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
                        self.publish();
                    }
                    // Wake up now and then even if idle so a lost waker cannot stall
                    // anything; no work is done on these wake-ups.
                    match self.rx.recv_timeout(Duration::from_millis(500)) {
                        Ok(c) => c,
                        Err(RecvTimeoutError::Timeout) => continue,
                        Err(RecvTimeoutError::Disconnected) => return,
                    }
                };
                if let Flow::Quit = self.apply(command) {
                    return;
                }
            }
            if self.dirty && self.due() {
                self.publish();
            }
            self.shoot_once();
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
        self.reflectance = Arc::new(corner_reflectance(&g, solver));
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
                    self.reflectance = Arc::new(corner_reflectance(g, s));
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
