//! [`HierarchicalSolver`] behind the [`Solver`] trait.

use std::sync::atomic::AtomicBool;

use super::super::ambient::RegionalAmbient;
use super::super::{Problem, RowCache, Solver, SolverError, channel_sum};
use super::{Basis, HierarchicalSolver};
use crate::scene::{MaterialId, Rgb};

/// The change, relative to the emitted power, under which the display correction is the
/// classic ambient term instead of the regional one.
const REGIONAL_FLOOR: f64 = 1e-3;

impl Solver for HierarchicalSolver {
    fn name(&self) -> &'static str {
        match self.basis {
            Basis::Haar => "hierarchical",
            Basis::Flatlet => "wavelet",
        }
    }
    fn problem(&self) -> &Problem {
        &self.problem
    }
    fn step(&mut self, cancel: &AtomicBool) -> bool {
        if self.tree.root().is_none() || self.residual == 0.0 {
            return false;
        }
        let t0 = std::time::Instant::now();
        if self.light_rows_pending {
            if !self.shoot_lights(cancel) {
                return false;
            }
            self.light_rows_pending = false;
        }
        // Links follow the light: refine while the solution still changes much (the
        // first steps), then only once the residual has fallen 8× since the last refine;
        // provisional links are decided anew as soon as their transfer outgrows one ray.
        let full = self.steps < 2 || self.residual * 8.0 <= self.residual_at_refine;
        if full || self.provisional_outgrown() {
            if !self.refine(cancel, full) {
                return false;
            }
            self.update_gain();
            if full {
                self.residual_at_refine = self.residual;
            }
        }
        let t1 = std::time::Instant::now();
        self.gather_push_pull();
        self.refine_seconds += (t1 - t0).as_secs_f64();
        self.gather_seconds += t1.elapsed().as_secs_f64();
        self.steps += 1;
        true
    }
    fn steps(&self) -> usize {
        self.steps
    }
    fn radiosity(&self) -> &[Rgb] {
        &self.radiosity
    }
    fn residual(&self) -> f64 {
        self.residual
    }
    /// The radiosity plus the light still to arrive, estimated from the last iteration's
    /// change as the ambient term estimates it from the unshot light: regionally
    /// ([`HierarchicalSolver::missing_per_patch`]) where the configuration asks for it, as
    /// for shooting; before the first iteration from the emission, so the first view is lit.
    fn display_radiance(&self) -> Vec<Rgb> {
        use rayon::prelude::*;
        let missing = self.missing_per_patch();
        let elements = &self.problem.mesh.elements;
        (self.radiosity.par_iter().zip(elements))
            .with_min_len(4096)
            .map(|(b, e)| {
                let p = e.patch.0 as usize;
                (*b + self.reflectance[p] * missing[p]).max(Rgb::ZERO)
            })
            .collect()
    }
    /// Keeps the links and continues from the current solution (later iterations refine
    /// where the new materials need it).
    fn set_material(
        &mut self,
        id: MaterialId,
        reflectance: Rgb,
        emission: Rgb,
    ) -> Result<(), SolverError> {
        self.problem
            .set_material(id.0 as usize, reflectance, emission)?;
        self.sources_changed();
        Ok(())
    }
    /// Keeps the links and continues from the current solution.
    fn set_lights(&mut self, lights: Vec<crate::scene::Light>) {
        self.problem.set_lights(lights);
        self.sources_changed();
    }
    /// Back to the emission alone, sent over links again; the links are kept.
    fn reset(&mut self) {
        self.direct = Vec::new();
        self.shot_base = None;
        self.emission = self.problem.patch_emission();
        self.reflectance = self.problem.patch_reflectance();
        self.radiosity = self.problem.element_emission();
        // The emission is the first change: all of it is still to be reflected.
        self.change = self.radiosity.clone();
        self.emitted = self.problem.emitted_power();
        self.residual = if self.emitted > 0.0 { 1.0 } else { 0.0 };
        self.steps = 0;
        self.residual_at_refine = f64::INFINITY;
        self.pull();
    }
    fn matrix_bytes(&self) -> usize {
        self.bytes()
    }
    /// `max|change| / (1 − ρ_max)` over each element's radiosity (as for the gathering
    /// solvers; the change of a Jacobi iteration is its residual). Infinite before the
    /// first iteration.
    fn error_estimate(&self) -> f64 {
        if self.steps == 0 {
            return f64::INFINITY;
        }
        let r_max = self
            .change
            .iter()
            .map(|c| c.abs().max_element())
            .fold(0.0, f64::max);
        let rho_max = self
            .reflectance
            .iter()
            .map(|r| r.max_element())
            .fold(0.0, f64::max);
        super::super::residual_error_estimate(
            &self.problem,
            &self.radiosity,
            &self.radiosity,
            r_max,
            rho_max,
        )
    }
    fn report(&self) -> String {
        let blocks = if self.basis == Basis::Flatlet {
            format!("{} flatlet blocks, ", self.blocks.len())
        } else {
            String::new()
        };
        blocks
            + &format!(
                "{} links ({} made), {} nodes ({} planar groups), {:.1} MB; refine {:.2} s, gather {:.2} s",
                self.links.len(),
                self.links_made,
                self.tree.nodes.len(),
                self.tree.planar_groups,
                self.bytes() as f64 / 1e6,
                self.refine_seconds,
                self.gather_seconds
            )
            + if self.link_budget_reached {
                "; link budget reached (--max-memory): coarser than the tolerance"
            } else {
                ""
            }
    }
    /// No rows: the hierarchy keeps links.
    fn into_parts(self: Box<Self>) -> (Problem, Option<RowCache>) {
        (self.problem, None)
    }
}

impl HierarchicalSolver {
    /// Goes on from another solver's state instead of the emission: `radiosity` per
    /// element (the light arrived so far) and `unshot` per patch (a shooting solver's
    /// unshot radiance: arrived and not yet passed on). The unshot light plays the part of
    /// the last iteration's change, which is what the next iteration reflects, so the
    /// residual starts at the shooter's unshot fraction and the display correction goes on
    /// from the shooter's. The first refinement still links by the emission alone, as from
    /// dark: linking by the light already spread makes the second refinement's links at
    /// once, so the first gathered image comes only after both (on the Crytek atrium 35 s
    /// instead of 13 s). Its gather then starts from the shot light, so the first image
    /// already has the bounces the shots spread.
    ///
    /// # Panics
    /// If `radiosity` does not have one value per element or `unshot` one per patch.
    pub fn continue_from(&mut self, radiosity: &[Rgb], unshot: &[Rgb]) {
        let mesh = &self.problem.mesh;
        assert_eq!(
            radiosity.len(),
            mesh.elements.len(),
            "one radiosity an element"
        );
        assert_eq!(
            unshot.len(),
            mesh.patches.len(),
            "one unshot radiance a patch"
        );
        if self.links.is_empty() && self.blocks.is_empty() {
            self.first_links_by = Some(std::mem::take(&mut self.node_b));
        }
        self.radiosity = radiosity.to_vec();
        self.change = (mesh.elements.iter())
            .map(|e| unshot[e.patch.0 as usize])
            .collect();
        let remaining: f64 = (self.change.iter().zip(&mesh.elements))
            .map(|(c, e)| channel_sum(*c) * e.area)
            .sum();
        self.residual = if self.emitted > 0.0 {
            (remaining / self.emitted).max(0.0)
        } else {
            0.0
        };
        debug_assert!(self.residual.is_finite());
        self.pull();
    }

    /// The irradiance still to arrive everywhere, estimated from the last iteration's
    /// change `Δ` as the ambient term estimates it from the unshot light (Cohen et al.
    /// 1988): each further Jacobi iteration's change is about `ρ̄` times the last, so the
    /// rest sums to `R · Σ Δ_j A_j / Σ A_j` with `R = 1 / (1 − ρ̄)`, `ρ̄` the area-mean
    /// reflectance. It vanishes as the iteration converges. Its error is the classic
    /// term's: the rest is assumed spread evenly, so an element out of reach of the light
    /// still to come shows too bright, one in its path too dark, by up to the term itself.
    pub fn missing_irradiance(&self) -> Rgb {
        let mesh = &self.problem.mesh;
        let (mut rho, mut change, mut area) = (Rgb::ZERO, Rgb::ZERO, 0.0);
        for (e, d) in mesh.elements.iter().zip(&self.change) {
            rho += self.reflectance[e.patch.0 as usize] * e.area;
            change += *d * e.area;
            area += e.area;
        }
        if area <= 0.0 {
            return Rgb::ZERO;
        }
        let r = Rgb::ONE / (Rgb::ONE - rho / area).max(Rgb::splat(1e-6));
        r * change / area
    }

    /// The light still to arrive per unit reflectance, per patch. The change `Δ` of a
    /// Jacobi iteration is what the next one reflects (`B_{k+1} − B_k = ρ K Δ_k`), so it
    /// plays the part of shooting's unshot radiance: the regional term
    /// ([`crate::solver::ambient::RegionalAmbient`], built on first use) carries it only
    /// where it can go, so that before the first gather the light's own surroundings show
    /// brighter than the rest. Once the change is under `REGIONAL_FLOOR` (1e-3) of the emitted
    /// power the two estimates differ by less than that and the classic term
    /// ([`HierarchicalSolver::missing_irradiance`]) is used (a converged solve does not
    /// pay for the regions' rays).
    pub fn missing_per_patch(&self) -> Vec<Rgb> {
        let mesh = &self.problem.mesh;
        let patches = mesh.patches.len();
        if !self.problem.config.shooting.regional_ambient || self.residual < REGIONAL_FLOOR {
            return vec![self.missing_irradiance(); patches];
        }
        let (mut change, mut area) = (vec![Rgb::ZERO; patches], vec![0.0; patches]);
        for (e, d) in mesh.elements.iter().zip(&self.change) {
            let p = e.patch.0 as usize;
            change[p] += *d * e.area;
            area[p] += e.area;
        }
        for (c, a) in change.iter_mut().zip(&area) {
            if *a > 0.0 {
                *c /= *a;
            }
        }
        let regional = self
            .regional
            .get_or_init(|| RegionalAmbient::build(&self.problem));
        regional.incoming(&area, &change, &self.reflectance)
    }

    /// Takes the emitting surfaces' direct light as given instead of sending their
    /// emission over links: `direct` per element is the irradiance over π their emission
    /// gives it, as a shooting solver's rows of the emitting patches compute it
    /// ([`crate::solver::handoff`]). Each gather adds it to what the links bring, and the
    /// links carry only reflected light, so the refinements that follow make no link for
    /// the emission (on the Crytek atrium, 3.2 M links of four rays each, the larger part
    /// of the first refinement) and link by the light as it is now, not by the emission.
    /// An edit of materials or lights, or a reset, sends the emission over links again.
    ///
    /// # Panics
    /// If `direct` does not have one value per element.
    pub fn set_direct(&mut self, direct: Vec<Rgb>) {
        assert_eq!(
            direct.len(),
            self.problem.mesh.elements.len(),
            "one direct irradiance an element"
        );
        debug_assert!(direct.iter().all(|d| d.is_finite()));
        self.direct = direct;
        self.coarse_first = true;
        self.first_links_by = None;
        self.pull();
    }

    /// After an edit of materials or lights: the patches' sources and reflectances anew,
    /// the residual unknown until the next iteration (links kept; the emission is sent
    /// over them again, as the direct light taken from the shots is stale).
    fn sources_changed(&mut self) {
        self.direct = Vec::new();
        self.shot_base = None;
        self.pull();
        self.emission = self.problem.patch_emission();
        self.reflectance = self.problem.patch_reflectance();
        self.emitted = self.problem.emitted_power();
        self.residual = if self.emitted > 0.0 { 1.0 } else { 0.0 };
        self.residual_at_refine = f64::INFINITY;
    }
}
