//! What the progressive solver shows while unconverged: the ambient term (Cohen et al.
//! 1988), global or regional, added to each element's radiosity for display, and the
//! overshoot it sends ahead of the light still to come.

use super::super::ambient::RegionalAmbient;
use super::ProgressiveSolver;
use crate::scene::Rgb;

impl ProgressiveSolver {
    /// The ambient term (Cohen et al. 1988): an estimate of the light not yet shot.
    pub fn ambient(&self) -> Rgb {
        if self.total_area <= 0.0 {
            return Rgb::ZERO;
        }
        let mut rho = Rgb::ZERO;
        let mut unshot = Rgb::ZERO;
        for (k, (p, u)) in self
            .problem
            .mesh
            .patches
            .iter()
            .zip(&self.unshot)
            .enumerate()
        {
            rho += self.problem.patch_rho(k) * p.area;
            unshot += *u * p.area;
        }
        let rho_avg = rho / self.total_area;
        let r = Rgb::ONE / (Rgb::ONE - rho_avg).max(Rgb::splat(1e-6));
        r * unshot / self.total_area
    }

    /// The regional ambient term per patch ([`crate::solver::ambient`]): the light still to arrive
    /// per unit reflectance. Builds the regions on first use.
    pub fn regional_ambient(&self) -> Vec<Rgb> {
        let regional = self
            .regional
            .get_or_init(|| RegionalAmbient::build(&self.problem));
        let patches = &self.problem.mesh.patches;
        let area: Vec<f64> = patches.iter().map(|p| p.area).collect();
        let rho: Vec<Rgb> = (0..patches.len())
            .map(|k| self.problem.patch_rho(k))
            .collect();
        regional.incoming(&area, &self.unshot, &rho)
    }

    /// Per-element radiance for display: `B_j + ρ_j · G_j`, `G` the regional ambient term
    /// or (`regional_ambient` off) the classic one.
    ///
    /// With overshooting the ambient term can be negative (light sent ahead and not yet
    /// cancelled: the image is too bright on average, and the term is still exact on
    /// average in a closed uniform scene); an element it would take below zero shows 0.
    pub fn display_radiance(&self) -> Vec<Rgb> {
        if self.problem.config.shooting.regional_ambient {
            self.shown_with(&self.regional_ambient())
        } else {
            self.element_radiance_global_ambient()
        }
    }

    /// [`display_radiance`](Self::display_radiance) with the classic global ambient term,
    /// whatever the configuration (for comparing the two).
    pub fn element_radiance_global_ambient(&self) -> Vec<Rgb> {
        self.shown_with(&vec![self.ambient(); self.problem.mesh.patches.len()])
    }

    /// `max(B_j + ρ_j G_p, 0)` per element, `G_p` the ambient term of its patch.
    pub(super) fn shown_with(&self, per_patch: &[Rgb]) -> Vec<Rgb> {
        use rayon::prelude::*;
        (self.radiosity.par_iter())
            .zip(&self.element_rho)
            .zip(&self.problem.mesh.elements)
            .with_min_len(4096)
            .map(|((b, rho), e)| (*b + *rho * per_patch[e.patch.0 as usize]).max(Rgb::ZERO))
            .collect()
    }

    /// What a shot from each patch would send beyond its unshot radiance: `ρ_i · ambient`
    /// with overshooting (never negative), nothing without.
    ///
    /// Never negative keeps every radiosity non-negative: what patch `i` has shot in all,
    /// `T_i = B_i − U_i`, is 0 before its first shot and `B_i + X_i ≥ B_i` after each
    /// (`U_i = −X_i`, `X_i ≥ 0`), so by induction every `T ≥ 0`, every incident
    /// `H_j = Σ F_ji T_i ≥ 0` and every `B_j = E_j + ρ_j H_j ≥ 0`. A negative ambient
    /// (overshot light not yet cancelled) would break the chain.
    pub(super) fn overshoot_basis(&self) -> Rgb {
        if self.problem.config.shooting.overshoot {
            self.ambient().max(Rgb::ZERO)
        } else {
            Rgb::ZERO
        }
    }
}
