//! The ray-traced view in the viewport (the Display section's toggle, `--ray-traced`): asks
//! the solver thread for the render input, submits it with the camera to the render thread
//! ([`super::raytrace`]) whenever the camera rests, and draws the newest image over the
//! viewport while it matches the camera (the rasterised view shows while the camera
//! moves).

use std::sync::Arc;

use eframe::egui;

use super::app::ViewerApp;
use super::export::srgb8;
use super::panels::Action;
use super::raytrace::{MAX_SIDE, RayImage, RayJob, RayTracer};
use super::snapshot::Snapshot;
use super::solver_thread::Command;

/// A screenshot of the ray-traced view waits for this many samples per pixel.
pub const SCREENSHOT_SPP: u32 = 16;

/// The ray-traced view's state on the UI side.
#[derive(Default)]
pub struct RayView {
    tracer: Option<RayTracer>,
    /// Whether the solver thread was told to publish the input.
    asked: bool,
    image: Option<Arc<RayImage>>,
    texture: Option<egui::TextureHandle>,
    /// The image and exposure the texture shows.
    texture_of: Option<(usize, u32)>,
    /// The job last submitted (the image must be of it to be shown).
    job: Option<(nusselt_core::scene::Camera, u32, u32, u64)>,
}

impl ViewerApp {
    /// Whether the ray-traced view (when on) shows an image of at least `spp` samples for the
    /// current camera and solution.
    pub(super) fn ray_ready(&self, spp: u32) -> bool {
        !self.panel.view.ray_traced
            || self
                .ray
                .image
                .as_ref()
                .is_some_and(|i| i.spp >= spp && self.ray.job == Some(key(i)))
    }

    pub(super) fn ray_view(
        &mut self,
        ui: &mut egui::Ui,
        rect: egui::Rect,
        snap: &Snapshot,
        moving: bool,
        actions: &mut Vec<Action>,
    ) {
        let on = self.panel.view.ray_traced;
        let view = &mut self.ray;
        if on != view.asked {
            view.asked = on;
            actions.push(Action::Solver(Command::RayTraced(on)));
        }
        if !on {
            if let Some(t) = view.tracer.as_mut() {
                t.stop();
            }
            view.image = None;
            view.job = None;
            return;
        }
        if view.tracer.is_none() {
            let ctx = ui.ctx().clone();
            match RayTracer::spawn(Box::new(move || ctx.request_repaint())) {
                Ok(t) => view.tracer = Some(t),
                Err(e) => {
                    self.panel.view.ray_traced = false;
                    self.message(true, format!("cannot start the ray-traced view: {e}"));
                    return;
                }
            }
        }
        let (Some(tracer), Some(input), Some(camera)) = (
            view.tracer.as_mut(),
            snap.ray_input.clone(),
            self.camera.as_ref(),
        ) else {
            label(ui, rect, "ray-traced view: waiting for the solution…");
            return;
        };
        let camera = camera.to_camera();
        let (width, height) = image_size(rect, ui.ctx().pixels_per_point());
        if !moving {
            view.job = Some((camera, width, height, input.seq));
            tracer.submit(RayJob {
                input: input.clone(),
                camera,
                width,
                height,
            });
        }
        if let Some(i) = tracer.take() {
            view.image = Some(i);
        }
        let current = (camera, width, height, input.seq);
        let Some(image) = view.image.clone().filter(|i| key(i) == current) else {
            if !moving {
                label(ui, rect, "ray-traced view: first pass…");
            }
            return;
        };
        view.draw(ui, rect, &image, self.panel.view.exposure());
        label(
            ui,
            rect,
            &format!(
                "ray-traced: {} samples per pixel, {:.1} s",
                image.spp, image.seconds
            ),
        );
    }
}

impl RayView {
    /// Draws `image` over the viewport at `exposure` (its texture made again only when the
    /// image or the exposure changed).
    fn draw(&mut self, ui: &egui::Ui, rect: egui::Rect, image: &Arc<RayImage>, exposure: f32) {
        let id = (Arc::as_ptr(image) as usize, exposure.to_bits());
        if self.texture_of != Some(id) {
            let pixels: Vec<egui::Color32> = image
                .pixels
                .iter()
                .map(|c| {
                    let [r, g, b] = c.as_vec3().to_array().map(|x| srgb8(x, exposure));
                    egui::Color32::from_rgb(r, g, b)
                })
                .collect();
            let img = egui::ColorImage::new([image.width as usize, image.height as usize], pixels);
            self.texture = Some(ui.ctx().load_texture(
                "ray-traced-view",
                img,
                egui::TextureOptions::LINEAR,
            ));
            self.texture_of = Some(id);
        }
        if let Some(t) = &self.texture {
            ui.painter().image(
                t.id(),
                rect,
                egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
                egui::Color32::WHITE,
            );
        }
    }
}

/// The viewport's size in pixels (`ppp` per point), at most [`MAX_SIDE`] on the longer side.
fn image_size(rect: egui::Rect, ppp: f32) -> (u32, u32) {
    let (w, h) = (rect.width() * ppp, rect.height() * ppp);
    let scale = (MAX_SIDE as f32 / w.max(h)).min(1.0);
    (
        ((w * scale).round() as u32).max(1),
        ((h * scale).round() as u32).max(1),
    )
}

/// What an image shows: camera, size, solution.
fn key(i: &RayImage) -> (nusselt_core::scene::Camera, u32, u32, u64) {
    (i.camera, i.width, i.height, i.input_seq)
}

fn label(ui: &egui::Ui, rect: egui::Rect, text: &str) {
    ui.painter().text(
        rect.left_bottom() + egui::vec2(8.0, -8.0),
        egui::Align2::LEFT_BOTTOM,
        text,
        egui::FontId::proportional(14.0),
        egui::Color32::from_gray(230),
    );
}
