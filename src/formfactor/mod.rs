//! Form factors: how much of the light leaving one surface arrives at another.
//!
//! The solver needs, for a shooting patch `i`, a *row*: for every receiving element `j` the
//! form factor `F_ji` from (a point of) `j` to the whole of `i`, so that
//! `ΔB_j = ρ_j ΔB_i F_ji` (Cohen, Chen, Wallace, Greenberg 1988). The default method,
//! `contour`, evaluates Lambert's exact point-to-polygon formula at the element's centroid
//! and multiplies it by the fraction of stratified shadow rays from that point to the patch
//! that are unblocked (Wallace, Elmquist, Haines 1989, "A ray tracing algorithm for
//! progressive radiosity"). Known error: the visibility fraction is exact for fully visible or
//! fully hidden pairs and has stratified-sampling noise O(N^-3/4) in penumbrae; the centroid
//! rule integrates over the receiving element with O(h²) error.

pub mod cases;
pub mod contour;

use std::sync::atomic::{AtomicBool, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use crate::geometry::sampling::{hash_seed, triangle_point};
use crate::geometry::shaft::Shaft;
use crate::geometry::{Bvh, Ray, Rng, polygon};
use crate::mesh::{Mesh, PatchId};
use crate::scene::Scene;

/// Which method computes form factors.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FormFactorMethod {
    /// Exact point-to-polygon contour formula × stratified visibility.
    Contour,
}

impl FormFactorMethod {
    pub const ALL: &'static [FormFactorMethod] = &[FormFactorMethod::Contour];

    pub fn name(self) -> &'static str {
        match self {
            FormFactorMethod::Contour => "contour",
        }
    }

    pub fn parse(s: &str) -> Option<FormFactorMethod> {
        Self::ALL.iter().copied().find(|m| m.name() == s)
    }
}

/// Tunables shared by all methods.
#[derive(Clone, Debug)]
pub struct FormFactorParams {
    /// Shadow rays per receiver–patch pair (rounded to a square, stratified).
    pub visibility_rays: u32,
    /// Probe with 4 rays first for non-emitting shooters (see [`visibility_fraction`]).
    pub probe_visibility: bool,
    pub seed: u64,
}

impl Default for FormFactorParams {
    fn default() -> Self {
        Self {
            visibility_rays: 16,
            probe_visibility: true,
            seed: 1,
        }
    }
}

/// What a row computation may look at.
pub struct RowContext<'a> {
    pub scene: &'a Scene,
    pub mesh: &'a Mesh,
    /// BVH over the patch triangles (ids = input face index).
    pub bvh: &'a Bvh,
    pub params: &'a FormFactorParams,
    /// Offset of shadow-ray end points from their surfaces (scene units).
    pub epsilon: f64,
}

/// Stratified points on a polygon (area-uniform), for visibility rays.
pub struct PolygonSampler {
    triangles: Vec<[DVec3; 3]>,
    cdf: Vec<f64>,
    normal: DVec3,
}

impl PolygonSampler {
    pub fn new(poly: &[DVec3]) -> Self {
        let triangles: Vec<[DVec3; 3]> = polygon::triangulate(poly)
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
        if acc > 0.0 {
            cdf.iter_mut().for_each(|c| *c /= acc);
        }
        Self {
            triangles,
            cdf,
            normal: polygon::normal(poly).unwrap_or(DVec3::Z),
        }
    }

    /// Maps a point of the unit square to the polygon, area-preserving.
    pub fn point(&self, u1: f64, u2: f64) -> DVec3 {
        let k = self
            .cdf
            .partition_point(|c| *c <= u1)
            .min(self.triangles.len().saturating_sub(1));
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
}

/// Fraction of `m × m` stratified rays from `x` to the sampler's polygon that arrive. With
/// `probe`, four rays go first and decide alone when they agree (all arrive or none do);
/// a blocker smaller than the gaps between them can then be missed.
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
        |ray| bvh.any_hit_except(ray, 1e-9, 1.0 - 1e-9, ignore),
        x + nx * epsilon,
        target,
        m,
        probe,
        epsilon,
        rng,
    )
}

/// [`visibility_fraction`] with the blocking test given: rays from `origin` to stratified
/// points lifted `epsilon` off the target.
fn sampled_visibility(
    blocked: impl Fn(&Ray) -> bool,
    origin: DVec3,
    target: &PolygonSampler,
    m: u32,
    probe: bool,
    epsilon: f64,
    rng: &mut Rng,
) -> f64 {
    let ray_to = |u1: f64, u2: f64| {
        let y = target.point(u1, u2) + target.normal() * epsilon;
        Ray::new(origin, y - origin)
    };
    if probe && m > 2 {
        // A 2×2 stratified probe; if it agrees, take it (4 rays instead of m²).
        let mut seen = 0;
        for k in 0..4u32 {
            let u1 = ((k % 2) as f64 + rng.next_f64()) / 2.0;
            let u2 = ((k / 2) as f64 + rng.next_f64()) / 2.0;
            seen += u32::from(!blocked(&ray_to(u1, u2)));
        }
        if seen == 0 || seen == 4 {
            return seen as f64 / 4.0;
        }
    }
    let mut visible = 0u32;
    for a in 0..m {
        for b in 0..m {
            let u1 = (a as f64 + rng.next_f64()) / m as f64;
            let u2 = (b as f64 + rng.next_f64()) / m as f64;
            if !blocked(&ray_to(u1, u2)) {
                visible += 1;
            }
        }
    }
    visible as f64 / (m * m) as f64
}

fn side(rays: u32) -> u32 {
    ((rays.max(1) as f64).sqrt().round() as u32).max(1)
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
    let above = poly.iter().all(|v| (*v - x).dot(nx) >= 0.0);
    let v = if above {
        visibility_fraction(bvh, x, nx, full, m, probe, epsilon, ignore, rng)
    } else {
        let clipped = polygon::clip_to_halfspace(poly, x, nx);
        let part = PolygonSampler::new(&clipped);
        visibility_fraction(bvh, x, nx, &part, m, probe, epsilon, ignore, rng)
    };
    analytic * v
}

/// Computes `out[j] = F_ji`, from element `j` to the shooting patch `i`.
/// Returns `false` (leaving `out` partly written) when `cancel` was set during the work.
pub fn compute_row(
    method: FormFactorMethod,
    ctx: &RowContext,
    shooter: PatchId,
    out: &mut [f32],
    cancel: &AtomicBool,
) -> bool {
    match method {
        FormFactorMethod::Contour => contour_row(ctx, shooter, out, cancel),
    }
}

fn contour_row(ctx: &RowContext, shooter: PatchId, out: &mut [f32], cancel: &AtomicBool) -> bool {
    let mesh = ctx.mesh;
    let patch = mesh.patch(shooter);
    let sampler = PolygonSampler::new(&patch.polygon);
    let m = side(ctx.params.visibility_rays);
    let seed = ctx.params.seed;
    // Light sources always get every ray: their shadows matter most.
    let emitter = ctx.scene.materials[patch.material.0 as usize].is_emitter();
    let probe = ctx.params.probe_visibility && !emitter;
    // One slice of `out` per receiving patch (a patch's elements are contiguous).
    let mut slices = Vec::with_capacity(mesh.patches.len());
    let mut rest = out;
    for (k, r) in mesh.patches.iter().enumerate() {
        let (head, tail) = rest.split_at_mut((r.elements.end - r.elements.start) as usize);
        slices.push((k, head));
        rest = tail;
    }
    slices
        .into_par_iter()
        .for_each_init(Vec::new, |candidates, (k, slice)| {
            if cancel.load(Ordering::Relaxed) {
                return;
            }
            let receiver = &mesh.patches[k];
            let first = receiver.elements.start as usize;
            // Behind the shooter, or the shooter behind it (coplanar patches included).
            let behind = |poly: &[DVec3], of: &crate::mesh::Patch| {
                poly.iter()
                    .all(|v| (*v - of.centroid).dot(of.normal) <= 0.0)
            };
            if k == shooter.0 as usize
                || behind(&receiver.polygon, patch)
                || behind(&patch.polygon, receiver)
            {
                slice.fill(0.0);
                return;
            }
            // BVH ids are input faces; a planar face cannot block rays between its points.
            let ignore = [receiver.face as u32, patch.face as u32];
            // Triangles in the pair's bounding box first; the hull only when there are some.
            let bbox = Shaft::bounding_box(&receiver.polygon, &patch.polygon, ctx.epsilon);
            let culled = ctx
                .bvh
                .collect_in_shaft(&bbox, ignore, MAX_SHAFT_CANDIDATES, candidates);
            if culled && !candidates.is_empty() {
                let hull = Shaft::between(&receiver.polygon, &patch.polygon, ctx.epsilon);
                candidates.retain(|&t| !hull.excludes_triangle(ctx.bvh.stored_triangle(t)));
            }
            for (i, f) in slice.iter_mut().enumerate() {
                let j = first + i;
                let e = &mesh.elements[j];
                let analytic = contour::point_to_polygon_with_normal(
                    e.centroid,
                    e.normal,
                    &patch.polygon,
                    patch.normal,
                );
                if analytic <= 0.0 || (culled && candidates.is_empty()) {
                    *f = analytic.max(0.0) as f32;
                    continue;
                }
                let mut rng = Rng::new(hash_seed(&[seed, shooter.0 as u64, j as u64]), 0);
                let v = if culled {
                    element_visibility(
                        ctx, e.centroid, e.normal, patch, &sampler, m, probe, candidates, &mut rng,
                    )
                } else {
                    let above = patch
                        .polygon
                        .iter()
                        .all(|v| (*v - e.centroid).dot(e.normal) >= 0.0);
                    let part;
                    let target = if above {
                        &sampler
                    } else {
                        part = PolygonSampler::new(&polygon::clip_to_halfspace(
                            &patch.polygon,
                            e.centroid,
                            e.normal,
                        ));
                        &part
                    };
                    visibility_fraction(
                        ctx.bvh,
                        e.centroid,
                        e.normal,
                        target,
                        m,
                        probe,
                        ctx.epsilon,
                        ignore,
                        &mut rng,
                    )
                };
                *f = (analytic * v) as f32;
            }
        });
    !cancel.load(Ordering::Relaxed)
}

/// More candidate blockers than this in a patch pair's shaft: use the BVH instead.
const MAX_SHAFT_CANDIDATES: usize = 48;

/// Visible fraction of the shooter from a receiving point, given the only triangles that
/// can block (`candidates`, from the receiving patch's shaft): if none of them cuts the
/// point's own pyramid to the (clipped) shooter the answer is exactly 1 without a ray;
/// otherwise stratified rays are tested against the candidates alone.
#[allow(clippy::too_many_arguments)]
fn element_visibility(
    ctx: &RowContext,
    x: DVec3,
    nx: DVec3,
    patch: &crate::mesh::Patch,
    sampler: &PolygonSampler,
    m: u32,
    probe: bool,
    candidates: &[u32],
    rng: &mut Rng,
) -> f64 {
    let above = patch.polygon.iter().all(|v| (*v - x).dot(nx) >= 0.0);
    let clipped;
    let (poly, part) = if above {
        (&patch.polygon[..], None)
    } else {
        clipped = polygon::clip_to_halfspace(&patch.polygon, x, nx);
        (&clipped[..], Some(PolygonSampler::new(&clipped)))
    };
    let origin = x + nx * ctx.epsilon;
    let pyramid = Shaft::pyramid(origin, poly, ctx.epsilon);
    let cutting: Vec<u32> = candidates
        .iter()
        .copied()
        .filter(|&k| !pyramid.excludes_triangle(ctx.bvh.stored_triangle(k)))
        .collect();
    if cutting.is_empty() {
        return 1.0;
    }
    let target = part.as_ref().unwrap_or(sampler);
    sampled_visibility(
        |ray| ctx.bvh.any_hit_among(&cutting, ray, 1e-9, 1.0 - 1e-9),
        origin,
        target,
        m,
        probe,
        ctx.epsilon,
        rng,
    )
}
