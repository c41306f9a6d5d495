//! Lights made of many facets (a tessellated sphere, a bulb's mesh) in the direct pass.
//!
//! Treated facet by facet, a light costs per pixel what each facet costs: an exact
//! point-to-polygon factor, a shaft through the BVH and up to [`SHADOW_RAYS`] rays, so the
//! Crytek atrium's two spheres of 960 facets took 40 minutes at 256². Here the connected
//! emitting faces of one emission form a group, and a group of at least [`MANY_FACETS`]
//! is evaluated as one light:
//!
//! - its unoccluded form factor is the sum over facets of the point kernel
//!   `A cos θ cos θ' / (π r²)` at each facet's centroid, and the exact point-to-polygon factor
//!   for facets closer than [`NEAR_FACTOR`] of their size (where the point kernel errs:
//!   its relative error is of order `(size / r)²`, under 1 % beyond that distance);
//! - the fraction of it that is not blocked is estimated by [`SHADOW_RAYS`] shadow rays to
//!   points drawn in proportion to each facet's kernel (stratified over the facets), each
//!   weighted by its point kernel over its probability, as a single facet's rays are.
//!
//! So a group costs a few flops per facet and [`SHADOW_RAYS`] rays per pixel, not a BVH
//! shaft per facet; its error is the point kernel's (bounded above) where nothing blocks
//! the light and `1/√n` of the visible fraction in penumbrae, as for a single sampled
//! light (Shirley, Wang & Zimmerman 1996, "Monte Carlo techniques for direct lighting
//! calculations", for sampling a luminaire in proportion to its estimated contribution).

use std::collections::HashMap;

use glam::DVec3;

use crate::formfactor;
use crate::geometry::bvh::ShadowRay;
use crate::geometry::sampling::triangle_point;
use crate::geometry::{Bvh, Ray, Rng, polygon};
use crate::scene::Rgb;

use super::SHADOW_RAYS;

/// Groups of at least this many faces are evaluated as one light.
pub(super) const MANY_FACETS: usize = 16;

/// A facet closer than this many times its size gets its exact factor.
const NEAR_FACTOR: f64 = 8.0;

/// One facet of a group: a triangle of an emitting face.
struct Facet {
    corners: [DVec3; 3],
    centroid: DVec3,
    /// Unit normal (the emitting side).
    normal: DVec3,
    area: f64,
    /// Its longest edge.
    size: f64,
    /// The face's visibility group, which its own shadow rays ignore.
    occluder: u32,
}

/// A point lit by a group: `p` with normal `n` on a surface of occluder group `own`, whose
/// shadow rays start at `origin` (the point lifted off its surface).
#[derive(Clone, Copy, Debug)]
pub(super) struct Receiver {
    pub p: DVec3,
    pub n: DVec3,
    pub origin: DVec3,
    pub own: u32,
}

/// Connected emitting faces of one emission.
pub(super) struct FacetGroup {
    facets: Vec<Facet>,
    pub(super) emission: Rgb,
}

/// An emitting face as [`group_faces`] reads it.
pub(super) struct EmittingFace<'a> {
    pub vertices: &'a [DVec3],
    pub emission: Rgb,
    pub occluder: u32,
}

/// The faces (by index into `faces`) split into connected groups of one emission: faces
/// that share a vertex position and an emission are one group. Groups come in the order of
/// their first face, each face list ascending.
pub(super) fn group_faces(faces: &[EmittingFace]) -> Vec<Vec<usize>> {
    let mut parent: Vec<usize> = (0..faces.len()).collect();
    fn root(parent: &mut [usize], mut k: usize) -> usize {
        while parent[k] != k {
            parent[k] = parent[parent[k]];
            k = parent[k];
        }
        k
    }
    let mut first_at: HashMap<([u64; 3], [u64; 3]), usize> = HashMap::new();
    for (k, f) in faces.iter().enumerate() {
        let e = f.emission.to_array().map(f64::to_bits);
        for v in f.vertices {
            let key = ([v.x, v.y, v.z].map(f64::to_bits), e);
            let other = *first_at.entry(key).or_insert(k);
            let (a, b) = (root(&mut parent, k), root(&mut parent, other));
            // The smaller index is the root, so a group is named by its first face.
            parent[a.max(b)] = a.min(b);
        }
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut slot: HashMap<usize, usize> = HashMap::new();
    for k in 0..faces.len() {
        let r = root(&mut parent, k);
        let s = *slot.entry(r).or_insert_with(|| {
            groups.push(Vec::new());
            groups.len() - 1
        });
        groups[s].push(k);
    }
    groups
}

impl FacetGroup {
    /// The group of `faces` (all of one emission), cut into triangles.
    pub(super) fn new(faces: &[&EmittingFace]) -> Self {
        let mut facets = Vec::new();
        for f in faces {
            let Some(normal) = polygon::normal(f.vertices) else {
                continue;
            };
            for t in polygon::triangulate(f.vertices) {
                let corners = t.map(|i| f.vertices[i]);
                let area = polygon::area(&corners);
                if area.is_nan() || area <= 0.0 {
                    continue;
                }
                let size = (0..3)
                    .map(|i| corners[i].distance(corners[(i + 1) % 3]))
                    .fold(0.0, f64::max);
                facets.push(Facet {
                    corners,
                    centroid: (corners[0] + corners[1] + corners[2]) / 3.0,
                    normal,
                    area,
                    size,
                    occluder: f.occluder,
                });
            }
        }
        FacetGroup {
            facets,
            emission: faces.first().map_or(Rgb::ZERO, |f| f.emission),
        }
    }

    /// The unoccluded form factor from the point `p` (normal `n`) to each facet, `π` times
    /// over (the kernel `A cos θ cos θ' / r²`), written to `cumulative` as running sums (for
    /// drawing facets by kernel); returns the total.
    fn kernels(&self, p: DVec3, n: DVec3, cumulative: &mut Vec<f64>) -> f64 {
        cumulative.clear();
        let mut total = 0.0;
        for f in &self.facets {
            let d = f.centroid - p;
            let r2 = d.length_squared();
            let near = r2 < (NEAR_FACTOR * f.size).powi(2);
            let w = if near {
                std::f64::consts::PI
                    * formfactor::contour::point_to_polygon_with_normal(p, n, &f.corners, f.normal)
                        .max(0.0)
            } else {
                let (cx, cy) = (d.dot(n), -d.dot(f.normal));
                if cx <= 0.0 || cy <= 0.0 {
                    0.0
                } else {
                    f.area * cx * cy / (r2 * r2)
                }
            };
            total += w;
            cumulative.push(total);
        }
        total
    }

    /// The group's visible form factor from `at`: the unoccluded factor times the
    /// kernel-weighted fraction of [`SHADOW_RAYS`] rays that nothing in `blockers` stops.
    /// Adds its work (a unit per ray, one per 16 facets) to `work`.
    pub(super) fn visible_factor(
        &self,
        at: &Receiver,
        blockers: &Bvh,
        rng: &mut Rng,
        work: &mut u64,
    ) -> f64 {
        let Receiver { p, n, origin, own } = *at;
        let mut cumulative = Vec::with_capacity(self.facets.len());
        let total = self.kernels(p, n, &mut cumulative);
        *work += 1 + self.facets.len() as u64 / 16;
        if total.is_nan() || total <= 0.0 {
            return 0.0;
        }
        *work += SHADOW_RAYS as u64;
        let mut all = 0.0;
        let mut samples = Vec::with_capacity(SHADOW_RAYS);
        for k in 0..SHADOW_RAYS {
            // Stratified over the facets' cumulative kernel.
            let pick = (k as f64 + rng.next_f64()) / SHADOW_RAYS as f64 * total;
            let t = cumulative
                .partition_point(|&c| c < pick)
                .min(self.facets.len() - 1);
            let below = if t == 0 { 0.0 } else { cumulative[t - 1] };
            let share = cumulative[t] - below;
            if share.is_nan() || share <= 0.0 {
                continue;
            }
            let f = &self.facets[t];
            let [a, b, c] = f.corners;
            let y = triangle_point(a, b, c, rng.next_f64(), rng.next_f64());
            let d = y - origin;
            let r2 = d.length_squared();
            let (cx, cy) = (d.dot(n), -d.dot(f.normal));
            if r2 <= 0.0 || cx <= 0.0 || cy <= 0.0 {
                continue;
            }
            // The point kernel over the sample's probability density `share / (total·A)`.
            let g = cx * cy / (r2 * r2) * f.area / share;
            all += g;
            samples.push((
                ShadowRay {
                    ray: Ray::new(origin, d),
                    ignore: [own, f.occluder],
                },
                g,
            ));
        }
        let seen = super::unblocked_weight(blockers, &samples);
        if all > 0.0 {
            total / std::f64::consts::PI * (seen / all)
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests;
