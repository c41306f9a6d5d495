//! Building a [`Mesh`]: meshing units (a convex surface outline, a large face, or a
//! cluster of small faces) into patches and elements.

use glam::DVec3;
use rayon::prelude::*;
use rustc_hash::FxHashMap;

use super::cluster::{cluster_parts, cluster_patch};
use super::footprint;
use super::surfaces::Topology;
use super::{Element, MAX_ELEMENTS, Mesh, MeshError, MeshSpec, Patch, PatchId};
use crate::geometry::polygon;
use crate::scene::Scene;

/// What one or more patches are made from.
enum Unit {
    /// A planar polygon (a surface's convex outline or one face), cut into patches.
    Polygon { poly: Vec<DVec3>, face: usize },
    /// Small faces shooting together as one patch: the polygons to mesh (a face, or the
    /// convex outline of a small planar surface whose faces all fell in this cluster) and
    /// the face each stands for.
    Cluster { parts: Vec<(Vec<DVec3>, usize)> },
}

/// A triangle with `longest² / area` above this is a sliver (equilateral: 2.3, right
/// isosceles: 4): bisected along its longest edge rather than cut into a regular grid.
const SLIVER_RATIO: f64 = 12.0;

impl Mesh {
    /// The mesh of `scene` that `spec` asks for: at its element size (patches
    /// [`MeshSpec::patch_for`] it), or, with none given, at the size its element budget
    /// gives (estimated from face areas, then rebuilt coarser at most twice while more than
    /// 5 % over); the lights' shadow outlines are element edges when `spec.discontinuity`
    /// ([`super::discontinuity`]).
    pub fn build(scene: &Scene, spec: &MeshSpec) -> Result<Mesh, MeshError> {
        Mesh::build_refined(scene, spec, &[])
    }

    /// [`Mesh::build`], with patch `i` of that mesh (its *base* patch) refined `levels[i]`
    /// times (none past the end of `levels`): a planar patch is cut into patches `2^level`
    /// times smaller, each with elements `2^level` times smaller; a cluster of facets keeps
    /// one patch and gets the smaller elements. [`Mesh::base_patch`] maps the result back,
    /// so levels computed from a solution on one mesh apply to the next
    /// ([`super::adaptive`]) when `spec` is the one that mesh was built from (or names its
    /// sizes): with discontinuity meshing the base patches are the cut pieces, and the
    /// levels are indexed by them.
    pub fn build_refined(scene: &Scene, spec: &MeshSpec, levels: &[u8]) -> Result<Mesh, MeshError> {
        let topo = Topology::new(scene);
        let (element_size, patch_size) = match spec.element_size {
            Some(size) => (size, spec.patch_for(size)),
            None => {
                let base = Mesh::build_for_budget(scene, &topo, spec)?;
                if levels.iter().all(|&l| l == 0) {
                    return Ok(base);
                }
                (base.element_size, base.patch_size)
            }
        };
        Mesh::build_from(
            scene,
            &topo,
            element_size,
            patch_size,
            levels,
            spec.discontinuity,
        )
    }

    /// The mesh at these sizes, on faces already grouped (the grouping does not depend on
    /// the sizes, so meshing the same scene again reuses it).
    pub(super) fn build_from(
        scene: &Scene,
        topo: &Topology,
        element_size: f64,
        patch_size: f64,
        levels: &[u8],
        discontinuity: bool,
    ) -> Result<Mesh, MeshError> {
        check_sizes(scene, element_size, patch_size)?;
        let patch_size = patch_size.max(element_size);
        let units = Units::of(scene, topo, patch_size, discontinuity);
        let parts = Parts::new(
            scene,
            topo,
            &units.face_occluder,
            element_size,
            patch_size,
            levels,
        );
        let parts = if levels.iter().all(|&l| l == 0) {
            parts.mesh_units_parallel(&units.units, UNIT_CHUNK)
        } else {
            parts.mesh_units(&units.units)
        };
        let Parts {
            patches,
            base_patch,
            elements,
            element_group,
            ..
        } = parts;
        static NEXT_MESH_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        let mut mesh = Mesh {
            id: NEXT_MESH_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            patches,
            elements,
            vertices: Vec::new(),
            triangles: Vec::new(),
            triangle_element: Vec::new(),
            element_size,
            patch_size,
            face_occluder: units.face_occluder,
            surface_count: units.surface_count,
            cluster_count: units.cluster_count,
            base_patch,
            t_vertices: Vec::new(),
            vertex_weight_start: Vec::new(),
            vertex_weights: Vec::new(),
        };
        mesh.build_vertices(&element_group);
        mesh.build_vertex_weights();
        Ok(mesh)
    }
}

/// Refuses sizes that are not positive and finite, and an element size that would make
/// more than [`MAX_ELEMENTS`] elements (estimated before allocating: a face smaller than an
/// element is one element).
fn check_sizes(scene: &Scene, element_size: f64, patch_size: f64) -> Result<(), MeshError> {
    if !(element_size.is_finite() && element_size > 0.0) {
        return Err(MeshError::BadElementSize(element_size));
    }
    if !(patch_size.is_finite() && patch_size > 0.0) {
        return Err(MeshError::BadPatchSize(patch_size));
    }
    let sides = if scene.two_sided { 2 } else { 1 };
    let estimate: f64 = scene
        .faces
        .iter()
        .map(|f| (2.0 * polygon::area(&f.vertices) / (element_size * element_size)).max(1.0))
        .sum::<f64>()
        * sides as f64;
    if estimate > MAX_ELEMENTS as f64 {
        return Err(MeshError::TooManyElements {
            size: element_size,
            count: estimate as usize,
        });
    }
    Ok(())
}

/// The meshing units of a scene, in meshing order, and what grouping them found.
struct Units {
    units: Vec<Unit>,
    /// Visibility group of each scene face ([`Mesh::face_occluder`]).
    face_occluder: Vec<u32>,
    surface_count: usize,
    cluster_count: usize,
}

/// Faces (and small surfaces) smaller than half a patch, to be clustered.
#[derive(Default)]
struct Small {
    faces: Vec<u32>,
    /// Per planar surface, its convex outline and face count.
    outline: FxHashMap<u32, (Vec<DVec3>, usize)>,
}

impl Units {
    /// The planar units (large surfaces and faces, cut along contacts and, with
    /// `discontinuity`, the lights' shadow outlines), then the clusters of small faces.
    fn of(scene: &Scene, topo: &Topology, patch_size: f64, discontinuity: bool) -> Units {
        let patch_area = patch_size * patch_size;
        let (pieces, small, surface_count) = large_pieces(scene, topo, patch_area);
        // Large faces cut along the outlines of faces facing them closer than a patch
        // (objects resting on or hovering over a floor), so no patch straddles a contact.
        let pieces = footprint::split(pieces, patch_size);
        let pieces = if discontinuity {
            super::discontinuity::split(pieces, scene, patch_area)
        } else {
            pieces
        };
        let mut units: Vec<Unit> = pieces
            .into_iter()
            .map(|p| Unit::Polygon {
                poly: p.poly,
                face: p.face,
            })
            .collect();
        let clusters = topo.clusters(&small.faces, patch_area, 0.75 * patch_size);
        let mut face_occluder = topo.planar.clone();
        let mut next_occluder = topo.planar_count as u32;
        let mut cluster_count = 0;
        let cluster_polys: Vec<Vec<(Vec<DVec3>, usize)>> = clusters
            .par_iter()
            .map(|faces| cluster_parts(scene, topo, &small.outline, faces))
            .collect();
        for (faces, parts) in clusters.into_iter().zip(cluster_polys) {
            if faces.len() > 1 {
                cluster_count += 1;
                let planar = topo.planar[faces[0] as usize];
                // A cluster across planar surfaces occludes as one group of its own.
                if faces.iter().any(|&f| topo.planar[f as usize] != planar) {
                    for &f in &faces {
                        face_occluder[f as usize] = next_occluder;
                    }
                    next_occluder += 1;
                }
            }
            units.push(Unit::Cluster { parts });
        }
        Units {
            units,
            face_occluder,
            surface_count,
            cluster_count,
        }
    }
}

/// The polygons of at least half a patch (a planar surface's convex outline, or a face),
/// the smaller faces and surfaces left to cluster, and the number of surfaces merged.
fn large_pieces(
    scene: &Scene,
    topo: &Topology,
    patch_area: f64,
) -> (Vec<footprint::Piece>, Small, usize) {
    let mut pieces = Vec::new();
    let mut small = Small::default();
    let mut surface_count = 0;
    let planar = topo.planar_members();
    // The outlines, each a walk of its surface's edges, are independent of one another.
    let outlines: Vec<Option<Vec<DVec3>>> = planar
        .par_iter()
        .map(|members| {
            let flat = topo.normal[members[0] as usize] != DVec3::ZERO;
            (flat && members.len() > 1)
                .then(|| topo.convex_outline(scene, members))
                .flatten()
        })
        .collect();
    for (members, outline) in planar.into_iter().zip(outlines) {
        let f0 = members[0] as usize;
        if topo.normal[f0] == DVec3::ZERO {
            continue;
        }
        if let Some(poly) = outline {
            surface_count += 1;
            if polygon::area(&poly) >= 0.5 * patch_area {
                pieces.push(footprint::Piece { poly, face: f0 });
            } else {
                // A small surface (the two triangles of a sphere's quad): its faces are
                // clustered like small faces, and meshed as the outline when they land in
                // one cluster together.
                small.outline.insert(topo.planar[f0], (poly, members.len()));
                small.faces.extend_from_slice(&members);
            }
            continue;
        }
        for &f in &members {
            if topo.area[f as usize] >= 0.5 * patch_area {
                pieces.push(footprint::Piece {
                    poly: scene.faces[f as usize].vertices.clone(),
                    face: f as usize,
                });
            } else {
                small.faces.push(f);
            }
        }
    }
    (pieces, small, surface_count)
}

/// The patches and elements made so far, and what making more needs.
struct Parts<'a> {
    scene: &'a Scene,
    topo: &'a Topology,
    face_occluder: &'a [u32],
    element_size: f64,
    patch_size: f64,
    /// Refinement level per base patch ([`Mesh::build_refined`]).
    levels: &'a [u8],
    patches: Vec<Patch>,
    base_patch: Vec<u32>,
    /// Index of the next patch of the unrefined mesh.
    next_base: usize,
    elements: Vec<Element>,
    /// Display group of each element (its face's display surface and side).
    element_group: Vec<u32>,
}

/// Units a thread meshes at a time ([`Parts::mesh_units_parallel`]).
const UNIT_CHUNK: usize = 512;

impl<'a> Parts<'a> {
    fn new(
        scene: &'a Scene,
        topo: &'a Topology,
        face_occluder: &'a [u32],
        element_size: f64,
        patch_size: f64,
        levels: &'a [u8],
    ) -> Self {
        Parts {
            scene,
            topo,
            face_occluder,
            element_size,
            patch_size,
            levels,
            patches: Vec::new(),
            base_patch: Vec::new(),
            next_base: 0,
            elements: Vec::new(),
            element_group: Vec::new(),
        }
    }

    /// No parts yet, with the same settings.
    fn empty(&self) -> Self {
        Parts::new(
            self.scene,
            self.topo,
            self.face_occluder,
            self.element_size,
            self.patch_size,
            self.levels,
        )
    }

    /// Meshes `units` in order, each on every side.
    fn mesh_units(mut self, units: &[Unit]) -> Self {
        let sides = if self.scene.two_sided { 2 } else { 1 };
        for unit in units {
            for side in 0..sides {
                match unit {
                    Unit::Polygon { poly, face } => self.polygon(poly, *face, side == 1),
                    Unit::Cluster { parts: polys } => self.cluster(polys, side == 1),
                }
            }
        }
        self
    }

    /// [`Parts::mesh_units`] on chunks of `chunk` units in parallel, each numbering its
    /// patches, elements and base patches from 0, joined in order with their numbers
    /// offset: the same mesh, as long as no base patch is refined (a base patch's level is
    /// looked up by its number, which a chunk does not know).
    fn mesh_units_parallel(self, units: &[Unit], chunk: usize) -> Self {
        let meshed: Vec<Parts> = units
            .par_chunks(chunk.max(1))
            .map(|c| self.empty().mesh_units(c))
            .collect();
        meshed.into_iter().fold(self, Parts::append)
    }

    /// `self` followed by `next`, whose numbers started from 0.
    fn append(mut self, next: Parts) -> Self {
        let patch_offset = self.patches.len() as u32;
        let element_offset = self.elements.len() as u32;
        let base_offset = self.next_base as u32;
        self.elements.extend(next.elements.into_iter().map(|mut e| {
            e.patch.0 += patch_offset;
            e
        }));
        self.patches.extend(next.patches.into_iter().map(|mut p| {
            p.elements = p.elements.start + element_offset..p.elements.end + element_offset;
            p
        }));
        self.base_patch
            .extend(next.base_patch.iter().map(|b| b + base_offset));
        self.next_base += next.next_base;
        self.element_group.extend(next.element_group);
        self
    }

    /// How many times smaller than the base sizes base patch `base` is meshed.
    fn scale_of(&self, base: usize) -> f64 {
        f64::from(1u32 << self.levels.get(base).copied().unwrap_or(0).min(8))
    }

    fn group(&self, face: usize, back: bool) -> u32 {
        self.topo.display[face] * 2 + u32::from(back)
    }

    /// One side of a planar unit: cut into base patches of the patch size, each refined to
    /// its level.
    fn polygon(&mut self, poly: &[DVec3], face: usize, back: bool) {
        let mut poly = poly.to_vec();
        if back {
            poly.reverse();
        }
        let Some(normal) = polygon::normal(&poly) else {
            return;
        };
        let mut patch_polys: Vec<Vec<DVec3>> = Vec::new();
        subdivide(&poly, self.patch_size, &mut |corners: &[DVec3]| {
            if polygon::area(corners) > 0.0 {
                patch_polys.push(corners.to_vec());
            }
        });
        for base in patch_polys {
            // A base patch makes elements (so counts as a patch of the unrefined mesh)
            // unless it is degenerate at the base size.
            let mut probe = Vec::new();
            let base_normal = polygon::normal(&base).unwrap_or(normal);
            push_elements(
                &base,
                base_normal,
                self.element_size,
                PatchId(0),
                face,
                &mut probe,
            );
            if probe.is_empty() {
                continue;
            }
            let base_id = self.next_base;
            self.next_base += 1;
            let scale = self.scale_of(base_id);
            let mut pieces: Vec<Vec<DVec3>> = Vec::new();
            if scale > 1.0 {
                subdivide(&base, self.patch_size / scale, &mut |c: &[DVec3]| {
                    if polygon::area(c) > 0.0 {
                        pieces.push(c.to_vec());
                    }
                });
            } else {
                pieces.push(base);
            }
            for pp in pieces {
                self.planar_piece(pp, normal, face, back, base_id, scale);
            }
        }
    }

    /// One patch of a planar unit, part of base patch `base_id`, with elements `scale`
    /// times smaller than the base size (none if it makes no element).
    fn planar_piece(
        &mut self,
        pp: Vec<DVec3>,
        normal: DVec3,
        face: usize,
        back: bool,
        base_id: usize,
        scale: f64,
    ) {
        let pid = PatchId(self.patches.len() as u32);
        let first = self.elements.len();
        let pn = polygon::normal(&pp).unwrap_or(normal);
        push_elements(
            &pp,
            pn,
            self.element_size / scale,
            pid,
            face,
            &mut self.elements,
        );
        self.element_group
            .resize(self.elements.len(), self.group(face, back));
        if self.elements.len() == first {
            return;
        }
        self.base_patch.push(base_id as u32);
        self.patches.push(planar_patch(
            self.scene,
            face,
            self.face_occluder[face],
            pp,
            pn,
            back,
            &self.elements[first..],
            first as u32,
        ));
    }

    /// One side of a cluster of small faces: one patch (one base patch), its elements at
    /// the patch's level.
    fn cluster(&mut self, parts: &[(Vec<DVec3>, usize)], back: bool) {
        let pid = PatchId(self.patches.len() as u32);
        let first = self.elements.len();
        let base_id = self.next_base;
        let scale = self.scale_of(base_id);
        for (poly, f) in parts {
            let mut poly = poly.clone();
            if back {
                poly.reverse();
            }
            let Some(n) = polygon::normal(&poly) else {
                continue;
            };
            let size = self.element_size / scale;
            push_elements(&poly, n, size, pid, *f, &mut self.elements);
            self.element_group
                .resize(self.elements.len(), self.group(*f, back));
        }
        if self.elements.len() == first {
            return;
        }
        self.next_base += 1;
        self.base_patch.push(base_id as u32);
        let f0 = parts[0].1;
        let elements = &self.elements[first..];
        let patch = if parts.len() == 1 {
            let mut poly = parts[0].0.clone();
            if back {
                poly.reverse();
            }
            let n = polygon::normal(&poly).unwrap_or(DVec3::Z);
            let occluder = self.face_occluder[f0];
            planar_patch(
                self.scene,
                f0,
                occluder,
                poly,
                n,
                back,
                elements,
                first as u32,
            )
        } else {
            let occluder = self.face_occluder[f0];
            cluster_patch(self.scene, f0, occluder, back, elements, first as u32)
        };
        self.patches.push(patch);
    }
}

fn push_elements(
    poly: &[DVec3],
    fallback_normal: DVec3,
    size: f64,
    patch: PatchId,
    face: usize,
    elements: &mut Vec<Element>,
) {
    subdivide(poly, size, &mut |corners: &[DVec3]| {
        let area = polygon::area(corners);
        if area.is_nan() || area <= 0.0 {
            return;
        }
        let mut c = [DVec3::ZERO; 4];
        c[..corners.len()].copy_from_slice(corners);
        elements.push(Element {
            patch,
            corners: c,
            corner_count: corners.len() as u8,
            vertices: [0; 4],
            centroid: polygon::centroid(corners),
            normal: polygon::normal(corners).unwrap_or(fallback_normal),
            area,
            face: face as u32,
        });
    });
}

#[allow(clippy::too_many_arguments)]
fn planar_patch(
    scene: &Scene,
    face: usize,
    occluder: u32,
    poly: Vec<DVec3>,
    normal: DVec3,
    back: bool,
    elements: &[Element],
    first: u32,
) -> Patch {
    let centroid = polygon::centroid(&poly);
    Patch {
        face,
        source_face: scene.faces[face].source_face,
        occluder,
        material: scene.faces[face].material,
        area: elements.iter().map(|e| e.area).sum(),
        centroid,
        radius: poly
            .iter()
            .map(|v| (*v - centroid).length())
            .fold(0.0, f64::max),
        largest_element_area: elements.iter().map(|e| e.area).fold(0.0, f64::max),
        bounds: poly.clone(),
        polygon: poly,
        normal,
        elements: first..first + elements.len() as u32,
        back,
    }
}

/// Calls `emit` with the corners of each element of `poly`: a convex quad as a bilinear
/// grid of about `size` edges; anything else triangulated, each triangle cut into a regular
/// grid of n² triangles of at most half a `size` square each (a triangle smaller than that
/// stays whole), or, for a sliver, bisected along its longest edge to that area. A quad
/// whose grid would hold far more cells than its area and edges ask for (a sliver quad, one
/// corner pulled far out: its grid is long both ways, its area small; fuzzing found one
/// that made 10⁹ cells) is cut as two triangles instead.
pub(super) fn subdivide(poly: &[DVec3], size: f64, emit: &mut dyn FnMut(&[DVec3])) {
    if let Some((nu, nv)) = quad_grid(poly, size) {
        let [p0, p1, p2, p3] = [poly[0], poly[1], poly[2], poly[3]];
        let at = |i: usize, j: usize| {
            let (u, v) = (i as f64 / nu as f64, j as f64 / nv as f64);
            (p0 * (1.0 - u) + p1 * u) * (1.0 - v) + (p3 * (1.0 - u) + p2 * u) * v
        };
        for j in 0..nv {
            for i in 0..nu {
                emit(&[at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        return;
    }
    let target = 0.5 * size * size;
    for t in polygon::triangulate(poly) {
        let (a, b, c) = (poly[t[0]], poly[t[1]], poly[t[2]]);
        let area = polygon::area(&[a, b, c]);
        if area.is_nan() || area <= 0.0 {
            continue;
        }
        let longest = (b - a)
            .length_squared()
            .max((c - b).length_squared())
            .max((a - c).length_squared());
        if longest / area > SLIVER_RATIO {
            bisect(a, b, c, target, 24, emit);
            continue;
        }
        let n = steps((area / target).sqrt(), 1.0);
        let at = |i: usize, j: usize| {
            a + (b - a) * (i as f64 / n as f64) + (c - a) * (j as f64 / n as f64)
        };
        for j in 0..n {
            for i in 0..n - j {
                emit(&[at(i, j), at(i + 1, j), at(i, j + 1)]);
                if i + j + 1 < n {
                    emit(&[at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
                }
            }
        }
    }
}

/// The bilinear grid's cells along and across a convex quad `poly` at `size`, unless the
/// grid would be over four times the cells its area and its edges need (then `None`, as
/// for any other polygon).
fn quad_grid(poly: &[DVec3], size: f64) -> Option<(usize, usize)> {
    if poly.len() != 4 || !polygon::is_convex(poly) {
        return None;
    }
    let [p0, p1, p2, p3] = [poly[0], poly[1], poly[2], poly[3]];
    let nu = steps(((p1 - p0).length()).max((p2 - p3).length()), size);
    let nv = steps(((p3 - p0).length()).max((p2 - p1).length()), size);
    let needed = polygon::area(poly) / (size * size) + (nu + nv) as f64;
    ((nu * nv) as f64 <= 4.0 * needed).then_some((nu, nv))
}

/// Longest-edge bisection of a triangle (orientation kept) until each piece has at most
/// `target` area.
fn bisect(a: DVec3, b: DVec3, c: DVec3, target: f64, depth: u32, emit: &mut dyn FnMut(&[DVec3])) {
    if depth == 0 || polygon::area(&[a, b, c]) <= target * (1.0 + 1e-9) {
        emit(&[a, b, c]);
        return;
    }
    let (ab, bc, ca) = (
        (b - a).length_squared(),
        (c - b).length_squared(),
        (a - c).length_squared(),
    );
    // Rotate so that the longest edge is a–b.
    let (a, b, c) = if ab >= bc && ab >= ca {
        (a, b, c)
    } else if bc >= ca {
        (b, c, a)
    } else {
        (c, a, b)
    };
    let m = (a + b) * 0.5;
    bisect(a, m, c, target, depth - 1, emit);
    bisect(m, b, c, target, depth - 1, emit);
}

/// Segments of at most `size` along `length`. A ratio within 1e-9 of a whole number counts
/// as that number, so the same scene written at another scale meshes the same.
fn steps(length: f64, size: f64) -> usize {
    ((length / size * (1.0 - 1e-9)).ceil() as usize).clamp(1, 100_000)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::LoadOptions;

    /// Meshing the units in parallel chunks and joining them gives the mesh of one pass in
    /// unit order: the same patches, elements, base patches and display groups, numbered
    /// the same.
    #[test]
    fn units_meshed_in_chunks_join_into_the_serial_mesh() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let topo = Topology::new(&scene);
        let (element_size, patch_size) = (40.0, 160.0);
        let units = Units::of(&scene, &topo, patch_size, false);
        assert!(units.units.len() > 6, "{} units", units.units.len());
        let parts = || {
            let occluder = &units.face_occluder;
            Parts::new(&scene, &topo, occluder, element_size, patch_size, &[])
        };
        let serial = parts().mesh_units(&units.units);
        let chunked = parts().mesh_units_parallel(&units.units, 3);
        assert!(serial.elements.len() > 100 && serial.patches.len() > 10);
        assert_eq!(
            format!("{:?}", serial.elements),
            format!("{:?}", chunked.elements)
        );
        assert_eq!(
            format!("{:?}", serial.patches),
            format!("{:?}", chunked.patches)
        );
        assert_eq!(serial.base_patch, chunked.base_patch);
        assert_eq!(serial.element_group, chunked.element_group);
        assert_eq!(serial.next_base, chunked.next_base);
    }
}
