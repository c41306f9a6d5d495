//! Carrying a progressive solution onto a refined mesh, so that adaptive meshing (Cohen,
//! Greenberg, Immel & Brock 1986) goes on from where the solve was instead of from dark,
//! and the viewer never goes dark when the mesh grows.
//!
//! What a patch has shot is `S_p = B̄_p − U_p` (gathered minus unshot, see the module docs
//! of [`super`]), and an element's incident radiance is the sum of the shots that reached
//! it, `H_j = Σ_i S_i F_ji`. On the new mesh:
//! - **Shot light is carried**: each new patch takes the `S` of the old patch its centroid
//!   lies in, scaled per base patch so that `Σ S A` over every base patch is the old one.
//! - **Every shot is re-aimed**: `H` is rebuilt as `Σ S F` with the new mesh's rows, so the
//!   new elements get what they would have received had they been there from the start:
//!   shadows and contact lines as sharp as the new elements at once. Each base patch's
//!   shots are scaled to deliver exactly the power they delivered (a factor of 1 ± the
//!   centroid rule's error, which the shooter's unshot radiance takes up). Conserving the
//!   power per *receiving* patch instead would freeze the coarse elements' O(h) error at
//!   shadow edges into the answer; inheriting the old elements' incident light (tried
//!   first, re-aiming only the lights) left the indirect light blocky near contacts: 2 %
//!   RMS and 30 % at worst on the Cornell floor, which later shots never corrected.
//! - `B = E + ρ H`, and the unshot radiance is again `U = B̄ − S`, so the residual is the
//!   new mesh's residual and shooting on converges to the new mesh's solution (the same,
//!   to the solve's tolerance, as solving it from dark, in fewer shots).
//!
//! So the light delivered, in all (`Σ H A`) and by each base patch's shots, is the same
//! before and after, to round-off: none gained or lost. The
//! one exception: a patch whose new rows reach nothing where its old ones reached
//! something (its light is dropped). Cost: a row per shooting patch on the new mesh, which
//! a solve from dark computes too (rows are held one base patch at a time); what the old
//! rows delivered is kept per patch while shooting, so they are not needed again. Declined (the
//! caller solves from dark) when the two meshes do not share their base patches, or on
//! cancel.

use std::sync::atomic::AtomicBool;

use glam::DVec3;

use super::super::rows::{RowCache, delivered};
use super::super::{Problem, channel_sum};
use super::ProgressiveSolver;
use crate::mesh::{Mesh, PatchId};
use crate::scene::Rgb;

/// Relative difference in a base patch's area above which two meshes are not of one scene
/// and one base mesh.
const SAME_AREA: f64 = 1e-6;

impl ProgressiveSolver {
    /// This solution carried onto `problem`, a mesh of the same scene with the same base
    /// patches (as [`Mesh::build_refined`] makes at any levels), see the module docs.
    /// Hands `problem` back when it cannot (other base patches, materials or sizes; or
    /// `cancel` set while rows were computed): then solve it from dark. Either way this
    /// solver's cached rows are dropped first (it recomputes a row it needs again).
    pub fn carry_to(
        &mut self,
        problem: Problem,
        cancel: &AtomicBool,
    ) -> Result<ProgressiveSolver, Box<Problem>> {
        if !same_base(&self.problem.mesh, &problem.mesh) {
            return Err(Box::new(problem));
        }
        // The old rows are not read again (what they delivered is kept per patch), and
        // the new mesh's rows fill a cache of their own: both at once held twice the
        // budget's cache share (an adaptive Cornell run peaked at 5.4 GB under 4 GB).
        self.rows.clear();
        match self.carried(&problem, cancel) {
            Some(state) => {
                let mut next = ProgressiveSolver::with_rows(problem, state.rows);
                next.incident = state.incident;
                next.radiosity = state.radiosity;
                next.unshot = state.unshot;
                next.delivered = state.delivered;
                next.shots = self.shots;
                debug_assert!(next.radiosity.iter().all(|b| b.is_finite()));
                debug_assert!(next.unshot.iter().all(|u| u.is_finite()));
                Ok(next)
            }
            None => Err(Box::new(problem)),
        }
    }

    /// Light shot so far per patch, `S_p = B̄_p − U_p` (radiance units).
    pub fn shot(&self) -> Vec<Rgb> {
        self.problem
            .mesh
            .patch_means(&self.radiosity)
            .into_iter()
            .zip(&self.unshot)
            .map(|(b, u)| b - *u)
            .collect()
    }

    fn carried(&mut self, new: &Problem, cancel: &AtomicBool) -> Option<Carried> {
        let old = &self.problem.mesh;
        let mesh = &new.mesh;
        let locator = Locator::new(old);
        let bases = old.base_count();

        // Shot light per new patch, conserved per base patch. A patch that never shot has
        // delivered nothing; its `B̄ − U` is round-off, and would cost a row.
        let old_shot: Vec<Rgb> = self
            .shot()
            .into_iter()
            .zip(&self.delivered)
            .map(|(s, d)| if *d == Rgb::ZERO { Rgb::ZERO } else { s })
            .collect();
        let mut shot: Vec<Rgb> = mesh
            .patches
            .iter()
            .enumerate()
            .map(|(p, patch)| {
                let j = locator.locate(mesh.base_patch[p], patch.centroid);
                old_shot[old.elements[j].patch.0 as usize]
            })
            .collect();
        let old_patch_area: Vec<f64> = old.patches.iter().map(|p| p.area).collect();
        let new_patch_area: Vec<f64> = mesh.patches.iter().map(|p| p.area).collect();
        let target = totals(&old_shot, &old_patch_area, &old.base_patch, bases);
        conserve(&mut shot, &new_patch_area, &mesh.base_patch, &target);

        // The power each base patch's shots delivered on the old mesh.
        let mut delivered_old = vec![Rgb::ZERO; bases];
        for (d, &b) in self.delivered.iter().zip(&old.base_patch) {
            delivered_old[b as usize] += *d;
        }

        // Every shot again through the new rows, a base patch at a time (its rows held
        // until its scale is known), scaled to deliver what it delivered.
        let mut by_base: Vec<Vec<usize>> = vec![Vec::new(); bases];
        for (p, &b) in mesh.base_patch.iter().enumerate() {
            if channel_sum(shot[p]) > 0.0 {
                by_base[b as usize].push(p);
            }
        }
        let mut rows = RowCache::default();
        let mut incident = vec![Rgb::ZERO; mesh.elements.len()];
        let mut delivered_new = vec![Rgb::ZERO; mesh.patches.len()];
        // Dimmest first: where the rows pass the cache's budget, the least recently used go,
        // and the brightest shooters, which shoot again soonest, stay.
        let mut order: Vec<usize> = (0..bases).collect();
        order.sort_by(|&a, &b| {
            channel_sum(delivered_old[a]).total_cmp(&channel_sum(delivered_old[b]))
        });
        for b in order {
            let patches = &by_base[b];
            let mut held = Vec::with_capacity(patches.len());
            for &p in patches {
                let row = rows.row(new, PatchId(p as u32), cancel)?;
                delivered_new[p] = shot[p] * delivered(mesh, &row);
                held.push(row);
            }
            let now = patches
                .iter()
                .fold(Rgb::ZERO, |sum, &p| sum + delivered_new[p]);
            let scale = scale(delivered_old[b], now);
            for (&p, row) in patches.iter().zip(&held) {
                shot[p] *= scale;
                delivered_new[p] *= scale;
                let s = shot[p];
                for (h, f) in incident.iter_mut().zip(row.iter()) {
                    *h += s * f64::from(*f);
                }
            }
        }

        let emission = new.element_emission();
        let rho = new.element_reflectance();
        let radiosity: Vec<Rgb> = incident
            .iter()
            .zip(emission.iter().zip(&rho))
            .map(|(h, (e, r))| *e + *r * *h)
            .collect();
        let unshot = mesh
            .patch_means(&radiosity)
            .into_iter()
            .zip(&shot)
            .map(|(b, s)| b - *s)
            .collect();
        Some(Carried {
            rows,
            incident,
            radiosity,
            unshot,
            delivered: delivered_new,
        })
    }
}

/// Per channel, what scales `now` to `was`; 1 where `now` is zero (a patch whose new rows
/// reach nothing: what it delivered is then not kept, the one exception to exactness).
fn scale(was: Rgb, now: Rgb) -> Rgb {
    let channel = |w: f64, n: f64| if n != 0.0 { w / n } else { 1.0 };
    Rgb::new(
        channel(was.x, now.x),
        channel(was.y, now.y),
        channel(was.z, now.z),
    )
}

/// The new solver's state.
struct Carried {
    rows: RowCache,
    incident: Vec<Rgb>,
    radiosity: Vec<Rgb>,
    unshot: Vec<Rgb>,
    delivered: Vec<Rgb>,
}

/// `Σ v A` per base patch.
fn totals(values: &[Rgb], area: &[f64], base: &[u32], bases: usize) -> Vec<Rgb> {
    let mut t = vec![Rgb::ZERO; bases];
    for ((v, a), &b) in values.iter().zip(area).zip(base) {
        t[b as usize] += *v * *a;
    }
    t
}

/// Scales `values` per base patch and channel so that `Σ v A` is `target`; a base whose
/// values sum to zero where the target does not gets the target spread evenly.
fn conserve(values: &mut [Rgb], area: &[f64], base: &[u32], target: &[Rgb]) {
    let now = totals(values, area, base, target.len());
    let mut base_area = vec![0.0; target.len()];
    for (a, &b) in area.iter().zip(base) {
        base_area[b as usize] += *a;
    }
    for ((v, _), &b) in values.iter_mut().zip(area).zip(base) {
        let b = b as usize;
        let fix = |v: f64, now: f64, target: f64| {
            if now != 0.0 {
                v * (target / now)
            } else {
                target / base_area[b]
            }
        };
        *v = Rgb::new(
            fix(v.x, now[b].x, target[b].x),
            fix(v.y, now[b].y, target[b].y),
            fix(v.z, now[b].z, target[b].z),
        );
    }
}

/// True when `new` is meshed on the same base patches as `old`: the same count, each of
/// the same area and material.
fn same_base(old: &Mesh, new: &Mesh) -> bool {
    let area = |m: &Mesh| {
        let mut a = vec![(0.0, None); m.base_count()];
        for (p, &b) in m.patches.iter().zip(&m.base_patch) {
            a[b as usize].0 += p.area;
            a[b as usize].1 = Some(p.material);
        }
        a
    };
    let (a, b) = (area(old), area(new));
    a.len() == b.len()
        && a.iter()
            .zip(&b)
            .all(|(x, y)| x.1 == y.1 && (x.0 - y.0).abs() <= SAME_AREA * x.0.max(y.0))
}

/// Finds the old element under a point of a new patch, among the old elements of the same
/// base patch.
struct Locator<'a> {
    old: &'a Mesh,
    /// Old patches per base patch.
    patches: Vec<Vec<u32>>,
}

impl<'a> Locator<'a> {
    fn new(old: &'a Mesh) -> Self {
        let mut patches = vec![Vec::new(); old.base_count()];
        for (p, &b) in old.base_patch.iter().enumerate() {
            patches[b as usize].push(p as u32);
        }
        Self { old, patches }
    }

    /// The old element of base patch `base` that holds `point`, or the one with the
    /// nearest centroid (a cluster's facets are not in one plane).
    fn locate(&self, base: u32, point: DVec3) -> usize {
        let patches = &self.patches[base as usize];
        for &p in patches {
            let patch = &self.old.patches[p as usize];
            if patch.centroid.distance(point) > patch.radius * (1.0 + 1e-9) {
                continue;
            }
            for j in patch.elements.start..patch.elements.end {
                let e = &self.old.elements[j as usize];
                if holds(e.corners(), e.normal, point) {
                    return j as usize;
                }
            }
        }
        let mut nearest = (f64::INFINITY, usize::MAX);
        for &p in patches {
            let patch = &self.old.patches[p as usize];
            for j in patch.elements.start..patch.elements.end {
                let d = self.old.elements[j as usize]
                    .centroid
                    .distance_squared(point);
                if d < nearest.0 {
                    nearest = (d, j as usize);
                }
            }
        }
        debug_assert!(nearest.1 != usize::MAX, "a base patch without elements");
        nearest.1
    }
}

/// `point` inside (or on) the convex polygon `corners` with normal `normal`, and in its
/// plane to a small fraction of its size.
fn holds(corners: &[DVec3], normal: DVec3, point: DVec3) -> bool {
    let n = corners.len();
    let size = corners[0].distance(corners[n / 2]).max(f64::MIN_POSITIVE);
    if (point - corners[0]).dot(normal).abs() > 1e-6 * size {
        return false;
    }
    (0..n).all(|k| {
        let (a, b) = (corners[k], corners[(k + 1) % n]);
        (b - a).cross(point - a).dot(normal) >= -1e-9 * (b - a).length_squared()
    })
}

#[cfg(test)]
mod tests;
