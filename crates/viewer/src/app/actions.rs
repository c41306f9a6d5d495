//! The panels' actions, handled in one place: solver commands, file dialogs, exports and
//! the material editor's edits.

use super::*;

impl ViewerApp {
    /// Applies one user action: the single place where UI input becomes a change.
    pub(crate) fn handle(&mut self, ctx: &egui::Context, action: Action) {
        match action {
            Action::Solver(c) => self.solver.queue(c),
            Action::Remesh(size) => self.solver.queue(Command::Remesh(size)),
            Action::SetMethod(m) => self.solver.queue(Command::SetMethod(m)),
            Action::SetSolver(k) => self.solver.queue(Command::SetSolver(k)),
            Action::Teach(t) => self.solver.queue(Command::Teach(t)),
            Action::OpenDialog => self.open_dialog(
                ctx,
                Request::new(
                    Purpose::Open,
                    ("OBJ or glTF model, or scene file", "obj,gltf,glb,json"),
                    false,
                ),
            ),
            Action::Open(p) => {
                self.message(false, format!("opening {}", p.display()));
                self.solver.queue(Command::LoadPath(p));
            }
            Action::OpenBuiltin(name) => match Scene::builtin(&name, &LoadOptions::default()) {
                Ok(s) => self.solver.queue(Command::LoadScene(Box::new(s))),
                Err(e) => self.message(true, e.to_string()),
            },
            Action::ClearRecent => self.panel.recent.clear(),
            Action::SaveMtl => self.save_mtl_beside_model(),
            Action::SaveScene => self.save_scene(),
            Action::SaveMtlAs => self.save_mtl_as_dialog(ctx),
            Action::ResetEdits => {
                self.solver.queue(Command::ResetMaterials);
                self.resync_editor_after = Some(self.snapshot.as_ref().map_or(0, |s| s.seq));
            }
            Action::ExportPly => self.export_dialog(ctx, Purpose::ExportPly, ("PLY", "ply"), "ply"),
            Action::ExportGltf => {
                self.export_dialog(ctx, Purpose::ExportGltf, ("glTF", "glb,gltf"), "glb")
            }
            Action::ExportPng => {
                let mut r = Request::new(Purpose::ExportPng, ("PNG", "png"), true);
                r.file_name = Some("viewport.png".into());
                self.open_dialog(ctx, r);
            }
            // The chosen first view: the scene's own camera, or the view that sees the most
            // lit surface (render::view).
            Action::FrameScene | Action::ResetView => self.frame_scene(),
            Action::Select(p) => {
                self.panel.selection = p;
                self.panel.editor = None;
            }
            Action::Edit { material, kd, ke } => {
                self.edit_latency.sent(material, kd, ke);
                self.solver.queue(Command::SetMaterial {
                    material: nusselt_core::scene::MaterialId(material),
                    reflectance: kd,
                    emission: ke,
                });
            }
            Action::SetLights(lights) => self.solver.queue(Command::SetLights(lights)),
            Action::SetAreaLights(lights) => self.solver.queue(Command::SetAreaLights(lights)),
            Action::Quit => ctx.send_viewport_cmd(egui::ViewportCommand::Close),
        }
    }

    /// Writes the materials next to the model (its MTL path), or to `<scene name>.mtl` in
    /// the working directory for a built-in scene.
    fn save_mtl_beside_model(&mut self) {
        if let Some(s) = self.snapshot.clone() {
            let path = match &s.scene_source {
                Some(obj) => export::mtl_path_for(obj),
                None => PathBuf::from(format!("{}.mtl", s.scene_name)),
            };
            self.save_mtl(&s, &path);
        }
    }

    /// Asks the solver thread to write the scene file next to the model (or in the working
    /// directory), with the current camera.
    fn save_scene(&mut self) {
        if let Some(s) = self.snapshot.clone() {
            let path = match &s.scene_source {
                Some(obj) => obj.with_extension("scene.json"),
                None => PathBuf::from(format!("{}.scene.json", s.scene_name)),
            };
            let camera = self.camera.as_ref().map(|c| c.to_camera());
            self.message(false, format!("saving {}", path.display()));
            self.solver.queue(Command::SaveScene { path, camera });
        }
    }

    /// The "save materials as" dialog, opened in the model's folder.
    fn save_mtl_as_dialog(&mut self, ctx: &egui::Context) {
        if let Some(s) = self.snapshot.clone() {
            let mut r = Request::new(Purpose::SaveMtlAs, ("MTL", "mtl"), true);
            r.directory = s
                .scene_source
                .as_deref()
                .and_then(Path::parent)
                .map(Path::to_path_buf);
            r.file_name = Some(format!("{}.mtl", s.scene_name));
            self.open_dialog(ctx, r);
        }
    }

    /// A save dialog for an export of the scene, named after it (`scene.extension`).
    fn export_dialog(
        &mut self,
        ctx: &egui::Context,
        purpose: Purpose,
        filter: (&'static str, &'static str),
        extension: &str,
    ) {
        if let Some(s) = self.snapshot.clone() {
            let mut r = Request::new(purpose, filter, true);
            r.file_name = Some(format!("{}.{extension}", s.scene_name));
            self.open_dialog(ctx, r);
        }
    }

    /// The camera back to the scene's first view.
    fn frame_scene(&mut self) {
        if let Some(s) = &self.snapshot {
            self.camera = Some(OrbitCamera::from_camera(
                &s.scene_camera,
                s.geometry.bounds_min,
                s.geometry.bounds_max,
            ));
        }
    }
}
