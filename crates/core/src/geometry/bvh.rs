//! A binned-SAH bounding-volume hierarchy over triangles (Wald 2007, "On fast
//! Construction of SAH-based Bounding Volume Hierarchies").
//!
//! Nodes are flattened depth-first; the left child directly follows its parent. Triangles
//! are stored as `(v0, e1, e2)` in `f32` for the Möller–Trumbore test. Each triangle carries a
//! caller-chosen `u32` id (a patch or element index) and whether back faces are culled.
//!
//! Everything is stored and tested in coordinates normalised by the input's bounding box
//! (centre at the origin, diagonal 1), so the `f32` rounding of a vertex, the tree and every
//! hit decision are the same whatever the scene's unit: a scene at 1e-3 or 1e4 times the
//! size gives the same answers, not answers that differ wherever `f32` rounds `0.45` and
//! `0.00045` differently (a visibility decision flipped between scales).

use std::sync::Arc;

use super::{
    Aabb, Ray,
    alpha_mask::{AlphaMask, CutOut},
    shaft::Shaft,
};
use glam::{DVec3, Vec3};

mod build;
mod packet;

pub use self::packet::{PACKET, ShadowRay};

use self::build::{PARALLEL_MIN, build_tree};

const BINS: usize = 32;
const MAX_LEAF: usize = 4;

#[derive(Clone, Copy, Debug)]
struct Node {
    min: Vec3,
    /// Leaf: index of the first triangle; interior: index of the right child.
    first_or_right: u32,
    max: Vec3,
    /// Number of triangles in a leaf; 0 for interior nodes.
    count: u32,
}

#[derive(Clone, Copy, Debug)]
struct Tri {
    v0: Vec3,
    e1: Vec3,
    e2: Vec3,
    id: u32,
    cull_back: bool,
    /// Index into [`Bvh::cuts`], or [`NO_CUT`] for a triangle that is opaque everywhere.
    cut: u32,
}

/// [`Tri::cut`] of a triangle without a cut-out.
const NO_CUT: u32 = u32::MAX;

/// A closest-hit result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit.
    pub t: f64,
    /// Id given to the triangle at build time.
    pub id: u32,
    /// Index of the stored triangle (for [`Bvh::stored_triangle`]).
    pub triangle: u32,
    /// Barycentric coordinates of the hit (weights of v1 and v2).
    pub u: f64,
    pub v: f64,
    /// True when the ray hit the triangle's front (counter-clockwise) side.
    pub front: bool,
}

/// Input triangle for [`Bvh::build`].
#[derive(Clone, Copy, Debug)]
pub struct TriangleInput {
    pub vertices: [DVec3; 3],
    pub id: u32,
    pub cull_back: bool,
    /// Where the triangle is a hole (alpha map): rays pass there ([`Bvh::build_with_masks`]).
    pub cut: Option<CutOut>,
}

/// Bounding-volume hierarchy over triangles.
#[derive(Clone, Debug)]
pub struct Bvh {
    nodes: Vec<Node>,
    tris: Vec<Tri>,
    /// World point at the normalised origin (the centre of the input's bounding box).
    origin: DVec3,
    /// World length of one normalised unit (the input's bounding-box diagonal).
    scale: f64,
    /// The cut-outs of the triangles that have one, and the masks they read.
    cuts: Vec<CutOut>,
    masks: Arc<[AlphaMask]>,
}

impl Default for Bvh {
    fn default() -> Self {
        Bvh {
            nodes: Vec::new(),
            tris: Vec::new(),
            origin: DVec3::ZERO,
            scale: 1.0,
            cuts: Vec::new(),
            masks: Arc::new([]),
        }
    }
}

impl Bvh {
    /// Builds the hierarchy. Degenerate (zero-area) triangles are kept but never hit.
    /// Triangles are opaque everywhere (their [`TriangleInput::cut`] is ignored).
    pub fn build(input: &[TriangleInput]) -> Bvh {
        Bvh::build_with_masks(input, Arc::new([]))
    }

    /// The same hierarchy with each triangle's id `i` replaced by `map(i)`. Ids are carried,
    /// never used to build, so this is the hierarchy the new ids would have built (a
    /// hierarchy over a scene's faces can be built before the faces' groups are known).
    pub fn relabel(&mut self, map: impl Fn(u32) -> u32) {
        for t in &mut self.tris {
            t.id = map(t.id);
        }
    }

    /// [`Bvh::build`] with cut-outs: a triangle whose `cut` names one of `masks` is a hole
    /// wherever that mask is transparent, for every query. A `cut` naming no mask is ignored.
    pub fn build_with_masks(input: &[TriangleInput], masks: Arc<[AlphaMask]>) -> Bvh {
        let n = input.len();
        if n == 0 {
            return Bvh::default();
        }
        let mut all = Aabb::EMPTY;
        for t in input {
            for v in &t.vertices {
                if v.is_finite() {
                    all.grow(*v);
                }
            }
        }
        let diagonal = all.diagonal();
        let (origin, scale) = if diagonal > 0.0 && diagonal.is_finite() {
            (all.center(), diagonal)
        } else {
            (
                if all.is_empty() {
                    DVec3::ZERO
                } else {
                    all.center()
                },
                1.0,
            )
        };
        // Normalised on the fly (not kept per triangle): the build's memory is what a
        // million-element render peaks at.
        let local = |t: &TriangleInput| t.vertices.map(|v| (v - origin) / scale);
        let mut boxes = Vec::with_capacity(n);
        let mut centers = Vec::with_capacity(n);
        for t in input {
            let v = local(t);
            let b = Aabb::from_points(v.iter());
            centers.push(b.center());
            boxes.push(b);
        }
        let mut idx: Vec<u32> = (0..n as u32).collect();
        let mut nodes = build_tree(&mut idx, &boxes, &centers, PARALLEL_MIN);
        drop((boxes, centers));
        nodes.shrink_to_fit();
        let mut cuts = Vec::new();
        let tris = idx
            .iter()
            .map(|&i| {
                let t = &input[i as usize];
                let v = local(t);
                let v0 = v[0].as_vec3();
                let cut = match t.cut {
                    Some(c) if (c.mask as usize) < masks.len() => {
                        cuts.push(c);
                        cuts.len() as u32 - 1
                    }
                    _ => NO_CUT,
                };
                Tri {
                    v0,
                    e1: v[1].as_vec3() - v0,
                    e2: v[2].as_vec3() - v0,
                    id: t.id,
                    cull_back: t.cull_back,
                    cut,
                }
            })
            .collect();
        Bvh {
            nodes,
            tris,
            origin,
            scale,
            cuts,
            masks,
        }
    }

    /// A world point in normalised coordinates, rounded to `f32`.
    fn local_point(&self, p: DVec3) -> Vec3 {
        ((p - self.origin) / self.scale).as_vec3()
    }

    /// A world direction (or offset) in normalised coordinates, rounded to `f32`; ray
    /// parameters `t` are the same in both.
    fn local_dir(&self, d: DVec3) -> Vec3 {
        (d / self.scale).as_vec3()
    }

    /// A normalised point back in world coordinates.
    fn world_point(&self, p: Vec3) -> DVec3 {
        p.as_dvec3() * self.scale + self.origin
    }

    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// Whether a hit at barycentrics `(u, v)` of `tri` falls in a hole of its cut-out.
    #[inline]
    fn is_hole(&self, tri: &Tri, u: f32, v: f32) -> bool {
        if tri.cut == NO_CUT {
            return false;
        }
        let c = &self.cuts[tri.cut as usize];
        !self.masks[c.mask as usize].opaque(c.uv_at(u, v))
    }

    /// Whether any triangle has a cut-out.
    pub fn has_cutouts(&self) -> bool {
        !self.cuts.is_empty()
    }

    /// Whether stored triangle `k` has a cut-out (holes that rays pass).
    pub fn is_cut(&self, k: u32) -> bool {
        self.tris.get(k as usize).is_some_and(|t| t.cut != NO_CUT)
    }

    /// Closest hit with `t` in `(t_min, t_max)`.
    pub fn closest_hit(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<Hit> {
        if self.nodes.is_empty() {
            return None;
        }
        let o = self.local_point(ray.origin);
        let d = self.local_dir(ray.dir);
        let inv = d.recip();
        let mut best_t = t_max as f32;
        let mut best: Option<(u32, f32, f32, bool)> = None;
        let mut stack = [0u32; 64];
        let mut sp = 0usize;
        let mut node = 0u32;
        loop {
            let nd = &self.nodes[node as usize];
            if nd.count > 0 {
                let first = nd.first_or_right as usize;
                for k in first..first + nd.count as usize {
                    let tri = &self.tris[k];
                    if let Some((t, u, v, front)) =
                        intersect(tri, tri.cull_back, o, d, t_min as f32, best_t)
                        && !self.is_hole(tri, u, v)
                    {
                        best_t = t;
                        best = Some((k as u32, u, v, front));
                    }
                }
            } else {
                let left = node + 1;
                let right = nd.first_or_right;
                let tl = slab(&self.nodes[left as usize], o, inv, best_t);
                let tr = slab(&self.nodes[right as usize], o, inv, best_t);
                match (tl, tr) {
                    (Some(a), Some(b)) => {
                        let (near, far) = if a <= b { (left, right) } else { (right, left) };
                        if sp < stack.len() {
                            stack[sp] = far;
                            sp += 1;
                        }
                        node = near;
                        continue;
                    }
                    (Some(_), None) => {
                        node = left;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = right;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            if sp == 0 {
                break;
            }
            sp -= 1;
            node = stack[sp];
        }
        best.map(|(k, u, v, front)| {
            // The hit found in f32, its parameters recomputed in f64 from the same stored
            // triangle: shading interpolates with (u, v), and f32 barycentrics carry ~1e-7
            // of noise (more at grazing angles) that depends on the last bit of the ray,
            // so the same view in another unit was shaded 1e-6 differently.
            let tri = &self.tris[k as usize];
            let (o64, d64) = (
                (ray.origin - self.origin) / self.scale,
                ray.dir / self.scale,
            );
            let (t, u, v) = refine(tri, o64, d64).unwrap_or((best_t as f64, u as f64, v as f64));
            Hit {
                t,
                id: tri.id,
                triangle: k,
                u,
                v,
                front,
            }
        })
    }

    /// True when any triangle is hit with `t` in `(t_min, t_max)` (shadow ray).
    pub fn any_hit(&self, ray: &Ray, t_min: f64, t_max: f64) -> bool {
        self.any_hit_except(ray, t_min, t_max, [u32::MAX; 2])
    }

    /// Like [`Bvh::any_hit`], ignoring triangles whose id is in `ignore` (the two planar
    /// patches a shadow ray joins cannot block it, and skipping them makes the test immune to
    /// the ray's end points lying a hair behind their own surface).
    pub fn any_hit_except(&self, ray: &Ray, t_min: f64, t_max: f64, ignore: [u32; 2]) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let o = self.local_point(ray.origin);
        let d = self.local_dir(ray.dir);
        let inv = d.recip();
        let (t_min, t_max) = (t_min as f32, t_max as f32);
        let mut stack = [0u32; 64];
        let mut sp = 0usize;
        let mut node = 0u32;
        loop {
            let nd = &self.nodes[node as usize];
            if slab(nd, o, inv, t_max).is_some() {
                if nd.count > 0 {
                    let first = nd.first_or_right as usize;
                    for tri in &self.tris[first..first + nd.count as usize] {
                        if tri.id == ignore[0] || tri.id == ignore[1] {
                            continue;
                        }
                        // Shadow rays ignore culling: a back face still blocks light.
                        if let Some((_, u, v, _)) = intersect(tri, false, o, d, t_min, t_max)
                            && !self.is_hole(tri, u, v)
                        {
                            return true;
                        }
                    }
                } else {
                    if sp < stack.len() {
                        stack[sp] = nd.first_or_right;
                        sp += 1;
                    }
                    node += 1;
                    continue;
                }
            }
            if sp == 0 {
                return false;
            }
            sp -= 1;
            node = stack[sp];
        }
    }
    /// Stored indices of the triangles that may cut `shaft` (see [`Shaft`]), skipping ids in
    /// `ignore`. Returns `false` (with `out` incomplete) once more than `limit` were found.
    pub fn collect_in_shaft(
        &self,
        shaft: &Shaft,
        ignore: [u32; 2],
        limit: usize,
        out: &mut Vec<u32>,
    ) -> bool {
        out.clear();
        if self.nodes.is_empty() {
            return true;
        }
        let mut stack = [0u32; 64];
        let mut sp = 0usize;
        let mut node = 0u32;
        loop {
            let nd = &self.nodes[node as usize];
            if !shaft.excludes_box(self.world_point(nd.min), self.world_point(nd.max)) {
                if nd.count > 0 {
                    let first = nd.first_or_right as usize;
                    for (k, tri) in self.tris[first..first + nd.count as usize]
                        .iter()
                        .enumerate()
                    {
                        if tri.id == ignore[0] || tri.id == ignore[1] {
                            continue;
                        }
                        if !shaft.excludes_triangle(self.stored_triangle((first + k) as u32)) {
                            if out.len() >= limit {
                                return false;
                            }
                            out.push((first + k) as u32);
                        }
                    }
                } else {
                    if sp < stack.len() {
                        stack[sp] = nd.first_or_right;
                        sp += 1;
                    } else {
                        // Too deep to remember the other side: give up (caller uses the BVH).
                        return false;
                    }
                    node += 1;
                    continue;
                }
            }
            if sp == 0 {
                return true;
            }
            sp -= 1;
            node = stack[sp];
        }
    }

    /// Vertices of the stored triangle `k` in world coordinates (as stored: `f32`
    /// precision relative to the scene's bounding box, whatever its unit).
    pub fn stored_triangle(&self, k: u32) -> [DVec3; 3] {
        let t = &self.tris[k as usize];
        let v0 = t.v0.as_dvec3();
        [v0, v0 + t.e1.as_dvec3(), v0 + t.e2.as_dvec3()].map(|v| v * self.scale + self.origin)
    }

    /// Any hit among the stored triangles `candidates` (from [`Bvh::collect_in_shaft`]),
    /// both faces counted, with `t` in `(t_min, t_max)`.
    pub fn any_hit_among(&self, candidates: &[u32], ray: &Ray, t_min: f64, t_max: f64) -> bool {
        let o = self.local_point(ray.origin);
        let d = self.local_dir(ray.dir);
        let (t_min, t_max) = (t_min as f32, t_max as f32);
        candidates.iter().any(|&k| {
            let t = &self.tris[k as usize];
            intersect(t, false, o, d, t_min, t_max)
                .is_some_and(|(_, u, v, _)| !self.is_hole(t, u, v))
        })
    }
}

/// The ray parameter and barycentrics of `tri`'s plane hit, in f64 (no inside test: the
/// caller found the hit in f32 already). `None` for a ray parallel to the plane.
fn refine(tri: &Tri, o: DVec3, d: DVec3) -> Option<(f64, f64, f64)> {
    let (v0, e1, e2) = (tri.v0.as_dvec3(), tri.e1.as_dvec3(), tri.e2.as_dvec3());
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv_det = 1.0 / det;
    let s = o - v0;
    let u = s.dot(p) * inv_det;
    let q = s.cross(e1);
    let v = d.dot(q) * inv_det;
    let t = e2.dot(q) * inv_det;
    // Barycentrics kept in the triangle (the f32 test put the hit there).
    let (u, v) = (u.clamp(0.0, 1.0), v.clamp(0.0, 1.0));
    let excess = (u + v - 1.0).max(0.0) * 0.5;
    Some((t, u - excess, v - excess))
}

#[inline]
fn slab(n: &Node, o: Vec3, inv: Vec3, t_max: f32) -> Option<f32> {
    let t0 = (n.min - o) * inv;
    let t1 = (n.max - o) * inv;
    // A NaN lane (0 * inf: the origin on a slab's plane, the direction along it) is
    // skipped by `f32::min`/`max`, which keeps the node. `tmin` is never NaN after
    // `max(0.0)`, nor `tmax` after `min(t_max)` unless `t_max` is NaN, and then no triangle
    // test passes anyway: one comparison decides (two tests and branches less per box).
    let tmin = t0.min(t1).max_element().max(0.0);
    let tmax = t0.max(t1).min_element().min(t_max);
    if tmin <= tmax { Some(tmin) } else { None }
}

/// Möller–Trumbore; `cull_back` skips back faces (closest hits pass the triangle's own flag,
/// shadow rays `false`: a back face still blocks light).
#[inline]
fn intersect(
    tri: &Tri,
    cull_back: bool,
    o: Vec3,
    d: Vec3,
    t_min: f32,
    t_max: f32,
) -> Option<(f32, f32, f32, bool)> {
    let p = d.cross(tri.e2);
    let det = tri.e1.dot(p);
    if det.abs() < 1e-20 || (cull_back && det < 0.0) {
        return None;
    }
    let inv_det = 1.0 / det;
    let s = o - tri.v0;
    let u = s.dot(p) * inv_det;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(tri.e1);
    let v = d.dot(q) * inv_det;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = tri.e2.dot(q) * inv_det;
    if t > t_min && t < t_max {
        // det > 0 means the ray runs against the normal e1 × e2: a front-face hit.
        Some((t, u, v, det > 0.0))
    } else {
        None
    }
}

#[cfg(test)]
mod tests;
