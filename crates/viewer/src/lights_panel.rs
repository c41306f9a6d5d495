//! The Lights section of the side panel: every light of the scene (emitting materials too),
//! add a sky, a sun or a point light, change its power, direction or position, switch it
//! off and on, delete it. Each change is sent whole as the new list of lights that are on;
//! the solver continues from its current state.

use eframe::egui;
use nusselt_core::scene::{Light, Rgb};

use crate::panels::Action;
use crate::snapshot::Snapshot;

/// Strength of a colour: its brightest channel, edited on a logarithmic slider with the
/// channels' ratios kept. Returns whether it changed.
fn strength(ui: &mut egui::Ui, label: &str, c: &mut Rgb, max: f64) -> bool {
    let mut s = c.max_element();
    let changed = ui
        .add(
            egui::Slider::new(&mut s, 0.0..=max)
                .logarithmic(true)
                .text(label),
        )
        .changed();
    if changed {
        let old = c.max_element();
        *c = if old > 0.0 {
            *c * (s / old)
        } else {
            Rgb::splat(s)
        };
    }
    changed
}

/// Azimuth (from +z towards +x) and elevation sliders, in degrees, for a sun's direction.
fn sun_direction(ui: &mut egui::Ui, d: &mut glam::DVec3) -> bool {
    let mut el = d.y.clamp(-1.0, 1.0).asin().to_degrees();
    let mut az = d.x.atan2(d.z).to_degrees();
    let a = ui
        .add(egui::Slider::new(&mut az, -180.0..=180.0).text("azimuth °"))
        .changed();
    let e = ui
        .add(egui::Slider::new(&mut el, -10.0..=90.0).text("elevation °"))
        .changed();
    if a || e {
        let (el, az) = (el.to_radians(), az.to_radians());
        *d = glam::DVec3::new(el.cos() * az.sin(), el.sin(), el.cos() * az.cos());
    }
    a || e
}

fn point_position(ui: &mut egui::Ui, p: &mut glam::DVec3, step: f64) -> bool {
    ui.horizontal(|ui| {
        let mut changed = false;
        for (name, v) in [("x", &mut p.x), ("y", &mut p.y), ("z", &mut p.z)] {
            changed |= ui
                .add(egui::DragValue::new(v).speed(step).prefix(name))
                .changed();
        }
        changed
    })
    .inner
}

fn kind(light: &Light) -> &'static str {
    match light {
        Light::Sky { .. } => "sky",
        Light::Sun { .. } => "sun",
        Light::Point { cone: Some(_), .. } => "spot",
        Light::Point { .. } => "point",
    }
}

/// What the user did to one light in its row.
#[derive(Default)]
struct RowEdit {
    changed: bool,
    delete: bool,
    switch_off: bool,
}

/// One light's controls.
fn light_row(ui: &mut egui::Ui, k: usize, light: &mut Light, step: f64) -> RowEdit {
    let mut edit = RowEdit::default();
    ui.horizontal(|ui| {
        let mut on = true;
        if ui
            .checkbox(&mut on, format!("{}. {}", k + 1, kind(light)))
            .changed()
        {
            edit.switch_off = true;
        }
        edit.delete = ui.small_button("delete").clicked();
    });
    let mut changed = false;
    match light {
        Light::Sky { radiance } => changed |= strength(ui, "radiance", radiance, 100.0),
        Light::Sun {
            direction,
            irradiance,
            ..
        } => {
            changed |= sun_direction(ui, direction);
            changed |= strength(ui, "irradiance", irradiance, 1000.0);
        }
        Light::Point {
            position,
            intensity,
            ..
        } => {
            changed |= point_position(ui, position, step);
            changed |= strength(ui, "intensity", intensity, 1e9);
        }
    }
    edit.changed = changed;
    edit
}

/// The lights switched off, each with a box to switch it on again; returns the one switched
/// on, if any.
fn off_rows(ui: &mut egui::Ui, off: &[Light]) -> Option<usize> {
    let mut back = None;
    for (k, l) in off.iter().enumerate() {
        let mut on = false;
        if ui.checkbox(&mut on, format!("{} (off)", kind(l))).changed() {
            back = Some(k);
        }
    }
    back
}

/// The section; pushes [`Action::SetLights`] with the whole new list on any change. `off`
/// holds the lights switched off (for the scene `off.0`).
pub fn lights_section(
    ui: &mut egui::Ui,
    off: &mut (u64, Vec<Light>),
    snap: &Snapshot,
    actions: &mut Vec<Action>,
) {
    if off.0 != snap.scene_rev {
        *off = (snap.scene_rev, Vec::new());
    }
    egui::CollapsingHeader::new("Lights")
        .default_open(true)
        .show(ui, |ui| {
            let g = &snap.geometry;
            let size = (g.bounds_max - g.bounds_min).length().max(1e-9);
            let centre = (g.bounds_max + g.bounds_min) * 0.5;
            let mut lights = (*snap.lights).clone();
            let mut changed = false;
            let mut remove = None;
            for (k, l) in lights.iter_mut().enumerate() {
                let edit = light_row(ui, k, l, size * 0.005);
                changed |= edit.changed;
                if edit.delete || edit.switch_off {
                    remove = Some((k, edit.switch_off));
                }
            }
            if let Some((k, keep)) = remove {
                let l = lights.remove(k);
                if keep {
                    off.1.push(l);
                }
                changed = true;
            }
            if let Some(k) = off_rows(ui, &off.1) {
                lights.push(off.1.remove(k));
                changed = true;
            }
            for m in snap.materials.iter().filter(|m| m.is_emitter()) {
                let e = m.emission;
                ui.label(format!(
                    "emitting material '{}': Ke {:.3} {:.3} {:.3} (edit it under Selection)",
                    m.name, e.x, e.y, e.z
                ));
            }
            ui.horizontal(|ui| {
                if ui.button("+ sky").clicked() {
                    lights.push(Light::Sky {
                        radiance: Rgb::splat(nusselt_core::scene::DEFAULT_SKY),
                    });
                    changed = true;
                }
                if ui.button("+ sun").clicked() {
                    lights.push(Light::Sun {
                        direction: nusselt_core::scene::default_sun_direction(),
                        irradiance: Rgb::splat(nusselt_core::scene::DEFAULT_SUN),
                        angular_radius: 0.0,
                    });
                    changed = true;
                }
                if ui.button("+ point").clicked() {
                    // Irradiance about π at half the scene's diagonal.
                    let r = size * 0.5;
                    lights.push(Light::Point {
                        position: centre,
                        intensity: Rgb::splat(std::f64::consts::PI * r * r),
                        cone: None,
                    });
                    changed = true;
                }
            });
            if changed {
                actions.push(Action::SetLights(lights));
            }
        });
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use egui_kittest::Harness;
    use egui_kittest::kittest::Queryable;

    use super::*;
    use crate::solver_thread::Command;
    use crate::teach::panel_tests::snapshot_after;

    struct Panel {
        snapshot: Arc<Snapshot>,
        off: (u64, Vec<Light>),
        actions: Vec<Action>,
    }

    fn harness(snapshot: Arc<Snapshot>) -> Harness<'static, Panel> {
        let mut h = Harness::builder()
            .with_size(egui::vec2(420.0, 700.0))
            .build_ui_state(
                |ui, p: &mut Panel| {
                    lights_section(ui, &mut p.off, &p.snapshot.clone(), &mut p.actions)
                },
                Panel {
                    off: (snapshot.scene_rev, Vec::new()),
                    snapshot,
                    actions: Vec::new(),
                },
            );
        h.run();
        h
    }

    fn sent(h: &Harness<'_, Panel>) -> Vec<Light> {
        match h.state().actions.last() {
            Some(Action::SetLights(l)) => l.clone(),
            other => panic!("no SetLights: {other:?}"),
        }
    }

    /// The panel lists the solver's lights and the emitting material, adds a sun and
    /// deletes a light, each time sending the whole new list.
    #[test]
    fn lights_are_listed_added_and_deleted() {
        let sky = Light::Sky {
            radiance: Rgb::splat(1.0),
        };
        let snap = snapshot_after(vec![Command::SetLights(vec![sky])], |s| s.lights.len() == 1);
        let mut h = harness(snap);
        h.get_by_label("1. sky");
        h.get_by_label_contains("emitting material 'light'");
        h.get_by_label("+ sun").click();
        h.run();
        let lights = sent(&h);
        assert_eq!(lights.len(), 2);
        assert_eq!(lights[0], sky);
        assert!(matches!(lights[1], Light::Sun { .. }));
        h.state_mut().actions.clear();
        h.get_by_label("delete").click();
        h.run();
        assert!(sent(&h).is_empty());
    }

    /// Switched off, a light leaves the solver's list and stays in the panel; switched on
    /// again, it comes back unchanged.
    #[test]
    fn a_light_switched_off_and_on_comes_back() {
        let sun = Light::Sun {
            direction: glam::DVec3::Y,
            irradiance: Rgb::splat(2.0),
            angular_radius: 0.0,
        };
        let snap = snapshot_after(vec![Command::SetLights(vec![sun])], |s| s.lights.len() == 1);
        let mut h = harness(snap.clone());
        // As the app does: the next snapshot holds the list that was sent.
        let solved = |h: &mut Harness<'_, Panel>| {
            let lights = sent(h);
            let next = Snapshot {
                lights: Arc::new(lights.clone()),
                ..(*h.state().snapshot).clone()
            };
            h.state_mut().snapshot = Arc::new(next);
            h.state_mut().actions.clear();
            h.run();
            lights
        };
        h.get_by_label("1. sun").click();
        h.step();
        assert!(solved(&mut h).is_empty());
        assert_eq!(h.state().off.1, vec![sun]);
        h.get_by_label("sun (off)").click();
        h.step();
        assert_eq!(solved(&mut h), vec![sun]);
        assert!(h.state().off.1.is_empty());
    }
}
