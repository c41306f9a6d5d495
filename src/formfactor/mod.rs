//! Form factors: how much of the light leaving one surface arrives at another.
//!
//! The solver needs, for a shooting patch `i`, a *row*: for every receiving element `j` the
//! form factor `F_ji` from (a point of) `j` to the whole of `i`, so that
//! `ΔB_j = ρ_j ΔB_i F_ji` (Cohen, Chen, Wallace, Greenberg 1988). The default method,
//! `contour`, evaluates Lambert's exact point-to-polygon formula at the element's centroid
//! and deals with blockers in three tiers: triangles outside the pair's shaft (Haines &
//! Wallace 1994) cannot block, so most pairs need no ray at all; for a light source (or with
//! probing off), when up to `exact_blockers` (12) triangles cut the point's own pyramid to
//! the patch, their shadows are subtracted from the patch polygon and Lambert's formula
//! integrates the visible rest exactly ([`exact::point_to_visible_polygon`]); otherwise the
//! visible fraction of stratified shadow rays is used (a 4-ray probe first for non-emitters),
//! each ray weighted by its point-to-point form factor (Wallace, Elmquist, Haines 1989).
//! Known error: the probe can miss a blocker smaller than its ray spacing; the sampled tier
//! has stratified noise O(N^-3/4) in penumbrae; the centroid rule integrates over the
//! receiving element with O(h²) error.

pub mod cases;
pub mod contour;
pub mod exact;
pub mod hemicube;
pub mod hybrid;
pub mod montecarlo;
pub mod raycast;

use std::sync::atomic::{AtomicBool, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use crate::geometry::sampling::{hash_seed, triangle_point};
use crate::geometry::shaft::Shaft;
use crate::geometry::{Bvh, Ray, Rng, polygon};
use crate::mesh::{Mesh, PatchId};
use crate::scene::Scene;

/// Which method computes form factors. Parsed from its [`name`](Self::name) by
/// [`FromStr`](std::str::FromStr) and by clap (`ValueEnum`), so every command line shares
/// one parser and one list.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, clap::ValueEnum)]
pub enum FormFactorMethod {
    /// Exact point-to-polygon contour formula × stratified visibility.
    Contour,
    /// Exact polygon-to-polygon double contour integral (cases); as a solver row, the
    /// element's own polygon against the patch, × stratified visibility.
    Exact,
    /// Item-buffer hemicube at the shooter's centroid.
    Hemicube,
    /// Cosine-weighted rays from the shooter against the scene.
    Raycast,
    /// Random point pairs on both polygons, with visibility.
    Montecarlo,
    /// Analytic for lights and near or small receivers, hemicube for the rest.
    Hybrid,
    /// The item-buffer hemicube rasterised by a GPU through wgpu (`crate::gpu`); needs a
    /// [`hemicube::ItemBufferRaster`] in the [`RowContext`].
    GpuHemicube,
}

impl FormFactorMethod {
    pub const ALL: &'static [FormFactorMethod] = &[
        FormFactorMethod::Contour,
        FormFactorMethod::Exact,
        FormFactorMethod::Hemicube,
        FormFactorMethod::Raycast,
        FormFactorMethod::Montecarlo,
        FormFactorMethod::Hybrid,
        FormFactorMethod::GpuHemicube,
    ];

    pub fn name(self) -> &'static str {
        match self {
            FormFactorMethod::Contour => "contour",
            FormFactorMethod::Exact => "exact",
            FormFactorMethod::Hemicube => "hemicube",
            FormFactorMethod::Raycast => "raycast",
            FormFactorMethod::Montecarlo => "montecarlo",
            FormFactorMethod::Hybrid => "hybrid",
            FormFactorMethod::GpuHemicube => "gpu-hemicube",
        }
    }

    pub fn parse(s: &str) -> Option<FormFactorMethod> {
        Self::ALL.iter().copied().find(|m| m.name() == s)
    }

    /// The names, comma-separated (for messages).
    pub fn names() -> String {
        Self::ALL
            .iter()
            .map(|m| m.name())
            .collect::<Vec<_>>()
            .join(", ")
    }
}

impl std::fmt::Display for FormFactorMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown method name.
#[derive(Debug, thiserror::Error)]
#[error("unknown form-factor method '{0}' (available: {names})", names = FormFactorMethod::names())]
pub struct UnknownMethod(pub String);

impl std::str::FromStr for FormFactorMethod {
    type Err = UnknownMethod;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::parse(s).ok_or_else(|| UnknownMethod(s.to_string()))
    }
}

/// Tunables shared by all methods.
#[derive(Clone, Debug)]
pub struct FormFactorParams {
    /// Shadow rays per receiver–patch pair (rounded to a square, stratified); for
    /// `montecarlo` rows, point pairs per receiving element.
    pub visibility_rays: u32,
    /// Probe with 4 rays first for non-emitting shooters (see [`visibility_fraction`]).
    pub probe_visibility: bool,
    pub seed: u64,
    /// Hemicube resolution: pixels across the top face (the sides are half as tall).
    pub hemicube_res: u32,
    /// Rotate each hemicube by a random angle about the normal (breaks aliasing patterns).
    pub hemicube_rotate: bool,
    /// Rays per `raycast` row (from the shooting patch), and samples per case for the
    /// sampling methods (`raycast` rays, `montecarlo` point pairs).
    pub rays: u32,
    /// Refinement levels of the adaptive cubature over A1 for `exact` cases with occluders
    /// (the integrand has kinks along penumbra boundaries, so its 1e-10 tolerance is not
    /// reached there; each level quarters the cells near the kinks).
    pub cubature_depth: u32,
    /// `hybrid`: a receiver closer than `hybrid_k · √(A_shooter/π)` is computed analytically.
    pub hybrid_k: f64,
    /// `hybrid`: a receiver expected to cover fewer hemicube pixels than this is computed
    /// analytically too (aliasing of small or far patches).
    pub hybrid_min_pixels: f64,
    /// `contour`: for shooters that get every ray (lights; all with `probe_visibility` off),
    /// at most this many blockers cutting a point's pyramid have their shadows clipped away
    /// exactly ([`exact::point_to_visible_polygon`]); more, and weighted shadow rays decide.
    /// 0 always samples.
    pub exact_blockers: usize,
}

impl Default for FormFactorParams {
    fn default() -> Self {
        Self {
            visibility_rays: 16,
            probe_visibility: true,
            seed: 1,
            hemicube_res: 256,
            hemicube_rotate: true,
            rays: 1 << 16,
            cubature_depth: 5,
            hybrid_k: 5.0,
            hybrid_min_pixels: 64.0,
            exact_blockers: 12,
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
    /// The rasteriser of `gpu-hemicube` rows (without one they fall back to the CPU hemicube).
    pub raster: Option<&'a dyn hemicube::ItemBufferRaster>,
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

    /// True for a degenerate polygon (no triangles to sample).
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
        |ray| bvh.any_hit_except(ray, 1e-9, 1.0 - 1e-9, ignore),
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
/// to stratified points lifted `epsilon` off the target.
#[allow(clippy::too_many_arguments)]
fn sampled_visibility(
    blocked: impl Fn(&Ray) -> bool,
    origin: DVec3,
    nx: DVec3,
    target: &PolygonSampler,
    m: u32,
    probe: bool,
    epsilon: f64,
    rng: &mut Rng,
) -> f64 {
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
            if !blocked(&ray) {
                visible += w;
            }
        }
    }
    if total > 0.0 { visible / total } else { 0.0 }
}

/// How many of 2×2 stratified rays from `origin` to the target (lifted `epsilon`) arrive.
fn probe_rays(
    blocked: impl Fn(&Ray) -> bool,
    origin: DVec3,
    target: &PolygonSampler,
    epsilon: f64,
    rng: &mut Rng,
) -> u32 {
    let mut seen = 0;
    for k in 0..4u32 {
        let u1 = ((k % 2) as f64 + rng.next_f64()) / 2.0;
        let u2 = ((k / 2) as f64 + rng.next_f64()) / 2.0;
        let y = target.point(u1, u2) + target.normal() * epsilon;
        seen += u32::from(!blocked(&Ray::new(origin, y - origin)));
    }
    seen
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
    let lift = |p: DVec3, n: DVec3| p + n * eps;
    let blocked = |from: DVec3, to: DVec3| {
        let (a, b) = (lift(from, receiver.normal), lift(to, shooter.normal));
        ctx.bvh
            .any_hit_except(&Ray::new(a, b - a), 1e-9, 1.0 - 1e-9, ignore)
    };
    if blocked(receiver.centroid, shooter.centroid) {
        return false;
    }
    for corner in &receiver.polygon {
        // A little inside the corner, off the neighbouring faces.
        let from = *corner + (receiver.centroid - *corner) * 0.01;
        for k in 0..4u32 {
            let u1 = ((k % 2) as f64 + rng.next_f64()) / 2.0;
            let u2 = ((k / 2) as f64 + rng.next_f64()) / 2.0;
            if blocked(from, sampler.point(u1, u2)) {
                return false;
            }
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
        FormFactorMethod::Exact => exact::row(ctx, shooter, out, cancel),
        FormFactorMethod::Hemicube => hemicube::row(ctx, shooter, out, cancel),
        FormFactorMethod::Raycast => raycast::row(ctx, shooter, out, cancel),
        FormFactorMethod::Montecarlo => montecarlo::row(ctx, shooter, out, cancel),
        FormFactorMethod::Hybrid => hybrid::row(ctx, shooter, out, cancel),
        FormFactorMethod::GpuHemicube => hemicube::raster_row(ctx, shooter, out, cancel),
    }
}

/// Splits a row into one slice per receiving patch (a patch's elements are contiguous).
pub(crate) fn patch_slices<'o>(mesh: &Mesh, out: &'o mut [f32]) -> Vec<(usize, &'o mut [f32])> {
    let mut slices = Vec::with_capacity(mesh.patches.len());
    let mut rest = out;
    for (k, r) in mesh.patches.iter().enumerate() {
        let (head, tail) = rest.split_at_mut((r.elements.end - r.elements.start) as usize);
        slices.push((k, head));
        rest = tail;
    }
    slices
}

/// What the analytic rows share for one shot.
pub(crate) struct ShotSetup {
    pub sampler: PolygonSampler,
    pub m: u32,
    pub probe: bool,
}

impl ShotSetup {
    pub fn new(ctx: &RowContext, shooter: PatchId) -> Self {
        let patch = ctx.mesh.patch(shooter);
        // Light sources always get every ray: their shadows matter most.
        let emitter = ctx.scene.materials[patch.material.0 as usize].is_emitter();
        Self {
            sampler: PolygonSampler::new(&patch.polygon),
            m: side(ctx.params.visibility_rays),
            probe: ctx.params.probe_visibility && !emitter,
        }
    }
}

/// The contour method for the elements of receiving patch `k` (`slice`).
pub(crate) fn contour_patch(
    ctx: &RowContext,
    shooter: PatchId,
    setup: &ShotSetup,
    k: usize,
    slice: &mut [f32],
) {
    let mesh = ctx.mesh;
    let patch = mesh.patch(shooter);
    let receiver = &mesh.patches[k];
    let first = receiver.elements.start as usize;
    // Behind the shooter, or the shooter behind it (coplanar patches included).
    let behind = |poly: &[DVec3], of: &crate::mesh::Patch| {
        poly.iter()
            .all(|v| (*v - of.centroid).dot(of.normal) <= 0.0)
    };
    if k == shooter.0 as usize || behind(&receiver.bounds, patch) || behind(&patch.bounds, receiver)
    {
        slice.fill(0.0);
        return;
    }
    // BVH ids are visibility groups; a planar surface (or a small cluster of facets)
    // cannot block rays between its own points.
    let ignore = [receiver.occluder, patch.occluder];
    // Triangles in the pair's bounding box first; the hull only when there are some.
    let mut candidates = Vec::new();
    let bbox = Shaft::bounding_box(&receiver.bounds, &patch.bounds, ctx.epsilon);
    let culled = ctx
        .bvh
        .collect_in_shaft(&bbox, ignore, MAX_SHAFT_CANDIDATES, &mut candidates);
    if culled && !candidates.is_empty() {
        let hull = Shaft::between(&receiver.bounds, &patch.bounds, ctx.epsilon);
        candidates.retain(|&t| !hull.excludes_triangle(ctx.bvh.stored_triangle(t)));
    }
    for (i, f) in slice.iter_mut().enumerate() {
        let j = first + i;
        let e = &mesh.elements[j];
        let mut rng = Rng::new(hash_seed(&[ctx.params.seed, shooter.0 as u64, j as u64]), 0);
        if !culled {
            // Too many candidate blockers to list: shadow rays through the whole BVH.
            *f = occluded_point_to_polygon(
                ctx.bvh,
                e.centroid,
                e.normal,
                &patch.polygon,
                &setup.sampler,
                setup.m,
                setup.probe,
                ctx.epsilon,
                ignore,
                &mut rng,
            ) as f32;
            continue;
        }
        let analytic = contour::point_to_polygon_with_normal(
            e.centroid,
            e.normal,
            &patch.polygon,
            patch.normal,
        );
        if analytic <= 0.0 || candidates.is_empty() {
            *f = analytic.max(0.0) as f32;
            continue;
        }
        *f = match element_visibility(
            ctx,
            e.centroid,
            e.normal,
            patch,
            &setup.sampler,
            setup.m,
            setup.probe,
            &candidates,
            &mut rng,
        ) {
            Visibility::Fraction(v) => (analytic * v) as f32,
            Visibility::Exact(value) => value as f32,
        };
    }
}

/// What [`element_visibility`] found.
enum Visibility {
    /// Multiply Lambert's unoccluded value by this.
    Fraction(f64),
    /// The form factor to the visible part itself.
    Exact(f64),
}

fn contour_row(ctx: &RowContext, shooter: PatchId, out: &mut [f32], cancel: &AtomicBool) -> bool {
    let setup = ShotSetup::new(ctx, shooter);
    patch_slices(ctx.mesh, out)
        .into_par_iter()
        .for_each(|(k, slice)| {
            if cancel.load(Ordering::Relaxed) {
                return;
            }
            contour_patch(ctx, shooter, &setup, k, slice);
        });
    !cancel.load(Ordering::Relaxed)
}

/// More candidate blockers than this in a patch pair's shaft: use the BVH instead.
const MAX_SHAFT_CANDIDATES: usize = 48;

/// The shooter as seen from a receiving point, given the only triangles that can block
/// (`candidates`, from the receiving patch's shaft): if none of them cuts the point's own
/// pyramid to the (clipped) shooter it is fully visible, without a ray; if a few do, their
/// shadows are subtracted from the shooter polygon and Lambert's formula integrates what is
/// left (exact, no noise); with many, stratified rays are tested against them alone.
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
) -> Visibility {
    let above = patch.polygon.iter().all(|v| (*v - x).dot(nx) >= 0.0);
    let clipped;
    let poly = if above {
        &patch.polygon[..]
    } else {
        clipped = polygon::clip_to_halfspace(&patch.polygon, x, nx);
        &clipped[..]
    };
    let origin = x + nx * ctx.epsilon;
    let pyramid = Shaft::pyramid(origin, poly, ctx.epsilon);
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
    // and the rays it saves: measured in docs/FORMFACTORS.md).
    if !probe && cutting.len() <= ctx.params.exact_blockers {
        let blockers: Vec<Vec<DVec3>> = cutting
            .iter()
            .map(|&k| ctx.bvh.stored_triangle(k).to_vec())
            .collect();
        let value = exact::point_to_visible_polygon(origin, nx, &patch.polygon, &blockers);
        debug_assert!(value.is_finite());
        return Visibility::Exact(value.max(0.0));
    }
    // Only the sampled tier needs a sampler of the clipped polygon.
    let part = (!above).then(|| PolygonSampler::new(poly));
    let target = part.as_ref().unwrap_or(sampler);
    Visibility::Fraction(sampled_visibility(
        |ray| ctx.bvh.any_hit_among(&cutting, ray, 1e-9, 1.0 - 1e-9),
        origin,
        nx,
        target,
        m,
        probe,
        ctx.epsilon,
        rng,
    ))
}
