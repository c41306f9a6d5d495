//! Shadow rays traced as a packet: up to [`PACKET`] rays walk the tree together, each node
//! and each leaf's triangles loaded once for all of them (Wald, Slusallek, Benthin & Wagner
//! 2001, "Interactive Rendering with Coherent Ray Tracing").
//!
//! A link's rays run between two small regions of the scene and visit nearly the same
//! nodes, and on a large scene a shadow ray's time is mostly waiting on memory (the first
//! load of a node or leaf triangle): four rays that share the loads cost little more than
//! one. Each ray is answered exactly as [`Bvh::any_hit_except`] answers it alone: it is
//! tested at a node only if it passed every box above it (the mask carried on the stack),
//! and against a triangle only in a leaf whose box it passed, with the same `f32` tests.

use super::{Bvh, NO_CUT, Tri};
use crate::geometry::Ray;
use glam::{Vec3, Vec4};

/// Most rays in one packet.
pub const PACKET: usize = 4;

/// One shadow ray of a packet: the segment `origin + t·dir` and the two ids it ignores (see
/// [`Bvh::any_hit_except`]).
#[derive(Clone, Copy, Debug)]
pub struct ShadowRay {
    pub ray: Ray,
    pub ignore: [u32; 2],
}

impl Bvh {
    /// [`Bvh::any_hit_except`] for each of up to [`PACKET`] rays, traced together: bit `k`
    /// of the result is set where ray `k` is blocked, the same answer as alone.
    ///
    /// # Panics
    /// If more than [`PACKET`] rays are given.
    pub fn any_hit_packet(&self, rays: &[ShadowRay], t_min: f64, t_max: f64) -> u8 {
        let n = rays.len();
        assert!(n <= PACKET, "{n} rays in a packet of {PACKET}");
        if self.nodes.is_empty() || n == 0 {
            return 0;
        }
        let mut o = [Vec3::ZERO; PACKET];
        let mut d = [Vec3::ZERO; PACKET];
        let mut inv = [Vec3::ZERO; PACKET];
        for (k, r) in rays.iter().enumerate() {
            o[k] = self.local_point(r.ray.origin);
            d[k] = self.local_dir(r.ray.dir);
            inv[k] = d[k].recip();
        }
        let (t_min, t_max) = (t_min as f32, t_max as f32);
        let lanes = Lanes::new(&o[..n], &d[..n], &inv[..n]);
        let all = ((1u16 << n) - 1) as u8;
        let mut blocked = 0u8;
        // Each entry: a node and the rays that passed every box above it.
        let mut stack = [(0u32, 0u8); 64];
        let mut sp = 0usize;
        let (mut node, mut mask) = (0u32, all);
        loop {
            let nd = &self.nodes[node as usize];
            let pass = lanes.slab(nd.min, nd.max, t_max) & mask & !blocked;
            if pass != 0 {
                if nd.count == 0 {
                    if sp < stack.len() {
                        stack[sp] = (nd.first_or_right, pass);
                        sp += 1;
                    }
                    node += 1;
                    mask = pass;
                    continue;
                }
                let first = nd.first_or_right as usize;
                for tri in &self.tris[first..first + nd.count as usize] {
                    let mut want = pass & !blocked;
                    for (k, r) in rays.iter().enumerate() {
                        if tri.id == r.ignore[0] || tri.id == r.ignore[1] {
                            want &= !(1 << k);
                        }
                    }
                    if want == 0 {
                        continue;
                    }
                    // Shadow rays ignore culling: a back face still blocks light.
                    let (hit, u, v) = lanes.intersect(tri, t_min, t_max);
                    let mut hit = hit & want;
                    if hit != 0 && tri.cut != NO_CUT {
                        for k in 0..n {
                            if hit & (1 << k) != 0 && self.is_hole(tri, u[k], v[k]) {
                                hit &= !(1 << k);
                            }
                        }
                    }
                    blocked |= hit;
                    if pass & !blocked == 0 {
                        break;
                    }
                }
                if blocked == all {
                    return blocked;
                }
            }
            if sp == 0 {
                return blocked;
            }
            sp -= 1;
            (node, mask) = stack[sp];
        }
    }
}

/// A packet's origins, directions and inverse directions by axis, one ray a lane, so that a
/// node's box or a triangle is tested against all of them at once (`Vec4`: four lanes in
/// one SSE register on x86).
struct Lanes {
    o: [Vec4; 3],
    d: [Vec4; 3],
    inv: [Vec4; 3],
}

impl Lanes {
    /// Lanes past the packet's rays repeat its first ray (their bits are masked off).
    fn new(o: &[Vec3], d: &[Vec3], inv: &[Vec3]) -> Self {
        let lane = |v: &[Vec3], axis: usize| {
            Vec4::from_array(std::array::from_fn(|k| v[k.min(v.len() - 1)][axis]))
        };
        Lanes {
            o: [0, 1, 2].map(|a| lane(o, a)),
            d: [0, 1, 2].map(|a| lane(d, a)),
            inv: [0, 1, 2].map(|a| lane(inv, a)),
        }
    }

    /// Bit `k` set where ray `k` passes the box `[lo, hi]` before `t_max`: [`super::slab`]
    /// for each lane, with the same operations in the same order. `Vec4::min` and `max` are
    /// `a < b ? a : b` and `a > b ? a : b` (`minps`, `maxps`), as `Vec3`'s per-element
    /// `min`/`max` and `min_element`/`max_element` are; the last `max(0)` and `min(t_max)`
    /// give the number where the lane is NaN, as `f32::max`/`min` do; so every lane's
    /// answer is the scalar test's, NaN lanes included.
    #[inline]
    fn slab(&self, lo: Vec3, hi: Vec3, t_max: f32) -> u8 {
        let t = |axis: usize| {
            let t0 = (Vec4::splat(lo[axis]) - self.o[axis]) * self.inv[axis];
            let t1 = (Vec4::splat(hi[axis]) - self.o[axis]) * self.inv[axis];
            (t0.min(t1), t0.max(t1))
        };
        let ((nx, fx), (ny, fy), (nz, fz)) = (t(0), t(1), t(2));
        let tmin = nx.max(ny).max(nz).max(Vec4::ZERO);
        let tmax = fx.min(fy).min(fz).min(Vec4::splat(t_max));
        tmin.cmple(tmax).bitmask() as u8
    }

    /// [`super::intersect`] without culling for each lane: bit `k` set where ray `k` hits
    /// `tri` with `t` in `(t_min, t_max)`, and every lane's barycentrics. The same
    /// operations on the same operands in the same order as the scalar test (`Vec3::cross`
    /// and `dot` written out, `1 / det` a true division), and each of its rejections as a
    /// lane mask that a NaN fails or passes as the scalar comparison does.
    #[inline]
    fn intersect(&self, tri: &Tri, t_min: f32, t_max: f32) -> (u8, [f32; 4], [f32; 4]) {
        let [dx, dy, dz] = self.d;
        let (e1, e2) = (tri.e1, tri.e2);
        let s = |v: f32| Vec4::splat(v);
        // p = d × e2
        let px = dy * s(e2.z) - s(e2.y) * dz;
        let py = dz * s(e2.x) - s(e2.z) * dx;
        let pz = dx * s(e2.y) - s(e2.x) * dy;
        let det = s(e1.x) * px + s(e1.y) * py + s(e1.z) * pz;
        let inv_det = Vec4::ONE / det;
        let [sx, sy, sz] = [0, 1, 2].map(|a| self.o[a] - s(tri.v0[a]));
        let u = (sx * px + sy * py + sz * pz) * inv_det;
        // q = s × e1
        let qx = sy * s(e1.z) - s(e1.y) * sz;
        let qy = sz * s(e1.x) - s(e1.z) * sx;
        let qz = sx * s(e1.y) - s(e1.x) * sy;
        let v = (dx * qx + dy * qy + dz * qz) * inv_det;
        let t = (s(e2.x) * qx + s(e2.y) * qy + s(e2.z) * qz) * inv_det;
        let flat = det.abs().cmplt(s(1e-20)).bitmask();
        let inside_u = (u.cmpge(Vec4::ZERO) & u.cmple(Vec4::ONE)).bitmask();
        let outside_v = (v.cmplt(Vec4::ZERO) | (u + v).cmpgt(Vec4::ONE)).bitmask();
        let within = (t.cmpgt(s(t_min)) & t.cmplt(s(t_max))).bitmask();
        let hit = !flat & inside_u & !outside_v & within;
        (hit as u8 & 0xf, u.to_array(), v.to_array())
    }
}
