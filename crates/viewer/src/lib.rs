//! The live viewer: open a model and watch it brighten from dark as the solver shoots.
//!
//! Layout (after rerun's viewer: UI split by concern, commands handled in one place):
//! - [`solver_thread`]: a named thread owns the solver (any [`nusselt_core::solver::Solver`],
//!   chosen in the panel or by `--solver`); the UI sends [`solver_thread::Command`]s
//!   through a bounded channel and takes a latest-wins [`snapshot::Snapshot`]; the thread
//!   wakes the UI when it publishes.
//! - [`render`]: wgpu pipelines in egui-wgpu's callback resources (egui's `custom3d_wgpu`
//!   pattern); per-vertex radiance, exposure and linear→sRGB in `shaders/viewport.wgsl`.
//! - [`app`]: the eframe app: side panel (`panels`), viewport (`viewport.rs`) with orbit
//!   camera ([`camera`]), and every user action funnelled through `ViewerApp::handle`.
//! - [`automation`]: `--screenshot`, `--edit`: reproducible runs for screenshots and
//!   tests; [`frame_log`]: `--frame-log`, the timings and latency figures in
//!   docs/VIEWER.md.
//! - [`export`]: PLY, MTL and PNG files, written atomically; [`dialog`]: rfd file dialogs
//!   on their own thread, so the viewport keeps drawing while one is open.
//!
//! Nothing here is used by the core; the core never imports egui, eframe or wgpu.

pub mod app;
mod auto_exposure;
pub mod automation;
pub mod camera;
pub mod dialog;
pub mod export;
pub mod export_gltf;
mod files;
pub mod frame_log;
mod lights_panel;
mod panels;
mod ray_view;
pub mod raytrace;
pub mod render;
pub mod snapshot;
pub mod solver_thread;
pub mod teach;
pub mod textures;
mod viewport;

use std::sync::{Arc, OnceLock};

use nusselt_core::formfactor::FormFactorMethod;
use nusselt_core::scene::Scene;

pub use automation::{Automation, EditSpec, EditTarget, ScreenshotPlan, ScreenshotWhen};

/// How the viewer starts.
#[derive(Debug)]
pub struct ViewerOptions {
    pub scene: Scene,
    pub ui: UiOptions,
}

/// Everything but the scene.
#[derive(Clone, Debug)]
pub struct UiOptions {
    pub element_size: Option<f64>,
    /// Patch size (`MeshSpec::patch_size`; a scene file's `mesh.patch_size`).
    pub patch_size: Option<f64>,
    /// Element budget when no element size is given (`MeshSpec::max_elements`).
    pub max_elements: Option<usize>,
    /// Stop below this residual (default: the solver thread's).
    pub stop_unshot: Option<f64>,
    pub method: FormFactorMethod,
    /// The solver to start with (`--solver`).
    pub solver: nusselt_core::solver::SolverKind,
    /// Why, when `--solver auto` chose it (shown in the stats panel).
    pub solver_reason: Option<String>,
    /// `--solver auto`: shooting hands a large scene over to hierarchical radiosity once
    /// most of the light is spread (`ThreadConfig::handoff`).
    pub solver_auto: bool,
    /// Teaching mode (`--teach`): the Teach panel opens on this view.
    pub teach: Option<teach::TeachView>,
    /// Teaching mode starts in projector mode (large text, light theme).
    pub projector: bool,
    /// The GPU hemicube, when `method` is `gpu-hemicube` (made on first use otherwise).
    pub raster: Option<std::sync::Arc<dyn nusselt_core::formfactor::hemicube::ItemBufferRaster>>,
    /// Window size in points.
    pub window: [f32; 2],
    pub wireframe: bool,
    pub patch_outlines: bool,
    pub ambient: bool,
    /// Exposure in stops.
    pub exposure_stops: f32,
    pub highlight_shooter: bool,
    /// Start with the ray-traced view on.
    pub ray_traced: bool,
    /// Show the diffuse maps (the Display section's "textures"; on unless `--no-textures`).
    pub textures: bool,
    /// Refine the mesh adaptively to this tolerance from the start.
    pub adaptive: Option<f64>,
    /// Cut the lights' shadow outlines into the surfaces before meshing
    /// (`MeshSpec::discontinuity`).
    pub discontinuity: bool,
    /// Start paused.
    pub paused: bool,
    /// Present without waiting for vertical sync.
    pub no_vsync: bool,
    /// Threads computing form factors (`None`: one per core).
    pub solver_threads: Option<usize>,
    /// The run's memory budget in bytes (`SolverConfig::memory_bytes`).
    pub memory_bytes: usize,
    pub automation: Automation,
}

#[derive(Debug, thiserror::Error)]
pub enum ViewerError {
    #[error("the viewer could not start: {0}")]
    Start(String),
    #[error("{0}")]
    Run(String),
}

/// Opens the window and runs until it closes.
pub fn run(options: ViewerOptions) -> Result<(), ViewerError> {
    let started = std::time::Instant::now();
    let ViewerOptions { scene, ui } = options;
    let screenshot_mode = ui.automation.screenshot.is_some();
    let title = format!("Nusselt — {}", scene.name);
    // The solver starts before the window: meshing overlaps window and GPU set-up, and the
    // first snapshot is waiting when the first frame is drawn. The UI's repaint handle is
    // given to the waker once the window exists.
    let ctx_slot: Arc<OnceLock<eframe::egui::Context>> = Arc::new(OnceLock::new());
    let waker_slot = ctx_slot.clone();
    let waker = Box::new(move || {
        if let Some(ctx) = waker_slot.get() {
            ctx.request_repaint();
        }
    });
    let solver = solver_thread::SolverHandle::spawn(scene, app::thread_config(&ui), waker)
        .map_err(|e| ViewerError::Start(format!("cannot start the solver thread: {e}")))?;
    let viewport = eframe::egui::ViewportBuilder::default()
        .with_title(title)
        .with_app_id("nusselt")
        .with_inner_size(ui.window)
        .with_drag_and_drop(true);
    let native = eframe::NativeOptions {
        viewport,
        depth_buffer: render::DEPTH_BITS,
        persist_window: !screenshot_mode,
        renderer: eframe::Renderer::Wgpu,
        ..Default::default()
    };
    let mut native = native;
    if ui.no_vsync {
        native.wgpu_options.surface.present_mode =
            eframe::egui_wgpu::wgpu::PresentMode::AutoNoVsync;
    }
    let outcome = std::sync::Arc::new(std::sync::Mutex::new(None::<String>));
    let outcome_app = outcome.clone();
    eframe::run_native(
        "nusselt",
        native,
        Box::new(move |cc| {
            let _ = ctx_slot.set(cc.egui_ctx.clone());
            // Whatever the solver published before the window existed.
            cc.egui_ctx.request_repaint();
            let app = app::ViewerApp::new(cc, ui, solver, started, outcome_app)
                .map_err(|e| -> Box<dyn std::error::Error + Send + Sync> { e.into() })?;
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| ViewerError::Start(e.to_string()))?;
    let failure = outcome
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .take();
    match failure {
        Some(message) => Err(ViewerError::Run(message)),
        None => Ok(()),
    }
}
