//! The viewport: the orbit camera's mouse and key bindings, picking by click, and the
//! paint callback that draws the snapshot (see [`super::render`]).

use eframe::egui;
use eframe::egui_wgpu;

use super::app::ViewerApp;
use super::panels::Action;
use super::render::{FLAG_SELECTION, FLAG_SHOOTER, NO_PATCH, Overlays, Uniforms, ViewportCallback};
use super::snapshot::Snapshot;
use super::solver_thread::Command;
use super::teach::TeachView;
use std::sync::Arc;

impl ViewerApp {
    pub(super) fn viewport(&mut self, ui: &mut egui::Ui, actions: &mut Vec<Action>) {
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
        steer(camera, ui, &response, rect);
        let view_proj = camera
            .view_proj(rect.aspect_ratio() as f64)
            .to_cols_array_2d();
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
            self.pick(&snap, o, d, actions);
        }
        let (snap, ambient, exposure) = self.shown(snap);
        let uniforms = self.uniforms(&snap, view_proj, ambient, exposure);
        let view = &self.panel.view;
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
        let moving = response.dragged() || ui.input(|i| i.smooth_scroll_delta.y != 0.0);
        self.ray_view(ui, rect, &snap, moving, actions);
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

    /// A click in the viewport along the ray `o + t·d`: places the light the Lights panel
    /// asked for, or selects the patch (and, in teaching mode, the element) hit.
    fn pick(&mut self, snap: &Snapshot, o: glam::DVec3, d: glam::DVec3, actions: &mut Vec<Action>) {
        if self.panel.lights.is_placing() {
            // The Lights panel asked for this click: place the light there.
            if let Some((point, normal)) = snap.geometry.pick_surface(o, d) {
                crate::lights_panel::place_at(&mut self.panel.lights, snap, point, normal, actions);
            }
        } else {
            actions.push(Action::Select(snap.geometry.pick(o, d).map(|p| p.0)));
            if let Some(teach) = self.teach.as_mut() {
                teach.element = snap.geometry.pick_element(o, d);
            }
        }
    }

    /// What the viewport draws: the snapshot, or in step mode what the last shot added and
    /// in the matrix view the shooter's column (colours as radiance, exposure 0) instead of
    /// the solution; with the ambient multiplier and the exposure to draw it with.
    fn shown(&self, snap: Arc<Snapshot>) -> (Arc<Snapshot>, [f32; 3], f32) {
        let view = &self.panel.view;
        // Multiplies the per-vertex display correction (see `Snapshot::correction`).
        let ambient = if view.ambient { [1.0; 3] } else { [0.0; 3] };
        let replaced = self.teach.as_ref().and_then(|t| match t.view {
            TeachView::Step if t.show_received => snap
                .teach_step
                .as_ref()
                .map(|d| d.received_vertices.clone()),
            TeachView::Matrix if t.show_column => snap
                .teach_matrix
                .as_ref()
                .and_then(|d| d.column_colours.clone()),
            _ => None,
        });
        // The column's colours are display colours: no exposure.
        let exposure = if replaced.is_some()
            && self
                .teach
                .as_ref()
                .is_some_and(|t| t.view == TeachView::Matrix)
        {
            1.0
        } else {
            view.exposure()
        };
        match replaced {
            Some(radiance) => {
                let snap = Arc::new(Snapshot {
                    // Its own sequence numbers, so the radiance buffer is uploaded again.
                    seq: snap.seq | 1 << 62,
                    radiance,
                    ..(*snap).clone()
                });
                (snap, [0.0; 3], exposure)
            }
            None => (snap, ambient, exposure),
        }
    }

    /// The viewport shader's uniforms for drawing `snap`.
    fn uniforms(
        &self,
        snap: &Snapshot,
        view_proj: [[f32; 4]; 4],
        ambient: [f32; 3],
        exposure: f32,
    ) -> Uniforms {
        let view = &self.panel.view;
        let mut flags = 0;
        if view.highlight_shooter {
            flags |= FLAG_SHOOTER;
        }
        if self.panel.selection.is_some() {
            flags |= FLAG_SELECTION;
        }
        let shooter = snap.stats.last_shooter.unwrap_or(NO_PATCH);
        Uniforms {
            view_proj,
            ambient_exposure: [ambient[0], ambient[1], ambient[2], exposure],
            ids: [shooter, self.panel.selection.unwrap_or(NO_PATCH), flags, 0],
            element_line_color: [0.0, 0.0, 0.0, 0.45],
            patch_line_color: [1.0, 1.0, 1.0, 0.8],
            params: [
                1e-3,
                if view.textures && snap.textures.is_some() {
                    1.0
                } else {
                    0.0
                },
                0.0,
                0.0,
            ],
        }
    }

    pub(super) fn keys(&mut self, ctx: &egui::Context, actions: &mut Vec<Action>) {
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

/// Camera: drag = orbit, right/middle drag or shift+drag = pan, wheel = zoom.
fn steer(
    camera: &mut crate::camera::OrbitCamera,
    ui: &egui::Ui,
    response: &egui::Response,
    rect: egui::Rect,
) {
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
}
