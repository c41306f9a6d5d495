//! Building and publishing a [`Snapshot`] of the worker's state (radiance per drawn vertex,
//! stats, history, teaching data), then waking the UI.

use std::sync::Arc;
use std::time::{Duration, Instant};

use rayon::prelude::*;

use nusselt_core::mesh::PatchId;
use nusselt_core::scene::Rgb;
use nusselt_core::solver::Solver;

use super::super::snapshot::{Geometry, HistoryPoint, Snapshot, Stats};
use super::texture_job::TextureJob;
use super::worker::Worker;
use super::{PUBLISH_COST_RATIO, PUBLISH_INTERVAL};

/// What was published, and when.
#[derive(Default)]
pub(super) struct Published {
    /// The last snapshot's sequence number.
    pub(super) seq: u64,
    /// When the last snapshot was published.
    pub(super) last: Option<Instant>,
    /// What building the last snapshot took (on a large mesh, tens of milliseconds).
    pub(super) cost: Duration,
    /// A material edit was applied and not yet published.
    pub(super) edit_unpublished: bool,
    /// When the latest edit was first published.
    edit_published: Option<Instant>,
}

impl Published {
    /// Whether the next snapshot is due: [`PUBLISH_INTERVAL`] after the last one, or
    /// [`PUBLISH_COST_RATIO`] times what the last one took where that is longer, so that
    /// snapshots never take more than about a tenth of the solver thread's time.
    pub(super) fn due(&self) -> bool {
        let interval = PUBLISH_INTERVAL.max(self.cost * PUBLISH_COST_RATIO);
        self.last.is_none_or(|t| t.elapsed() >= interval)
    }

    /// Counts a snapshot published at `now`: its sequence number, and when the latest edit
    /// was first published (now, if one waited).
    fn next(&mut self, now: Instant) -> (u64, Option<Instant>) {
        self.seq += 1;
        if self.edit_unpublished {
            self.edit_unpublished = false;
            self.edit_published = Some(now);
        }
        (self.seq, self.edit_published)
    }
}

impl Worker {
    /// Publishes the current state as a [`Snapshot`] and wakes the UI.
    pub(super) fn publish(&mut self) {
        let start = Instant::now();
        self.refresh_teaching();
        self.refresh_ray_input();
        let Some(snapshot) = self.snapshot() else {
            return;
        };
        let now = snapshot.published;
        self.latest.publish(Arc::new(snapshot));
        self.published.last = Some(now);
        self.published.cost = now - start;
        self.dirty = false;
        (self.waker)();
        self.after_publish();
    }

    /// What waits for a new scene's first image to be out rather than delaying it: the
    /// picking hierarchy (else built on the UI thread at the first click) and the texture
    /// array (on two cores its thread would slow the first image down).
    fn after_publish(&mut self) {
        if let Some(g) = &self.geometry {
            g.bvh();
        }
        if std::mem::take(&mut self.texture_job_due)
            && let Some(s) = &self.solver
        {
            self.texture_job = TextureJob::start(&s.problem().scene, self.scene_rev);
        }
    }

    /// The current state, numbered as the next snapshot; `None` without a scene.
    fn snapshot(&mut self) -> Option<Snapshot> {
        let (Some(solver), Some(geometry)) = (&self.solver, &self.geometry) else {
            return None;
        };
        let problem = solver.problem();
        // Read again when the mesh or the materials (an area light's radiance) change.
        let key = (geometry.id, self.reflectance_rev);
        if self.area_lights.0 != key {
            self.area_lights = (key, Arc::new(problem.scene.area_lights()));
        }
        let (radiance, correction) = drawn_radiance(solver.as_ref(), geometry);
        let ambient = solver.shooting().map_or(Rgb::ZERO, |s| s.ambient());
        debug_assert!(ambient.is_finite());
        let stats = self.stats(solver.as_ref(), geometry);
        let now = Instant::now();
        let (seq, edit_published) = self.published.next(now);
        let teach = self.teach.view();
        Some(Snapshot {
            seq,
            published: now,
            edit_published,
            geometry: geometry.clone(),
            radiance: Arc::new(radiance),
            correction: Arc::new(correction),
            reflectance: self.reflectance.clone(),
            reflectance_rev: self.reflectance_rev,
            ambient: ambient.as_vec3().to_array(),
            stats,
            materials: Arc::new(problem.scene.materials.clone()),
            lights: Arc::new(problem.scene.lights.clone()),
            area_lights: self.area_lights.1.clone(),
            loaded_materials: self.loaded_materials.clone(),
            history: self.history.clone(),
            scene_name: problem.scene.name.clone(),
            scene_source: problem.scene.source.clone(),
            scene_rev: self.scene_rev,
            textures: self.textures.clone(),
            scene_textures: problem.scene.textures.clone(),
            scene_camera: self.scene_camera,
            two_sided: problem.scene.two_sided,
            method: problem.config.formfactor.method,
            solver_kind: self.kind,
            teach_step: teach.step,
            teach_hemicube: teach.hemicube,
            teach_matrix: teach.matrix,
            teach_nusselt: teach.nusselt,
            teach_compare: teach.compare,
            teach_mesh: teach.mesh,
            teach_mesh_stage: teach.mesh_stage,
            ray_input: self.ray.input.clone(),
        })
    }

    /// The numbers the side panel shows.
    fn stats(&self, solver: &dyn Solver, geometry: &Geometry) -> Stats {
        let residual = solver.residual();
        Stats {
            solver: solver.name(),
            report: match &self.adapting {
                Some(a) => format!(
                    "{}; adaptive: pass {}, tolerance {}",
                    solver.report(),
                    a.passes() + 1,
                    a.tolerance()
                ),
                None => solver.report(),
            },
            matrix_bytes: solver.matrix_bytes(),
            resident_bytes: solver.problem().resident_bytes(),
            memory_budget: solver.problem().config.memory_bytes,
            elements: geometry.elements,
            patches: geometry.patches,
            steps: solver.steps(),
            steps_per_second: steps_per_second(&self.history, solver.steps()),
            residual,
            elapsed_seconds: self.elapsed.as_secs_f64(),
            playing: self.playing,
            converged: (residual <= self.stop_unshot || self.exhausted) && self.adapting.is_none(),
            limit_reached: self.max_shots.is_some_and(|m| solver.steps() >= m),
            last_shooter: solver
                .shooting()
                .and_then(|s| s.last_shooter())
                .map(|p: PatchId| p.0),
        }
    }
}

/// Radiance per drawn vertex without the display correction, and the correction (the
/// solver's estimate of the light still missing).
fn drawn_radiance(solver: &dyn Solver, geometry: &Geometry) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let mesh = &solver.problem().mesh;
    let plain = solver.radiosity();
    let shown = solver.display_radiance();
    let correction: Vec<Rgb> = (shown.par_iter().zip(plain))
        .with_min_len(4096)
        .map(|(s, b)| *s - *b)
        .collect();
    let radiance = geometry.expand(&mesh.vertex_values(plain));
    let correction = geometry.expand(&mesh.vertex_values(&correction));
    debug_assert!(radiance.iter().flatten().all(|x| x.is_finite()));
    (radiance, correction)
}

/// Steps per second over the last second of solve time (or since the start, when shorter),
/// counted within the current solver's steps: a handover to another solver
/// (`handoff.rs`) restarts the count while the history goes on. `steps_now`: the current
/// solver's steps (0 after a handover until its first step, while the history's last point
/// is still the old solver's).
fn steps_per_second(h: &[HistoryPoint], steps_now: usize) -> f64 {
    let Some(l) = h.last() else {
        return 0.0;
    };
    if l.steps > steps_now {
        return 0.0;
    }
    let (run, t0) = match h.windows(2).rposition(|w| w[1].steps < w[0].steps) {
        Some(i) => (&h[i + 1..], h[i].seconds),
        None => (h, 0.0),
    };
    match run.iter().rev().find(|p| l.seconds - p.seconds >= 1.0) {
        Some(p) => (l.steps - p.steps) as f64 / (l.seconds - p.seconds),
        None if l.seconds > t0 => l.steps as f64 / (l.seconds - t0),
        None => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(seconds: f64, steps: usize) -> HistoryPoint {
        HistoryPoint {
            seconds,
            steps,
            residual: 1.0,
            ambient: 0.0,
        }
    }

    /// A snapshot that took 30 ms to build is followed by the next no sooner than 300 ms
    /// later; a cheap one (1 ms, as on the Cornell box) by the next after the 15 ms
    /// interval.
    #[test]
    fn snapshots_wait_ten_times_their_cost() {
        let ago = |ms: u64| Instant::now().checked_sub(Duration::from_millis(ms));
        let published = |cost_ms: u64, last_ms: u64| Published {
            last: ago(last_ms),
            cost: Duration::from_millis(cost_ms),
            ..Default::default()
        };
        assert!(Published::default().due(), "the first is due at once");
        assert!(!published(30, 100).due());
        assert!(published(30, 320).due());
        assert!(!published(1, 5).due());
        assert!(published(1, 20).due());
    }

    /// Ten shots a second for 5 s, then a solver of long steps: its rate is its own steps
    /// over its own time, not a difference with the shots' count.
    #[test]
    fn a_handover_restarts_the_rate() {
        let mut h: Vec<HistoryPoint> = (1..=50).map(|k| point(k as f64 * 0.1, k)).collect();
        assert!((steps_per_second(&h, 50) - 10.0).abs() < 1e-9);
        // Handed over, before the new solver's first step: no rate yet, not the old one's.
        assert_eq!(steps_per_second(&h, 0), 0.0);
        h.push(point(25.0, 1));
        assert!((steps_per_second(&h, 1) - 1.0 / 20.0).abs() < 1e-9);
        h.push(point(35.0, 2));
        assert!((steps_per_second(&h, 2) - 1.0 / 10.0).abs() < 1e-9);
    }
}
