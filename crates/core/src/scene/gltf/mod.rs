//! glTF 2.0 import (`.gltf` with external or `data:` buffers and images, and `.glb`), so
//! that a model from Blender, a game engine or the Khronos samples opens like an OBJ.
//!
//! What is read, and what it becomes (see the submodules for the details):
//! - geometry (`mesh.rs`): every node of the default scene (else the first) that has a mesh,
//!   with its world transform composed down the tree; the triangles of `TRIANGLES`,
//!   `TRIANGLE_STRIP` and `TRIANGLE_FAN` primitives, indexed or not, each one face. A node
//!   whose transform mirrors (negative determinant) has its winding reversed, so the front
//!   stays the side glTF renders as front. Points and lines are skipped with a warning naming
//!   the mesh and primitive; a file with no triangle left is an error. Units: metres, as
//!   glTF says, taken as they are.
//! - materials ([`materials`]): base colour factor × texture as the reflectance and diffuse
//!   map, `TEXCOORD_n` as the faces' texture coordinates with `v` flipped (glTF's `v` = 0 is
//!   the image's top row, [`crate::scene::Texture::sample`]'s the bottom), alpha modes as
//!   cut-outs, transmission as glass, emissive factor × strength (× the emissive texture's
//!   mean) as the emitted radiance.
//! - lights and camera ([`lights`]): `KHR_lights_punctual` with Blender's photometric
//!   conversion (cd / 683 = W/sr, lux / 683 = W/m²), spots as point lights with a
//!   [`crate::scene::SpotCone`]; the first perspective camera.
//! - sides: glTF faces are one-sided unless their material is `doubleSided`. When every
//!   material in use is double-sided (what Blender writes by default) the scene is loaded
//!   two-sided; when only some are, each face of a double-sided material gets a back-facing
//!   copy (reversed winding, its own source face) so that both its sides take part, and the
//!   others stay one-sided. [`super::LoadOptions::two_sided`] makes the whole scene two-sided.
//!
//! Not read: normals and tangents (faces are flat), normal, occlusion and metallic-roughness
//! maps, `KHR_texture_transform`, vertex colours, skins, morph targets, animations, sparse
//! accessors (an error), orthographic cameras.
//!
//! Errors: a file that cannot be parsed, a missing or short buffer, a buffer view outside its
//! buffer, an accessor of the wrong type, too short for its count or whose count differs from
//! POSITION's, an index out of range, or a position that is not finite is a
//! [`SceneError::Invalid`] naming the file and the JSON path (`meshes[2].primitives[0].
//! attributes.POSITION`); nothing panics (the parser and image decoders run under
//! `catch_unwind` as a second net). A texture that cannot be read is a warning.

mod data;
pub mod lights;
pub mod materials;
mod mesh;

use std::path::Path;

use super::{Face, LoadOptions, Scene, SceneError};

pub use lights::LUMENS_PER_WATT;

/// An error in `file` at JSON path `at` (none for the whole file).
fn invalid(file: &str, at: &str, message: impl std::fmt::Display) -> SceneError {
    SceneError::Invalid {
        file: file.to_string(),
        message: if at.is_empty() {
            message.to_string()
        } else {
            format!("{at}: {message}")
        },
    }
}

/// Loads a `.gltf` or `.glb` file (see the module docs).
pub fn load(path: &Path, opts: &LoadOptions) -> Result<Scene, SceneError> {
    let src = data::read(path)?;
    let mut scene = guarded(&src, opts)?;
    scene.name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    scene.source = Some(path.to_path_buf());
    Ok(scene)
}

/// Loads glTF or GLB bytes held in memory (`name` for messages; external files are looked
/// up in `dir`). For tests and tools that build a file on the fly.
pub fn from_slice(
    bytes: &[u8],
    name: &str,
    dir: &Path,
    opts: &LoadOptions,
) -> Result<Scene, SceneError> {
    let src = data::parse(bytes, name.to_string(), dir.to_path_buf())?;
    let mut scene = guarded(&src, opts)?;
    scene.name = name.to_string();
    Ok(scene)
}

/// [`build`], a panic inside the `gltf` crate's readers (on input its validation and the
/// checks here let through) turned into an error.
fn guarded(src: &data::Source, opts: &LoadOptions) -> Result<Scene, SceneError> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| build(src, opts))).unwrap_or_else(
        |_| {
            Err(invalid(
                &src.file,
                "",
                "the glTF reader failed on this file (malformed input)",
            ))
        },
    )
}

fn build(src: &data::Source, opts: &LoadOptions) -> Result<Scene, SceneError> {
    let mut warnings = Vec::new();
    let instances = mesh::instances(src)?;
    let mut materials = materials::Materials::build(src, &mut warnings);
    let mut stats = mesh::MeshStats::default();
    let uv_sets = materials.uv_set.clone();
    let mut faces = mesh::faces(
        src,
        &instances,
        &mut |i| materials.of(i),
        &|m| uv_sets.get(m.0 as usize).copied().flatten(),
        &mut stats,
    )?;
    warnings.extend(stats.skipped.iter().map(|s| format!("{}: {s}", src.file)));
    if stats.dropped > 0 {
        warnings.push(format!(
            "{}: dropped {} zero-area triangle(s)",
            src.file, stats.dropped
        ));
    }
    if faces.is_empty() {
        return Err(invalid(
            &src.file,
            "",
            "no triangles: the scene has no mesh with a triangle primitive of non-zero area",
        ));
    }
    let two_sided = opts.two_sided || sides(&mut faces, &materials.double_sided);
    let lights = lights::lights(src, &instances, &mut warnings);
    let camera = lights::camera(src, &instances, &mut warnings);
    let texture_bytes = materials.textures.iter().map(|t| t.bytes()).sum();
    Ok(Scene {
        name: String::new(),
        faces,
        materials: materials.list,
        two_sided,
        camera,
        warnings,
        source: None,
        lights,
        textures: materials.textures,
        texture_bytes,
    })
}

/// Whether the scene is two-sided: every face's material is double-sided. Otherwise the
/// faces of double-sided materials get back-facing copies (see the module docs).
fn sides(faces: &mut Vec<Face>, double_sided: &[bool]) -> bool {
    let ds = |f: &Face| {
        double_sided
            .get(f.material.0 as usize)
            .copied()
            .unwrap_or(false)
    };
    if faces.iter().all(ds) {
        return true;
    }
    let mut next = faces.len();
    let backs: Vec<Face> = faces
        .iter()
        .filter(|f| ds(f))
        .map(|f| {
            next += 1;
            Face {
                vertices: f.vertices.iter().rev().copied().collect(),
                uvs: f.uvs.as_ref().map(|uv| uv.iter().rev().copied().collect()),
                source_face: next - 1,
                ..f.clone()
            }
        })
        .collect();
    faces.extend(backs);
    false
}
