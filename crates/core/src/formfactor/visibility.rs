//! Visibility between a receiving point and a shooting polygon: stratified shadow rays
//! weighted by the point-to-point form factor, a 4-ray probe, the patch-pair shortcut, and
//! the contour row's per-element choice between "no blocker", exact shadows and rays.

use std::borrow::Cow;

use glam::DVec3;

use super::row::RowContext;
use super::{contour, exact};
use crate::geometry::bvh::{PACKET, ShadowRay};
use crate::geometry::sampling::{hash_seed, triangle_point};
use crate::geometry::shaft::Shaft;
use crate::geometry::{Bvh, Ray, Rng, polygon};
use crate::mesh::PatchId;

/// Stratified points on a polygon (area-uniform), for visibility rays.
///
/// A degenerate polygon (fewer than 3 vertices, collinear, or of zero area) gives an
/// *empty* sampler ([`is_empty`](Self::is_empty)): it has no area to sample, every caller
/// treats it as "nothing visible" (visibility 0, form factor 0), and [`point`](Self::point)
/// returns the mean of the polygon's vertices (the origin when it has none) instead of
/// indexing a triangle that does not exist.
#[derive(Clone, Debug)]
pub struct PolygonSampler {
    /// Empty for a degenerate polygon.
    triangles: Vec<[DVec3; 3]>,
    cdf: Vec<f64>,
    normal: DVec3,
    /// What [`point`](Self::point) returns when there is nothing to sample.
    fallback: DVec3,
}

impl PolygonSampler {
    pub fn new(poly: &[DVec3]) -> Self {
        let mut triangles: Vec<[DVec3; 3]> = polygon::triangulate(poly)
            .into_iter()
            .map(|t| [poly[t[0]], poly[t[1]], poly[t[2]]])
            .collect();
        let mut acc = 0.0;
        let mut cdf: Vec<f64> = triangles
            .iter()
            .map(|t| {
                acc += polygon::area(t);
                acc
            })
            .collect();
        if acc > 0.0 && acc.is_finite() {
            cdf.iter_mut().for_each(|c| *c /= acc);
        } else {
            // Zero (or non-finite) area: nothing to sample.
            triangles.clear();
            cdf.clear();
        }
        let fallback = if poly.is_empty() {
            DVec3::ZERO
        } else {
            poly.iter().copied().sum::<DVec3>() / poly.len() as f64
        };
        Self {
            triangles,
            cdf,
            normal: polygon::normal(poly).unwrap_or(DVec3::Z),
            fallback,
        }
    }

    /// Maps a point of the unit square to the polygon, area-preserving. For an empty
    /// sampler, the mean of the polygon's vertices.
    pub fn point(&self, u1: f64, u2: f64) -> DVec3 {
        if self.triangles.is_empty() {
            return self.fallback;
        }
        let k = self
            .cdf
            .partition_point(|c| *c <= u1)
            .min(self.triangles.len() - 1);
        let lo = if k == 0 { 0.0 } else { self.cdf[k - 1] };
        let hi = self.cdf.get(k).copied().unwrap_or(1.0);
        let u = if hi > lo {
            ((u1 - lo) / (hi - lo)).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let [a, b, c] = self.triangles[k];
        triangle_point(a, b, c, u, u2)
    }

    pub fn normal(&self) -> DVec3 {
        self.normal
    }

    /// True for a degenerate polygon: no area to sample, so nothing of it is visible.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }
}

/// Visible fraction of the polygon from `x`, weighted by the point-to-point form factor:
/// `Σ w_k v_k / Σ w_k` over `m × m` stratified points `y_k`, with `v_k` = 1 when the ray
/// arrives and `w_k = cosθ_x cosθ_y / r²` (Wallace, Elmquist & Haines 1989 weight each
/// sample by its delta form factor). Multiplied by Lambert's exact unoccluded value this is
/// exact for a fully visible or fully hidden polygon and, unlike the plain area fraction,
/// unbiased to first order when a blocker hides the part of the polygon that matters most
/// (straight overhead). With `probe`, four rays go first and decide alone when they agree
/// (all arrive or none do); a blocker smaller than the gaps between them can then be missed.
#[allow(clippy::too_many_arguments)]
pub fn visibility_fraction(
    bvh: &Bvh,
    x: DVec3,
    nx: DVec3,
    target: &PolygonSampler,
    m: u32,
    probe: bool,
    epsilon: f64,
    ignore: [u32; 2],
    rng: &mut Rng,
) -> f64 {
    sampled_visibility(
        |rays| {
            // On the stack: this runs for every receiver point of every row.
            let packet: [ShadowRay; PACKET] = std::array::from_fn(|k| ShadowRay {
                ray: rays[k.min(rays.len() - 1)],
                ignore,
            });
            bvh.any_hit_packet(&packet[..rays.len()], 1e-9, 1.0 - 1e-9)
        },
        x + nx * epsilon,
        nx,
        target,
        m,
        probe,
        epsilon,
        rng,
    )
}

/// [`visibility_fraction`] with the blocking test given: rays from `origin` (normal `nx`)
/// to stratified points lifted `epsilon` off the target. `blocked` answers up to
/// [`PACKET`] rays at once (bit `k` set where ray `k` is blocked): the rays of one origin
/// to one polygon run close together, and a packet shares their walk through the BVH.
#[allow(clippy::too_many_arguments)]
fn sampled_visibility(
    blocked: impl Fn(&[Ray]) -> u8,
    origin: DVec3,
    nx: DVec3,
    target: &PolygonSampler,
    m: u32,
    probe: bool,
    epsilon: f64,
    rng: &mut Rng,
) -> f64 {
    if target.is_empty() {
        return 0.0; // No area: nothing to see.
    }
    let ny = target.normal();
    let ray_to = |u1: f64, u2: f64| {
        let y = target.point(u1, u2) + ny * epsilon;
        Ray::new(origin, y - origin)
    };
    if probe && m > 2 {
        // A 2×2 stratified probe; if it agrees, take it (4 rays instead of m²).
        let seen = probe_rays(&blocked, origin, target, epsilon, rng);
        if seen == 0 || seen == 4 {
            return seen as f64 / 4.0;
        }
    }
    let (mut visible, mut total) = (0.0f64, 0.0f64);
    let (mut rays, mut weights) = ([Ray::new(origin, ny); PACKET], [0.0; PACKET]);
    let mut n = 0;
    for a in 0..m {
        for b in 0..m {
            let u1 = (a as f64 + rng.next_f64()) / m as f64;
            let u2 = (b as f64 + rng.next_f64()) / m as f64;
            let ray = ray_to(u1, u2);
            let d = ray.dir;
            let r2 = d.length_squared();
            // cosθx cosθy / r² with an unnormalised direction.
            let w = (nx.dot(d) * ny.dot(d)).abs() / (r2 * r2).max(f64::MIN_POSITIVE);
            total += w;
            (rays[n], weights[n]) = (ray, w);
            n += 1;
            if n == PACKET || (a + 1 == m && b + 1 == m) {
                let hidden = blocked(&rays[..n]);
                for (k, w) in weights[..n].iter().enumerate() {
                    if hidden & (1 << k) == 0 {
                        visible += w;
                    }
                }
                n = 0;
            }
        }
    }
    if total > 0.0 { visible / total } else { 0.0 }
}

/// How many of 2×2 stratified rays from `origin` to the target (lifted `epsilon`) arrive.
fn probe_rays(
    blocked: impl Fn(&[Ray]) -> u8,
    origin: DVec3,
    target: &PolygonSampler,
    epsilon: f64,
    rng: &mut Rng,
) -> u32 {
    let rays: [Ray; 4] = std::array::from_fn(|k| {
        let u1 = ((k % 2) as f64 + rng.next_f64()) / 2.0;
        let u2 = ((k / 2) as f64 + rng.next_f64()) / 2.0;
        let y = target.point(u1, u2) + target.normal() * epsilon;
        Ray::new(origin, y - origin)
    });
    4 - (blocked(&rays) & 0xf).count_ones()
}

pub(crate) fn side(rays: u32) -> u32 {
    ((rays.max(1) as f64).sqrt().round() as u32).max(1)
}

/// Whether a whole receiving patch sees the whole shooting patch: both lie strictly in
/// front of each other and 4 × 4 rays between points near the receiver's corners and
/// stratified points on the shooter, plus centre to centre, all arrive. Then every element
/// of the receiver skips its own shadow rays (a blocker that slips between these 17 rays is
/// missed, as with the per-element probe).
pub(crate) fn patch_pair_unblocked(
    ctx: &RowContext,
    receiver: &crate::mesh::Patch,
    shooter: &crate::mesh::Patch,
    shooter_id: PatchId,
    receiver_index: usize,
    ignore: [u32; 2],
) -> bool {
    let eps = ctx.epsilon;
    let in_front = |points: &[DVec3], of: &crate::mesh::Patch| {
        points
            .iter()
            .all(|p| (*p - of.centroid).dot(of.normal) > 10.0 * eps)
    };
    if !in_front(&shooter.bounds, receiver) || !in_front(&receiver.bounds, shooter) {
        return false;
    }
    let mut rng = Rng::new(
        hash_seed(&[
            ctx.params.seed,
            shooter_id.0 as u64,
            receiver_index as u64,
            0x5a4f7,
        ]),
        1,
    );
    let sampler = PolygonSampler::new(&shooter.polygon);
    if sampler.is_empty() {
        return false; // A degenerate shooter: let each element find it invisible.
    }
    let lift = |p: DVec3, n: DVec3| p + n * eps;
    let shadow = |from: DVec3, to: DVec3| {
        let (a, b) = (lift(from, receiver.normal), lift(to, shooter.normal));
        ShadowRay {
            ray: Ray::new(a, b - a),
            ignore,
        }
    };
    let centre = shadow(receiver.centroid, shooter.centroid);
    if ctx
        .bvh
        .any_hit_except(&centre.ray, 1e-9, 1.0 - 1e-9, centre.ignore)
    {
        return false;
    }
    for corner in &receiver.polygon {
        // A little inside the corner, off the neighbouring faces; its four rays as a packet.
        let from = *corner + (receiver.centroid - *corner) * 0.01;
        let packet: [ShadowRay; 4] = std::array::from_fn(|k| {
            let u1 = ((k % 2) as f64 + rng.next_f64()) / 2.0;
            let u2 = ((k / 2) as f64 + rng.next_f64()) / 2.0;
            shadow(from, sampler.point(u1, u2))
        });
        if ctx.bvh.any_hit_packet(&packet, 1e-9, 1.0 - 1e-9) != 0 {
            return false;
        }
    }
    true
}

/// Lambert's point-to-polygon form factor times the visible fraction of stratified shadow
/// rays to the part of the polygon above the receiver's tangent plane (`full` samples the
/// whole polygon and is used when no clipping is needed).
#[allow(clippy::too_many_arguments)]
pub fn occluded_point_to_polygon(
    bvh: &Bvh,
    x: DVec3,
    nx: DVec3,
    poly: &[DVec3],
    full: &PolygonSampler,
    m: u32,
    probe: bool,
    epsilon: f64,
    ignore: [u32; 2],
    rng: &mut Rng,
) -> f64 {
    let analytic = contour::point_to_polygon(x, nx, poly);
    if analytic <= 0.0 {
        return 0.0;
    }
    let part = part_above(poly, x, nx);
    let target = part_sampler(&part, full);
    analytic * visibility_fraction(bvh, x, nx, &target, m, probe, epsilon, ignore, rng)
}

/// The part of `poly` on or above the tangent plane at `x` (unit normal `nx`), the only part
/// a receiver there can see: `poly` itself when every vertex is on or above the plane,
/// otherwise the clipped polygon (possibly degenerate).
///
/// "On" allows the round-off of the points' coordinates: a vertex below the plane by at
/// most `ON_PLANE` times its distance from `x` counts as on it. Without that, a shooter
/// whose edge lies in the receiver's plane (a wall patch starting at the height of a box
/// top) was clipped or not depending on the last bit of a coordinate, and the clipped
/// polygon's sampler places its stratified points differently, so the same scene in another
/// unit got other shadow-ray samples (1e-3 vs 1 differed by 25 % in such rows).
pub fn part_above(poly: &[DVec3], x: DVec3, nx: DVec3) -> Cow<'_, [DVec3]> {
    if poly.iter().all(|v| {
        let d = *v - x;
        d.dot(nx) >= -ON_PLANE * d.length()
    }) {
        Cow::Borrowed(poly)
    } else {
        Cow::Owned(polygon::clip_to_halfspace(poly, x, nx))
    }
}

/// Relative tolerance of "on the tangent plane" in [`part_above`]: far above the round-off
/// of coordinates (1e-16 of the scene size), far below any tilt that matters (the part of
/// the polygon it lets below the plane subtends at most this angle, and contributes
/// cos θ ≤ 1e-12 to the sampled weights).
const ON_PLANE: f64 = 1e-12;

/// A sampler of `part` (from [`part_above`]): `whole`, the sampler of the whole polygon,
/// when nothing was clipped, otherwise a new sampler of the clipped part (empty when the
/// clipped part is degenerate, which callers count as nothing visible).
#[expect(
    clippy::ptr_arg,
    reason = "Borrowed vs Owned says whether anything was clipped"
)]
pub fn part_sampler<'a>(
    part: &Cow<'_, [DVec3]>,
    whole: &'a PolygonSampler,
) -> Cow<'a, PolygonSampler> {
    match part {
        Cow::Borrowed(_) => Cow::Borrowed(whole),
        Cow::Owned(clipped) => Cow::Owned(PolygonSampler::new(clipped)),
    }
}

/// What [`element_visibility`] found.
pub(crate) enum Visibility {
    /// Multiply Lambert's unoccluded value by this.
    Fraction(f64),
    /// The form factor to the visible part itself.
    Exact(f64),
}

/// The shooter as seen from a receiving point, given the only triangles that can block
/// (`candidates`, from the receiving patch's shaft): if none of them cuts the point's own
/// pyramid to the (clipped) shooter it is fully visible, without a ray; if a few do, their
/// shadows are subtracted from the shooter polygon and Lambert's formula integrates what is
/// left (exact, no noise); with many, stratified rays are tested against them alone.
#[allow(clippy::too_many_arguments)]
pub(crate) fn element_visibility(
    ctx: &RowContext,
    x: DVec3,
    nx: DVec3,
    patch: &crate::mesh::Patch,
    sampler: &PolygonSampler,
    m: u32,
    probe: bool,
    candidates: &[u32],
    rng: &mut Rng,
) -> Visibility {
    let part = part_above(&patch.polygon, x, nx);
    let origin = x + nx * ctx.epsilon;
    let pyramid = Shaft::pyramid(origin, &part, ctx.epsilon);
    let cutting: Vec<u32> = candidates
        .iter()
        .copied()
        .filter(|&k| !pyramid.excludes_triangle(ctx.bvh.stored_triangle(k)))
        .collect();
    if cutting.is_empty() {
        return Visibility::Fraction(1.0);
    }
    // Shooters that get every ray (lights, or all with probing off) get exact shadows
    // instead; the others' penumbrae are sampled (clipping costs more than the 4-ray probe
    // and the rays it saves: measured in docs/FORMFACTORS.md). A cut-out blocker has holes
    // the clipping cannot see: its shadow is sampled.
    if !probe
        && cutting.len() <= ctx.params.exact_blockers
        && !cutting.iter().any(|&k| ctx.bvh.is_cut(k))
    {
        let blockers: Vec<Vec<DVec3>> = cutting
            .iter()
            .map(|&k| ctx.bvh.stored_triangle(k).to_vec())
            .collect();
        let value = exact::point_to_visible_polygon(origin, nx, &patch.polygon, &blockers);
        debug_assert!(value.is_finite());
        return Visibility::Exact(value.max(0.0));
    }
    // Only the sampled tier needs a sampler of the clipped polygon.
    let target = part_sampler(&part, sampler);
    Visibility::Fraction(sampled_visibility(
        |rays| {
            (rays.iter().enumerate())
                .filter(|(_, ray)| ctx.bvh.any_hit_among(&cutting, ray, 1e-9, 1.0 - 1e-9))
                .fold(0, |bits, (k, _)| bits | (1 << k))
        },
        origin,
        nx,
        &target,
        m,
        probe,
        ctx.epsilon,
        rng,
    ))
}

#[cfg(test)]
mod tests;
