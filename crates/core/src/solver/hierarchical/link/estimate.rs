//! The transfer estimates of a link (see the parent module's docs): the unoccluded kernel
//! and its bound, normal incidence for cluster receivers, and visibility by shadow rays
//! between area-sampled points of the two nodes.

use std::f64::consts::PI;

use glam::DVec3;

use super::super::tree::Node;
use super::{CANDIDATES, Linker, RAYS, RAYS_PARTIAL, RECEIVER_POINTS, SENDER_POINTS};
use crate::formfactor::contour;
use crate::geometry::bvh::{PACKET, ShadowRay};
use crate::geometry::sampling::hash_seed;
use crate::geometry::{Ray, Rng};

impl Linker<'_> {
    /// Normal-incidence kernel at `x` facing `dir` (towards the sender's centroid).
    pub(super) fn normal_incidence(&self, x: DVec3, dir: DVec3, j: u32) -> f64 {
        let nj = self.node(j);
        if nj.is_leaf() {
            let e = &self.mesh.elements[self.tree.order[nj.first as usize] as usize];
            return contour::point_to_polygon_with_normal(x, dir, e.corners(), e.normal);
        }
        let r2 = (nj.centroid - x).length_squared();
        if let Some(a) = self.tree.projected_area(j, -dir) {
            (a / (PI * r2)).min(1.0)
        } else {
            let cos_j = (-nj.normal.dot(dir)).max(0.0);
            nj.area * cos_j / (PI * r2 + nj.area)
        }
    }

    /// The unoccluded kernel estimate (module docs) and its spread (largest minus smallest)
    /// over the receiver's sample points.
    pub(super) fn unoccluded(&self, i: u32, j: u32) -> (f64, f64) {
        let (ni, nj) = (self.node(i), self.node(j));
        let sender = |x: DVec3, n: DVec3| -> f64 {
            if nj.is_leaf() {
                let e = &self.mesh.elements[self.tree.order[nj.first as usize] as usize];
                contour::point_to_polygon_with_normal(x, n, e.corners(), e.normal)
            } else {
                let d = nj.centroid - x;
                let r2 = d.length_squared();
                if r2 <= 0.0 {
                    return 0.0;
                }
                let r = r2.sqrt();
                let cos_i = (n.dot(d) / r).max(0.0);
                if let Some(a) = self.tree.projected_area(j, -d / r) {
                    (a / (PI * r2)).min(1.0) * cos_i
                } else {
                    // Four sub-sources at stratified element centroids: one at the
                    // centroid underestimates a large sender seen obliquely.
                    let a = nj.area / SENDER_POINTS as f64;
                    (0..SENDER_POINTS)
                        .map(|k| {
                            let u = (k as f64 + 0.5) / SENDER_POINTS as f64;
                            let e = &self.mesh.elements[self.tree.element_at(nj, u) as usize];
                            let d = e.centroid - x;
                            let r2 = d.length_squared().max(f64::MIN_POSITIVE);
                            let r = r2.sqrt();
                            let cos_i = (n.dot(d) / r).max(0.0);
                            let cos_j = (-nj.normal.dot(d) / r).max(0.0);
                            a * cos_i * cos_j / (PI * r2 + a)
                        })
                        .sum()
                }
            }
        };
        if ni.is_leaf() {
            return (sender(ni.centroid, ni.normal), 0.0);
        }
        let mut rng = Rng::new(hash_seed(&[self.seed, i as u64, j as u64]), 1);
        let (mut sum, mut lo, mut hi) = (0.0, f64::INFINITY, 0.0f64);
        for k in 0..RECEIVER_POINTS {
            let u = (k as f64 + rng.next_f64()) / RECEIVER_POINTS as f64;
            let e = &self.mesh.elements[self.tree.element_at(ni, u) as usize];
            let f = sender(e.centroid, e.normal);
            sum += f;
            lo = lo.min(f);
            hi = hi.max(f);
        }
        (sum / RECEIVER_POINTS as f64, hi - lo)
    }

    /// Fraction of shadow rays between area-sampled points of `i` and `j` that arrive.
    pub(in crate::solver::hierarchical) fn visibility(&self, i: u32, j: u32) -> f64 {
        self.visibility_rounds(i, j, false)
    }

    /// [`Linker::visibility`] for a caller that splits a partly hidden pair: where the
    /// first round of rays already finds the pair partly hidden, that round's estimate,
    /// without the further rays a partly hidden leaf pair gets. Further rounds cannot make
    /// a partial estimate whole (the weights seen and blocked both stay positive), so the
    /// caller's decision is the same, at a quarter of the rays.
    pub(super) fn visibility_or_partial(&self, i: u32, j: u32) -> f64 {
        self.visibility_rounds(i, j, true)
    }

    fn visibility_rounds(&self, i: u32, j: u32, stop_if_partial: bool) -> f64 {
        let (ni, nj) = (self.node(i), self.node(j));
        let mut rng = Rng::new(hash_seed(&[self.seed, i as u64, j as u64]), 2);
        let leaf_end = ni.is_leaf() || nj.is_leaf();
        let mut seen = 0u32;
        let mut total = 0u32;
        let (mut w_seen, mut w_total) = (0.0, 0.0);
        loop {
            let rays = if total == 0 {
                RAYS
            } else {
                RAYS_PARTIAL - RAYS
            };
            let m = if total == 0 { 2 } else { 3 };
            // The rays of a round are drawn first (the sampling does not depend on which
            // are blocked) and traced in packets: they run between the same two nodes.
            let mut k = 0;
            while k < rays {
                let mut packet = [ShadowRay {
                    ray: Ray::new(DVec3::ZERO, DVec3::ZERO),
                    ignore: [0; 2],
                }; PACKET];
                let mut weight = [0.0; PACKET];
                let count = PACKET.min((rays - k) as usize);
                for (slot, w) in packet.iter_mut().zip(&mut weight).take(count) {
                    *slot = self.shadow_ray(ni, nj, k, m, &mut rng, w);
                    k += 1;
                }
                let blocked = self.bvh.any_hit_packet(&packet[..count], 1e-9, 1.0 - 1e-9);
                for (s, w) in weight.iter().enumerate().take(count) {
                    w_total += w;
                    if blocked & (1 << s) == 0 {
                        seen += 1;
                        w_seen += w;
                    }
                    total += 1;
                }
            }
            let v = w_seen / w_total; // NaN (not partial) while no weight is drawn
            let partial = v > 0.0 && v < 1.0;
            if total >= RAYS_PARTIAL
                || !leaf_end
                || seen == 0
                || seen == total
                || (stop_if_partial && partial)
            {
                break;
            }
        }
        if w_total > 0.0 {
            w_seen / w_total
        } else if ni.is_cluster() || nj.is_cluster() {
            // No point drawn faced the other node (a cluster's faces turned away): one ray
            // to a point chosen among more.
            self.visibility_ray(i, j)
        } else {
            seen as f64 / total as f64
        }
    }

    /// The `k`-th shadow ray of a round stratified `m × m` on the receiver's and the
    /// sender's area, and its weight: the point-to-point kernel cosθ_x cosθ_y / r²
    /// (Wallace, Elmquist & Haines 1989), as the contour rows weigh theirs. A leaf
    /// receiver looks from its centroid, where its kernel is evaluated.
    fn shadow_ray(
        &self,
        ni: &Node,
        nj: &Node,
        k: u32,
        m: u32,
        rng: &mut Rng,
        weight: &mut f64,
    ) -> ShadowRay {
        let (a, c) = (k % m, (k / m) % m);
        let ui = (a as f64 + rng.next_f64()) / m as f64;
        let uj = (c as f64 + rng.next_f64()) / m as f64;
        let (x, nx, gx) = if ni.is_leaf() {
            let e = self.tree.order[ni.first as usize] as usize;
            let group = self.mesh.patches[self.mesh.elements[e].patch.0 as usize].occluder;
            (ni.centroid, ni.normal, group)
        } else {
            self.point_on(ni, ui, rng)
        };
        let (y, ny, gy) = self.point_on(nj, uj, rng);
        let o = x + nx * self.epsilon;
        let t = y + ny * self.epsilon;
        let d = t - o;
        *weight = point_kernel(nx, ny, d);
        ShadowRay {
            ray: Ray::new(o, d),
            ignore: [gx, gy],
        }
    }

    /// Visibility from one shadow ray between points of `i` and `j` (0 or 1): the estimate a
    /// provisional link keeps ([`super::Link::provisional`]).
    ///
    /// The receiver's point is area-uniform. So is the sender's, except where either node
    /// is a cluster: there it is a uniform point of one of [`CANDIDATES`] elements (drawn
    /// uniformly from the node's), chosen with probability in proportion to the element's
    /// area times its kernel `cosθ_x cosθ_y / r²` at its centroid towards the receiver's
    /// point (resampled importance sampling, Talbot, Cline & Egbert 2005). The ray then estimates
    /// the kernel-weighted visibility the 4-ray estimate ([`Linker::visibility`]) measures.
    /// An area-uniform point alone falls on a face turned away from the receiver about half
    /// the time on a closed object (a column, a sphere), and its ray, blocked by the
    /// object's own front, counted the whole link as hidden: the atrium's cluster links
    /// lost about half their kernels that way. Elements are drawn by index, not by area,
    /// so a candidate costs one element's load, not a search of the node's areas.
    pub(in crate::solver::hierarchical) fn visibility_ray(&self, i: u32, j: u32) -> f64 {
        let (ni, nj) = (self.node(i), self.node(j));
        let mut rng = Rng::new(hash_seed(&[self.seed, i as u64, j as u64]), 3);
        let u = rng.next_f64();
        let (x, nx, gx) = self.point_on(ni, u, &mut rng);
        let u = rng.next_f64();
        let target = if ni.is_cluster() || nj.is_cluster() {
            // The area-uniform point of `nj` uses the next two numbers; where a candidate
            // is chosen instead it is never needed, so it is made only as the fallback.
            let mut uniform = rng.clone();
            rng.next_f64();
            rng.next_f64();
            let (mut w_sum, mut chosen) = (0.0, None);
            for _ in 0..CANDIDATES {
                let k = nj.first + ((rng.next_f64() * nj.count as f64) as u32).min(nj.count - 1);
                let s = &self.tree.samples[k as usize];
                let w = s.area * point_kernel(nx, s.normal, s.centroid - x);
                w_sum += w;
                if w > 0.0 && rng.next_f64() * w_sum < w {
                    chosen = Some(k);
                }
            }
            match chosen {
                Some(k) => {
                    let e = &self.mesh.elements[self.tree.order[k as usize] as usize];
                    let y = e.point_at(rng.next_f64(), rng.next_f64());
                    (y, e.normal, self.mesh.patches[e.patch.0 as usize].occluder)
                }
                None => self.point_on(nj, u, &mut uniform),
            }
        } else {
            self.point_on(nj, u, &mut rng)
        };
        let (y, ny, gy) = target;
        let o = x + nx * self.epsilon;
        let d = y + ny * self.epsilon - o;
        let blocked = self
            .bvh
            .any_hit_except(&Ray::new(o, d), 1e-9, 1.0 - 1e-9, [gx, gy]);
        if blocked { 0.0 } else { 1.0 }
    }

    /// An area-uniform point of `node` (element chosen by `u`), its normal and the
    /// occluder group to ignore.
    pub(super) fn point_on(&self, node: &Node, u: f64, rng: &mut Rng) -> (DVec3, DVec3, u32) {
        let e = &self.mesh.elements[self.tree.element_at(node, u.min(1.0 - 1e-12)) as usize];
        let group = self.mesh.patches[e.patch.0 as usize].occluder;
        let (u1, u2) = (rng.next_f64(), rng.next_f64());
        let p = e.point_at(u1, u2);
        (p, e.normal, group)
    }
}

/// The point-to-point kernel `cosθ_x cosθ_y / r²` between a point with normal `nx` and one
/// with normal `ny` at offset `d` from it (without `1/π`; 0 where either faces away).
fn point_kernel(nx: DVec3, ny: DVec3, d: DVec3) -> f64 {
    let r2 = d.length_squared();
    nx.dot(d).max(0.0) * (-ny.dot(d)).max(0.0) / (r2 * r2).max(f64::MIN_POSITIVE)
}
