//! Exporting a solution for other programs: the lit mesh as glTF 2.0 ([`gltf`]), with the
//! radiosity baked into per-vertex colours, so Blender, Godot, Bevy or any glTF viewer shows
//! the scene as Nusselt computed it.
//!
//! [`BakedMesh`] is what every exporter reads: triangles with per-vertex positions, normals,
//! texture coordinates, radiance and irradiance, and a material per triangle. The CLI fills
//! it from a [`crate::solver::Problem`] and its per-element radiance
//! ([`BakedMesh::from_solution`]); the viewer fills it from its snapshot. Units: radiance
//! in W·m⁻²·sr⁻¹ per channel (the solver's, README "Units and conventions"), irradiance in
//! W·m⁻² per channel (π times the mean incident radiance `H` of `B = E + ρH`); positions in
//! scene units.
//!
//! Known error: the per-vertex values are the mesh's interpolation of per-element values
//! ([`crate::mesh::Mesh::vertex_values`]), so a shadow edge is smeared over an element, as
//! in the `vertex` render pass.

mod bake;
pub mod gltf;
mod weld;

pub use gltf::{GltfFormat, GltfInput, GltfStats, write_gltf};

/// A lit triangle mesh: what an exporter writes. Every per-vertex array has one entry per
/// vertex of `positions`; `indices` holds three vertices per triangle, counter-clockwise
/// seen from the front (the side the normal points to).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BakedMesh {
    pub positions: Vec<[f32; 3]>,
    /// Unit normals.
    pub normals: Vec<[f32; 3]>,
    /// Texture coordinates in the OBJ convention (v = 0 at the image's bottom row), the
    /// material's `-s`/`-o` transform applied; `None` when nothing is textured.
    pub uvs: Option<Vec<[f32; 2]>>,
    pub indices: Vec<u32>,
    /// Material (index into the scene's materials) of each triangle.
    pub triangle_material: Vec<u32>,
    /// Displayed radiance, W·m⁻²·sr⁻¹ per channel, linear (ambient term included if shown).
    pub radiance: Vec<[f32; 3]>,
    /// Irradiance, W·m⁻² per channel: `radiance = emission + reflectance × irradiance / π`.
    pub irradiance: Vec<[f32; 3]>,
}

impl BakedMesh {
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Checks that the arrays agree in length and the indices are in range.
    pub fn check(&self) -> Result<(), ExportError> {
        let n = self.positions.len();
        let bad = |what: String| Err(ExportError::Inconsistent(what));
        for (name, len) in [
            ("normals", self.normals.len()),
            ("radiance", self.radiance.len()),
            ("irradiance", self.irradiance.len()),
        ] {
            if len != n {
                return bad(format!("{len} {name} for {n} vertices"));
            }
        }
        if let Some(uv) = &self.uvs
            && uv.len() != n
        {
            return bad(format!("{} texture coordinates for {n} vertices", uv.len()));
        }
        if !self.indices.len().is_multiple_of(3) {
            return bad(format!(
                "{} indices: not whole triangles",
                self.indices.len()
            ));
        }
        if self.triangle_material.len() != self.triangle_count() {
            return bad(format!(
                "{} triangle materials for {} triangles",
                self.triangle_material.len(),
                self.triangle_count()
            ));
        }
        if let Some(i) = self.indices.iter().find(|&&i| i as usize >= n) {
            return bad(format!("index {i} past the {n} vertices"));
        }
        Ok(())
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error("nothing to export: the mesh has no triangles")]
    Empty,
    #[error("inconsistent mesh: {0}")]
    Inconsistent(String),
    #[error("unknown export format for {0} (expected .glb or .gltf)")]
    Extension(std::path::PathBuf),
    #[error("the export is too large for glTF ({0} bytes; a buffer holds at most 4 GiB)")]
    TooLarge(usize),
    #[error("cannot encode texture {index} as PNG: {message}")]
    Texture { index: usize, message: String },
    #[error("cannot write {path}: {source}")]
    Io {
        path: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
}
