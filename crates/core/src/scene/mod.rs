//! Scene description: planar polygons with Lambertian materials, read from OBJ/MTL or glTF 2.0
//! ([`gltf`]; [`Scene::load`] picks the reader by the file's extension).
//!
//! Units: `Kd` is RGB reflectance in [0, 1); `Ke` is RGB emitted radiance
//! (W·m⁻²·sr⁻¹ per channel). Radiosity is solved in radiance units, `L = Ke + ρ Σ F L`, so a
//! solution can be compared pixel by pixel with a path tracer given the same `Ke` and `Kd`.
//! A face reflects and emits on its front side, the side from which its vertices run
//! counter-clockwise, unless the scene is loaded two-sided.
//!
//! Textures: a material's `map_Kd` colour multiplies its `Kd` (so `Kd 1 1 1` under a map,
//! which many exporters write, reflects the map's colour times [`CLAMPED_REFLECTANCE`]; a
//! textured material without `Kd` does the same), and `map_d` (else the colour map's alpha)
//! tells where it is opaque: alpha ≥ 0.5, the rest a cut-out. Maps are read only by [`Scene::load_obj`] ([`texture`] for the texels, their
//! means over patches and their error); a map that cannot be found or read is a warning
//! and the material keeps its `Kd`.
//!
//! Loading never panics and never half-loads: the OBJ and MTL text are checked line by line
//! first (errors name `file:line`), then parsed by `tobj`, then the geometry is checked.

mod area_lights;
mod camera;
pub mod cutouts;
mod default_lights;
pub mod file;
pub mod gallery;
pub mod gltf;
pub mod lights;
mod maps;
mod obj_scan;
mod specular;
pub mod texture;
#[cfg(test)]
mod texture_tests;
mod texturing;
mod validate;

pub use area_lights::{AreaLight, AreaLightError, square_corners};
pub use camera::Camera;
pub use default_lights::{DEFAULT_LIGHTS_HINT, DEFAULT_SKY, DEFAULT_SUN, default_sun_direction};
pub use file::{SceneFile, is_scene_file};
pub use lights::{Light, LightError, SpotCone};
pub use maps::{UvTransform, resolve_texture_path};
pub use texture::{Texture, TextureId};
pub use texturing::TextureMean;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DVec2, DVec3};

use crate::geometry::polygon;

/// RGB triple in linear units.
pub type Rgb = DVec3;

/// Largest reflectance accepted; a `Kd` channel between it and 1 is lowered to it.
pub const MAX_REFLECTANCE: f64 = 0.999;

/// What a `Kd` channel of 1 or more becomes. Such a surface would reflect all the light it
/// receives or more, so a closed scene's radiosity never converges; and `Kd 1 1 1` is what
/// many exporters write under a texture map, whose colour then multiplies it. 0.95 is about
/// the brightest real diffuse white (fresh snow, a white reflectance standard), so the
/// texture keeps nearly its authored brightness and the solve converges. Values below 1
/// are kept (up to [`MAX_REFLECTANCE`]), so a furnace at ρ = 0.99 still works.
pub const CLAMPED_REFLECTANCE: f64 = 0.95;

/// A `Kd` channel as the solver uses it: [`CLAMPED_REFLECTANCE`] from 1 up, else at most
/// [`MAX_REFLECTANCE`], and not negative.
pub fn clamp_reflectance(kd: f64) -> f64 {
    if kd >= 1.0 {
        CLAMPED_REFLECTANCE
    } else {
        kd.clamp(0.0, MAX_REFLECTANCE)
    }
}

/// `Ns` from which a mirror (`illum` 3 or 5) is perfect: the top of the MTL range (0–1000),
/// what Blender writes for roughness 0.
pub const MIRROR_EXPONENT: f64 = 1000.0;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct MaterialId(pub u32);

/// A material's specular part, on top of its diffuse `reflectance` (MTL `illum`, `Ks`, `Ni`,
/// `d`/`Tr`). The radiosity solve ignores it (a specular surface takes part with its `Kd`
/// only); the eye pass ([`crate::render::specular`]) and the path tracer follow it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Surface {
    /// Lambertian only (every material of an MTL without `illum` 3–7 or `d` < 1).
    #[default]
    Diffuse,
    /// A perfect mirror (`illum` 3 or 5 without `Ns`, or `Ns` ≥ [`MIRROR_EXPONENT`])
    /// reflecting `Ks` per channel; `Kd + Ks` ≤ 1.
    Mirror { ks: Rgb },
    /// A glossy mirror (`illum` 3 or 5 with `Ns` below [`MIRROR_EXPONENT`]): a mirror
    /// blurred by the Phong lobe, reflecting `Ks` of the light from directions around the
    /// mirror direction, spread with density `(n + 1)/(2π) cosⁿα`, n = `Ns` (the glossy
    /// reflection of Cook, Porter & Carpenter 1984); `Kd + Ks` ≤ 1.
    Glossy { ks: Rgb, exponent: f64 },
    /// A smooth dielectric (`illum` 4, 6 or 7, or `d` < 1 / `Tr` > 0) of refractive index
    /// `ior` (`Ni`, default 1.5): Fresnel reflection and refraction, no absorption.
    Glass { ior: f64 },
}

#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    /// RGB reflectance ρ, each channel in [0, 0.999] ([`clamp_reflectance`] of `Kd`); a
    /// diffuse map's colour multiplies it.
    pub reflectance: Rgb,
    /// RGB emitted radiance.
    pub emission: Rgb,
    /// The specular part, if any.
    pub surface: Surface,
    /// The diffuse map (`map_Kd`), if one loaded.
    pub diffuse_map: Option<TextureId>,
    /// The alpha map (`map_d`), if one loaded.
    pub alpha_map: Option<TextureId>,
    /// The diffuse map's `-s`/`-o` transform of the faces' texture coordinates.
    pub diffuse_uv: UvTransform,
    /// The alpha map's `-s`/`-o` transform of the faces' texture coordinates.
    pub alpha_uv: UvTransform,
}

impl Material {
    pub fn is_emitter(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    /// Whether light leaves the surface in a mirror or refracted direction.
    pub fn is_specular(&self) -> bool {
        self.surface != Surface::Diffuse
    }
}

/// One input polygon, counter-clockwise seen from its front.
#[derive(Clone, Debug)]
pub struct Face {
    pub vertices: Vec<DVec3>,
    pub material: MaterialId,
    /// Index of the input face in file order (faces split by loading share it).
    pub source_face: usize,
    /// 1-based line in the OBJ file, 0 for generated faces and those of a glTF file.
    pub line: usize,
    /// The OBJ `vt` texture coordinates of each vertex, when every vertex of the face has one.
    pub uvs: Option<Vec<DVec2>>,
}

#[derive(Clone, Debug)]
pub struct Scene {
    pub name: String,
    pub faces: Vec<Face>,
    pub materials: Vec<Material>,
    /// Every face reflects and emits on both sides.
    pub two_sided: bool,
    /// The scene's own camera (the published one for the Cornell box).
    pub camera: Option<Camera>,
    /// Non-fatal problems found while loading (clamped values, dropped faces, …).
    pub warnings: Vec<String>,
    /// The model file (OBJ or glTF) this came from, if any.
    pub source: Option<PathBuf>,
    /// Light sources that are not faces: sky, suns, point lights ([`lights`]).
    pub lights: Vec<Light>,
    /// The texture maps materials refer to ([`TextureId`] indexes them); read only by
    /// [`Scene::load_obj`] and [`Scene::load_gltf`], each distinct image once.
    pub textures: Vec<Arc<Texture>>,
    /// Memory held by `textures`, in bytes.
    pub texture_bytes: usize,
}

#[derive(Clone, Debug, Default)]
pub struct LoadOptions {
    pub two_sided: bool,
    /// Uniform reflectance for the `furnace` scene (default 0.9).
    pub rho: Option<f64>,
}

#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("cannot read {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}:{line}: {message}")]
    Parse {
        file: String,
        line: usize,
        message: String,
    },
    #[error("{file}: {message}")]
    Invalid { file: String, message: String },
    #[error(
        "unknown built-in scene '{0}' (available: cornell, furnace, cube, tworooms, gallery, cornell-specular, cornell-glossy)"
    )]
    UnknownBuiltin(String),
    #[error("bad camera {0}")]
    Camera(String),
}

const CORNELL_OBJ: &str = include_str!("../../../../assets/cornell.obj");
const CORNELL_MTL: &str = include_str!("../../../../assets/cornell.mtl");
const FURNACE_OBJ: &str = include_str!("../../../../assets/furnace.obj");
const FURNACE_MTL: &str = include_str!("../../../../assets/furnace.mtl");
const CUBE_OBJ: &str = include_str!("../../../../assets/cube.obj");
const TWOROOMS_OBJ: &str = include_str!("../../../../assets/tworooms.obj");
const TWOROOMS_MTL: &str = include_str!("../../../../assets/tworooms.mtl");
const CORNELL_SPECULAR_OBJ: &str = include_str!("../../../../assets/cornell-specular.obj");
const CORNELL_SPECULAR_MTL: &str = include_str!("../../../../assets/cornell-specular.mtl");
const CORNELL_GLOSSY_MTL: &str = include_str!("../../../../assets/cornell-glossy.mtl");

/// Names of the built-in scenes.
pub const BUILTINS: &[&str] = &[
    "cornell",
    "furnace",
    "cube",
    "tworooms",
    "gallery",
    "cornell-specular",
    "cornell-glossy",
];

/// The model file extensions [`Scene::load`] reads.
pub const MODEL_EXTENSIONS: &[&str] = &["obj", "gltf", "glb"];

fn has_extension(path: &Path, names: &[&str]) -> bool {
    path.extension()
        .is_some_and(|e| names.iter().any(|n| e.eq_ignore_ascii_case(n)))
}

/// Whether `path` names a glTF file (`.gltf` or `.glb`).
pub fn is_gltf_file(path: &Path) -> bool {
    has_extension(path, &["gltf", "glb"])
}

/// Whether `path` names a model [`Scene::load`] reads (see [`MODEL_EXTENSIONS`]).
pub fn is_model_file(path: &Path) -> bool {
    has_extension(path, MODEL_EXTENSIONS)
}

impl Scene {
    /// Loads a model by its extension: `.obj` ([`Scene::load_obj`]), `.gltf` or `.glb`
    /// ([`Scene::load_gltf`]); any other is an error naming what is accepted.
    pub fn load(path: &Path, opts: &LoadOptions) -> Result<Scene, SceneError> {
        if has_extension(path, &["obj"]) {
            Scene::load_obj(path, opts)
        } else if is_gltf_file(path) {
            Scene::load_gltf(path, opts)
        } else {
            Err(SceneError::Invalid {
                file: path.display().to_string(),
                message: "not a model Nusselt reads: give a Wavefront .obj (with its .mtl), \
                          a glTF 2.0 .gltf or .glb, or a .json scene file"
                    .into(),
            })
        }
    }

    /// Loads a glTF 2.0 file, `.gltf` (JSON with external or embedded buffers and images) or
    /// `.glb` (binary); see [`gltf`] for what is read and how.
    pub fn load_gltf(path: &Path, opts: &LoadOptions) -> Result<Scene, SceneError> {
        gltf::load(path, opts)
    }

    /// Loads an OBJ file and the MTL files it names (relative to the OBJ's folder).
    pub fn load_obj(path: &Path, opts: &LoadOptions) -> Result<Scene, SceneError> {
        let text = std::fs::read(path).map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let text = String::from_utf8(text).map_err(|_| SceneError::Invalid {
            file: path.display().to_string(),
            message: "not a text file (invalid UTF-8)".into(),
        })?;
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "scene".into());
        let (mut scene, requests, preloaded) = validate::load(
            &path.display().to_string(),
            &text,
            &mut |mtl| {
                let p = dir.join(mtl);
                match std::fs::read_to_string(&p) {
                    Ok(t) => Ok((p.display().to_string(), t)),
                    Err(source) => Err(SceneError::Io { path: p, source }),
                }
            },
            opts,
            |ahead| maps::preload(&ahead),
        )?;
        scene.name = name;
        scene.source = Some(path.to_path_buf());
        scene.attach_maps(&requests, preloaded);
        Ok(scene)
    }

    /// Reads the requested texture maps and points the materials at them.
    fn attach_maps(&mut self, requests: &[maps::MapRequest], preloaded: maps::Preloaded) {
        let loaded = maps::load_maps(requests, preloaded);
        for (r, id) in requests.iter().zip(&loaded.assigned) {
            let m = &mut self.materials[r.material];
            match r.slot {
                maps::Slot::Diffuse => m.diffuse_map = *id,
                maps::Slot::Alpha => m.alpha_map = *id,
            }
        }
        self.texture_bytes = loaded.textures.iter().map(|t| t.bytes()).sum();
        self.textures = loaded.textures;
        self.warnings.extend(loaded.warnings);
    }

    /// Loads OBJ text with an in-memory MTL library (`mtllib` names are looked up in it).
    pub fn from_obj_str(
        name: &str,
        obj: &str,
        mtls: &[(&str, &str)],
        opts: &LoadOptions,
    ) -> Result<Scene, SceneError> {
        let (mut scene, requests, ()) = validate::load(
            name,
            obj,
            &mut |mtl| {
                mtls.iter()
                    .find(|(n, _)| *n == mtl)
                    .map(|(n, t)| (n.to_string(), t.to_string()))
                    .ok_or_else(|| SceneError::Invalid {
                        file: name.to_string(),
                        message: format!("material library '{mtl}' not found"),
                    })
            },
            opts,
            |_| (),
        )?;
        scene.name = name.to_string();
        if let Some(r) = requests.first() {
            scene.warnings.push(format!(
                "{}:{}: {} texture map(s) not read: an in-memory scene has no folder to find them in (load the file to use them)",
                r.mtl_file,
                r.line,
                requests.len()
            ));
        }
        Ok(scene)
    }

    /// A built-in Cornell box variant: the OBJ and the MTL library it names, each (file
    /// name, text), seen from the published camera.
    fn cornell_box(
        name: &str,
        obj: (&str, &str),
        mtl: (&str, &str),
        opts: &LoadOptions,
    ) -> Result<Scene, SceneError> {
        let mut s = Scene::from_obj_str(obj.0, obj.1, &[mtl], opts)?;
        s.name = name.into();
        s.camera = Some(Camera::cornell());
        Ok(s)
    }

    /// A built-in scene by name: `cornell`, `furnace` (every face emits 1 and reflects
    /// `opts.rho`, default 0.9) or `cube` (12 triangles, the ceiling emits 1, every face
    /// reflects `opts.rho`, default 0.5) or `tworooms` (two rooms joined by a door left ajar,
    /// the light in the left one; `scripts/tworooms.py`) or `gallery` (a furnished room with a
    /// 100,500-triangle statue, generated by [`gallery`]) or `cornell-specular` (the Cornell
    /// box with a mirror tall block and a glass short block) or `cornell-glossy` (the same
    /// with the tall block a glossy metal, `Ns` 60).
    pub fn builtin(name: &str, opts: &LoadOptions) -> Result<Scene, SceneError> {
        match name {
            "cornell" => Self::cornell_box(
                name,
                ("cornell.obj", CORNELL_OBJ),
                ("cornell.mtl", CORNELL_MTL),
                opts,
            ),
            "cornell-specular" => Self::cornell_box(
                name,
                ("cornell-specular.obj", CORNELL_SPECULAR_OBJ),
                ("cornell-specular.mtl", CORNELL_SPECULAR_MTL),
                opts,
            ),
            // The mirror scene's geometry; its OBJ names the library cornell-specular.mtl.
            "cornell-glossy" => Self::cornell_box(
                name,
                ("cornell-specular.obj", CORNELL_SPECULAR_OBJ),
                ("cornell-specular.mtl", CORNELL_GLOSSY_MTL),
                opts,
            ),
            "furnace" => {
                let rho = opts.rho.unwrap_or(0.9);
                if !rho.is_finite() || rho < 0.0 {
                    return Err(SceneError::Invalid {
                        file: "furnace".into(),
                        message: format!("--rho must be a finite number >= 0, got {rho}"),
                    });
                }
                let mtl = format!("newmtl wall\nKd {rho} {rho} {rho}\nKe 1 1 1\n");
                let mut s = Scene::from_obj_str(
                    "furnace.obj",
                    FURNACE_OBJ,
                    &[("furnace.mtl", &mtl)],
                    opts,
                )?;
                let _ = FURNACE_MTL;
                s.name = "furnace".into();
                s.camera = Some(Camera {
                    eye: DVec3::new(0.5, 0.5, 0.98),
                    target: DVec3::new(0.5, 0.5, 0.0),
                    vfov_deg: 70.0,
                });
                Ok(s)
            }
            "cube" => {
                let rho = opts.rho.unwrap_or(0.5);
                if !rho.is_finite() || rho < 0.0 {
                    return Err(SceneError::Invalid {
                        file: "cube".into(),
                        message: format!("--rho must be a finite number >= 0, got {rho}"),
                    });
                }
                let mtl = format!(
                    "newmtl wall\nKd {rho} {rho} {rho}\nnewmtl light\nKd {rho} {rho} {rho}\nKe 1 1 1\n"
                );
                let mut s = Scene::from_obj_str("cube.obj", CUBE_OBJ, &[("cube.mtl", &mtl)], opts)?;
                s.name = "cube".into();
                s.camera = Some(Camera {
                    eye: DVec3::new(0.5, 0.5, 0.98),
                    target: DVec3::new(0.5, 0.5, 0.0),
                    vfov_deg: 70.0,
                });
                Ok(s)
            }
            "tworooms" => {
                let mut s = Scene::from_obj_str(
                    "tworooms.obj",
                    TWOROOMS_OBJ,
                    &[("tworooms.mtl", TWOROOMS_MTL)],
                    opts,
                )?;
                s.name = "tworooms".into();
                // In the unlit room, facing the gap.
                s.camera = Some(Camera {
                    eye: DVec3::new(7.9, 1.4, 3.6),
                    target: DVec3::new(4.1, 1.0, 1.3),
                    vfov_deg: 70.0,
                });
                Ok(s)
            }
            "gallery" => {
                let obj = gallery::obj();
                let mut s = Scene::from_obj_str(
                    "gallery.obj",
                    &obj,
                    &[("gallery.mtl", gallery::MTL)],
                    opts,
                )?;
                s.name = "gallery".into();
                s.camera = Some(Camera {
                    eye: DVec3::new(3.0, 1.7, 4.9),
                    target: DVec3::new(3.2, 1.0, 1.5),
                    vfov_deg: 70.0,
                });
                Ok(s)
            }
            other => Err(SceneError::UnknownBuiltin(other.to_string())),
        }
    }

    /// Whether any material has a specular part (the eye pass then follows it).
    pub fn has_specular(&self) -> bool {
        self.materials.iter().any(Material::is_specular)
    }

    /// Axis-aligned bounds of all faces.
    pub fn bounds(&self) -> crate::geometry::Aabb {
        crate::geometry::Aabb::from_points(self.faces.iter().flat_map(|f| f.vertices.iter()))
    }

    /// Whether anything gives light: an emitting face or a light of [`Scene::lights`].
    pub fn has_light(&self) -> bool {
        self.emitted_power().max_element() > 0.0 || self.lights.iter().any(Light::is_on)
    }

    /// Adds a rectangular (or any planar convex) emitter of radiance `emission`, emitting
    /// towards the side from which `corners` run counter-clockwise, as a face of its own
    /// material (reflectance 0.5). Returns the material's index.
    pub fn add_area_light(&mut self, corners: Vec<DVec3>, emission: Rgb) -> MaterialId {
        let id = MaterialId(self.materials.len() as u32);
        let n = self
            .materials
            .iter()
            .filter(|m| m.name.starts_with("area light"))
            .count();
        self.materials.push(Material {
            name: format!("area light {}", n + 1),
            reflectance: Rgb::splat(0.5),
            emission,
            surface: Surface::Diffuse,
            diffuse_map: None,
            alpha_map: None,
            diffuse_uv: UvTransform::default(),
            alpha_uv: UvTransform::default(),
        });
        let source_face = self
            .faces
            .iter()
            .map(|f| f.source_face + 1)
            .max()
            .unwrap_or(0);
        self.faces.push(Face {
            vertices: corners,
            material: id,
            source_face,
            line: 0,
            uvs: None,
        });
        id
    }

    /// Refuses a scene that nothing lights (with `--no-default-lights`).
    pub fn check_lit(&self) -> Result<(), SceneError> {
        if self.has_light() {
            return Ok(());
        }
        Err(SceneError::Invalid {
            file: self
                .source
                .as_ref()
                .map(|p| p.display().to_string())
                .unwrap_or_else(|| self.name.clone()),
            message: "no emitter: no face has a material with positive Ke and no light was \
                      given (--sky, --sun, --point), so the image would be black"
                .into(),
        })
    }

    /// Total emitted power Σ E·A (per channel, radiance units × area).
    pub fn emitted_power(&self) -> Rgb {
        self.faces
            .iter()
            .map(|f| self.materials[f.material.0 as usize].emission * polygon::area(&f.vertices))
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cornell_loads_with_inward_normals() {
        let s = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        assert_eq!(s.faces.len(), 19);
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        let light = s
            .materials
            .iter()
            .find(|m| m.name == "light")
            .expect("light");
        assert_eq!(light.emission, DVec3::new(17.0, 12.0, 4.0));
        // Walls, floor and ceiling face the room's centre; block faces face away from it.
        let room = DVec3::new(278.0, 274.0, 280.0);
        for f in &s.faces[..8] {
            let n = polygon::normal(&f.vertices).expect("normal");
            assert!(
                (room - polygon::centroid(&f.vertices)).dot(n) > 0.0,
                "face line {}",
                f.line
            );
        }
        for (range, c) in [
            (8..13, DVec3::new(186.0, 82.0, 169.0)),
            (13..18, DVec3::new(368.0, 165.0, 351.0)),
        ] {
            for f in &s.faces[range] {
                let n = polygon::normal(&f.vertices).expect("normal");
                assert!(
                    (polygon::centroid(&f.vertices) - c).dot(n) > 0.0,
                    "block face line {}",
                    f.line
                );
            }
        }
        let ln = polygon::normal(&s.faces[18].vertices).expect("light normal");
        assert!(ln.y < -0.999);
    }

    #[test]
    fn furnace_faces_point_inward() {
        let s = Scene::builtin(
            "furnace",
            &LoadOptions {
                rho: Some(0.5),
                ..Default::default()
            },
        )
        .expect("furnace");
        assert_eq!(s.faces.len(), 6);
        assert_eq!(s.materials[0].reflectance, DVec3::splat(0.5));
        for f in &s.faces {
            let n = polygon::normal(&f.vertices).expect("normal");
            assert!((DVec3::splat(0.5) - polygon::centroid(&f.vertices)).dot(n) > 0.49);
        }
    }
}
