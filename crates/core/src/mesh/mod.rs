//! Patches, elements and per-vertex radiance.
//!
//! Input faces are first grouped ([`surfaces`]): edge-adjacent coplanar faces of one
//! material whose outline is one convex polygon are meshed as that polygon, so a wall
//! exported as two triangles gets no element boundary along its diagonal. Each such polygon
//! (or large face) is split into *patches* (shooters, `patch_size`) and each patch into
//! *elements* (receivers, `element_size`): convex quads into a bilinear grid, everything
//! else into triangles whose count follows their area (a triangle smaller than an element
//! stays whole; a sliver is bisected along its longest edge instead of cut into n² slivers).
//! Faces smaller than half a patch are *clustered* into shooters of about one patch (across
//! the facets of a curved surface too), each shooting through a planar proxy polygon of the
//! cluster's area, so the number of shooters grows with the scene's area, not its triangle
//! count (Cohen, Greenberg, Immel, Brock 1986, "An efficient radiosity approach for
//! realistic image synthesis": substructuring). Known error of a cluster's proxy: of the
//! order of the cluster's curvature times its size, like any patch's area-averaged
//! radiance.
//!
//! Default sizes come from an element budget ([`ELEMENT_BUDGET`]), not from the bounding
//! box alone: a unit cube and a city block get about the same number of elements.

pub mod adaptive;
mod build;
mod cluster;
pub mod discontinuity;
mod footprint;
mod interpolate;
mod spec;
pub mod surfaces;

pub use spec::MeshSpec;

use std::ops::Range;

use glam::DVec3;

use crate::geometry::bvh::TriangleInput;
use crate::geometry::polygon;
use crate::geometry::{Aabb, Bvh};
use crate::scene::{MaterialId, Rgb, Scene};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PatchId(pub u32);

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ElementId(pub u32);

/// Patch edge length in element sizes (48 mm patches over 12 mm elements in the Cornell
/// box). Patches shoot with their area-averaged unshot radiance, so a patch much larger than
/// the scale on which radiance varies spreads light wrongly: whole-wall patches put the
/// Cornell box 19 % off a path tracer, 96 mm patches 2.6 %. With 12 mm elements (image error
/// against `benches/data/cornell_256_ref.pfm`, `--unshot 1e-4`, CPU seconds on 2 cores):
/// 40 mm patches 1.67 % in 12.3 s, 48 mm 1.78 % in 9.2 s, 60 mm 1.90 % in 7.1 s. Every patch
/// costs one form-factor row, the bulk of a solve's time.
pub const PATCH_ELEMENTS: f64 = 4.0;

/// Elements the default element size aims at for the whole scene (both sides of a
/// two-sided scene count). The Cornell box gets about 19,000 at 11.8 mm, within 2 % of a
/// path tracer (README).
pub const ELEMENT_BUDGET: usize = 20_000;

/// Most elements a mesh may have (memory and time guard for a tiny `--element-size`).
pub const MAX_ELEMENTS: usize = 4_000_000;

/// A default element size: the edge length that gives about `budget` elements, counting a
/// face smaller than one element as one (a scene of more faces than the budget gets one
/// element per small face). Bisection on the estimate `Σ max(1, k A_f / s²)` per side
/// (k = 1 for convex quads, 2 for triangles and other polygons).
pub fn element_size_for_budget(scene: &Scene, budget: usize) -> f64 {
    let areas = cut_areas(scene);
    let total: f64 = areas.iter().sum();
    let diag = scene.bounds().diagonal();
    if !(total > 0.0 && total.is_finite() && diag > 0.0) {
        return if diag > 0.0 { diag / 80.0 } else { 1.0 };
    }
    let budget = budget.max(1) as f64;
    let count = |s: f64| count_at(scene, &areas, s);
    // count() falls as s grows; find the smallest s with count(s) <= budget.
    let (mut lo, mut hi) = ((total / budget).sqrt() * 1e-3, diag);
    if count(hi) > budget {
        // More faces than the budget: one element per small face, the large ones cut to
        // the size of an average face.
        return (total / scene.faces.len() as f64).sqrt().max(1e-300);
    }
    for _ in 0..80 {
        let mid = (lo * hi).sqrt();
        if count(mid) > budget {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// Per face, its area times the elements per s² [`build`] cuts it into: 1 for a convex
/// quad (squares of about s²), 2 for anything else (triangles of at most s²/2).
fn cut_areas(scene: &Scene) -> Vec<f64> {
    scene
        .faces
        .iter()
        .map(|f| {
            let per = if f.vertices.len() == 4 && polygon::is_convex(&f.vertices) {
                1.0
            } else {
                2.0
            };
            per * polygon::area(&f.vertices)
        })
        .collect()
}

/// `Σ max(1, k A_f / s²)` over the faces (both sides of a two-sided scene).
fn count_at(scene: &Scene, areas: &[f64], s: f64) -> f64 {
    let sides = if scene.two_sided { 2.0 } else { 1.0 };
    let s2 = s * s;
    sides
        * areas
            .iter()
            .map(|a| {
                if a.is_finite() {
                    (a / s2).max(1.0)
                } else {
                    1.0
                }
            })
            .sum::<f64>()
}

/// About how many elements [`Mesh::build`] makes of `scene` at element size `size`,
/// known before meshing so that a mesh too large for the memory budget is refused at once:
/// per face `max(1, k A / s² + P / 2s)`, the area term of [`element_size_for_budget`] plus
/// the part-elements along the perimeter `P` (a w × h quad cut into ⌈w/s⌉ × ⌈h/s⌉ squares
/// has about (w/s + ½)(h/s + ½)); discontinuity cuts and T-vertex repairs add more.
pub fn estimated_elements(scene: &Scene, size: f64) -> f64 {
    let sides = if scene.two_sided { 2.0 } else { 1.0 };
    let s2 = size * size;
    let per_face = |(f, a): (&crate::scene::Face, &f64)| {
        let n = f.vertices.len();
        let perimeter: f64 = (0..n)
            .map(|i| (f.vertices[(i + 1) % n] - f.vertices[i]).length())
            .sum();
        let count = a / s2 + perimeter / (2.0 * size);
        if count.is_finite() {
            count.max(1.0)
        } else {
            1.0
        }
    };
    sides
        * scene
            .faces
            .iter()
            .zip(&cut_areas(scene))
            .map(per_face)
            .sum::<f64>()
}

/// The element size at which cutting the faces larger than an element adds about `extra`
/// elements to the one each face gets (`Σ max(0, k A_f / s² − 1)` over the faces, `k` as in
/// [`element_size_for_budget`]): the mesh of a scene with more faces than its budget.
pub fn element_size_for_excess(scene: &Scene, extra: f64) -> f64 {
    let sides = if scene.two_sided { 2.0 } else { 1.0 };
    let mut weighted: Vec<f64> = cut_areas(scene)
        .into_iter()
        .filter(|a| a.is_finite() && *a > 0.0)
        .collect();
    let diag = scene.bounds().diagonal();
    if weighted.is_empty() || diag.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return 1.0;
    }
    // Largest first, with running sums: the faces cut at size s are a prefix, so each
    // step of the search costs a binary search, not a pass over every face.
    weighted.sort_unstable_by(|a, b| b.total_cmp(a));
    let prefix: Vec<f64> = std::iter::once(0.0)
        .chain(weighted.iter().scan(0.0, |sum, a| {
            *sum += a;
            Some(*sum)
        }))
        .collect();
    let excess = |s: f64| -> f64 {
        let s2 = s * s;
        let cut = weighted.partition_point(|&a| a > s2);
        sides * (prefix[cut] / s2 - cut as f64).max(0.0)
    };
    let (mut lo, mut hi) = (diag * 1e-9, diag);
    for _ in 0..100 {
        let mid = (lo * hi).sqrt();
        if excess(mid) > extra.max(1.0) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// Elements across the light sources' scale that the default mesh needs at most.
pub const ELEMENTS_PER_LIGHT: f64 = 20.0;

/// The default element size: [`element_size_for_budget`] with [`ELEMENT_BUDGET`], but no
/// finer than 1/[`ELEMENTS_PER_LIGHT`] of the light sources' scale (the square root of their
/// total area). Radiosity varies on the scale of the lights and of the distances between
/// surfaces; where the light is large (a lit ceiling) the budget need not be spent: a unit
/// cube lit by its whole ceiling gets 2,400 elements instead of 20,000. The Cornell box's
/// small light leaves the budget in charge.
pub fn default_element_size(scene: &Scene) -> f64 {
    let emitting: f64 = scene
        .faces
        .iter()
        .filter(|f| scene.materials[f.material.0 as usize].is_emitter())
        .map(|f| polygon::area(&f.vertices))
        .sum();
    let light_floor = emitting.sqrt() / ELEMENTS_PER_LIGHT;
    let budget = element_size_for_budget(scene, ELEMENT_BUDGET);
    if light_floor.is_finite() {
        budget.max(light_floor)
    } else {
        budget
    }
}

/// The default patch size for an element size: [`PATCH_ELEMENTS`] elements across.
pub fn default_patch_size(element_size: f64) -> f64 {
    element_size * PATCH_ELEMENTS
}

#[derive(Clone, Debug)]
pub struct Patch {
    /// Index into `Scene::faces` (the first face of a surface or cluster).
    pub face: usize,
    /// Index of that input face in file order.
    pub source_face: usize,
    /// Visibility-group id of the patch's triangles in the blocker BVH
    /// ([`Mesh::blocker_triangles`]): rays between a receiver and a shooter ignore their
    /// two groups (a planar surface, or a cluster of facets, cannot block itself).
    pub occluder: u32,
    pub material: MaterialId,
    /// The shooting polygon, counter-clockwise seen from the front (reversed for a back
    /// patch): the patch itself, or for a cluster of facets a planar proxy of the
    /// cluster's area (convex hull of its vertices projected on its mean plane, scaled).
    pub polygon: Vec<DVec3>,
    /// Points whose convex hull holds the whole patch (its elements and `polygon`): for
    /// shaft culling.
    pub bounds: Vec<DVec3>,
    pub normal: DVec3,
    pub area: f64,
    pub centroid: DVec3,
    pub elements: Range<u32>,
    /// True for the back side of a two-sided face.
    pub back: bool,
    /// Largest distance from the centroid to a point of `bounds` (bounding sphere radius).
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
    /// Index into `Scene::faces` of the face the element lies on.
    pub face: u32,
}

impl Element {
    pub fn corners(&self) -> &[DVec3] {
        &self.corners[..self.corner_count as usize]
    }
    pub fn vertex_ids(&self) -> &[u32] {
        &self.vertices[..self.corner_count as usize]
    }

    /// The point of the element at `(u1, u2)` in [0, 1)²: area-uniform for uniform
    /// `(u1, u2)` (a quad's two triangles picked by `u1` in proportion to their areas).
    pub fn point_at(&self, u1: f64, u2: f64) -> DVec3 {
        use crate::geometry::sampling::triangle_point;
        let c = self.corners();
        if c.len() == 3 {
            return triangle_point(c[0], c[1], c[2], u1, u2);
        }
        let a1 = polygon::area(&[c[0], c[1], c[2]]);
        let a2 = polygon::area(&[c[0], c[2], c[3]]);
        let split = a1 / (a1 + a2).max(f64::MIN_POSITIVE);
        if u1 < split {
            triangle_point(c[0], c[1], c[2], u1 / split.max(1e-300), u2)
        } else {
            triangle_point(
                c[0],
                c[2],
                c[3],
                (u1 - split) / (1.0 - split).max(1e-300),
                u2,
            )
        }
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
    pub patch_size: f64,
    /// Visibility group of each scene face (see [`Patch::occluder`]).
    pub face_occluder: Vec<u32>,
    /// Input faces joined into planar surfaces, and shooters made of clustered facets.
    pub surface_count: usize,
    pub cluster_count: usize,
    /// For each patch, the patch of the unrefined mesh it is part of (itself unless built
    /// by [`Mesh::build_refined`]): refinement levels are indexed by these.
    pub base_patch: Vec<u32>,
    t_vertices: Vec<TVertex>,
    /// Per vertex, the element weights of its value (CSR: `vertex_weights[start[v]..start[v+1]]`).
    vertex_weight_start: Vec<u32>,
    vertex_weights: Vec<(u32, f64)>,
}

#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    #[error("element size must be a positive finite number, got {0}")]
    BadElementSize(f64),
    #[error("patch size must be a positive finite number, got {0}")]
    BadPatchSize(f64),
    #[error(
        "element size {size} would make about {count} elements (limit {MAX_ELEMENTS}); use a larger --element-size"
    )]
    TooManyElements { size: f64, count: usize },
}

impl Mesh {
    /// The mesh of `scene` at the element size of `spec` when it has one; else at the size
    /// from its element budget ([`element_size_for_budget`]), or with no budget given
    /// [`default_element_size`]. The size from a budget is an estimate from face areas
    /// (merged outlines, slivers and small faces change the real count), so a mesh more
    /// than 5 % over the budget is rebuilt coarser, at most twice.
    fn build_for_budget(
        scene: &Scene,
        topo: &surfaces::Topology,
        spec: &MeshSpec,
    ) -> Result<Mesh, MeshError> {
        let budget = spec.max_elements;
        let target = budget.unwrap_or(ELEMENT_BUDGET).max(1) as f64;
        let mut size = match budget {
            Some(b) => element_size_for_budget(scene, b),
            None => default_element_size(scene),
        };
        let mut tries = 0;
        let build = |size: f64| {
            Mesh::build_from(
                scene,
                topo,
                size,
                spec.patch_for(size),
                &[],
                spec.discontinuity,
            )
        };
        // A face smaller than an element is one element: with more faces than the budget
        // the count cannot reach it, and coarser elements only coarsen the large faces.
        let min_count = (topo.planar_members().len() * if scene.two_sided { 2 } else { 1 }) as f64;
        if budget.is_none() && target < 1.05 * min_count {
            // The budget is below the one-element-per-surface floor: coarser elements would
            // only coarsen the few large faces (the atrium: 227 k elements at this size, 216 k
            // at 3.4× it, 5 s a try), so one meshing at the size that cuts them into about
            // 5 % more elements than the surfaces.
            return build(size.max(element_size_for_excess(scene, 0.05 * min_count)));
        }
        loop {
            let mesh = build(size)?;
            let count = mesh.elements.len() as f64;
            tries += 1;
            if count <= 1.05 * target || count <= 1.05 * min_count || tries == 3 {
                return Ok(mesh);
            }
            size *= (count / target).sqrt();
        }
    }

    pub fn patch(&self, id: PatchId) -> &Patch {
        &self.patches[id.0 as usize]
    }

    /// Area-weighted mean over each patch's elements of a per-element value
    /// (`Σ v A / A_p`, as shooting keeps a patch's radiosity); 0 for a patch of no area.
    pub fn patch_means(&self, values: &[Rgb]) -> Vec<Rgb> {
        (self.patches.iter())
            .map(|p| {
                let sum: Rgb = (p.elements.start..p.elements.end)
                    .map(|e| values[e as usize] * self.elements[e as usize].area)
                    .sum();
                if p.area > 0.0 {
                    sum / p.area
                } else {
                    Rgb::ZERO
                }
            })
            .collect()
    }

    /// Patches of the unrefined mesh ([`Mesh::base_patch`]): the length of refinement
    /// levels and of anything kept per base patch.
    pub fn base_count(&self) -> usize {
        self.base_patch
            .iter()
            .map(|&b| b as usize + 1)
            .max()
            .unwrap_or(0)
    }

    /// Axis-aligned bounds of all patches.
    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(self.patches.iter().flat_map(|p| p.bounds.iter()))
    }

    /// Triangles of the input faces for visibility queries, with ids = the face's
    /// visibility group ([`Patch::occluder`]). Faces, not patches: the hierarchy stays as
    /// small as the model (38 triangles for the Cornell box instead of one or two per
    /// patch).
    pub fn blocker_triangles(&self, scene: &Scene) -> Vec<TriangleInput> {
        self.blocker_triangles_where(scene, |_| true)
    }

    /// [`Mesh::blocker_triangles`] of the faces `keep` accepts.
    pub fn blocker_triangles_where(
        &self,
        scene: &Scene,
        keep: impl Fn(&crate::scene::Face) -> bool,
    ) -> Vec<TriangleInput> {
        self.blocker_input(scene, keep).0
    }

    /// The blockers with the face of each triangle.
    fn blocker_input(
        &self,
        scene: &Scene,
        keep: impl Fn(&crate::scene::Face) -> bool,
    ) -> (Vec<TriangleInput>, Vec<usize>) {
        face_triangles(scene, keep, |i| self.face_occluder[i])
    }

    /// The hierarchy over every face's triangles with the scene's cut-outs, each triangle's
    /// id its face's index. It needs only the scene, so it can be built while the mesh is;
    /// [`Mesh::blocker_bvh_from`] makes it the blockers' hierarchy.
    pub fn face_bvh(scene: &Scene) -> Bvh {
        let (mut input, faces) = face_triangles(scene, |_| true, |i| i as u32);
        let cuts = scene.cutouts();
        cuts.mark(scene, &mut input, |i| faces[i]);
        cuts.bvh(&input)
    }

    /// [`Mesh::blocker_bvh`] from the scene's [`Mesh::face_bvh`]: its ids relabelled from
    /// faces to occluder groups.
    pub fn blocker_bvh_from(&self, mut faces: Bvh) -> Bvh {
        faces.relabel(|f| self.face_occluder.get(f as usize).copied().unwrap_or(f));
        faces
    }

    /// The hierarchy over [`Mesh::blocker_triangles`] of the faces `keep` accepts, with the
    /// scene's cut-outs as holes ([`Scene::cutouts`]).
    pub fn blocker_bvh_where(
        &self,
        scene: &Scene,
        keep: impl Fn(&crate::scene::Face) -> bool,
    ) -> Bvh {
        let (mut input, faces) = self.blocker_input(scene, keep);
        let cuts = scene.cutouts();
        cuts.mark(scene, &mut input, |i| faces[i]);
        cuts.bvh(&input)
    }

    /// [`Mesh::blocker_bvh_where`] of every face.
    pub fn blocker_bvh(&self, scene: &Scene) -> Bvh {
        self.blocker_bvh_from(Mesh::face_bvh(scene))
    }

    /// The hierarchy over [`Mesh::display_triangles`], with the scene's cut-outs as holes.
    pub fn display_bvh(&self, scene: &Scene, two_sided: bool) -> Bvh {
        let mut input = self.display_triangles(two_sided);
        let cuts = scene.cutouts();
        cuts.mark(scene, &mut input, |i| {
            self.elements[self.triangle_element[i].0 as usize].face as usize
        });
        cuts.bvh(&input)
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
                cut: None,
            })
            .collect()
    }
}

/// The triangles of the faces `keep` accepts, with ids `id(face index)`, and the face of
/// each triangle.
fn face_triangles(
    scene: &Scene,
    keep: impl Fn(&crate::scene::Face) -> bool,
    id: impl Fn(usize) -> u32,
) -> (Vec<TriangleInput>, Vec<usize>) {
    let mut out = Vec::new();
    let mut faces = Vec::new();
    for (i, f) in scene.faces.iter().enumerate().filter(|(_, f)| keep(f)) {
        let v = &f.vertices;
        for t in polygon::triangulate(v) {
            out.push(TriangleInput {
                vertices: [v[t[0]], v[t[1]], v[t[2]]],
                id: id(i),
                cull_back: false,
                cut: None,
            });
            faces.push(i);
        }
    }
    (out, faces)
}

#[cfg(test)]
mod tests;
