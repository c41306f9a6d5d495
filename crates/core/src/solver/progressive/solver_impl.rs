//! [`ProgressiveSolver`] behind the [`Solver`] trait.

use std::sync::atomic::AtomicBool;

use super::super::rows::RowCache;
use super::super::{Problem, Solver, SolverError};
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
    fn element_radiance(&self, with_ambient: bool) -> Vec<Rgb> {
        ProgressiveSolver::element_radiance(self, with_ambient)
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
    fn ambient(&self) -> Rgb {
        ProgressiveSolver::ambient(self)
    }
    fn matrix_bytes(&self) -> usize {
        self.rows.bytes()
    }
    fn last_shooter(&self) -> Option<PatchId> {
        self.last_shooter
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
    fn unshot(&self) -> Option<&[Rgb]> {
        Some(&self.unshot)
    }
    fn into_parts(self: Box<Self>) -> (Problem, RowCache) {
        (self.problem, self.rows)
    }
    fn carry_to(
        &mut self,
        problem: Problem,
        cancel: &AtomicBool,
    ) -> Result<Box<dyn Solver>, Box<Problem>> {
        ProgressiveSolver::carry_to(self, problem, cancel).map(|s| Box::new(s) as Box<dyn Solver>)
    }
    fn report(&self) -> String {
        format!(
            "{} shots{}",
            self.shots,
            if self.problem.config.overshoot {
                ", overshooting"
            } else {
                ""
            }
        )
    }
}
