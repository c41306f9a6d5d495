//! Shooting vs gathering: the controls and numbers in the Teach panel, and in place of the
//! viewport the two images (one colour per patch, the step's shooter and gatherer tinted)
//! above their error curves.

use std::sync::Arc;

use eframe::egui;
use egui_plot::{Legend, Line, Plot, PlotPoints, VLine};

use super::super::export::srgb8;
use super::super::panels::Action;
use super::super::snapshot::Snapshot;
use super::compare::{CompareCommand, CompareDetail};
use super::{TeachCommand, TeachState};

/// The textures of the detail last drawn, and the display settings they were drawn with.
#[derive(Default)]
pub(crate) struct Textures {
    detail: Option<Arc<CompareDetail>>,
    key: Option<(u32, bool)>,
    shooting: Option<egui::TextureHandle>,
    gathering: Option<egui::TextureHandle>,
}

impl std::fmt::Debug for Textures {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Textures")
    }
}

fn send(actions: &mut Vec<Action>, c: CompareCommand) {
    actions.push(Action::Teach(TeachCommand::Compare(c)));
}

fn percent(e: f64) -> String {
    if e.is_finite() {
        format!("{:.2} %", 100.0 * e)
    } else {
        "–".into()
    }
}

pub(super) fn show(
    ui: &mut egui::Ui,
    state: &mut TeachState,
    s: &Snapshot,
    actions: &mut Vec<Action>,
) {
    if !state.compare_on {
        state.compare_on = true;
        send(
            actions,
            CompareCommand::On {
                steps: state.compare_steps,
            },
        );
    }
    ui.label(
        "The same patch system B_p = E_p + ρ_p Σ_q F_pq B_q solved two ways, one row of F \
         (n form factors) per step each, so equal steps are equal work:",
    );
    ui.label("• shooting: the patch with the most unshot power ΔB_i A_i sends it to all, B_q += ρ_q ΔB_i F_qi;");
    ui.label(
        "• Gauss-Seidel: the next patch in order gathers from all, B_p = E_p + ρ_p Σ_q F_pq B_q.",
    );
    let Some(d) = s.teach_compare.clone() else {
        ui.label("Starting… (a mesh too large for the view is refused in the messages)");
        return;
    };
    if d.rows_done < d.patches {
        ui.label(format!(
            "Computing the form factors first (the error needs the converged answer): {}/{} rows",
            d.rows_done, d.patches
        ));
        ui.add(egui::ProgressBar::new(
            d.rows_done as f32 / d.patches.max(1) as f32,
        ));
        return;
    }
    ui.separator();
    controls(ui, state, &d, actions);
    numbers(ui, &d);
    ui.label(
        "Error: Σ A_p |B_p − B*_p| / Σ A_p B*_p against the converged answer of the same \
         matrix (the iteration's error, not the mesh's). Notice: after a few steps shooting \
         has sent the lights' power everywhere, while gathering has updated only the first \
         patches. After a sweep Gauss-Seidel shows the whole room too, but shooting stays \
         ahead: it always sends the largest unshot power next.",
    );
}

/// Step, Play/Pause, Reset, the rate, and the ambient toggle.
fn controls(
    ui: &mut egui::Ui,
    state: &mut TeachState,
    d: &CompareDetail,
    actions: &mut Vec<Action>,
) {
    ui.horizontal(|ui| {
        if ui
            .button("Step")
            .on_hover_text("one step of each")
            .clicked()
        {
            send(actions, CompareCommand::Step);
        }
        let play = if d.playing { "Pause" } else { "Play" };
        if ui.button(play).clicked() {
            send(actions, CompareCommand::Play(!d.playing));
        }
        if ui.button("Reset").on_hover_text("back to B = E").clicked() {
            send(actions, CompareCommand::Reset);
        }
    });
    let mut rate = d.rate;
    if ui
        .add(
            egui::Slider::new(&mut rate, 1.0..=2000.0)
                .logarithmic(true)
                .text("steps per second"),
        )
        .changed()
    {
        send(actions, CompareCommand::Rate(rate));
    }
    ui.checkbox(
        &mut state.compare_ambient,
        "show shooting with the ambient term",
    );
}

/// The runs' sizes and errors, the unshot power and the ambient term.
fn numbers(ui: &mut egui::Ui, d: &CompareDetail) {
    let last = d.curve.last().copied();
    egui::Grid::new("teach-compare")
        .num_columns(2)
        .show(ui, |ui| {
            let mut row = |k: &str, v: String| {
                ui.label(k);
                ui.monospace(v);
                ui.end_row();
            };
            row("patches n", d.patches.to_string());
            row("steps (rows read) each", d.steps.to_string());
            row("Gauss-Seidel sweeps", format!("{:.2}", d.sweeps()));
            row(
                "error, shooting + ambient",
                percent(last.map_or(f64::NAN, |p| p.shooting_ambient)),
            );
            row(
                "error, shooting",
                percent(last.map_or(f64::NAN, |p| p.shooting)),
            );
            row(
                "error, Gauss-Seidel",
                percent(last.map_or(f64::NAN, |p| p.gathering)),
            );
            row("unshot power", percent(d.unshot_fraction));
            row(
                "ambient term",
                format!(
                    "({:.3}, {:.3}, {:.3})",
                    d.ambient.x, d.ambient.y, d.ambient.z
                ),
            );
        });
}

/// Linear radiance to an sRGB colour after `exposure`.
fn colour(c: [f32; 3], exposure: f32) -> [u8; 3] {
    c.map(|x| srgb8(x, exposure))
}

fn tint(c: [u8; 3], with: [u8; 3]) -> [u8; 3] {
    [0, 1, 2].map(|k| ((c[k] as u16 + with[k] as u16) / 2) as u8)
}

/// An image of per-patch values, the `mark` patch tinted.
fn image(
    d: &CompareDetail,
    s: &Snapshot,
    values: &[[f32; 3]],
    mark: Option<(u32, [u8; 3])>,
    exposure: f32,
) -> egui::ColorImage {
    let patch_of = &s.geometry.element_patch;
    let px = d.image.paint(
        |e| {
            let p = patch_of.get(e as usize).copied().unwrap_or(u32::MAX);
            let c = values
                .get(p as usize)
                .map_or([0, 0, 0], |v| colour(*v, exposure));
            match mark {
                Some((m, with)) if m == p => tint(c, with),
                _ => c,
            }
        },
        None,
    );
    let rgba: Vec<egui::Color32> = px
        .iter()
        .map(|c| egui::Color32::from_rgb(c[0], c[1], c[2]))
        .collect();
    egui::ColorImage::new([d.image.width, d.image.height], rgba)
}

pub(super) fn central(ui: &mut egui::Ui, state: &mut TeachState, s: &Snapshot, exposure: f32) {
    let Some(d) = s.teach_compare.clone() else {
        ui.label("Starting the comparison…");
        return;
    };
    if d.rows_done < d.patches {
        ui.label(format!(
            "Computing the form factors: {}/{} rows",
            d.rows_done, d.patches
        ));
        return;
    }
    update_textures(ui, state, s, &d, exposure);
    side_by_side(ui, state, &d);
    error_curves(ui, &d);
}

/// The two images as textures, made again when the detail or the display settings
/// changed.
fn update_textures(
    ui: &egui::Ui,
    state: &mut TeachState,
    s: &Snapshot,
    d: &Arc<CompareDetail>,
    exposure: f32,
) {
    let key = (exposure.to_bits(), state.compare_ambient);
    let t = &mut state.compare_textures;
    if t.detail.as_ref().is_none_or(|old| !Arc::ptr_eq(old, d)) || t.key != Some(key) {
        let shooting = if state.compare_ambient {
            &d.shooting_ambient
        } else {
            &d.shooting
        };
        let yellow = [255, 230, 0];
        let cyan = [0, 220, 255];
        let left = image(
            d,
            s,
            shooting,
            d.last_shooter.map(|p| (p, yellow)),
            exposure,
        );
        let right = image(
            d,
            s,
            &d.gathering,
            d.last_gatherer.map(|p| (p, cyan)),
            exposure,
        );
        let opts = egui::TextureOptions::NEAREST;
        t.shooting = Some(ui.ctx().load_texture("compare-shooting", left, opts));
        t.gathering = Some(ui.ctx().load_texture("compare-gathering", right, opts));
        t.detail = Some(d.clone());
        t.key = Some(key);
    }
}

/// The two runs' images side by side, each with its step, error and last patch.
fn side_by_side(ui: &mut egui::Ui, state: &TeachState, d: &CompareDetail) {
    let t = &state.compare_textures;
    let last = d.curve.last().copied();
    let side = ((ui.available_width() - 24.0) / 2.0)
        .min(ui.available_height() - 260.0)
        .max(120.0);
    ui.horizontal(|ui| {
        for (title, tex, err, who) in [
            (
                if state.compare_ambient {
                    "Progressive shooting + ambient"
                } else {
                    "Progressive shooting"
                },
                &t.shooting,
                last.map(|p| {
                    if state.compare_ambient {
                        p.shooting_ambient
                    } else {
                        p.shooting
                    }
                }),
                d.last_shooter.map(|p| format!("shooter i = {p} (yellow)")),
            ),
            (
                "Gauss-Seidel gathering",
                &t.gathering,
                last.map(|p| p.gathering),
                d.last_gatherer.map(|p| format!("gatherer p = {p} (cyan)")),
            ),
        ] {
            ui.vertical(|ui| {
                ui.heading(title);
                if let Some(tex) = tex {
                    ui.image((tex.id(), egui::vec2(side, side)));
                }
                ui.label(format!(
                    "step {}   error {}   {}",
                    d.steps,
                    percent(err.unwrap_or(f64::NAN)),
                    who.unwrap_or_default()
                ));
            });
        }
    });
}

/// Both runs' error against steps, on a log scale.
fn error_curves(ui: &mut egui::Ui, d: &CompareDetail) {
    let pts = |f: fn(&super::compare::ComparePoint) -> f64| -> PlotPoints<'static> {
        d.curve
            .iter()
            .filter(|p| f(p) > 0.0)
            .map(|p| [p.steps as f64, f(p).log10()])
            .collect::<Vec<_>>()
            .into()
    };
    let pow10 = |m: egui_plot::GridMark, _: &std::ops::RangeInclusive<f64>| {
        format!("1e{}", m.value.round())
    };
    Plot::new("teach-compare-curves")
        .height(ui.available_height().clamp(120.0, 240.0))
        .legend(Legend::default())
        .x_axis_label("steps (rows of F read)")
        .y_axis_label("error (log)")
        .y_axis_formatter(pow10)
        // Log scale: a grid line at each power of ten only.
        .y_grid_spacer(|input: egui_plot::GridInput| {
            let (lo, hi) = input.bounds;
            (lo.ceil() as i64..=hi.floor() as i64)
                .map(|v| egui_plot::GridMark {
                    value: v as f64,
                    step_size: 1.0,
                })
                .collect()
        })
        .allow_scroll(false)
        .show(ui, |p| {
            p.line(Line::new("shooting + ambient", pts(|p| p.shooting_ambient)));
            p.line(Line::new("shooting", pts(|p| p.shooting)));
            p.line(Line::new("Gauss-Seidel", pts(|p| p.gathering)));
            p.vline(VLine::new("one sweep (n steps)", d.patches as f64));
        });
}
