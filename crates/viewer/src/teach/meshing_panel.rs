//! Uniform vs adaptive meshing: the tolerance and the numbers in the Teach panel, and in
//! place of the viewport the two meshes' images (one colour per element, edges drawn).

use std::sync::Arc;

use eframe::egui;

use super::super::export::srgb8;
use super::super::panels::Action;
use super::super::snapshot::Snapshot;
use super::meshing::{MeshDetail, MeshSide};
use super::{TeachCommand, TeachState};

/// The textures of the detail last drawn, and the settings they were drawn with.
#[derive(Default)]
pub(crate) struct Textures {
    detail: Option<Arc<MeshDetail>>,
    key: Option<(u32, bool, bool)>,
    uniform: Option<egui::TextureHandle>,
    adaptive: Option<egui::TextureHandle>,
}

impl std::fmt::Debug for Textures {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Textures")
    }
}

pub(super) fn show(
    ui: &mut egui::Ui,
    state: &mut TeachState,
    s: &Snapshot,
    actions: &mut Vec<Action>,
) {
    let mut send = |state: &mut TeachState| {
        state.mesh_sent = Some(state.mesh_tolerance);
        actions.push(Action::Teach(TeachCommand::Mesh(Some(
            state.mesh_tolerance,
        ))));
    };
    if state.mesh_sent.is_none() {
        send(state);
    }
    ui.label(
        "Constant elements show one radiosity each: they must be small where the light \
         changes fast (shadow edges, near the light, contact lines) and may be large where it \
         is constant. Left, the uniform mesh of the viewer; right, an adaptive one: the scene \
         meshed four times coarser, solved, and refined twice (each time halving the \
         elements) where the radiance across an element varies by more than the tolerance, \
         or a light is partly hidden from it by as much; the solution is carried onto each \
         refined mesh, none of its light gained or lost.",
    );
    let r = ui
        .add(
            egui::Slider::new(&mut state.mesh_tolerance, 0.02..=1.0)
                .logarithmic(true)
                .text("tolerance"),
        )
        .on_hover_text(
            "refine where the display vertices around an element differ from its value by \
             more than this fraction of it",
        );
    // Each value is seconds of work: sent when the drag ends.
    if (r.drag_stopped() || (r.changed() && !r.dragged()))
        && state.mesh_sent != Some(state.mesh_tolerance)
    {
        send(state);
    }
    ui.checkbox(&mut state.mesh_edges, "draw the element edges");
    ui.checkbox(
        &mut state.mesh_sizes,
        "colour by element size (heat scale: small elements bright)",
    );
    if let Some(stage) = s.teach_mesh_stage {
        ui.horizontal(|ui| {
            ui.spinner();
            ui.label(format!("Computing: {stage}…"));
        });
    }
    let Some(d) = s.teach_mesh.clone() else {
        return;
    };
    egui::Grid::new("teach-mesh").num_columns(3).show(ui, |ui| {
        ui.label("");
        ui.strong("uniform");
        ui.strong(format!("adaptive ({})", d.tolerance));
        ui.end_row();
        let mut row = |k: &str, f: &dyn Fn(&MeshSide) -> String| {
            ui.label(k);
            ui.monospace(f(&d.uniform));
            ui.monospace(f(&d.adaptive));
            ui.end_row();
        };
        row("elements", &|m| m.elements.to_string());
        row("patches (shooters)", &|m| m.patches.to_string());
        row("smallest element area", &|m| format!("{:.1}", m.smallest));
        row("largest element area", &|m| format!("{:.1}", m.largest));
        row("mesh + solve", &|m| format!("{:.1} s", m.seconds));
    });
    ui.label(format!(
        "The adaptive mesh has {:.0} % of the uniform one's elements. Colour by element \
         size and look where it refined (near the light, along the blocks' edges and \
         shadows, in the corners) and where it stayed coarse (the middle of the walls).",
        100.0 * d.adaptive.elements as f64 / d.uniform.elements.max(1) as f64
    ));
}

fn image(
    side: &MeshSide,
    edges: bool,
    sizes: bool,
    range: (f32, f32),
    exposure: f32,
) -> egui::ColorImage {
    // Element size on a log heat scale from the largest (dark) to the smallest (white).
    let (small, large) = range;
    let size_colour = |a: f32| {
        let t = if large > small {
            ((large / a.max(small)).ln() / (large / small).ln()).clamp(0.0, 1.0)
        } else {
            1.0
        };
        super::matrix::heat(0.15 + 0.85 * f64::from(t)).map(|c| (c * 255.0) as u8)
    };
    let px = side.image.paint(
        |e| {
            let e = e as usize;
            if sizes {
                side.area.get(e).map_or([0, 0, 0], |a| size_colour(*a))
            } else {
                side.radiance
                    .get(e)
                    .map_or([0, 0, 0], |c| c.map(|x| srgb8(x, exposure)))
            }
        },
        edges.then_some([40, 40, 40]),
    );
    let rgba: Vec<egui::Color32> = px
        .iter()
        .map(|c| egui::Color32::from_rgb(c[0], c[1], c[2]))
        .collect();
    egui::ColorImage::new([side.image.width, side.image.height], rgba)
}

pub(super) fn central(ui: &mut egui::Ui, state: &mut TeachState, s: &Snapshot, exposure: f32) {
    let Some(d) = s.teach_mesh.clone() else {
        ui.horizontal(|ui| {
            ui.spinner();
            ui.label(format!(
                "Meshing and solving both ways: {}…",
                s.teach_mesh_stage.unwrap_or("starting")
            ));
        });
        return;
    };
    let key = (exposure.to_bits(), state.mesh_edges, state.mesh_sizes);
    // One size scale for both meshes.
    let range = (
        d.uniform.smallest.min(d.adaptive.smallest) as f32,
        d.uniform.largest.max(d.adaptive.largest) as f32,
    );
    let t = &mut state.mesh_textures;
    if t.detail.as_ref().is_none_or(|old| !Arc::ptr_eq(old, &d)) || t.key != Some(key) {
        let opts = egui::TextureOptions::NEAREST;
        let ctx = ui.ctx();
        t.uniform = Some(ctx.load_texture(
            "mesh-uniform",
            image(
                &d.uniform,
                state.mesh_edges,
                state.mesh_sizes,
                range,
                exposure,
            ),
            opts,
        ));
        t.adaptive = Some(ctx.load_texture(
            "mesh-adaptive",
            image(
                &d.adaptive,
                state.mesh_edges,
                state.mesh_sizes,
                range,
                exposure,
            ),
            opts,
        ));
        t.detail = Some(d.clone());
        t.key = Some(key);
    }
    let side = ((ui.available_width() - 24.0) / 2.0)
        .min(ui.available_height() - 60.0)
        .max(120.0);
    ui.horizontal(|ui| {
        for (title, tex, m) in [
            ("Uniform", &t.uniform, &d.uniform),
            ("Adaptive", &t.adaptive, &d.adaptive),
        ] {
            ui.vertical(|ui| {
                ui.heading(format!("{title}: {} elements", m.elements));
                if let Some(tex) = tex {
                    ui.image((tex.id(), egui::vec2(side, side)));
                }
            });
        }
    });
}
