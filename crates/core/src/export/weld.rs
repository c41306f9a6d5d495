//! Welding a [`BakedMesh`] into one indexed vertex set per material: vertices are shared
//! where position, normal, texture coordinates and baked values are all equal (bit for bit,
//! −0 and +0 alike). The baked values are part of the key because two surfaces that touch
//! (a light in its ceiling, two display groups meeting at a crease) have different values at
//! the same point, and welding them would change the solution; within a display group the
//! mesh already shares its vertices, so nothing is lost.

use std::collections::HashMap;

use super::BakedMesh;

/// The triangles of one material, indexed into their own vertex set.
#[derive(Debug, PartialEq)]
pub(super) struct Primitive {
    pub material: u32,
    /// The vertex of the [`BakedMesh`] behind each welded vertex.
    pub source: Vec<u32>,
    /// Three welded vertices per triangle.
    pub indices: Vec<u32>,
}

/// Bits of a float with −0 read as +0.
fn bits(x: f32) -> u32 {
    if x == 0.0 { 0 } else { x.to_bits() }
}

/// What two vertices must share to be one.
fn key(mesh: &BakedMesh, v: usize) -> [u32; 14] {
    let mut k = [0u32; 14];
    let uv = mesh.uvs.as_ref().map_or([0.0; 2], |u| u[v]);
    let values = mesh.positions[v]
        .iter()
        .chain(&mesh.normals[v])
        .chain(&uv)
        .chain(&mesh.radiance[v])
        .chain(&mesh.irradiance[v]);
    for (slot, &x) in k.iter_mut().zip(values) {
        *slot = bits(x);
    }
    k
}

/// One primitive per material that has triangles, in material order (the mesh must have
/// passed [`BakedMesh::check`]).
pub(super) fn primitives(mesh: &BakedMesh) -> Vec<Primitive> {
    let mut by_material: Vec<(u32, usize)> = mesh
        .triangle_material
        .iter()
        .enumerate()
        .map(|(t, &m)| (m, t))
        .collect();
    by_material.sort_unstable();
    let mut out: Vec<Primitive> = Vec::new();
    let mut index: HashMap<[u32; 14], u32> = HashMap::new();
    for (material, t) in by_material {
        if out.last().is_none_or(|p| p.material != material) {
            index.clear();
            out.push(Primitive {
                material,
                source: Vec::new(),
                indices: Vec::new(),
            });
        }
        let p = out.last_mut().expect("pushed above");
        for &v in &mesh.indices[3 * t..3 * t + 3] {
            let id = *index.entry(key(mesh, v as usize)).or_insert_with(|| {
                p.source.push(v);
                p.source.len() as u32 - 1
            });
            p.indices.push(id);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two quads of material 0 sharing an edge, one triangle of material 1 on that edge:
    /// the quads' six corners weld to four, the other material keeps its own, and a vertex
    /// with another value at the same point stays apart.
    #[test]
    fn equal_vertices_weld_within_a_material_only() {
        let p = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let mut mesh = BakedMesh::default();
        let corners = [0, 1, 2, 0, 2, 3, 1, 2, 0];
        for (k, &c) in corners.iter().enumerate() {
            let mut q = p[c];
            if k == 4 {
                q[2] = -0.0; // welds with the +0 of corner 2
            }
            mesh.positions.push(q);
            mesh.normals.push([0.0, 0.0, 1.0]);
            mesh.radiance.push([1.0; 3]);
            mesh.irradiance.push([2.0; 3]);
            mesh.indices.push(k as u32);
        }
        mesh.triangle_material = vec![0, 0, 1];
        // Corner 3 repeats corner 0 but with another radiance: not the same vertex.
        mesh.radiance[3] = [0.5; 3];
        mesh.check().expect("consistent");
        let prims = primitives(&mesh);
        assert_eq!(prims.len(), 2);
        assert_eq!(prims[0].material, 0);
        assert_eq!(prims[0].source, vec![0, 1, 2, 3, 5]);
        assert_eq!(prims[0].indices, vec![0, 1, 2, 3, 2, 4]);
        assert_eq!(prims[1].material, 1);
        assert_eq!(prims[1].source, vec![6, 7, 8]);
        assert_eq!(prims[1].indices, vec![0, 1, 2]);
    }
}
