//! The app's file work: file dialogs (on their own thread, `dialog.rs`) and what their
//! answers lead to: saving materials, exporting the solution and the viewport.

use std::path::{Path, PathBuf};

use eframe::egui;

use super::app::ViewerApp;
use super::dialog::{Outcome, Purpose, Request};
use super::export;
use super::panels::Action;
use super::snapshot::Snapshot;

impl ViewerApp {
    pub(super) fn open_dialog(&mut self, ctx: &egui::Context, request: Request) {
        let c = ctx.clone();
        if let Err(e) = self.dialogs.open(request, move || c.request_repaint()) {
            self.message(true, e);
        }
    }

    /// Acts on a dialog's answer: the path goes where the dialog was opened for (the
    /// snapshot then on screen is the one saved or exported).
    pub(super) fn finish_dialog(&mut self, ctx: &egui::Context) {
        let Some(outcome) = self.dialogs.poll() else {
            return;
        };
        match outcome {
            Outcome::Chosen(purpose, p) => match purpose {
                Purpose::Open => self.handle(ctx, Action::Open(p)),
                Purpose::SaveMtlAs => {
                    if let Some(s) = self.snapshot.clone() {
                        self.save_mtl(&s, &p);
                    }
                }
                Purpose::ExportPly => {
                    if let Some(s) = self.snapshot.clone() {
                        self.export_ply(&s, &p);
                    }
                }
                Purpose::ExportGltf => {
                    if let Some(s) = self.snapshot.clone() {
                        self.export_gltf(&s, &p);
                    }
                }
                Purpose::ExportPng => self.request_viewport_png(ctx, p),
            },
            Outcome::Cancelled(_) => {}
            Outcome::Failed(purpose) => {
                self.message(true, format!("the file dialog ({purpose:?}) failed"));
            }
        }
    }

    pub(super) fn save_mtl(&mut self, s: &Snapshot, path: &Path) {
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

    fn export_gltf(&mut self, s: &Snapshot, path: &Path) {
        let (ambient, exposure) = (self.panel.view.ambient, self.panel.view.exposure());
        match super::export_gltf::write_snapshot_gltf(s, path, ambient, exposure) {
            Ok(st) => self.message(
                false,
                format!(
                    "exported {}: {} vertices, {} triangles, {} bytes",
                    path.display(),
                    st.vertices,
                    st.triangles,
                    st.bytes
                ),
            ),
            Err(e) => self.message(true, e.to_string()),
        }
    }

    pub(super) fn request_viewport_png(&mut self, ctx: &egui::Context, path: PathBuf) {
        self.png_export = Some((path, self.viewport_rect));
        let slot = self.png_image.clone();
        let c = ctx.clone();
        ctx.request_screenshot(move |image| {
            slot.publish(image);
            c.request_repaint();
        });
    }

    pub(super) fn finish_viewport_png(&mut self, ctx: &egui::Context) {
        let Some(image) = self.png_image.take() else {
            return;
        };
        let Some((path, rect)) = self.png_export.take() else {
            return;
        };
        let crop = image.region(&rect, Some(ctx.pixels_per_point()));
        match export::write_color_image(&path, &crop) {
            Ok(()) => self.message(false, format!("saved {}", path.display())),
            Err(e) => self.message(true, e.to_string()),
        }
    }
}
