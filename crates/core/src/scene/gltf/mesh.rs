//! glTF nodes and meshes to faces: the node tree walked from the scene's roots with each
//! node's world transform (`parent × local`, from its `matrix` or its TRS), and each
//! triangle primitive's triangles transformed into the world, one [`Face`] each.
//!
//! Every accessor read is checked first (element type, count, and the bytes it spans inside
//! its buffer view) so that a bad file gives an error naming its JSON path rather than a
//! wrong read or a panic inside the reader.

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::mesh::{Mode, Semantic};
use glam::{DMat4, DVec2, DVec3};

use super::data::Source;
use super::invalid;
use crate::geometry::polygon;
use crate::scene::{Face, MaterialId, SceneError};

/// A node placed in the world.
pub(super) struct Instance {
    pub node: usize,
    pub world: DMat4,
}

/// The nodes of the default scene (else the first; else every root node) with their world
/// transforms, parents before children.
pub(super) fn instances(src: &Source) -> Result<Vec<Instance>, SceneError> {
    let doc = &src.doc;
    let roots: Vec<::gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(s) => s.nodes().collect(),
        None => {
            let mut child = vec![false; doc.nodes().len()];
            for n in doc.nodes() {
                for c in n.children() {
                    child[c.index()] = true;
                }
            }
            doc.nodes().filter(|n| !child[n.index()]).collect()
        }
    };
    let mut out = Vec::new();
    let mut stack: Vec<(::gltf::Node, DMat4)> = roots
        .into_iter()
        .rev()
        .map(|n| (n, DMat4::IDENTITY))
        .collect();
    // glTF's node hierarchy is a set of disjoint trees: a node met twice is a cycle or a
    // second parent, refused (it would otherwise never end or repeat a subtree).
    let mut seen = vec![false; doc.nodes().len()];
    while let Some((node, parent)) = stack.pop() {
        let at = format!("nodes[{}]", node.index());
        if std::mem::replace(&mut seen[node.index()], true) {
            return Err(invalid(
                &src.file,
                &at,
                "is reached twice in the node tree (a cycle, or a node with two parents)",
            ));
        }
        let local = node.transform().matrix().map(|c| c.map(f64::from));
        let world = parent * DMat4::from_cols_array_2d(&local);
        if !world.is_finite() {
            return Err(invalid(&src.file, &at, "its world transform is not finite"));
        }
        for c in node.children().collect::<Vec<_>>().into_iter().rev() {
            stack.push((c, world));
        }
        out.push(Instance {
            node: node.index(),
            world,
        });
    }
    Ok(out)
}

/// What [`faces`] found besides faces.
#[derive(Default)]
pub(super) struct MeshStats {
    pub dropped: usize,
    pub skipped: Vec<String>,
}

/// For each material, the texture-coordinate set its base colour texture reads, if any.
pub(super) type UvSets<'a> = dyn Fn(MaterialId) -> Option<u32> + 'a;

/// The faces of every mesh instance; `material` maps a primitive's material index (`None`:
/// the default material) to the scene's.
pub(super) fn faces(
    src: &Source,
    instances: &[Instance],
    material: &mut dyn FnMut(Option<usize>) -> MaterialId,
    uv_set: &UvSets,
    stats: &mut MeshStats,
) -> Result<Vec<Face>, SceneError> {
    let nodes: Vec<::gltf::Node> = src.doc.nodes().collect();
    let mut out = Vec::new();
    for inst in instances {
        let Some(mesh) = nodes[inst.node].mesh() else {
            continue;
        };
        for prim in mesh.primitives() {
            let at = format!("meshes[{}].primitives[{}]", mesh.index(), prim.index());
            if !matches!(
                prim.mode(),
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
            ) {
                stats.skipped.push(format!(
                    "{at} (mesh '{}'): {:?} skipped, only triangles are read",
                    mesh.name().unwrap_or(""),
                    prim.mode()
                ));
                continue;
            }
            let m = material(prim.material().index());
            let tris = Primitive::read(src, &prim, &at, uv_set(m))?;
            tris.emit(inst.world, m, &mut out, &mut stats.dropped);
        }
    }
    Ok(out)
}

/// One primitive's vertices (positions, texture coordinates) and triangles.
struct Primitive {
    positions: Vec<DVec3>,
    uvs: Option<Vec<DVec2>>,
    triangles: Vec<[u32; 3]>,
}

impl Primitive {
    fn read(
        src: &Source,
        prim: &::gltf::Primitive,
        at: &str,
        uv_set: Option<u32>,
    ) -> Result<Primitive, SceneError> {
        let file = &src.file;
        let get = |b: ::gltf::Buffer| src.buffers.get(b.index()).map(Vec::as_slice);
        let reader = prim.reader(get);
        let pos_at = format!("{at}.attributes.POSITION");
        let acc = prim
            .get(&Semantic::Positions)
            .ok_or_else(|| invalid(file, &format!("{at}.attributes"), "has no POSITION"))?;
        check(src, &acc, &pos_at, &[DataType::F32], Dimensions::Vec3)?;
        let n = acc.count();
        let positions: Vec<DVec3> = reader
            .read_positions()
            .ok_or_else(|| invalid(file, &pos_at, "its data cannot be read"))?
            .map(|p| DVec3::from_array(p.map(f64::from)))
            .collect();
        if let Some(k) = positions.iter().position(|p| !p.is_finite()) {
            return Err(invalid(
                file,
                &pos_at,
                format!("vertex {k} is not finite (NaN or infinity)"),
            ));
        }
        let uvs = match (
            uv_set,
            uv_set.and_then(|s| prim.get(&Semantic::TexCoords(s))),
        ) {
            (Some(set), Some(acc)) => {
                let uv_at = format!("{at}.attributes.TEXCOORD_{set}");
                let types = [DataType::F32, DataType::U8, DataType::U16];
                check(src, &acc, &uv_at, &types, Dimensions::Vec2)?;
                if acc.count() != n {
                    return Err(invalid(
                        file,
                        &uv_at,
                        format!("has {} elements but POSITION has {n}", acc.count()),
                    ));
                }
                let uv: Vec<DVec2> = reader
                    .read_tex_coords(set)
                    .ok_or_else(|| invalid(file, &uv_at, "its data cannot be read"))?
                    .into_f32()
                    // glTF's v runs down from the image's top row, Nusselt's up from the bottom.
                    .map(|[u, v]| DVec2::new(f64::from(u), 1.0 - f64::from(v)))
                    .collect();
                if uv.iter().any(|p| !p.is_finite()) {
                    return Err(invalid(file, &uv_at, "holds a value that is not finite"));
                }
                Some(uv)
            }
            _ => None,
        };
        let indices: Vec<u32> = match prim.indices() {
            Some(acc) => {
                let idx_at = format!("{at}.indices");
                let types = [DataType::U8, DataType::U16, DataType::U32];
                check(src, &acc, &idx_at, &types, Dimensions::Scalar)?;
                let idx: Vec<u32> = reader
                    .read_indices()
                    .ok_or_else(|| invalid(file, &idx_at, "its data cannot be read"))?
                    .into_u32()
                    .collect();
                if let Some(k) = idx.iter().position(|&i| i as usize >= n) {
                    return Err(invalid(
                        file,
                        &idx_at,
                        format!(
                            "index {} (element {k}) is out of range: the primitive has {n} vertices",
                            idx[k]
                        ),
                    ));
                }
                idx
            }
            None => (0..n as u32).collect(),
        };
        Ok(Primitive {
            positions,
            uvs,
            triangles: triangles(prim.mode(), &indices),
        })
    }

    /// Pushes the triangles transformed by `world` (winding reversed when it mirrors),
    /// counting those of zero area in `dropped`.
    fn emit(&self, world: DMat4, material: MaterialId, out: &mut Vec<Face>, dropped: &mut usize) {
        let flip = world.determinant() < 0.0;
        let p: Vec<DVec3> = self
            .positions
            .iter()
            .map(|&v| world.transform_point3(v))
            .collect();
        for t in &self.triangles {
            let t = if flip { [t[0], t[2], t[1]] } else { *t };
            let vertices: Vec<DVec3> = t.iter().map(|&i| p[i as usize]).collect();
            let scale = (vertices[1] - vertices[0])
                .length()
                .max((vertices[2] - vertices[0]).length());
            // Written so that a NaN area is dropped too.
            let kept = polygon::area(&vertices) > 1e-12 * scale * scale;
            if !kept {
                *dropped += 1;
                continue;
            }
            out.push(Face {
                vertices,
                material,
                source_face: out.len(),
                line: 0,
                uvs: self
                    .uvs
                    .as_ref()
                    .map(|uv| t.iter().map(|&i| uv[i as usize]).collect()),
            });
        }
    }
}

/// The triangles of an index list drawn in `mode` (strips alternate their winding so that
/// every triangle keeps the first one's orientation, as the glTF specification draws them).
fn triangles(mode: Mode, idx: &[u32]) -> Vec<[u32; 3]> {
    match mode {
        Mode::Triangles => idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        Mode::TriangleStrip => (0..idx.len().saturating_sub(2))
            .map(|i| {
                if i % 2 == 0 {
                    [idx[i], idx[i + 1], idx[i + 2]]
                } else {
                    [idx[i + 1], idx[i], idx[i + 2]]
                }
            })
            .collect(),
        Mode::TriangleFan => (1..idx.len().saturating_sub(1))
            .map(|i| [idx[i], idx[i + 1], idx[0]])
            .collect(),
        _ => Vec::new(),
    }
}

/// Checks that accessor `acc` holds `dims` elements of one of `types` and that the bytes it
/// reads lie inside its buffer view (the views were checked against their buffers).
fn check(
    src: &Source,
    acc: &::gltf::Accessor,
    at: &str,
    types: &[DataType],
    dims: Dimensions,
) -> Result<(), SceneError> {
    let file = &src.file;
    let what = format!("{at} (accessors[{}])", acc.index());
    if !types.contains(&acc.data_type()) || acc.dimensions() != dims {
        return Err(invalid(
            file,
            &what,
            format!(
                "is {:?} of {:?}, expected {dims:?} of {}",
                acc.dimensions(),
                acc.data_type(),
                types
                    .iter()
                    .map(|t| format!("{t:?}"))
                    .collect::<Vec<_>>()
                    .join(" or ")
            ),
        ));
    }
    if acc.sparse().is_some() {
        return Err(invalid(file, &what, "sparse accessors are not supported"));
    }
    if acc.count() == 0 {
        return Err(invalid(file, &what, "has no elements (count 0)"));
    }
    let Some(view) = acc.view() else {
        return Err(invalid(
            file,
            &what,
            "has no bufferView (an all-zero accessor)",
        ));
    };
    let size = acc.size();
    let stride = view.stride().unwrap_or(size);
    if stride < size {
        return Err(invalid(
            file,
            &what,
            format!(
                "bufferViews[{}] has byteStride {stride}, less than the element size {size}",
                view.index()
            ),
        ));
    }
    let end = (acc.count() - 1)
        .checked_mul(stride)
        .and_then(|x| x.checked_add(size))
        .and_then(|x| x.checked_add(acc.offset()));
    if end.is_none_or(|e| e > view.length()) {
        return Err(invalid(
            file,
            &what,
            format!(
                "{} elements from byte {} run past the end of bufferViews[{}] ({} bytes)",
                acc.count(),
                acc.offset(),
                view.index(),
                view.length()
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans_keep_one_winding() {
        let idx = [0, 1, 2, 3, 4];
        assert_eq!(
            triangles(Mode::TriangleStrip, &idx),
            [[0, 1, 2], [2, 1, 3], [2, 3, 4]]
        );
        assert_eq!(
            triangles(Mode::TriangleFan, &idx),
            [[1, 2, 0], [2, 3, 0], [3, 4, 0]]
        );
        assert_eq!(triangles(Mode::Triangles, &idx), [[0, 1, 2]]);
        assert!(triangles(Mode::TriangleStrip, &idx[..2]).is_empty());
    }
}
