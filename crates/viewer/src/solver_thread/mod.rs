//! The solver thread: it owns the solver (any [`nusselt_core::solver::Solver`], chosen by
//! [`SolverKind`]); the UI talks to it through a bounded command channel and reads a
//! latest-wins [`Snapshot`].
//!
//! Why this shape (after rerun's viewer and egui's custom3d demo): the UI must never wait
//! for a shot, which can take from microseconds (cached form-factor row) to a second (a new
//! row on a fine mesh). So
//! - commands go through a `sync_channel`; the UI uses `try_send` and keeps what did not
//!   fit for the next frame, so it never blocks;
//! - commands that change the problem (edits, re-mesh, reset, load, pause, quit) also raise
//!   a cancel flag that [`nusselt_core::solver::Solver::step`] polls, so a long step is abandoned
//!   (leaving the solver untouched) and the command applies within milliseconds;
//! - results are published by swapping an `Arc<Snapshot>` into a slot under a mutex held
//!   only for the swap, never while shooting; the UI takes it when it draws;
//! - every publish calls the waker (`egui::Context::request_repaint` in the viewer), so the
//!   window redraws exactly when there is something new.
//!
//! Publishing is rate-limited (about 60 per second) because building a snapshot costs a
//! pass over the mesh; the first state (emitters only) and the first shots are published
//! at once so light shows up immediately.

mod adapt;
mod handoff;
mod publish;
mod ray_input;
mod switch;
mod teach;
mod texture_job;
mod worker;

use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use nusselt_core::formfactor::FormFactorMethod;
use nusselt_core::scene::{MaterialId, Scene};
use nusselt_core::solver::{SolverConfig, SolverKind};

use super::snapshot::Snapshot;
use worker::Worker;

/// Capacity of the command channel.
pub const COMMAND_CAPACITY: usize = 256;
/// Most history points kept (older ones are thinned out by half when full).
pub const HISTORY_CAPACITY: usize = 4096;
/// Shortest time between two published snapshots while shooting.
pub const PUBLISH_INTERVAL: Duration = Duration::from_millis(15);
/// Snapshots come no more often than this many times what the last one took to build:
/// on the 227 k-element atrium one took 25–60 ms on one thread, as long as a fifth of a
/// shot, and publishing after every shot cost the solve a fifth of its shots.
pub const PUBLISH_COST_RATIO: u32 = 10;

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
    /// The new list of skies, suns and point lights (incremental: no restart).
    SetLights(Vec<nusselt_core::scene::Light>),
    /// The new list of area lights: the scene's faces change, so it is re-meshed at the
    /// current element size and restarts from dark (other lights, material edits and the
    /// camera kept). The old snapshot stays published until the new mesh is ready; a
    /// refused list (an error event says why) changes nothing.
    SetAreaLights(Vec<nusselt_core::scene::AreaLight>),
    /// Write the scene as it is now (model, lights, camera, materials) to a scene file.
    SaveScene {
        path: std::path::PathBuf,
        camera: Option<nusselt_core::scene::Camera>,
    },
    /// Switch the form-factor method (restarts the solve).
    SetMethod(FormFactorMethod),
    /// Switch the solver, keeping the mesh and cached rows (restarts from dark). Refused
    /// with an [`Event::Error`] (the current solver goes on) when the new kind would refuse
    /// the problem ([`SolverKind::check`]).
    SetSolver(SolverKind),
    /// Refine the mesh adaptively while solving, to this tolerance (`None`: stop refining;
    /// see `adapt.rs`).
    Adapt(Option<f64>),
    /// Teaching mode's requests (`viewer::teach`).
    Teach(crate::teach::TeachCommand),
    /// Publish what the ray-traced view renders ([`crate::raytrace::RenderInput`])
    /// with the snapshots (on), or stop (off).
    RayTraced(bool),
    /// Load an OBJ file; on error the current scene stays.
    LoadPath(PathBuf),
    /// Replace the scene with one loaded elsewhere.
    LoadScene(Box<Scene>),
    /// Stop below this residual (for shooting, the unshot fraction).
    SetStopThreshold(f64),
    Quit,
    /// Test hook: the next shot panics with this message, to check that a panic in the
    /// solver is reported and the thread lives on (tests/viewer_panic.rs). Not reachable
    /// from the UI.
    #[doc(hidden)]
    PanicOnNextShot(String),
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
    /// Something the user should know that is not an error (lights added to an unlit model).
    Notice(String),
    /// The solver panicked: `"solver failed on <scene>: <message>"`. The solver it was
    /// working on is gone (nothing more is published for it, so the last snapshot stays on
    /// screen); the thread takes commands as before, so another scene can be loaded.
    Failed(String),
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
    /// The solver to start with (and to build for loaded scenes).
    pub kind: SolverKind,
    /// Start shooting at once.
    pub play: bool,
    /// Stop stepping below this residual (for shooting, the unshot fraction).
    pub stop_unshot: f64,
    /// Stop after this many steps (shots, matrix rows, sweeps) since the last (re)start
    /// (scripted runs).
    pub max_shots: Option<usize>,
    /// Threads that compute form-factor rows; `None` = one per core
    /// (`available_parallelism`). Leaving the UI a core was tried on the 2-core test
    /// machine with lavapipe: no measurable change in frame times under load, 25 % fewer
    /// shots; see docs/VIEWER.md.
    pub shot_threads: Option<usize>,
    /// `--solver auto`: shooting hands a large scene over to hierarchical radiosity once
    /// most of the light is spread (`handoff.rs`); a solver chosen by name stays.
    pub handoff: bool,
}

impl ThreadConfig {
    /// The shot pool's size: `shot_threads`, or one per core.
    pub fn shot_threads(&self) -> usize {
        self.shot_threads
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
            .max(1)
    }
}

impl Default for ThreadConfig {
    fn default() -> Self {
        Self {
            solver: SolverConfig::default(),
            kind: SolverKind::Shooting,
            play: true,
            stop_unshot: 1e-6,
            max_shots: None,
            shot_threads: None,
            handoff: false,
        }
    }
}

/// The UI's end of the solver thread.
pub struct SolverHandle {
    tx: SyncSender<Command>,
    /// Commands that did not fit in the channel yet (sent first by the next
    /// [`SolverHandle::flush`]).
    outbox: VecDeque<Command>,
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
        let worker = Worker::new(rx, etx, cancel.clone(), latest.clone(), waker, config);
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
            outbox: VecDeque::new(),
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

    /// Sends what is queued, then `command`, without blocking: what does not fit waits in
    /// the outbox for the next [`SolverHandle::flush`] (the UI calls it every frame).
    /// Consecutive edits of one material collapse into the newest.
    pub fn queue(&mut self, command: Command) {
        if let Command::SetMaterial { material, .. } = &command
            && let Some(Command::SetMaterial { material: last, .. }) = self.outbox.back()
            && last == material
        {
            self.outbox.pop_back();
        }
        if matches!(command, Command::SetLights(_))
            && matches!(self.outbox.back(), Some(Command::SetLights(_)))
        {
            self.outbox.pop_back();
        }
        // Each list of area lights costs a re-mesh: only the newest waiting one counts.
        if matches!(command, Command::SetAreaLights(_))
            && matches!(self.outbox.back(), Some(Command::SetAreaLights(_)))
        {
            self.outbox.pop_back();
        }
        self.outbox.push_back(command);
        self.flush();
    }

    /// Sends queued commands, in order, until the channel is full.
    pub fn flush(&mut self) {
        while let Some(c) = self.outbox.pop_front() {
            if let Err(back) = self.send(c) {
                self.outbox.push_front(back);
                break;
            }
        }
    }

    /// Commands still waiting in the outbox.
    pub fn queued(&self) -> usize {
        self.outbox.len()
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
        self.outbox.clear();
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shot_threads_default_to_one_per_core() {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        assert_eq!(ThreadConfig::default().shot_threads(), cores);
        let one = ThreadConfig {
            shot_threads: Some(0),
            ..Default::default()
        };
        assert_eq!(one.shot_threads(), 1, "at least one thread");
        let three = ThreadConfig {
            shot_threads: Some(3),
            ..Default::default()
        };
        assert_eq!(three.shot_threads(), 3);
    }
}
