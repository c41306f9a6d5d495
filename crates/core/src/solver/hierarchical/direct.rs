//! The lights' direct light from form-factor rows instead of links.
//!
//! Hierarchical radiosity links every receiver to the lights in its first refinement; on
//! the Crytek atrium, two small emitting spheres that each element sees whole, that is
//! 3.2 M links of four shadow rays, the larger part of the first refinement, and the
//! second refinement links everything again by the first bounce. A light of a few patches
//! is cheaper to shoot: one row of form factors from each emitting patch to every element
//! (the progressive solver's rows, [`crate::solver::rows`]) gives the direct light exactly
//! as a shot of the emission would, with the form-factor method's error. The hierarchy
//! then takes that light as given ([`HierarchicalSolver::set_direct`]) and links only
//! reflected light, by the first bounce at once.

use std::sync::atomic::AtomicBool;

use super::HierarchicalSolver;
use crate::mesh::PatchId;
use crate::scene::Rgb;
use crate::solver::{Problem, RowCache};

/// Emitting patches up to which a hierarchical solve from dark takes the lights' direct
/// light from their rows ([`HierarchicalSolver::lights_by_rows`]). A row costs about what
/// a shot does, a visibility estimate from every element; the links it replaces grow with
/// the elements too, by the light's nodes each element links to. Measured on the Crytek
/// atrium, whose two spheres are 78 emitting patches (`render sponza.obj --json`, default
/// flags, 2-core AMD EPYC, 2026-12-07, one run each): with the rows the solve took 47.6 s
/// (the first step, rows and a coarse refinement, 22.1 s) against 50.8 and 55.8 s with
/// the lights linked, for 9.0 M links against 15.1 M and a peak of 1.15 GB against
/// 1.25 GB. A scene with many more emitting patches (an emissive texture, a glowing
/// floor) links them as before, where each row would cost more than the links it saves.
pub const LIGHT_ROWS_MAX: usize = 128;

/// The patches whose material emits.
pub fn emitting_patches(problem: &Problem) -> Vec<PatchId> {
    (0..problem.mesh.patches.len() as u32)
        .map(PatchId)
        .filter(|&p| problem.material_of(p).emission != Rgb::ZERO)
        .collect()
}

/// Per element, the irradiance over π that the emitting patches' emission gives it:
/// `Σ_i E_i F_ji` over the rows of the emitting patches `i` (from `rows`, computed where
/// not cached). What a shot of each emitting patch's emission alone would deliver, so its
/// error is the rows' (the form-factor method's, with its visibility samples). `None`
/// when `cancel` was set.
pub fn emitters_direct(
    problem: &Problem,
    rows: &mut RowCache,
    cancel: &AtomicBool,
) -> Option<Vec<Rgb>> {
    let mut direct = vec![Rgb::ZERO; problem.mesh.elements.len()];
    for patch in emitting_patches(problem) {
        let emission = problem.material_of(patch).emission;
        let row = rows.row(problem, patch, cancel)?;
        for (d, f) in direct.iter_mut().zip(row.iter()) {
            *d += emission * f64::from(*f);
        }
    }
    debug_assert!(direct.iter().all(|d| d.is_finite()));
    Some(direct)
}

impl HierarchicalSolver {
    /// A hierarchical solve whose first step shoots the lights' rows and takes their
    /// direct light as given (module docs), where the scene has at most
    /// [`LIGHT_ROWS_MAX`] emitting patches; a plain one otherwise.
    pub fn lights_by_rows(problem: Problem) -> Self {
        let lights = emitting_patches(&problem).len();
        let mut s = Self::new(problem);
        s.light_rows_pending = (1..=LIGHT_ROWS_MAX).contains(&lights);
        s
    }

    /// The lights shot once: their direct light given, each element's radiosity its
    /// source plus the direct light reflected, and that reflected light (with the sky's
    /// and suns' share of the source, not sent yet) the change the next gather passes on.
    /// `false` if cancelled (nothing changed).
    pub(super) fn shoot_lights(&mut self, cancel: &AtomicBool) -> bool {
        let Some(direct) = emitters_direct(&self.problem, &mut RowCache::default(), cancel) else {
            return false;
        };
        let mesh = &self.problem.mesh;
        let reflectance = self.problem.patch_reflectance();
        let mut unshot = vec![Rgb::ZERO; mesh.patches.len()];
        let mut radiosity = Vec::with_capacity(mesh.elements.len());
        for (e, (el, d)) in mesh.elements.iter().zip(&direct).enumerate() {
            let p = el.patch.0 as usize;
            let source = self.problem.element_source(e);
            let reflected = reflectance[p] * *d;
            radiosity.push(source + reflected);
            let emission = self.problem.material_of(el.patch).emission;
            unshot[p] += (source - emission + reflected) * el.area;
        }
        for (u, patch) in unshot.iter_mut().zip(&mesh.patches) {
            if patch.area > 0.0 {
                *u /= patch.area;
            }
        }
        self.continue_from(&radiosity, &unshot);
        self.set_direct(direct);
        true
    }
}
