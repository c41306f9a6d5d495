//! The scene file (`*.json`): a model (an OBJ or glTF path relative to the file, or a built-in), the
//! lights added to it, the camera and the material edits, so that what a user set up can be
//! saved and opened again. Unknown fields are refused, and every error names the file, the
//! line and the field. The format is documented in the README ("Scene files").

use std::path::{Path, PathBuf};

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::{Camera, Light, LoadOptions, Rgb, Scene, SceneError, SpotCone};

/// What a scene file holds.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// OBJ, glTF or GLB file, relative to the scene file's folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<String>,
    /// `lights` replace the lights the model brings (a glTF file's `KHR_lights_punctual`)
    /// instead of adding to them: what a saved scene says, since it lists every light.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub replaces_model_lights: bool,
    /// A built-in scene instead of a model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub builtin: Option<String>,
    #[serde(default)]
    pub two_sided: bool,
    #[serde(default)]
    pub lights: Vec<LightEntry>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<CameraEntry>,
    /// Material edits by name: `Kd` and/or `Ke`.
    #[serde(default)]
    pub materials: std::collections::BTreeMap<String, MaterialEntry>,
    /// Meshing settings: defaults for `render` and `view`, which their flags override.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh: Option<MeshEntry>,
    /// Solver settings: defaults for `render` and `view`, which their flags override.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solver: Option<SolverEntry>,
}

/// How the scene is meshed (as `--element-size`, `--patch-size`, `--max-elements` and
/// `--discontinuity`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshEntry {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub element_size: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub patch_size: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_elements: Option<usize>,
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub discontinuity: bool,
}

/// How the scene is solved (as `--solver`, `--formfactor` and `--unshot`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverEntry {
    /// A `--solver` name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// A `--formfactor` name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub formfactor: Option<String>,
    /// The residual to stop at (for shooting, the unshot fraction).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unshot: Option<f64>,
}

impl MeshEntry {
    /// Refuses values the mesher would refuse, naming the field (`mesh.…`).
    fn check(&self, file: &Path) -> Result<(), SceneError> {
        for (field, v) in [
            ("element_size", self.element_size),
            ("patch_size", self.patch_size),
        ] {
            if let Some(v) = v
                && !(v.is_finite() && v > 0.0)
            {
                return Err(invalid(
                    file,
                    format!("mesh.{field}: {v} must be a positive number"),
                ));
            }
        }
        if self.max_elements == Some(0) {
            return Err(invalid(file, "mesh.max_elements must be at least 1".into()));
        }
        Ok(())
    }
}

impl SolverEntry {
    /// Refuses unknown names and a negative residual, naming the field (`solver.…`).
    fn check(&self, file: &Path) -> Result<(), SceneError> {
        use crate::formfactor::FormFactorMethod;
        use crate::solver::SolverKind;
        if let Some(n) = &self.name
            && n != "auto"
            && SolverKind::parse(n, None).is_none()
        {
            return Err(invalid(
                file,
                format!(
                    "solver.name: unknown solver '{n}' (expected auto or one of: {})",
                    SolverKind::names_joined()
                ),
            ));
        }
        if let Some(f) = &self.formfactor
            && f.parse::<FormFactorMethod>().is_err()
        {
            return Err(invalid(
                file,
                format!(
                    "solver.formfactor: unknown method '{f}' (available: {})",
                    FormFactorMethod::names()
                ),
            ));
        }
        if let Some(u) = self.unshot
            && !(u.is_finite() && u >= 0.0)
        {
            return Err(invalid(
                file,
                format!("solver.unshot: {u} must be a number >= 0"),
            ));
        }
        Ok(())
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum LightEntry {
    Sky {
        radiance: [f64; 3],
    },
    Sun {
        direction: [f64; 3],
        irradiance: [f64; 3],
        #[serde(default)]
        angular_radius_deg: f64,
    },
    Point {
        position: [f64; 3],
        intensity: [f64; 3],
        /// A spot light's cone ([`super::SpotCone`]).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        spot: Option<SpotEntry>,
    },
    /// A planar convex emitter, counter-clockwise seen from the side it lights.
    Area {
        corners: Vec<[f64; 3]>,
        radiance: [f64; 3],
    },
}

/// A spot light's cone: the way it shines and its inner and outer half-angles.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpotEntry {
    pub direction: [f64; 3],
    pub inner_cone_deg: f64,
    pub outer_cone_deg: f64,
}

impl SpotEntry {
    fn cone(&self, file: &Path, field: &str) -> Result<SpotCone, SceneError> {
        let direction = point(file, &format!("{field}.direction"), self.direction)?
            .try_normalize()
            .ok_or_else(|| invalid(file, format!("{field}.direction must not be zero")))?;
        let (inner, outer) = (self.inner_cone_deg, self.outer_cone_deg);
        if !((0.0..=outer).contains(&inner) && outer <= 90.0) {
            return Err(invalid(
                file,
                format!("{field}: needs 0 <= inner_cone_deg <= outer_cone_deg <= 90"),
            ));
        }
        Ok(SpotCone {
            direction,
            inner: inner.to_radians(),
            outer: outer.to_radians(),
        })
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraEntry {
    pub eye: [f64; 3],
    pub target: [f64; 3],
    pub vfov_deg: f64,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialEntry {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kd: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ke: Option<[f64; 3]>,
}

/// Whether `path` names a scene file rather than a model.
pub fn is_scene_file(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
}

fn invalid(file: &Path, message: String) -> SceneError {
    SceneError::Invalid {
        file: file.display().to_string(),
        message,
    }
}

fn colour(file: &Path, field: &str, c: [f64; 3]) -> Result<Rgb, SceneError> {
    let c = Rgb::from_array(c);
    if !c.is_finite() || c.min_element() < 0.0 {
        return Err(invalid(
            file,
            format!("{field}: {c} must be finite and non-negative"),
        ));
    }
    Ok(c)
}

fn point(file: &Path, field: &str, p: [f64; 3]) -> Result<DVec3, SceneError> {
    let p = DVec3::from_array(p);
    if !p.is_finite() {
        return Err(invalid(file, format!("{field}: {p} must be finite")));
    }
    Ok(p)
}

impl LightEntry {
    /// Installs the light in `scene` (an area light as an emitting face).
    fn apply(&self, file: &Path, field: &str, scene: &mut Scene) -> Result<(), SceneError> {
        let light = match *self {
            LightEntry::Sky { radiance } => Light::Sky {
                radiance: colour(file, &format!("{field}.radiance"), radiance)?,
            },
            LightEntry::Sun {
                direction,
                irradiance,
                angular_radius_deg,
            } => Light::Sun {
                direction: point(file, &format!("{field}.direction"), direction)?
                    .try_normalize()
                    .ok_or_else(|| invalid(file, format!("{field}.direction must not be zero")))?,
                irradiance: colour(file, &format!("{field}.irradiance"), irradiance)?,
                angular_radius: if (0.0..=45.0).contains(&angular_radius_deg) {
                    angular_radius_deg.to_radians()
                } else {
                    return Err(invalid(
                        file,
                        format!("{field}.angular_radius_deg must be in 0..=45"),
                    ));
                },
            },
            LightEntry::Point {
                position,
                intensity,
                spot,
            } => Light::Point {
                position: point(file, &format!("{field}.position"), position)?,
                intensity: colour(file, &format!("{field}.intensity"), intensity)?,
                cone: match spot {
                    Some(s) => Some(s.cone(file, &format!("{field}.spot"))?),
                    None => None,
                },
            },
            LightEntry::Area {
                ref corners,
                radiance,
            } => {
                let corners = corners
                    .iter()
                    .map(|c| point(file, &format!("{field}.corners"), *c))
                    .collect::<Result<Vec<_>, _>>()?;
                if corners.len() < 3 || crate::geometry::polygon::normal(&corners).is_none() {
                    return Err(invalid(
                        file,
                        format!("{field}.corners must be 3 or more points of a non-zero area"),
                    ));
                }
                let radiance = colour(file, &format!("{field}.radiance"), radiance)?;
                scene.add_area_light(corners, radiance);
                return Ok(());
            }
        };
        scene.lights.push(light);
        Ok(())
    }
}

impl SceneFile {
    /// Reads and checks a scene file (JSON errors name the line and column; bad mesh and
    /// solver settings name their field).
    pub fn read(path: &Path) -> Result<SceneFile, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let file: SceneFile = serde_json::from_str(&text).map_err(|e| SceneError::Parse {
            file: path.display().to_string(),
            line: e.line(),
            message: e.to_string(),
        })?;
        if let Some(m) = &file.mesh {
            m.check(path)?;
        }
        if let Some(s) = &file.solver {
            s.check(path)?;
        }
        Ok(file)
    }

    /// The scene it describes: the model loaded, then the edits and lights applied.
    pub fn load(&self, path: &Path) -> Result<Scene, SceneError> {
        let opts = LoadOptions {
            two_sided: self.two_sided,
            ..Default::default()
        };
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut scene = match (&self.model, &self.builtin) {
            (Some(m), None) => Scene::load(&dir.join(m), &opts)?,
            (None, Some(b)) => Scene::builtin(b, &opts)?,
            _ => {
                return Err(invalid(
                    path,
                    "give exactly one of \"model\" (an OBJ or glTF path) and \"builtin\"".into(),
                ));
            }
        };
        if self.replaces_model_lights {
            scene.lights.clear();
        }
        for (name, edit) in &self.materials {
            let field = format!("materials.{name}");
            let Some(m) = scene.materials.iter_mut().find(|m| &m.name == name) else {
                return Err(invalid(
                    path,
                    format!("{field}: the model has no such material"),
                ));
            };
            if let Some(kd) = edit.kd {
                let kd = colour(path, &format!("{field}.kd"), kd)?;
                m.reflectance = kd.min(Rgb::splat(super::MAX_REFLECTANCE));
            }
            if let Some(ke) = edit.ke {
                m.emission = colour(path, &format!("{field}.ke"), ke)?;
            }
        }
        for (k, l) in self.lights.iter().enumerate() {
            l.apply(path, &format!("lights[{k}]"), &mut scene)?;
        }
        if let Some(c) = self.camera {
            let camera = Camera {
                eye: point(path, "camera.eye", c.eye)?,
                target: point(path, "camera.target", c.target)?,
                vfov_deg: c.vfov_deg,
            };
            if !(c.vfov_deg > 0.0 && c.vfov_deg < 180.0) || camera.basis().is_none() {
                return Err(invalid(
                    path,
                    "camera: needs eye ≠ target and 0 < vfov_deg < 180".into(),
                ));
            }
            scene.camera = Some(camera);
        }
        Ok(scene)
    }

    /// What `scene` (as loaded from its source, then edited) is, for a scene file at
    /// `path`: the model relative to it, the lights, the camera and every material's Kd/Ke.
    pub fn describe(scene: &Scene, camera: Option<Camera>, path: &Path) -> SceneFile {
        let (model, builtin) = match &scene.source {
            Some(src) => (Some(relative_to(src, path)), None),
            None => (None, Some(scene.name.clone())),
        };
        let mut lights: Vec<LightEntry> = scene.lights.iter().map(LightEntry::from).collect();
        lights.extend(scene.area_lights().into_iter().map(|a| LightEntry::Area {
            corners: a.corners.iter().map(|v| v.to_array()).collect(),
            radiance: a.radiance.to_array(),
        }));
        let materials = scene
            .materials
            .iter()
            .filter(|m| !m.name.starts_with("area light"))
            .map(|m| {
                let entry = MaterialEntry {
                    kd: Some(m.reflectance.to_array()),
                    ke: Some(m.emission.to_array()),
                };
                (m.name.clone(), entry)
            })
            .collect();
        SceneFile {
            replaces_model_lights: scene.source.as_deref().is_some_and(super::is_gltf_file),
            model,
            builtin,
            two_sided: scene.two_sided,
            lights,
            camera: camera.or(scene.camera).map(|c| CameraEntry {
                eye: c.eye.to_array(),
                target: c.target.to_array(),
                vfov_deg: c.vfov_deg,
            }),
            materials,
            mesh: None,
            solver: None,
        }
    }

    /// Writes the file atomically (a temporary file beside it, then a rename).
    pub fn save(&self, path: &Path) -> Result<(), SceneError> {
        let text = serde_json::to_string_pretty(self).map_err(|e| invalid(path, e.to_string()))?;
        let tmp = path.with_extension("json.tmp");
        let io = |source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        };
        std::fs::write(&tmp, text + "\n").map_err(io)?;
        std::fs::rename(&tmp, path).map_err(io)
    }
}

impl From<&Light> for LightEntry {
    fn from(l: &Light) -> Self {
        match *l {
            Light::Sky { radiance } => LightEntry::Sky {
                radiance: radiance.to_array(),
            },
            Light::Sun {
                direction,
                irradiance,
                angular_radius,
            } => LightEntry::Sun {
                direction: direction.to_array(),
                irradiance: irradiance.to_array(),
                angular_radius_deg: angular_radius.to_degrees(),
            },
            Light::Point {
                position,
                intensity,
                cone,
            } => LightEntry::Point {
                position: position.to_array(),
                intensity: intensity.to_array(),
                spot: cone.map(|c| SpotEntry {
                    direction: c.direction.to_array(),
                    inner_cone_deg: c.inner.to_degrees(),
                    outer_cone_deg: c.outer.to_degrees(),
                }),
            },
        }
    }
}

/// `target` relative to the folder of `file` where both are in one tree, else absolute.
fn relative_to(target: &Path, file: &Path) -> String {
    let abs = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    let target = abs(target);
    let dir = abs(file.parent().unwrap_or(Path::new(".")));
    let (t, d): (Vec<_>, Vec<_>) = (target.components().collect(), dir.components().collect());
    let common = t.iter().zip(&d).take_while(|(a, b)| a == b).count();
    if common == 0 {
        return target.display().to_string();
    }
    let mut rel = PathBuf::new();
    for _ in common..d.len() {
        rel.push("..");
    }
    for c in &t[common..] {
        rel.push(c);
    }
    rel.display().to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("nusselt-scenefile-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    #[test]
    fn a_scene_round_trips_through_its_file() {
        let mut scene = Scene::builtin("cornell", &LoadOptions::default()).unwrap();
        scene
            .lights
            .push(Light::parse_sun("1,2,3,4,5,6,0.5").unwrap());
        scene
            .lights
            .push(Light::parse_point("1,2,3,7,8,9").unwrap());
        let corners = vec![
            DVec3::new(0.0, 500.0, 0.0),
            DVec3::new(100.0, 500.0, 0.0),
            DVec3::new(100.0, 500.0, 100.0),
        ];
        scene.add_area_light(corners.clone(), Rgb::splat(5.0));
        scene.materials[0].reflectance = Rgb::new(0.1, 0.2, 0.3);
        let path = temp("round.json");
        SceneFile::describe(&scene, None, &path)
            .save(&path)
            .unwrap();
        let back = SceneFile::read(&path).unwrap().load(&path).unwrap();
        assert_eq!(back.lights.len(), 2);
        for (a, b) in back.lights.iter().zip(&scene.lights) {
            assert_eq!(LightEntry::from(a), LightEntry::from(b));
        }
        assert_eq!(back.materials[0].reflectance, Rgb::new(0.1, 0.2, 0.3));
        assert_eq!(back.faces.last().unwrap().vertices, corners);
        assert_eq!(back.camera, scene.camera);
        assert_eq!(back.faces.len(), scene.faces.len());
    }

    #[test]
    fn bad_fields_are_named_with_their_line() {
        let path = temp("bad.json");
        std::fs::write(&path, "{\n \"builtin\": \"cornell\",\n \"lihgts\": []\n}").unwrap();
        let e = SceneFile::read(&path).unwrap_err().to_string();
        assert!(e.contains("bad.json:3") && e.contains("lihgts"), "{e}");
        // Well-formed files whose values the loader refuses.
        let refused = |text: &str| {
            std::fs::write(&path, text).unwrap();
            let file = SceneFile::read(&path).unwrap();
            file.load(&path).unwrap_err().to_string()
        };
        let e = refused(
            "{\"builtin\": \"cornell\", \"lights\": [{\"type\": \"sun\", \"direction\": [0,0,0], \"irradiance\": [1,1,1]}]}",
        );
        assert!(e.contains("lights[0].direction"), "{e}");
        let e = refused("{\"builtin\": \"cornell\", \"materials\": {\"nope\": {}}}");
        assert!(e.contains("materials.nope"), "{e}");
    }

    /// Mesh and solver settings are written and read back as they were.
    #[test]
    fn mesh_and_solver_settings_round_trip() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).unwrap();
        let path = temp("settings.json");
        let mut file = SceneFile::describe(&scene, None, &path);
        file.mesh = Some(MeshEntry {
            element_size: Some(25.0),
            patch_size: Some(100.0),
            max_elements: Some(5000),
            discontinuity: true,
        });
        file.solver = Some(SolverEntry {
            name: Some("gauss-seidel".into()),
            formfactor: Some("hemicube".into()),
            unshot: Some(1e-3),
        });
        file.save(&path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("\"element_size\": 25.0"), "{text}");
        assert_eq!(SceneFile::read(&path).unwrap(), file);
    }

    /// A bad setting is named by its path in the JSON; a misspelt one is refused with its
    /// line.
    #[test]
    fn bad_settings_are_named_by_their_path() {
        let path = temp("bad_settings.json");
        let refused = |text: &str| {
            std::fs::write(&path, text).unwrap();
            SceneFile::read(&path).unwrap_err().to_string()
        };
        for (text, field) in [
            ("\"mesh\": {\"element_size\": -2}", "mesh.element_size"),
            ("\"mesh\": {\"patch_size\": 0}", "mesh.patch_size"),
            ("\"mesh\": {\"max_elements\": 0}", "mesh.max_elements"),
            ("\"solver\": {\"name\": \"newton\"}", "solver.name"),
            (
                "\"solver\": {\"formfactor\": \"magic\"}",
                "solver.formfactor",
            ),
            ("\"solver\": {\"unshot\": -1}", "solver.unshot"),
        ] {
            let e = refused(&format!("{{\"builtin\": \"cornell\", {text}}}"));
            assert!(e.contains(field) && e.contains("bad_settings.json"), "{e}");
        }
        let e = refused("{\"builtin\": \"cornell\",\n \"mesh\": {\"elemnt_size\": 2}}");
        assert!(
            e.contains("bad_settings.json:2") && e.contains("elemnt_size"),
            "{e}"
        );
    }
}
