//! A binned-SAH bounding-volume hierarchy over triangles (Wald 2007, "On fast
//! Construction of SAH-based Bounding Volume Hierarchies").
//!
//! Nodes are flattened depth-first; the left child directly follows its parent. Triangles
//! are stored as `(v0, e1, e2)` in `f32` for the Möller–Trumbore test. Each triangle carries a
//! caller-chosen `u32` id (a patch or element index) and whether back faces are culled.

use super::{Aabb, Ray, shaft::Shaft};
use glam::{DVec3, Vec3};

const BINS: usize = 12;
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
}

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
}

/// Bounding-volume hierarchy over triangles.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    tris: Vec<Tri>,
}

impl Bvh {
    /// Builds the hierarchy. Degenerate (zero-area) triangles are kept but never hit.
    pub fn build(input: &[TriangleInput]) -> Bvh {
        let n = input.len();
        if n == 0 {
            return Bvh::default();
        }
        let mut boxes = Vec::with_capacity(n);
        let mut centers = Vec::with_capacity(n);
        for t in input {
            let b = Aabb::from_points(t.vertices.iter());
            centers.push(b.center());
            boxes.push(b);
        }
        let mut idx: Vec<u32> = (0..n as u32).collect();
        let mut nodes = Vec::with_capacity(2 * n);
        build_rec(&mut nodes, &mut idx, 0, n, &boxes, &centers);
        let tris = idx
            .iter()
            .map(|&i| {
                let t = &input[i as usize];
                let v0 = t.vertices[0].as_vec3();
                Tri {
                    v0,
                    e1: t.vertices[1].as_vec3() - v0,
                    e2: t.vertices[2].as_vec3() - v0,
                    id: t.id,
                    cull_back: t.cull_back,
                }
            })
            .collect();
        Bvh { nodes, tris }
    }

    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// Closest hit with `t` in `(t_min, t_max)`.
    pub fn closest_hit(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<Hit> {
        if self.nodes.is_empty() {
            return None;
        }
        let o = ray.origin.as_vec3();
        let d = ray.dir.as_vec3();
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
                    if let Some((t, u, v, front)) = intersect(tri, o, d, t_min as f32, best_t) {
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
        best.map(|(k, u, v, front)| Hit {
            t: best_t as f64,
            id: self.tris[k as usize].id,
            triangle: k,
            u: u as f64,
            v: v as f64,
            front,
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
        let o = ray.origin.as_vec3();
        let d = ray.dir.as_vec3();
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
                        let mut t = *tri;
                        t.cull_back = false;
                        if intersect(&t, o, d, t_min, t_max).is_some() {
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
            if !shaft.excludes_box(nd.min.as_dvec3(), nd.max.as_dvec3()) {
                if nd.count > 0 {
                    let first = nd.first_or_right as usize;
                    for (k, tri) in self.tris[first..first + nd.count as usize]
                        .iter()
                        .enumerate()
                    {
                        if tri.id == ignore[0] || tri.id == ignore[1] {
                            continue;
                        }
                        let v0 = tri.v0.as_dvec3();
                        let v = [v0, v0 + tri.e1.as_dvec3(), v0 + tri.e2.as_dvec3()];
                        if !shaft.excludes_triangle(v) {
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

    /// Vertices of the stored triangle `k` (as stored, in `f32` precision).
    pub fn stored_triangle(&self, k: u32) -> [DVec3; 3] {
        let t = &self.tris[k as usize];
        let v0 = t.v0.as_dvec3();
        [v0, v0 + t.e1.as_dvec3(), v0 + t.e2.as_dvec3()]
    }

    /// Any hit among the stored triangles `candidates` (from [`Bvh::collect_in_shaft`]),
    /// both faces counted, with `t` in `(t_min, t_max)`.
    pub fn any_hit_among(&self, candidates: &[u32], ray: &Ray, t_min: f64, t_max: f64) -> bool {
        let o = ray.origin.as_vec3();
        let d = ray.dir.as_vec3();
        let (t_min, t_max) = (t_min as f32, t_max as f32);
        candidates.iter().any(|&k| {
            let mut t = self.tris[k as usize];
            t.cull_back = false;
            intersect(&t, o, d, t_min, t_max).is_some()
        })
    }
}

#[inline]
fn slab(n: &Node, o: Vec3, inv: Vec3, t_max: f32) -> Option<f32> {
    let t0 = (n.min - o) * inv;
    let t1 = (n.max - o) * inv;
    let tmin = t0.min(t1).max_element().max(0.0);
    let tmax = t0.max(t1).min_element().min(t_max);
    // NaN (0 * inf) compares false, which conservatively keeps the node.
    if tmin <= tmax || tmin.is_nan() || tmax.is_nan() {
        Some(tmin)
    } else {
        None
    }
}

#[inline]
fn intersect(tri: &Tri, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> Option<(f32, f32, f32, bool)> {
    let p = d.cross(tri.e2);
    let det = tri.e1.dot(p);
    if det.abs() < 1e-20 || (tri.cull_back && det < 0.0) {
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

fn build_rec(
    nodes: &mut Vec<Node>,
    idx: &mut [u32],
    start: usize,
    end: usize,
    boxes: &[Aabb],
    centers: &[DVec3],
) -> u32 {
    let me = nodes.len() as u32;
    let mut bounds = Aabb::EMPTY;
    let mut cbounds = Aabb::EMPTY;
    for &i in &idx[start..end] {
        bounds.grow(boxes[i as usize].min);
        bounds.grow(boxes[i as usize].max);
        cbounds.grow(centers[i as usize]);
    }
    nodes.push(Node {
        min: bounds.min.as_vec3(),
        max: bounds.max.as_vec3(),
        first_or_right: start as u32,
        count: (end - start) as u32,
    });
    let count = end - start;
    if count <= MAX_LEAF {
        return me;
    }
    let mid = match sah_split(idx, start, end, boxes, centers, &bounds, &cbounds) {
        Some(m) => m,
        None => {
            if count <= 16 {
                return me;
            }
            // All centres coincide or SAH says no: split in the middle of the list.
            start + count / 2
        }
    };
    let _left = build_rec(nodes, idx, start, mid, boxes, centers);
    let right = build_rec(nodes, idx, mid, end, boxes, centers);
    let n = &mut nodes[me as usize];
    n.count = 0;
    n.first_or_right = right;
    me
}

fn area(b: &Aabb) -> f64 {
    if b.is_empty() {
        return 0.0;
    }
    let d = b.max - b.min;
    d.x * d.y + d.y * d.z + d.z * d.x
}

fn sah_split(
    idx: &mut [u32],
    start: usize,
    end: usize,
    boxes: &[Aabb],
    centers: &[DVec3],
    bounds: &Aabb,
    cbounds: &Aabb,
) -> Option<usize> {
    let count = end - start;
    let extent = cbounds.max - cbounds.min;
    let mut best = (f64::INFINITY, 0usize, 0usize);
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        let mut bins = [(Aabb::EMPTY, 0usize); BINS];
        let scale = BINS as f64 / extent[axis];
        let bin_of = |c: DVec3| (((c[axis] - cbounds.min[axis]) * scale) as usize).min(BINS - 1);
        for &i in &idx[start..end] {
            let b = bin_of(centers[i as usize]);
            bins[b].0.grow(boxes[i as usize].min);
            bins[b].0.grow(boxes[i as usize].max);
            bins[b].1 += 1;
        }
        let mut right_area = [0.0; BINS];
        let mut right_count = [0usize; BINS];
        let mut acc = Aabb::EMPTY;
        let mut n = 0;
        for b in (1..BINS).rev() {
            if !bins[b].0.is_empty() {
                acc.grow(bins[b].0.min);
                acc.grow(bins[b].0.max);
            }
            n += bins[b].1;
            right_area[b] = area(&acc);
            right_count[b] = n;
        }
        let mut acc = Aabb::EMPTY;
        let mut n = 0;
        for b in 0..BINS - 1 {
            if !bins[b].0.is_empty() {
                acc.grow(bins[b].0.min);
                acc.grow(bins[b].0.max);
            }
            n += bins[b].1;
            let cost = area(&acc) * n as f64 + right_area[b + 1] * right_count[b + 1] as f64;
            if n > 0 && right_count[b + 1] > 0 && cost < best.0 {
                best = (cost, axis, b);
            }
        }
    }
    if !best.0.is_finite() {
        return None;
    }
    let leaf_cost = area(bounds) * count as f64;
    if count <= MAX_LEAF * 4 && best.0 + area(bounds) * 0.5 >= leaf_cost {
        return None;
    }
    let (axis, split_bin) = (best.1, best.2);
    let scale = BINS as f64 / extent[axis];
    let slice = &mut idx[start..end];
    let mut i = 0;
    let mut j = slice.len();
    while i < j {
        let c = centers[slice[i] as usize];
        let b = (((c[axis] - cbounds.min[axis]) * scale) as usize).min(BINS - 1);
        if b <= split_bin {
            i += 1;
        } else {
            j -= 1;
            slice.swap(i, j);
        }
    }
    if i == 0 || i == slice.len() {
        None
    } else {
        Some(start + i)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Rng;

    fn brute_closest(tris: &[TriangleInput], ray: &Ray) -> Option<(f64, u32)> {
        let mut best: Option<(f64, u32)> = None;
        for (k, t) in tris.iter().enumerate() {
            let v0 = t.vertices[0].as_vec3();
            let tri = Tri {
                v0,
                e1: t.vertices[1].as_vec3() - v0,
                e2: t.vertices[2].as_vec3() - v0,
                id: k as u32,
                cull_back: t.cull_back,
            };
            let limit = best.map_or(f32::INFINITY, |b| b.0 as f32);
            if let Some((tt, ..)) =
                intersect(&tri, ray.origin.as_vec3(), ray.dir.as_vec3(), 0.0, limit)
            {
                best = Some((tt as f64, t.id));
            }
        }
        best
    }

    #[test]
    fn bvh_matches_brute_force() {
        let mut rng = Rng::new(3, 0);
        let mut r = || rng.next_f64();
        let tris: Vec<TriangleInput> = (0..500)
            .map(|i| {
                let c = DVec3::new(r(), r(), r()) * 10.0;
                let mut v = || c + DVec3::new(r() - 0.5, r() - 0.5, r() - 0.5);
                TriangleInput {
                    vertices: [v(), v(), v()],
                    id: i,
                    cull_back: false,
                }
            })
            .collect();
        let bvh = Bvh::build(&tris);
        let mut rng = Rng::new(4, 0);
        let mut hits = 0;
        for _ in 0..2000 {
            let o = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 12.0 - 1.0;
            let d = DVec3::new(
                rng.next_f64() - 0.5,
                rng.next_f64() - 0.5,
                rng.next_f64() - 0.5,
            );
            let ray = Ray::new(o, d);
            let a = bvh.closest_hit(&ray, 0.0, f64::INFINITY);
            let b = brute_closest(&tris, &ray);
            assert_eq!(a.map(|h| h.id), b.map(|h| h.1));
            assert_eq!(bvh.any_hit(&ray, 0.0, f64::INFINITY), b.is_some());
            hits += a.is_some() as usize;
        }
        assert!(hits > 200, "test rays should hit something: {hits}");
    }

    #[test]
    fn culling_and_front_flag() {
        let tri = TriangleInput {
            vertices: [DVec3::ZERO, DVec3::X, DVec3::Y],
            id: 9,
            cull_back: true,
        };
        let bvh = Bvh::build(&[tri]);
        let down = Ray::new(DVec3::new(0.2, 0.2, 1.0), DVec3::NEG_Z);
        let up = Ray::new(DVec3::new(0.2, 0.2, -1.0), DVec3::Z);
        let h = bvh.closest_hit(&down, 0.0, 10.0).expect("front hit");
        assert!(h.front && (h.t - 1.0).abs() < 1e-6 && h.id == 9);
        assert!(bvh.closest_hit(&up, 0.0, 10.0).is_none());
        assert!(
            bvh.any_hit(&up, 0.0, 10.0),
            "back faces still block shadow rays"
        );
        assert!(!bvh.any_hit(&down, 0.0, 0.5));
    }
}
