//! The stats grid and the convergence plot of the side panel: what the solver thread
//! reported in the snapshot, whichever solver it runs.

use eframe::egui;
use egui_plot::{Legend, Line, Plot, PlotPoints};

use super::super::snapshot::Snapshot;

/// "mesh 20 + stored 4 MB" and "12.3 GB": what draws on `--max-memory`, and the budget, on
/// two short rows (one long row widened the side panel and narrowed the viewport).
fn memory_lines(st: &super::super::snapshot::Stats) -> (String, String) {
    let mb = |b: usize| b as f64 / 1e6;
    let budget = if st.memory_budget >= 1_000_000_000 {
        format!("{:.1} GB", st.memory_budget as f64 / 1e9)
    } else {
        format!("{:.0} MB", mb(st.memory_budget))
    };
    (
        format!(
            "mesh {:.0} + stored {:.0} MB",
            mb(st.resident_bytes),
            mb(st.matrix_bytes)
        ),
        budget,
    )
}

/// `reason`: why `--solver auto` chose the first solver, shown while a solver it names
/// runs (the first one, or the one it hands over to).
pub(super) fn stats_section(ui: &mut egui::Ui, s: &Snapshot, failed: bool, reason: Option<&str>) {
    let st = &s.stats;
    egui::Grid::new("stats").num_columns(2).show(ui, |ui| {
        let row = |ui: &mut egui::Ui, k: &str, v: String| {
            ui.label(k);
            ui.monospace(v);
            ui.end_row();
        };
        row(
            ui,
            "elements",
            format!("{} ({} patches)", st.elements, st.patches),
        );
        row(ui, "solver", st.solver.to_string());
        if let Some(why) = reason.filter(|r| r.contains(st.solver)) {
            // The reason after "shooting: ", wrapped: it is a sentence.
            ui.label("auto");
            ui.add(egui::Label::new(why.split_once(": ").map_or(why, |(_, w)| w)).wrap());
            ui.end_row();
        }
        // Shooting's unit of work is a shot; a gathering solver's a row, then a sweep.
        let (steps, residual) = if st.solver == "shooting" {
            ("shots", "unshot")
        } else {
            ("steps", "residual")
        };
        row(ui, steps, st.steps.to_string());
        row(
            ui,
            &format!("{steps}/s"),
            format!("{:.1}", st.steps_per_second),
        );
        row(ui, residual, format!("{:.4} %", 100.0 * st.residual));
        // One clause a row: a long report would widen the panel over the viewport.
        let clauses = st
            .report
            .split([',', ';'])
            .map(str::trim)
            .filter(|c| !c.is_empty());
        for (k, clause) in clauses.enumerate() {
            row(ui, if k == 0 { "report" } else { "" }, clause.to_string());
        }
        if st.matrix_bytes > 0 {
            row(
                ui,
                "stored F",
                format!("{:.1} MB", st.matrix_bytes as f64 / 1e6),
            );
        }
        if st.memory_budget > 0 {
            let (used, budget) = memory_lines(st);
            row(ui, "memory", used);
            row(ui, "budget", budget);
        }
        if let Some(t) = &s.textures {
            row(
                ui,
                "textures",
                format!(
                    "{} × {}², {:.1} MB on the GPU",
                    t.layers,
                    t.size,
                    t.gpu_bytes() as f64 / 1e6
                ),
            );
        }
        row(ui, "elapsed", format!("{:.2} s", st.elapsed_seconds));
        let a = s.ambient;
        // The classic global term; the display adds the solver's own (regional) one.
        row(
            ui,
            "ambient (global)",
            format!("{:.4} {:.4} {:.4}", a[0], a[1], a[2]),
        );
        let status = if failed {
            "solver failed (see messages); last image kept"
        } else if st.converged {
            "converged"
        } else if st.limit_reached {
            "stopped at step limit"
        } else if st.playing {
            "running"
        } else {
            "paused"
        };
        row(ui, "status", status.into());
    });
}

pub(super) fn plot_section(ui: &mut egui::Ui, s: &Snapshot) {
    // Log scales: plot log10 of both axes and label the ticks as powers of ten.
    let pts = |f: fn(&super::super::snapshot::HistoryPoint) -> f64| -> PlotPoints<'static> {
        s.history
            .iter()
            .filter(|p| p.seconds > 0.0 && f(p) > 0.0)
            .map(|p| [p.seconds.log10(), f(p).log10()])
            .collect::<Vec<_>>()
            .into()
    };
    let pow10 = |m: egui_plot::GridMark, _: &std::ops::RangeInclusive<f64>| {
        format!("1e{}", m.value.round())
    };
    Plot::new("convergence")
        .height(150.0)
        .legend(Legend::default())
        .x_axis_label("time (s, log)")
        .x_axis_formatter(pow10)
        .y_axis_formatter(pow10)
        .allow_scroll(false)
        .show(ui, |p| {
            let residual = if s.stats.solver == "shooting" {
                "unshot fraction"
            } else {
                "residual"
            };
            p.line(Line::new(residual, pts(|p| p.residual)));
            if s.history.iter().any(|p| p.ambient > 0.0) {
                p.line(Line::new("ambient (mean)", pts(|p| p.ambient)));
            }
        });
}
