//! Building and publishing a [`Snapshot`] of the worker's state (radiance per drawn vertex,
//! stats, history, teaching data), then waking the UI.

use std::sync::Arc;
use std::time::Instant;

use nusselt_core::mesh::PatchId;
use nusselt_core::scene::Rgb;

use super::super::snapshot::{Snapshot, Stats};
use super::worker::Worker;

impl Worker {
    /// Publishes the current state as a [`Snapshot`] and wakes the UI.
    pub(super) fn publish(&mut self) {
        self.refresh_hemicube();
        self.refresh_matrix();
        self.refresh_nusselt();
        self.refresh_compare();
        self.refresh_mesh_view();
        self.refresh_ray_input();
        let (Some(solver), Some(geometry)) = (&self.solver, &self.geometry) else {
            return;
        };
        let problem = solver.problem();
        // Read again when the mesh or the materials (an area light's radiance) change.
        let key = (geometry.id, self.reflectance_rev);
        if self.area_lights.0 != key {
            self.area_lights = (key, Arc::new(problem.scene.area_lights()));
        }
        let plain = solver.element_radiance(false);
        let shown = solver.element_radiance(true);
        let correction: Vec<Rgb> = shown.iter().zip(&plain).map(|(s, b)| *s - *b).collect();
        let radiance = geometry.expand(&problem.mesh.vertex_values(&plain));
        let correction = geometry.expand(&problem.mesh.vertex_values(&correction));
        debug_assert!(radiance.iter().flatten().all(|x| x.is_finite()));
        let ambient = solver.ambient();
        debug_assert!(ambient.is_finite());
        let steps_per_second = {
            let h = &self.history;
            match (
                h.last(),
                h.iter()
                    .rev()
                    .find(|p| h.last().is_some_and(|l| l.seconds - p.seconds >= 1.0)),
            ) {
                (Some(l), Some(p)) => (l.steps - p.steps) as f64 / (l.seconds - p.seconds),
                (Some(l), None) if l.seconds > 0.0 => l.steps as f64 / l.seconds,
                _ => 0.0,
            }
        };
        let residual = solver.residual();
        let stats = Stats {
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
            steps_per_second,
            residual,
            elapsed_seconds: self.elapsed.as_secs_f64(),
            playing: self.playing,
            converged: (residual <= self.stop_unshot || self.exhausted) && self.adapting.is_none(),
            limit_reached: self.max_shots.is_some_and(|m| solver.steps() >= m),
            last_shooter: solver.last_shooter().map(|p: PatchId| p.0),
        };
        self.seq += 1;
        let now = Instant::now();
        if self.edit_unpublished {
            self.edit_unpublished = false;
            self.edit_published = Some(now);
        }
        let snapshot = Snapshot {
            seq: self.seq,
            published: now,
            edit_published: self.edit_published,
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
            method: problem.config.method,
            solver_kind: self.kind,
            teach_step: self.step_detail.clone(),
            teach_hemicube: self.hemicube_detail.clone(),
            teach_matrix: self.matrix_detail.clone(),
            teach_nusselt: self.nusselt_detail.clone(),
            teach_compare: self.compare_detail.clone(),
            teach_mesh: self.mesh_detail.clone(),
            teach_mesh_stage: self.mesh_job.as_ref().map(|j| j.stage()),
            ray_input: self.ray_input.clone(),
        };
        self.latest.publish(Arc::new(snapshot));
        self.last_publish = Some(now);
        self.dirty = false;
        (self.waker)();
    }
}
