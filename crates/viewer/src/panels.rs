//! The side panel and the menu bar. Widgets only read state and return [`Action`]s; the
//! app applies them in one place (`ViewerApp::handle`), so every path to a change (menu,
//! button, key, drop, command line) goes through the same code.

use std::path::PathBuf;

use eframe::egui;

use nusselt_core::formfactor::FormFactorMethod;
use nusselt_core::scene::MAX_REFLECTANCE;
use nusselt_core::solver::SolverKind;

use super::automation::parse_channel;
use super::snapshot::Snapshot;
use super::solver_thread::Command;

mod solver_choice;
mod stats;

/// Everything the user can ask for.
#[derive(Debug)]
pub enum Action {
    Solver(Command),
    Remesh(f64),
    SetMethod(FormFactorMethod),
    SetSolver(SolverKind),
    Teach(super::teach::TeachCommand),
    OpenDialog,
    Open(PathBuf),
    OpenBuiltin(String),
    ClearRecent,
    SaveMtl,
    SaveMtlAs,
    SaveScene,
    ResetEdits,
    ExportPly,
    ExportGltf,
    ExportPng,
    FrameScene,
    ResetView,
    Select(Option<u32>),
    Edit {
        material: u32,
        kd: [f64; 3],
        ke: [f64; 3],
    },
    SetLights(Vec<nusselt_core::scene::Light>),
    /// The whole new list of area lights (a re-mesh).
    SetAreaLights(Vec<nusselt_core::scene::AreaLight>),
    Quit,
}

/// Display settings (uniforms and overlays).
#[derive(Clone, Debug)]
pub struct ViewSettings {
    pub ambient: bool,
    pub exposure_stops: f32,
    pub element_edges: bool,
    pub patch_outlines: bool,
    pub highlight_shooter: bool,
    /// Show the ray-traced view (`ray_view.rs`) over the viewport.
    pub ray_traced: bool,
    /// Show the diffuse maps under the solution (what the eye sees); off, the untextured
    /// solution (each element in its mean colour, what radiosity computes).
    pub textures: bool,
}

impl ViewSettings {
    pub fn exposure(&self) -> f32 {
        self.exposure_stops.exp2()
    }
}

/// The numeric fields of the material editor (text kept while it does not parse).
#[derive(Clone, Debug)]
pub struct MaterialEditor {
    pub material: u32,
    pub kd: [f64; 3],
    pub ke: [f64; 3],
    pub kd_text: [String; 3],
    pub ke_text: [String; 3],
    pub error: Option<String>,
}

impl MaterialEditor {
    pub fn new(material: u32, kd: [f64; 3], ke: [f64; 3]) -> Self {
        Self {
            material,
            kd,
            ke,
            kd_text: kd.map(fmt),
            ke_text: ke.map(fmt),
            error: None,
        }
    }
}

fn fmt(x: f64) -> String {
    let s = format!("{x:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s.is_empty() { "0".into() } else { s.into() }
}

/// Panel-side state the app owns.
pub struct PanelState {
    pub view: ViewSettings,
    /// Why `--solver auto` chose the first solver (`UiOptions::solver_reason`).
    pub solver_reason: Option<String>,
    pub element_size: f64,
    pub element_size_text: String,
    pub element_size_error: Option<String>,
    /// Tolerance of "refine adaptively" (`--adaptive`).
    pub adaptive_tolerance: f64,
    /// The ω field of SOR (empty: estimated from the first sweeps).
    pub omega_text: String,
    pub omega_error: Option<String>,
    pub editor: Option<MaterialEditor>,
    pub selection: Option<u32>,
    pub recent: Vec<PathBuf>,
    pub messages: Vec<(bool, String)>,
    /// The solver panicked (the image is the last one it published).
    pub solver_failure: Option<String>,
    pub show_plot: bool,
    /// The Lights panel's own state (lights switched off, the area-light form, placing).
    pub lights: crate::lights_panel::LightsPanel,
}

pub fn menu_bar(ui: &mut egui::Ui, state: &PanelState, actions: &mut Vec<Action>) {
    egui::MenuBar::new().ui(ui, |ui| {
        ui.menu_button("File", |ui| {
            if ui.button("Open…").clicked() {
                actions.push(Action::OpenDialog);
            }
            ui.menu_button("Open recent", |ui| {
                if state.recent.is_empty() {
                    ui.label("(none)");
                }
                for p in &state.recent {
                    if ui.button(p.display().to_string()).clicked() {
                        actions.push(Action::Open(p.clone()));
                    }
                }
                if !state.recent.is_empty() && ui.button("Clear").clicked() {
                    actions.push(Action::ClearRecent);
                }
            });
            ui.menu_button("Built-in", |ui| {
                for name in nusselt_core::scene::BUILTINS {
                    if ui.button(*name).clicked() {
                        actions.push(Action::OpenBuiltin(name.to_string()));
                    }
                }
            });
            ui.separator();
            if ui.button("Save materials (MTL)").clicked() {
                actions.push(Action::SaveMtl);
            }
            if ui.button("Save materials as…").clicked() {
                actions.push(Action::SaveMtlAs);
            }
            if ui
                .button("Save scene (JSON: model, lights, camera, materials)")
                .clicked()
            {
                actions.push(Action::SaveScene);
            }
            if ui.button("Reset edits").clicked() {
                actions.push(Action::ResetEdits);
            }
            ui.separator();
            if ui.button("Export solution (PLY)…").clicked() {
                actions.push(Action::ExportPly);
            }
            if ui.button("Export lit mesh (glTF)…").clicked() {
                actions.push(Action::ExportGltf);
            }
            if ui.button("Export viewport (PNG)…").clicked() {
                actions.push(Action::ExportPng);
            }
            ui.separator();
            if ui.button("Quit").clicked() {
                actions.push(Action::Quit);
            }
        });
        ui.menu_button("View", |ui| {
            if ui.button("Frame scene (F)").clicked() {
                actions.push(Action::FrameScene);
            }
            if ui.button("Scene camera (Home)").clicked() {
                actions.push(Action::ResetView);
            }
        });
    });
}

pub fn side_panel(
    ui: &mut egui::Ui,
    state: &mut PanelState,
    snap: Option<&Snapshot>,
    actions: &mut Vec<Action>,
) {
    egui::ScrollArea::vertical().show(ui, |ui| {
        solver_section(ui, state, snap, actions);
        ui.separator();
        display_section(ui, state, snap, actions);
        ui.separator();
        if let Some(s) = snap {
            stats::stats_section(
                ui,
                s,
                state.solver_failure.is_some(),
                state.solver_reason.as_deref(),
            );
            if state.show_plot {
                stats::plot_section(ui, s);
            }
            ui.checkbox(&mut state.show_plot, "convergence plot");
            ui.separator();
            crate::lights_panel::lights_section(ui, &mut state.lights, s, actions);
            ui.separator();
            selection_section(ui, state, s, actions);
        } else {
            ui.label("Building the mesh…");
        }
        messages_section(ui, state);
    });
}

fn solver_section(
    ui: &mut egui::Ui,
    state: &mut PanelState,
    snap: Option<&Snapshot>,
    actions: &mut Vec<Action>,
) {
    ui.heading("Solver");
    if let Some(s) = snap {
        ui.label(match &s.scene_source {
            Some(p) => format!("{} ({})", s.scene_name, p.display()),
            None => format!("{} (built-in)", s.scene_name),
        });
    }
    play_controls(ui, snap.is_some_and(|s| s.stats.playing), actions);
    if let Some(s) = snap {
        method_choice(ui, s, actions);
        solver_choice::solver_choice(ui, state, s.solver_kind, actions);
        element_size_controls(ui, state, s, actions);
        adaptive_controls(ui, state, actions);
        if let Some(e) = &state.element_size_error {
            ui.colored_label(egui::Color32::LIGHT_RED, e);
        }
    }
}

/// Play or Pause, Step, Reset.
fn play_controls(ui: &mut egui::Ui, playing: bool, actions: &mut Vec<Action>) {
    ui.horizontal(|ui| {
        if playing {
            if ui.button("Pause").clicked() {
                actions.push(Action::Solver(Command::Pause));
            }
        } else if ui.button("Play").clicked() {
            actions.push(Action::Solver(Command::Play));
        }
        if ui
            .button("Step")
            .on_hover_text("one step: a shot, or a matrix row, or a sweep")
            .clicked()
        {
            actions.push(Action::Solver(Command::Step));
        }
        if ui.button("Reset").on_hover_text("back to dark").clicked() {
            actions.push(Action::Solver(Command::Reset));
        }
    });
}

/// The form-factor method's combo box.
fn method_choice(ui: &mut egui::Ui, s: &Snapshot, actions: &mut Vec<Action>) {
    let mut method = s.method;
    egui::ComboBox::from_label("form factors")
        .selected_text(method.name())
        .show_ui(ui, |ui| {
            for m in FormFactorMethod::ALL {
                ui.selectable_value(&mut method, *m, m.name());
            }
        });
    if method != s.method {
        actions.push(Action::SetMethod(method));
    }
}

/// Element size: a log slider (applied when released) and a validated field.
fn element_size_controls(
    ui: &mut egui::Ui,
    state: &mut PanelState,
    s: &Snapshot,
    actions: &mut Vec<Action>,
) {
    let diag = (s.geometry.bounds_max - s.geometry.bounds_min)
        .length()
        .max(1e-9);
    let (lo, hi) = (diag / 1000.0, diag / 8.0);
    ui.label("element size");
    ui.horizontal(|ui| {
        let r = ui.add(
            egui::Slider::new(&mut state.element_size, lo..=hi)
                .logarithmic(true)
                .show_value(false),
        );
        if r.changed() {
            state.element_size_text = fmt_size(state.element_size);
        }
        if r.drag_stopped() || (r.changed() && !r.dragged()) {
            actions.push(Action::Remesh(state.element_size));
        }
        let t =
            ui.add(egui::TextEdit::singleline(&mut state.element_size_text).desired_width(70.0));
        if t.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter)) {
            match state.element_size_text.trim().parse::<f64>() {
                Ok(x) if x.is_finite() && x > 0.0 => {
                    state.element_size = x;
                    state.element_size_error = None;
                    actions.push(Action::Remesh(x));
                }
                _ => {
                    state.element_size_error = Some(format!(
                        "'{}' is not a positive number",
                        state.element_size_text.trim()
                    ))
                }
            }
        }
    });
}

/// "Refine adaptively" with its tolerance.
fn adaptive_controls(ui: &mut egui::Ui, state: &mut PanelState, actions: &mut Vec<Action>) {
    ui.horizontal(|ui| {
        if ui
            .button("Refine adaptively")
            .on_hover_text(
                "refine where the radiance varies across an element by more than the \
                 tolerance, solve again, and repeat (turn on the element wireframe to \
                 watch the mesh grow)",
            )
            .clicked()
        {
            actions.push(Action::Solver(Command::Adapt(Some(
                state.adaptive_tolerance,
            ))));
        }
        ui.add(
            egui::DragValue::new(&mut state.adaptive_tolerance)
                .range(0.02..=2.0)
                .speed(0.005)
                .prefix("tolerance "),
        );
    });
}

fn fmt_size(x: f64) -> String {
    format!("{x:.4}")
}

fn display_section(
    ui: &mut egui::Ui,
    state: &mut PanelState,
    snap: Option<&Snapshot>,
    actions: &mut Vec<Action>,
) {
    ui.heading("Display");
    let v = &mut state.view;
    ui.checkbox(&mut v.ambient, "ambient term");
    let textured = snap.is_some_and(|s| s.textures.is_some());
    ui.add_enabled(textured, egui::Checkbox::new(&mut v.textures, "textures"))
        .on_hover_text(
            "on: the diffuse maps under the computed light (what the eye sees); off: each \
             element in its texture's mean colour (what radiosity computes)",
        )
        .on_disabled_hover_text("the scene has no diffuse maps");
    ui.add(egui::Slider::new(&mut v.exposure_stops, -8.0..=8.0).text("exposure (stops)"));
    ui.checkbox(&mut v.element_edges, "element wireframe");
    ui.checkbox(&mut v.patch_outlines, "patch outlines");
    ui.checkbox(&mut v.highlight_shooter, "highlight shooter");
    ui.checkbox(&mut v.ray_traced, "ray-traced view")
        .on_hover_text(
            "the second pass: direct light per pixel with exact shadows, the indirect rest from \
         the solution; refines while the camera rests",
        );
    ui.horizontal(|ui| {
        if ui.button("Frame scene").clicked() {
            actions.push(Action::FrameScene);
        }
        if ui.button("Scene camera").clicked() {
            actions.push(Action::ResetView);
        }
    });
}

fn rgb_rows(
    ui: &mut egui::Ui,
    id: &str,
    values: &mut [f64; 3],
    texts: &mut [String; 3],
    max: f64,
    error: &mut Option<String>,
) -> bool {
    let mut changed = false;
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        ui.horizontal(|ui| {
            ui.label(*name);
            let r = ui.add(
                egui::Slider::new(&mut values[c], 0.0..=max)
                    .show_value(false)
                    .clamping(egui::SliderClamping::Never),
            );
            if r.changed() {
                texts[c] = fmt(values[c]);
                changed = true;
            }
            let t = ui.add(
                egui::TextEdit::singleline(&mut texts[c])
                    .id_salt((id, c))
                    .desired_width(64.0),
            );
            if t.lost_focus() {
                match parse_channel(&texts[c]) {
                    Ok(x) if x <= max || max > MAX_REFLECTANCE => {
                        values[c] = x;
                        *error = None;
                        changed = true;
                    }
                    Ok(x) => *error = Some(format!("{id} {name}: {x} is above {max}")),
                    Err(e) => *error = Some(format!("{id} {name}: {e}")),
                }
            }
        });
    }
    changed
}

fn selection_section(
    ui: &mut egui::Ui,
    state: &mut PanelState,
    s: &Snapshot,
    actions: &mut Vec<Action>,
) {
    ui.heading("Selection");
    let Some(patch) = state.selection else {
        ui.label("Click a surface to select it.");
        return;
    };
    let Some(&mat) = s.geometry.patch_material.get(patch as usize) else {
        return;
    };
    let Some(m) = s.materials.get(mat as usize) else {
        return;
    };
    ui.label(format!("patch {patch}, material '{}'", m.name));
    if let Some(loaded) = s.loaded_materials.get(mat as usize)
        && loaded != m
    {
        ui.label("(edited)");
    }
    let editor = state
        .editor
        .get_or_insert_with(|| MaterialEditor::new(mat, m.reflectance.into(), m.emission.into()));
    if editor.material != mat {
        *editor = MaterialEditor::new(mat, m.reflectance.into(), m.emission.into());
    }
    ui.label("reflectance (Kd)");
    let mut changed = rgb_rows(
        ui,
        "Kd",
        &mut editor.kd,
        &mut editor.kd_text,
        MAX_REFLECTANCE,
        &mut editor.error,
    );
    ui.label("emission (Ke, W/(m² sr))");
    let ke_max = editor.ke.iter().copied().fold(50.0, f64::max);
    changed |= rgb_rows(
        ui,
        "Ke",
        &mut editor.ke,
        &mut editor.ke_text,
        ke_max,
        &mut editor.error,
    );
    ui.horizontal(|ui| {
        if ui.button("Make it a light").clicked() {
            editor.ke = [10.0; 3];
            editor.ke_text = editor.ke.map(fmt);
            changed = true;
        }
        if ui.button("No emission").clicked() {
            editor.ke = [0.0; 3];
            editor.ke_text = editor.ke.map(fmt);
            changed = true;
        }
    });
    if let Some(e) = &editor.error {
        ui.colored_label(egui::Color32::LIGHT_RED, e);
    }
    if changed {
        editor.kd = editor.kd.map(|x| x.clamp(0.0, MAX_REFLECTANCE));
        actions.push(Action::Edit {
            material: mat,
            kd: editor.kd,
            ke: editor.ke,
        });
    }
    ui.horizontal(|ui| {
        if ui.button("Save MTL").clicked() {
            actions.push(Action::SaveMtl);
        }
        if ui.button("Reset edits").clicked() {
            actions.push(Action::ResetEdits);
        }
        if ui.button("Deselect").clicked() {
            actions.push(Action::Select(None));
        }
    });
}

fn messages_section(ui: &mut egui::Ui, state: &mut PanelState) {
    if state.messages.is_empty() {
        return;
    }
    ui.separator();
    for (error, text) in state.messages.iter().rev().take(6) {
        if *error {
            ui.colored_label(egui::Color32::LIGHT_RED, text);
        } else {
            ui.label(text);
        }
    }
    if ui.button("Clear messages").clicked() {
        state.messages.clear();
    }
}
