//! The solver combo of the side panel (shooting, jacobi, gauss-seidel, sor, cg) and the ω
//! field of SOR.

use eframe::egui;

use nusselt_core::solver::SolverKind;

use super::{Action, PanelState};

/// The solver combo, and the ω field while SOR is chosen. A switch is a command; the solver
/// thread refuses one it cannot make (the error shows in the messages).
pub(super) fn solver_choice(
    ui: &mut egui::Ui,
    state: &mut PanelState,
    current: SolverKind,
    actions: &mut Vec<Action>,
) {
    let mut name = current.name();
    egui::ComboBox::from_label("solver")
        .selected_text(name)
        .show_ui(ui, |ui| {
            for n in SolverKind::names() {
                ui.selectable_value(&mut name, n, n);
            }
        });
    let mut wanted = (name != current.name()).then_some(name);
    if name == "sor" {
        ui.horizontal(|ui| {
            ui.label("ω");
            let t = ui.add(
                egui::TextEdit::singleline(&mut state.omega_text)
                    .hint_text("estimated")
                    .desired_width(70.0),
            );
            if t.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter)) {
                wanted = Some("sor");
            }
        })
        .response
        .on_hover_text("SOR relaxation factor in (0, 2); empty: estimated from the first sweeps");
    }
    if let Some(name) = wanted {
        let omega = if name == "sor" {
            parse_omega(&state.omega_text)
        } else {
            Ok(None)
        };
        match omega {
            Ok(w) => {
                state.omega_error = None;
                if let Some(kind) = SolverKind::parse(name, w) {
                    actions.push(Action::SetSolver(kind));
                }
            }
            Err(e) => state.omega_error = Some(e),
        }
    }
    if let Some(e) = &state.omega_error {
        ui.colored_label(egui::Color32::LIGHT_RED, e);
    }
}

/// The ω field: empty is `None` (estimated); the range is the solver's to check.
fn parse_omega(text: &str) -> Result<Option<f64>, String> {
    let t = text.trim();
    if t.is_empty() {
        return Ok(None);
    }
    match t.parse::<f64>() {
        Ok(w) if w.is_finite() => Ok(Some(w)),
        _ => Err(format!("ω: '{t}' is not a number")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_omega_field_is_empty_or_a_number() {
        assert_eq!(parse_omega(""), Ok(None));
        assert_eq!(parse_omega("  "), Ok(None));
        assert_eq!(parse_omega(" 1.5 "), Ok(Some(1.5)));
        // The range is the solver's to refuse (its message names the range).
        assert_eq!(parse_omega("2.5"), Ok(Some(2.5)));
        assert!(parse_omega("fast").is_err());
        assert!(parse_omega("nan").is_err());
        assert!(parse_omega("inf").is_err());
    }
}
