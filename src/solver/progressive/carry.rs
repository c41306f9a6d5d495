//! Carrying a progressive solution onto a refined mesh, so that adaptive meshing (Cohen,
//! Greenberg, Immel & Brock 1986) goes on from where the solve was instead of from dark.
//!
//! What a patch has shot is `S_p = B̄_p − U_p` (gathered minus unshot, see the module docs
//! of [`super`]), and an element's incident radiance is the sum of the shots that reached
//! it, `H_j = Σ_i S_i F_ji`. On the new mesh:
//! - **Shot light is kept**: each new patch takes the `S` of the old patch its centroid lies
//!   in, scaled per base patch so that `Σ S A` over every base patch is exactly the old one.
//! - **The emitters' shots are re-aimed**: the part of `H` that came from emitting patches
//!   is taken out and shot again with the new mesh's rows, so shadows of the lights get as
//!   sharp as the new elements at once. The power each emitting base patch delivered is
//!   kept exactly: its new patches' `S` is scaled by old over new delivered power (a factor
//!   of 1 ± the centroid rule's error, which their unshot radiance takes up), so that
//!   `H = Σ S F` still holds for the emitters on the new mesh. Conserving the power per
//!   receiving patch instead would freeze the coarse elements' O(h) error at shadow edges
//!   into the answer.
//! - **The rest of `H` (light reflected on its way) is inherited**: a new element takes the
//!   value of the old element its centroid lies in, scaled per base patch so its power is
//!   exactly the old one. Known error: this part stays piecewise constant at the old
//!   element size, a fraction of the element's radiance that is small where only indirect
//!   light varies (it is smooth) and that later shots do not correct.
//! - `B = E + ρ H`, and the unshot radiance is again `U = B̄ − S`, so the residual stays the
//!   residual of the new mesh's system, and shooting it converges on the new mesh.
//!
//! So the light delivered (`Σ H A`, and per emitting base patch), and the light each
//! reflecting base patch has shot (`Σ S A`), are the same before and after, to round-off:
//! none gained or lost. Declined (the caller solves from
//! dark) when the two meshes do not share their base patches, or on cancel.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use glam::DVec3;

use super::super::Problem;
use super::super::rows::RowCache;
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
    /// `cancel` set while rows were computed): then solve it from dark.
    pub fn carry_to(
        &mut self,
        problem: Problem,
        cancel: &AtomicBool,
    ) -> Result<ProgressiveSolver, Box<Problem>> {
        if !same_base(&self.problem.mesh, &problem.mesh) {
            return Err(Box::new(problem));
        }
        match self.carried(&problem, cancel) {
            Some(state) => {
                let mut next = ProgressiveSolver::with_rows(problem, state.rows);
                next.incident = state.incident;
                next.radiosity = state.radiosity;
                next.unshot = state.unshot;
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
        patch_mean(&self.problem.mesh, &self.radiosity)
            .into_iter()
            .zip(&self.unshot)
            .map(|(b, u)| b - *u)
            .collect()
    }

    fn carried(&mut self, new: &Problem, cancel: &AtomicBool) -> Option<Carried> {
        let old = &self.problem.mesh;
        let mesh = &new.mesh;
        let locator = Locator::new(old);
        let bases = base_count(old);

        // Shot light per new patch, conserved per base patch.
        let old_shot = self.shot();
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

        // The emitters' rows, old and new, and the power each emitting base delivered.
        let emits = |p: &Problem, i: usize| {
            super::super::channel_sum(p.material_of(PatchId(i as u32)).emission) > 0.0
        };
        let mut old_rows: Vec<(usize, Arc<[f32]>)> = Vec::new();
        let mut delivered_old = vec![Rgb::ZERO; bases];
        for (i, s) in old_shot.iter().enumerate() {
            if emits(&self.problem, i) && super::super::channel_sum(*s) > 0.0 {
                let row = self.rows.row(&self.problem, PatchId(i as u32), cancel)?;
                delivered_old[old.base_patch[i] as usize] += *s * delivered(old, &row);
                old_rows.push((i, row));
            }
        }
        let mut rows = RowCache::default();
        let mut new_rows: Vec<(usize, Arc<[f32]>)> = Vec::new();
        let mut delivered_new = vec![Rgb::ZERO; bases];
        for (i, s) in shot.iter().enumerate() {
            if emits(new, i) && super::super::channel_sum(*s) > 0.0 {
                let row = rows.row(new, PatchId(i as u32), cancel)?;
                delivered_new[mesh.base_patch[i] as usize] += *s * delivered(mesh, &row);
                new_rows.push((i, row));
            }
        }
        // Per emitting base, per channel: new rows scaled to the old delivered power.
        // A base whose light lands nowhere on one of the meshes is not re-aimed.
        let scale: Vec<Option<Rgb>> = delivered_old
            .iter()
            .zip(&delivered_new)
            .map(|(o, n)| {
                let channel = |o: f64, n: f64| match (o == 0.0, n == 0.0) {
                    (true, true) => Some(0.0),
                    (false, false) => Some(o / n),
                    _ => None,
                };
                Some(Rgb::new(
                    channel(o.x, n.x)?,
                    channel(o.y, n.y)?,
                    channel(o.z, n.z)?,
                ))
            })
            .collect();

        // What the rest of the shots brought (reflected light), inherited and conserved.
        let mut rest = self.incident.clone();
        for (i, row) in &old_rows {
            if scale[old.base_patch[*i] as usize].is_some() {
                let s = old_shot[*i];
                for (h, f) in rest.iter_mut().zip(row.iter()) {
                    *h -= s * f64::from(*f);
                }
            }
        }
        let old_area: Vec<f64> = old.elements.iter().map(|e| e.area).collect();
        let new_area: Vec<f64> = mesh.elements.iter().map(|e| e.area).collect();
        let old_base: Vec<u32> = old
            .elements
            .iter()
            .map(|e| old.base_patch[e.patch.0 as usize])
            .collect();
        let new_base: Vec<u32> = mesh
            .elements
            .iter()
            .map(|e| mesh.base_patch[e.patch.0 as usize])
            .collect();
        let target = totals(&rest, &old_area, &old_base, bases);
        let mut incident: Vec<Rgb> = mesh
            .elements
            .iter()
            .zip(&new_base)
            .map(|(e, &b)| rest[locator.locate(b, e.centroid)])
            .collect();
        conserve(&mut incident, &new_area, &new_base, &target);

        // The emitters' shots again, through the new rows.
        for (i, row) in &new_rows {
            if let Some(k) = scale[mesh.base_patch[*i] as usize] {
                shot[*i] *= k;
                let s = shot[*i];
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
        let unshot = patch_mean(mesh, &radiosity)
            .into_iter()
            .zip(&shot)
            .map(|(b, s)| b - *s)
            .collect();
        Some(Carried {
            rows,
            incident,
            radiosity,
            unshot,
        })
    }
}

/// The new solver's state.
struct Carried {
    rows: RowCache,
    incident: Vec<Rgb>,
    radiosity: Vec<Rgb>,
    unshot: Vec<Rgb>,
}

/// The power a unit shot radiance of the row's patch `i` delivers, `Σ_j F_ji A_j`.
fn delivered(mesh: &Mesh, row: &[f32]) -> f64 {
    row.iter()
        .zip(&mesh.elements)
        .map(|(f, e)| f64::from(*f) * e.area)
        .sum()
}

/// Area-weighted mean of element values per patch (`Σ B A / A_p`, as shooting keeps it).
fn patch_mean(mesh: &Mesh, values: &[Rgb]) -> Vec<Rgb> {
    mesh.patches
        .iter()
        .map(|p| {
            let sum = (p.elements.start..p.elements.end)
                .map(|j| values[j as usize] * mesh.elements[j as usize].area)
                .fold(Rgb::ZERO, |a, b| a + b);
            sum / p.area
        })
        .collect()
}

fn base_count(mesh: &Mesh) -> usize {
    mesh.base_patch
        .iter()
        .map(|&b| b as usize + 1)
        .max()
        .unwrap_or(0)
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
        let mut a = vec![(0.0, None); base_count(m)];
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
        let mut patches = vec![Vec::new(); base_count(old)];
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
