//! Changing what the worker solves with: re-meshing, another form-factor method, another
//! solver. Each takes the solver apart ([`nusselt_core::solver::Solver::into_parts`]), changes the
//! problem or the kind, and builds the new solver on the same problem and cached rows
//! ([`SolverKind::build_with_rows`]); each restarts from dark. A change that is refused
//! leaves the user with what they had.

use std::sync::Arc;

use nusselt_core::formfactor::FormFactorMethod;
use nusselt_core::formfactor::hemicube::ItemBufferRaster;
use nusselt_core::scene::{AreaLight, Material, MaterialId, Rgb};
use nusselt_core::solver::{Problem, RowCache, SolverKind};

use super::Event;
use super::worker::Worker;

impl Worker {
    /// Builds a solver of the current kind on `problem`, reusing `rows`. A kind that
    /// refuses the problem (a matrix over the memory budget) falls back to shooting, which
    /// takes any problem, with an error event saying why.
    pub(super) fn build(&mut self, problem: Problem, rows: Option<RowCache>) {
        let kind = match self.kind.check(&problem) {
            Ok(()) => self.kind,
            Err(e) => {
                self.send_event(Event::Error(format!("{e}; solving with shooting instead")));
                SolverKind::Shooting
            }
        };
        match kind.build_with_rows(problem, rows) {
            Ok(solver) => {
                self.kind = kind;
                self.solver = Some(solver);
            }
            // `check` passed, so this is not expected; the problem is gone with the error.
            Err(e) => self.send_event(Event::Failed(format!("cannot build the solver: {e}"))),
        }
        self.restart_clock();
    }

    /// Re-meshes at `size` and restarts from dark on the new mesh. On error the old mesh
    /// (and its cached rows) stay.
    pub(super) fn remesh(&mut self, size: f64) {
        if !(size.is_finite() && size > 0.0) {
            // Refused before anything is taken apart, so the solve goes on as it was.
            self.send_event(Event::Error(format!(
                "re-mesh: the element size must be a positive number, got {size}"
            )));
            return;
        }
        let Some(solver) = self.solver.take() else {
            return;
        };
        let (mut problem, mut rows) = solver.into_parts();
        match problem.remesh(size) {
            Ok(()) => {
                rows = None;
                self.config.mesh.element_size = Some(size);
                self.build(problem, rows);
                self.new_geometry();
            }
            Err(e) => {
                // `Problem::remesh` left the problem as it was: same mesh, rows still valid.
                self.send_event(Event::Error(format!("re-mesh: {e}")));
                self.build(problem, rows);
            }
        }
    }

    /// Replaces the area lights and re-meshes at the current element size, from dark;
    /// other lights, material edits and the camera stay. A refused list (a degenerate
    /// light, a power overflow, a mesh over the budget) leaves the scene and the solve as
    /// they were. A list that changes only radiances (a colour or power edit, a light
    /// switched off as radiance 0 and on again) is applied as edits of the lights'
    /// materials instead: no re-meshing, and the solve goes on from where it is as for
    /// any material edit.
    pub(super) fn set_area_lights(&mut self, lights: Vec<AreaLight>) {
        let checked = lights
            .iter()
            .enumerate()
            .try_for_each(|(k, l)| l.check(k + 1));
        if let Err(e) = checked {
            self.send_event(Event::Error(e.to_string()));
            return;
        }
        if self.set_area_radiance(&lights) {
            return;
        }
        let Some(solver) = self.solver.take() else {
            return;
        };
        let (mut problem, mut rows) = solver.into_parts();
        let size = problem.mesh.element_size;
        let before = (problem.scene.faces.clone(), problem.scene.materials.clone());
        let result = problem
            .scene
            .set_area_lights(&lights)
            .map_err(|e| e.to_string())
            .and_then(|remap| {
                problem.remesh(size).map_err(|e| e.to_string())?;
                Ok(remap)
            });
        match result {
            Ok(remap) => {
                rows = None;
                self.loaded_materials = Arc::new(remap_loaded(
                    &self.loaded_materials,
                    &remap,
                    &problem.scene.materials,
                ));
                if let Some(a) = self.adapting.as_mut() {
                    // Levels were per patch of the old mesh.
                    a.restart_levels();
                }
                self.build(problem, rows);
                self.new_geometry();
            }
            Err(e) => {
                // The mesh is untouched when re-meshing fails, so the rows still hold.
                (problem.scene.faces, problem.scene.materials) = before;
                self.send_event(Event::Error(format!("area lights: {e}")));
                self.build(problem, rows);
            }
        }
    }

    /// When `lights` are the current area lights in shape and order, sets each changed
    /// radiance as its material's emission and returns true (the loaded materials follow,
    /// so "reset edits" leaves the lights as set, as after a re-mesh).
    fn set_area_radiance(&mut self, lights: &[AreaLight]) -> bool {
        let Some(solver) = self.solver.as_ref() else {
            return false;
        };
        let scene = &solver.problem().scene;
        let current = scene.area_lights();
        let same_shape = current.len() == lights.len()
            && current
                .iter()
                .zip(lights)
                .all(|(a, b)| a.corners == b.corners);
        if !same_shape {
            return false;
        }
        let ids = scene.area_light_materials();
        let edits: Vec<(MaterialId, Rgb, Rgb)> = ids
            .iter()
            .zip(current.iter().zip(lights))
            .filter(|(_, (a, b))| a.radiance != b.radiance)
            .map(|(&id, (_, b))| (id, scene.materials[id.0 as usize].reflectance, b.radiance))
            .collect();
        if edits.is_empty() {
            return true;
        }
        let mut loaded = (*self.loaded_materials).clone();
        for (id, reflectance, emission) in edits {
            self.set_material(id, reflectance, emission);
            if let Some(m) = loaded.get_mut(id.0 as usize) {
                m.emission = emission;
            }
        }
        self.loaded_materials = Arc::new(loaded);
        true
    }

    /// Switches the form-factor method (cached rows dropped) and restarts from dark. The
    /// GPU hemicube is started on first use; if it cannot be, nothing changes.
    pub(super) fn set_method(&mut self, method: FormFactorMethod) {
        if let Err(e) = self.start_raster_for(method) {
            self.send_event(Event::Error(e));
            return;
        }
        let Some(solver) = self.solver.take() else {
            return;
        };
        // Rows of the old method are dropped.
        let (mut problem, _) = solver.into_parts();
        if problem.config.formfactor.raster.is_none() {
            problem.set_raster(self.config.formfactor.raster.clone());
        }
        problem.config.formfactor.method = method;
        self.config.formfactor.method = method;
        self.build(problem, None);
    }

    /// Starts the GPU hemicube when `method` needs it and it is not running yet; the
    /// reason when it cannot be started.
    pub(super) fn start_raster_for(&mut self, method: FormFactorMethod) -> Result<(), String> {
        if method == FormFactorMethod::GpuHemicube && self.config.formfactor.raster.is_none() {
            let gpu = nusselt_gpu::GpuHemicube::new().map_err(|e| format!("gpu-hemicube: {e}"))?;
            let raster: Arc<dyn ItemBufferRaster> = Arc::new(gpu);
            self.config.formfactor.raster = Some(raster);
        }
        Ok(())
    }

    /// Switches to a solver of `kind` on the same mesh and cached rows, from dark. Refused
    /// (the current solver goes on, an error event says why) when `kind` would refuse the
    /// problem: ω out of range, a matrix over the memory budget.
    pub(super) fn set_solver(&mut self, kind: SolverKind) {
        let Some(current) = self.solver.as_ref() else {
            // Nothing loaded (a failed solve): the next load uses it.
            self.kind = kind;
            self.handoff = false;
            return;
        };
        if let Err(e) = kind.check(current.problem()) {
            self.send_event(Event::Error(format!(
                "cannot switch to {}: {e}",
                kind.name()
            )));
            return;
        }
        let Some(solver) = self.solver.take() else {
            return;
        };
        let (problem, rows) = solver.into_parts();
        self.kind = kind;
        // A solver chosen by name stays.
        self.handoff = false;
        self.build(problem, rows);
    }
}

/// The materials as loaded after [`nusselt_core::scene::Scene::set_area_lights`]: the kept
/// ones as they were loaded (by `remap`, old id to new), the new area lights' as they are
/// now (`current`), so "reset edits" leaves the lights alone.
fn remap_loaded(
    loaded: &[Material],
    remap: &[Option<MaterialId>],
    current: &[Material],
) -> Vec<Material> {
    let mut out: Vec<Material> = loaded
        .iter()
        .zip(remap)
        .filter(|(_, new)| new.is_some())
        .map(|(m, _)| m.clone())
        .collect();
    out.extend(current.iter().skip(out.len()).cloned());
    out
}

#[cfg(test)]
mod tests {
    use glam::DVec3;
    use nusselt_core::scene::{AreaLight, Light, MaterialId, Rgb, SceneFile};

    use super::super::Command;
    use crate::teach::panel_tests::snapshot_after;

    /// Adding an area light re-meshes at the same element size with the light's face,
    /// and keeps the sky, a material edit and "reset edits" in step with the materials.
    #[test]
    fn an_area_light_remeshes_and_keeps_the_rest() {
        let first = snapshot_after(Vec::new(), |_| true);
        let sky = Light::Sky {
            radiance: Rgb::splat(0.5),
        };
        let a = AreaLight::square(
            DVec3::new(278.0, 500.0, 278.0),
            DVec3::NEG_Y,
            120.0,
            Rgb::splat(5.0),
        )
        .unwrap();
        let commands = vec![
            Command::SetMaterial {
                material: MaterialId(0),
                reflectance: [0.1, 0.2, 0.3],
                emission: [0.0; 3],
            },
            Command::SetLights(vec![sky]),
            Command::SetAreaLights(vec![a.clone()]),
        ];
        let s = snapshot_after(commands, |s| s.area_lights.len() == 1);
        assert_eq!(*s.area_lights, vec![a]);
        assert_eq!(*s.lights, vec![sky]);
        assert_eq!(s.materials[0].reflectance, Rgb::new(0.1, 0.2, 0.3));
        assert_eq!(s.loaded_materials.len(), s.materials.len());
        assert_eq!(s.loaded_materials[0], first.loaded_materials[0]);
        assert!(s.geometry.elements > first.geometry.elements);
        assert_eq!(s.geometry.element_size, first.geometry.element_size);
    }

    /// A scene file opened in a running viewer meshes and solves as the file says, as
    /// `nusselt view FILE` does (they were ignored: the file's lights and camera applied,
    /// its mesh and solver did not).
    #[test]
    fn an_opened_scene_file_brings_its_mesh_and_solver() {
        let dir = std::env::temp_dir().join(format!("nusselt-open-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("coarse.scene.json");
        std::fs::write(
            &path,
            r#"{"builtin": "cornell", "mesh": {"element_size": 90, "patch_size": 180},
                "solver": {"name": "jacobi", "formfactor": "hemicube", "unshot": 0.01}}"#,
        )
        .unwrap();
        let first = snapshot_after(Vec::new(), |_| true);
        assert_eq!(first.geometry.element_size, 60.0);
        let s = snapshot_after(vec![Command::LoadPath(path)], |s| {
            s.geometry.element_size != 60.0
        });
        assert_eq!(s.geometry.element_size, 90.0);
        assert_eq!(s.solver_kind, nusselt_core::solver::SolverKind::Jacobi);
        assert_eq!(
            s.method,
            nusselt_core::formfactor::FormFactorMethod::Hemicube
        );
        assert!(s.geometry.elements < first.geometry.elements);
    }

    /// A change of an area light's radiance alone (its colour, its power, switched off
    /// as 0) is a material edit: the mesh stays and the shots already made stay, where a
    /// re-mesh would start from dark.
    #[test]
    fn an_area_light_power_edit_keeps_the_mesh_and_the_light_shot() {
        use crate::teach::panel_tests::{coarse_cornell_thread, wait_for};
        use std::time::Duration;
        let a = AreaLight::square(
            DVec3::new(278.0, 500.0, 278.0),
            DVec3::NEG_Y,
            120.0,
            Rgb::splat(5.0),
        )
        .unwrap();
        let brighter = AreaLight {
            radiance: Rgb::new(10.0, 8.0, 6.0),
            ..a.clone()
        };
        let mut h = coarse_cornell_thread();
        h.send(Command::SetAreaLights(vec![a])).expect("queue");
        let mut shot = wait_for(&mut h, |s| s.area_lights.len() == 1);
        for _ in 0..5 {
            h.send(Command::Step).expect("queue");
            let steps = shot.stats.steps;
            shot = wait_for(&mut h, move |s| s.stats.steps > steps);
        }
        assert!(shot.stats.steps >= 5);
        h.send(Command::SetAreaLights(vec![brighter.clone()]))
            .expect("queue");
        let want = brighter.radiance;
        let s = wait_for(&mut h, move |s| {
            s.area_lights.first().is_some_and(|l| l.radiance == want)
        });
        assert!(h.shutdown(Duration::from_secs(30)));
        assert_eq!(s.geometry.id, shot.geometry.id, "re-meshed");
        assert!(
            s.stats.steps >= shot.stats.steps,
            "restarted: {} steps after {}",
            s.stats.steps,
            shot.stats.steps
        );
        let id = s.materials.iter().position(|m| m.emission == want);
        assert!(id.is_some(), "the light's material carries the radiance");
        assert_eq!(s.loaded_materials[id.unwrap()].emission, want);
    }

    /// "Save scene" writes the mesh's element size and the solver settings in use.
    #[test]
    fn saved_scenes_carry_mesh_and_solver_settings() {
        let dir = std::env::temp_dir().join(format!("nusselt-save-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("saved.scene.json");
        let _ = std::fs::remove_file(&path);
        let commands = vec![
            Command::Remesh(50.0),
            Command::SaveScene {
                path: path.clone(),
                camera: None,
            },
        ];
        let wait = path.clone();
        snapshot_after(commands, move |_| wait.exists());
        let file = SceneFile::read(&path).unwrap();
        let mesh = file.mesh.expect("mesh settings");
        assert_eq!(mesh.element_size, Some(50.0));
        assert_eq!(mesh.patch_size, Some(120.0));
        let solver = file.solver.expect("solver settings");
        assert_eq!(solver.name.as_deref(), Some("shooting"));
        assert_eq!(solver.formfactor.as_deref(), Some("contour"));
        assert!(solver.unshot.is_some());
    }
}
