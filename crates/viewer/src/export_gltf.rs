//! "Export lit mesh (glTF)": the snapshot on screen as a [`BakedMesh`] for the core's glTF
//! writer ([`nusselt_core::export::gltf`]), at the viewport's exposure, with the ambient
//! term when it is shown.
//!
//! The snapshot holds drawn vertices (one per patch using a mesh vertex); normals are the
//! area-weighted mean of the triangles' normals around each mesh vertex (a triangle's own
//! where they disagree: the two sides of a two-sided face). Irradiance per vertex is
//! `π (L − E)/ρ` with `ρ` = `Kd` × the texture's mean over the vertex's elements (what the
//! shader divides the texel by), 0 in a channel that reflects nothing. A textured scene's
//! vertices keep their texture coordinates and its maps go into the `albedo` variant, as
//! with `render --export-gltf`.

use std::path::Path;

use glam::DVec3;

use nusselt_core::export::{BakedMesh, ExportError, GltfInput, GltfStats, write_gltf};

use super::snapshot::Snapshot;

/// Per mesh vertex, the unit mean of the drawn triangles' normals around it (`None` where
/// they disagree), and per triangle its own unit normal.
fn normals(s: &Snapshot) -> (Vec<Option<DVec3>>, Vec<DVec3>) {
    let g = &s.geometry;
    let n = g.display_vertex_count();
    let mut sum = vec![(DVec3::ZERO, 0.0); n];
    let mut own = Vec::with_capacity(g.indices.len() / 3);
    for t in g.indices.chunks_exact(3) {
        let p: [DVec3; 3] =
            std::array::from_fn(|k| DVec3::from_array(g.positions[t[k] as usize].map(f64::from)));
        let cross = (p[1] - p[0]).cross(p[2] - p[0]);
        let unit = cross.try_normalize().unwrap_or(DVec3::Z);
        own.push(unit);
        for &d in t {
            let v = g.source_vertex[d as usize] as usize;
            sum[v].0 += cross * 0.5;
            sum[v].1 += cross.length() * 0.5;
        }
    }
    let mean = sum
        .into_iter()
        .map(|(n, a)| (a > 0.0 && n.length() >= 0.5 * a).then(|| n.normalize_or_zero()))
        .collect();
    (mean, own)
}

/// The snapshot as a baked mesh: radiance with the ambient term when `with_ambient`.
pub fn baked_mesh(s: &Snapshot, with_ambient: bool) -> BakedMesh {
    let g = &s.geometry;
    let (mean_normal, own) = normals(s);
    let ambient = if with_ambient { 1.0 } else { 0.0 };
    let mut out = BakedMesh {
        // The texture coordinates of the drawn vertices (OBJ convention, as the export's).
        uvs: g.textures.as_ref().map(|_| Vec::new()),
        ..BakedMesh::default()
    };
    for (t, tri) in g.indices.chunks_exact(3).enumerate() {
        let material = g.patch_material[g.patch[tri[0] as usize] as usize];
        let m = &s.materials[material as usize];
        for &d in tri {
            let d = d as usize;
            let (b, c) = (s.radiance[d], s.correction[d]);
            let radiance: [f32; 3] = [0, 1, 2].map(|k| b[k] + c[k] * ambient);
            let texture = g
                .textures
                .as_ref()
                .filter(|x| x.layer[d] != 0)
                .map_or([1.0; 3], |x| x.mean[d]);
            let irradiance = [0, 1, 2].map(|k| {
                let rho = f64::from(s.reflectance[d][k]) * f64::from(texture[k]);
                let h = (f64::from(radiance[k]) - m.emission[k]) / rho;
                if rho > 1e-6 {
                    (std::f64::consts::PI * h).max(0.0) as f32
                } else {
                    0.0
                }
            });
            let normal = mean_normal[g.source_vertex[d] as usize].unwrap_or(own[t]);
            out.indices.push(out.positions.len() as u32);
            out.positions.push(g.positions[d]);
            out.normals.push(normal.as_vec3().to_array());
            out.radiance.push(radiance);
            out.irradiance.push(irradiance);
            if let (Some(uvs), Some(x)) = (out.uvs.as_mut(), g.textures.as_ref()) {
                uvs.push(x.uv[d]);
            }
        }
        out.triangle_material.push(material);
    }
    out
}

/// Writes the snapshot as `.glb` or `.gltf` (by `path`'s extension), atomically.
pub fn write_snapshot_gltf(
    s: &Snapshot,
    path: &Path,
    with_ambient: bool,
    exposure: f32,
) -> Result<GltfStats, ExportError> {
    let mesh = baked_mesh(s, with_ambient);
    let input = GltfInput {
        mesh: &mesh,
        materials: &s.materials,
        textures: &s.scene_textures,
        exposure: f64::from(exposure),
        name: &s.scene_name,
    };
    write_gltf(path, &input)
}
