//! The Nusselt analogue's panel: the base disk seen from above with the patch's projection
//! outlined and the sample points that fell inside it; the covered fraction beside the
//! exact form factor; copies of the patch with the same projection and the same value.

use eframe::egui;

use super::super::panels::Action;
use super::super::snapshot::Snapshot;
use super::nusselt::NusseltRequest;
use super::{TeachCommand, TeachState};

pub(super) fn show(
    ui: &mut egui::Ui,
    state: &mut TeachState,
    s: &Snapshot,
    selection: Option<u32>,
    actions: &mut Vec<Action>,
) {
    let request = NusseltRequest {
        from: None,
        to: selection,
    };
    if state.nusselt_sent != Some(request) {
        state.nusselt_sent = Some(request);
        actions.push(Action::Teach(TeachCommand::Nusselt(Some(request))));
    }
    let Some(d) = s.teach_nusselt.clone() else {
        ui.label("Projecting… (from the shooter: the scene needs a light)");
        return;
    };
    ui.strong(format!(
        "From the centre of patch {} (the shooter) to patch {} ({})",
        d.from,
        d.to,
        if selection == Some(d.to) {
            "selected"
        } else {
            "largest form factor; click a surface for another"
        }
    ));
    ui.label(
        "Project the patch onto the unit hemisphere around the point, then straight down \
         onto its base disk: F = projected area / π.",
    );
    let side = (ui.available_width() - 8.0).clamp(120.0, 240.0);
    let (rect, _) = ui.allocate_exact_size(egui::vec2(side, side), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    let centre = rect.center();
    let radius = side * 0.48;
    let to_screen = |[x, y]: [f64; 2]| centre + egui::vec2(x as f32, -(y as f32)) * radius;
    painter.circle_filled(centre, radius, egui::Color32::from_gray(40));
    painter.circle_stroke(centre, radius, egui::Stroke::new(1.5, egui::Color32::GRAY));
    for (p, hit) in &d.samples {
        if *hit {
            painter.circle_filled(to_screen(*p), 1.2, egui::Color32::from_rgb(255, 210, 60));
        }
    }
    let outline: Vec<egui::Pos2> = d.outline.iter().map(|p| to_screen(*p)).collect();
    painter.add(egui::Shape::closed_line(
        outline,
        egui::Stroke::new(2.0, egui::Color32::from_rgb(0, 220, 255)),
    ));
    ui.label("Cyan: the projection's outline; yellow: sample points inside it.");

    egui::Grid::new("teach-nusselt")
        .num_columns(2)
        .show(ui, |ui| {
            let mut row = |k: &str, v: String| {
                ui.label(k);
                ui.monospace(v);
                ui.end_row();
            };
            row(
                "covered fraction",
                format!(
                    "{:.5} ± {:.5} ({} points)",
                    d.fraction,
                    d.sigma,
                    d.samples.len()
                ),
            );
            row("exact F, dA_i to A_j", format!("{:.5}", d.exact));
            for (scale, f) in &d.copies {
                row(
                    &format!("patch scaled ×{scale} about the point"),
                    format!("{f:.5}"),
                );
            }
        });
    ui.label(
        "The scaled copies are nearer or farther but have the same projection: the same \
         form factor. (Occlusion is left out here; the hemicube adds it.)",
    );
    ui.separator();
    ui.label("The same in 3-D: the patch, its projection on the hemisphere (yellow), dropped onto the disk (cyan).");
    let side = (ui.available_width() - 8.0).clamp(160.0, 300.0);
    super::nusselt_3d::draw(ui, &d, &mut state.nusselt_view, side);
}
