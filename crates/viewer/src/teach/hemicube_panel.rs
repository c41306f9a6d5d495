//! The hemicube view's panel: the five faces unfolded, coloured by the patch each pixel
//! sees (the item buffer) and by its delta form factor (a heat map), a resolution slider,
//! and a receiver's hemicube value beside the exact one.

use std::sync::Arc;

use eframe::egui;

use nusselt_core::formfactor::hemicube::DeltaTable;

use super::super::panels::Action;
use super::super::snapshot::Snapshot;
use super::hemicube::{HemicubeDetail, HemicubeRequest, MAX_RES, unfolded};
use super::{TeachCommand, TeachState};

/// The two images of the detail last drawn.
#[derive(Default)]
pub(crate) struct Textures {
    detail: Option<Arc<HemicubeDetail>>,
    items: Option<egui::TextureHandle>,
    deltas: Option<egui::TextureHandle>,
}

impl std::fmt::Debug for Textures {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Textures")
    }
}

/// A patch's colour in the item buffer: its material's reflectance (lights pale yellow),
/// a little brighter or darker per patch so that neighbouring patches can be told apart.
fn patch_colour(p: u32, material: Option<&nusselt_core::scene::Material>) -> egui::Color32 {
    let shade = 0.75 + 0.25 * ((p.wrapping_mul(2_654_435_761) >> 29) as f32 / 7.0);
    let base = match material {
        Some(m) if m.is_emitter() => [1.0, 0.95, 0.7],
        // Square root: a rough display encoding of the linear reflectance.
        Some(m) => m.reflectance.to_array().map(|c| (c as f32).sqrt()),
        None => [0.5; 3],
    };
    let [r, g, b] = base.map(|c| (c * shade * 255.0).clamp(0.0, 255.0) as u8);
    egui::Color32::from_rgb(r, g, b)
}

/// A heat map: black, red, yellow, white for 0…1.
fn heat(t: f64) -> egui::Color32 {
    let t = t.clamp(0.0, 1.0) as f32;
    let r = (3.0 * t).min(1.0);
    let g = (3.0 * t - 1.0).clamp(0.0, 1.0);
    let b = (3.0 * t - 2.0).clamp(0.0, 1.0);
    egui::Color32::from_rgb((r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8)
}

/// The item buffer and the delta heat map as unfolded crosses (`2·res` square; the corners
/// are blank). The receiver's pixels are cyan in the item buffer.
pub(super) fn images(d: &HemicubeDetail, s: &Snapshot) -> [egui::ColorImage; 2] {
    let element_patch = &s.geometry.element_patch;
    let material = |p: u32| {
        s.geometry
            .patch_material
            .get(p as usize)
            .and_then(|&m| s.materials.get(m as usize))
    };
    let res = d.res;
    let w = 2 * res;
    let blank = egui::Color32::from_gray(24);
    let mut items = vec![blank; w * w];
    let mut deltas = vec![blank; w * w];
    let table = DeltaTable::new(res as u32);
    let max = table.deltas(0).iter().copied().fold(0.0, f64::max);
    let receiver = d.receiver.map(|r| r.patch);
    let mut offset = 0;
    for f in 0..5 {
        let rows = if f == 0 { res } else { res / 2 };
        for j in 0..rows {
            for i in 0..res {
                let k = offset + j * res + i;
                let (x, y) = unfolded(f, i, j, res);
                let id = d.item_buffer[k];
                items[y * w + x] = match element_patch.get(id as usize) {
                    Some(&p) if Some(p) == receiver => egui::Color32::from_rgb(0, 230, 255),
                    Some(&p) => patch_colour(p, material(p)),
                    None => egui::Color32::BLACK,
                };
                deltas[y * w + x] = heat(table.deltas(f)[j * res + i] / max);
            }
        }
        offset += rows * res;
    }
    [
        egui::ColorImage::new([w, w], items),
        egui::ColorImage::new([w, w], deltas),
    ]
}

pub(super) fn show(
    ui: &mut egui::Ui,
    state: &mut TeachState,
    s: &Snapshot,
    selection: Option<u32>,
    actions: &mut Vec<Action>,
) {
    ui.add(
        egui::Slider::new(&mut state.hemicube_res, 2..=MAX_RES / 2)
            .logarithmic(true)
            .text("pixels across the top"),
    );
    state.hemicube_res = state.hemicube_res.div_ceil(2) * 2;
    let request = HemicubeRequest {
        res: state.hemicube_res,
        patch: None,
        receiver: selection,
    };
    if state.sent != Some(request) {
        state.sent = Some(request);
        actions.push(Action::Teach(TeachCommand::Hemicube(Some(request))));
    }
    let Some(d) = s.teach_hemicube.clone() else {
        ui.label("Drawing the hemicube… (it sits at the shooter: the scene needs a light)");
        return;
    };
    let t = &mut state.hemicube_textures;
    if t.detail.as_ref().is_none_or(|old| !Arc::ptr_eq(old, &d)) {
        let [items, deltas] = images(&d, s);
        let ctx = ui.ctx();
        t.items = Some(ctx.load_texture("hemicube-items", items, egui::TextureOptions::NEAREST));
        t.deltas = Some(ctx.load_texture("hemicube-deltas", deltas, egui::TextureOptions::NEAREST));
        t.detail = Some(d.clone());
    }
    let at = if s.stats.last_shooter == Some(d.patch) {
        "the last shooter"
    } else {
        "the first shooter (no shot yet)"
    };
    ui.strong(format!(
        "Hemicube at patch {} ({at}): top {r}×{r}, sides {r}×{h}",
        d.patch,
        r = d.res,
        h = d.res / 2
    ));
    // The two unfolded crosses side by side: the top face in the middle, each side face
    // folded out from the edge it shares with it.
    let side = ((ui.available_width() - 12.0) / 2.0).clamp(100.0, 320.0);
    ui.horizontal(|ui| {
        for tex in [&t.items, &t.deltas].into_iter().flatten() {
            ui.image((tex.id(), egui::vec2(side, side)));
        }
    });
    ui.label(
        "Left, the item buffer: the patch each pixel sees, nearest wins (material colours; \
         cyan: the receiver below; black: nothing). Right, the delta form factors: \
         ΔF_p = ΔA/(π(x²+y²+1)²) on the top, zΔA/(π(y²+z²+1)²) on the sides.",
    );
    let names = ["top", "+u side", "−u side", "+v side", "−v side"];
    egui::Grid::new("teach-hemicube-faces")
        .num_columns(2)
        .show(ui, |ui| {
            for (name, sum) in names.iter().zip(d.face_sums) {
                ui.label(format!("Σ ΔF seen, {name}"));
                // `+ 0.0`: an empty sum is −0.0.
                ui.monospace(format!("{:.5}", sum + 0.0));
                ui.end_row();
            }
            ui.label("Σ ΔF, all pixels");
            ui.monospace(format!("{:.5}", d.table_sum));
            ui.end_row();
        });
    if let Some(r) = d.receiver {
        ui.label(format!(
            "F to patch {} ({}):",
            r.patch,
            if selection == Some(r.patch) {
                "selected"
            } else {
                "seen most; click a surface for another"
            }
        ));
        ui.monospace(format!(
            "hemicube {:.5}   exact {:.5}   error {:+.2} %",
            r.hemicube,
            r.exact,
            100.0 * (r.hemicube - r.exact) / r.exact.max(1e-300)
        ));
    }
}
