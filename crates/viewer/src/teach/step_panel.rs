//! Step mode's panel: one shot per click, and back; the shot's numbers with the formula
//! each came from, in the lecture's notation.

use eframe::egui;

use nusselt_core::scene::Rgb;

use super::super::panels::Action;
use super::super::snapshot::Snapshot;
use super::super::solver_thread::Command;
use super::step::StepDetail;
use super::{TeachCommand, TeachState};

fn rgb(c: Rgb) -> String {
    format!("({:.4}, {:.4}, {:.4})", c.x, c.y, c.z)
}

pub(super) fn show(
    ui: &mut egui::Ui,
    state: &mut TeachState,
    s: &Snapshot,
    actions: &mut Vec<Action>,
) {
    step_buttons(ui, s, actions);
    ui.checkbox(
        &mut state.show_received,
        "show what the last shot added (ΔB_j) instead of B",
    );
    if s.stats.solver != "shooting" {
        ui.label(format!(
            "Step mode explains shooting; the solver is {} (choose shooting in the solver panel).",
            s.stats.solver
        ));
        return;
    }
    let Some(d) = s.teach_step.as_deref() else {
        ui.label(format!(
            "{} shots so far. Press \"Shoot once\": the shot's numbers appear here, the \
             shooter turns yellow, and a click on a surface shows its element's numbers.",
            s.stats.steps
        ));
        return;
    };
    ui.strong(format!("Shot {}: patch i = {}", d.step, d.shooter));
    shooter_numbers(ui, d);
    let n = d.received.len();
    let f_sum: f64 = (0..n).map(|j| d.f_ij(j)).sum();
    ui.label("2. A column of form factors from i to every element j:");
    mono(ui, format!("Σ_j F_ij = {f_sum:.4} ({n} elements)"));
    ui.label("3. Every receiver gains B_j += ρ_j ΔB_i F_ij A_i/A_j:");
    let j = state
        .element
        .map(|e| e as usize)
        .filter(|&e| e < n)
        .or_else(|| d.top_receivers(1).first().copied());
    if let Some(j) = j {
        receiver_numbers(ui, d, j, state.element.is_some());
    }
    ambient_numbers(ui, d);
    ui.separator();
    largest_gains(ui, d);
}

/// One line of numbers, monospaced and wrapped.
fn mono(ui: &mut egui::Ui, text: String) {
    ui.add(egui::Label::new(egui::RichText::new(text).monospace()).wrap());
}

/// Shoot once, Back, Reset.
fn step_buttons(ui: &mut egui::Ui, s: &Snapshot, actions: &mut Vec<Action>) {
    ui.horizontal(|ui| {
        if ui
            .button("Shoot once")
            .on_hover_text("one shot from the patch with the most unshot power")
            .clicked()
        {
            actions.push(Action::Solver(Command::Step));
        }
        // Back replays shots; a gathering solver's steps (rows, then sweeps) do not replay
        // from a reset that keeps its matrix.
        let back = ui.add_enabled(
            s.stats.steps > 0 && s.stats.solver == "shooting",
            egui::Button::new("Back"),
        );
        if back
            .on_hover_text("one shot back (replayed from dark with the stored rows)")
            .clicked()
        {
            actions.push(Action::Teach(TeachCommand::Back));
        }
        if ui.button("Reset").on_hover_text("back to dark").clicked() {
            actions.push(Action::Solver(Command::Reset));
        }
    });
}

/// 1: the shooter's unshot radiosity and power (and what overshooting adds).
fn shooter_numbers(ui: &mut egui::Ui, d: &StepDetail) {
    ui.label("1. Find the patch with the most unshot power ΔB_i A_i:");
    mono(ui, format!("ΔB_i = {}", rgb(d.unshot)));
    mono(
        ui,
        format!(
            "A_i = {:.4}   ΔB_i A_i = {:.4}",
            d.shooter_area,
            (d.unshot.x + d.unshot.y + d.unshot.z) * d.shooter_area
        ),
    );
    if d.overshoot {
        mono(
            ui,
            format!("shot = ΔB_i + ρ_i·ambient = {} (overshooting)", rgb(d.shot)),
        );
    }
}

/// 3, for receiver `j` (`clicked`, or the one with the largest gain): the formula with its
/// numbers, and what the solver added.
fn receiver_numbers(ui: &mut egui::Ui, d: &StepDetail, j: usize, clicked: bool) {
    let which = if clicked {
        "clicked"
    } else {
        "largest gain; click a surface for another"
    };
    mono(ui, format!("j = {j} ({which})"));
    mono(
        ui,
        format!(
            "ρ_j = {}  F_ij = {:.3e}  A_i/A_j = {:.3}",
            rgb(d.element_rho[j]),
            d.f_ij(j),
            d.shooter_area / d.element_area[j]
        ),
    );
    let formula = if d.overshoot {
        "ρ_j (ΔB_i + ρ_i·ambient) F_ij A_i/A_j"
    } else {
        "ρ_j ΔB_i F_ij A_i/A_j"
    };
    mono(ui, format!("{formula} = {}", rgb(d.formula(j))));
    mono(
        ui,
        format!("ΔB_j added by the solver = {}", rgb(d.received[j])),
    );
}

/// 4: the ambient term and the unshot fraction before and after the shot.
fn ambient_numbers(ui: &mut egui::Ui, d: &StepDetail) {
    ui.label("4. The ambient term shrinks:");
    mono(
        ui,
        format!(
            "ambient {} → {}",
            rgb(d.ambient_before),
            rgb(d.ambient_after)
        ),
    );
    mono(
        ui,
        format!(
            "unshot {:.3} % → {:.3} %",
            100.0 * d.residual_before,
            100.0 * d.residual_after
        ),
    );
}

/// The five receivers that gained most.
fn largest_gains(ui: &mut egui::Ui, d: &StepDetail) {
    ui.label("Largest gains this shot:");
    egui::Grid::new("teach-receivers")
        .num_columns(3)
        .striped(true)
        .show(ui, |ui| {
            ui.label("element j");
            ui.label("F_ij");
            ui.label("ΔB_j");
            ui.end_row();
            for j in d.top_receivers(5) {
                ui.monospace(j.to_string());
                ui.monospace(format!("{:.3e}", d.f_ij(j)));
                ui.monospace(rgb(d.received[j]));
                ui.end_row();
            }
        });
}
