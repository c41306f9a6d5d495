//! The form-factor matrix view's panel: the patch-level matrix as an image (log scale, the
//! shooter's row and column highlighted) filling row by row, its sparsity and storage, and
//! the legend of the scene coloured by the shooter's column `F_ij`.

use std::sync::Arc;

use eframe::egui;

use super::super::panels::Action;
use super::super::snapshot::Snapshot;
use super::matrix::{LOG_FLOOR, MatrixDetail, heat, log_scale};
use super::{TeachCommand, TeachState};

/// Largest side of the matrix image (larger matrices are sampled).
const MAX_SIDE: usize = 1024;

/// The texture of the detail last drawn.
#[derive(Default)]
pub(crate) struct Texture {
    detail: Option<Arc<MatrixDetail>>,
    image: Option<egui::TextureHandle>,
}

impl std::fmt::Debug for Texture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Texture")
    }
}

fn colour([r, g, b]: [f32; 3]) -> egui::Color32 {
    let c = |x: f32| (x.clamp(0.0, 1.0) * 255.0) as u8;
    egui::Color32::from_rgb(c(r), c(g), c(b))
}

/// The matrix as an image: row `p` top to bottom, column `q` left to right, `log10 F_pq`
/// on the heat scale; rows not computed yet dark blue; the shooter's row and column tinted
/// cyan.
pub(super) fn image(d: &MatrixDetail) -> egui::ColorImage {
    let n = d.patches.max(1);
    let side = n.min(MAX_SIDE);
    let max = d
        .patch_f
        .iter()
        .filter(|f| f.is_finite())
        .fold(0.0f64, |m, &f| m.max(f64::from(f)));
    let band = n / 150;
    let mut pixels = Vec::with_capacity(side * side);
    for y in 0..side {
        let p = y * n / side;
        for x in 0..side {
            let q = x * n / side;
            let f = d.patch_f.get(p * n + q).copied().unwrap_or(f32::NAN);
            let mut c = if f.is_nan() {
                egui::Color32::from_rgb(10, 14, 40)
            } else {
                colour(heat(log_scale(f64::from(f), max)))
            };
            // A band a few pixels wide on screen, however many patches.
            let near = |k: usize, s: u32| k.abs_diff(s as usize) <= band;
            if d.shooter.is_some_and(|s| near(p, s) || near(q, s)) {
                c = egui::Color32::from_rgb(c.r() / 2, 128 + c.g() / 2, 128 + c.b() / 2);
            }
            pixels.push(c);
        }
    }
    egui::ColorImage::new([side, side], pixels)
}

fn megabytes(bytes: f64) -> String {
    format!("{:.1} MB", bytes / 1e6)
}

pub(super) fn show(
    ui: &mut egui::Ui,
    state: &mut TeachState,
    s: &Snapshot,
    actions: &mut Vec<Action>,
) {
    if !state.matrix_on {
        state.matrix_on = true;
        actions.push(Action::Teach(TeachCommand::Matrix(true)));
    }
    ui.checkbox(
        &mut state.show_column,
        "colour the scene by F_ij from the shooter (log scale)",
    );
    let Some(d) = s.teach_matrix.clone() else {
        ui.label(
            "Computing the first row… (a mesh too large for the view is refused in the messages)",
        );
        return;
    };
    if let Some(shooter) = d.shooter {
        let which = if s.stats.last_shooter == Some(shooter) {
            "the last shooter"
        } else {
            "the first shooter"
        };
        ui.label(format!(
            "Column of patch i = {shooter} ({which}): F_ij to every element j, largest {:.3e}",
            d.column_max
        ));
        // The legend of the viewport's colours.
        let (rect, _) = ui.allocate_exact_size(
            egui::vec2(ui.available_width().min(320.0), 14.0),
            egui::Sense::hover(),
        );
        let steps = 64;
        for k in 0..steps {
            let t = k as f64 / (steps - 1) as f64;
            let x0 = rect.left() + rect.width() * k as f32 / steps as f32;
            let x1 = rect.left() + rect.width() * (k + 1) as f32 / steps as f32;
            ui.painter().rect_filled(
                egui::Rect::from_min_max(egui::pos2(x0, rect.top()), egui::pos2(x1, rect.bottom())),
                0.0,
                colour(heat(t)),
            );
        }
        ui.horizontal(|ui| {
            ui.monospace(format!("≤ {LOG_FLOOR:.0e}"));
            ui.add_space(ui.available_width().min(320.0) - 150.0);
            ui.monospace(format!("{:.1e}", d.column_max));
        });
    } else {
        ui.label("No shot yet: the highlighted column appears with the first shot.");
    }
    let t = &mut state.matrix_texture;
    if t.detail.as_ref().is_none_or(|old| !Arc::ptr_eq(old, &d)) {
        t.image = Some(ui.ctx().load_texture(
            "form-factor-matrix",
            image(&d),
            egui::TextureOptions::NEAREST,
        ));
        t.detail = Some(d.clone());
    }
    ui.label(format!(
        "Patch matrix F_pq ({n}×{n}), rows filled while the solver is idle: {}/{n}",
        d.rows_done,
        n = d.patches
    ));
    if let Some(tex) = &t.image {
        let side = (ui.available_width() - 8.0).clamp(120.0, 360.0);
        ui.image((tex.id(), egui::vec2(side, side)));
    }
    let n = d.patches as f64;
    let filled = d.rows_done as f64 * n;
    egui::Grid::new("teach-matrix")
        .num_columns(2)
        .show(ui, |ui| {
            let mut row = |k: &str, v: String| {
                ui.label(k);
                ui.monospace(v);
                ui.end_row();
            };
            row(
                "non-zero (rows done)",
                format!("{:.1} %", 100.0 * d.nonzero as f64 / filled.max(1.0)),
            );
            row("patch matrix, 4 B each", megabytes(4.0 * n * n));
            row(
                "patch × element rows",
                megabytes(4.0 * n * d.elements as f64),
            );
            row("the lecture's 10,000 patches", megabytes(4.0 * 1e4 * 1e4));
        });
}
