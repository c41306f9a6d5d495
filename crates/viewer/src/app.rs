//! The eframe app: takes snapshots and events from the solver thread, lays out the panels
//! and the viewport, and applies every user action in one place (`ViewerApp::handle`).
//! The viewport and its keys are in `super::viewport`, scripted runs in
//! [`super::automation`], timings in [`super::frame_log`].

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use eframe::egui;

use nusselt_core::mesh::MeshSpec;
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::{FormFactorConfig, SolverConfig};

use super::UiOptions;
use super::automation::{Automation, ScreenshotWhen, ShotState};
use super::camera::OrbitCamera;
use super::dialog::{Dialogs, Purpose, Request};
use super::export;
use super::frame_log::{EditLatency, FrameLog, FrameRow};
use super::panels::{self, Action, PanelState, ViewSettings};
use super::render::ViewportResources;
use super::snapshot::Snapshot;
use super::solver_thread::{Command, Event, Latest, SolverHandle, ThreadConfig};
use super::teach::{TeachCommand, TeachState, TeachView};

mod actions;

const RECENT_KEY: &str = "nusselt.recent";
const MAX_RECENT: usize = 10;

pub struct ViewerApp {
    solver: SolverHandle,
    pub(super) snapshot: Option<Arc<Snapshot>>,
    new_snapshot: bool,
    scene_rev: Option<u64>,
    auto_exposure: super::auto_exposure::AutoExposure,
    pub(super) camera: Option<OrbitCamera>,
    pub(super) viewport_rect: egui::Rect,
    pub(super) panel: PanelState,
    resync_editor_after: Option<u64>,
    pub(super) auto: Automation,
    pub(super) shot_state: ShotState,
    pub(super) screenshot_image: Arc<Latest<Arc<egui::ColorImage>>>,
    /// Viewport PNG export waiting for its screenshot.
    pub(super) png_export: Option<(PathBuf, egui::Rect)>,
    pub(super) png_image: Arc<Latest<Arc<egui::ColorImage>>>,
    /// The file dialog in progress (runs on its own thread).
    pub(super) dialogs: Dialogs,
    pub(super) edits_sent: bool,
    pub(super) edit_latency: EditLatency,
    frame_log: FrameLog,
    log_frames: bool,
    started: Instant,
    pub(super) first_frame: Option<Instant>,
    last_frame: Option<Instant>,
    logic_start: Option<Instant>,
    /// Set when a scripted run fails (read by `viewer::run` after the window closes).
    outcome: Arc<Mutex<Option<String>>>,
    persist: bool,
    /// Teaching mode's panel (`--teach`).
    pub(super) teach: Option<TeachState>,
    /// The ray-traced view's thread and image (`ray_view.rs`).
    pub(super) ray: super::ray_view::RayView,
}

/// The solver thread's settings for these options.
pub fn thread_config(options: &UiOptions) -> ThreadConfig {
    let max_shots = match options.automation.screenshot.as_ref().map(|p| p.when) {
        Some(ScreenshotWhen::Shots(n)) => Some(n),
        _ => None,
    };
    ThreadConfig {
        solver: SolverConfig {
            mesh: MeshSpec {
                element_size: options.element_size,
                patch_size: options.patch_size,
                max_elements: options.max_elements,
                discontinuity: options.discontinuity,
            },
            memory_bytes: options.memory_bytes,
            formfactor: FormFactorConfig {
                method: options.method,
                raster: options.raster.clone(),
                ..Default::default()
            },
            ..Default::default()
        },
        kind: options.solver,
        // Teaching starts paused: the class sees one shot per click.
        play: !options.paused && options.teach.is_none(),
        max_shots,
        shot_threads: options.solver_threads,
        handoff: options.solver_auto,
        stop_unshot: options
            .stop_unshot
            .unwrap_or(ThreadConfig::default().stop_unshot),
    }
}

impl ViewerApp {
    pub fn new(
        cc: &eframe::CreationContext<'_>,
        options: UiOptions,
        solver: SolverHandle,
        started: Instant,
        outcome: Arc<Mutex<Option<String>>>,
    ) -> Result<Self, String> {
        let render_state = cc
            .wgpu_render_state
            .as_ref()
            .ok_or("no wgpu render state (the viewer needs the wgpu backend)")?;
        ViewportResources::install(render_state);
        let persist = options.automation.screenshot.is_none();
        let recent = if persist {
            cc.storage
                .and_then(|s| eframe::get_value::<Vec<PathBuf>>(s, RECENT_KEY))
                .unwrap_or_default()
        } else {
            Vec::new()
        };
        let panel = PanelState {
            solver_reason: options.solver_reason.clone(),
            view: ViewSettings {
                ambient: options.ambient,
                exposure_stops: options.exposure_stops,
                element_edges: options.wireframe,
                patch_outlines: options.patch_outlines,
                highlight_shooter: options.highlight_shooter,
                ray_traced: options.ray_traced,
                textures: options.textures,
            },
            element_size: options.element_size.unwrap_or(0.0),
            element_size_text: String::new(),
            element_size_error: None,
            adaptive_tolerance: options.adaptive.unwrap_or(0.25),
            omega_text: match options.solver {
                nusselt_core::solver::SolverKind::Sor(Some(w)) => w.to_string(),
                _ => String::new(),
            },
            omega_error: None,
            editor: None,
            selection: options.automation.select,
            recent,
            messages: Vec::new(),
            solver_failure: None,
            show_plot: true,
            lights: Default::default(),
        };
        let log_frames = options.automation.frame_log.is_some();
        let scripted_steps = match (options.teach, options.automation.screenshot.as_ref()) {
            (Some(_), Some(plan)) => match plan.when {
                ScreenshotWhen::Shots(n) => n,
                _ => 0,
            },
            _ => 0,
        };
        let teach = options.teach.map(|v| TeachState {
            projector: options.projector,
            // A scripted screenshot of the comparison: its steps (shooting and gathering).
            compare_steps: scripted_steps,
            ..TeachState::new(v)
        });
        let mut app = Self {
            solver,
            snapshot: None,
            new_snapshot: false,
            scene_rev: None,
            auto_exposure: super::auto_exposure::AutoExposure::new(options.exposure_stops),
            camera: None,
            viewport_rect: egui::Rect::NOTHING,
            panel,
            resync_editor_after: None,
            auto: options.automation,
            shot_state: ShotState::Waiting,
            screenshot_image: Arc::new(Latest::default()),
            png_export: None,
            png_image: Arc::new(Latest::default()),
            dialogs: Dialogs::default(),
            edits_sent: false,
            edit_latency: EditLatency::default(),
            frame_log: FrameLog::default(),
            log_frames,
            started,
            first_frame: None,
            last_frame: None,
            logic_start: None,
            outcome,
            persist,
            teach,
            ray: Default::default(),
        };
        if let Some(t) = options.adaptive {
            app.solver.queue(Command::Adapt(Some(t)));
        }
        if app.teach.is_some() {
            app.solver
                .queue(Command::Teach(TeachCommand::RecordSteps(true)));
            // A scripted step-mode screenshot: N clicks on "Shoot once".
            for _ in 0..scripted_steps {
                app.solver.queue(Command::Step);
            }
        }
        Ok(app)
    }

    pub(super) fn message(&mut self, error: bool, text: impl Into<String>) {
        let text = text.into();
        if error {
            eprintln!("viewer: {text}");
        }
        self.panel.messages.push((error, text));
        if self.panel.messages.len() > 50 {
            self.panel.messages.remove(0);
        }
    }

    pub(super) fn fail(&mut self, ctx: &egui::Context, text: String) {
        eprintln!("error: {text}");
        *self.outcome.lock().unwrap_or_else(PoisonError::into_inner) = Some(text);
        self.shot_state = ShotState::Done;
        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
    }

    fn on_snapshot(&mut self, s: Arc<Snapshot>) {
        if self.scene_rev != Some(s.scene_rev) {
            if self.scene_rev.is_some() {
                self.auto_exposure
                    .on_new_scene(&mut self.panel.view.exposure_stops);
            }
            self.scene_rev = Some(s.scene_rev);
            self.camera = Some(OrbitCamera::from_camera(
                &s.scene_camera,
                s.geometry.bounds_min,
                s.geometry.bounds_max,
            ));
            if self
                .panel
                .selection
                .is_some_and(|p| p as usize >= s.geometry.patches)
                || self.snapshot.is_some()
            {
                self.panel.selection = None;
                self.panel.editor = None;
            }
        }
        if self
            .snapshot
            .as_ref()
            .is_none_or(|old| old.geometry.id != s.geometry.id)
        {
            self.panel.element_size = s.geometry.element_size;
            self.panel.element_size_text = format!("{:.4}", s.geometry.element_size);
            if self
                .panel
                .selection
                .is_some_and(|p| p as usize >= s.geometry.patches)
            {
                self.panel.selection = None;
            }
        }
        if self.resync_editor_after.is_some_and(|seq| s.seq > seq) {
            self.panel.editor = None;
            self.resync_editor_after = None;
        }
        self.edit_latency.on_snapshot(&s, &mut self.frame_log);
        self.frame_log.mesh_size = Some((s.radiance.len(), s.geometry.indices.len() / 3));
        // The material changed from elsewhere (reset, scripted edit): show its new values.
        if let Some(ed) = &self.panel.editor
            && !self.edit_latency.waits_for(ed.material)
            && let Some(m) = s.materials.get(ed.material as usize)
            && (m.reflectance.to_array() != ed.kd || m.emission.to_array() != ed.ke)
        {
            self.panel.editor = None;
        }
        self.check_exposure(&s);
        self.snapshot = Some(s);
        self.new_snapshot = true;
    }

    /// The first lit snapshot of a scene whose exposure nobody chose: a dark scene gets the
    /// exposure that shows it ([`super::auto_exposure`]).
    fn check_exposure(&mut self, s: &Snapshot) {
        if !self.auto_exposure.armed {
            return;
        }
        let displayed: Vec<[f32; 3]> = s
            .radiance
            .iter()
            .zip(s.correction.iter())
            .map(|(b, g)| [0, 1, 2].map(|c| b[c] + g[c]))
            .collect();
        if let Some(stops) = self
            .auto_exposure
            .on_snapshot(&displayed, &mut self.panel.view.exposure_stops)
        {
            self.message(
                false,
                format!(
                    "the scene is nearly {} at exposure 0 (its lights are {} for its size): exposure set to {stops:+} stops (Display; --exposure to choose)",
                    if stops > 0.0 { "black" } else { "white" },
                    if stops > 0.0 { "weak" } else { "strong" }
                ),
            );
        }
    }

    fn on_event(&mut self, e: Event) {
        match e {
            Event::Error(text) => self.message(true, text),
            Event::Notice(text) => self.message(false, text),
            Event::Failed(text) => {
                self.panel.solver_failure = Some(text.clone());
                self.message(true, text);
            }
            Event::Loaded { name, source } => {
                if let Some(p) = source {
                    let p = std::fs::canonicalize(&p).unwrap_or(p);
                    self.panel.recent.retain(|r| *r != p);
                    self.panel.recent.insert(0, p);
                    self.panel.recent.truncate(MAX_RECENT);
                }
                self.panel.solver_failure = None;
                self.message(false, format!("loaded {name}"));
            }
        }
    }
}

impl eframe::App for ViewerApp {
    fn logic(&mut self, ctx: &egui::Context, _frame: &mut eframe::Frame) {
        self.logic_start = Some(Instant::now());
        self.new_snapshot = false;
        if let Some(s) = self.solver.take_snapshot() {
            self.on_snapshot(s);
        }
        while let Some(e) = self.solver.try_event() {
            self.on_event(e);
        }
        let dropped: Vec<PathBuf> = ctx.input(|i| {
            i.raw
                .dropped_files
                .iter()
                .map(|f| f.path().to_path_buf())
                .collect()
        });
        for p in dropped {
            if nusselt_core::scene::is_model_file(&p) || nusselt_core::scene::is_scene_file(&p) {
                self.handle(ctx, Action::Open(p));
            } else {
                self.message(
                    true,
                    format!(
                        "{}: not an .obj, .gltf or .glb model or .json scene file",
                        p.display()
                    ),
                );
            }
        }
        self.run_edits(ctx);
        self.solver.flush();
        if self.solver.queued() > 0 {
            ctx.request_repaint();
        }
        self.finish_dialog(ctx);
        self.finish_viewport_png(ctx);
    }

    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let now = Instant::now();
        let ctx = ui.ctx().clone();
        if self.first_frame.is_none() {
            self.first_frame = Some(now);
            self.frame_log.first_frame_ms = Some((now - self.started).as_secs_f64() * 1e3);
        }
        let mut actions = Vec::new();
        egui::Panel::top("menu").show(ui, |ui| {
            panels::menu_bar(ui, &self.panel, &mut actions);
        });
        egui::Panel::left("controls")
            .default_size(300.0)
            .resizable(true)
            .show(ui, |ui| {
                panels::side_panel(ui, &mut self.panel, self.snapshot.as_deref(), &mut actions);
            });
        if let Some(teach) = self.teach.as_mut() {
            egui::Panel::right("teach")
                .default_size(400.0)
                .resizable(true)
                .show(ui, |ui| {
                    super::teach::teach_panel(
                        ui,
                        teach,
                        self.snapshot.as_deref(),
                        self.panel.selection,
                        &mut actions,
                    );
                });
            if teach.view != TeachView::Hemicube && teach.sent.take().is_some() {
                actions.push(Action::Teach(TeachCommand::Hemicube(None)));
            }
            // Projector mode: text half as large again, light theme.
            if teach.projector != teach.projector_applied {
                teach.projector_applied = teach.projector;
                ctx.set_zoom_factor(if teach.projector { 1.5 } else { 1.0 });
                ctx.set_theme(if teach.projector {
                    egui::Theme::Light
                } else {
                    egui::Theme::Dark
                });
            }
            if teach.view != TeachView::Nusselt && teach.nusselt_sent.take().is_some() {
                actions.push(Action::Teach(TeachCommand::Nusselt(None)));
            }
            if teach.view != TeachView::Matrix && teach.matrix_on {
                teach.matrix_on = false;
                actions.push(Action::Teach(TeachCommand::Matrix(false)));
            }
            super::teach::leave_views(teach, &mut actions);
        }
        match self.teach.as_mut().filter(|t| t.view.replaces_viewport()) {
            Some(teach) => {
                let exposure = self.panel.view.exposure();
                // The central area stands for the viewport (`--viewport-png` crops it).
                self.viewport_rect = egui::CentralPanel::default()
                    .show(ui, |ui| {
                        super::teach::central(ui, teach, self.snapshot.as_deref(), exposure);
                    })
                    .response
                    .rect;
            }
            None => {
                egui::CentralPanel::no_frame().show(ui, |ui| self.viewport(ui, &mut actions));
            }
        }
        self.keys(&ctx, &mut actions);
        for a in actions {
            self.handle(&ctx, a);
        }
        self.run_screenshot(&ctx);

        // Timings.
        let first = self.first_frame.unwrap_or(now);
        if let Some(s) = &self.snapshot {
            let t = (now - first).as_secs_f64() * 1e3;
            self.frame_log.first_light_ms.get_or_insert(t);
            if s.stats.steps >= 1 {
                self.frame_log.first_shot_ms.get_or_insert(t);
            }
        }
        if self.log_frames {
            let end = Instant::now();
            self.frame_log.rows.push(FrameRow {
                t_ms: (now - first).as_secs_f64() * 1e3,
                interval_ms: self
                    .last_frame
                    .map_or(0.0, |l| (now - l).as_secs_f64() * 1e3),
                ui_ms: (end - self.logic_start.unwrap_or(now)).as_secs_f64() * 1e3,
                cpu_ms: frame.info().cpu_usage.map_or(f64::NAN, |c| c as f64 * 1e3),
                shots: self.snapshot.as_ref().map_or(0, |s| s.stats.steps),
                elements: self.snapshot.as_ref().map_or(0, |s| s.stats.elements),
                new_snapshot: self.new_snapshot,
            });
        }
        self.last_frame = Some(now);
    }

    fn save(&mut self, storage: &mut dyn eframe::Storage) {
        if self.persist {
            eframe::set_value(storage, RECENT_KEY, &self.panel.recent);
        }
    }

    fn persist_egui_memory(&self) -> bool {
        false
    }

    fn on_exit(&mut self) {
        self.solver.shutdown(Duration::from_secs(5));
        if let Some(path) = self.auto.frame_log.clone() {
            eprint!("{}", self.frame_log.summary());
            if let Err(e) = export::atomic_write(&path, self.frame_log.to_text().as_bytes()) {
                eprintln!("error: {e}");
            }
        }
    }
}
