//! Reproducible viewer runs: `--screenshot` (wait, capture exactly what is on screen, save,
//! close), `--edit` (material edits sent at a given shot, as a user would), and
//! `--frame-log` (per-frame timings and the latency figures of docs/VIEWER.md).
//!
//! Screenshots go through `egui::Context::request_screenshot` (egui 0.37's form of
//! `ViewportCommand::Screenshot` + `Event::Screenshot`): the image arrives a frame or two
//! later, is saved, and then `ViewportCommand::Close` ends the run. eframe's
//! `EFRAME_SCREENSHOT_TO` does not work with the wgpu backend.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use eframe::egui;

use super::app::ViewerApp;
use super::export;
use super::panels::Action;

/// When to take the screenshot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ScreenshotWhen {
    /// After this many shots (the solver stops there, so the image is of exactly N shots;
    /// earlier if it converges first).
    Shots(usize),
    /// This long after the window opened (the solver keeps running).
    Seconds(f64),
    /// When the solve has converged.
    Converged,
}

#[derive(Clone, Debug)]
pub struct ScreenshotPlan {
    pub path: PathBuf,
    pub when: ScreenshotWhen,
    /// Give up (and exit with an error) after this long.
    pub timeout: Duration,
}

/// What an `--edit` changes.
#[derive(Clone, Debug, PartialEq)]
pub enum EditTarget {
    /// A material by name.
    Material(String),
    /// The material of a patch (by id); the patch is also selected.
    Patch(u32),
}

/// `--edit TARGET:kd=r,g,b[:ke=r,g,b]`, TARGET = material name or `#patch`.
#[derive(Clone, Debug, PartialEq)]
pub struct EditSpec {
    pub target: EditTarget,
    pub kd: Option<[f64; 3]>,
    pub ke: Option<[f64; 3]>,
}

impl EditSpec {
    pub fn parse(text: &str) -> Result<EditSpec, String> {
        let mut parts = text.split(':');
        let target = parts.next().unwrap_or_default().trim();
        if target.is_empty() {
            return Err(format!("'{text}': expected TARGET:kd=r,g,b[:ke=r,g,b]"));
        }
        let target = match target.strip_prefix('#') {
            Some(id) => EditTarget::Patch(
                id.parse()
                    .map_err(|_| format!("'{text}': '#{id}' is not a patch number"))?,
            ),
            None => EditTarget::Material(target.to_string()),
        };
        let (mut kd, mut ke) = (None, None);
        for part in parts {
            let (key, value) = part
                .split_once('=')
                .ok_or_else(|| format!("'{text}': '{part}' should be kd=r,g,b or ke=r,g,b"))?;
            let v = parse_rgb(value).map_err(|e| format!("'{text}': {key}: {e}"))?;
            match key.trim() {
                "kd" => kd = Some(v),
                "ke" => ke = Some(v),
                other => return Err(format!("'{text}': unknown key '{other}' (kd or ke)")),
            }
        }
        if kd.is_none() && ke.is_none() {
            return Err(format!("'{text}': give kd=r,g,b and/or ke=r,g,b"));
        }
        Ok(EditSpec { target, kd, ke })
    }
}

/// Parses `r,g,b` (three finite numbers >= 0).
pub fn parse_rgb(text: &str) -> Result<[f64; 3], String> {
    let v: Vec<&str> = text.split(',').collect();
    if v.len() != 3 {
        return Err(format!("expected three numbers r,g,b, got '{text}'"));
    }
    let mut out = [0.0; 3];
    for (o, s) in out.iter_mut().zip(&v) {
        *o = parse_channel(s)?;
    }
    Ok(out)
}

/// One colour channel: a finite number >= 0.
pub fn parse_channel(text: &str) -> Result<f64, String> {
    let x: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("'{}' is not a number", text.trim()))?;
    if !x.is_finite() || x < 0.0 {
        return Err(format!("{x} must be a finite number >= 0"));
    }
    Ok(x)
}

/// Everything a scripted run does.
#[derive(Clone, Debug, Default)]
pub struct Automation {
    pub screenshot: Option<ScreenshotPlan>,
    pub frame_log: Option<PathBuf>,
    pub edits: Vec<EditSpec>,
    /// Send the edits once this many shots are on screen.
    pub edit_after_shots: usize,
    /// Select this patch at start.
    pub select: Option<u32>,
    /// With the screenshot, also save the viewport alone (the PNG export).
    pub viewport_png: Option<PathBuf>,
    /// With the screenshot, also export the solution as PLY.
    pub export_ply: Option<PathBuf>,
}

/// Progress of a scripted screenshot.
#[derive(Debug, Default)]
pub enum ShotState {
    #[default]
    Waiting,
    /// The condition held in frame `frames` ago; wait a frame more so it is on screen.
    Ready(u32),
    Requested(Instant),
    Done,
}

impl ViewerApp {
    /// Scripted edits, once enough shots are on screen.
    pub(super) fn run_edits(&mut self, ctx: &egui::Context) {
        if self.edits_sent || self.auto.edits.is_empty() {
            return;
        }
        let Some(s) = self.snapshot.clone() else {
            return;
        };
        if s.stats.steps < self.auto.edit_after_shots && !s.stats.converged {
            return;
        }
        self.edits_sent = true;
        for spec in self.auto.edits.clone() {
            let material = match &spec.target {
                EditTarget::Material(name) => {
                    let m = s.materials.iter().position(|m| m.name == *name);
                    // Show the edit panel: select a patch of that material.
                    if self.panel.selection.is_none()
                        && let Some(m) = m
                    {
                        self.panel.selection = s
                            .geometry
                            .patch_material
                            .iter()
                            .position(|&p| p as usize == m)
                            .map(|p| p as u32);
                    }
                    m.map(|i| i as u32)
                }
                EditTarget::Patch(p) => {
                    let m = s.geometry.patch_material.get(*p as usize).copied();
                    if m.is_some() {
                        self.panel.selection = Some(*p);
                        self.panel.editor = None;
                    }
                    m
                }
            };
            let Some(material) = material else {
                let text = format!(
                    "--edit: no {} in {} (materials: {})",
                    match &spec.target {
                        EditTarget::Material(n) => format!("material '{n}'"),
                        EditTarget::Patch(p) =>
                            format!("patch #{p} ({} patches)", s.geometry.patches),
                    },
                    s.scene_name,
                    s.materials
                        .iter()
                        .map(|m| m.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                );
                self.fail(ctx, text);
                return;
            };
            let m = &s.materials[material as usize];
            let kd = spec.kd.unwrap_or(m.reflectance.to_array());
            let ke = spec.ke.unwrap_or(m.emission.to_array());
            if kd.iter().any(|&x| x > nusselt_core::scene::MAX_REFLECTANCE) {
                self.fail(
                    ctx,
                    format!(
                        "--edit: kd must be <= {}",
                        nusselt_core::scene::MAX_REFLECTANCE
                    ),
                );
                return;
            }
            self.handle(ctx, Action::Edit { material, kd, ke });
        }
    }

    /// Scripted screenshot: wait for the condition, capture, save, close.
    pub(super) fn run_screenshot(&mut self, ctx: &egui::Context) {
        let Some(plan) = self.auto.screenshot.clone() else {
            return;
        };
        // While waiting, a few checks a second (each publish repaints too): repainting every
        // frame would take a core from the load and the solve being measured.
        if matches!(self.shot_state, ShotState::Waiting) {
            ctx.request_repaint_after(Duration::from_millis(100));
        } else {
            ctx.request_repaint();
        }
        let since_open = self.first_frame.map_or(Duration::ZERO, |t| t.elapsed());
        if !matches!(self.shot_state, ShotState::Done) && since_open > plan.timeout {
            let steps = self.snapshot.as_ref().map_or(0, |s| s.stats.steps);
            self.fail(
                ctx,
                format!(
                    "screenshot not taken within {:.0} s ({steps} steps so far)",
                    plan.timeout.as_secs_f64()
                ),
            );
            return;
        }
        match self.shot_state {
            ShotState::Waiting => {
                if self.screenshot_ready(&plan, since_open) {
                    self.shot_state = ShotState::Ready(0);
                }
            }
            ShotState::Ready(k) if k < 2 => self.shot_state = ShotState::Ready(k + 1),
            ShotState::Ready(_) => {
                let slot = self.screenshot_image.clone();
                let c = ctx.clone();
                ctx.request_screenshot(move |image| {
                    slot.publish(image);
                    c.request_repaint();
                });
                self.shot_state = ShotState::Requested(Instant::now());
            }
            ShotState::Requested(at) => {
                if let Some(image) = self.screenshot_image.take() {
                    self.save_screenshot(ctx, &plan, &image);
                } else if at.elapsed() > Duration::from_secs(20) {
                    self.fail(ctx, "the screenshot never arrived".into());
                }
            }
            ShotState::Done => {}
        }
    }

    /// Whether the scripted screenshot may be taken: the edits applied, the teaching and
    /// ray-traced views ready, and the plan's condition met.
    fn screenshot_ready(&self, plan: &ScreenshotPlan, since_open: Duration) -> bool {
        let Some(s) = &self.snapshot else {
            return false;
        };
        let edits_done =
            self.auto.edits.is_empty() || (self.edits_sent && self.edit_latency.is_empty());
        edits_done
            && super::teach::ready(self.teach.as_ref(), s)
            && self.ray_ready(super::ray_view::SCREENSHOT_SPP)
            && match plan.when {
                ScreenshotWhen::Shots(n) => {
                    s.stats.steps >= n || s.stats.converged || s.stats.limit_reached
                }
                ScreenshotWhen::Seconds(t) => since_open.as_secs_f64() >= t,
                // The side-by-side teaching views run their own solves (the viewer's stays
                // paused): ready is when they are done.
                ScreenshotWhen::Converged => {
                    s.stats.converged
                        || self
                            .teach
                            .as_ref()
                            .is_some_and(|t| t.view.replaces_viewport())
                }
            }
    }

    /// Writes the captured window (and the viewport crop and the PLY when asked for), then
    /// closes the viewer; an error fails the run.
    fn save_screenshot(
        &mut self,
        ctx: &egui::Context,
        plan: &ScreenshotPlan,
        image: &egui::ColorImage,
    ) {
        let saved = export::write_color_image(&plan.path, image);
        if let Some(p) = self.auto.viewport_png.clone() {
            let crop = image.region(&self.viewport_rect, Some(ctx.pixels_per_point()));
            if let Err(e) = export::write_color_image(&p, &crop) {
                self.fail(ctx, e.to_string());
                return;
            }
        }
        if let (Some(p), Some(s)) = (self.auto.export_ply.clone(), self.snapshot.clone()) {
            let bytes = export::ply_bytes(&s, self.panel.view.ambient, self.panel.view.exposure());
            if let Err(e) = export::atomic_write(&p, &bytes) {
                self.fail(ctx, e.to_string());
                return;
            }
        }
        match saved {
            Ok(()) => {
                let s = self.snapshot.as_ref();
                eprintln!(
                    "saved {} ({}x{} px, {} {} steps, {} elements)",
                    plan.path.display(),
                    image.size[0],
                    image.size[1],
                    s.map_or("no", |s| s.stats.solver),
                    s.map_or(0, |s| s.stats.steps),
                    s.map_or(0, |s| s.stats.elements)
                );
                self.shot_state = ShotState::Done;
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            }
            Err(e) => self.fail(ctx, e.to_string()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edit_specs_parse_and_reject() {
        assert_eq!(
            EditSpec::parse("red:kd=0.1,0.2,0.3"),
            Ok(EditSpec {
                target: EditTarget::Material("red".into()),
                kd: Some([0.1, 0.2, 0.3]),
                ke: None
            })
        );
        let e = EditSpec::parse("#12:ke=5,5,5:kd=0,0,0").expect("parse");
        assert_eq!(e.target, EditTarget::Patch(12));
        assert_eq!(e.ke, Some([5.0; 3]));
        for bad in [
            "",
            "red",
            "red:kd=1,2",
            "red:kd=a,b,c",
            "red:kd=-1,0,0",
            "red:kd=nan,0,0",
            "red:xx=1,1,1",
            "#x:kd=0,0,0",
        ] {
            assert!(EditSpec::parse(bad).is_err(), "{bad}");
        }
    }
}
