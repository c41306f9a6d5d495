//! Area-to-area Monte Carlo: random point pairs on both polygons, with visibility.
//!
//! `F_12 = (1/A_1) ∫∫ cosθ_1 cosθ_2 V / (π r²) dA_2 dA_1 ≈ (A_2/N) Σ cosθ_1 cosθ_2 V / (π r²)`
//! over `N` independent uniform pairs (the Monte Carlo estimator of the form-factor integral;
//! e.g. Cohen & Wallace 1993, "Radiosity and Realistic Image Synthesis", §4.9). From a
//! differential receiver (a case with `point`), the first point is fixed.
//!
//! Known error: unbiased, plain Monte Carlo, standard deviation `σ/√N` (the `N^-1/2` rate is
//! tested), but σ grows without bound as the polygons approach each other: the integrand
//! `cos cos / (π r²)` is unbounded near contact, so touching or nearly touching polygons
//! (squares sharing an edge, 0.01 apart) need orders of magnitude more pairs. In the solver
//! each element gets `visibility_rays` pairs, so the row is noisy for near receivers.

use std::sync::atomic::{AtomicBool, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use super::row::RowContext;
use super::visibility::PolygonSampler;
use crate::geometry::sampling::hash_seed;
use crate::geometry::{Bvh, Ray, Rng};
use crate::mesh::PatchId;

/// The point-pair kernel `cosθ_1 cosθ_2 / (π r²)` (0 when either faces away).
pub fn kernel(x: DVec3, nx: DVec3, y: DVec3, ny: DVec3) -> f64 {
    let d = y - x;
    let r2 = d.length_squared();
    if r2 <= 0.0 {
        return 0.0;
    }
    let c1 = nx.dot(d);
    let c2 = -ny.dot(d);
    if c1 <= 0.0 || c2 <= 0.0 {
        return 0.0;
    }
    c1 * c2 / (std::f64::consts::PI * r2 * r2)
}

/// Where the first point of each pair comes from.
pub enum Receiver<'a> {
    Point(DVec3, DVec3),
    Polygon(&'a PolygonSampler),
}

/// Estimate of F from the receiver to `target` (area `target_area`) with `n` pairs; a pair
/// counts only when the segment between them misses `bvh` (ids in `ignore` are skipped).
#[allow(clippy::too_many_arguments)]
pub fn estimate(
    receiver: &Receiver,
    target: &PolygonSampler,
    target_area: f64,
    bvh: Option<&Bvh>,
    ignore: [u32; 2],
    epsilon: f64,
    n: u64,
    rng: &mut Rng,
) -> f64 {
    let empty_receiver = matches!(receiver, Receiver::Polygon(s) if s.is_empty());
    if n == 0 || target.is_empty() || empty_receiver {
        return 0.0; // A degenerate polygon has no area to exchange light with.
    }
    let ny = target.normal();
    let mut sum = 0.0;
    for _ in 0..n {
        let (x, nx) = match receiver {
            Receiver::Point(p, nrm) => (*p, *nrm),
            Receiver::Polygon(s) => (s.point(rng.next_f64(), rng.next_f64()), s.normal()),
        };
        let y = target.point(rng.next_f64(), rng.next_f64());
        let k = kernel(x, nx, y, ny);
        if k <= 0.0 {
            continue;
        }
        if let Some(b) = bvh {
            let (a, c) = (x + nx * epsilon, y + ny * epsilon);
            if b.any_hit_except(&Ray::new(a, c - a), 1e-9, 1.0 - 1e-9, ignore) {
                continue;
            }
        }
        sum += k;
    }
    sum * target_area / n as f64
}

/// `out[j] = F_ji` from `visibility_rays` random point pairs per receiving element.
pub fn row(ctx: &RowContext, shooter: PatchId, out: &mut [f32], cancel: &AtomicBool) -> bool {
    let mesh = ctx.mesh;
    let patch = mesh.patch(shooter);
    let target = PolygonSampler::new(&patch.polygon);
    let n = ctx.params.visibility_rays.max(1) as u64;
    let seed = ctx.params.seed;
    out.par_iter_mut().enumerate().for_each(|(j, f)| {
        if j % 256 == 0 && cancel.load(Ordering::Relaxed) {
            return;
        }
        let e = &mesh.elements[j];
        if e.patch == shooter {
            *f = 0.0;
            return;
        }
        let receiver_patch = mesh.patch(e.patch);
        let ignore = [receiver_patch.occluder, patch.occluder];
        let sampler = PolygonSampler::new(e.corners());
        let mut rng = Rng::new(hash_seed(&[seed, shooter.0 as u64, j as u64, 0x3c4a]), 0);
        *f = estimate(
            &Receiver::Polygon(&sampler),
            &target,
            patch.area,
            Some(ctx.bvh),
            ignore,
            ctx.epsilon,
            n,
            &mut rng,
        ) as f32;
    });
    !cancel.load(Ordering::Relaxed)
}
