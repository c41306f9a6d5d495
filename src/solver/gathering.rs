//! Gathering with a stored matrix (the lecture's "full matrix" radiosity; Cohen & Wallace
//! 1993, ch. 5): Jacobi, Gauss-Seidel and successive over-relaxation on the patch system
//! `B_p = E_p + ρ_p Σ_i F_pi B_i`, `F_pi = Σ_{j∈p} A_j F_ji / A_p` from the elements' rows,
//! then every element gathered from the patch solution, `B_j = E_j + ρ_j Σ_i F_ji B_i`.
//! The patch averages of that element field solve the patch system exactly (one material
//! per patch), so this is the same answer the shooting solver converges to on the same
//! rows.
//!
//! The matrix is built a row per step (each row is one shooter's form factors to every
//! element, the same rows shooting uses) and stored sparse: a receiver keeps only the
//! shooters it sees. Every row is kept for the element gather, so the rows must fit in
//! [`SolverConfig::row_cache_bytes`](super::SolverConfig); a larger mesh is refused with
//! [`SolverError::MatrixTooLarge`] before any work.
//!
//! SOR without a given ω estimates it (Young's formula for consistently ordered systems):
//! after three Gauss-Seidel sweeps the residual ratio μ estimates the Gauss-Seidel
//! convergence factor `μ_J²`, and `ω = 2 / (1 + √(1 − μ))`.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use rayon::prelude::*;

use crate::mesh::PatchId;
use crate::scene::{MaterialId, Rgb};

use super::problem::Problem;
use super::rows::RowCache;
use super::{Solver, SolverError, channel_sum};

/// Which gathering iteration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GatherMethod {
    Jacobi,
    GaussSeidel,
    /// `None`: ω estimated from the first sweeps.
    Sor(Option<f64>),
}

/// The patch-level matrix, by receiver, built one shooter row at a time.
pub(crate) struct PatchMatrix {
    /// For each receiving patch `p`: `(i, F_pi)` for every shooter `i` it sees.
    pub by_receiver: Vec<Vec<(u32, f64)>>,
    /// The element rows, by shooter (kept for the element gather).
    pub rows: Vec<Arc<[f32]>>,
    cache: RowCache,
}

impl PatchMatrix {
    /// Refuses (before any work) rows that would not fit the memory budget.
    pub fn new(problem: &Problem, solver: &'static str) -> Result<Self, SolverError> {
        let (patches, elements) = (problem.mesh.patches.len(), problem.mesh.elements.len());
        let needed = patches * elements * 4 + patches * patches * 12 / 2;
        if needed > problem.config.row_cache_bytes {
            return Err(SolverError::MatrixTooLarge {
                solver,
                needed_mb: needed.div_ceil(1 << 20),
                limit_mb: problem.config.row_cache_bytes >> 20,
                patches,
                elements,
            });
        }
        Ok(Self {
            by_receiver: vec![Vec::new(); patches],
            rows: Vec::with_capacity(patches),
            cache: RowCache::default(),
        })
    }

    pub fn complete(&self, problem: &Problem) -> bool {
        self.rows.len() == problem.mesh.patches.len()
    }

    /// Computes the next shooter's row. `false` if `cancel` was set.
    pub fn build_next(&mut self, problem: &Problem, cancel: &AtomicBool) -> bool {
        let i = self.rows.len();
        let Some(row) = self.cache.row(problem, PatchId(i as u32), cancel) else {
            return false;
        };
        let mesh = &problem.mesh;
        for (p, patch) in mesh.patches.iter().enumerate() {
            let r = patch.elements.start as usize..patch.elements.end as usize;
            let f: f64 = row[r.clone()]
                .iter()
                .zip(&mesh.elements[r])
                .map(|(f, e)| *f as f64 * e.area)
                .sum::<f64>()
                / patch.area;
            if f > 0.0 && f.is_finite() {
                self.by_receiver[p].push((i as u32, f));
            }
        }
        self.rows.push(row);
        true
    }

    pub fn bytes(&self) -> usize {
        self.cache.bytes() + self.by_receiver.iter().map(|r| r.len() * 16).sum::<usize>()
    }

    /// `Σ_i F_pi B_i` for patch `p`.
    pub fn gather(&self, p: usize, b: &[Rgb]) -> Rgb {
        self.by_receiver[p]
            .iter()
            .fold(Rgb::ZERO, |acc, &(i, f)| acc + b[i as usize] * f)
    }

    /// Element radiosity from patch radiosity: `B_j = E_j + ρ_j Σ_i F_ji B_i`.
    pub fn element_radiosity(&self, problem: &Problem, rho: &[Rgb], patch_b: &[Rgb]) -> Vec<Rgb> {
        let mesh = &problem.mesh;
        let mut out = vec![Rgb::ZERO; mesh.elements.len()];
        const CHUNK: usize = 2048;
        out.par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(c, chunk)| {
                let first = c * CHUNK;
                for (i, row) in self.rows.iter().enumerate() {
                    let b = patch_b[i];
                    for (k, h) in chunk.iter_mut().enumerate() {
                        let f = row[first + k];
                        if f != 0.0 {
                            *h += b * f as f64;
                        }
                    }
                }
                for (k, h) in chunk.iter_mut().enumerate() {
                    let j = first + k;
                    *h = problem.material_of(mesh.elements[j].patch).emission + rho[j] * *h;
                }
            });
        out
    }

    /// Relative residual of the patch system at `b`: `Σ|E + ρFB − B|A / emitted`.
    pub fn residual(&self, problem: &Problem, b: &[Rgb], emitted: f64) -> f64 {
        let r: f64 = problem
            .mesh
            .patches
            .iter()
            .enumerate()
            .map(|(p, patch)| {
                let m = &problem.scene.materials[patch.material.0 as usize];
                channel_sum(m.emission + m.reflectance * self.gather(p, b) - b[p]) * patch.area
            })
            .sum();
        relative(r, emitted)
    }
}

pub(crate) fn relative(r: f64, emitted: f64) -> f64 {
    if emitted > 0.0 {
        r / emitted
    } else if r > 0.0 {
        f64::INFINITY
    } else {
        0.0
    }
}

/// Jacobi, Gauss-Seidel or SOR on a stored matrix (see the module docs).
pub struct GatheringSolver {
    problem: Problem,
    method: GatherMethod,
    matrix: PatchMatrix,
    /// Per patch.
    patch_b: Vec<Rgb>,
    /// Per element (gathered after each sweep).
    radiosity: Vec<Rgb>,
    element_rho: Vec<Rgb>,
    steps: usize,
    sweeps: usize,
    residual: f64,
    residual_history: Vec<f64>,
    /// ω in use (SOR), estimated or given.
    omega: Option<f64>,
    emitted: f64,
}

impl GatheringSolver {
    pub fn new(problem: Problem, method: GatherMethod) -> Result<Self, SolverError> {
        let name = match method {
            GatherMethod::Jacobi => "jacobi",
            GatherMethod::GaussSeidel => "gauss-seidel",
            GatherMethod::Sor(_) => "sor",
        };
        if let GatherMethod::Sor(Some(w)) = method
            && !(w > 0.0 && w < 2.0)
        {
            return Err(SolverError::BadValue {
                what: "--omega",
                range: "in (0, 2)",
                value: [w; 3],
            });
        }
        let matrix = PatchMatrix::new(&problem, name)?;
        let mut s = Self {
            problem,
            method,
            matrix,
            patch_b: Vec::new(),
            radiosity: Vec::new(),
            element_rho: Vec::new(),
            steps: 0,
            sweeps: 0,
            residual: 1.0,
            residual_history: Vec::new(),
            omega: match method {
                GatherMethod::Sor(w) => w,
                _ => None,
            },
            emitted: 0.0,
        };
        s.reset();
        Ok(s)
    }

    /// Sweeps done since the matrix was complete.
    pub fn sweeps(&self) -> usize {
        self.sweeps
    }

    /// The relaxation factor in use (SOR only; `None` while still estimating).
    pub fn omega(&self) -> Option<f64> {
        self.omega
    }

    fn sweep(&mut self) {
        let p = &self.problem;
        let n = p.mesh.patches.len();
        let material = |k: usize| &p.scene.materials[p.mesh.patches[k].material.0 as usize];
        match self.method {
            GatherMethod::Jacobi => {
                let old = self.patch_b.clone();
                for k in 0..n {
                    let m = material(k);
                    self.patch_b[k] = m.emission + m.reflectance * self.matrix.gather(k, &old);
                }
            }
            GatherMethod::GaussSeidel | GatherMethod::Sor(_) => {
                let w = match self.method {
                    GatherMethod::Sor(_) => self.omega.unwrap_or(1.0),
                    _ => 1.0,
                };
                for k in 0..n {
                    let m = material(k);
                    let gs = m.emission + m.reflectance * self.matrix.gather(k, &self.patch_b);
                    self.patch_b[k] = self.patch_b[k] * (1.0 - w) + gs * w;
                }
            }
        }
        self.sweeps += 1;
        self.residual = self.matrix.residual(p, &self.patch_b, self.emitted);
        self.residual_history.push(self.residual);
        if matches!(self.method, GatherMethod::Sor(None))
            && self.omega.is_none()
            && self.residual_history.len() >= 3
        {
            let h = &self.residual_history;
            let mu = (h[h.len() - 1] / h[h.len() - 2]).clamp(0.0, 0.999_999);
            self.omega = Some(2.0 / (1.0 + (1.0 - mu).sqrt()));
        }
        self.radiosity = self
            .matrix
            .element_radiosity(p, &self.element_rho, &self.patch_b);
        debug_assert!(self.radiosity.iter().all(|b| b.is_finite()));
    }
}

impl Solver for GatheringSolver {
    fn name(&self) -> &'static str {
        match self.method {
            GatherMethod::Jacobi => "jacobi",
            GatherMethod::GaussSeidel => "gauss-seidel",
            GatherMethod::Sor(_) => "sor",
        }
    }
    fn problem(&self) -> &Problem {
        &self.problem
    }
    fn step(&mut self, cancel: &AtomicBool) -> bool {
        if !self.matrix.complete(&self.problem) {
            if !self.matrix.build_next(&self.problem, cancel) {
                return false;
            }
        } else {
            if self.residual == 0.0 {
                return false;
            }
            self.sweep();
        }
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
    /// No display correction: until the first sweep only the lights show.
    fn element_radiance(&self, _with_ambient: bool) -> Vec<Rgb> {
        self.radiosity.clone()
    }
    fn set_material(
        &mut self,
        id: MaterialId,
        reflectance: Rgb,
        emission: Rgb,
    ) -> Result<(), SolverError> {
        self.problem
            .set_material(id.0 as usize, reflectance, emission)?;
        self.element_rho = self.problem.element_reflectance();
        self.emitted = self.problem.emitted_power().max(f64::MIN_POSITIVE);
        if self.matrix.complete(&self.problem) {
            // Continue from the current solution with the new materials.
            self.residual = self
                .matrix
                .residual(&self.problem, &self.patch_b, self.emitted);
        }
        Ok(())
    }
    fn reset(&mut self) {
        let p = &self.problem;
        self.patch_b = p
            .mesh
            .patches
            .iter()
            .map(|q| p.scene.materials[q.material.0 as usize].emission)
            .collect();
        self.element_rho = p.element_reflectance();
        self.radiosity = p
            .mesh
            .elements
            .iter()
            .map(|e| p.material_of(e.patch).emission)
            .collect();
        self.emitted = p.emitted_power();
        self.residual = if self.emitted > 0.0 { 1.0 } else { 0.0 };
        self.residual_history.clear();
        self.steps = 0;
        self.sweeps = 0;
        if let GatherMethod::Sor(w) = self.method {
            self.omega = w;
        }
    }
    fn matrix_bytes(&self) -> usize {
        self.matrix.bytes()
    }
    fn report(&self) -> String {
        match (self.method, self.omega) {
            (GatherMethod::Sor(None), Some(w)) => {
                format!("{} sweeps, omega {w:.3} (estimated)", self.sweeps)
            }
            (GatherMethod::Sor(Some(w)), _) => format!("{} sweeps, omega {w:.3}", self.sweeps),
            _ => format!("{} sweeps", self.sweeps),
        }
    }
}
