//! Rows of form factors: the solver's unit of work. For a shooting patch `i`, a row holds
//! `F_ji` for every receiving element `j`. [`compute_row`] dispatches on the method; the
//! contour row itself (`contour_patch`) is here, its visibility in [`super::visibility`]
//! and its kernel in [`super::contour`].

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use super::visibility::{
    PolygonSampler, Visibility, element_visibility, occluded_point_to_polygon,
    patch_pair_unblocked, side,
};
use super::{
    FormFactorMethod, FormFactorParams, contour, exact, hemicube, hybrid, montecarlo, raycast,
};
use crate::geometry::sampling::hash_seed;
use crate::geometry::shaft::Shaft;
use crate::geometry::{Bvh, Rng};
use crate::mesh::{Mesh, PatchId};
use crate::scene::Scene;

use glam::DVec3;

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

/// A light-source patch carrying less than this share of the scene's emitted power probes
/// like any other shooter instead of getting every ray.
pub const FULL_RAYS_LIGHT_SHARE: f64 = 1.0 / 16.0;

impl ShotSetup {
    pub fn new(ctx: &RowContext, shooter: PatchId) -> Self {
        let patch = ctx.mesh.patch(shooter);
        Self {
            sampler: PolygonSampler::new(&patch.polygon),
            m: side(ctx.params.visibility_rays),
            probe: ctx.params.probe_visibility && !major_light(ctx, shooter),
        }
    }
}

/// Whether `shooter` is a light source carrying at least [`FULL_RAYS_LIGHT_SHARE`] of the
/// power the scene's faces emit. Those get every shadow ray (and exact shadows): their
/// shadows are what the eye sees sharpest. A light cut into many patches (an emitting
/// sphere of 500 facets) has each piece probe with 4 rays first: the pieces' independent
/// samples average out in the penumbra they share, and a shot then costs what its light
/// is worth instead of 16 rays per receiving element (the atrium's two spheres: 16 → about
/// 4 rays per element and shot).
fn major_light(ctx: &RowContext, shooter: PatchId) -> bool {
    let power = |p: &crate::mesh::Patch| {
        let e = ctx.scene.materials[p.material.0 as usize].emission;
        (e.x + e.y + e.z) * p.area
    };
    let own = power(ctx.mesh.patch(shooter));
    if own <= 0.0 {
        return false;
    }
    let total: f64 = ctx.mesh.patches.iter().map(power).sum();
    // A light cut into exactly 16 equal pieces sits on the threshold: the margin keeps
    // rounding (which differs with the scene's unit) from deciding.
    own >= FULL_RAYS_LIGHT_SHARE * total * (1.0 - 1e-9)
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
    // Too many candidate blockers to list: shadow rays through the whole BVH, unless the
    // 17-ray patch-pair test (for shooters that probe) finds the pair wholly unblocked.
    let all_visible =
        !culled && setup.probe && patch_pair_unblocked(ctx, receiver, patch, shooter, k, ignore);
    for (i, f) in slice.iter_mut().enumerate() {
        let j = first + i;
        let e = &mesh.elements[j];
        let mut rng = Rng::new(hash_seed(&[ctx.params.seed, shooter.0 as u64, j as u64]), 0);
        if !culled && !all_visible {
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
        if analytic <= 0.0 || all_visible || candidates.is_empty() {
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
