//! Patches, elements and per-vertex radiance.
//!
//! Each input polygon becomes a patch (two, front and back, when the scene is two-sided);
//! each patch is subdivided into elements of edge length about `element_size`: convex quads
//! into a bilinear grid of quads, everything else into triangles (ear clipping), each
//! triangle into a regular grid of smaller triangles. Patches shoot, elements receive
//! (Cohen, Greenberg, Immel, Brock 1986, "An efficient radiosity approach for realistic image
//! synthesis": substructuring).
//!
//! Display vertices are shared only by elements on the same *surface* (same material,
//! coplanar): radiance is averaged over those elements, never across a crease or a material
//! change. Where a vertex of one patch lies inside an edge of a neighbouring patch's element
//! (a T-vertex), its value is set to the interpolation along that edge so the shading has no
//! cracks (Baum, Mann, Smith, Winget 1991).

use std::collections::HashMap;
use std::ops::Range;

use glam::DVec3;

use crate::geometry::bvh::TriangleInput;
use crate::geometry::{Aabb, polygon};
use crate::scene::{MaterialId, Rgb, Scene};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PatchId(pub u32);

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ElementId(pub u32);

/// Patch edge length in element sizes for [`Mesh::build`].
pub const PATCH_ELEMENTS: f64 = 4.0;

/// A default patch (shooter) size: 1/24 of the scene's diagonal (40 mm in the Cornell box).
/// Patches shoot with their area-averaged unshot radiance, so a patch much larger than the
/// scale on which radiance varies spreads light wrongly: whole-wall patches put the Cornell
/// box 19 % off a path tracer, 96 mm patches 2.6 %, 40 mm patches 1.9 % (with 12 mm
/// elements).
pub fn default_patch_size(scene: &Scene) -> f64 {
    let d = scene.bounds().diagonal();
    if d > 0.0 { d / 24.0 } else { 1.0 }
}

/// Most elements a mesh may have (memory and time guard for a tiny `--element-size`).
pub const MAX_ELEMENTS: usize = 4_000_000;

#[derive(Clone, Debug)]
pub struct Patch {
    /// Index into `Scene::faces`.
    pub face: usize,
    /// Index of the input face in file order.
    pub source_face: usize,
    pub material: MaterialId,
    /// Counter-clockwise seen from the front (reversed for a back patch).
    pub polygon: Vec<DVec3>,
    pub normal: DVec3,
    pub area: f64,
    pub centroid: DVec3,
    pub elements: Range<u32>,
    /// True for the back side of a two-sided face.
    pub back: bool,
    /// Largest distance from the centroid to a corner (bounding sphere radius).
    pub radius: f64,
    /// Area of the patch's largest element.
    pub largest_element_area: f64,
}

#[derive(Clone, Debug)]
pub struct Element {
    pub patch: PatchId,
    /// 3 or 4 corners, counter-clockwise seen from the front.
    pub corners: [DVec3; 4],
    pub corner_count: u8,
    /// Display vertices of the corners.
    pub vertices: [u32; 4],
    pub centroid: DVec3,
    pub normal: DVec3,
    pub area: f64,
}

impl Element {
    pub fn corners(&self) -> &[DVec3] {
        &self.corners[..self.corner_count as usize]
    }
    pub fn vertex_ids(&self) -> &[u32] {
        &self.vertices[..self.corner_count as usize]
    }
}

/// A vertex that lies inside the edge `a`–`b` of a neighbouring element.
#[derive(Clone, Copy, Debug)]
struct TVertex {
    vertex: u32,
    a: u32,
    b: u32,
    t: f64,
}

#[derive(Clone, Debug)]
pub struct Mesh {
    /// Unique per built mesh (a clone keeps it: same geometry), so that caches elsewhere
    /// (the GPU hemicube's vertex buffer) know when the geometry changed.
    pub id: u64,
    pub patches: Vec<Patch>,
    pub elements: Vec<Element>,
    /// Display vertex positions.
    pub vertices: Vec<DVec3>,
    /// Display triangles (indices into `vertices`), two per quad element.
    pub triangles: Vec<[u32; 3]>,
    /// Element of each display triangle.
    pub triangle_element: Vec<ElementId>,
    pub element_size: f64,
    t_vertices: Vec<TVertex>,
    /// Per vertex, the element weights of its value (CSR: `vertex_weights[start[v]..start[v+1]]`).
    vertex_weight_start: Vec<u32>,
    vertex_weights: Vec<(u32, f64)>,
}

#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    #[error("element size must be a positive finite number, got {0}")]
    BadElementSize(f64),
    #[error(
        "element size {size} would make about {count} elements (limit {MAX_ELEMENTS}); use a larger --element-size"
    )]
    TooManyElements { size: f64, count: usize },
}

/// A default element size: 1/80 of the scene's bounding-box diagonal (12 mm in the Cornell
/// box, where it gives a converged image within 2 % of a path tracer; see README).
pub fn default_element_size(scene: &Scene) -> f64 {
    let d = scene.bounds().diagonal();
    if d > 0.0 { d / 80.0 } else { 1.0 }
}

impl Mesh {
    /// Meshes with patches of about [`PATCH_ELEMENTS`] elements across.
    pub fn build(scene: &Scene, element_size: f64) -> Result<Mesh, MeshError> {
        Mesh::build_with(scene, element_size, element_size * PATCH_ELEMENTS)
    }

    /// Meshes with explicit patch and element sizes (scene units).
    pub fn build_with(
        scene: &Scene,
        element_size: f64,
        patch_size: f64,
    ) -> Result<Mesh, MeshError> {
        if !(element_size.is_finite() && element_size > 0.0) {
            return Err(MeshError::BadElementSize(element_size));
        }
        if !(patch_size.is_finite() && patch_size > 0.0) {
            return Err(MeshError::BadElementSize(patch_size));
        }
        let sides = if scene.two_sided { 2 } else { 1 };
        // Estimate before allocating.
        let estimate: f64 = scene
            .faces
            .iter()
            .map(|f| polygon::area(&f.vertices) / (element_size * element_size) + 1.0)
            .sum::<f64>()
            * sides as f64;
        if estimate > MAX_ELEMENTS as f64 {
            return Err(MeshError::TooManyElements {
                size: element_size,
                count: estimate as usize,
            });
        }
        let mut patches = Vec::new();
        let mut elements: Vec<Element> = Vec::new();
        for (fi, face) in scene.faces.iter().enumerate() {
            for side in 0..sides {
                let back = side == 1;
                let mut poly = face.vertices.clone();
                if back {
                    poly.reverse();
                }
                let Some(normal) = polygon::normal(&poly) else {
                    continue;
                };
                let mut patch_polys: Vec<Vec<DVec3>> = Vec::new();
                subdivide(&poly, patch_size, &mut |corners: &[DVec3]| {
                    if polygon::area(corners) > 0.0 {
                        patch_polys.push(corners.to_vec());
                    }
                });
                for pp in patch_polys {
                    let pid = PatchId(patches.len() as u32);
                    let first = elements.len() as u32;
                    let pn = polygon::normal(&pp).unwrap_or(normal);
                    subdivide(&pp, element_size, &mut |corners: &[DVec3]| {
                        let area = polygon::area(corners);
                        if area <= 0.0 {
                            return;
                        }
                        let mut c = [DVec3::ZERO; 4];
                        c[..corners.len()].copy_from_slice(corners);
                        elements.push(Element {
                            patch: pid,
                            corners: c,
                            corner_count: corners.len() as u8,
                            vertices: [0; 4],
                            centroid: polygon::centroid(corners),
                            normal: polygon::normal(corners).unwrap_or(pn),
                            area,
                        });
                    });
                    let centroid = polygon::centroid(&pp);
                    patches.push(Patch {
                        face: fi,
                        source_face: face.source_face,
                        material: face.material,
                        area: polygon::area(&pp),
                        centroid,
                        radius: pp
                            .iter()
                            .map(|v| (*v - centroid).length())
                            .fold(0.0, f64::max),
                        largest_element_area: elements[first as usize..]
                            .iter()
                            .map(|e| e.area)
                            .fold(0.0, f64::max),
                        polygon: pp,
                        normal: pn,
                        elements: first..elements.len() as u32,
                        back,
                    });
                }
            }
        }
        static NEXT_MESH_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        let mut mesh = Mesh {
            id: NEXT_MESH_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            patches,
            elements,
            vertices: Vec::new(),
            triangles: Vec::new(),
            triangle_element: Vec::new(),
            element_size,
            t_vertices: Vec::new(),
            vertex_weight_start: Vec::new(),
            vertex_weights: Vec::new(),
        };
        mesh.build_vertices(scene);
        mesh.build_vertex_weights();
        Ok(mesh)
    }

    pub fn patch(&self, id: PatchId) -> &Patch {
        &self.patches[id.0 as usize]
    }

    /// Axis-aligned bounds of all patches.
    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(self.patches.iter().flat_map(|p| p.polygon.iter()))
    }

    /// Triangles of the input faces (ids = face index) for visibility queries. Faces, not
    /// patches: the hierarchy stays as small as the model (38 triangles for the Cornell box
    /// instead of one or two per patch).
    pub fn face_triangles(scene: &Scene) -> Vec<TriangleInput> {
        let mut out = Vec::new();
        for (i, f) in scene.faces.iter().enumerate() {
            let v = &f.vertices;
            for t in polygon::triangulate(v) {
                out.push(TriangleInput {
                    vertices: [v[t[0]], v[t[1]], v[t[2]]],
                    id: i as u32,
                    cull_back: false,
                });
            }
        }
        out
    }

    /// Display triangles (ids = index into `triangles`); back faces are culled for
    /// two-sided patches so the side facing the viewer is found.
    pub fn display_triangles(&self, two_sided: bool) -> Vec<TriangleInput> {
        self.triangles
            .iter()
            .enumerate()
            .map(|(i, t)| TriangleInput {
                vertices: [
                    self.vertices[t[0] as usize],
                    self.vertices[t[1] as usize],
                    self.vertices[t[2] as usize],
                ],
                id: i as u32,
                cull_back: two_sided,
            })
            .collect()
    }

    /// Per-vertex values from per-element values (one value per element, its centroid's).
    ///
    /// A vertex inside a surface takes the value at the vertex of the area-weighted
    /// least-squares plane through the centroids of the elements of that surface meeting at
    /// it (on a regular grid, their plain average). A vertex on a surface's boundary — a
    /// corner, a contact line — has elements on one side only, where an average is the value
    /// half an element inwards, an O(h) bias exactly where radiosity changes fastest; there
    /// the plane is fitted through two rings of elements and extrapolated (O(h²)). Results
    /// are clamped to be non-negative. A linear field is reproduced exactly. T-vertices are interpolated along the
    /// edge they lie on, so shading has no cracks.
    pub fn vertex_values(&self, element_values: &[Rgb]) -> Vec<Rgb> {
        debug_assert_eq!(element_values.len(), self.elements.len());
        let mut out: Vec<Rgb> = (0..self.vertices.len())
            .map(|v| {
                let (a, b) = (
                    self.vertex_weight_start[v] as usize,
                    self.vertex_weight_start[v + 1] as usize,
                );
                let value: Rgb = self.vertex_weights[a..b]
                    .iter()
                    .map(|&(e, w)| element_values[e as usize] * w)
                    .sum();
                value.max(Rgb::ZERO)
            })
            .collect();
        // Nested T-vertices settle in a few passes.
        for _ in 0..3 {
            for tv in &self.t_vertices {
                out[tv.vertex as usize] =
                    out[tv.a as usize] * (1.0 - tv.t) + out[tv.b as usize] * tv.t;
            }
        }
        out
    }

    /// Precomputes the weights used by [`Mesh::vertex_values`].
    fn build_vertex_weights(&mut self) {
        let nv = self.vertices.len();
        let mut count = vec![0u32; nv + 1];
        for e in &self.elements {
            for &v in e.vertex_ids() {
                count[v as usize + 1] += 1;
            }
        }
        for i in 0..nv {
            count[i + 1] += count[i];
        }
        let mut at = count.clone();
        let mut adjacent = vec![0u32; count[nv] as usize];
        for (ei, e) in self.elements.iter().enumerate() {
            for &v in e.vertex_ids() {
                adjacent[at[v as usize] as usize] = ei as u32;
                at[v as usize] += 1;
            }
        }
        let elems_of =
            |v: u32| &adjacent[count[v as usize] as usize..count[v as usize + 1] as usize];
        let mut start = Vec::with_capacity(nv + 1);
        let mut weights = Vec::with_capacity(count[nv] as usize * 2);
        let mut ring: Vec<u32> = Vec::new();
        for v in 0..nv as u32 {
            start.push(weights.len() as u32);
            let p = self.vertices[v as usize];
            let first = elems_of(v);
            let total: f64 = first.iter().map(|&e| self.elements[e as usize].area).sum();
            if first.is_empty() || total <= 0.0 {
                continue;
            }
            let h = (total / first.len() as f64).sqrt();
            let offset = first
                .iter()
                .map(|&e| {
                    let el = &self.elements[e as usize];
                    (el.centroid - p) * el.area
                })
                .sum::<DVec3>()
                / total;
            let average = |weights: &mut Vec<(u32, f64)>| {
                for &e in first {
                    weights.push((e, self.elements[e as usize].area / total));
                }
            };
            // A least-squares plane through the centroids: over the elements at the vertex
            // when they surround it (the plain average on a regular grid), over two rings of
            // elements on a boundary (or where one ring is too thin to fit), extrapolating.
            let n = self.elements[first[0] as usize].normal;
            let (t1, t2) = n.any_orthonormal_pair();
            let phi = |e: u32| {
                let d = (self.elements[e as usize].centroid - p) / h;
                DVec3::new(1.0, d.dot(t1), d.dot(t2))
            };
            let fit = |ring: &[u32]| -> Option<DVec3> {
                let mut m = glam::DMat3::ZERO;
                for &e in ring {
                    let f = phi(e);
                    let a = self.elements[e as usize].area;
                    m += glam::DMat3::from_cols(f * f.x, f * f.y, f * f.z) * a;
                }
                let scale = m.x_axis.x.max(f64::MIN_POSITIVE);
                (ring.len() >= 3 && (m.determinant() / scale.powi(3)).abs() > 1e-6)
                    .then(|| m.inverse() * DVec3::X)
            };
            let mut solution = if offset.length() < 0.2 * h {
                fit(first).map(|z| (z, first.to_vec()))
            } else {
                None
            };
            if solution.is_none() {
                ring.clear();
                for &e in first {
                    for &u in self.elements[e as usize].vertex_ids() {
                        ring.extend_from_slice(elems_of(u));
                    }
                }
                ring.sort_unstable();
                ring.dedup();
                solution = fit(&ring).map(|z| (z, ring.clone()));
            }
            match solution {
                Some((z, ring)) => {
                    for e in ring {
                        let w = self.elements[e as usize].area * z.dot(phi(e));
                        debug_assert!(w.is_finite());
                        weights.push((e, w));
                    }
                }
                None => average(&mut weights),
            }
        }
        start.push(weights.len() as u32);
        self.vertex_weight_start = start;
        self.vertex_weights = weights;
    }

    fn build_vertices(&mut self, scene: &Scene) {
        // Surfaces: all patches of one input face, joined with other faces of the same
        // material and side that lie in the same plane.
        let mut surfaces: Vec<(MaterialId, bool, DVec3, f64)> = Vec::new();
        let mut face_surface: HashMap<(usize, bool), u32> = HashMap::new();
        let diag = self.bounds().diagonal().max(1e-300);
        let eps = 1e-6 * diag;
        let mut patch_surface = Vec::with_capacity(self.patches.len());
        for p in &self.patches {
            let id = *face_surface.entry((p.face, p.back)).or_insert_with(|| {
                let f = &scene.faces[p.face].vertices;
                let mut n = polygon::normal(f).unwrap_or(p.normal);
                if p.back {
                    n = -n;
                }
                let offset = n.dot(polygon::centroid(f));
                let found = surfaces.iter().position(|(m, back, sn, d)| {
                    *m == p.material
                        && *back == p.back
                        && sn.dot(n) > 0.9998
                        && (d - offset).abs() < 1e-4 * diag
                });
                found.unwrap_or_else(|| {
                    surfaces.push((p.material, p.back, n, offset));
                    surfaces.len() - 1
                }) as u32
            });
            patch_surface.push(id);
        }
        let quant = |p: DVec3| {
            let q = (p / eps).round();
            (q.x as i64, q.y as i64, q.z as i64)
        };
        let mut index: HashMap<(u32, (i64, i64, i64)), u32> = HashMap::new();
        let mut vertex_surface: Vec<u32> = Vec::new();
        for ei in 0..self.elements.len() {
            let surface = patch_surface[self.elements[ei].patch.0 as usize];
            for k in 0..self.elements[ei].corner_count as usize {
                let p = self.elements[ei].corners[k];
                let id = *index.entry((surface, quant(p))).or_insert_with(|| {
                    self.vertices.push(p);
                    vertex_surface.push(surface);
                    self.vertices.len() as u32 - 1
                });
                self.elements[ei].vertices[k] = id;
            }
            let v = self.elements[ei].vertices;
            let eid = ElementId(ei as u32);
            self.triangles.push([v[0], v[1], v[2]]);
            self.triangle_element.push(eid);
            if self.elements[ei].corner_count == 4 {
                self.triangles.push([v[0], v[2], v[3]]);
                self.triangle_element.push(eid);
            }
        }
        self.find_t_vertices(&patch_surface, &vertex_surface, eps);
    }

    fn find_t_vertices(&mut self, patch_surface: &[u32], vertex_surface: &[u32], eps: f64) {
        // Only surfaces made of several patches can have T-vertices between patches.
        let mut patches_per_surface: HashMap<u32, usize> = HashMap::new();
        for s in patch_surface {
            *patches_per_surface.entry(*s).or_default() += 1;
        }
        let cell = self.element_size.max(eps);
        let key = |p: DVec3| {
            let q = (p / cell).floor();
            (q.x as i64, q.y as i64, q.z as i64)
        };
        let mut grid: HashMap<(i64, i64, i64), Vec<u32>> = HashMap::new();
        for (v, p) in self.vertices.iter().enumerate() {
            if patches_per_surface[&vertex_surface[v]] > 1 {
                grid.entry(key(*p)).or_default().push(v as u32);
            }
        }
        if grid.is_empty() {
            return;
        }
        let mut found: HashMap<u32, TVertex> = HashMap::new();
        for e in &self.elements {
            let surface = patch_surface[e.patch.0 as usize];
            if patches_per_surface[&surface] < 2 {
                continue;
            }
            let n = e.corner_count as usize;
            for k in 0..n {
                let (a, b) = (e.vertices[k], e.vertices[(k + 1) % n]);
                let (pa, pb) = (self.vertices[a as usize], self.vertices[b as usize]);
                let d = pb - pa;
                let len2 = d.length_squared();
                if len2 <= 0.0 {
                    continue;
                }
                let (lo, hi) = (
                    key(pa.min(pb) - DVec3::splat(eps)),
                    key(pa.max(pb) + DVec3::splat(eps)),
                );
                for x in lo.0..=hi.0 {
                    for y in lo.1..=hi.1 {
                        for z in lo.2..=hi.2 {
                            let Some(list) = grid.get(&(x, y, z)) else {
                                continue;
                            };
                            for &v in list {
                                if v == a || v == b || vertex_surface[v as usize] != surface {
                                    continue;
                                }
                                let p = self.vertices[v as usize];
                                let t = (p - pa).dot(d) / len2;
                                if t <= 1e-9 || t >= 1.0 - 1e-9 {
                                    continue;
                                }
                                if (pa + d * t - p).length() < eps * 10.0 {
                                    found.entry(v).or_insert(TVertex { vertex: v, a, b, t });
                                }
                            }
                        }
                    }
                }
            }
        }
        let mut list: Vec<TVertex> = found.into_values().collect();
        list.sort_by_key(|t| t.vertex);
        self.t_vertices = list;
    }

    /// Number of T-vertices found (for tests and statistics).
    pub fn t_vertex_count(&self) -> usize {
        self.t_vertices.len()
    }
}

/// Calls `emit` with the corners of each element of `poly`.
fn subdivide(poly: &[DVec3], size: f64, emit: &mut dyn FnMut(&[DVec3])) {
    if poly.len() == 4 && polygon::is_convex(poly) {
        let [p0, p1, p2, p3] = [poly[0], poly[1], poly[2], poly[3]];
        let nu = steps(((p1 - p0).length()).max((p2 - p3).length()), size);
        let nv = steps(((p3 - p0).length()).max((p2 - p1).length()), size);
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
    for t in polygon::triangulate(poly) {
        let (a, b, c) = (poly[t[0]], poly[t[1]], poly[t[2]]);
        let longest = (b - a).length().max((c - b).length()).max((a - c).length());
        let n = steps(longest, size);
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

fn steps(length: f64, size: f64) -> usize {
    ((length / size).ceil() as usize).clamp(1, 100_000)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{LoadOptions, Scene};

    fn cornell() -> Scene {
        Scene::builtin("cornell", &LoadOptions::default()).expect("cornell")
    }

    #[test]
    fn elements_tile_their_patches() {
        let scene = cornell();
        let mesh = Mesh::build(&scene, 30.0).expect("mesh");
        for p in &mesh.patches {
            let sum: f64 = mesh.elements[p.elements.start as usize..p.elements.end as usize]
                .iter()
                .map(|e| e.area)
                .sum();
            assert!(
                (sum - p.area).abs() < 1e-5 * p.area,
                "patch {} {} vs {}",
                p.face,
                sum,
                p.area
            );
            for e in &mesh.elements[p.elements.start as usize..p.elements.end as usize] {
                let edge = e.corners().iter().zip(e.corners().iter().cycle().skip(1));
                for (a, b) in edge {
                    assert!((*a - *b).length() <= 30.0 * 1.01 + 1e-9 || p.polygon.len() != 4);
                }
            }
        }
    }

    #[test]
    fn triangles_subdivide_with_right_area() {
        let mut out = Vec::new();
        let tri = [
            DVec3::ZERO,
            DVec3::new(3.0, 0.0, 0.0),
            DVec3::new(0.0, 3.0, 0.0),
        ];
        subdivide(&tri, 1.5, &mut |c| out.push(polygon::area(c)));
        assert_eq!(out.len(), 9);
        assert!((out.iter().sum::<f64>() - 4.5).abs() < 1e-12);
    }

    #[test]
    fn vertices_are_not_shared_across_creases_or_materials() {
        let scene = cornell();
        let mesh = Mesh::build(&scene, 50.0).expect("mesh");
        // The floor-to-back-wall corner point appears once per surface.
        let corner = DVec3::new(0.0, 0.0, 559.2);
        let copies = mesh
            .vertices
            .iter()
            .filter(|v| (**v - corner).length() < 1e-6)
            .count();
        assert_eq!(
            copies, 3,
            "floor, back wall and right wall each keep their own vertex"
        );
    }

    #[test]
    fn t_vertices_are_interpolated_along_the_coarse_edge() {
        // Two coplanar patches of one material with different subdivisions.
        let obj = "mtllib m.mtl\nusemtl w\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\nf 1 2 3 4\nf 2 5 6 3\nusemtl l\nv 0 0 3\nv 0 1 3\nv 1 1 3\nf 7 8 9\n";
        let mtl = "newmtl w\nKd 0.5 0.5 0.5\nnewmtl l\nKe 1 1 1\n";
        let scene = Scene::from_obj_str("t.obj", obj, &[("m.mtl", mtl)], &LoadOptions::default())
            .expect("scene");
        let mut mesh = Mesh::build(&scene, 0.5).expect("mesh");
        // Make the second patch finer by rebuilding it alone is awkward; instead check that
        // conforming patches have no T-vertices and a finer neighbour does.
        assert_eq!(mesh.t_vertex_count(), 0);
        let obj2 = obj.replace("v 2 0 0\nv 2 1 0", "v 1.5 0 0\nv 1.5 1 0");
        let scene2 =
            Scene::from_obj_str("t.obj", &obj2, &[("m.mtl", mtl)], &LoadOptions::default())
                .expect("scene");
        mesh = Mesh::build(&scene2, 0.34).expect("mesh");
        // Left patch: 3×3 grid (vertices at y = 1/3, 2/3); right patch 0.5 wide: 2×3 grid…
        // both have 3 rows, so still conforming. Use sizes that differ per patch instead:
        let values: Vec<Rgb> = mesh
            .elements
            .iter()
            .map(|e| Rgb::splat(e.centroid.y))
            .collect();
        let vv = mesh.vertex_values(&values);
        assert!(vv.iter().all(|v| v.is_finite()));
        let obj3 = "mtllib m.mtl\nusemtl w\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 1 0.5 0\nv 1.1 0.5 0\nv 1.1 1 0\nf 1 2 5 3 4\nf 5 6 7 3\nusemtl l\nv 0 0 3\nv 0 1 3\nv 1 1 3\nf 8 9 10\n";
        let scene3 = Scene::from_obj_str("t.obj", obj3, &[("m.mtl", mtl)], &LoadOptions::default())
            .expect("scene");
        let mesh3 = Mesh::build(&scene3, 10.0).expect("mesh");
        // The left pentagon's vertex (1, 0.5) is a corner of the right quad but lies inside
        // no edge of the pentagon's triangles: the pentagon has it as a corner too.
        let values: Vec<Rgb> = mesh3
            .elements
            .iter()
            .map(|e| Rgb::splat(e.centroid.x))
            .collect();
        assert!(mesh3.vertex_values(&values).iter().all(|v| v.is_finite()));
        // A true T-vertex: a single quad next to two stacked quads.
        let obj4 = "mtllib m.mtl\nusemtl w\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 0.5 0\nv 1 0.5 0\nv 2 1 0\nf 1 2 3 4\nf 2 5 6 7\nf 7 6 8 3\nusemtl l\nv 0 0 3\nv 0 1 3\nv 1 1 3\nf 9 10 11\n";
        let scene4 = Scene::from_obj_str("t.obj", obj4, &[("m.mtl", mtl)], &LoadOptions::default())
            .expect("scene");
        let mesh4 = Mesh::build(&scene4, 10.0).expect("mesh");
        assert_eq!(mesh4.t_vertex_count(), 1);
        let values: Vec<Rgb> = mesh4
            .elements
            .iter()
            .map(|e| {
                Rgb::splat(if e.centroid.x < 1.0 {
                    0.0
                } else {
                    e.centroid.y
                })
            })
            .collect();
        let vv = mesh4.vertex_values(&values);
        let t = mesh4
            .vertices
            .iter()
            .position(|p| (*p - DVec3::new(1.0, 0.5, 0.0)).length() < 1e-9)
            .expect("T-vertex");
        let a = mesh4
            .vertices
            .iter()
            .position(|p| (*p - DVec3::new(1.0, 0.0, 0.0)).length() < 1e-9)
            .expect("a");
        let b = mesh4
            .vertices
            .iter()
            .position(|p| (*p - DVec3::new(1.0, 1.0, 0.0)).length() < 1e-9)
            .expect("b");
        assert!(
            (vv[t] - (vv[a] + vv[b]) * 0.5).length() < 1e-12,
            "{:?} {:?} {:?}",
            vv[t],
            vv[a],
            vv[b]
        );
    }

    #[test]
    fn vertex_values_reproduce_a_linear_field_up_to_the_boundary() {
        // Every wall of the Cornell box with radiance linear in position: interior vertices
        // (averages) and boundary vertices (least-squares extrapolation) must both be exact.
        // Averaging alone would be off by half an element's gradient at the boundary.
        let scene = cornell();
        let mesh = Mesh::build(&scene, 30.0).expect("mesh");
        let field = |p: DVec3| 1.0 + 0.002 * p.x + 0.001 * p.y + 0.0015 * p.z;
        let values: Vec<Rgb> = mesh
            .elements
            .iter()
            .map(|e| Rgb::splat(field(e.centroid)))
            .collect();
        let vv = mesh.vertex_values(&values);
        let mut worst: f64 = 0.0;
        for (p, v) in mesh.vertices.iter().zip(&vv) {
            worst = worst.max((v.x - field(*p)).abs() / field(*p));
        }
        // Not 1e-15: the published walls are a few mm off planar, so some centroids lie off
        // the fitted plane. Plain averaging is off by ~1 % at the boundary here.
        assert!(worst < 1e-5, "worst relative error {worst}");
    }

    #[test]
    fn too_small_element_size_is_refused() {
        let scene = cornell();
        assert!(matches!(
            Mesh::build(&scene, 0.01),
            Err(MeshError::TooManyElements { .. })
        ));
        assert!(matches!(
            Mesh::build(&scene, f64::NAN),
            Err(MeshError::BadElementSize(_))
        ));
    }
}
