//! Step mode's numbers: what one shot did, in the lecture's notation ("Shooting and ambient
//! progressive refinement"): the shooter `i` with the most unshot power `ΔB_i A_i`, a
//! column of form factors from it, and each receiver's gain
//! `ΔB_j = ρ_j ΔB_i F_ij A_i / A_j` (reciprocity), then the new ambient term.
//!
//! Computed on the solver thread around a single step of a shooting solver: the state
//! before ([`Before`]) and after the step give the shooter, what it shot and what every
//! element received; the row `F_ij A_i / A_j` is the solver's own (the same
//! [`RowCache::row`], so the same numbers, energy conservation included).

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use nusselt_core::scene::Rgb;
use nusselt_core::solver::{RowCache, Solver};

use super::super::snapshot::Geometry;

/// The state of a shooting solver before a step.
pub struct Before {
    radiosity: Vec<Rgb>,
    unshot: Vec<Rgb>,
    ambient: Rgb,
    residual: f64,
}

impl Before {
    /// `None` for solvers that do not shoot (no unshot radiance).
    pub fn take(solver: &dyn Solver) -> Option<Before> {
        let shooting = solver.shooting()?;
        Some(Before {
            unshot: shooting.unshot().to_vec(),
            radiosity: solver.radiosity().to_vec(),
            ambient: shooting.ambient(),
            residual: solver.residual(),
        })
    }
}

/// What one shot did.
#[derive(Debug)]
pub struct StepDetail {
    /// The shot's number (1 for the first).
    pub step: usize,
    /// The shooting patch `i`.
    pub shooter: u32,
    /// `A_i`.
    pub shooter_area: f64,
    /// `ρ_i`.
    pub shooter_rho: Rgb,
    /// `ΔB_i`: the shooter's unshot radiance before the shot.
    pub unshot: Rgb,
    /// The ambient term before the shot (the overshoot basis, if positive).
    pub ambient_before: Rgb,
    /// What was shot: `ΔB_i`, plus `ρ_i · ambient` with overshooting.
    pub shot: Rgb,
    pub overshoot: bool,
    pub ambient_after: Rgb,
    pub residual_before: f64,
    pub residual_after: f64,
    /// `F_ij A_i / A_j` per element `j` (the solver's row).
    pub row: Arc<[f32]>,
    /// `ΔB_j` per element: what the shot added to its radiosity.
    pub received: Vec<Rgb>,
    /// `ΔB_j` per drawn vertex (for the viewport).
    pub received_vertices: Arc<Vec<[f32; 3]>>,
    /// `A_j` per element.
    pub element_area: Vec<f64>,
    /// `ρ_j` per element.
    pub element_rho: Vec<Rgb>,
}

impl StepDetail {
    /// `F_ij` (shooter to element `j`) from the stored `F_ij A_i / A_j`.
    pub fn f_ij(&self, j: usize) -> f64 {
        self.row.get(j).map_or(0.0, |&r| {
            f64::from(r) * self.element_area[j] / self.shooter_area
        })
    }

    /// `ρ_j ΔB_i F_ij A_i / A_j`: the lecture's formula for element `j`, from the parts.
    pub fn formula(&self, j: usize) -> Rgb {
        self.element_rho[j] * self.shot * self.f_ij(j) * self.shooter_area / self.element_area[j]
    }

    /// The elements that received the most (channel sum), largest first.
    pub fn top_receivers(&self, n: usize) -> Vec<usize> {
        let mut order: Vec<usize> = (0..self.received.len()).collect();
        let key = |j: usize| self.received[j].x + self.received[j].y + self.received[j].z;
        order.sort_by(|&a, &b| key(b).total_cmp(&key(a)));
        order.truncate(n);
        order
    }
}

/// What the step from `before` to `solver`'s state did; `None` if it was not a shot.
pub fn capture(before: Before, solver: &dyn Solver, geometry: &Geometry) -> Option<StepDetail> {
    let shooting = solver.shooting()?;
    let shooter = shooting.last_shooter()?;
    let problem = solver.problem();
    let i = shooter.0 as usize;
    let patch = problem.mesh.patches.get(i)?;
    let shooter_rho = problem.material_of(shooter).reflectance;
    let overshoot = problem.config.shooting.overshoot;
    let basis = if overshoot {
        before.ambient.max(Rgb::ZERO)
    } else {
        Rgb::ZERO
    };
    let unshot = *before.unshot.get(i)?;
    // A row the solver has cached comes back as it is; otherwise it is computed the same
    // way (the throwaway cache keeps nothing).
    let row = RowCache::default().row(problem, shooter, &AtomicBool::new(false))?;
    let received: Vec<Rgb> = solver
        .radiosity()
        .iter()
        .zip(&before.radiosity)
        .map(|(a, b)| *a - *b)
        .collect();
    let per_vertex = problem.mesh.vertex_values(&received);
    Some(StepDetail {
        step: solver.steps(),
        shooter: shooter.0,
        shooter_area: patch.area,
        shooter_rho,
        unshot,
        ambient_before: before.ambient,
        shot: unshot + shooter_rho * basis,
        overshoot,
        ambient_after: shooting.ambient(),
        residual_before: before.residual,
        residual_after: solver.residual(),
        row,
        received,
        received_vertices: Arc::new(geometry.expand(&per_vertex)),
        element_area: problem.mesh.elements.iter().map(|e| e.area).collect(),
        element_rho: problem.element_reflectance(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nusselt_core::mesh::MeshSpec;
    use nusselt_core::scene::{LoadOptions, Scene};
    use nusselt_core::solver::{Problem, SolverConfig, SolverKind};

    /// Every element's gain in a shot is the lecture's `ρ_j ΔB_i F_ij A_i / A_j` with the
    /// recorded parts, for the first shots (from the light, then from walls, with
    /// overshooting); a wrong reciprocity factor, a wrong `ΔB_i` (the overshoot left out)
    /// or another row would break it.
    #[test]
    fn each_gain_is_the_lectures_formula() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let config = SolverConfig {
            mesh: MeshSpec::sized(60.0, 120.0),
            ..Default::default()
        };
        let problem = Problem::new(scene, config).expect("problem");
        let mut solver = SolverKind::Shooting.build(problem).expect("solver");
        let geometry = Geometry::from_mesh(1, &solver.problem().mesh);
        let never = AtomicBool::new(false);
        let mut overshot = false;
        for step in 1..=6 {
            let before = Before::take(solver.as_ref()).expect("shooting");
            assert!(solver.step(&never));
            let d = capture(before, solver.as_ref(), &geometry).expect("a shot");
            assert_eq!(d.step, step);
            overshot |= d.shot != d.unshot;
            let mut checked = 0;
            for j in 0..d.received.len() {
                let want = d.formula(j);
                let got = d.received[j];
                let scale = want.abs().max_element().max(1e-12);
                assert!(
                    (got - want).abs().max_element() <= 1e-9 * scale.max(1.0),
                    "step {step} element {j}: gained {got}, formula {want}"
                );
                if want.max_element() > 0.0 {
                    checked += 1;
                }
            }
            assert!(checked > 10, "step {step}: only {checked} receivers");
            assert_eq!(d.received_vertices.len(), geometry.positions.len());
            assert!(d.residual_after < d.residual_before || step > 1);
        }
        assert!(overshot, "overshooting never added ρ_i·ambient to a shot");
    }
}
