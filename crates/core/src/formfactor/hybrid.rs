//! Hybrid: the hemicube where it is good, the analytic contour method everywhere else.
//!
//! VRAD (Valve's radiosity compiler) and Wallace, Elmquist & Haines (1989) use analytic
//! form factors for light sources and for receivers within about five shooter radii, where
//! the hemicube's point approximation of the shooter fails. The hemicube also fails the other
//! way — aliasing — for receivers that cover few of its pixels (small or far elements, and
//! every reference case at distance 100), so the rule here is: a receiving element gets
//! [`contour`](super::contour) values (Lambert × stratified visibility) when
//!
//! * the shooter emits (its shadows matter most), or
//! * its centroid is closer than `k · √(A_i/π)` to the shooter's centroid (`hybrid_k`), or
//! * it is expected to cover fewer than `hybrid_min_pixels` hemicube pixels
//!   (`A_j cosθ_j / r²` over the solid angle of a top-face pixel),
//!
//! and the hemicube value otherwise. The hemicube is rasterised only when some element
//! needs it. Known error: that of the contour method on the analytic part, and of a
//! hemicube with at least `hybrid_min_pixels` pixels per element on the rest (roughly one
//! boundary pixel in `√pixels`); the measured figures and the choice of `k` are in
//! docs/FORMFACTORS.md.

use std::sync::atomic::{AtomicBool, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use super::FormFactorParams;
use super::hemicube::{self, DeltaTable};
use super::row::{RowContext, ShotSetup, contour_patch, patch_slices};
use crate::mesh::PatchId;

/// Whether a receiver (centroid `c`, normal `n`, area `a`) is computed analytically for a
/// shooter (centroid `sc`, area `sa`, emitting or not).
#[allow(clippy::too_many_arguments)]
pub fn analytic(
    params: &FormFactorParams,
    pixel_solid_angle: f64,
    emitter: bool,
    sc: DVec3,
    sa: f64,
    c: DVec3,
    n: DVec3,
    a: f64,
) -> bool {
    if emitter {
        return true;
    }
    let d = sc - c;
    let r2 = d.length_squared();
    let radius = (sa.max(a) / std::f64::consts::PI).sqrt();
    if r2 < (params.hybrid_k * radius).powi(2) {
        return true;
    }
    let cos = n.dot(d) / r2.sqrt();
    if cos <= 0.0 {
        return true; // Faces away: the contour row gives 0 at no cost.
    }
    a * cos / r2 / pixel_solid_angle < params.hybrid_min_pixels
}

/// Below this share of receivers for the hemicube, a shot uses the contour method alone.
pub const MIN_HEMICUBE_SHARE: f64 = 0.25;

/// Whether [`analytic`] holds for every element of `receiver` (decided from its bounding
/// sphere and largest element; `false` means "perhaps not").
fn all_analytic(
    ctx: &RowContext,
    shooter: &crate::mesh::Patch,
    receiver: &crate::mesh::Patch,
    pixel_solid_angle: f64,
) -> bool {
    let near_radius = ctx.params.hybrid_k * (shooter.area / std::f64::consts::PI).sqrt();
    let d = (receiver.centroid - shooter.centroid).length();
    if d + receiver.radius < near_radius {
        return true;
    }
    let nearest = (d - receiver.radius).max(0.0);
    nearest > 0.0
        && receiver.largest_element_area / (nearest * nearest) / pixel_solid_angle
            < ctx.params.hybrid_min_pixels
}

/// [`analytic`] for an element receiving from `shooter`.
fn element_analytic(
    ctx: &RowContext,
    shooter: &crate::mesh::Patch,
    emitter: bool,
    omega: f64,
    e: &crate::mesh::Element,
) -> bool {
    analytic(
        ctx.params,
        omega,
        emitter,
        shooter.centroid,
        shooter.area,
        e.centroid,
        e.normal,
        e.area,
    )
}

/// The number of receiving elements [`analytic`] gives the hemicube, the shooter's own
/// excluded: per-element tests only on the patches whose bounding sphere and largest element
/// (a few operations per patch) do not already decide that all of theirs are analytic.
pub fn hemicube_count(ctx: &RowContext, shooter: PatchId, emitter: bool, omega: f64) -> usize {
    let mesh = ctx.mesh;
    let patch = mesh.patch(shooter);
    mesh.patches
        .iter()
        .enumerate()
        .filter(|(k, r)| *k != shooter.0 as usize && !all_analytic(ctx, patch, r, omega))
        .map(|(_, r)| {
            mesh.elements[r.elements.start as usize..r.elements.end as usize]
                .iter()
                .filter(|e| !element_analytic(ctx, patch, emitter, omega, e))
                .count()
        })
        .sum()
}

/// `out[j] = F_ji`: contour values for analytic receivers, hemicube values for the rest.
pub fn row(ctx: &RowContext, shooter: PatchId, out: &mut [f32], cancel: &AtomicBool) -> bool {
    let mesh = ctx.mesh;
    let patch = mesh.patch(shooter);
    let emitter = ctx.scene.materials[patch.material.0 as usize].is_emitter();
    let omega = DeltaTable::pixel_solid_angle_at(ctx.params.hemicube_res);
    // The hemicube costs a whole raster per shot; when it would serve only a small share of
    // the receivers, the contour method for all of them is cheaper and never less accurate.
    // Counted without allocating, patch by patch, so that this case costs the contour row
    // plus a pass over the patches.
    if emitter
        || (hemicube_count(ctx, shooter, emitter, omega) as f64)
            < MIN_HEMICUBE_SHARE * mesh.elements.len() as f64
    {
        return super::compute_row(super::FormFactorMethod::Contour, ctx, shooter, out, cancel);
    }
    let is_analytic: Vec<bool> = mesh
        .elements
        .par_iter()
        .map(|e| element_analytic(ctx, patch, emitter, omega, e))
        .collect();
    let table = DeltaTable::new(ctx.params.hemicube_res);
    let Some(cube) = hemicube::element_values(ctx, shooter, &table, cancel) else {
        return false;
    };
    let setup = ShotSetup::new(ctx, shooter);
    patch_slices(mesh, out)
        .into_par_iter()
        .for_each(|(k, slice)| {
            if cancel.load(Ordering::Relaxed) {
                return;
            }
            let first = mesh.patches[k].elements.start as usize;
            let range = first..first + slice.len();
            if is_analytic[range.clone()].iter().any(|a| *a) {
                contour_patch(ctx, shooter, &setup, k, slice);
            }
            for (i, f) in slice.iter_mut().enumerate() {
                let j = first + i;
                if !is_analytic[j] {
                    let e = &mesh.elements[j];
                    *f = (cube[j] * patch.area / e.area) as f32;
                }
            }
        });
    !cancel.load(Ordering::Relaxed)
}
