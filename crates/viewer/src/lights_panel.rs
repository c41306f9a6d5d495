//! The Lights section of the side panel: every light of the scene (emitting materials too),
//! add a sky, a sun, a point or an area light, change its power, direction or position,
//! switch it off and on, delete it, or place a point or area light at the surface point
//! clicked next in the viewport. Each change is sent whole as the new list of lights that
//! are on: skies, suns and points incrementally (the solver continues from its current
//! state); area lights, which are faces, as one re-mesh on the solver thread.

use eframe::egui;
use glam::DVec3;
use nusselt_core::scene::{AreaLight, Light, Rgb};

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

/// Distance from the clicked surface of a placed point light, as a fraction of the scene's
/// diagonal: far enough that the surface below is not one bright spot (inverse square),
/// near enough that the light stays in the room it was clicked in.
pub const POINT_OFFSET: f64 = 1.0 / 20.0;
/// Distance from the clicked surface of a placed area light, as a fraction of the scene's
/// diagonal: just off it, so the emitter is not coplanar with (and meshed into) it.
pub const AREA_OFFSET: f64 = 1.0 / 200.0;

/// What the next click in the viewport places.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Placing {
    /// The point light at this index of the snapshot's lights.
    Point(usize),
    /// The area light of the open form.
    Area,
}

/// The area-light form: a square of side `size` centred at `centre`, facing `normal`.
#[derive(Clone, Debug, PartialEq)]
pub struct AreaForm {
    /// The area light edited (index in the snapshot's area lights), or `None` to add one.
    pub editing: Option<usize>,
    pub centre: DVec3,
    pub normal: DVec3,
    pub size: f64,
    pub radiance: [f64; 3],
    pub error: Option<String>,
}

impl AreaForm {
    /// A new light for `g`: under the top of its bounds, facing down, a quarter of the
    /// smaller horizontal extent on a side, bright enough that the floor straight below
    /// gets an irradiance of about π (as the default ceiling light).
    pub fn default_for(g: &crate::snapshot::Geometry) -> AreaForm {
        let ext = g.bounds_max - g.bounds_min;
        let diagonal = ext.length().max(1e-9);
        let size = match 0.25 * ext.x.min(ext.z) {
            s if s > 1e-6 * diagonal => s,
            _ => 0.05 * diagonal,
        };
        let centre = DVec3::new(
            0.5 * (g.bounds_min.x + g.bounds_max.x),
            g.bounds_max.y - 0.02 * ext.y,
            0.5 * (g.bounds_min.z + g.bounds_max.z),
        );
        let drop = (0.98 * ext.y).max(size);
        AreaForm {
            editing: None,
            centre,
            normal: DVec3::NEG_Y,
            size,
            radiance: [std::f64::consts::PI * drop * drop / (size * size); 3],
            error: None,
        }
    }

    /// The form for editing area light `k` (a polygon becomes the square of its area).
    fn editing(k: usize, a: &AreaLight) -> AreaForm {
        AreaForm {
            editing: Some(k),
            centre: a.centre(),
            normal: a.normal().unwrap_or(DVec3::NEG_Y),
            size: a.side(),
            radiance: a.radiance.to_array(),
            error: None,
        }
    }

    /// The snapshot's area lights with this one added or replacing the one edited.
    fn submit(&self, current: &[AreaLight]) -> Result<Vec<AreaLight>, String> {
        let radiance = Rgb::from_array(self.radiance);
        if !radiance.is_finite() || radiance.min_element() < 0.0 {
            return Err("the radiance must be finite and non-negative".into());
        }
        let light = AreaLight::square(self.centre, self.normal, self.size, radiance)
            .ok_or("needs a non-zero normal and a positive size")?;
        let mut lights = current.to_vec();
        match self.editing {
            Some(k) if k < lights.len() => lights[k] = light,
            _ => lights.push(light),
        }
        Ok(lights)
    }
}

/// The panel's own state, kept by the app between frames.
#[derive(Debug, Default)]
pub struct LightsPanel {
    /// The scene the rest belongs to (`Snapshot::scene_rev`).
    scene_rev: u64,
    /// Lights switched off, kept to switch on again.
    pub off: Vec<Light>,
    /// Area lights switched off (radiance 0, the mesh kept): their radiance, by index in
    /// the snapshot's area lights, to switch on again.
    pub area_off: std::collections::BTreeMap<usize, Rgb>,
    pub area_form: Option<AreaForm>,
    pub placing: Option<Placing>,
}

impl LightsPanel {
    /// Whether the next click in the viewport places a light.
    pub fn is_placing(&self) -> bool {
        self.placing.is_some()
    }
}

/// Where a light placed at `point` on a surface of unit `normal` goes: `distance` off it.
pub fn off_surface(point: DVec3, normal: DVec3, distance: f64) -> DVec3 {
    point + normal.normalize_or_zero() * distance
}

/// Places what `state` is placing at the clicked `point` (unit `normal` on the side seen)
/// and pushes the command: [`Action::SetLights`] for a point light,
/// [`Action::SetAreaLights`] for the form's area light (which then faces along `normal`).
pub fn place_at(
    state: &mut LightsPanel,
    snap: &Snapshot,
    point: DVec3,
    normal: DVec3,
    actions: &mut Vec<Action>,
) {
    let g = &snap.geometry;
    let diagonal = (g.bounds_max - g.bounds_min).length().max(1e-9);
    match state.placing.take() {
        Some(Placing::Point(k)) => {
            let mut lights = (*snap.lights).clone();
            if let Some(Light::Point { position, .. }) = lights.get_mut(k) {
                *position = off_surface(point, normal, POINT_OFFSET * diagonal);
                actions.push(Action::SetLights(lights));
            }
        }
        Some(Placing::Area) => {
            if let Some(form) = state.area_form.as_mut() {
                form.centre = off_surface(point, normal, AREA_OFFSET * diagonal);
                form.normal = normal;
                match form.submit(&snap.area_lights) {
                    Ok(lights) => {
                        actions.push(Action::SetAreaLights(lights));
                        state.area_form = None;
                    }
                    Err(e) => form.error = Some(e),
                }
            }
        }
        None => {}
    }
}

/// What the user did to one light in its row.
#[derive(Default)]
struct RowEdit {
    changed: bool,
    delete: bool,
    switch_off: bool,
    place: bool,
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
        if matches!(light, Light::Point { .. }) {
            edit.place = ui.small_button("place at click").clicked();
        }
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

/// Three numbers side by side.
fn vector(ui: &mut egui::Ui, label: &str, v: &mut [f64; 3], speed: f64) {
    ui.horizontal(|ui| {
        ui.label(label);
        for (x, name) in v.iter_mut().zip(["x ", "y ", "z "]) {
            ui.add(egui::DragValue::new(x).speed(speed).prefix(name));
        }
    });
}

/// The area lights, each with "edit" and "delete"; a deletion is sent at once.
fn area_rows(
    ui: &mut egui::Ui,
    state: &mut LightsPanel,
    snap: &Snapshot,
    actions: &mut Vec<Action>,
) {
    for (k, a) in snap.area_lights.iter().enumerate() {
        let c = a.centre();
        let r = a.radiance;
        ui.horizontal(|ui| {
            // Off is radiance 0 on the same face: a material edit, so switching a light
            // off and on goes on from the current solution instead of re-meshing.
            let mut on = !state.area_off.contains_key(&k);
            if ui
                .checkbox(&mut on, format!("area light {}", k + 1))
                .changed()
            {
                let mut lights = (*snap.area_lights).clone();
                if on {
                    lights[k].radiance = state.area_off.remove(&k).unwrap_or(r);
                } else {
                    state.area_off.insert(k, r);
                    lights[k].radiance = Rgb::ZERO;
                }
                actions.push(Action::SetAreaLights(lights));
            }
            if ui.small_button("edit").clicked() {
                state.area_form = Some(AreaForm::editing(k, a));
            }
            if ui.small_button("delete").clicked() {
                let mut lights = (*snap.area_lights).clone();
                lights.remove(k);
                actions.push(Action::SetAreaLights(lights));
                state.area_form = None;
                // Indices after `k` move down one.
                state.area_off = std::mem::take(&mut state.area_off)
                    .into_iter()
                    .filter(|(i, _)| *i != k)
                    .map(|(i, r)| (if i > k { i - 1 } else { i }, r))
                    .collect();
            }
        });
        ui.label(format!(
            "  at {:.3} {:.3} {:.3}, side {:.3}, radiance {:.3} {:.3} {:.3}",
            c.x,
            c.y,
            c.z,
            a.side(),
            r.x,
            r.y,
            r.z
        ));
    }
}

/// The open area-light form: its fields, and "add" (or "apply"), "place at click" and
/// "cancel".
fn area_form(
    ui: &mut egui::Ui,
    state: &mut LightsPanel,
    snap: &Snapshot,
    actions: &mut Vec<Action>,
) {
    let Some(form) = state.area_form.as_mut() else {
        return;
    };
    let step = form.size.abs().max(1e-9) * 0.01;
    ui.label(match form.editing {
        Some(k) => format!("area light {} (a square)", k + 1),
        None => "new area light (a square)".to_string(),
    });
    let mut centre = form.centre.to_array();
    vector(ui, "centre", &mut centre, step);
    form.centre = DVec3::from_array(centre);
    let mut normal = form.normal.to_array();
    vector(ui, "normal", &mut normal, 0.01);
    form.normal = DVec3::from_array(normal);
    ui.add(
        egui::DragValue::new(&mut form.size)
            .speed(step)
            .prefix("side "),
    );
    vector(ui, "radiance", &mut form.radiance, 0.1);
    let (mut submit, mut cancel) = (false, false);
    ui.horizontal(|ui| {
        submit = ui
            .button(if form.editing.is_some() {
                "apply"
            } else {
                "add"
            })
            .clicked();
        if ui.button("place at click").clicked() {
            state.placing = Some(Placing::Area);
        }
        cancel = ui.button("cancel").clicked();
    });
    if let Some(e) = &form.error {
        ui.colored_label(egui::Color32::LIGHT_RED, e);
    }
    if submit {
        match form.submit(&snap.area_lights) {
            Ok(lights) => {
                actions.push(Action::SetAreaLights(lights));
                cancel = true;
            }
            Err(e) => form.error = Some(e),
        }
    }
    if cancel {
        state.area_form = None;
        state.placing = state.placing.filter(|p| *p != Placing::Area);
    }
}

/// While a light waits for its click: what to do, and a way out.
fn placing_row(ui: &mut egui::Ui, state: &mut LightsPanel) {
    if state.placing.is_none() {
        return;
    }
    ui.horizontal(|ui| {
        ui.colored_label(
            egui::Color32::YELLOW,
            "click a surface in the viewport to place the light",
        );
        if ui.small_button("stop placing").clicked() {
            state.placing = None;
        }
    });
}

/// The "+" buttons: new lights are pushed onto `lights`; "+ area" opens the form.
fn add_buttons(
    ui: &mut egui::Ui,
    state: &mut LightsPanel,
    snap: &Snapshot,
    lights: &mut Vec<Light>,
) -> bool {
    let g = &snap.geometry;
    let size = (g.bounds_max - g.bounds_min).length().max(1e-9);
    let centre = (g.bounds_max + g.bounds_min) * 0.5;
    let mut changed = false;
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
        if ui.button("+ area").clicked() {
            state.area_form = Some(AreaForm::default_for(g));
        }
    });
    changed
}

/// Skies, suns and points: their rows, the ones switched off, and the "+" buttons. Returns
/// the new list when something changed.
fn light_list(ui: &mut egui::Ui, state: &mut LightsPanel, snap: &Snapshot) -> Option<Vec<Light>> {
    let g = &snap.geometry;
    let step = (g.bounds_max - g.bounds_min).length().max(1e-9) * 0.005;
    let mut lights = (*snap.lights).clone();
    let mut changed = false;
    let mut remove = None;
    for (k, l) in lights.iter_mut().enumerate() {
        let edit = light_row(ui, k, l, step);
        changed |= edit.changed;
        if edit.delete || edit.switch_off {
            remove = Some((k, edit.switch_off));
        }
        if edit.place {
            state.placing = Some(Placing::Point(k));
        }
    }
    if let Some((k, keep)) = remove {
        let l = lights.remove(k);
        if keep {
            state.off.push(l);
        }
        // Indices after `k` moved: a pending placement would move the wrong light.
        state.placing = state.placing.filter(|p| !matches!(p, Placing::Point(_)));
        changed = true;
    }
    if let Some(k) = off_rows(ui, &state.off) {
        lights.push(state.off.remove(k));
        changed = true;
    }
    changed |= add_buttons(ui, state, snap, &mut lights);
    changed.then_some(lights)
}

/// The section; pushes [`Action::SetLights`] with the whole new list of skies, suns and
/// points on any change of them, [`Action::SetAreaLights`] with the whole list of area
/// lights on any change of those.
pub fn lights_section(
    ui: &mut egui::Ui,
    state: &mut LightsPanel,
    snap: &Snapshot,
    actions: &mut Vec<Action>,
) {
    if state.scene_rev != snap.scene_rev {
        *state = LightsPanel {
            scene_rev: snap.scene_rev,
            ..Default::default()
        };
    }
    egui::CollapsingHeader::new("Lights")
        .default_open(true)
        .show(ui, |ui| {
            if let Some(lights) = light_list(ui, state, snap) {
                actions.push(Action::SetLights(lights));
            }
            area_rows(ui, state, snap, actions);
            area_form(ui, state, snap, actions);
            placing_row(ui, state);
            let area = |m: &&nusselt_core::scene::Material| m.name.starts_with("area light");
            for m in snap.materials.iter().filter(|m| m.is_emitter() && !area(m)) {
                let e = m.emission;
                ui.label(format!(
                    "emitting material '{}': Ke {:.3} {:.3} {:.3} (edit it under Selection)",
                    m.name, e.x, e.y, e.z
                ));
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
        lights: LightsPanel,
        actions: Vec<Action>,
    }

    fn harness(snapshot: Arc<Snapshot>) -> Harness<'static, Panel> {
        let mut h = Harness::builder()
            .with_size(egui::vec2(420.0, 700.0))
            .build_ui_state(
                |ui, p: &mut Panel| {
                    lights_section(ui, &mut p.lights, &p.snapshot.clone(), &mut p.actions)
                },
                Panel {
                    lights: LightsPanel::default(),
                    snapshot,
                    actions: Vec::new(),
                },
            );
        h.run();
        h
    }

    fn sent_areas(h: &Harness<'_, Panel>) -> Vec<AreaLight> {
        match h.state().actions.last() {
            Some(Action::SetAreaLights(l)) => l.clone(),
            other => panic!("no SetAreaLights: {other:?}"),
        }
    }

    fn diagonal(s: &Snapshot) -> f64 {
        (s.geometry.bounds_max - s.geometry.bounds_min).length()
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
        assert_eq!(h.state().lights.off, vec![sun]);
        h.get_by_label("sun (off)").click();
        h.step();
        assert_eq!(solved(&mut h), vec![sun]);
        assert!(h.state().lights.off.is_empty());
    }

    /// "+ area" opens the form with a light under the top of the scene, facing down, a
    /// quarter of the narrower horizontal extent on a side; "add" sends it as the new list
    /// of area lights.
    #[test]
    fn an_area_light_is_added_from_the_form() {
        let snap = snapshot_after(Vec::new(), |_| true);
        let mut h = harness(snap.clone());
        h.get_by_label("+ area").click();
        h.run();
        h.get_by_label("add").click();
        h.run();
        let lights = sent_areas(&h);
        assert_eq!(lights.len(), 1);
        let (g, a) = (&snap.geometry, &lights[0]);
        let ext = g.bounds_max - g.bounds_min;
        assert!((a.side() - 0.25 * ext.x.min(ext.z)).abs() < 1e-6 * ext.x);
        assert!((a.normal().unwrap() - DVec3::NEG_Y).length() < 1e-9);
        let c = a.centre();
        assert!(
            c.y < g.bounds_max.y && c.y > g.bounds_max.y - 0.05 * ext.y,
            "{c}"
        );
        assert!(
            a.radiance.min_element() > 1.0,
            "visibly bright: {}",
            a.radiance
        );
        assert!(h.state().lights.area_form.is_none(), "the form closes");
    }

    /// An area light in the list is edited through the form and deleted by its button.
    #[test]
    fn an_area_light_is_edited_and_deleted() {
        let a = AreaLight::square(
            DVec3::new(278.0, 540.0, 278.0),
            DVec3::NEG_Y,
            100.0,
            Rgb::splat(9.0),
        )
        .unwrap();
        let snap = snapshot_after(vec![Command::SetAreaLights(vec![a.clone()])], |s| {
            s.area_lights.len() == 1
        });
        let mut h = harness(snap);
        h.get_by_label("area light 1");
        assert!(
            h.query_by_label_contains("emitting material 'area light")
                .is_none()
        );
        h.get_by_label("edit").click();
        h.run();
        assert_eq!(
            h.state().lights.area_form.as_ref().unwrap().editing,
            Some(0)
        );
        h.state_mut().lights.area_form.as_mut().unwrap().size = 50.0;
        h.get_by_label("apply").click();
        h.run();
        let lights = sent_areas(&h);
        assert_eq!(lights.len(), 1);
        assert!((lights[0].side() - 50.0).abs() < 1e-9);
        assert!((lights[0].centre() - a.centre()).length() < 1e-9);
        assert_eq!(lights[0].radiance, a.radiance);
        h.state_mut().actions.clear();
        h.get_by_label("delete").click();
        h.run();
        assert!(sent_areas(&h).is_empty());
    }

    /// An area light's box switches it off as radiance 0 on the same face (shape kept,
    /// so the solver thread takes it as a material edit) and on again at its radiance.
    #[test]
    fn an_area_light_is_switched_off_and_on_in_place() {
        let a = AreaLight::square(
            DVec3::new(278.0, 540.0, 278.0),
            DVec3::NEG_Y,
            100.0,
            Rgb::new(9.0, 8.0, 7.0),
        )
        .unwrap();
        let snap = snapshot_after(vec![Command::SetAreaLights(vec![a.clone()])], |s| {
            s.area_lights.len() == 1
        });
        let mut h = harness(snap);
        h.get_by_label("area light 1").click();
        h.run();
        let off = sent_areas(&h);
        assert_eq!(off.len(), 1);
        assert_eq!(off[0].corners, a.corners);
        assert_eq!(off[0].radiance, Rgb::ZERO);
        h.state_mut().actions.clear();
        h.get_by_label("area light 1").click();
        h.run();
        let on = sent_areas(&h);
        assert_eq!(on[0].corners, a.corners);
        assert_eq!(on[0].radiance, a.radiance);
        assert!(h.state().lights.area_off.is_empty());
    }

    #[test]
    fn a_placed_light_stands_off_the_surface_along_its_normal() {
        let p = off_surface(DVec3::new(1.0, 2.0, 3.0), DVec3::new(0.0, 0.0, -2.0), 0.5);
        assert_eq!(p, DVec3::new(1.0, 2.0, 2.5));
    }

    /// "place at click" on a point light, then a click on the floor: the command carries
    /// the position 1/20 of the scene's diagonal above the point clicked.
    #[test]
    fn a_point_light_is_placed_at_the_clicked_surface() {
        let point = Light::Point {
            position: DVec3::new(100.0, 100.0, 100.0),
            intensity: Rgb::splat(1e4),
            cone: None,
        };
        let snap = snapshot_after(vec![Command::SetLights(vec![point])], |s| {
            s.lights.len() == 1
        });
        let mut h = harness(snap.clone());
        h.get_by_label("place at click").click();
        h.run();
        assert_eq!(h.state().lights.placing, Some(Placing::Point(0)));
        h.get_by_label_contains("click a surface");
        // The click: a ray straight down onto the floor beside the blocks.
        let (o, d) = (DVec3::new(100.0, 500.0, 500.0), DVec3::NEG_Y);
        let (hit, normal) = snap.geometry.pick_surface(o, d).expect("the floor");
        assert!(
            (hit - DVec3::new(100.0, 0.0, 500.0)).length() < 1e-3,
            "{hit}"
        );
        assert!((normal - DVec3::Y).length() < 1e-9, "{normal}");
        let p = &mut *h.state_mut();
        place_at(&mut p.lights, &snap, hit, normal, &mut p.actions);
        let Light::Point { position, .. } = sent(&h)[0] else {
            panic!("not a point light");
        };
        let want = hit + DVec3::Y * diagonal(&snap) / 20.0;
        assert!((position - want).length() < 1e-9, "{position} vs {want}");
        assert!(!h.state().lights.is_placing(), "one click places once");
    }

    /// The area form's "place at click": the light goes just off the clicked wall, facing
    /// away from it, and is sent at once.
    #[test]
    fn an_area_light_is_placed_at_the_clicked_surface() {
        let snap = snapshot_after(Vec::new(), |_| true);
        let mut h = harness(snap.clone());
        h.get_by_label("+ area").click();
        h.run();
        h.get_by_label("place at click").click();
        h.run();
        assert_eq!(h.state().lights.placing, Some(Placing::Area));
        let (hit, normal) = (DVec3::new(0.0, 300.0, 300.0), DVec3::X);
        let p = &mut *h.state_mut();
        place_at(&mut p.lights, &snap, hit, normal, &mut p.actions);
        let lights = sent_areas(&h);
        let want = hit + DVec3::X * diagonal(&snap) / 200.0;
        assert!((lights[0].centre() - want).length() < 1e-9);
        assert!((lights[0].normal().unwrap() - DVec3::X).length() < 1e-9);
    }
}
