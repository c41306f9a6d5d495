//! Teaching mode (`nusselt view --teach VIEW`): views that show the algorithm step by step
//! in the notation of the lecture on implementing radiosity, in a "Teach" panel beside the
//! viewport. One file per view:
//! - [`step`]: one shot per click, and back; the shooter highlighted, the receivers
//!   coloured by the radiance they just received, the step's numbers with the formula
//!   `B_j += ρ_j ΔB_i F_ij A_i/A_j` (computed on the solver thread, [`step::StepDetail`];
//!   drawn by `step_panel.rs`);
//! - [`hemicube`]: the hemicube at the shooter, its five faces unfolded, the item buffer and
//!   the delta form factors, at a chosen resolution, with the hemicube value of a receiver
//!   beside the exact one (the solver thread computes it with the core's CPU hemicube,
//!   [`hemicube::HemicubeDetail`]; drawn by `hemicube_panel.rs`);
//! - [`nusselt`]: the Nusselt analogue: a patch projected onto the hemisphere and the base
//!   disk around the shooter's centre, the covered fraction beside the exact form factor,
//!   and scaled copies with the same projection (drawn by `nusselt_panel.rs`);
//! - [`matrix`]: the scene coloured by the shooter's column `F_ij` (log scale, legend) and
//!   the patch-level matrix as an image, filled a row at a time while the solver is idle,
//!   with its sparsity and storage (drawn by `matrix_panel.rs`);
//! - [`compare`]: progressive shooting (with the ambient term) and Gauss-Seidel gathering
//!   on the same patch system, a step of each at a time, in two images with their error
//!   curves (drawn by `compare_panel.rs`, in place of the viewport);
//! - [`meshing`]: the uniform mesh and an adaptive one side by side, with element counts
//!   (drawn by `meshing_panel.rs`, in place of the viewport).
//!
//! The last two draw small CPU images from an item buffer ([`item_image`]).
//!
//! The data is computed where the problem is, on the solver thread, on request
//! ([`TeachCommand`]), and published with the snapshot like everything else.

pub mod compare;
mod compare_panel;
pub mod hemicube;
mod hemicube_panel;
pub mod item_image;
pub mod matrix;
mod matrix_panel;
pub mod meshing;
mod meshing_panel;
pub mod nusselt;
mod nusselt_3d;
mod nusselt_panel;
#[cfg(test)]
pub(crate) mod panel_tests;
pub mod step;
mod step_panel;

use eframe::egui;

use super::panels::Action;
use super::snapshot::Snapshot;

/// A teaching view (`--teach`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TeachView {
    Step,
    Hemicube,
    Nusselt,
    Matrix,
    Compare,
    Mesh,
}

impl TeachView {
    /// The views built so far, as `--teach` spells them.
    pub const NAMES: &'static [&'static str] =
        &["step", "hemicube", "nusselt", "matrix", "compare", "mesh"];

    pub fn parse(name: &str) -> Option<TeachView> {
        match name {
            "step" => Some(TeachView::Step),
            "hemicube" => Some(TeachView::Hemicube),
            "nusselt" => Some(TeachView::Nusselt),
            "matrix" => Some(TeachView::Matrix),
            "compare" => Some(TeachView::Compare),
            "mesh" => Some(TeachView::Mesh),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            TeachView::Step => "step",
            TeachView::Hemicube => "hemicube",
            TeachView::Nusselt => "nusselt",
            TeachView::Matrix => "matrix",
            TeachView::Compare => "compare",
            TeachView::Mesh => "mesh",
        }
    }

    /// Views drawn in place of the 3-D viewport (two images side by side).
    pub fn replaces_viewport(self) -> bool {
        matches!(self, TeachView::Compare | TeachView::Mesh)
    }
}

/// What the Teach panel asks of the solver thread.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TeachCommand {
    /// Record what each single step did ([`step::StepDetail`]) (on) or stop (off).
    RecordSteps(bool),
    /// One step back: the solve is replayed from dark to one step before the current one
    /// (the form-factor rows are cached and shooting is deterministic, so the state is
    /// exactly the earlier one).
    Back,
    /// Keep a hemicube view up to date (`None`: none).
    Hemicube(Option<hemicube::HemicubeRequest>),
    /// Keep a Nusselt-analogue view up to date (`None`: none).
    Nusselt(Option<nusselt::NusseltRequest>),
    /// Fill the form-factor matrix while idle and publish it (on), or drop it (off).
    Matrix(bool),
    /// Shooting vs gathering.
    Compare(compare::CompareCommand),
    /// Compute uniform vs adaptive meshing with this tolerance (`None`: drop it).
    Mesh(Option<f64>),
}

/// The Teach panel's own state (UI side).
#[derive(Debug)]
pub struct TeachState {
    pub view: TeachView,
    /// Draw the radiance the last step added instead of the solution.
    pub show_received: bool,
    /// The element whose numbers the step view shows (clicked in the viewport).
    pub element: Option<u32>,
    /// Hemicube resolution (pixels across the top face).
    pub hemicube_res: u32,
    /// The hemicube request last sent (sent again when it changes).
    pub sent: Option<hemicube::HemicubeRequest>,
    pub(super) hemicube_textures: hemicube_panel::Textures,
    /// Projector mode: large text and a light theme (applied by the app).
    pub projector: bool,
    /// The projector setting last applied (the zoom is left alone otherwise, so that the
    /// user's own zoom keys keep working).
    pub projector_applied: bool,
    /// The Nusselt request last sent.
    pub nusselt_sent: Option<nusselt::NusseltRequest>,
    /// How the 3-D Nusselt drawing is turned.
    pub(super) nusselt_view: nusselt_3d::View3d,
    /// The matrix view asked the solver thread to fill the matrix.
    pub matrix_on: bool,
    /// Colour the scene by the shooter's column (matrix view).
    pub show_column: bool,
    pub(super) matrix_texture: matrix_panel::Texture,
    /// The comparison was asked for (with the steps of a scripted screenshot).
    pub compare_on: bool,
    pub compare_steps: usize,
    /// Show shooting with its ambient term.
    pub compare_ambient: bool,
    pub(super) compare_textures: compare_panel::Textures,
    /// The adaptive tolerance of the meshing view, the one asked for, and its textures.
    pub mesh_tolerance: f64,
    pub mesh_sent: Option<f64>,
    pub mesh_edges: bool,
    /// Colour the meshes by element size instead of radiance.
    pub mesh_sizes: bool,
    pub(super) mesh_textures: meshing_panel::Textures,
}

impl TeachState {
    pub fn new(view: TeachView) -> TeachState {
        TeachState {
            view,
            show_received: false,
            element: None,
            hemicube_res: 32,
            sent: None,
            hemicube_textures: Default::default(),
            projector: false,
            projector_applied: false,
            nusselt_sent: None,
            nusselt_view: Default::default(),
            matrix_on: false,
            show_column: true,
            matrix_texture: Default::default(),
            compare_on: false,
            compare_steps: 0,
            compare_ambient: true,
            compare_textures: Default::default(),
            mesh_tolerance: meshing::DEFAULT_TOLERANCE,
            mesh_sent: None,
            mesh_edges: true,
            mesh_sizes: false,
            mesh_textures: Default::default(),
        }
    }
}

/// The Teach panel: the view's controls and numbers.
pub fn teach_panel(
    ui: &mut egui::Ui,
    state: &mut TeachState,
    snap: Option<&Snapshot>,
    selection: Option<u32>,
    actions: &mut Vec<Action>,
) {
    ui.horizontal(|ui| {
        ui.heading("Teach");
        ui.checkbox(&mut state.projector, "projector")
            .on_hover_text("large text and a light theme, for a projected lecture");
    });
    ui.horizontal(|ui| {
        for name in TeachView::NAMES {
            if let Some(v) = TeachView::parse(name) {
                ui.selectable_value(&mut state.view, v, *name);
            }
        }
    });
    ui.separator();
    let Some(s) = snap else {
        ui.label("Building the mesh…");
        return;
    };
    egui::ScrollArea::vertical().show(ui, |ui| match state.view {
        TeachView::Step => step_panel::show(ui, state, s, actions),
        TeachView::Hemicube => hemicube_panel::show(ui, state, s, selection, actions),
        TeachView::Nusselt => nusselt_panel::show(ui, state, s, selection, actions),
        TeachView::Matrix => matrix_panel::show(ui, state, s, actions),
        TeachView::Compare => compare_panel::show(ui, state, s, actions),
        TeachView::Mesh => meshing_panel::show(ui, state, s, actions),
    });
}

/// The views that replace the viewport draw there (see [`TeachView::replaces_viewport`]).
pub fn central(ui: &mut egui::Ui, state: &mut TeachState, snap: Option<&Snapshot>, exposure: f32) {
    let Some(s) = snap else {
        ui.label("Building the mesh…");
        return;
    };
    match state.view {
        TeachView::Compare => compare_panel::central(ui, state, s, exposure),
        TeachView::Mesh => meshing_panel::central(ui, state, s, exposure),
        _ => {}
    }
}

/// Commands that turn off what a view asked for once another view is chosen.
pub fn leave_views(state: &mut TeachState, actions: &mut Vec<Action>) {
    if state.view != TeachView::Compare && state.compare_on {
        state.compare_on = false;
        actions.push(Action::Teach(TeachCommand::Compare(
            compare::CompareCommand::Off,
        )));
    }
    if state.view != TeachView::Mesh && state.mesh_sent.take().is_some() {
        actions.push(Action::Teach(TeachCommand::Mesh(None)));
    }
}

/// Whether the view on screen shows the state of `s` (for a scripted screenshot): the
/// hemicube drawn at the last shooter, the matrix complete with the shooter's column.
pub fn ready(state: Option<&TeachState>, s: &Snapshot) -> bool {
    let Some(state) = state else {
        return true;
    };
    let at_shooter = |p: u32| s.stats.last_shooter.is_none_or(|l| l == p);
    match state.view {
        TeachView::Step => s.stats.steps == 0 || s.teach_step.is_some(),
        TeachView::Hemicube => s
            .teach_hemicube
            .as_ref()
            .is_some_and(|d| at_shooter(d.patch)),
        TeachView::Nusselt => s.teach_nusselt.as_ref().is_some_and(|d| at_shooter(d.from)),
        TeachView::Matrix => s
            .teach_matrix
            .as_ref()
            .is_some_and(|d| d.rows_done == d.patches && d.shooter.is_some_and(at_shooter)),
        TeachView::Compare => s
            .teach_compare
            .as_ref()
            .is_some_and(|d| d.rows_done == d.patches && d.steps >= state.compare_steps),
        TeachView::Mesh => s.teach_mesh.is_some(),
    }
}
