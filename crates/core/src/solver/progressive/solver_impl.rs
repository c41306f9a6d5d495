//! [`ProgressiveSolver`] behind the [`Solver`] trait.

use std::sync::atomic::AtomicBool;

use super::super::ambient::RegionalAmbient;
use super::super::rows::RowCache;
use super::super::{Problem, Shooting, Solver, SolverError};
use super::ProgressiveSolver;
use crate::mesh::PatchId;
use crate::scene::{MaterialId, Rgb};

impl Solver for ProgressiveSolver {
    fn name(&self) -> &'static str {
        "shooting"
    }
    fn problem(&self) -> &Problem {
        &self.problem
    }
    fn step(&mut self, cancel: &AtomicBool) -> bool {
        self.shoot(cancel).is_some()
    }
    fn steps(&self) -> usize {
        self.shots
    }
    fn radiosity(&self) -> &[Rgb] {
        &self.radiosity
    }
    fn residual(&self) -> f64 {
        self.unshot_fraction()
    }
    fn display_radiance(&self) -> Vec<Rgb> {
        ProgressiveSolver::display_radiance(self)
    }
    fn set_material(
        &mut self,
        id: MaterialId,
        reflectance: Rgb,
        emission: Rgb,
    ) -> Result<(), SolverError> {
        ProgressiveSolver::set_material(self, id, reflectance, emission)
    }
    fn set_lights(&mut self, lights: Vec<crate::scene::Light>) {
        ProgressiveSolver::set_lights(self, lights)
    }
    fn reset(&mut self) {
        ProgressiveSolver::reset(self)
    }
    fn matrix_bytes(&self) -> usize {
        self.rows.bytes()
    }
    /// `ρ_j |G_j|` over what the element shows, `G` the regional ambient term (the light the
    /// unshot power is expected to bring).
    fn error_estimate(&self) -> f64 {
        let g = self.regional_ambient();
        let floor = super::super::error_floor(&self.problem, &self.radiosity);
        self.radiosity
            .iter()
            .zip(&self.element_rho)
            .zip(&self.problem.mesh.elements)
            .map(|((b, rho), e)| {
                let missing = (*rho * g[e.patch.0 as usize]).abs();
                let shown = (*b + *rho * g[e.patch.0 as usize]).max(Rgb::ZERO);
                (missing / shown.max(Rgb::splat(floor))).max_element()
            })
            .fold(0.0, f64::max)
    }
    fn into_parts(self: Box<Self>) -> (Problem, Option<RowCache>) {
        (self.problem, Some(self.rows))
    }
    fn shooting(&self) -> Option<&dyn Shooting> {
        Some(self)
    }
    fn shooting_mut(&mut self) -> Option<&mut dyn Shooting> {
        Some(self)
    }
    fn report(&self) -> String {
        format!(
            "{} shots{}",
            self.shots,
            if self.problem.config.shooting.overshoot {
                ", overshooting"
            } else {
                ""
            }
        )
    }
}

impl Shooting for ProgressiveSolver {
    fn ambient(&self) -> Rgb {
        ProgressiveSolver::ambient(self)
    }
    fn last_shooter(&self) -> Option<PatchId> {
        self.last_shooter
    }
    fn unshot(&self) -> &[Rgb] {
        &self.unshot
    }
    fn carry_to(
        &mut self,
        problem: Problem,
        cancel: &AtomicBool,
    ) -> Result<Box<dyn Solver>, Box<Problem>> {
        ProgressiveSolver::carry_to(self, problem, cancel).map(|s| Box::new(s) as Box<dyn Solver>)
    }
    fn use_regional_ambient(&mut self, regional: RegionalAmbient) {
        if regional.patch_regions().len() == self.problem.mesh.patches.len() {
            // Already built (a display came first): the two are the same.
            let _ = self.regional.set(regional);
        }
    }
}
