//! Ray casting: cosine-weighted rays from the shooter, counted where they land.
//!
//! A ray leaving a uniform random point of the shooter in a cosine-weighted direction lands
//! on receiver `j` with probability `F_ij` (Malley 1988, "A shading method for computer
//! generated images"; Shirley 1990, "A ray tracing method for illumination calculation in
//! diffuse-specular scenes"), so `F_ij ≈ hits_j / N` and the solver's `F_ji = F_ij A_i / A_j`.
//! From a differential receiver (a case with `point`), every ray leaves the point.
//!
//! Known error: plain Monte Carlo, unbiased, with standard deviation `√(F(1 − F)/N)` — the
//! rate `N^-1/2` is tested. In the solver the relative noise of one element's value is
//! `1/√(N F_ij)`, large for small or far elements (few hits), and the reciprocity factor
//! `A_i/A_j` turns a single stray hit on a small element into a bright speck.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use glam::DVec3;
use rayon::prelude::*;

use super::row::RowContext;
use super::visibility::PolygonSampler;
use crate::geometry::sampling::{cosine_hemisphere, hash_seed, splitmix};
use crate::geometry::{Bvh, Ray, Rng};
use crate::mesh::{Mesh, PatchId};

/// Fraction of `n` cosine-weighted rays from `origin` (uniform on `from`, or a fixed point)
/// whose first hit in `bvh` is the front of a triangle with id `target`.
pub fn hit_fraction(
    bvh: &Bvh,
    from: Origin,
    target: u32,
    n: u64,
    epsilon: f64,
    rng: &mut Rng,
) -> f64 {
    if n == 0 || matches!(&from, Origin::Polygon(s) if s.is_empty()) {
        return 0.0; // A degenerate origin polygon sends nothing.
    }
    let mut hits = 0u64;
    for _ in 0..n {
        let (o, normal) = match &from {
            Origin::Point(p, nrm) => (*p, *nrm),
            Origin::Polygon(s) => (s.point(rng.next_f64(), rng.next_f64()), s.normal()),
        };
        let d = cosine_hemisphere(normal, rng.next_f64(), rng.next_f64());
        let ray = Ray::new(o + normal * epsilon, d);
        if let Some(h) = bvh.closest_hit(&ray, 0.0, f64::INFINITY)
            && h.id == target
            && h.front
        {
            hits += 1;
        }
    }
    hits as f64 / n as f64
}

/// Where rays leave from.
pub enum Origin {
    /// A point and its unit normal.
    Point(DVec3, DVec3),
    /// Uniform points of a polygon.
    Polygon(PolygonSampler),
}

type CacheEntry = (u64, Arc<Bvh>);

/// The last element-level BVH built, keyed by a hash of the mesh's display geometry (rows of
/// one solve reuse it; a different mesh rebuilds it).
static ELEMENT_BVH: Mutex<Option<CacheEntry>> = Mutex::new(None);

fn fingerprint(mesh: &Mesh, two_sided: bool) -> u64 {
    let mut h = splitmix(mesh.triangles.len() as u64 ^ ((two_sided as u64) << 40));
    for v in &mesh.vertices {
        for x in v.to_array() {
            h = splitmix(h ^ x.to_bits());
        }
    }
    for t in &mesh.triangles {
        h = splitmix(h ^ (t[0] as u64) ^ ((t[1] as u64) << 21) ^ ((t[2] as u64) << 42));
    }
    h
}

/// A BVH over the mesh's display triangles (ids = triangle index), cached.
pub fn element_bvh(mesh: &Mesh, two_sided: bool) -> Arc<Bvh> {
    let key = fingerprint(mesh, two_sided);
    if let Ok(guard) = ELEMENT_BVH.lock()
        && let Some((k, b)) = guard.as_ref()
        && *k == key
    {
        return b.clone();
    }
    let bvh = Arc::new(Bvh::build(&mesh.display_triangles(two_sided)));
    if let Ok(mut guard) = ELEMENT_BVH.lock() {
        *guard = Some((key, bvh.clone()));
    }
    bvh
}

/// `out[j] = F_ji` from `params.rays` cosine-weighted rays leaving the shooting patch.
pub fn row(ctx: &RowContext, shooter: PatchId, out: &mut [f32], cancel: &AtomicBool) -> bool {
    let mesh = ctx.mesh;
    let patch = mesh.patch(shooter);
    let bvh = element_bvh(mesh, ctx.scene.two_sided);
    let total = ctx.params.rays.max(1) as u64;
    const CHUNKS: u64 = 16;
    let sampler = PolygonSampler::new(&patch.polygon);
    if sampler.is_empty() {
        out.fill(0.0); // A degenerate shooter sends nothing.
        return !cancel.load(Ordering::Relaxed);
    }
    let n_el = mesh.elements.len();
    let counts: Option<Vec<u32>> = (0..CHUNKS)
        .into_par_iter()
        .map(|c| {
            let mut counts = vec![0u32; n_el];
            let n = total / CHUNKS + u64::from(c < total % CHUNKS);
            let mut rng = Rng::new(
                hash_seed(&[ctx.params.seed, shooter.0 as u64, c, 0x7a1c]),
                c,
            );
            for k in 0..n {
                if k % 4096 == 0 && cancel.load(Ordering::Relaxed) {
                    return None;
                }
                let o = sampler.point(rng.next_f64(), rng.next_f64());
                let d = cosine_hemisphere(patch.normal, rng.next_f64(), rng.next_f64());
                let ray = Ray::new(o + patch.normal * ctx.epsilon, d);
                if let Some(h) = bvh.closest_hit(&ray, 0.0, f64::INFINITY)
                    && h.front
                {
                    let e = mesh.triangle_element[h.id as usize].0 as usize;
                    counts[e] += 1;
                }
            }
            Some(counts)
        })
        .try_reduce(
            || vec![0u32; n_el],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                Some(a)
            },
        );
    let Some(counts) = counts else {
        return false;
    };
    let first = patch.elements.start as usize..patch.elements.end as usize;
    for (j, (o, c)) in out.iter_mut().zip(&counts).enumerate() {
        let e = &mesh.elements[j];
        *o = if first.contains(&j) || e.area <= 0.0 {
            0.0
        } else {
            (*c as f64 / total as f64 * patch.area / e.area) as f32
        };
    }
    !cancel.load(Ordering::Relaxed)
}
