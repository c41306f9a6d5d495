//! The eframe app: takes snapshots, draws the viewport and panels, and applies every user
//! action in one place ([`ViewerApp::handle`]).

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use eframe::egui;
use eframe::egui_wgpu;

use crate::scene::{LoadOptions, Scene};
use crate::solver::SolverConfig;

use super::UiOptions;
use super::automation::{Automation, EditTarget, FrameLog, FrameRow, ScreenshotWhen, ShotState};
use super::camera::OrbitCamera;
use super::export;
use super::panels::{self, Action, PanelState, ViewSettings};
use super::render::{
    FLAG_SELECTION, FLAG_SHOOTER, NO_PATCH, Overlays, Uniforms, ViewportCallback, ViewportResources,
};
use super::snapshot::Snapshot;
use super::solver_thread::{Command, Event, Latest, SolverHandle, ThreadConfig};

const RECENT_KEY: &str = "nusselt.recent";
const MAX_RECENT: usize = 10;

/// An edit sent and not yet seen drawn (for the latency figure).
struct PendingEdit {
    sent: Instant,
    material: u32,
    kd: [f64; 3],
    ke: [f64; 3],
}

pub struct ViewerApp {
    solver: SolverHandle,
    /// Commands that did not fit in the channel yet (sent first next frame).
    outbox: VecDeque<Command>,
    snapshot: Option<Arc<Snapshot>>,
    new_snapshot: bool,
    scene_rev: Option<u64>,
    camera: Option<OrbitCamera>,
    viewport_rect: egui::Rect,
    panel: PanelState,
    resync_editor_after: Option<u64>,
    auto: Automation,
    shot_state: ShotState,
    screenshot_image: Arc<Latest<Arc<egui::ColorImage>>>,
    /// Viewport PNG export waiting for its screenshot.
    png_export: Option<(PathBuf, egui::Rect)>,
    png_image: Arc<Latest<Arc<egui::ColorImage>>>,
    edits_sent: bool,
    pending_edits: Vec<PendingEdit>,
    frame_log: FrameLog,
    log_frames: bool,
    started: Instant,
    first_frame: Option<Instant>,
    last_frame: Option<Instant>,
    logic_start: Option<Instant>,
    /// Set when a scripted run fails (read by `viewer::run` after the window closes).
    outcome: Arc<Mutex<Option<String>>>,
    persist: bool,
}

/// The solver thread's settings for these options.
pub fn thread_config(options: &UiOptions) -> ThreadConfig {
    let max_shots = match options.automation.screenshot.as_ref().map(|p| p.when) {
        Some(ScreenshotWhen::Shots(n)) => Some(n),
        _ => None,
    };
    ThreadConfig {
        solver: SolverConfig {
            element_size: options.element_size,
            method: options.method,
            raster: options.raster.clone(),
            ..Default::default()
        },
        play: !options.paused,
        max_shots,
        shot_threads: options.solver_threads,
        ..Default::default()
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
            view: ViewSettings {
                ambient: options.ambient,
                exposure_stops: options.exposure_stops,
                element_edges: options.wireframe,
                patch_outlines: options.patch_outlines,
                highlight_shooter: options.highlight_shooter,
            },
            element_size: options.element_size.unwrap_or(0.0),
            element_size_text: String::new(),
            element_size_error: None,
            editor: None,
            selection: options.automation.select,
            recent,
            messages: Vec::new(),
            show_plot: true,
        };
        let log_frames = options.automation.frame_log.is_some();
        Ok(Self {
            solver,
            outbox: VecDeque::new(),
            snapshot: None,
            new_snapshot: false,
            scene_rev: None,
            camera: None,
            viewport_rect: egui::Rect::NOTHING,
            panel,
            resync_editor_after: None,
            auto: options.automation,
            shot_state: ShotState::Waiting,
            screenshot_image: Arc::new(Latest::default()),
            png_export: None,
            png_image: Arc::new(Latest::default()),
            edits_sent: false,
            pending_edits: Vec::new(),
            frame_log: FrameLog::default(),
            log_frames,
            started,
            first_frame: None,
            last_frame: None,
            logic_start: None,
            outcome,
            persist,
        })
    }

    fn message(&mut self, error: bool, text: impl Into<String>) {
        let text = text.into();
        if error {
            eprintln!("viewer: {text}");
        }
        self.panel.messages.push((error, text));
        if self.panel.messages.len() > 50 {
            self.panel.messages.remove(0);
        }
    }

    fn fail(&mut self, ctx: &egui::Context, text: String) {
        eprintln!("error: {text}");
        *self.outcome.lock().unwrap_or_else(PoisonError::into_inner) = Some(text);
        self.shot_state = ShotState::Done;
        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
    }

    fn send(&mut self, command: Command) {
        // Consecutive edits of one material collapse into the newest.
        if let Command::SetMaterial { material, .. } = &command
            && let Some(Command::SetMaterial { material: last, .. }) = self.outbox.back()
            && last == material
        {
            self.outbox.pop_back();
        }
        self.outbox.push_back(command);
        self.flush();
    }

    fn flush(&mut self) {
        while let Some(c) = self.outbox.pop_front() {
            if let Err(back) = self.solver.send(c) {
                self.outbox.push_front(back);
                break;
            }
        }
    }

    fn on_snapshot(&mut self, s: Arc<Snapshot>) {
        if self.scene_rev != Some(s.scene_rev) {
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
        let now = Instant::now();
        let mut latencies = Vec::new();
        self.pending_edits.retain(|e| {
            let drawn = s
                .materials
                .get(e.material as usize)
                .is_some_and(|m| m.reflectance.to_array() == e.kd && m.emission.to_array() == e.ke);
            if drawn {
                latencies.push((
                    (now - e.sent).as_secs_f64() * 1e3,
                    s.edit_published
                        .unwrap_or(s.published)
                        .saturating_duration_since(e.sent)
                        .as_secs_f64()
                        * 1e3,
                ));
            }
            !drawn
        });
        for (drawn, published) in latencies {
            self.frame_log.edit_latency_ms.push(drawn);
            self.frame_log.edit_publish_ms.push(published);
        }
        // The material changed from elsewhere (reset, scripted edit): show its new values.
        if let Some(ed) = &self.panel.editor
            && !self.pending_edits.iter().any(|e| e.material == ed.material)
            && let Some(m) = s.materials.get(ed.material as usize)
            && (m.reflectance.to_array() != ed.kd || m.emission.to_array() != ed.ke)
        {
            self.panel.editor = None;
        }
        self.snapshot = Some(s);
        self.new_snapshot = true;
    }

    fn on_event(&mut self, e: Event) {
        match e {
            Event::Error(text) => self.message(true, text),
            Event::Loaded { name, source } => {
                if let Some(p) = source {
                    let p = std::fs::canonicalize(&p).unwrap_or(p);
                    self.panel.recent.retain(|r| *r != p);
                    self.panel.recent.insert(0, p);
                    self.panel.recent.truncate(MAX_RECENT);
                }
                self.message(false, format!("loaded {name}"));
            }
        }
    }

    /// Applies one user action: the single place where UI input becomes a change.
    fn handle(&mut self, ctx: &egui::Context, action: Action) {
        match action {
            Action::Solver(c) => self.send(c),
            Action::Remesh(size) => self.send(Command::Remesh(size)),
            Action::SetMethod(m) => self.send(Command::SetMethod(m)),
            Action::OpenDialog => {
                let picked = rfd::FileDialog::new()
                    .add_filter("Wavefront OBJ", &["obj"])
                    .pick_file();
                if let Some(p) = picked {
                    self.handle(ctx, Action::Open(p));
                }
            }
            Action::Open(p) => {
                self.message(false, format!("opening {}", p.display()));
                self.send(Command::LoadPath(p));
            }
            Action::OpenBuiltin(name) => match Scene::builtin(&name, &LoadOptions::default()) {
                Ok(s) => self.send(Command::LoadScene(Box::new(s))),
                Err(e) => self.message(true, e.to_string()),
            },
            Action::ClearRecent => self.panel.recent.clear(),
            Action::SaveMtl => {
                if let Some(s) = self.snapshot.clone() {
                    let path = match &s.scene_source {
                        Some(obj) => export::mtl_path_for(obj),
                        None => PathBuf::from(format!("{}.mtl", s.scene_name)),
                    };
                    self.save_mtl(&s, &path);
                }
            }
            Action::SaveMtlAs => {
                if let Some(s) = self.snapshot.clone() {
                    let mut dialog = rfd::FileDialog::new().add_filter("MTL", &["mtl"]);
                    if let Some(dir) = s.scene_source.as_deref().and_then(Path::parent) {
                        dialog = dialog.set_directory(dir);
                    }
                    if let Some(p) = dialog
                        .set_file_name(format!("{}.mtl", s.scene_name))
                        .save_file()
                    {
                        self.save_mtl(&s, &p);
                    }
                }
            }
            Action::ResetEdits => {
                self.send(Command::ResetMaterials);
                self.resync_editor_after = Some(self.snapshot.as_ref().map_or(0, |s| s.seq));
            }
            Action::ExportPly => {
                if let Some(s) = self.snapshot.clone() {
                    let picked = rfd::FileDialog::new()
                        .add_filter("PLY", &["ply"])
                        .set_file_name(format!("{}.ply", s.scene_name))
                        .save_file();
                    if let Some(p) = picked {
                        self.export_ply(&s, &p);
                    }
                }
            }
            Action::ExportPng => {
                let picked = rfd::FileDialog::new()
                    .add_filter("PNG", &["png"])
                    .set_file_name("viewport.png")
                    .save_file();
                if let Some(p) = picked {
                    self.request_viewport_png(ctx, p);
                }
            }
            Action::FrameScene => {
                if let (Some(c), Some(s)) = (self.camera.as_mut(), &self.snapshot) {
                    let aspect = self.viewport_rect.aspect_ratio() as f64;
                    c.frame(s.geometry.bounds_min, s.geometry.bounds_max, aspect);
                }
            }
            Action::ResetView => {
                if let Some(s) = &self.snapshot {
                    self.camera = Some(OrbitCamera::from_camera(
                        &s.scene_camera,
                        s.geometry.bounds_min,
                        s.geometry.bounds_max,
                    ));
                }
            }
            Action::Select(p) => {
                self.panel.selection = p;
                self.panel.editor = None;
            }
            Action::Edit { material, kd, ke } => {
                self.pending_edits.push(PendingEdit {
                    sent: Instant::now(),
                    material,
                    kd,
                    ke,
                });
                if self.pending_edits.len() > 64 {
                    self.pending_edits.remove(0);
                }
                self.send(Command::SetMaterial {
                    material: crate::scene::MaterialId(material),
                    reflectance: kd,
                    emission: ke,
                });
            }
            Action::Quit => ctx.send_viewport_cmd(egui::ViewportCommand::Close),
        }
    }

    fn save_mtl(&mut self, s: &Snapshot, path: &Path) {
        let text = export::mtl_text(
            &s.materials,
            &format!("materials of {} saved by nusselt's viewer", s.scene_name),
        );
        match export::atomic_write(path, text.as_bytes()) {
            Ok(()) => self.message(false, format!("saved {}", path.display())),
            Err(e) => self.message(true, e.to_string()),
        }
    }

    fn export_ply(&mut self, s: &Snapshot, path: &Path) {
        let bytes = export::ply_bytes(s, self.panel.view.ambient, self.panel.view.exposure());
        match export::atomic_write(path, &bytes) {
            Ok(()) => self.message(false, format!("exported {}", path.display())),
            Err(e) => self.message(true, e.to_string()),
        }
    }

    fn request_viewport_png(&mut self, ctx: &egui::Context, path: PathBuf) {
        self.png_export = Some((path, self.viewport_rect));
        let slot = self.png_image.clone();
        let c = ctx.clone();
        ctx.request_screenshot(move |image| {
            slot.publish(image);
            c.request_repaint();
        });
    }

    fn finish_viewport_png(&mut self, ctx: &egui::Context) {
        let Some(image) = self.png_image.take() else {
            return;
        };
        let Some((path, rect)) = self.png_export.take() else {
            return;
        };
        let crop = image.region(&rect, Some(ctx.pixels_per_point()));
        let rgba: Vec<u8> = crop.pixels.iter().flat_map(|c| c.to_array()).collect();
        match export::write_png(&path, crop.size[0] as u32, crop.size[1] as u32, &rgba) {
            Ok(()) => self.message(false, format!("saved {}", path.display())),
            Err(e) => self.message(true, e.to_string()),
        }
    }

    /// Scripted edits, once enough shots are on screen.
    fn run_edits(&mut self, ctx: &egui::Context) {
        if self.edits_sent || self.auto.edits.is_empty() {
            return;
        }
        let Some(s) = self.snapshot.clone() else {
            return;
        };
        if s.stats.shots < self.auto.edit_after_shots && !s.stats.converged {
            return;
        }
        self.edits_sent = true;
        for spec in self.auto.edits.clone() {
            let material = match &spec.target {
                EditTarget::Material(name) => {
                    let m = s.materials.iter().position(|m| m.name == *name);
                    // Show the edit panel: select a patch of that material.
                    if self.panel.selection.is_none()
                        && let Some(m) = m
                    {
                        self.panel.selection = s
                            .geometry
                            .patch_material
                            .iter()
                            .position(|&p| p as usize == m)
                            .map(|p| p as u32);
                    }
                    m.map(|i| i as u32)
                }
                EditTarget::Patch(p) => {
                    let m = s.geometry.patch_material.get(*p as usize).copied();
                    if m.is_some() {
                        self.panel.selection = Some(*p);
                        self.panel.editor = None;
                    }
                    m
                }
            };
            let Some(material) = material else {
                let text = format!(
                    "--edit: no {} in {} (materials: {})",
                    match &spec.target {
                        EditTarget::Material(n) => format!("material '{n}'"),
                        EditTarget::Patch(p) =>
                            format!("patch #{p} ({} patches)", s.geometry.patches),
                    },
                    s.scene_name,
                    s.materials
                        .iter()
                        .map(|m| m.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                );
                self.fail(ctx, text);
                return;
            };
            let m = &s.materials[material as usize];
            let kd = spec.kd.unwrap_or(m.reflectance.to_array());
            let ke = spec.ke.unwrap_or(m.emission.to_array());
            if kd.iter().any(|&x| x > crate::scene::MAX_REFLECTANCE) {
                self.fail(
                    ctx,
                    format!("--edit: kd must be <= {}", crate::scene::MAX_REFLECTANCE),
                );
                return;
            }
            self.handle(ctx, Action::Edit { material, kd, ke });
        }
    }

    /// Scripted screenshot: wait for the condition, capture, save, close.
    fn run_screenshot(&mut self, ctx: &egui::Context) {
        let Some(plan) = self.auto.screenshot.clone() else {
            return;
        };
        ctx.request_repaint();
        let since_open = self.first_frame.map_or(Duration::ZERO, |t| t.elapsed());
        if !matches!(self.shot_state, ShotState::Done) && since_open > plan.timeout {
            let shots = self.snapshot.as_ref().map_or(0, |s| s.stats.shots);
            self.fail(
                ctx,
                format!(
                    "screenshot not taken within {:.0} s ({shots} shots so far)",
                    plan.timeout.as_secs_f64()
                ),
            );
            return;
        }
        match self.shot_state {
            ShotState::Waiting => {
                let Some(s) = &self.snapshot else { return };
                let edits_done = self.auto.edits.is_empty()
                    || (self.edits_sent && self.pending_edits.is_empty());
                let ready = edits_done
                    && match plan.when {
                        ScreenshotWhen::Shots(n) => {
                            s.stats.shots >= n || s.stats.converged || s.stats.limit_reached
                        }
                        ScreenshotWhen::Seconds(t) => since_open.as_secs_f64() >= t,
                        ScreenshotWhen::Converged => s.stats.converged,
                    };
                if ready {
                    self.shot_state = ShotState::Ready(0);
                }
            }
            ShotState::Ready(k) if k < 2 => self.shot_state = ShotState::Ready(k + 1),
            ShotState::Ready(_) => {
                let slot = self.screenshot_image.clone();
                let c = ctx.clone();
                ctx.request_screenshot(move |image| {
                    slot.publish(image);
                    c.request_repaint();
                });
                self.shot_state = ShotState::Requested(Instant::now());
            }
            ShotState::Requested(at) => {
                if let Some(image) = self.screenshot_image.take() {
                    let rgba: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_array()).collect();
                    let saved = export::write_png(
                        &plan.path,
                        image.size[0] as u32,
                        image.size[1] as u32,
                        &rgba,
                    );
                    if let Some(p) = self.auto.viewport_png.clone() {
                        let crop = image.region(&self.viewport_rect, Some(ctx.pixels_per_point()));
                        let rgba: Vec<u8> = crop.pixels.iter().flat_map(|c| c.to_array()).collect();
                        if let Err(e) =
                            export::write_png(&p, crop.size[0] as u32, crop.size[1] as u32, &rgba)
                        {
                            self.fail(ctx, e.to_string());
                            return;
                        }
                    }
                    if let (Some(p), Some(s)) =
                        (self.auto.export_ply.clone(), self.snapshot.clone())
                    {
                        let bytes = export::ply_bytes(
                            &s,
                            self.panel.view.ambient,
                            self.panel.view.exposure(),
                        );
                        if let Err(e) = export::atomic_write(&p, &bytes) {
                            self.fail(ctx, e.to_string());
                            return;
                        }
                    }
                    match saved {
                        Ok(()) => {
                            let s = self.snapshot.as_ref();
                            eprintln!(
                                "saved {} ({}x{} px, {} shots, {} elements)",
                                plan.path.display(),
                                image.size[0],
                                image.size[1],
                                s.map_or(0, |s| s.stats.shots),
                                s.map_or(0, |s| s.stats.elements)
                            );
                            self.shot_state = ShotState::Done;
                            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                        }
                        Err(e) => self.fail(ctx, e.to_string()),
                    }
                } else if at.elapsed() > Duration::from_secs(20) {
                    self.fail(ctx, "the screenshot never arrived".into());
                }
            }
            ShotState::Done => {}
        }
    }

    fn viewport(&mut self, ui: &mut egui::Ui, actions: &mut Vec<Action>) {
        let rect = ui.available_rect_before_wrap();
        self.viewport_rect = rect;
        let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
        let Some(snap) = self.snapshot.clone() else {
            ui.painter().text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "building the mesh…",
                egui::FontId::proportional(18.0),
                egui::Color32::GRAY,
            );
            return;
        };
        let Some(camera) = self.camera.as_mut() else {
            return;
        };
        // Camera: drag = orbit, right/middle drag or shift+drag = pan, wheel = zoom.
        let shift = ui.input(|i| i.modifiers.shift);
        let delta = response.drag_delta();
        if response.dragged_by(egui::PointerButton::Primary) && !shift {
            camera.orbit(delta.x as f64, delta.y as f64);
        } else if response.dragged_by(egui::PointerButton::Secondary)
            || response.dragged_by(egui::PointerButton::Middle)
            || (response.dragged_by(egui::PointerButton::Primary) && shift)
        {
            camera.pan(delta.x as f64, delta.y as f64, rect.height() as f64);
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                camera.zoom(scroll as f64);
            }
        }
        if response.double_clicked() {
            actions.push(Action::FrameScene);
        } else if response.clicked()
            && let Some(pos) = response.interact_pointer_pos()
        {
            let local = pos - rect.min;
            let (o, d) = camera.ray(
                local.x as f64,
                local.y as f64,
                rect.width() as f64,
                rect.height() as f64,
            );
            actions.push(Action::Select(snap.geometry.pick(o, d).map(|p| p.0)));
        }
        let view = &self.panel.view;
        let ambient = if view.ambient { snap.ambient } else { [0.0; 3] };
        let mut flags = 0;
        if view.highlight_shooter {
            flags |= FLAG_SHOOTER;
        }
        if self.panel.selection.is_some() {
            flags |= FLAG_SELECTION;
        }
        let shooter = snap.stats.last_shooter.unwrap_or(NO_PATCH);
        let uniforms = Uniforms {
            view_proj: camera
                .view_proj(rect.aspect_ratio() as f64)
                .to_cols_array_2d(),
            ambient_exposure: [ambient[0], ambient[1], ambient[2], view.exposure()],
            ids: [shooter, self.panel.selection.unwrap_or(NO_PATCH), flags, 0],
            element_line_color: [0.0, 0.0, 0.0, 0.45],
            patch_line_color: [1.0, 1.0, 1.0, 0.8],
            params: [1e-3, 0.0, 0.0, 0.0],
        };
        ui.painter().add(egui_wgpu::Callback::new_paint_callback(
            rect,
            ViewportCallback {
                snapshot: Some(snap.clone()),
                uniforms,
                overlays: Overlays {
                    element_edges: view.element_edges,
                    patch_outlines: view.patch_outlines,
                },
            },
        ));
        // Hovered files: a hint.
        if ui.input(|i| !i.raw.hovered_files.is_empty()) {
            ui.painter().text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "drop an .obj to open it",
                egui::FontId::proportional(22.0),
                egui::Color32::WHITE,
            );
        }
    }

    fn keys(&mut self, ctx: &egui::Context, actions: &mut Vec<Action>) {
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        let playing = self.snapshot.as_ref().is_some_and(|s| s.stats.playing);
        ctx.input(|i| {
            if i.key_pressed(egui::Key::F) {
                actions.push(Action::FrameScene);
            }
            if i.key_pressed(egui::Key::Home) {
                actions.push(Action::ResetView);
            }
            if i.key_pressed(egui::Key::Space) {
                actions.push(Action::Solver(if playing {
                    Command::Pause
                } else {
                    Command::Play
                }));
            }
        });
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
            if p.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj")) {
                self.handle(ctx, Action::Open(p));
            } else {
                self.message(true, format!("{}: not an .obj file", p.display()));
            }
        }
        self.run_edits(ctx);
        self.flush();
        if !self.outbox.is_empty() {
            ctx.request_repaint();
        }
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
        egui::CentralPanel::no_frame().show(ui, |ui| self.viewport(ui, &mut actions));
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
            if s.stats.shots >= 1 {
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
                shots: self.snapshot.as_ref().map_or(0, |s| s.stats.shots),
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
