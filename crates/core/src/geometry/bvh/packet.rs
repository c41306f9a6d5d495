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

use super::{Bvh, intersect, slab};
use crate::geometry::Ray;
use glam::Vec3;

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
        let all = ((1u16 << n) - 1) as u8;
        let mut blocked = 0u8;
        // Each entry: a node and the rays that passed every box above it.
        let mut stack = [(0u32, 0u8); 64];
        let mut sp = 0usize;
        let (mut node, mut mask) = (0u32, all);
        loop {
            let nd = &self.nodes[node as usize];
            let mut pass = 0u8;
            for k in 0..n {
                let bit = 1 << k;
                if mask & !blocked & bit != 0 && slab(nd, o[k], inv[k], t_max).is_some() {
                    pass |= bit;
                }
            }
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
                    for (k, r) in rays.iter().enumerate() {
                        let bit = 1 << k;
                        if pass & !blocked & bit == 0
                            || tri.id == r.ignore[0]
                            || tri.id == r.ignore[1]
                        {
                            continue;
                        }
                        // Shadow rays ignore culling: a back face still blocks light.
                        if let Some((_, u, v, _)) = intersect(tri, false, o[k], d[k], t_min, t_max)
                            && !self.is_hole(tri, u, v)
                        {
                            blocked |= bit;
                        }
                    }
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
